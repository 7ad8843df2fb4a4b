//! Physical plants of the papers (SPEC §2, items 1–4).

pub mod gantry_crane;
pub mod linear_system;
pub mod opamp_filter;
pub mod wind_generator;
