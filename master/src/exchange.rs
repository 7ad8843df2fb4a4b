//! The instances of a running system and the values they exchange: every FMI call of a run
//! goes through here. [`Exchange`] holds the instances (members), the value buffer and the
//! compiled set/get batches of the [`Plan`]; a stepping algorithm ([`crate::algorithm`]) drives
//! it through the operations of a communication point: read the outputs of the instances whose
//! step ended, propagate values along the connections, step the instances that are due.
//!
//! Every operation calls every member it concerns and then reports every failure at once
//! ([`RunError::Fmi`] names each failing instance, its FMU, the call and the time, quoting
//! what that instance logged).

use crate::batch::{Batch, Unit};
use crate::coupled::{Coupled, Members};
use crate::coupling::ResolvedInstance;
use crate::data::{Cursor, DataTable, Reading};
use crate::error::{FmiFailure, RunError, SystemError};
use crate::fmu::{CallError, Experiment, FmiVersion, Interface, StepEnd, StepProblem};
use crate::monitor::{watched, CallMonitor};
use crate::plan::{push_op, Op, Plan, Transfer};
use std::sync::Arc;

enum Step {
    Set(Batch),
    Get(Batch),
}

struct Member {
    /// Its index in the system (for the call monitor).
    index: usize,
    monitor: Option<Arc<CallMonitor>>,
    name: String,
    file: String,
    instance: Unit,
    multiple: u64,
    /// Gets after this member's step (its slots).
    after_step: Vec<Batch>,
    /// The values last given to each array of the FMU (start values at first): an element
    /// is set with its whole array.
    held: Vec<Vec<f64>>,
}

impl Member {
    /// Reads this member's outputs into the buffer.
    #[inline]
    fn read(&mut self, buffer: &mut [f64], time: f64) -> Result<(), CallError> {
        let (monitor, index) = (self.monitor.as_deref(), self.index);
        for b in &mut self.after_step {
            watched(monitor, index, "fmi2Get*", time, || {
                b.get(&mut self.instance, buffer)
            })?;
        }
        Ok(())
    }

    /// Runs `f` on this member's instance as FMI call `call` at `time`, noted in the
    /// monitor.
    #[inline]
    fn call<T>(&mut self, call: &'static str, time: f64, f: impl FnOnce(&mut Unit) -> T) -> T {
        let instance = &mut self.instance;
        watched(self.monitor.as_deref(), self.index, call, time, || {
            f(instance)
        })
    }

    /// A failed call `call` (named by its FMI 2.0 name; an FMI 3.0 instance says its own).
    fn failure(&self, call: &'static str, e: CallError, time: f64) -> FmiFailure {
        FmiFailure {
            instance: self.name.clone(),
            file: self.file.clone(),
            call: self.instance.version().call_name(call),
            status: e.0,
            time,
            log: self
                .instance
                .log()
                .failure_note()
                .map(|note| format!(" ({note})"))
                .unwrap_or_default(),
        }
    }
}

impl Members for [Member] {
    fn unit(&mut self, position: usize) -> (&mut Unit, &mut [Vec<f64>]) {
        let m = &mut self[position];
        (&mut m.instance, &mut m.held)
    }

    fn name(&self, position: usize) -> &str {
        &self[position].name
    }
}

/// A data instance of a running system: its table, where its reader is, and the buffer slot
/// of each of its read outputs (the column and the reading). It is read at every
/// communication point (the value at t_k); it is not stepped.
struct Source {
    table: Arc<DataTable>,
    cursor: Cursor,
    /// (slot, column, reading).
    slots: Vec<(usize, usize, Reading)>,
}

impl Source {
    /// The source reading `table` into the slots of the plan's reads `after_step` (variable
    /// 3j + r is column j read as `Reading::ALL[r]`: [`FmuFile::table`]).
    fn new(table: Arc<DataTable>, after_step: &[Transfer]) -> Self {
        let n = Reading::ALL.len();
        let slots = after_step
            .iter()
            .flat_map(|t| t.slots.iter().zip(&t.vars))
            .map(|(&slot, &var)| (slot, var / n, Reading::ALL[var % n]))
            .collect();
        Self {
            table,
            cursor: Cursor::default(),
            slots,
        }
    }

    /// Writes the table's values at `time` into the buffer.
    #[inline]
    fn read(&mut self, buffer: &mut [f64], time: f64) {
        self.table.seek(&mut self.cursor, time);
        for &(slot, column, reading) in &self.slots {
            buffer[slot] = self.table.reading(self.cursor, column, reading, time);
        }
    }
}

/// Reads every source at `time`.
#[inline(always)]
fn read_sources(sources: &mut [Source], buffer: &mut [f64], time: f64) {
    for s in sources {
        s.read(buffer, time);
    }
}

