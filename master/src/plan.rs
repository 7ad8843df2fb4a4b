//! Compiling a system from names to an index plan, once.
//!
//! [`Plan::compile`] turns the names of a system (connections `"crane.x -> sensor.u[1]"`,
//! recorded variables) into indices, checking every causality and type, orders the
//! propagation at a communication point in the order the stepping algorithm gives
//! ([`Propagation::propagation`]: Gauss–Seidel the direct-feedthrough graph, Jacobi the
//! connections as given), gives every value a slot
//! in one buffer and groups the value references of one instance and type into batches,
//! so the engine's loop ([`crate::engine`]) only moves numbers.

use crate::coupling::{has_feedthrough, propagation_order, split_variable, unknown, variable_name};
use crate::coupling::{Connection, Propagation, PropagationStep, ResolvedInstance, VarRef};
use crate::description::SystemDescription;
use crate::error::SystemError;
use crate::fmu::{Causality, Interface, VarType};
use std::collections::HashMap;

/// Value references of one instance and one type, moved in one FMI call, and the buffer
/// slots their values go to (get) or come from (set).
#[derive(Debug, Clone, PartialEq)]
pub struct Transfer {
    /// Index of the instance.
    pub member: usize,
    pub var_type: VarType,
    pub vrs: Vec<u32>,
    pub slots: Vec<usize>,
    /// The index (in its FMU) of the variable of each value reference: an FMI 3.0 array
    /// element is moved with its whole array.
    pub vars: Vec<usize>,
}

/// One operation at a communication point.
#[derive(Debug, Clone, PartialEq)]
pub enum Op {
    /// Set inputs of an instance from the buffer.
    Set(Transfer),
    /// Read outputs of an instance into the buffer.
    Get(Transfer),
}

/// Appends variable `r` (of `instances`) with buffer slot `slot`, joining the last operation
/// when it is of the same kind, instance and type.
pub(crate) fn push_op(
    ops: &mut Vec<Op>,
    set: bool,
    instances: &[ResolvedInstance],
    r: VarRef,
    slot: usize,
) {
    let v = &instances[r.0].fmu.variables[r.1];
    let (member, var_type) = (r.0, v.head.var_type);
    let same = |t: &Transfer| t.member == member && t.var_type == var_type;
    let joins = match ops.last() {
        Some(Op::Set(t)) => set && same(t),
        Some(Op::Get(t)) => !set && same(t),
        None => false,
    };
    match ops.last_mut() {
        Some(Op::Set(t)) | Some(Op::Get(t)) if joins => {
            t.vrs.push(v.head.value_reference);
            t.slots.push(slot);
            t.vars.push(r.1);
        }
        _ => {
            let t = Transfer {
                member,
                var_type,
                vrs: vec![v.head.value_reference],
                slots: vec![slot],
                vars: vec![r.1],
            };
            ops.push(if set { Op::Set(t) } else { Op::Get(t) });
        }
    }
}

/// What a name in a connection or record stands for: one variable, or the elements of an
/// FMI 3.0 array named whole.
struct Resolved {
    refs: Vec<VarRef>,
    /// The array's dimensions (None: one variable).
    dimensions: Option<Vec<usize>>,
}

/// The recorded variables, in record order (three lists of one length).
#[derive(Debug, Clone, PartialEq)]
pub struct Recorded {
    pub vars: Vec<VarRef>,
    /// `instance.variable` of each.
    pub names: Vec<String>,
    /// Buffer slot of each.
    pub slots: Vec<usize>,
}

/// A system compiled to indices.
#[derive(Debug, Clone, PartialEq)]
pub struct Plan {
    /// The connections, resolved.
    pub connections: Vec<Connection>,
    /// The recorded variables.
    pub recorded: Recorded,
    /// Size of the value buffer.
    pub slot_count: usize,
    /// Per instance: the reads after its step (the values it feeds or records).
    pub after_step: Vec<Vec<Transfer>>,
    /// Sets and reads at each communication point, in order.
    pub propagation: Vec<Op>,
    /// Number of base steps from start to stop time.
    pub steps: u64,
    /// The Model Exchange instances, in groups connected to each other (each integrated as
    /// one ODE by the master).
    pub model_exchange: Vec<CoupledPlan>,
}

