//! spurio-master: a co-simulation engine for FMI 2.0 and FMI 3.0 Co-Simulation FMUs (ours or
//! a third party's), and for Model Exchange FMUs, which it integrates itself between
//! communication points ([`model_exchange`]; several connected ones as one ODE). It loads FMUs on rust-fmi ([`fmu`]), reads systems described by name in
//! TOML or SSP ([`SystemDescription`], [`ssp`]), resolves and edits them by name ([`System`]),
//! compiles them to indices once ([`Plan`]) for a stepping [`Algorithm`] ([`GaussSeidel`],
//! [`Jacobi`], or one of the caller's), steps them ([`Simulation`]), sends results to
//! observers ([`Observer`]: CSV, memory) and reads results back ([`ResultTable`]). It knows no
//! FMU of its own: any FMI 2.0 or 3.0 CS FMU runs, both versions mixed in one system.
//! Sweeps, shards and cluster runs are built on it by the `spurio-batch` crate.
//!
//! Its modules, each importing only those listed before it (but for [`fmu`]'s `me`, which
//! implements [`model_exchange`]'s calls for the FMI instances):
//! `xml`, `logging`, `data`, [`fmu`], `record`, [`model_exchange`] (Model Exchange import: the
//! stepper over the solvers crate), `description`, [`ssp`], `error`, `coupling`, `monitor`,
//! `plan`, `batch` (the values of one FMI call; a running CS or ME instance), `coupled` (the
//! ME instances of a system, integrated group by group), `exchange`, `algorithm`, `system`,
//! `results`, `engine`.
//!
//! Features: `systems` (default; everything from `description` on, data tables and CSV
//! records) and `archive` (opening `.fmu` files; implied by `systems`). Without them the crate
//! is `xml`, `logging`, [`fmu`] (an FMU unpacked into a folder), `record`'s observer trait and
//! [`model_exchange`] over the solvers: the engine-only build an estimator FMU links.

#![forbid(unsafe_code)]

/// The items of feature `systems` (systems of FMUs: descriptions, plan, engine, records).
macro_rules! systems {
    ($($item:item)*) => { $( #[cfg(feature = "systems")] $item )* };
}

systems! {
    mod algorithm;
    mod batch;
    mod coupled;
    mod coupling;
    mod description;
    mod engine;
    mod error;
    mod exchange;
    mod monitor;
    mod plan;
    mod results;
    pub mod ssp;
    mod system;
    /// The data source's table: the reader and interpolation it shares with the `TimeTable` FMU.
    use spurio_table as data;

    pub use algorithm::{named as named_algorithm, Algorithm, GaussSeidel, Jacobi};
    pub use coupling::{
        propagation_order, Connection, Integration, Propagation, PropagationStep, ResolvedInstance,
        VarRef,
    };
    pub use data::{read_text_at_most, Cursor, DataError, DataTable, Interpolation, Reading};
    pub use description::{AlgorithmName, InstanceDescription, ReadError, SystemDescription};
    pub use engine::{RunEnd, RunOptions, Simulation};
    pub use error::{FmiFailure, RunError, SystemError};
    pub use exchange::{Exchange, StepOutcome};
    pub use monitor::{CallInProgress, CallMonitor};
    pub use plan::{Op, Plan, Recorded, Transfer};
    pub use record::CsvWriter;
    pub use results::{ResultTable, ResultsError, MAX_RESULTS_BYTES};
    pub use system::{StartValue, System};
}

pub mod fmu;
pub mod logging;
pub mod model_exchange;
mod record;
pub mod xml;

pub use record::{replay, NoRecording, Observer, TimeSeries};
