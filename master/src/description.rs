//! A co-simulation system as written: names only, serialised as TOML (the system file) or
//! read from an SSP archive ([`crate::ssp`]).

use crate::data::Interpolation;
use serde::{Deserialize, Deserializer, Serialize, Serializer};
use spurio_solvers::Method;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// The built-in stepping algorithm a system file names (see [`crate::Algorithm`]): how the
/// instances exchange values at a communication point.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum AlgorithmName {
    /// Outputs flow to inputs within the same communication point, in the order of the
    /// direct-feedthrough graph (a loop of direct-feedthrough variables is an error).
    #[default]
    GaussSeidel,
    /// Every input gets the value its source had after the previous step (a one-step delay on
    /// direct-feedthrough paths; what fmpy's SSP runner does).
    Jacobi,
}

/// One instance in the TOML.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct InstanceDescription {
    pub name: String,
    /// Path of the `.fmu`, relative to the system file (empty for a data instance).
    #[serde(default, skip_serializing_if = "is_empty")]
    pub fmu: PathBuf,
    /// A data instance instead of an FMU: the CSV file of recorded signals, relative to the
    /// system file ([`crate::data`]); its columns are outputs.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub data: Option<PathBuf>,
    /// How a data instance reads between samples (default: hold).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub interpolation: Option<Interpolation>,
    /// Start values by variable name (parameters, and constant values of unconnected inputs).
    #[serde(default)]
    pub parameters: BTreeMap<String, toml::Value>,
    /// Steps every `step_multiple` base steps (multirate).
    #[serde(default = "one")]
    pub step_multiple: u32,
    /// Turns the FMU's debug logging on.
    #[serde(default)]
    pub logging: bool,
    /// The FMI interface to run the FMU with (`"me"` or `"cs"`); default: Co-Simulation when
    /// the FMU offers it, else Model Exchange (integrated by the master, [`crate::model_exchange`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub interface: Option<InterfaceName>,
    /// Model Exchange: the solver (`dopri5`, `rodas4` or `stiff`, `rodas3`, `shampine4`;
    /// default `dopri5`).
    #[serde(
        default,
        skip_serializing_if = "Option::is_none",
        deserialize_with = "method_by_name",
        serialize_with = "write_method"
    )]
    pub solver: Option<Method>,
    /// Model Exchange: the solver's relative tolerance (the absolute one: the same times each
    /// state's nominal); default [`DEFAULT_TOLERANCE`].
    #[serde(
        default,
        skip_serializing_if = "Option::is_none",
        deserialize_with = "positive"
    )]
    pub tolerance: Option<f64>,
    /// Model Exchange: the longest solver step in seconds (default: none).
    #[serde(
        default,
        skip_serializing_if = "Option::is_none",
        deserialize_with = "positive"
    )]
    pub max_step: Option<f64>,
}

/// The relative tolerance of a Model Exchange instance whose system file gives none.
pub const DEFAULT_TOLERANCE: f64 = 1e-6;

/// The FMI interface an instance runs with, as a system file writes it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum InterfaceName {
    /// Model Exchange: the master integrates the FMU's states with its own solvers.
    #[serde(rename = "me")]
    ModelExchange,
    /// Co-Simulation: the FMU steps itself (`DoStep`).
    #[serde(rename = "cs")]
    CoSimulation,
}

impl InstanceDescription {
    /// An FMU instance called `name` of the FMU at `fmu`, with the defaults of a system file.
    pub fn new(name: impl Into<String>, fmu: impl Into<PathBuf>) -> Self {
        Self {
            name: name.into(),
            fmu: fmu.into(),
            data: None,
            interpolation: None,
            parameters: BTreeMap::new(),
            step_multiple: 1,
            logging: false,
            interface: None,
            solver: None,
            tolerance: None,
            max_step: None,
        }
    }

    /// Whether a Model Exchange key (`solver`, `tolerance`, `max_step`) is given.
    pub fn has_solver_settings(&self) -> bool {
        self.solver.is_some() || self.tolerance.is_some() || self.max_step.is_some()
    }
}

/// A solver named as `spurio_solvers::Method` parses it (the error lists the names).
fn method_by_name<'de, D: Deserializer<'de>>(d: D) -> Result<Option<Method>, D::Error> {
    let name = String::deserialize(d)?;
    name.parse().map(Some).map_err(serde::de::Error::custom)
}

