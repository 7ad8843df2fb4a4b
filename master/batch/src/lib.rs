//! spurio-batch: many runs of one system on the spurio engine ([`spurio_master`]). Parameter
//! sweeps run in parallel on one machine ([`sweep`]), split into shards whose files merge
//! into the same table with every run checked present once ([`shard`]), and staged as a Slurm
//! job array with a merge job ([`slurm`]). The engine knows nothing of them.
//!
//! Its modules import one way: `slurm` → `shard` → `sweep` → the engine.

#![forbid(unsafe_code)]

pub mod shard;
pub mod slurm;
pub mod sweep;
