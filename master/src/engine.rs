//! The stepping loop: fixed-step Gauss–Seidel or Jacobi, multirate, by index.
//!
//! [`Simulation::new`] instantiates every instance on the calling thread, sets start values
//! by value reference, initialises, and follows the system's compiled [`Plan`] (names were
//! turned into value references and buffer slots once, in [`crate::plan`]). The loop then
//! only moves numbers:
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
//! An instance whose `fmi2DoStep` returns `fmi2Discard` with `fmi2GetBooleanStatus(
//! fmi2Terminated)` = true, or whose `fmi3DoStep` sets `terminateSimulation`, asks to end the
//! simulation (as the Reference FMU `Stair` does; fmpy, OMSimulator and the FMU Compliance
//! Checker stop there too): the run ends normally at that instance's last successful time
//! (FMI 3.0: the end of the step unless it says otherwise), records that point and says
//! why it ended ([`RunEnd::Terminated`]). Any other `fmi2Discard`/`fmi3Discard`, an error, an
//! FMI 3.0 `earlyReturn` (never allowed) or `eventHandlingNeeded` (event mode is not run) stop
//! the run with an error naming the instance, the FMU file, the call and the time, quoting what
//! that instance logged; when several instances fail in the same step (or in initialisation,
//! or in terminate), the error names every one of them.
//!
//! A simulation made with [`Simulation::with_monitor`] notes every FMI call it enters and
//! leaves in a [`CallMonitor`], so that a watchdog on another thread can name a call that
//! does not return (the instance, its FMU, the call, the time); what to do then is the
//! caller's (the CLI ends the process, keeping the results so far).

use crate::fmu::{
    CallError, Experiment, FmiVersion, FmuFile, Instance, StepEnd, StepProblem, VarType,
};
use crate::plan::{push_op, Op, Plan, Transfer};
use crate::record::Observer;
use crate::system::{System, SystemError};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

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
    #[error("writing results: {0}")]
    Output(#[from] std::io::Error),
}

impl From<FmiFailure> for RunError {
    fn from(f: FmiFailure) -> Self {
        Self::Fmi { failures: vec![f] }
    }
}

/// One value of a [`Batch`]: its buffer slot, its position among the call's values and,
/// for an FMI 3.0 array element, (array, position in the array).
#[derive(Debug, Clone, Copy)]
struct Entry {
    slot: usize,
    position: usize,
    element: Option<(usize, usize)>,
}

/// A [`Transfer`] of the plan as one FMI call: the value references of the call (an FMI 3.0
/// array once, with all its values), where each value goes, and the scratch space.
#[derive(Debug, Clone)]
struct Batch {
    var_type: VarType,
    member: usize,
    vrs: Vec<u32>,
    entries: Vec<Entry>,
    /// (array, first position) of every array moved whole by the call.
    arrays: Vec<(usize, usize)>,
    values: Vec<f64>,
}

impl Batch {
    fn new(t: &Transfer, fmu: &FmuFile) -> Self {
        let mut vrs = Vec::with_capacity(t.vrs.len());
        let mut entries = Vec::with_capacity(t.vrs.len());
        let mut arrays: Vec<(usize, usize)> = Vec::new();
        let mut count = 0;
        for ((&vr, &slot), &var) in t.vrs.iter().zip(&t.slots).zip(&t.vars) {
            let element = fmu.variables.get(var).and_then(|v| v.element);
            let position = match element {
                None => {
                    vrs.push(vr);
                    count += 1;
                    count - 1
                }
                Some((array, k)) => match arrays.iter().find(|(a, _)| *a == array) {
                    Some(&(_, first)) => first + k,
                    None => {
                        let first = count;
                        vrs.push(vr);
                        count += fmu.arrays.get(array).map_or(0, |a| a.elements.len());
                        arrays.push((array, first));
                        first + k
                    }
                },
            };
            entries.push(Entry {
                slot,
                position,
                element,
            });
        }
        Self {
            var_type: t.var_type,
            member: t.member,
            vrs,
            entries,
            arrays,
            values: vec![0.0; count],
        }
    }

