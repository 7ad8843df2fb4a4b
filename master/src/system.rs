//! A co-simulation system, described in TOML and resolved by name.
//!
//! ```toml
//! name = "crane with sensor"
//! start_time = 0.0
//! stop_time = 10.0
//! step_size = 0.05
//! algorithm = "gauss-seidel"     # or "jacobi"
//! connections = ["crane.x -> sensor.u[1]", "crane.theta -> sensor.u[2]"]
//! record = ["crane.x", "sensor.y[1]"]   # default: every output of every instance
//!
//! [[instance]]
//! name = "crane"
//! fmu = "../build/fmus/GantryCrane.fmu"  # relative to this file
//! parameters = { x0 = 0.2 }
//!
//! [[instance]]
//! name = "sensor"
//! fmu = "../build/fmus/Sensor2.fmu"
//! step_multiple = 1                       # multirate: steps every N base steps
//! ```
//!
//! [`System::resolve`] loads every FMU once and checks every name, type and causality,
//! reporting errors that name the instance, the variable and the file.

use crate::fmu::{Causality, FmuFile, LoadError, VarType};
use serde::{Deserialize, Serialize};
use std::collections::{BTreeMap, HashMap};
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// How the instances exchange values at a communication point.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Algorithm {
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
    /// Path of the `.fmu`, relative to the system file.
    pub fmu: PathBuf,
    /// Start values by variable name (parameters, and constant values of unconnected inputs).
    #[serde(default)]
    pub parameters: BTreeMap<String, toml::Value>,
    /// Steps every `step_multiple` base steps (multirate).
    #[serde(default = "one")]
    pub step_multiple: u32,
    /// Turns the FMU's debug logging on.
    #[serde(default)]
    pub logging: bool,
}

fn one() -> u32 {
    1
}

/// A system file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SystemDescription {
    #[serde(default)]
    pub name: String,
    #[serde(default)]
    pub start_time: f64,
    pub stop_time: f64,
    pub step_size: f64,
    #[serde(default)]
    pub algorithm: Algorithm,
    #[serde(default, rename = "instance")]
    pub instances: Vec<InstanceDescription>,
    #[serde(default)]
    pub connections: Vec<String>,
    #[serde(default)]
    pub record: Vec<String>,
}

/// What is wrong with a system.
#[derive(Debug, thiserror::Error)]
pub enum SystemError {
    #[error("{file}: {reason}")]
    Read { file: PathBuf, reason: String },
    #[error("{0}")]
    Load(#[from] LoadError),
    #[error("system: {0}")]
    Invalid(String),
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
    #[error("input `{input}` is driven twice: by `{first}` and by `{second}`")]
    DrivenTwice {
        input: String,
        first: String,
        second: String,
    },
    #[error("algebraic loop: these direct-feedthrough variables depend on each other within a communication point: {0}")]
    AlgebraicLoop(String),
}

/// A variable of an instance: (instance index, variable index in its FMU).
pub type VarRef = (usize, usize);

/// An instance with its FMU and resolved start values.
#[derive(Debug, Clone)]
pub struct ResolvedInstance {
    pub name: String,
    pub fmu: Arc<FmuFile>,
    /// (variable index, value as f64) to set before initialisation.
    pub start_values: Vec<(usize, f64)>,
    pub step_multiple: u32,
    pub logging: bool,
}

/// A connection from an output to an input.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Connection {
    pub from: VarRef,
    pub to: VarRef,
    pub var_type: VarType,
}

/// A system with every name resolved.
#[derive(Debug, Clone)]
pub struct System {
    pub name: String,
    pub start_time: f64,
    pub stop_time: f64,
    pub step_size: f64,
    pub algorithm: Algorithm,
    pub instances: Vec<ResolvedInstance>,
    pub connections: Vec<Connection>,
    pub recorded: Vec<VarRef>,
}

impl SystemDescription {
    /// Reads a TOML system file.
    pub fn read(path: &Path) -> Result<Self, SystemError> {
        let text = std::fs::read_to_string(path).map_err(|e| SystemError::Read {
            file: path.to_path_buf(),
            reason: e.to_string(),
        })?;
        toml::from_str(&text).map_err(|e| SystemError::Read {
            file: path.to_path_buf(),
            reason: e.to_string(),
        })
    }
}