/// Calls `call` on every member (that `due` selects), then reports every failure at once.
#[inline(always)]
fn on_every(
    members: &mut [Member],
    due: impl Fn(&Member) -> bool,
    mut call: impl FnMut(&mut Member) -> Result<(), FmiFailure>,
) -> Result<(), RunError> {
    // A plain loop: the list of failures exists only once there is one (this runs at every
    // communication point).
    let mut failures = Vec::new();
    for m in members.iter_mut() {
        if due(m) {
            if let Err(f) = call(m) {
                failures.push(f);
            }
        }
    }
    if failures.is_empty() {
        Ok(())
    } else {
        Err(RunError::Fmi { failures })
    }
}

/// Whether something done every `multiple` base steps is due at base step `k`: the common
/// single-rate case (`multiple` = 1) without a division.
#[inline]
pub(crate) fn due_at(k: u64, multiple: u64) -> bool {
    multiple == 1 || k.is_multiple_of(multiple)
}

/// Calls the FMI function `call` (`name`) at `time` on every member's instance, then reports
/// every failure at once.
fn call_every<T>(
    members: &mut [Member],
    name: &'static str,
    time: f64,
    call: impl Fn(&mut Unit) -> Result<T, CallError>,
) -> Result<(), RunError> {
    on_every(
        members,
        |_| true,
        |m| {
            m.call(name, time, &call)
                .map(|_| ())
                .map_err(|e| m.failure(name, e, time))
        },
    )
}

/// The outcome of one step of every due member ([`Exchange::step_due`]).
#[derive(Debug, Clone, PartialEq)]
pub enum StepOutcome {
    /// Every due member completed its step.
    Completed,
    /// (instance, last successful time, its version, its interface) of every member that
    /// asked to end the run (of a Model Exchange group: its first member).
    Terminated(Vec<(String, f64, FmiVersion, Interface)>),
}

/// The instances of a running system, the value buffer and the compiled transfers between
/// them, with the operations a stepping algorithm composes. Base step `k` begins at the
/// communication point t_k = start + k·h; a member of step multiple m steps over m·h at every
/// k that m divides.
pub struct Exchange {
    /// The FMU instances (a batch's `member` is a position here).
    members: Vec<Member>,
    /// The data instances.
    sources: Vec<Source>,
    /// The Model Exchange instances in their groups, each integrated as one ODE.
    coupled: Vec<Coupled>,
    /// Set/get operations at each communication point.
    propagation: Vec<Step>,
    buffer: Vec<f64>,
    start_time: f64,
    stop_time: f64,
    step_size: f64,
    steps: u64,
}

