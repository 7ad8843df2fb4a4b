//! spurio-master: a co-simulation master for FMI 2.0 and FMI 3.0 Co-Simulation FMUs (ours or a third
//! party's). It loads FMUs on rust-fmi ([`fmu`]), describes systems by name in TOML or SSP
//! ([`description`], [`ssp`]), loads and edits them by name ([`system`]), compiles them to
//! indices once ([`plan`]), steps them ([`engine`]), sends results to observers
//! ([`record`]), runs parameter sweeps in parallel ([`sweep`]), in shards ([`shard`]) and
//! on a Slurm cluster ([`slurm`]), and reads results back ([`results`]). It knows no FMU of
//! its own: any FMI 2.0 or 3.0 CS FMU runs, both versions mixed in one system.

#![forbid(unsafe_code)]

pub mod description;
pub mod engine;
pub mod fmu;
pub mod logging;
pub mod model_exchange;
pub mod plan;
pub mod record;
pub mod results;
pub mod shard;
pub mod slurm;
pub mod ssp;
pub mod sweep;
pub mod system;
mod xml;
