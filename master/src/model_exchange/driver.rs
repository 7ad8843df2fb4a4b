//! The Model Exchange simulation loop (module docs of [`super`]).

use super::{Call, EventUpdate, MeError, ModelExchangeCalls};
use crate::fmu::{CallError, Experiment, VarType};
use crate::record::Observer;
use spurio_solvers::{Direction, Method, OdeSystem, Settings, Solver, SolverError, Statistics};

/// The bracket to which a state event's time is located: `10⁻¹² · max(1, |t|)` s.
pub fn event_time_tolerance(t: f64) -> f64 {
    1e-12 * t.abs().max(1.0)
}

/// What the driver must know of the FMU beyond its calls.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Layout {
    /// Number of continuous states.
    pub states: usize,
    /// Number of event indicators.
    pub event_indicators: usize,
    /// The recorded variables: (name, type, value reference), in the order of the columns.
    pub recorded: Vec<(String, VarType, u32)>,
    /// Values set before initialisation: (type, value reference, value).
    pub start_values: Vec<(VarType, u32, f64)>,
}

/// How to run.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Options {
    pub method: Method,
    /// Relative tolerance; the absolute tolerance is the same times each state's nominal.
    pub tolerance: f64,
    /// The longest solver step (None: no bound).
    pub max_step: Option<f64>,
    pub start: f64,
    pub stop: f64,
    /// Results are recorded every `output_interval` from `start` (and at `stop`).
    pub output_interval: f64,
    /// The most solver steps between two recorded points or events.
    pub max_steps_per_interval: usize,
    /// The most events at one time before the run is stopped as chattering.
    pub max_events_without_progress: usize,
    /// The most iterations of one event iteration.
    pub max_event_iterations: usize,
}

impl Options {
    /// Defaults for a run over `[start, stop]` recorded every `output_interval`: the explicit
    /// solver at tolerance 1e-6, 10⁶ steps per interval, 100 events without progress, 1000
    /// event iterations.
    pub fn new(start: f64, stop: f64, output_interval: f64) -> Self {
        Self {
            method: Method::Dopri5,
            tolerance: 1e-6,
            max_step: None,
            start,
            stop,
            output_interval,
            max_steps_per_interval: 1_000_000,
            max_events_without_progress: 100,
            max_event_iterations: 1000,
        }
    }
}

/// The kind of an event.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum EventKind {
    /// Event indicator `indicator` (0-based) changed sign.
    State { indicator: usize },
    /// The FMU's `nextEventTime`.
    Time,
    /// `CompletedIntegratorStep` asked for event mode.
    Step,
}

/// One event handled.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Event {
    pub time: f64,
    pub kind: EventKind,
}

/// How a run ended and what it cost.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Summary {
    /// The time the run ended.
    pub end_time: f64,
    /// Whether the FMU asked to end it (`terminateSimulation`).
    pub terminated: bool,
    /// The solver's work.
    pub statistics: Statistics,
    pub state_events: usize,
    pub time_events: usize,
    pub step_events: usize,
}

/// A failed call during a right-hand side, as the solver carries it.
#[derive(Debug, thiserror::Error)]
#[error("{}", .error.0)]
struct Failure {
    call: Call,
    error: CallError,
}

/// The FMU as the solver sees it: `f(t, x)` by `SetTime`, `SetContinuousStates`,
/// `GetDerivatives`; `J v` by `GetDirectionalDerivative`.
struct Plant<'a, M> {
    fmu: &'a mut M,
}

impl<M: ModelExchangeCalls> Plant<'_, M> {
    fn set(&mut self, t: f64, x: &[f64]) -> Result<(), Failure> {
        let fail = |call| move |error| Failure { call, error };
        self.fmu.set_time(t).map_err(fail(Call::SetTime))?;
        self.fmu
            .set_continuous_states(x)
            .map_err(fail(Call::SetContinuousStates))
    }
}

