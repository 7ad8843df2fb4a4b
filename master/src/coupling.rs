//! A system's instances once resolved (each with its FMU and start values) and the
//! connections between their variables, by index: what the plan compiler ([`crate::plan`])
//! lays out and a stepping algorithm ([`crate::algorithm`]) orders.

use crate::data::DataTable;
use crate::description::DEFAULT_TOLERANCE;
use crate::error::SystemError;
use crate::fmu::{Causality, FmuFile, VarType};
use spurio_solvers::Method;
use std::sync::Arc;

/// A variable of an instance: (instance index, variable index in its FMU).
pub type VarRef = (usize, usize);

/// A connection from an output to an input.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Connection {
    pub from: VarRef,
    pub to: VarRef,
    pub var_type: VarType,
}

/// One action of the propagation at a communication point.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PropagationStep {
    /// Set a connected input from its source.
    SetInput(VarRef),
    /// Re-read a direct-feedthrough output after its inputs changed.
    GetOutput(VarRef),
}

/// An instance with its FMU and resolved start values.
#[derive(Debug, Clone)]
pub struct ResolvedInstance {
    pub name: String,
    pub fmu: Arc<FmuFile>,
    /// (variable index, value as f64) to set before initialisation; changed by name through
    /// the system (`System::set_start_value`), which checks them and keeps its description
    /// in step.
    pub start_values: Vec<(usize, f64)>,
    pub step_multiple: u32,
    pub logging: bool,
    /// For a data instance, its table (then `fmu` is only the table's interface,
    /// [`FmuFile::is_table`]).
    pub data: Option<Arc<DataTable>>,
    /// How the master integrates it when its FMU is loaded for Model Exchange.
    pub integration: Integration,
}

/// How the master integrates a Model Exchange instance ([`crate::model_exchange`]): the
/// system file's `solver`, `tolerance` and `max_step`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Integration {
    pub method: Method,
    /// The relative tolerance (the absolute one: the same times each state's nominal).
    pub tolerance: f64,
    /// The longest solver step (None: no bound).
    pub max_step: Option<f64>,
}

impl Default for Integration {
    /// DOPRI5 at [`DEFAULT_TOLERANCE`], no maximum step.
    fn default() -> Self {
        Self {
            method: Method::Dopri5,
            tolerance: DEFAULT_TOLERANCE,
            max_step: None,
        }
    }
}

/// Whether output `output` depends directly on input `input` of the same instance.
pub fn feeds_through(instances: &[ResolvedInstance], output: VarRef, input: VarRef) -> bool {
    output.0 == input.0
        && match &instances[output.0].fmu.variables[output.1].dependencies {
            None => true,
            Some(deps) => deps.contains(&input.1),
        }
}

/// Whether output `output` depends directly on any input.
pub fn has_feedthrough(instances: &[ResolvedInstance], output: VarRef) -> bool {
    match &instances[output.0].fmu.variables[output.1].dependencies {
        None => instances[output.0]
            .fmu
            .variables
            .iter()
            .any(|v| v.head.causality == Causality::Input),
        Some(deps) => !deps.is_empty(),
    }
}

/// `instance.variable`.
pub fn variable_name(instances: &[ResolvedInstance], r: VarRef) -> String {
    format!(
        "{}.{}",
        instances[r.0].name, instances[r.0].fmu.variables[r.1].head.name
    )
}

pub(crate) fn split_variable(text: &str) -> Option<(&str, &str)> {
    let text = text.trim();
    let (instance, variable) = text.split_once('.')?;
    (!instance.is_empty() && !variable.is_empty()).then_some((instance, variable))
}

pub(crate) fn unknown(instance: &str, variable: &str, fmu: &FmuFile) -> SystemError {
    if fmu.is_table() {
        let columns: Vec<&str> = fmu
            .variables
            .iter()
            .step_by(crate::data::Reading::ALL.len())
            .map(|v| v.head.name.as_str())
            .collect();
        return SystemError::Data(crate::data::DataError::NoColumn {
            file: fmu.path.clone(),
            line: 1,
            name: variable.to_string(),
            columns: columns.join(", "),
        });
    }
    let close: Vec<&str> = fmu
        .variables
        .iter()
        .map(|v| v.head.name.as_str())
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

/// The half of a stepping algorithm ([`crate::Algorithm`]) that the plan compiler consults,
/// once per compilation and before any instance exists: the order of a communication point.
pub trait Propagation: std::fmt::Debug + Send + Sync {
    /// The sets of connected inputs and re-reads of direct-feedthrough outputs at a
    /// communication point, in order, for `connections` between `instances` (an input that no
    /// connection drives is skipped). An order that cannot exist (an algebraic loop) is an
    /// error naming its variables.
    fn propagation(
        &self,
        instances: &[ResolvedInstance],
        connections: &[Connection],
    ) -> Result<Vec<PropagationStep>, SystemError>;

    /// Whether the recorded inputs and direct-feedthrough outputs of instances whose inputs are
    /// set at a communication point are read again after the propagation, so that a record
    /// holds the values of that point (true), or keep those read after the last step (false).
    fn refreshes_records(&self) -> bool;
}

/// The order in which, at a communication point, connected inputs are set and
/// direct-feedthrough outputs re-read: a topological order of the graph whose edges are
/// the connections (output → input) and the feedthrough inside each FMU (input → output
/// that depends on it). A cycle is an algebraic loop and is reported with its variables.
pub fn propagation_order(
    instances: &[ResolvedInstance],
    connections: &[Connection],
) -> Result<Vec<PropagationStep>, SystemError> {
    // Nodes: the connected inputs and the feedthrough outputs that are connection sources.
    let mut nodes: Vec<PropagationStep> = Vec::new();
    for c in connections {
        nodes.push(PropagationStep::SetInput(c.to));
        if has_feedthrough(instances, c.from) {
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
                    connections.iter().any(|c| c.from == *o && c.to == *i)
                }
                (PropagationStep::SetInput(i), PropagationStep::GetOutput(o)) => {
                    feeds_through(instances, *o, *i)
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
                    variable_name(instances, r)
                }
            })
            .collect();
        return Err(SystemError::AlgebraicLoop(stuck.join(", ")));
    }
    Ok(order)
}