    fn get(&mut self, inst: &mut Instance, buffer: &mut [f64]) -> Result<(), CallError> {
        inst.get(self.var_type, &self.vrs, &mut self.values)?;
        for e in &self.entries {
            buffer[e.slot] = self.values[e.position];
        }
        Ok(())
    }

    /// Sets the values from the buffer; the elements of an array this batch does not set
    /// keep the values last given to them (`held`, per array of the instance's FMU).
    fn set(
        &mut self,
        inst: &mut Instance,
        buffer: &[f64],
        held: &mut [Vec<f64>],
    ) -> Result<(), CallError> {
        for e in &self.entries {
            let v = buffer[e.slot];
            self.values[e.position] = v;
            if let Some((array, k)) = e.element {
                if let Some(x) = held.get_mut(array).and_then(|a| a.get_mut(k)) {
                    *x = v;
                }
            }
        }
        for &(array, first) in &self.arrays {
            if let Some(a) = held.get(array) {
                self.values[first..first + a.len()].copy_from_slice(a);
            }
        }
        inst.set(self.var_type, &self.vrs, &self.values)
    }
}

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
    instance: Instance,
    multiple: u64,
    /// Gets after this member's step (its slots).
    after_step: Vec<Batch>,
    /// The values last given to each array of the FMU (start values at first): an element
    /// is set with its whole array.
    held: Vec<Vec<f64>>,
}

impl Member {
    /// Reads this member's outputs into the buffer.
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
    fn call<T>(&mut self, call: &'static str, time: f64, f: impl FnOnce(&mut Instance) -> T) -> T {
        let instance = &mut self.instance;
        watched(self.monitor.as_deref(), self.index, call, time, || {
            f(instance)
        })
    }

    /// A failed call `call` (named by its FMI 2.0 name; an FMI 3.0 instance says its own).
    fn failure(&self, call: &'static str, e: CallError, time: f64) -> FmiFailure {
        let said = self.instance.log().recent_messages();
        FmiFailure {
            instance: self.name.clone(),
            file: self.file.clone(),
            call: self.instance.call_name(call),
            status: e.0,
            time,
            log: if said.is_empty() {
                String::new()
            } else {
                format!(" (the FMU logged: {})", said.join("; "))
            },
        }
    }
}

/// Calls `call` on every member (that `due` selects), then reports every failure at once.
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
fn due_at(k: u64, multiple: u64) -> bool {
    multiple == 1 || k.is_multiple_of(multiple)
}

/// Calls the FMI function `call` (`name`) at `time` on every member's instance, then reports
/// every failure at once.
fn call_every<T>(
    members: &mut [Member],
    name: &'static str,
    time: f64,
    call: impl Fn(&mut Instance) -> Result<T, CallError>,
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

/// The FMI call in progress, for a watchdog on another thread: which instance, which call,
/// at which simulation time, since when.
#[derive(Debug, Clone, PartialEq)]
pub struct CallInProgress {
    pub instance: String,
    pub file: String,
    pub call: &'static str,
    pub time: f64,
    pub since: Instant,
}

impl std::fmt::Display for CallInProgress {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "instance `{}` ({}): {} at t = {}",
            self.instance, self.file, self.call, self.time
        )
    }
}

/// Where a [`Simulation`] made with [`Simulation::with_monitor`] notes each FMI call it
/// enters and leaves, so that a watchdog thread can tell a call that does not return
/// ([`CallMonitor::current`]) and name it. The loop pays one uncontended lock and one clock
/// read per call.
#[derive(Debug, Default)]
pub struct CallMonitor {
    /// (instance name, FMU file) by instance index.
    instances: Mutex<Vec<(String, String)>>,
    /// (instance index, call, time, since).
    current: Mutex<Option<(usize, &'static str, f64, Instant)>>,
}

impl CallMonitor {
    /// The call in progress, if any.
    pub fn current(&self) -> Option<CallInProgress> {
        let (i, call, time, since) = (*lock(&self.current))?;
        let (instance, file) = lock(&self.instances).get(i).cloned().unwrap_or_default();
        Some(CallInProgress {
            instance,
            file,
            call,
            time,
            since,
        })
    }