impl<M: ModelExchangeCalls> OdeSystem for Plant<'_, M> {
    type Error = Failure;

    fn rhs(&mut self, t: f64, x: &[f64], dx: &mut [f64]) -> Result<(), Failure> {
        self.set(t, x)?;
        self.fmu.get_derivatives(dx).map_err(|error| Failure {
            call: Call::GetDerivatives,
            error,
        })
    }

    fn jacobian_times(&mut self, at: Direction<'_>, out: &mut [f64]) -> Result<bool, Failure> {
        self.set(at.t, at.x)?;
        self.fmu
            .directional_derivative(at.v, out)
            .map_err(|error| Failure {
                call: Call::GetDirectionalDerivative,
                error,
            })
    }
}

/// Whether an indicator going from `before` to `after` is an event (FMI 3.0 §3.1: a change
/// of domain, `z > 0` against `z ≤ 0`).
fn crossed(before: f64, after: f64) -> bool {
    (before > 0.0) != (after > 0.0)
}

/// The run's state between the calls.
struct Run<'a, M> {
    fmu: &'a mut M,
    fmi3: bool,
    name: String,
    solver: Solver,
    x: Vec<f64>,
    nominal: Vec<f64>,
    z_old: Vec<f64>,
    z_new: Vec<f64>,
    za: Vec<f64>,
    zm: Vec<f64>,
    /// The recorded variables by type: (type, value references, the column of each value).
    groups: Vec<(VarType, Vec<u32>, Vec<usize>)>,
    values: Vec<f64>,
    /// One group's values as read.
    read: Vec<f64>,
    scratch: Vec<f64>,
}