fn split_variable(text: &str) -> Option<(&str, &str)> {
    let text = text.trim();
    let (instance, variable) = text.split_once('.')?;
    (!instance.is_empty() && !variable.is_empty()).then_some((instance, variable))
}

impl System {
    /// Resolves `description`, loading FMUs relative to `base_dir`.
    pub fn resolve(description: &SystemDescription, base_dir: &Path) -> Result<Self, SystemError> {
        let d = description;
        if !(d.step_size.is_finite() && d.step_size > 0.0) {
            return Err(SystemError::Invalid(format!(
                "step_size must be > 0, got {}",
                d.step_size
            )));
        }
        if !(d.stop_time.is_finite() && d.start_time.is_finite() && d.stop_time >= d.start_time) {
            return Err(SystemError::Invalid(format!(
                "stop_time ({}) must be finite and not before start_time ({})",
                d.stop_time, d.start_time
            )));
        }
        if d.instances.is_empty() {
            return Err(SystemError::Invalid("no [[instance]]".into()));
        }
        let mut loaded: HashMap<PathBuf, Arc<FmuFile>> = HashMap::new();
        let mut instances = Vec::new();
        let mut index_of: HashMap<&str, usize> = HashMap::new();
        for spec in &d.instances {
            if spec.name.is_empty() || spec.name.contains('.') {
                return Err(SystemError::Invalid(format!(
                    "instance name `{}` must be non-empty and contain no '.'",
                    spec.name
                )));
            }
            if index_of
                .insert(spec.name.as_str(), instances.len())
                .is_some()
            {
                return Err(SystemError::Invalid(format!(
                    "two instances are called `{}`",
                    spec.name
                )));
            }
            if spec.step_multiple == 0 {
                return Err(SystemError::Invalid(format!(
                    "instance `{}`: step_multiple must be >= 1",
                    spec.name
                )));
            }
            let path = base_dir.join(&spec.fmu);
            let fmu = match loaded.get(&path) {
                Some(f) => f.clone(),
                None => {
                    let f = Arc::new(FmuFile::open(&path)?);
                    loaded.insert(path.clone(), f.clone());
                    f
                }
            };
            let mut start_values = Vec::new();
            for (name, value) in &spec.parameters {
                let err = |reason: String| SystemError::Parameter {
                    instance: spec.name.clone(),
                    variable: name.clone(),
                    file: fmu.path.clone(),
                    reason,
                };
                let Some(index) = fmu.index_of(name) else {
                    return Err(unknown(&spec.name, name, &fmu));
                };
                let v = &fmu.variables[index];
                if !matches!(v.causality, Causality::Parameter | Causality::Input) {
                    return Err(err(format!(
                        "has causality {:?}: only parameters and inputs can be given values",
                        v.causality
                    )));
                }
                let number = match (v.var_type, value) {
                    (VarType::Real, toml::Value::Float(x)) => *x,
                    (VarType::Real, toml::Value::Integer(i)) => *i as f64,
                    (VarType::Integer | VarType::Enumeration, toml::Value::Integer(i)) => {
                        i32::try_from(*i)
                            .map_err(|_| err(format!("{i} does not fit an Integer")))?
                            as f64
                    }
                    (VarType::Boolean, toml::Value::Boolean(b)) => f64::from(u8::from(*b)),
                    (t, v) => {
                        return Err(err(format!("is of type {t:?}; the value `{v}` is not")));
                    }
                };
                start_values.push((index, number));
            }
            instances.push(ResolvedInstance {
                name: spec.name.clone(),
                fmu,
                start_values,
                step_multiple: spec.step_multiple,
                logging: spec.logging,
            });
        }
        let lookup = |text: &str, connection: &str| -> Result<VarRef, SystemError> {
            let Some((inst, var)) = split_variable(text) else {
                return Err(SystemError::Connection {
                    connection: connection.to_string(),
                    reason: format!("`{text}` is not of the form instance.variable"),
                });
            };
            let Some(&i) = index_of.get(inst) else {
                return Err(SystemError::Connection {
                    connection: connection.to_string(),
                    reason: format!("no instance called `{inst}`"),
                });
            };
            let fmu = &instances[i].fmu;
            let Some(v) = fmu.index_of(var) else {
                return Err(unknown(inst, var, fmu));
            };
            Ok((i, v))
        };
        let name_of = |r: VarRef| {
            format!(
                "{}.{}",
                instances[r.0].name, instances[r.0].fmu.variables[r.1].name
            )
        };
        let mut connections = Vec::new();
        let mut drivers: HashMap<VarRef, String> = HashMap::new();
        for c in &d.connections {
            let Some((from, to)) = c.split_once("->") else {
                return Err(SystemError::Connection {
                    connection: c.clone(),
                    reason: "expected `instance.output -> instance.input`".into(),
                });
            };
            let (from, to) = (lookup(from, c)?, lookup(to, c)?);
            let fv = &instances[from.0].fmu.variables[from.1];
            let tv = &instances[to.0].fmu.variables[to.1];
            let fail = |reason: String| SystemError::Connection {
                connection: c.clone(),
                reason,
            };
            if !matches!(fv.causality, Causality::Output) {
                return Err(fail(format!(
                    "`{}` has causality {:?}; a connection starts at an output",
                    name_of(from),
                    fv.causality
                )));
            }
            if tv.causality != Causality::Input {
                return Err(fail(format!(
                    "`{}` has causality {:?}; a connection ends at an input",
                    name_of(to),
                    tv.causality
                )));
            }
            if fv.var_type != tv.var_type {
                return Err(fail(format!(
                    "type mismatch: `{}` is {:?} but `{}` is {:?}",
                    name_of(from),
                    fv.var_type,
                    name_of(to),
                    tv.var_type
                )));
            }
            if !matches!(
                fv.var_type,
                VarType::Real | VarType::Integer | VarType::Boolean
            ) {
                return Err(fail(format!(
                    "{:?} connections are not supported",
                    fv.var_type
                )));
            }
            if let Some(first) = drivers.insert(to, name_of(from)) {
                return Err(SystemError::DrivenTwice {
                    input: name_of(to),
                    first,
                    second: name_of(from),
                });
            }
            connections.push(Connection {
                from,
                to,
                var_type: fv.var_type,
            });
        }
        let recorded = if d.record.is_empty() {
            instances
                .iter()
                .enumerate()
                .flat_map(|(i, inst)| {
                    inst.fmu
                        .variables
                        .iter()
                        .enumerate()
                        .filter(|(_, v)| {
                            v.causality == Causality::Output
                                && matches!(
                                    v.var_type,
                                    VarType::Real | VarType::Integer | VarType::Boolean
                                )
                        })
                        .map(move |(j, _)| (i, j))
                })
                .collect()
        } else {
            d.record
                .iter()
                .map(|r| lookup(r, &format!("record {r}")))
                .collect::<Result<Vec<_>, _>>()?
        };
        let system = Self {
            name: d.name.clone(),
            start_time: d.start_time,
            stop_time: d.stop_time,
            step_size: d.step_size,
            algorithm: d.algorithm,
            instances,
            connections,
            recorded,
        };
        if system.algorithm == Algorithm::GaussSeidel {
            system.propagation_order()?;
        }
        Ok(system)
    }

