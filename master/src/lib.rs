//! The spurio co-simulation master: runs any FMI 2.0 Co-Simulation FMU (ours or a third
//! party's), connects and steps several together, records, plots and sweeps; plus the
//! packaging of the spurio FMUs and the outlier diagnostics.
//!
//! Import is built on rust-fmi ([`fmu`]); setup works with names ([`system`]), stepping with
//! indices resolved once ([`engine`]); results go to observers ([`record`]).

pub mod diagnose;
pub mod engine;
pub mod experiments;
pub mod fmu;
pub mod library_query;
pub mod logging;
pub mod package;
pub mod plot;
pub mod record;
pub mod results;
pub mod ssp;
pub mod sweep;
pub mod system;