impl<M: ModelExchangeCalls> Run<'_, M> {
    /// The error for `call` failing at `time`.
    fn failed(&self, call: Call, time: f64) -> impl FnOnce(CallError) -> MeError + '_ {
        move |e| MeError::Call {
            fmu: self.name.clone(),
            call: call.name(self.fmi3),
            time,
            reason: e.0,
        }
    }

    /// A solver error as the run reports it.
    fn solver_error(&self, e: SolverError<Failure>) -> MeError {
        let fmu = self.name.clone();
        let derivatives = Call::GetDerivatives.name(self.fmi3);
        match e {
            SolverError::Model { time, source } => MeError::Call {
                fmu,
                call: source.call.name(self.fmi3),
                time,
                reason: source.error.0,
            },
            SolverError::NonFiniteDerivative { time, index, value } => MeError::NotFinite {
                fmu,
                call: derivatives,
                time,
                what: format!("the derivative of state {} is {value}", index + 1),
            },
            SolverError::NonFiniteStages { time, step } => MeError::NotFinite {
                fmu,
                call: derivatives,
                time,
                what: format!(
                    "the derivatives were not finite in every step tried, down to {step:e} s"
                ),
            },
            other => {
                let time = match &other {
                    SolverError::StepTooSmall { time, .. }
                    | SolverError::TooManyRejections { time, .. }
                    | SolverError::TooManySteps { time, .. }
                    | SolverError::BadTarget { time, .. } => *time,
                    _ => self.solver.time(),
                };
                MeError::Solver {
                    fmu,
                    time,
                    reason: other.to_string(),
                }
            }
        }
    }

    /// Sets the time and the states (the solution at `t`, from the dense output when `t` is
    /// inside the last step).
    fn place(&mut self, t: f64) -> Result<(), MeError> {
        self.fmu
            .set_time(t)
            .map_err(self.failed(Call::SetTime, t))?;
        if !self.x.is_empty() {
            self.solver.interpolate(t, &mut self.scratch);
            let set = self.fmu.set_continuous_states(&self.scratch);
            set.map_err(self.failed(Call::SetContinuousStates, t))?;
        }
        Ok(())
    }

    /// The event indicators at `t` into `out` (the FMU placed at `t` first).
    fn indicators_at(&mut self, t: f64, which: Buffer) -> Result<(), MeError> {
        self.place(t)?;
        let buffer = match which {
            Buffer::New => &mut self.z_new,
            Buffer::Middle => &mut self.zm,
        };
        let result = self.fmu.get_event_indicators(buffer);
        result.map_err(self.failed(Call::GetEventIndicators, t))?;
        let buffer = match which {
            Buffer::New => &self.z_new,
            Buffer::Middle => &self.zm,
        };
        if let Some(i) = buffer.iter().position(|z| z.is_nan()) {
            return Err(MeError::NotFinite {
                fmu: self.name.clone(),
                call: Call::GetEventIndicators.name(self.fmi3),
                time: t,
                what: format!("event indicator {} is NaN", i + 1),
            });
        }
        Ok(())
    }

    /// Records the outputs at `t` (the FMU placed there).
    fn record(&mut self, t: f64, observer: &mut dyn Observer) -> Result<(), MeError> {
        let Self {
            fmu,
            groups,
            values,
            read,
            name,
            fmi3,
            ..
        } = self;
        for (var_type, vrs, columns) in groups.iter() {
            let out = &mut read[..columns.len()];
            fmu.get(*var_type, vrs, out).map_err(|e| MeError::Call {
                fmu: name.clone(),
                call: Call::Get.name(*fmi3),
                time: t,
                reason: e.0,
            })?;
            for (&column, value) in columns.iter().zip(out.iter()) {
                values[column] = *value;
            }
        }
        observer.sample(t, values)?;
        Ok(())
    }

    /// Locates the first sign change of an indicator in `(a, b]`, `z_old` holding the
    /// indicators at `a` and `z_new` those at `b` (module docs): the time at the bracket's
    /// right end and the indicator; `z_new` then holds the indicators there.
    fn locate(&mut self, a: f64, b: f64) -> Result<(f64, usize), MeError> {
        let (mut a, mut b) = (a, b);
        self.za.copy_from_slice(&self.z_old);
        let (mut weight_a, mut weight_b) = (1.0, 1.0);
        // Which end was kept by the last iteration (Illinois: twice the same end halves its
        // weight).
        let mut kept_a_last = None;
        let mut widths = [b - a; 3];
        for iteration in 0..400 {
            if b - a <= event_time_tolerance(b) {
                break;
            }
            let mut estimate = f64::INFINITY;
            for i in 0..self.za.len() {
                if crossed(self.za[i], self.z_new[i]) {
                    let (fa, fb) = (weight_a * self.za[i], weight_b * self.z_new[i]);
                    let t = if fa == fb {
                        b
                    } else {
                        a + (b - a) * fa / (fa - fb)
                    };
                    estimate = estimate.min(t);
                }
            }
            widths = [widths[1], widths[2], b - a];
            let stalled = iteration >= 2 && widths[2] > 0.5 * widths[0];
            let margin = 0.01 * (b - a);
            let t = if stalled || !estimate.is_finite() {
                0.5 * (a + b)
            } else {
                estimate.clamp(a + margin, b - margin)
            };
            self.indicators_at(t, Buffer::Middle)?;
            let crossing = (0..self.za.len()).any(|i| crossed(self.za[i], self.zm[i]));
            let (moved, kept) = if crossing {
                b = t;
                self.z_new.copy_from_slice(&self.zm);
                (&mut weight_b, &mut weight_a)
            } else {
                a = t;
                self.za.copy_from_slice(&self.zm);
                (&mut weight_a, &mut weight_b)
            };
            // Illinois: the end kept twice in a row has its weight halved.
            *moved = 1.0;
            if kept_a_last == Some(crossing) {
                *kept *= 0.5;
            }
            kept_a_last = Some(crossing);
        }
        let indicator = (0..self.za.len())
            .find(|&i| crossed(self.za[i], self.z_new[i]))
            .unwrap_or(0);
        Ok((b, indicator))
    }

    /// The event iteration at `t` (in event mode): until no new iteration is needed. The last
    /// update's flags are returned (its next event time, whether to terminate).
    fn iterate_events(&mut self, t: f64, max: usize) -> Result<EventUpdate, MeError> {
        let mut any_values_changed = false;
        let mut any_nominals_changed = false;
        for _ in 0..max {
            let update = self
                .fmu
                .update_discrete_states()
                .map_err(self.failed(Call::UpdateDiscreteStates, t))?;
            if let Some(te) = update.next_event_time.filter(|te| te.is_nan()) {
                return Err(MeError::NotFinite {
                    fmu: self.name.clone(),
                    call: Call::UpdateDiscreteStates.name(self.fmi3),
                    time: t,
                    what: format!("the next event time is {te}"),
                });
            }
            any_values_changed |= update.values_changed;
            any_nominals_changed |= update.nominals_changed;
            if update.terminate_simulation || !update.discrete_states_need_update {
                return Ok(EventUpdate {
                    values_changed: any_values_changed,
                    nominals_changed: any_nominals_changed,
                    ..update
                });
            }
        }
        Err(MeError::EventIteration {
            fmu: self.name.clone(),
            call: Call::UpdateDiscreteStates.name(self.fmi3),
            time: t,
            iterations: max,
        })
    }

    /// Continuous-time mode at `t` after an event iteration: the solver started afresh from
    /// the states and nominals read, the indicators read as the ones before the next step.
    fn resume(&mut self, t: f64) -> Result<(), MeError> {
        let entered = self.fmu.enter_continuous_time_mode();
        entered.map_err(self.failed(Call::EnterContinuousTimeMode, t))?;
        self.restart(t)?;
        self.fmu
            .set_time(t)
            .map_err(self.failed(Call::SetTime, t))?;
        if !self.z_old.is_empty() {
            let read = self.fmu.get_event_indicators(&mut self.z_old);
            read.map_err(self.failed(Call::GetEventIndicators, t))?;
        }
        Ok(())
    }

    /// Reads the states and nominals at `t` and starts the solver from them.
    fn restart(&mut self, t: f64) -> Result<(), MeError> {
        if self.x.is_empty() {
            return Ok(());
        }
        let read = self.fmu.get_continuous_states(&mut self.x);
        read.map_err(self.failed(Call::GetContinuousStates, t))?;
        let read = self.fmu.get_nominals(&mut self.nominal);
        read.map_err(self.failed(Call::GetNominalsOfContinuousStates, t))?;
        if let Some(i) = self.x.iter().position(|v| !v.is_finite()) {
            return Err(MeError::NotFinite {
                fmu: self.name.clone(),
                call: Call::GetContinuousStates.name(self.fmi3),
                time: t,
                what: format!("state {} is {}", i + 1, self.x[i]),
            });
        }
        let reset = self.solver.reset(t, &self.x, &self.nominal);
        reset.map_err(|e| self.solver_error(e))
    }
}

