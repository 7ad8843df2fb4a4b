//! Physical plants of the papers (docs/models.md §2.1–§2.4).

pub mod gantry_crane;
pub mod linear_system;
pub mod opamp_filter;
pub mod wind_generator;