fn write_method<S: Serializer>(m: &Option<Method>, s: S) -> Result<S::Ok, S::Error> {
    match m {
        Some(m) => s.serialize_str(m.name()),
        None => s.serialize_none(),
    }
}

/// A positive, finite number of seconds or a tolerance (an integer is taken as a number).
fn positive<'de, D: Deserializer<'de>>(d: D) -> Result<Option<f64>, D::Error> {
    #[derive(Deserialize)]
    #[serde(untagged)]
    enum Number {
        Float(f64),
        Integer(i64),
    }
    let x = match Number::deserialize(d)? {
        Number::Float(x) => x,
        Number::Integer(i) => i as f64,
    };
    if x.is_finite() && x > 0.0 {
        Ok(Some(x))
    } else {
        Err(serde::de::Error::custom(format!(
            "expected a positive number, found {x}"
        )))
    }
}

fn one() -> u32 {
    1
}

fn is_empty(path: &Path) -> bool {
    path.as_os_str().is_empty()
}

/// The `start_time`/`stop_time` that stands for "from the data": NaN in the description,
/// written `"data"` in the file.
pub const FROM_DATA: &str = "data";

fn from_data() -> f64 {
    f64::NAN
}

/// A time of the system file: a number, or `"data"` (NaN here), which the system takes from
/// its data instances ([`crate::System::resolve`]).
fn time_or_data<'de, D: Deserializer<'de>>(d: D) -> Result<f64, D::Error> {
    #[derive(Deserialize)]
    #[serde(untagged)]
    enum Time {
        Number(f64),
        Integer(i64),
        Word(String),
    }
    match Time::deserialize(d)? {
        Time::Number(x) => Ok(x),
        Time::Integer(i) => Ok(i as f64),
        Time::Word(w) if w == FROM_DATA => Ok(f64::NAN),
        Time::Word(w) => Err(serde::de::Error::custom(format!(
            "expected a time in seconds or \"{FROM_DATA}\", found \"{w}\""
        ))),
    }
}

fn write_time<S: Serializer>(t: &f64, s: S) -> Result<S::Ok, S::Error> {
    if t.is_nan() {
        s.serialize_str(FROM_DATA)
    } else {
        s.serialize_f64(*t)
    }
}

/// A system file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SystemDescription {
    #[serde(default)]
    pub name: String,
    /// Seconds, or `"data"` (NaN here): the latest first sample of the data instances.
    #[serde(
        default,
        deserialize_with = "time_or_data",
        serialize_with = "write_time"
    )]
    pub start_time: f64,
    /// Seconds, or `"data"` or omitted (NaN here): the earliest last sample of the data
    /// instances.
    #[serde(
        default = "from_data",
        deserialize_with = "time_or_data",
        serialize_with = "write_time"
    )]
    pub stop_time: f64,
    pub step_size: f64,
    #[serde(default)]
    pub algorithm: AlgorithmName,
    #[serde(default, rename = "instance")]
    pub instances: Vec<InstanceDescription>,
    #[serde(default)]
    pub connections: Vec<String>,
    #[serde(default)]
    pub record: Vec<String>,
}

/// Why a system file cannot be read.
#[derive(Debug, thiserror::Error)]
#[error("{}: {reason}", file.display())]
pub struct ReadError {
    pub file: PathBuf,
    pub reason: String,
}

/// The largest system file [`SystemDescription::read`] reads: 64 MiB, the loader's default
/// bound on a model description ([`crate::fmu::LoadLimits`]).
pub const MAX_SYSTEM_FILE: u64 = 64 << 20;

impl SystemDescription {
    /// Reads a TOML system file of at most [`MAX_SYSTEM_FILE`] bytes.
    pub fn read(path: &Path) -> Result<Self, ReadError> {
        Self::read_at_most(path, MAX_SYSTEM_FILE)
    }

    /// Reads a TOML system file, refusing one of more than `max_bytes` bytes (and reading no
    /// more than `max_bytes + 1` of it, so an endless file such as `/dev/zero` is refused too).
    pub fn read_at_most(path: &Path, max_bytes: u64) -> Result<Self, ReadError> {
        let text = crate::data::read_text_at_most(
            path,
            max_bytes,
            "the system file",
            "max_model_description",
        )
        .map_err(|reason| ReadError {
            file: path.to_path_buf(),
            reason,
        })?;
        toml::from_str(&text).map_err(|e| ReadError {
            file: path.to_path_buf(),
            reason: e.to_string(),
        })
    }
}