/// Which indicator buffer to fill.
#[derive(Clone, Copy)]
enum Buffer {
    New,
    Middle,
}

/// Runs `fmu` (instantiated, not yet initialised) over the experiment of `options`, recording
/// `layout.recorded` at every output point into `observer` and telling `on_event` each event
/// handled (module docs of [`super`]). The instance is terminated at the end (also when the
/// FMU asked to end early), not when the run fails.
pub fn simulate<M: ModelExchangeCalls>(
    fmu: &mut M,
    layout: &Layout,
    options: &Options,
    observer: &mut dyn Observer,
    on_event: &mut dyn FnMut(&Event),
) -> Result<Summary, MeError> {
    let name = fmu.name();
    let fmi3 = fmu.is_fmi3();
    let bad = |reason: String| MeError::Layout {
        fmu: name.clone(),
        reason,
    };
    if !(options.stop >= options.start && options.output_interval > 0.0) {
        return Err(bad(format!(
            "the experiment runs from {} to {} recorded every {}: the stop time must not be before the start and the interval must be positive",
            options.start, options.stop, options.output_interval
        )));
    }
    let n = layout.states;
    let settings = Settings {
        relative: options.tolerance,
        absolute: options.tolerance,
        max_step: options.max_step.unwrap_or(f64::INFINITY),
        ..Settings::default()
    };
    // One read per type; the elements of an FMI 3.0 array (consecutive, one value reference)
    // are read as the array.
    let mut groups: Vec<(VarType, Vec<u32>, Vec<usize>)> = Vec::new();
    for (column, (_, t, vr)) in layout.recorded.iter().enumerate() {
        match groups.iter_mut().find(|g| g.0 == *t) {
            Some(g) => {
                if !(fmi3 && g.1.last() == Some(vr)) {
                    g.1.push(*vr);
                }
                g.2.push(column);
            }
            None => groups.push((*t, vec![*vr], vec![column])),
        }
    }
    let m = layout.event_indicators;
    let zeros = |k: usize| vec![0.0; k];
    let mut run = Run {
        fmu,
        fmi3,
        name: name.clone(),
        solver: Solver::new(options.method, n, settings),
        x: zeros(n),
        nominal: vec![1.0; n],
        z_old: zeros(m),
        z_new: zeros(m),
        za: zeros(m),
        zm: zeros(m),
        groups,
        values: zeros(layout.recorded.len()),
        read: zeros(layout.recorded.len()),
        scratch: zeros(n),
    };
    let (start, stop) = (options.start, options.stop);
    let experiment = Experiment {
        tolerance: Some(options.tolerance),
        start,
        stop: Some(stop),
    };
    // Initialisation (FMI 2.0 §3.2.3 / FMI 3.0 §3.2.1).
    run.fmu
        .setup_experiment(experiment)
        .map_err(run.failed(Call::SetupExperiment, start))?;
    for (t, vr, value) in &layout.start_values {
        run.fmu
            .set(*t, &[*vr], &[*value])
            .map_err(run.failed(Call::Set, start))?;
    }
    run.fmu
        .enter_initialization_mode(experiment)
        .map_err(run.failed(Call::EnterInitializationMode, start))?;
    run.fmu
        .exit_initialization_mode()
        .map_err(run.failed(Call::ExitInitializationMode, start))?;
    let names: Vec<String> = layout.recorded.iter().map(|r| r.0.clone()).collect();
    observer.start(&names)?;
    let mut summary = Summary {
        end_time: start,
        ..Summary::default()
    };
    let mut update = run.iterate_events(start, options.max_event_iterations)?;
    let mut t = start;
    // The output grid: start + k · interval, and the stop time.
    let intervals = ((stop - start) / options.output_interval - 1e-9)
        .ceil()
        .max(0.0) as u64;
    let grid = |k: u64| (start + k as f64 * options.output_interval).min(stop);
    let mut k_next = 1;
    if update.terminate_simulation {
        run.record(t, observer)?;
        return finish(run, summary, observer, true);
    }
    run.resume(t)?;
    run.record(t, observer)?;
    let (mut last_event_time, mut events_here) = (f64::NEG_INFINITY, 0usize);
    let mut steps_in_interval = 0usize;
    while t < stop {
        // A time event announced at or before the current time is due now: handled at `t`
        // without a step (an FMU that keeps announcing one is stopped as chattering).
        let time_event = update
            .next_event_time
            .filter(|&te| te <= stop)
            .map(|te| te.max(t));
        let limit = time_event.unwrap_or(stop);
        // One step (no states, or an event due now: straight to the next output point or the
        // limit).
        let t_new = if n == 0 || limit <= t {
            limit.min(grid(k_next))
        } else {
            steps_in_interval += 1;
            if steps_in_interval > options.max_steps_per_interval {
                return Err(MeError::Solver {
                    fmu: name,
                    time: t,
                    reason: format!(
                        "more than {} steps without reaching an output point or an event",
                        options.max_steps_per_interval
                    ),
                });
            }
            let mut plant = Plant { fmu: &mut *run.fmu };
            match run.solver.step(&mut plant, limit) {
                Ok(t_new) => t_new,
                Err(e) => return Err(run.solver_error(e)),
            }
        };
        // State events over (t, t_new].
        let mut state_event = None;
        let mut t_valid = t_new;
        if m > 0 {
            run.indicators_at(t_new, Buffer::New)?;
            if (0..m).any(|i| crossed(run.z_old[i], run.z_new[i])) {
                let (t_event, indicator) = run.locate(t, t_new)?;
                t_valid = t_event;
                state_event = Some(indicator);
            }
        }
        // Output points before t_valid (at t_valid: after any event there).
        while k_next <= intervals && grid(k_next) < t_valid {
            let t_out = grid(k_next);
            run.place(t_out)?;
            run.record(t_out, observer)?;
            k_next += 1;
            steps_in_interval = 0;
        }
        run.place(t_valid)?;
        let mut step_event = false;
        if state_event.is_none() {
            let (enter, terminate) = run
                .fmu
                .completed_integrator_step()
                .map_err(run.failed(Call::CompletedIntegratorStep, t_valid))?;
            if terminate {
                run.record(t_valid, observer)?;
                summary.end_time = t_valid;
                return finish(run, summary, observer, true);
            }
            step_event = enter;
        }
        let is_time_event = time_event.is_some_and(|te| te <= t_valid);
        t = t_valid;
        let kind = match (state_event, is_time_event, step_event) {
            (Some(indicator), _, _) => Some(EventKind::State { indicator }),
            (None, true, _) => Some(EventKind::Time),
            (None, false, true) => Some(EventKind::Step),
            (None, false, false) => None,
        };
        if let Some(kind) = kind {
            match kind {
                EventKind::State { .. } => summary.state_events += 1,
                EventKind::Time => summary.time_events += 1,
                EventKind::Step => summary.step_events += 1,
            }
            if t - last_event_time <= event_time_tolerance(t) {
                events_here += 1;
                if events_here > options.max_events_without_progress {
                    return Err(MeError::Chattering {
                        fmu: name,
                        time: t,
                        events: events_here,
                        bound: options.max_events_without_progress,
                        call: match kind {
                            EventKind::State { .. } => Call::GetEventIndicators,
                            EventKind::Time => Call::UpdateDiscreteStates,
                            EventKind::Step => Call::CompletedIntegratorStep,
                        }
                        .name(fmi3),
                    });
                }
            } else {
                events_here = 1;
            }
            last_event_time = t;
            on_event(&Event { time: t, kind });
            run.fmu
                .enter_event_mode()
                .map_err(run.failed(Call::EnterEventMode, t))?;
            update = run.iterate_events(t, options.max_event_iterations)?;
            if update.terminate_simulation {
                run.record(t, observer)?;
                summary.end_time = t;
                return finish(run, summary, observer, true);
            }
            run.resume(t)?;
            steps_in_interval = 0;
        } else if m > 0 {
            // The indicators at the accepted point (t_valid = t_new here).
            run.z_old.copy_from_slice(&run.z_new);
        }
        if k_next <= intervals && grid(k_next) <= t {
            run.record(t, observer)?;
            k_next += 1;
            steps_in_interval = 0;
        }
    }
    summary.end_time = t;
    finish(run, summary, observer, false)
}

/// Terminates the instance and closes the recording.
fn finish<M: ModelExchangeCalls>(
    run: Run<'_, M>,
    mut summary: Summary,
    observer: &mut dyn Observer,
    terminated: bool,
) -> Result<Summary, MeError> {
    summary.terminated = terminated;
    summary.statistics = run.solver.statistics();
    let t = summary.end_time;
    run.fmu
        .terminate()
        .map_err(run.failed(Call::Terminate, t))?;
    observer.finish()?;
    Ok(summary)
}
