//! The engine's errors: what is wrong with a system ([`SystemError`], found while loading,
//! resolving names and compiling) and why a run stopped ([`RunError`], naming every FMU that
//! failed in the same step).

use crate::description::ReadError;
use crate::fmu::LoadError;
use crate::ssp::SspError;
use std::path::{Path, PathBuf};

/// What is wrong with a system.
#[derive(Debug, thiserror::Error)]
pub enum SystemError {
    #[error(transparent)]
    Read(#[from] ReadError),
    #[error(transparent)]
    Ssp(#[from] SspError),
    #[error(transparent)]
    Load(#[from] LoadError),
    #[error("system: {0}")]
    Invalid(String),
    #[error(transparent)]
    Data(#[from] crate::data::DataError),
    #[error("connection `{connection}`: {reason}")]
    Connection { connection: String, reason: String },
    #[error("instance `{instance}` ({file}): no variable `{variable}`{hint}")]
    UnknownVariable {
        instance: String,
        variable: String,
        file: PathBuf,
        hint: String,
    },
    #[error("instance `{instance}` ({file}): parameter `{variable}`: {reason}")]
    Parameter {
        instance: String,
        variable: String,
        file: PathBuf,
        reason: String,
    },
    #[error("no instance called `{instance}` (instances: {known})")]
    UnknownInstance { instance: String, known: String },
    #[error("input `{input}` is driven twice: by `{first}` and by `{second}`")]
    DrivenTwice {
        input: String,
        first: String,
        second: String,
    },
    #[error("algebraic loop: these direct-feedthrough variables depend on each other within a communication point: {0}")]
    AlgebraicLoop(String),
    #[error("an algebraic loop between the Model Exchange instances {instances}, which the master integrates as one ODE: these variables depend on each other directly, through the connections between them: {variables}; break the loop (an output that depends only on states, or a Co-Simulation instance in between)")]
    ModelExchangeLoop {
        instances: String,
        variables: String,
    },
    /// What is wrong with the system an SSP archive describes, naming the archive (and its
    /// FMUs by their paths inside it, not by the folder they were unpacked into). The
    /// message holds the error's whole text, so the error is no `source()` of it (an error
    /// chain would print it twice, the second time with the unpacked folder's paths).
    #[error("{}: {}", ssp.display(), in_archive(error, unpacked))]
    InArchive {
        ssp: PathBuf,
        /// Where the archive was unpacked.
        unpacked: PathBuf,
        error: Box<SystemError>,
    },
}

fn in_archive(error: &SystemError, unpacked: &Path) -> String {
    error
        .to_string()
        .replace(&format!("{}/", unpacked.display()), "")
}

/// One FMI call of one instance that did not succeed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("instance `{instance}` ({file}): {call} returned {status} at t = {time}{log}")]
pub struct FmiFailure {
    pub instance: String,
    pub file: String,
    pub call: &'static str,
    /// `fmi2Discard`, `fmi2Error`, `fmi2Fatal` (or rust-fmi's description of another failure).
    pub status: String,
    pub time: f64,
    /// What the instance logged, quoted (empty if nothing).
    pub log: String,
}

/// Every failure of one step (or initialisation, or terminate), joined.
fn joined(failures: &[FmiFailure]) -> String {
    match failures {
        [one] => one.to_string(),
        many => format!(
            "{} instances failed: {}",
            many.len(),
            many.iter()
                .map(ToString::to_string)
                .collect::<Vec<_>>()
                .join("; ")
        ),
    }
}

/// Why a run stopped.
#[derive(Debug, thiserror::Error)]
pub enum RunError {
    /// The system, or an FMU of it (loading, instantiating).
    #[error(transparent)]
    System(#[from] SystemError),
    /// One or more FMUs failed in the same step (all of them are listed).
    #[error("{}", joined(failures))]
    Fmi { failures: Vec<FmiFailure> },
    /// A Model Exchange instance (or a group of them integrated as one ODE) failed: the
    /// FMU, the call and the time.
    #[error(transparent)]
    ModelExchange(#[from] crate::model_exchange::MeError),
    /// Writing the results failed (the I/O error's text is the message's, not a source).
    #[error("writing results: {0}")]
    Output(std::io::Error),
}

impl From<std::io::Error> for RunError {
    fn from(e: std::io::Error) -> Self {
        Self::Output(e)
    }
}

impl From<FmiFailure> for RunError {
    fn from(f: FmiFailure) -> Self {
        Self::Fmi { failures: vec![f] }
    }
}