/// Model Exchange instances connected to each other (directly or through others of them),
/// integrated as one ODE (OMSimulator's strongly coupled system): at every evaluation of
/// the right-hand side, the outputs that feed other members are read and the connected
/// inputs set, in dependency order, before the derivatives are read.
#[derive(Debug, Clone, PartialEq)]
pub struct CoupledPlan {
    /// The instances, in the order of the system.
    pub members: Vec<usize>,
    /// The outputs feeding other members that depend on no input: read first.
    pub reads: Vec<Transfer>,
    /// The connected inputs set and the direct-feedthrough outputs re-read, in dependency
    /// order ([`crate::propagation_order`] over the connections between members).
    pub propagation: Vec<Op>,
    /// The step multiple of every member.
    pub step_multiple: u32,
    /// Whether a connection from outside the group drives an input of a member (set at
    /// every communication point: the solver starts again there).
    pub driven_from_outside: bool,
}

impl Plan {
    /// Compiles the connections and records of `d` over `instances` (loaded, in the order of
    /// `d.instances`) for `algorithm`.
    pub fn compile(
        d: &SystemDescription,
        instances: &[ResolvedInstance],
        algorithm: &dyn Propagation,
    ) -> Result<Self, SystemError> {
        let index_of: HashMap<&str, usize> = instances
            .iter()
            .enumerate()
            .map(|(i, inst)| (inst.name.as_str(), i))
            .collect();
        // A variable, or every element of an FMI 3.0 array named whole (with its dimensions).
        let lookup = |text: &str, connection: &str| -> Result<Resolved, SystemError> {
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
            if let Some(v) = fmu.index_of(var) {
                return Ok(Resolved {
                    refs: vec![(i, v)],
                    dimensions: None,
                });
            }
            let Some(array) = fmu.array(var) else {
                return Err(unknown(inst, var, fmu));
            };
            Ok(Resolved {
                refs: array.elements.iter().map(|&e| (i, e)).collect(),
                dimensions: Some(array.dimensions.clone()),
            })
        };
        let name_of = |r: VarRef| variable_name(instances, r);
        let mut connections = Vec::new();
        let mut drivers: HashMap<VarRef, String> = HashMap::new();
        for c in &d.connections {
            let Some((from, to)) = c.split_once("->") else {
                return Err(SystemError::Connection {
                    connection: c.clone(),
                    reason: "expected `instance.output -> instance.input`".into(),
                });
            };
            let (from_text, to_text) = (from.trim(), to.trim());
            let (from, to) = (lookup(from, c)?, lookup(to, c)?);
            if from.dimensions != to.dimensions {
                let shape = |d: &Option<Vec<usize>>| match d {
                    None => "a scalar (or one array element)".to_string(),
                    Some(d) => format!(
                        "an array of dimensions [{}]",
                        d.iter().map(usize::to_string).collect::<Vec<_>>().join(",")
                    ),
                };
                return Err(SystemError::Connection {
                    connection: c.clone(),
                    reason: format!(
                        "`{from_text}` is {} but `{to_text}` is {}; a whole array connects to an array of the same dimensions (or connect elements, `x[1,2]`)",
                        shape(&from.dimensions),
                        shape(&to.dimensions)
                    ),
                });
            }
            for (from, to) in from.refs.into_iter().zip(to.refs) {
                let fv = &instances[from.0].fmu.variables[from.1];
                let tv = &instances[to.0].fmu.variables[to.1];
                let fail = |reason: String| SystemError::Connection {
                    connection: c.clone(),
                    reason,
                };
                if !matches!(fv.head.causality, Causality::Output) {
                    return Err(fail(format!(
                        "`{}` has causality {:?}; a connection starts at an output",
                        name_of(from),
                        fv.head.causality
                    )));
                }
                if tv.head.causality != Causality::Input {
                    return Err(fail(format!(
                        "`{}` has causality {:?}; a connection ends at an input",
                        name_of(to),
                        tv.head.causality
                    )));
                }
                if fv.head.var_type != tv.head.var_type {
                    return Err(fail(format!(
                        "type mismatch: `{}` is {:?} but `{}` is {:?}",
                        name_of(from),
                        fv.head.var_type,
                        name_of(to),
                        tv.head.var_type
                    )));
                }
                if !fv.head.var_type.is_numeric() || fv.head.var_type == VarType::Enumeration {
                    return Err(fail(format!(
                        "{:?} connections are not supported",
                        fv.head.var_type
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
                    var_type: fv.head.var_type,
                });
            }
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
                            v.head.causality == Causality::Output && v.head.var_type.is_numeric()
                        })
                        .map(move |(j, _)| (i, j))
                })
                .collect()
        } else {
            let mut recorded: Vec<VarRef> = Vec::with_capacity(d.record.len());
            for r in &d.record {
                for v in lookup(r, &format!("record {r}"))?.refs {
                    if recorded.contains(&v) {
                        return Err(SystemError::Invalid(format!(
                            "record lists `{}` twice (a results file has one column per variable)",
                            name_of(v)
                        )));
                    }
                    recorded.push(v);
                }
            }
            recorded
        };
        // An algebraic loop between Model Exchange instances is named as one (before the
        // algorithm's order, which would name it as a loop of a communication point).
        coupled_groups(instances, &connections, &|_| 0)?;
        let order = algorithm.propagation(instances, &connections)?;
        Self::lay_out(
            d,
            instances,
            connections,
            recorded,
            &order,
            algorithm.refreshes_records(),
        )
    }

    /// This plan recording nothing: after a step only the outputs that feed connections are
    /// read (`spurio run --no-record`); an observer receives rows without values.
    pub fn without_records(
        &self,
        d: &SystemDescription,
        instances: &[ResolvedInstance],
        algorithm: &dyn Propagation,
    ) -> Result<Self, SystemError> {
        let order = algorithm.propagation(instances, &self.connections)?;
        Self::lay_out(
            d,
            instances,
            self.connections.clone(),
            Vec::new(),
            &order,
            algorithm.refreshes_records(),
        )
    }

    /// Slots, batches and the propagation for resolved connections and records.
    fn lay_out(
        d: &SystemDescription,
        instances: &[ResolvedInstance],
        connections: Vec<Connection>,
        recorded: Vec<VarRef>,
        order: &[PropagationStep],
        refresh_records: bool,
    ) -> Result<Self, SystemError> {
        // Buffer slots: every connection source and every recorded variable.
        let mut slot_of: HashMap<VarRef, usize> = HashMap::new();
        let mut slot = |r: VarRef| {
            let n = slot_of.len();
            *slot_of.entry(r).or_insert(n)
        };
        for c in &connections {
            slot(c.from);
        }
        let recorded = Recorded {
            slots: recorded.iter().map(|r| slot(*r)).collect(),
            names: recorded
                .iter()
                .map(|r| variable_name(instances, *r))
                .collect(),
            vars: recorded,
        };
        let mut by_slot: Vec<VarRef> = vec![(0, 0); slot_of.len()];
        for (r, s) in &slot_of {
            by_slot[*s] = *r;
        }
        let variable = |r: VarRef| &instances[r.0].fmu.variables[r.1];

        let after_step = (0..instances.len())
            .map(|i| {
                let mut gets: Vec<Op> = Vec::new();
                for (s, r) in by_slot.iter().enumerate() {
                    if r.0 == i {
                        push_op(&mut gets, false, instances, *r, s);
                    }
                }
                gets.into_iter()
                    .filter_map(|op| match op {
                        Op::Get(t) => Some(t),
                        Op::Set(_) => None,
                    })
                    .collect()
            })
            .collect();

        let mut propagation = Vec::new();
        for step in order {
            match *step {
                PropagationStep::SetInput(to) => {
                    let Some(c) = connections.iter().find(|c| c.to == to) else {
                        continue;
                    };
                    push_op(&mut propagation, true, instances, to, slot_of[&c.from]);
                }
                PropagationStep::GetOutput(from) => {
                    push_op(&mut propagation, false, instances, from, slot_of[&from]);
                }
            }
        }

        // Recorded inputs and direct-feedthrough outputs of instances whose inputs are set at
        // a communication point are re-read after the propagation when the algorithm asks so
        // ([`Propagation::refreshes_records`]). An output the order already re-reads (a
        // connection source) is not read again.
        let connected: Vec<usize> = if refresh_records {
            connections.iter().map(|c| c.to.0).collect()
        } else {
            Vec::new()
        };
        for r in &recorded.vars {
            let v = variable(*r);
            let refreshed = connected.contains(&r.0)
                && (v.head.causality == Causality::Input
                    || (v.head.causality == Causality::Output
                        && has_feedthrough(instances, *r)
                        && !order.contains(&PropagationStep::GetOutput(*r))));
            if refreshed {
                push_op(&mut propagation, false, instances, *r, slot_of[r]);
            }
        }

        let steps = ((d.stop_time - d.start_time) / d.step_size - 1e-9)
            .ceil()
            .max(0.0) as u64;
        let model_exchange = coupled_groups(instances, &connections, &|r| slot_of[&r])?;
        Ok(Self {
            slot_count: slot_of.len(),
            after_step,
            propagation,
            steps,
            connections,
            recorded,
            model_exchange,
        })
    }
}