    fn enter(&self, member: usize, call: &'static str, time: f64) {
        *lock(&self.current) = Some((member, call, time, Instant::now()));
    }

    fn leave(&self) {
        *lock(&self.current) = None;
    }
}

/// The data behind a mutex, also when another thread panicked holding it (the data here is
/// plain values, valid at any time).
fn lock<T>(m: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    m.lock().unwrap_or_else(std::sync::PoisonError::into_inner)
}

/// Runs `f` as FMI call `call` of member `member` at `time`, noted in `monitor` (if any).
fn watched<T>(
    monitor: Option<&CallMonitor>,
    member: usize,
    call: &'static str,
    time: f64,
    f: impl FnOnce() -> T,
) -> T {
    match monitor {
        None => f(),
        Some(m) => {
            m.enter(member, call, time);
            let out = f();
            m.leave();
            out
        }
    }
}

/// Options of a run.
#[derive(Debug, Clone, Default)]
pub struct RunOptions {
    /// Pace the simulation to wall-clock time divided by this factor (1 = real time).
    pub real_time_factor: Option<f64>,
    /// Show a progress bar on standard error.
    pub progress: bool,
    /// Send every `output_interval`-th communication point to the observer (0 and 1: every
    /// one); the start and the last point are always sent.
    pub output_interval: u64,
}

/// How a run ended.
#[derive(Debug, Clone, PartialEq)]
pub enum RunEnd {
    /// Every instance reached the stop time.
    StopTime { time: f64 },
    /// An instance asked to end the simulation (FMI 2.0: `fmi2DoStep` returned
    /// `fmi2Discard` and `fmi2GetBooleanStatus(fmi2Terminated)` is true; FMI 3.0:
    /// `fmi3DoStep` set `terminateSimulation`); the run ended at `time`, its last successful
    /// time, which is the last recorded point.
    Terminated {
        instance: String,
        time: f64,
        version: FmiVersion,
    },
}

impl std::fmt::Display for RunEnd {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::StopTime { time } => write!(f, "the run reached its stop time t = {time}"),
            Self::Terminated {
                instance,
                time,
                version,
            } => write!(
                f,
                "instance `{instance}` asked to end the simulation at t = {time} ({})",
                match version {
                    FmiVersion::Fmi2 =>
                        "fmi2DoStep returned fmi2Discard with fmi2Terminated = true",
                    FmiVersion::Fmi3 => "fmi3DoStep returned terminateSimulation = true",
                }
            ),
        }
    }
}

/// The outcome of one `fmi2DoStep` of every due member.
enum StepOutcome {
    Completed,
    /// (instance, last successful time, its version) of every member that asked to end
    /// the run.
    Terminated(Vec<(String, f64, FmiVersion)>),
}

/// A system ready to run: instances created, names resolved to indices.
pub struct Simulation {
    members: Vec<Member>,
    /// Set/get operations at each communication point.
    propagation: Vec<Step>,
    buffer: Vec<f64>,
    record_names: Vec<String>,
    record_slots: Vec<usize>,
    record_values: Vec<f64>,
    start_time: f64,
    stop_time: f64,
    step_size: f64,
    steps: u64,
    /// Where the run ended (the stop time until it has run).
    end_time: f64,
}

impl Simulation {
    /// Instantiates and initialises every instance of `system` on this thread.
    pub fn new(system: &System) -> Result<Self, RunError> {
        Self::with_monitor(system, None)
    }

