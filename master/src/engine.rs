//! The stepping loop: fixed-step Gauss–Seidel or Jacobi, multirate, by index.
//!
//! Setup ([`Simulation::new`]) instantiates every instance on the calling thread, sets start
//! values by value reference, initialises, and turns the system's names into batches of value
//! references and buffer slots. The loop then only moves numbers:
//!
//! 1. at each communication point t_k, the connected inputs are set from their sources (for
//!    Gauss–Seidel in the order of the direct-feedthrough graph, re-reading feedthrough outputs
//!    as their inputs change, so values flow through sensors and estimators within the same
//!    point; for Jacobi from the values read after the previous step);
//! 2. the recorded variables are sent to the observer;
//! 3. every instance whose multiple divides k steps over `multiple · h`; its outputs are read
//!    at the communication point where that step ends (a multirate instance holds its outputs
//!    in between).
//!
//! `fmi2Discard` and `fmi2Error` stop the run with an error naming the instance, the FMU file,
//! the call and the time, quoting what the FMU logged.

use crate::fmu::{Causality, LoadError, VarType};
use crate::record::Observer;
use crate::system::{Algorithm, PropagationStep, System, SystemError, VarRef};
use fmi::fmi2::instance::{CoSimulation, Common, InstanceCS};
use fmi::fmi2::Fmi2Error;
use fmi::traits::FmiInstance;
use std::collections::HashMap;
use std::time::{Duration, Instant};