impl Exchange {
    /// Instantiates every instance of `instances` on this thread, sets up the experiment
    /// [`start_time`, `stop_time`], sets the start values (grouped by type into calls, an
    /// array's elements in one) and enters initialisation mode, noting every FMI call in
    /// `monitor` (if any).
    pub(crate) fn instantiate(
        instances: &[ResolvedInstance],
        plan: &Plan,
        (start_time, stop_time, step_size): (f64, f64, f64),
        monitor: Option<Arc<CallMonitor>>,
    ) -> Result<Self, RunError> {
        let t0 = start_time;
        if let Some(m) = &monitor {
            m.name_instances(
                instances
                    .iter()
                    .map(|i| (i.name.clone(), i.fmu.path.display().to_string()))
                    .collect(),
            );
        }
        let mut members = Vec::with_capacity(instances.len());
        let mut sources = Vec::new();
        // The position among the members of each instance (a data instance has none).
        let mut position = vec![usize::MAX; instances.len()];
        for (i, spec) in instances.iter().enumerate() {
            if let Some(table) = &spec.data {
                sources.push(Source::new(table.clone(), &plan.after_step[i]));
                continue;
            }
            position[i] = members.len();
            let fmu = &spec.fmu;
            let me = fmu.interface == Interface::ModelExchange;
            let instance = watched(monitor.as_deref(), i, "fmi2Instantiate", t0, || {
                if me {
                    let instance = fmu.instantiate_model_exchange(&spec.name, spec.logging);
                    instance.map(Unit::Me)
                } else {
                    fmu.instantiate(&spec.name, spec.logging).map(Unit::Cs)
                }
            })
            .map_err(SystemError::from)?;
            let mut m = Member {
                index: i,
                monitor: monitor.clone(),
                name: spec.name.clone(),
                file: fmu.path.display().to_string(),
                instance,
                multiple: u64::from(spec.step_multiple),
                after_step: plan.after_step[i]
                    .iter()
                    .map(|t| Batch::new(t, fmu))
                    .collect(),
                held: fmu
                    .arrays
                    .iter()
                    .map(|a| {
                        a.elements
                            .iter()
                            .map(|&e| fmu.variables[e].start.unwrap_or(0.0))
                            .collect()
                    })
                    .collect(),
            };
            let experiment = Experiment {
                tolerance: me.then_some(spec.integration.tolerance),
                start: t0,
                stop: Some(stop_time),
            };
            m.call("fmi2SetupExperiment", t0, |inst| {
                inst.setup_experiment(experiment)
            })
            .map_err(|e| m.failure("fmi2SetupExperiment", e, t0))?;
            // Start values, grouped by type into calls (an array's elements in one).
            let mut sets = Vec::new();
            let mut values = Vec::with_capacity(spec.start_values.len());
            for (index, value) in &spec.start_values {
                push_op(&mut sets, true, instances, (i, *index), values.len());
                values.push(*value);
            }
            for op in &sets {
                if let Op::Set(t) = op {
                    let mut batch = Batch::new(t, fmu);
                    watched(
                        m.monitor.as_deref(),
                        m.index,
                        "fmi2Set* (start value)",
                        t0,
                        || batch.set(&mut m.instance, &values, &mut m.held),
                    )
                    .map_err(|e| m.failure("fmi2Set* (start value)", e, t0))?;
                }
            }
            m.call("fmi2EnterInitializationMode", t0, |inst| {
                inst.enter_initialization_mode(experiment)
            })
            .map_err(|e| m.failure("fmi2EnterInitializationMode", e, t0))?;
            members.push(m);
        }
        let mut coupled = Vec::with_capacity(plan.model_exchange.len());
        for group in &plan.model_exchange {
            let made = Coupled::new(
                group,
                instances,
                &position,
                members.as_mut_slice(),
                (t0, stop_time),
            );
            let first = &members[position[group.members[0]]];
            coupled.push(made.map_err(|e| first.failure("fmi2Instantiate", e, t0))?);
        }
        Ok(Self {
            members,
            coupled,
            propagation: plan
                .propagation
                .iter()
                .map(|op| {
                    let (Op::Set(t) | Op::Get(t)) = op;
                    let mut batch = Batch::new(t, &instances[t.member].fmu);
                    batch.member = position[t.member];
                    match op {
                        Op::Set(_) => Step::Set(batch),
                        Op::Get(_) => Step::Get(batch),
                    }
                })
                .collect(),
            sources,
            buffer: vec![0.0; plan.slot_count],
            start_time,
            stop_time,
            step_size,
            steps: plan.steps,
        })
    }

    /// Number of base steps from the start to the stop time.
    #[inline]
    pub fn steps(&self) -> u64 {
        self.steps
    }

    /// The communication point t_k at which base step `k` begins.
    #[inline]
    pub fn time_of(&self, k: u64) -> f64 {
        self.start_time + k as f64 * self.step_size
    }

    /// The value buffer (every connection source and recorded variable has a slot).
    #[inline]
    pub(crate) fn buffer(&self) -> &[f64] {
        &self.buffer
    }

    /// Reads every member's outputs at `time`, noting the reads as FMI call `call`.
    pub fn read_all(&mut self, call: &'static str, time: f64) -> Result<(), RunError> {
        let buffer = &mut self.buffer;
        read_sources(&mut self.sources, buffer, time);
        on_every(
            &mut self.members,
            |_| true,
            |m| m.read(buffer, time).map_err(|e| m.failure(call, e, time)),
        )
    }

    /// Reads the outputs of the members whose step ends at base step `k` (every member for
    /// k = 0) at `time`; a member none of whose outputs is connected or recorded is not called.
    #[inline(always)]
    pub fn read_outputs(&mut self, k: u64, time: f64) -> Result<(), RunError> {
        let buffer = &mut self.buffer;
        read_sources(&mut self.sources, buffer, time);
        on_every(
            &mut self.members,
            |m| !m.after_step.is_empty() && due_at(k, m.multiple),
            |m| {
                m.read(buffer, time)
                    .map_err(|e| m.failure("fmi2Get*", e, time))
            },
        )
    }

    /// The propagation of the plan at base step `k`: the connected inputs set from their
    /// sources' slots and the direct-feedthrough outputs re-read, in the algorithm's order;
    /// for the members due at `k` (every member when `all`).
    #[inline(always)]
    pub fn propagate(&mut self, k: u64, all: bool) -> Result<(), RunError> {
        let time = self.time_of(k);
        for op in &mut self.propagation {
            let (batch, set) = match op {
                Step::Set(b) => (b, true),
                Step::Get(b) => (b, false),
            };
            let m = &mut self.members[batch.member];
            if !all && !due_at(k, m.multiple) {
                continue;
            }
            let call = if set { "fmi2Set*" } else { "fmi2Get*" };
            let buffer = &mut self.buffer;
            let result = watched(m.monitor.as_deref(), m.index, call, time, || {
                if set {
                    batch.set(&mut m.instance, buffer, &mut m.held)
                } else {
                    batch.get(&mut m.instance, buffer)
                }
            });
            result.map_err(|e| m.failure(call, e, time))?;
        }
        Ok(())
    }