    /// Reads and resolves a system file: TOML, or an SSP archive (`.ssp`, whose FMUs are
    /// unpacked next to it in `<name>.ssp.d/`).
    pub fn from_file(path: &Path) -> Result<Self, SystemError> {
        if path.extension().is_some_and(|e| e == "ssp") {
            let dir = path.with_extension("ssp.d");
            let description = crate::ssp::import(path, &dir).map_err(|e| SystemError::Read {
                file: path.to_path_buf(),
                reason: e.to_string(),
            })?;
            return Self::resolve(&description, &dir);
        }
        let description = SystemDescription::read(path)?;
        let base = path.parent().unwrap_or(Path::new("."));
        Self::resolve(&description, base)
    }

    /// `instance.variable`.
    pub fn variable_name(&self, r: VarRef) -> String {
        format!(
            "{}.{}",
            self.instances[r.0].name, self.instances[r.0].fmu.variables[r.1].name
        )
    }

    /// Whether output `r` depends directly on input `input` of the same instance.
    fn feeds_through(&self, output: VarRef, input: VarRef) -> bool {
        output.0 == input.0
            && match &self.instances[output.0].fmu.variables[output.1].dependencies {
                None => true,
                Some(deps) => deps.contains(&input.1),
            }
    }

    /// Whether output `r` depends directly on any input.
    pub fn has_feedthrough(&self, output: VarRef) -> bool {
        match &self.instances[output.0].fmu.variables[output.1].dependencies {
            None => self.instances[output.0]
                .fmu
                .variables
                .iter()
                .any(|v| v.causality == Causality::Input),
            Some(deps) => !deps.is_empty(),
        }
    }