/// Why a run stopped.
#[derive(Debug, thiserror::Error)]
pub enum RunError {
    #[error(transparent)]
    Load(#[from] LoadError),
    #[error(transparent)]
    System(#[from] SystemError),
    #[error("instance `{instance}` ({file}): {call} returned {status} at t = {time}{log}")]
    Fmi {
        instance: String,
        file: String,
        call: &'static str,
        status: String,
        time: f64,
        log: String,
    },
    #[error("writing results: {0}")]
    Output(#[from] std::io::Error),
}

/// A group of variables of one instance and one type, moved in one FMI call.
#[derive(Debug, Clone)]
struct Batch {
    member: usize,
    var_type: VarType,
    vrs: Vec<u32>,
    /// Buffer slots: where read values go (get) or where set values come from (set).
    slots: Vec<usize>,
    reals: Vec<f64>,
    integers: Vec<i32>,
}

impl Batch {
    fn new(member: usize, var_type: VarType) -> Self {
        Self {
            member,
            var_type,
            vrs: Vec::new(),
            slots: Vec::new(),
            reals: Vec::new(),
            integers: Vec::new(),
        }
    }

    fn push(&mut self, vr: u32, slot: usize) {
        self.vrs.push(vr);
        self.slots.push(slot);
        self.reals.push(0.0);
        self.integers.push(0);
    }

    fn get(&mut self, inst: &mut InstanceCS, buffer: &mut [f64]) -> Result<(), Fmi2Error> {
        match self.var_type {
            VarType::Real => {
                Common::get_real(inst, &self.vrs, &mut self.reals)?;
                for (slot, v) in self.slots.iter().zip(&self.reals) {
                    buffer[*slot] = *v;
                }
            }
            VarType::Boolean => {
                Common::get_boolean(inst, &self.vrs, &mut self.integers)?;
                for (slot, v) in self.slots.iter().zip(&self.integers) {
                    buffer[*slot] = f64::from(u8::from(*v != 0));
                }
            }
            _ => {
                Common::get_integer(inst, &self.vrs, &mut self.integers)?;
                for (slot, v) in self.slots.iter().zip(&self.integers) {
                    buffer[*slot] = f64::from(*v);
                }
            }
        }
        Ok(())
    }

    fn set(&mut self, inst: &mut InstanceCS, buffer: &[f64]) -> Result<(), Fmi2Error> {
        match self.var_type {
            VarType::Real => {
                for (v, slot) in self.reals.iter_mut().zip(&self.slots) {
                    *v = buffer[*slot];
                }
                Common::set_real(inst, &self.vrs, &self.reals)?;
            }
            VarType::Boolean => {
                for (v, slot) in self.integers.iter_mut().zip(&self.slots) {
                    *v = i32::from(buffer[*slot] != 0.0);
                }
                Common::set_boolean(inst, &self.vrs, &self.integers)?;
            }
            _ => {
                for (v, slot) in self.integers.iter_mut().zip(&self.slots) {
                    *v = buffer[*slot] as i32;
                }
                Common::set_integer(inst, &self.vrs, &self.integers)?;
            }
        }
        Ok(())
    }
}

#[derive(Debug, Clone)]
enum Op {
    Set(Batch),
    Get(Batch),
}

struct Member {
    name: String,
    file: String,
    instance: InstanceCS,
    multiple: u64,
    /// Gets after this member's step (its slots).
    after_step: Vec<Batch>,
}

/// Options of a run.
#[derive(Debug, Clone, Default)]
pub struct RunOptions {
    /// Pace the simulation to wall-clock time divided by this factor (1 = real time).
    pub real_time_factor: Option<f64>,
    /// Show a progress bar on standard error.
    pub progress: bool,
}

/// A system ready to run: instances created, names resolved to indices.
pub struct Simulation {
    members: Vec<Member>,
    /// Set/get operations at each communication point.
    propagation: Vec<Op>,
    buffer: Vec<f64>,
    record_names: Vec<String>,
    record_slots: Vec<usize>,
    record_values: Vec<f64>,
    start_time: f64,
    stop_time: f64,
    step_size: f64,
    steps: u64,
}

fn fmi_error(name: &str, file: &str, call: &'static str, e: Fmi2Error, time: f64) -> RunError {
    let said = crate::logging::recent_messages(name);
    RunError::Fmi {
        instance: name.to_string(),
        file: file.to_string(),
        call,
        status: match e {
            Fmi2Error::Discard => "fmi2Discard".into(),
            Fmi2Error::Error => "fmi2Error".into(),
            Fmi2Error::Fatal => "fmi2Fatal".into(),
            other => other.to_string(),
        },
        time,
        log: if said.is_empty() {
            String::new()
        } else {
            format!(" (the FMU logged: {})", said.join("; "))
        },
    }
}

/// Groups consecutive operations of the same kind, member and type into one batch.
fn push_op(ops: &mut Vec<Op>, set: bool, member: usize, var_type: VarType, vr: u32, slot: usize) {
    let same = |b: &Batch| b.member == member && b.var_type == var_type;
    match ops.last_mut() {
        Some(Op::Set(b)) if set && same(b) => b.push(vr, slot),
        Some(Op::Get(b)) if !set && same(b) => b.push(vr, slot),
        _ => {
            let mut b = Batch::new(member, var_type);
            b.push(vr, slot);
            ops.push(if set { Op::Set(b) } else { Op::Get(b) });
        }
    }
}

impl Simulation {
    /// Instantiates and initialises every instance of `system` on this thread.
    pub fn new(system: &System) -> Result<Self, RunError> {
        // Buffer slots: every connection source and every recorded variable.
        let mut slot_of: HashMap<VarRef, usize> = HashMap::new();
        let slot = |r: VarRef, slot_of: &mut HashMap<VarRef, usize>| {
            let n = slot_of.len();
            *slot_of.entry(r).or_insert(n)
        };
        for c in &system.connections {
            slot(c.from, &mut slot_of);
        }
        let record_slots: Vec<usize> = system
            .recorded
            .iter()
            .map(|r| slot(*r, &mut slot_of))
            .collect();
        let mut by_slot: Vec<VarRef> = vec![(0, 0); slot_of.len()];
        for (r, s) in &slot_of {
            by_slot[*s] = *r;
        }

        let mut members = Vec::with_capacity(system.instances.len());
        for (i, spec) in system.instances.iter().enumerate() {
            let fmu = &spec.fmu;
            let mut instance = fmu.instantiate(&spec.name, spec.logging)?;
            let mut m = Member {
                name: spec.name.clone(),
                file: fmu.path.display().to_string(),
                instance: {
                    Common::setup_experiment(
                        &mut instance,
                        None,
                        system.start_time,
                        Some(system.stop_time),
                    )
                    .map_err(|e| RunError::Fmi {
                        instance: spec.name.clone(),
                        file: fmu.path.display().to_string(),
                        call: "fmi2SetupExperiment",
                        status: e.to_string(),
                        time: system.start_time,
                        log: String::new(),
                    })?;
                    instance
                },
                multiple: u64::from(spec.step_multiple),
                after_step: Vec::new(),
            };
            for (index, value) in &spec.start_values {
                let v = &fmu.variables[*index];
                let mut b = Batch::new(i, v.var_type);
                b.push(v.value_reference, 0);
                b.set(&mut m.instance, &[*value]).map_err(|e| {
                    fmi_error(
                        &m.name,
                        &m.file,
                        "fmi2Set* (start value)",
                        e,
                        system.start_time,
                    )
                })?;
            }
            Common::enter_initialization_mode(&mut m.instance).map_err(|e| {
                fmi_error(
                    &m.name,
                    &m.file,
                    "fmi2EnterInitializationMode",
                    e,
                    system.start_time,
                )
            })?;
            let mut gets: Vec<Op> = Vec::new();
            for (s, r) in by_slot.iter().enumerate() {
                if r.0 == i {
                    let v = &fmu.variables[r.1];
                    push_op(&mut gets, false, i, v.var_type, v.value_reference, s);
                }
            }
            m.after_step = gets
                .into_iter()
                .filter_map(|op| match op {
                    Op::Get(b) => Some(b),
                    Op::Set(_) => None,
                })
                .collect();
            members.push(m);
        }

        let mut propagation = Vec::new();
        let steps: Vec<PropagationStep> = match system.algorithm {
            Algorithm::GaussSeidel => system.propagation_order()?,
            Algorithm::Jacobi => system
                .connections
                .iter()
                .map(|c| PropagationStep::SetInput(c.to))
                .collect(),
        };
        for step in steps {
            match step {
                PropagationStep::SetInput(to) => {
                    let Some(c) = system.connections.iter().find(|c| c.to == to) else {
                        continue;
                    };
                    let v = &system.instances[to.0].fmu.variables[to.1];
                    push_op(
                        &mut propagation,
                        true,
                        to.0,
                        v.var_type,
                        v.value_reference,
                        slot_of[&c.from],
                    );
                }
                PropagationStep::GetOutput(from) => {
                    let v = &system.instances[from.0].fmu.variables[from.1];
                    push_op(
                        &mut propagation,
                        false,
                        from.0,
                        v.var_type,
                        v.value_reference,
                        slot_of[&from],
                    );
                }
            }
        }

        // Gauss–Seidel: recorded inputs and direct-feedthrough outputs of instances whose
        // inputs are set at a communication point are re-read after the propagation, so that
        // a record holds the values that belong to that point (e.g. a Sensor's `y_clean`,
        // which feeds no connection, for the input just set) rather than those read after the
        // last step. Jacobi keeps the values read after the step, as fmpy's SSP runner does.
        let connected: Vec<usize> = match system.algorithm {
            Algorithm::GaussSeidel => system.connections.iter().map(|c| c.to.0).collect(),
            Algorithm::Jacobi => Vec::new(),
        };
        for r in &system.recorded {
            let v = &system.instances[r.0].fmu.variables[r.1];
            let refreshed = connected.contains(&r.0)
                && (v.causality == Causality::Input
                    || (v.causality == Causality::Output && system.has_feedthrough(*r)));
            if refreshed {
                push_op(
                    &mut propagation,
                    false,
                    r.0,
                    v.var_type,
                    v.value_reference,
                    slot_of[r],
                );
            }
        }

        let steps = ((system.stop_time - system.start_time) / system.step_size - 1e-9)
            .ceil()
            .max(0.0) as u64;
        let mut sim = Self {
            members,
            propagation,
            buffer: vec![0.0; slot_of.len()],
            record_names: system
                .recorded
                .iter()
                .map(|r| system.variable_name(*r))
                .collect(),
            record_slots,
            record_values: vec![0.0; system.recorded.len()],
            start_time: system.start_time,
            stop_time: system.stop_time,
            step_size: system.step_size,
            steps,
        };
        // Initial values flow through the connections in initialization mode, then every
        // instance leaves it.
        let t0 = sim.start_time;
        for m in &mut sim.members {
            for b in &mut m.after_step {
                b.get(&mut m.instance, &mut sim.buffer).map_err(|e| {
                    fmi_error(&m.name, &m.file, "fmi2Get* (initial outputs)", e, t0)
                })?;
            }
        }
        sim.propagate(0, true)?;
        for m in &mut sim.members {
            Common::exit_initialization_mode(&mut m.instance)
                .map_err(|e| fmi_error(&m.name, &m.file, "fmi2ExitInitializationMode", e, t0))?;
        }
        for m in &mut sim.members {
            for b in &mut m.after_step {
                b.get(&mut m.instance, &mut sim.buffer).map_err(|e| {
                    fmi_error(&m.name, &m.file, "fmi2Get* (initial outputs)", e, t0)
                })?;
            }
        }
        Ok(sim)
    }

    /// The names of the recorded variables.
    pub fn recorded_names(&self) -> &[String] {
        &self.record_names
    }

    /// Number of base steps the run takes.
    pub fn step_count(&self) -> u64 {
        self.steps
    }

    fn propagate(&mut self, k: u64, all: bool) -> Result<(), RunError> {
        let time = self.start_time + k as f64 * self.step_size;
        for op in &mut self.propagation {
            let (batch, set) = match op {
                Op::Set(b) => (b, true),
                Op::Get(b) => (b, false),
            };
            let m = &mut self.members[batch.member];
            if !all && !k.is_multiple_of(m.multiple) {
                continue;
            }
            let result = if set {
                batch.set(&mut m.instance, &self.buffer)
            } else {
                batch.get(&mut m.instance, &mut self.buffer)
            };
            result.map_err(|e| {
                fmi_error(
                    &m.name,
                    &m.file,
                    if set { "fmi2Set*" } else { "fmi2Get*" },
                    e,
                    time,
                )
            })?;
        }
        Ok(())
    }

    /// Reads the outputs of the instances whose step ends at base step `k` (all for k = 0).
    fn read_outputs(&mut self, k: u64, time: f64) -> Result<(), RunError> {
        for m in &mut self.members {
            if !k.is_multiple_of(m.multiple) {
                continue;
            }
            for b in &mut m.after_step {
                b.get(&mut m.instance, &mut self.buffer)
                    .map_err(|e| fmi_error(&m.name, &m.file, "fmi2Get*", e, time))?;
            }
        }
        Ok(())
    }

    fn record(&mut self, observer: &mut dyn Observer, time: f64) -> Result<(), RunError> {
        for (v, s) in self.record_values.iter_mut().zip(&self.record_slots) {
            *v = self.buffer[*s];
        }
        observer.sample(time, &self.record_values)?;
        Ok(())
    }

    /// Runs to the stop time, sending the recorded variables to `observer` at every
    /// communication point (start time included).
    pub fn run(
        &mut self,
        observer: &mut dyn Observer,
        options: &RunOptions,
    ) -> Result<(), RunError> {
        observer.start(&self.record_names)?;
        let progress = options.progress.then(|| {
            let bar = indicatif::ProgressBar::new(self.steps);
            bar.set_style(
                indicatif::ProgressStyle::with_template(
                    "{bar:40} {pos}/{len} steps {elapsed_precise} (eta {eta})",
                )
                .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
            );
            bar
        });
        let wall_start = Instant::now();
        for k in 0..self.steps {
            let time = self.start_time + k as f64 * self.step_size;
            if k > 0 {
                // An instance's outputs are published at the communication point its step
                // reaches (a multirate instance holds them in between).
                self.read_outputs(k, time)?;
            }
            self.propagate(k, false)?;
            self.record(observer, time)?;
            for m in &mut self.members {
                if !k.is_multiple_of(m.multiple) {
                    continue;
                }
                let h = (self.step_size * m.multiple as f64).min(self.stop_time - time);
                m.instance
                    .do_step(time, h, true)
                    .map_err(|e| fmi_error(&m.name, &m.file, "fmi2DoStep", e, time))?;
            }
            if let Some(factor) = options.real_time_factor {
                let due =
                    Duration::from_secs_f64((time + self.step_size - self.start_time) / factor);
                if let Some(wait) = due.checked_sub(wall_start.elapsed()) {
                    std::thread::sleep(wait);
                }
            }
            if let Some(bar) = &progress {
                bar.inc(1);
            }
        }
        let end = self.start_time + self.steps as f64 * self.step_size;
        // Every instance's last step ends at the stop time.
        self.read_outputs(0, end)?;
        self.propagate(self.steps, true)?;
        self.record(observer, end.min(self.stop_time))?;
        if let Some(bar) = progress {
            bar.finish_and_clear();
        }
        observer.finish()?;
        Ok(())
    }

    /// Terminates every instance (they are freed when the simulation is dropped).
    pub fn terminate(&mut self) -> Result<(), RunError> {
        let t = self.stop_time;
        for m in &mut self.members {
            FmiInstance::terminate(&mut m.instance)
                .map_err(|e| fmi_error(&m.name, &m.file, "fmi2Terminate", e, t))?;
        }
        Ok(())
    }
}