    /// Every member leaves initialisation mode at `time`; the Model Exchange ones then
    /// iterate their first event and enter continuous-time mode, group by group.
    pub fn exit_initialization_mode(&mut self, time: f64) -> Result<(), RunError> {
        call_every(
            &mut self.members,
            "fmi2ExitInitializationMode",
            time,
            Unit::exit_initialization_mode,
        )?;
        for group in &mut self.coupled {
            let members = self.members.as_mut_slice();
            let first = group.first_position();
            let (monitor, index) = (members[first].monitor.clone(), members[first].index);
            watched(
                monitor.as_deref(),
                index,
                "fmi2NewDiscreteStates (first event iteration)",
                time,
                || group.initialise(members, &mut self.buffer, time),
            )?;
        }
        Ok(())
    }

    /// Terminates every member at `time` (they are freed when dropped).
    pub(crate) fn terminate(&mut self, time: f64) -> Result<(), RunError> {
        call_every(&mut self.members, "fmi2Terminate", time, Unit::terminate)
    }

    /// `fmi2DoStep`/`fmi3DoStep` on every member due at base step `k` (beginning at `time`),
    /// over its multiple of the step size and not past the stop time: every failure is
    /// reported at once; members that ask to end the run (`fmi2Discard` with
    /// `fmi2Terminated`, `terminateSimulation`) are listed.
    #[inline(always)]
    pub fn step_due(&mut self, k: u64, time: f64) -> Result<StepOutcome, RunError> {
        let (step_size, stop_time) = (self.step_size, self.stop_time);
        let mut failures = Vec::new();
        let mut terminated = Vec::new();
        let co_simulation = |m: &&mut Member| matches!(m.instance, Unit::Cs(_));
        for m in self
            .members
            .iter_mut()
            .filter(|m| due_at(k, m.multiple))
            .filter(co_simulation)
        {
            let h = (step_size * m.multiple as f64).min(stop_time - time);
            let step = |unit: &mut Unit| match unit {
                Unit::Cs(instance) => instance.do_step(time, h),
                Unit::Me(_) => Ok(StepEnd::Completed),
            };
            match m.call("fmi2DoStep", time, step) {
                Ok(StepEnd::Completed) => {}
                Ok(StepEnd::Terminate(last)) => {
                    // FMI 2.0 stopped within the step (fmi2Discard); FMI 3.0 completed it
                    // unless it says otherwise.
                    let version = m.instance.version();
                    let fallback = match version {
                        FmiVersion::Fmi2 => time,
                        FmiVersion::Fmi3 => time + h,
                    };
                    let end = last.unwrap_or(fallback);
                    terminated.push((m.name.clone(), end, version, Interface::CoSimulation));
                }
                Err(StepProblem::Failed(e)) => failures.push(m.failure("fmi2DoStep", e, time)),
                Err(StepProblem::EarlyReturn {
                    last_successful_time,
                }) => failures.push(m.failure(
                    "fmi2DoStep",
                    CallError(format!(
                        "earlyReturn = true (lastSuccessfulTime = {last_successful_time}), \
                         although this master instantiates without early return"
                    )),
                    time,
                )),
                Err(StepProblem::EventHandlingNeeded) => failures.push(
                    m.failure(
                        "fmi2DoStep",
                        CallError(
                            "eventHandlingNeeded = true, although the FMU was instantiated with \
                         eventModeUsed = false (its CoSimulation does not declare \
                         hasEventMode=\"true\")"
                                .into(),
                        ),
                        time,
                    ),
                ),
                Err(StepProblem::Event {
                    call,
                    error,
                    time: at,
                }) => failures.push(m.failure(call, error, at)),
            }
        }
        if !failures.is_empty() {
            return Err(RunError::Fmi { failures });
        }
        // The Model Exchange groups, integrated over the same interval with their inputs
        // held as set at `time`.
        for group in self.coupled.iter_mut().filter(|g| due_at(k, g.multiple)) {
            let h = (step_size * group.multiple as f64).min(stop_time - time);
            let members = self.members.as_mut_slice();
            let first = group.first_position();
            let (monitor, index) = (members[first].monitor.clone(), members[first].index);
            let buffer = &mut self.buffer;
            let end = watched(
                monitor.as_deref(),
                index,
                "Model Exchange integration",
                time,
                || group.advance_to(members, buffer, time + h),
            )?;
            if let Some(end) = end {
                let m = &members[first];
                let version = m.instance.version();
                terminated.push((m.name.clone(), end, version, Interface::ModelExchange));
            }
        }
        Ok(if terminated.is_empty() {
            StepOutcome::Completed
        } else {
            StepOutcome::Terminated(terminated)
        })
    }
}