/// The Model Exchange instances of `instances` in groups: two are in one group when a
/// connection joins them (directly or through other members). Each group's propagation
/// is laid out on the slots of the connections' sources; an algebraic loop between
/// members, or members of different step multiples, is an error naming them.
fn coupled_groups(
    instances: &[ResolvedInstance],
    connections: &[Connection],
    slot_of: &dyn Fn(VarRef) -> usize,
) -> Result<Vec<CoupledPlan>, SystemError> {
    let is_me = |i: usize| {
        instances[i].data.is_none() && instances[i].fmu.interface == Interface::ModelExchange
    };
    // Union–find on the instances, over the connections between two members.
    let mut root: Vec<usize> = (0..instances.len()).collect();
    fn find(root: &mut [usize], mut i: usize) -> usize {
        while root[i] != i {
            root[i] = root[root[i]];
            i = root[i];
        }
        i
    }
    for c in connections {
        if is_me(c.from.0) && is_me(c.to.0) {
            let (a, b) = (find(&mut root, c.from.0), find(&mut root, c.to.0));
            root[a.max(b)] = a.min(b);
        }
    }
    let mut groups: Vec<CoupledPlan> = Vec::new();
    for i in (0..instances.len()).filter(|&i| is_me(i)) {
        let r = find(&mut root, i);
        let first = r;
        match groups.iter_mut().find(|g| g.members[0] == first) {
            Some(g) => g.members.push(i),
            None => groups.push(CoupledPlan {
                members: vec![i],
                reads: Vec::new(),
                propagation: Vec::new(),
                step_multiple: instances[i].step_multiple,
                driven_from_outside: false,
            }),
        }
    }
    for g in &mut groups {
        let names = || {
            g.members
                .iter()
                .map(|&i| format!("`{}`", instances[i].name))
                .collect::<Vec<_>>()
                .join(", ")
        };
        if let Some(&other) = g
            .members
            .iter()
            .find(|&&i| instances[i].step_multiple != g.step_multiple)
        {
            return Err(SystemError::Invalid(format!(
                "the Model Exchange instances {} are connected to each other and integrated as one ODE, so they step together: give them one step_multiple (`{}` has {}, `{}` has {})",
                names(),
                instances[g.members[0]].name,
                g.step_multiple,
                instances[other].name,
                instances[other].step_multiple
            )));
        }
        let method = instances[g.members[0]].integration.method;
        if let Some(&other) = g
            .members
            .iter()
            .find(|&&i| instances[i].integration.method != method)
        {
            return Err(SystemError::Invalid(format!(
                "the Model Exchange instances {} are connected to each other and integrated as one ODE by one solver: give them one `solver` (`{}` has {method}, `{}` has {})",
                names(),
                instances[g.members[0]].name,
                instances[other].name,
                instances[other].integration.method
            )));
        }
        g.driven_from_outside = connections
            .iter()
            .any(|c| g.members.contains(&c.to.0) && !g.members.contains(&c.from.0));
        let inner: Vec<Connection> = connections
            .iter()
            .filter(|c| g.members.contains(&c.from.0) && g.members.contains(&c.to.0))
            .copied()
            .collect();
        let order = propagation_order(instances, &inner).map_err(|e| match e {
            SystemError::AlgebraicLoop(variables) => SystemError::ModelExchangeLoop {
                instances: names(),
                variables,
            },
            other => other,
        })?;
        let mut reads = Vec::new();
        for c in &inner {
            let source = c.from;
            let read = !has_feedthrough(instances, source)
                && !reads.iter().any(|op| match op {
                    Op::Get(t) => t.member == source.0 && t.vars.contains(&source.1),
                    Op::Set(_) => false,
                });
            if read {
                push_op(&mut reads, false, instances, source, slot_of(source));
            }
        }
        g.reads = reads
            .into_iter()
            .filter_map(|op| match op {
                Op::Get(t) => Some(t),
                Op::Set(_) => None,
            })
            .collect();
        for step in order {
            match step {
                PropagationStep::SetInput(to) => {
                    if let Some(c) = inner.iter().find(|c| c.to == to) {
                        push_op(&mut g.propagation, true, instances, to, slot_of(c.from));
                    }
                }
                PropagationStep::GetOutput(from) => {
                    push_op(&mut g.propagation, false, instances, from, slot_of(from));
                }
            }
        }
    }
    Ok(groups)
}