    /// [`Simulation::new`], noting every FMI call (from `fmi2Instantiate` on) in `monitor`.
    pub fn with_monitor(
        system: &System,
        monitor: Option<Arc<CallMonitor>>,
    ) -> Result<Self, RunError> {
        let plan: &Plan = &system.plan;
        let t0 = system.start_time;
        if let Some(m) = &monitor {
            *lock(&m.instances) = system
                .instances
                .iter()
                .map(|i| (i.name.clone(), i.fmu.path.display().to_string()))
                .collect();
        }
        let mut members = Vec::with_capacity(system.instances.len());
        for (i, spec) in system.instances.iter().enumerate() {
            let fmu = &spec.fmu;
            let instance = watched(monitor.as_deref(), i, "fmi2Instantiate", t0, || {
                fmu.instantiate(&spec.name, spec.logging)
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
                tolerance: None,
                start: t0,
                stop: Some(system.stop_time),
            };
            m.call("fmi2SetupExperiment", t0, |inst| {
                inst.setup_experiment(experiment)
            })
            .map_err(|e| m.failure("fmi2SetupExperiment", e, t0))?;
            // Start values, grouped by type into calls (an array's elements in one).
            let mut sets = Vec::new();
            let mut values = Vec::with_capacity(spec.start_values.len());
            for (index, value) in &spec.start_values {
                push_op(
                    &mut sets,
                    true,
                    &system.instances,
                    (i, *index),
                    values.len(),
                );
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
        let mut sim = Self {
            members,
            propagation: plan
                .propagation
                .iter()
                .map(|op| match op {
                    Op::Set(t) => Step::Set(Batch::new(t, &system.instances[t.member].fmu)),
                    Op::Get(t) => Step::Get(Batch::new(t, &system.instances[t.member].fmu)),
                })
                .collect(),
            buffer: vec![0.0; plan.slot_count],
            record_names: plan.recorded.names.clone(),
            record_slots: plan.recorded.slots.clone(),
            record_values: vec![0.0; plan.recorded.vars.len()],
            start_time: system.start_time,
            stop_time: system.stop_time,
            step_size: system.step_size,
            steps: plan.steps,
            end_time: system.stop_time,
        };
        // Initial values flow through the connections in initialization mode, then every
        // instance leaves it.
        sim.read_all("fmi2Get* (initial outputs)", t0)?;
        sim.propagate(0, true)?;
        call_every(
            &mut sim.members,
            "fmi2ExitInitializationMode",
            t0,
            Instance::exit_initialization_mode,
        )?;
        sim.read_all("fmi2Get* (initial outputs)", t0)?;
        Ok(sim)
    }

    /// Reads every member's outputs (initialisation).
    fn read_all(&mut self, call: &'static str, time: f64) -> Result<(), RunError> {
        let buffer = &mut self.buffer;
        on_every(
            &mut self.members,
            |_| true,
            |m| m.read(buffer, time).map_err(|e| m.failure(call, e, time)),
        )
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

    /// Reads the outputs of the instances whose step ends at base step `k` (all for k = 0);
    /// an instance none of whose outputs is connected or recorded is not called.
    fn read_outputs(&mut self, k: u64, time: f64) -> Result<(), RunError> {
        let buffer = &mut self.buffer;
        on_every(
            &mut self.members,
            |m| !m.after_step.is_empty() && due_at(k, m.multiple),
            |m| {
                m.read(buffer, time)
                    .map_err(|e| m.failure("fmi2Get*", e, time))
            },
        )
    }

    fn record(&mut self, observer: &mut dyn Observer, time: f64) -> Result<(), RunError> {
        for (v, s) in self.record_values.iter_mut().zip(&self.record_slots) {
            *v = self.buffer[*s];
        }
        observer.sample(time, &self.record_values)?;
        Ok(())
    }

    /// Runs to the stop time (or until an instance asks to end the simulation), sending the
    /// recorded variables to `observer` at every communication point (every
    /// [`RunOptions::output_interval`]-th one; start time and last point included), and says
    /// how the run ended.
    pub fn run(
        &mut self,
        observer: &mut dyn Observer,
        options: &RunOptions,
    ) -> Result<RunEnd, RunError> {
        if let Some(factor) = options.real_time_factor {
            if !(factor.is_finite() && factor > 0.0) {
                return Err(SystemError::Invalid(format!(
                    "the real-time factor must be a positive number, got {factor}"
                ))
                .into());
            }
        }
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
        let every = options.output_interval.max(1);
        for k in 0..self.steps {
            let time = self.start_time + k as f64 * self.step_size;
            if k > 0 {
                // An instance's outputs are published at the communication point its step
                // reaches (a multirate instance holds them in between).
                self.read_outputs(k, time)?;
            }
            self.propagate(k, false)?;
            if due_at(k, every) {
                self.record(observer, time)?;
            }
            if let StepOutcome::Terminated(asked) = self.step_all(k, time)? {
                // The run ends where the earliest of them stopped: every output is read
                // there and recorded as the last point.
                let (instance, end, version) = asked
                    .into_iter()
                    .reduce(|first, other| if first.1 <= other.1 { first } else { other })
                    .unwrap_or((String::new(), time, FmiVersion::Fmi2));
                self.finish(observer, progress, end, end)?;
                return Ok(RunEnd::Terminated {
                    instance,
                    time: end,
                    version,
                });
            }
            if let Some(factor) = options.real_time_factor {
                // A due time beyond Duration's range (a tiny factor) is never reached.
                let due =
                    Duration::try_from_secs_f64((time + self.step_size - self.start_time) / factor)
                        .unwrap_or(Duration::MAX);
                if let Some(wait) = due.checked_sub(wall_start.elapsed()) {
                    std::thread::sleep(wait);
                }
            }
            if let Some(bar) = &progress {
                bar.inc(1);
            }
        }
        let last = self.start_time + self.steps as f64 * self.step_size;
        // Every instance's last step ends at the stop time.
        let end = last.min(self.stop_time);
        self.finish(observer, progress, last, end)?;
        Ok(RunEnd::StopTime { time: end })
    }

    /// Ends a run: every output read at `read_time` and propagated, recorded as the last
    /// point at `end`; the progress bar cleared, the observer finished.
    fn finish(
        &mut self,
        observer: &mut dyn Observer,
        progress: Option<indicatif::ProgressBar>,
        read_time: f64,
        end: f64,
    ) -> Result<(), RunError> {
        self.read_outputs(0, read_time)?;
        self.propagate(self.steps, true)?;
        self.record(observer, end)?;
        if let Some(bar) = progress {
            bar.finish_and_clear();
        }
        observer.finish()?;
        self.end_time = end;
        Ok(())
    }

    /// `fmi2DoStep` on every member due at base step `k`: every failure is reported at once;
    /// members that ask to end the run (`fmi2Discard` with `fmi2Terminated`) are listed.
    fn step_all(&mut self, k: u64, time: f64) -> Result<StepOutcome, RunError> {
        let (step_size, stop_time) = (self.step_size, self.stop_time);
        let mut failures = Vec::new();
        let mut terminated = Vec::new();
        for m in self.members.iter_mut().filter(|m| due_at(k, m.multiple)) {
            let h = (step_size * m.multiple as f64).min(stop_time - time);
            match m.call("fmi2DoStep", time, |inst| inst.do_step(time, h)) {
                Ok(StepEnd::Completed) => {}
                Ok(StepEnd::Terminate(last)) => {
                    // FMI 2.0 stopped within the step (fmi2Discard); FMI 3.0 completed it
                    // unless it says otherwise.
                    let version = m.instance.version();
                    let fallback = match version {
                        FmiVersion::Fmi2 => time,
                        FmiVersion::Fmi3 => time + h,
                    };
                    terminated.push((m.name.clone(), last.unwrap_or(fallback), version));
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
                            "eventHandlingNeeded = true: the FMU needs event mode, which this \
                         master does not run (it instantiates with eventModeUsed = false)"
                                .into(),
                        ),
                        time,
                    ),
                ),
            }
        }
        if !failures.is_empty() {
            return Err(RunError::Fmi { failures });
        }
        Ok(if terminated.is_empty() {
            StepOutcome::Completed
        } else {
            StepOutcome::Terminated(terminated)
        })
    }

    /// Terminates every instance (they are freed when the simulation is dropped); reports
    /// every instance that fails to.
    pub fn terminate(&mut self) -> Result<(), RunError> {
        let t = self.end_time;
        call_every(&mut self.members, "fmi2Terminate", t, Instance::terminate)
    }
}