    /// The order in which, at a communication point, connected inputs are set and
    /// direct-feedthrough outputs re-read: a topological order of the graph whose edges are
    /// the connections (output → input) and the feedthrough inside each FMU (input → output
    /// that depends on it). A cycle is an algebraic loop and is reported with its variables.
    pub fn propagation_order(&self) -> Result<Vec<PropagationStep>, SystemError> {
        // Nodes: the connected inputs and the feedthrough outputs that are connection sources.
        let mut nodes: Vec<PropagationStep> = Vec::new();
        for c in &self.connections {
            nodes.push(PropagationStep::SetInput(c.to));
            if self.has_feedthrough(c.from) {
                let n = PropagationStep::GetOutput(c.from);
                if !nodes.contains(&n) {
                    nodes.push(n);
                }
            }
        }
        let n = nodes.len();
        let mut edges = vec![Vec::new(); n];
        let mut indegree = vec![0usize; n];
        for (a, na) in nodes.iter().enumerate() {
            for (b, nb) in nodes.iter().enumerate() {
                let edge = match (na, nb) {
                    (PropagationStep::GetOutput(o), PropagationStep::SetInput(i)) => {
                        self.connections.iter().any(|c| c.from == *o && c.to == *i)
                    }
                    (PropagationStep::SetInput(i), PropagationStep::GetOutput(o)) => {
                        self.feeds_through(*o, *i)
                    }
                    _ => false,
                };
                if edge {
                    edges[a].push(b);
                    indegree[b] += 1;
                }
            }
        }
        let mut ready: Vec<usize> = (0..n).filter(|&i| indegree[i] == 0).rev().collect();
        let mut order = Vec::with_capacity(n);
        while let Some(a) = ready.pop() {
            order.push(nodes[a]);
            for &b in edges[a].iter().rev() {
                indegree[b] -= 1;
                if indegree[b] == 0 {
                    ready.push(b);
                }
            }
        }
        if order.len() < n {
            let stuck: Vec<String> = (0..n)
                .filter(|&i| indegree[i] > 0)
                .map(|i| match nodes[i] {
                    PropagationStep::SetInput(r) | PropagationStep::GetOutput(r) => {
                        self.variable_name(r)
                    }
                })
                .collect();
            return Err(SystemError::AlgebraicLoop(stuck.join(", ")));
        }
        Ok(order)
    }
}

/// One action of the propagation at a communication point.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PropagationStep {
    /// Set a connected input from its source.
    SetInput(VarRef),
    /// Re-read a direct-feedthrough output after its inputs changed.
    GetOutput(VarRef),
}

fn unknown(instance: &str, variable: &str, fmu: &FmuFile) -> SystemError {
    let close: Vec<&str> = fmu
        .variables
        .iter()
        .map(|v| v.name.as_str())
        .filter(|n| {
            let base = variable.split('[').next().unwrap_or(variable);
            n.starts_with(base) || base.starts_with(n.split('[').next().unwrap_or(n))
        })
        .take(8)
        .collect();
    SystemError::UnknownVariable {
        instance: instance.to_string(),
        variable: variable.to_string(),
        file: fmu.path.clone(),
        hint: if close.is_empty() {
            String::new()
        } else {
            format!(" (did you mean one of: {}?)", close.join(", "))
        },
    }
}
