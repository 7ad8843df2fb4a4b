//! The Model Exchange simulation loop (module docs of [`super`]).

use super::{Call, EventUpdate, MeError, ModelExchangeCalls};
use crate::fmu::{CallError, Experiment, VarType};
use crate::record::Observer;
use spurio_solvers::{
    Direction, Method, OdeSystem, Settings, Solver, SolverError, SolverErrorKind, Statistics,
};

/// The bracket to which a state event's time is located: `10⁻¹² · max(1, |t|)` s.
pub fn event_time_tolerance(t: f64) -> f64 {
    1e-12 * t.abs().max(1.0)
}

/// Events closer than this to the one before (1 µs at |t| ≤ 1, relative beyond) are *close*:
/// a run of more than [`Options::max_close_events`] of them in a row is stopped as chattering
/// (time moves on, but by so little that the run would not end in any useful time).
pub fn close_event_spacing(t: f64) -> f64 {
    1e-6 * t.abs().max(1.0)
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
    /// The most events in a row each closer than [`close_event_spacing`] to the one before,
    /// before the run is stopped as chattering.
    pub max_close_events: usize,
    /// The most iterations of one event iteration.
    pub max_event_iterations: usize,
}

impl Options {
    /// Defaults for a run over `[start, stop]` recorded every `output_interval`: the explicit
    /// solver at tolerance 1e-6, 10⁶ steps per interval, 100 events without progress, 10⁴
    /// close events in a row, 1000 event iterations.
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
            max_close_events: 10_000,
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

impl std::fmt::Display for EventKind {
    /// `state event (indicator i)` (1-based), `time event`, `step event
    /// (CompletedIntegratorStep)`.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            EventKind::State { indicator } => {
                write!(f, "state event (indicator {})", indicator + 1)
            }
            EventKind::Time => f.write_str("time event"),
            EventKind::Step => f.write_str("step event (CompletedIntegratorStep)"),
        }
    }
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

/// The time and continuous states the driver last gave the FMU in continuous-time mode
/// (`SetTime`, `SetContinuousStates`), so that a call at the same point sets nothing again:
/// the Jacobian's columns, the indicators after a step at the state the step's last
/// derivative was taken at, the derivative after an event at the state read back. A set
/// value the FMU takes as new makes it evaluate its equations again; the same value would
/// give the same result. Forgotten whenever the FMU may have changed its states itself (an
/// event iteration) or a call failed; compared bit for bit.
#[derive(Debug, Clone)]
struct Placed {
    t: f64,
    x: Vec<f64>,
    /// Whether `t` and `x` are what the FMU holds.
    known: bool,
}

impl Placed {
    fn new(n: usize) -> Self {
        Self {
            t: f64::NAN,
            x: vec![0.0; n],
            known: false,
        }
    }

    /// Sets time `t` and states `x` in `fmu`, each only when it differs from what the FMU
    /// holds; `call` names the failed call. A few instructions a call when both differ (a
    /// solver's stage), as for a plain set.
    #[inline(always)]
    fn set<M: ModelExchangeCalls>(
        &mut self,
        fmu: &mut M,
        t: f64,
        x: &[f64],
    ) -> Result<(), (Call, CallError)> {
        let known = std::mem::replace(&mut self.known, false);
        if !(known && self.t.to_bits() == t.to_bits()) {
            fmu.set_time(t).map_err(|e| (Call::SetTime, e))?;
            self.t = t;
        }
        // compared and copied in one pass: the states set are the ones kept
        let mut same = known;
        for (kept, &given) in self.x.iter_mut().zip(x) {
            same &= kept.to_bits() == given.to_bits();
            *kept = given;
        }
        if !same && !x.is_empty() {
            fmu.set_continuous_states(x)
                .map_err(|e| (Call::SetContinuousStates, e))?;
        }
        self.known = true;
        Ok(())
    }

    /// Takes `(t, x)` as what the FMU holds (it was just set there, or read there).
    fn note(&mut self, t: f64, x: &[f64]) {
        self.t = t;
        self.x.copy_from_slice(x);
        self.known = true;
    }

    /// What the FMU holds is no longer known.
    fn forget(&mut self) {
        self.known = false;
    }
}

/// The FMU as the solver sees it: `f(t, x)` by `SetTime`, `SetContinuousStates`,
/// `GetDerivatives`; `J v` by `GetDirectionalDerivative`.
struct Plant<'a, M> {
    fmu: &'a mut M,
    placed: &'a mut Placed,
}

impl<M: ModelExchangeCalls> Plant<'_, M> {
    #[inline]
    fn set(&mut self, t: f64, x: &[f64]) -> Result<(), Failure> {
        self.placed
            .set(self.fmu, t, x)
            .map_err(|(call, error)| Failure { call, error })
    }
}

impl<M: ModelExchangeCalls> OdeSystem for Plant<'_, M> {
    type Error = Failure;

    #[inline]
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

/// How an [`Stepper::advance_to`] ended.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Advance {
    /// The instance reached the time asked for.
    Reached(f64),
    /// The FMU asked to end the simulation (`terminateSimulation`) at this time.
    Terminated(f64),
}

/// The recorded variables of a single-FMU run ([`simulate`]) and its output grid
/// `start + k · interval` (and the stop time).
struct Recording {
    /// The recorded variables by type: (type, value references, the column of each value).
    groups: Vec<(VarType, Vec<u32>, Vec<usize>)>,
    values: Vec<f64>,
    /// One group's values as read.
    read: Vec<f64>,
    start: f64,
    stop: f64,
    interval: f64,
    /// The number of intervals from start to stop, and the next grid point's index.
    intervals: u64,
    next: u64,
}

impl Recording {
    /// The grid point `k`.
    fn grid(&self, k: u64) -> f64 {
        (self.start + k as f64 * self.interval).min(self.stop)
    }

    /// The next grid point, if any is left.
    fn next_point(&self) -> Option<f64> {
        (self.next <= self.intervals).then(|| self.grid(self.next))
    }
}

/// One Model Exchange instance integrated by a solver of its own from event to event, in
/// three calls (module docs of [`super`]): [`Stepper::initialise`] after initialisation mode
/// (the first event iteration, continuous-time mode), [`Stepper::advance_to`] as often as
/// the caller wants (a co-simulation advances it from one communication point to the next,
/// its inputs held over the interval), and [`Stepper::finish`]. It holds no FMU: each call
/// is given the instance, so that a co-simulation keeps its instances where it reads and
/// sets their values. Every buffer is sized when it is made: an advance allocates nothing
/// (but for the messages of an error).
pub struct Stepper {
    name: String,
    fmi3: bool,
    options: Options,
    solver: Solver,
    /// The time the instance is at.
    t: f64,
    x: Vec<f64>,
    nominal: Vec<f64>,
    /// The event indicators at `t`, at the end of a step, and the ends of a bracket.
    z_old: Vec<f64>,
    z_new: Vec<f64>,
    za: Vec<f64>,
    zm: Vec<f64>,
    /// The indicators at the place of the bracket's end before its last move (location).
    zp: Vec<f64>,
    scratch: Vec<f64>,
    /// What the FMU holds of time and states.
    placed: Placed,
    /// The time event the FMU announced last.
    next_event_time: Option<f64>,
    /// The last event's time and how many events happened at it (chattering).
    last_event_time: f64,
    events_here: usize,
    /// The first event of the present run of close events and how many it holds.
    close_since: f64,
    close_events: usize,
    summary: Summary,
    recording: Option<Recording>,
}

impl Stepper {
    /// A stepper for an instance of `layout.states` states and `layout.event_indicators`
    /// indicators called `name` (FMI 3.0 when `fmi3`, for the calls' names), run with
    /// `options` (its method, tolerance, maximum step and bounds; its start time is the
    /// first [`Stepper::initialise`]'s).
    pub fn new(name: String, fmi3: bool, layout: &Layout, options: &Options) -> Self {
        let (n, m) = (layout.states, layout.event_indicators);
        let settings = Settings {
            relative: options.tolerance,
            absolute: options.tolerance,
            max_step: options.max_step.unwrap_or(f64::INFINITY),
            ..Settings::default()
        };
        let zeros = |k: usize| vec![0.0; k];
        Self {
            name,
            fmi3,
            options: *options,
            solver: Solver::new(options.method, n, settings),
            t: options.start,
            x: zeros(n),
            nominal: vec![1.0; n],
            z_old: zeros(m),
            z_new: zeros(m),
            za: zeros(m),
            zm: zeros(m),
            zp: zeros(m),
            scratch: zeros(n),
            placed: Placed::new(n),
            next_event_time: None,
            last_event_time: f64::NEG_INFINITY,
            events_here: 0,
            close_since: f64::NEG_INFINITY,
            close_events: 0,
            summary: Summary {
                end_time: options.start,
                ..Summary::default()
            },
            recording: None,
        }
    }

    /// Back to what [`Stepper::new`] made for the same instance, layout and options, its
    /// buffers kept (nothing allocated): for an instance reset and initialised again
    /// ([`initialise`], then [`Stepper::initialise`]), which it then runs bit for bit as a new
    /// stepper would.
    pub fn renew(&mut self) {
        self.solver.renew();
        self.t = self.options.start;
        self.placed.forget();
        self.next_event_time = None;
        self.last_event_time = f64::NEG_INFINITY;
        self.events_here = 0;
        self.close_events = 0;
        self.summary = Summary {
            end_time: self.options.start,
            ..Summary::default()
        };
        if let Some(recording) = &mut self.recording {
            recording.next = 1;
        }
    }

    /// The time the instance is at.
    pub fn time(&self) -> f64 {
        self.t
    }

    /// What the run did so far (its end time: the time reached; its statistics: the
    /// solver's).
    pub fn summary(&self) -> Summary {
        Summary {
            end_time: self.t,
            statistics: self.solver.statistics(),
            ..self.summary
        }
    }

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
        let time = e.time;
        match e.kind {
            SolverErrorKind::Model(source) => MeError::Call {
                fmu,
                call: source.call.name(self.fmi3),
                time,
                reason: source.error.0,
            },
            SolverErrorKind::NonFiniteDerivative { index, value } => MeError::NotFinite {
                fmu,
                call: derivatives,
                time,
                what: format!("the derivative of state {} is {value}", index + 1),
            },
            SolverErrorKind::NonFiniteStages { step } => MeError::NotFinite {
                fmu,
                call: derivatives,
                time,
                what: format!(
                    "the derivatives were not finite in every step tried, down to {step:e} s"
                ),
            },
            kind => MeError::Solver {
                fmu,
                time,
                reason: SolverError::at(time, kind).to_string(),
            },
        }
    }

    /// Sets the time and the states (the solution at `t`, from the dense output when `t` is
    /// inside the last step).
    fn place<M: ModelExchangeCalls>(&mut self, fmu: &mut M, t: f64) -> Result<(), MeError> {
        if !self.x.is_empty() {
            self.solver.interpolate(t, &mut self.scratch);
        }
        match self.placed.set(fmu, t, &self.scratch) {
            Ok(()) => Ok(()),
            Err((call, e)) => Err(self.failed(call, t)(e)),
        }
    }

    /// The event indicators of the FMU as it is (at `t`) into `which`; a NaN is an error.
    fn read_indicators<M: ModelExchangeCalls>(
        &mut self,
        fmu: &mut M,
        t: f64,
        which: Buffer,
    ) -> Result<(), MeError> {
        let buffer = match which {
            Buffer::New => &mut self.z_new,
            Buffer::Middle => &mut self.zm,
        };
        let result = fmu.get_event_indicators(buffer);
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

    /// Records the outputs at `t` (the FMU placed there), when this stepper records.
    fn record<M: ModelExchangeCalls>(
        &mut self,
        fmu: &mut M,
        t: f64,
        observer: &mut dyn Observer,
    ) -> Result<(), MeError> {
        let Some(recording) = &mut self.recording else {
            return Ok(());
        };
        let Recording {
            groups,
            values,
            read,
            ..
        } = recording;
        for (var_type, vrs, columns) in groups.iter() {
            let out = &mut read[..columns.len()];
            fmu.get(*var_type, vrs, out).map_err(|e| MeError::Call {
                fmu: self.name.clone(),
                call: Call::Get.name(self.fmi3),
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
    ///
    /// Each iteration evaluates the indicators at one time inside the bracket: for every
    /// indicator that changes sign over it, the regula falsi estimate `a − z(a)(b − a)/(z(b) −
    /// z(a))`, or, when the same end moved in the last two iterations (the estimates
    /// approach the root from one side, as regula falsi does on a convex indicator), the
    /// secant through that end's last two places, `t₁ − z(t₁)(t₁ − t₀)/(z(t₁) − z(t₀))`, if it
    /// falls inside the bracket (superlinear, where regula falsi only shaves the bracket);
    /// the earliest estimate, kept half the tolerance inside the bracket, so that an estimate
    /// next to the root closes the bracket from the other side at the next evaluation.
    /// Bisection when the bracket has not halved in four iterations.
    fn locate<M: ModelExchangeCalls>(
        &mut self,
        fmu: &mut M,
        a: f64,
        b: f64,
    ) -> Result<(f64, usize), MeError> {
        let (mut a, mut b) = (a, b);
        self.za.copy_from_slice(&self.z_old);
        // The end that moved in the last iteration (true: b), whether it also moved in the
        // one before, and its place before its last move (its indicators in `zp`).
        let mut moved_b = None;
        let mut one_sided = false;
        let mut before = f64::NAN;
        let mut widths = [b - a; 5];
        for iteration in 0..400 {
            if b - a <= event_time_tolerance(b) {
                break;
            }
            let mut estimate = f64::INFINITY;
            for i in 0..self.za.len() {
                let (za, zb) = (self.za[i], self.z_new[i]);
                if !crossed(za, zb) {
                    continue;
                }
                let falsi = if za == zb {
                    b
                } else {
                    a + (b - a) * za / (za - zb)
                };
                let secant = match moved_b {
                    Some(end_b) if one_sided => {
                        let (t1, z1) = if end_b { (b, zb) } else { (a, za) };
                        let (t0, z0) = (before, self.zp[i]);
                        let t = t1 - z1 * (t1 - t0) / (z1 - z0);
                        (t > a && t < b).then_some(t)
                    }
                    _ => None,
                };
                estimate = estimate.min(secant.unwrap_or(falsi));
            }
            widths = [widths[1], widths[2], widths[3], widths[4], b - a];
            let stalled = iteration >= 4 && widths[4] > 0.5 * widths[0];
            let margin = 0.5 * event_time_tolerance(b);
            let t = if stalled || !estimate.is_finite() {
                0.5 * (a + b)
            } else {
                estimate.clamp(a + margin, b - margin)
            };
            self.place(fmu, t)?;
            self.read_indicators(fmu, t, Buffer::Middle)?;
            let crossing = (0..self.za.len()).any(|i| crossed(self.za[i], self.zm[i]));
            if crossing {
                before = b;
                self.zp.copy_from_slice(&self.z_new);
                b = t;
                self.z_new.copy_from_slice(&self.zm);
            } else {
                before = a;
                self.zp.copy_from_slice(&self.za);
                a = t;
                self.za.copy_from_slice(&self.zm);
            }
            one_sided = moved_b == Some(crossing);
            moved_b = Some(crossing);
        }
        let indicator = (0..self.za.len())
            .find(|&i| crossed(self.za[i], self.z_new[i]))
            .unwrap_or(0);
        Ok((b, indicator))
    }

    /// The event iteration at `t` (in event mode): until no new iteration is needed. The last
    /// update's flags are returned (its next event time, whether to terminate).
    fn iterate_events<M: ModelExchangeCalls>(
        &mut self,
        fmu: &mut M,
        t: f64,
    ) -> Result<EventUpdate, MeError> {
        let max = self.options.max_event_iterations;
        let mut any_values_changed = false;
        let mut any_nominals_changed = false;
        for _ in 0..max {
            let update = fmu
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
    fn resume<M: ModelExchangeCalls>(&mut self, fmu: &mut M, t: f64) -> Result<(), MeError> {
        let entered = fmu.enter_continuous_time_mode();
        entered.map_err(self.failed(Call::EnterContinuousTimeMode, t))?;
        // the time first: the states read next and the indicators then come from one
        // evaluation of the FMU
        fmu.set_time(t).map_err(self.failed(Call::SetTime, t))?;
        self.restart(fmu, t)?;
        // the FMU holds the states just read, at `t`
        self.placed.note(t, &self.x);
        if !self.z_old.is_empty() {
            let read = fmu.get_event_indicators(&mut self.z_old);
            read.map_err(self.failed(Call::GetEventIndicators, t))?;
        }
        Ok(())
    }

    /// Reads the states and nominals at `t` and starts the solver from them.
    fn restart<M: ModelExchangeCalls>(&mut self, fmu: &mut M, t: f64) -> Result<(), MeError> {
        if self.x.is_empty() {
            return Ok(());
        }
        let read = fmu.get_continuous_states(&mut self.x);
        read.map_err(self.failed(Call::GetContinuousStates, t))?;
        let read = fmu.get_nominals(&mut self.nominal);
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

    /// Leaves initialisation at `t` (the FMU out of initialisation mode, in event mode): the
    /// first event iteration, then continuous-time mode with the solver started from the
    /// states. `Advance::Terminated` when the FMU asks to end the run there.
    pub fn initialise<M: ModelExchangeCalls>(
        &mut self,
        fmu: &mut M,
        t: f64,
    ) -> Result<Advance, MeError> {
        self.t = t;
        self.summary.end_time = t;
        self.values_set_in_event_mode(fmu)
    }

    /// Puts the instance (in continuous-time mode) at time `t` with the continuous states `x`,
    /// wherever it was before, and starts the solver afresh from there: the time set, the
    /// states set and read back with their nominals, the event indicators there taken as the
    /// ones before the next step, the count of events without progress started again. An
    /// estimator propagating sigma points or a state estimate from one sample to the next
    /// calls this before [`Stepper::advance_to`].
    ///
    /// `reference`: event indicators of a state the caller takes as the one this state
    /// deviates from (an estimator's mean for a sigma point); an indicator on the other side
    /// of zero from its reference ([`crossed`]) means the state is past that event surface,
    /// and the event is handled at `t` (the FMU's event iteration, as for a state event), so
    /// that a sigma point placed a little past a bounce bounces. `Advance::Terminated` when
    /// the FMU asks to end the run there.
    pub fn place_at<M: ModelExchangeCalls>(
        &mut self,
        fmu: &mut M,
        t: f64,
        x: &[f64],
        reference: Option<&[f64]>,
        on_event: &mut dyn FnMut(&Event),
    ) -> Result<Advance, MeError> {
        if x.len() != self.x.len() {
            return Err(MeError::Layout {
                fmu: self.name.clone(),
                reason: format!("{} states given for an FMU with {}", x.len(), self.x.len()),
            });
        }
        self.t = t;
        self.last_event_time = f64::NEG_INFINITY;
        self.events_here = 0;
        self.close_events = 0;
        self.placed.forget();
        fmu.set_time(t).map_err(self.failed(Call::SetTime, t))?;
        if !x.is_empty() {
            let set = fmu.set_continuous_states(x);
            set.map_err(self.failed(Call::SetContinuousStates, t))?;
        }
        self.restart(fmu, t)?;
        if self.z_old.is_empty() {
            return Ok(Advance::Reached(t));
        }
        let read = fmu.get_event_indicators(&mut self.z_old);
        read.map_err(self.failed(Call::GetEventIndicators, t))?;
        let past = reference.and_then(|r| {
            (0..self.z_old.len().min(r.len())).find(|&i| crossed(r[i], self.z_old[i]))
        });
        if let Some(indicator) = past {
            let kind = EventKind::State { indicator };
            if let Some(end) = self.handle_event(fmu, kind, on_event)? {
                return Ok(Advance::Terminated(end));
            }
        }
        Ok(Advance::Reached(t))
    }

    /// The event indicators as the stepper last read them (after [`Stepper::place_at`]: at
    /// the state placed, before any step).
    pub fn event_indicators(&self) -> &[f64] {
        &self.z_old
    }

    /// Values were set in event mode at the stepper's time (the caller entered event mode
    /// and set tunable parameters, FMI 2.0 §3.2.3): the event iteration there, then
    /// continuous-time mode with the solver started afresh. `Advance::Terminated` when the
    /// FMU asks to end the run.
    pub fn values_set_in_event_mode<M: ModelExchangeCalls>(
        &mut self,
        fmu: &mut M,
    ) -> Result<Advance, MeError> {
        let t = self.t;
        self.placed.forget();
        let update = self.iterate_events(fmu, t)?;
        self.next_event_time = update.next_event_time;
        if update.terminate_simulation {
            self.summary.terminated = true;
            return Ok(Advance::Terminated(t));
        }
        self.resume(fmu, t)?;
        Ok(Advance::Reached(t))
    }

    /// The inputs of the FMU were set at its time (a communication point of a
    /// co-simulation): the solver starts again from the states there (the derivatives
    /// changed), and an event indicator that changed sign with the inputs is an event there.
    pub fn inputs_changed<M: ModelExchangeCalls>(
        &mut self,
        fmu: &mut M,
        on_event: &mut dyn FnMut(&Event),
    ) -> Result<Advance, MeError> {
        let t = self.t;
        self.placed.forget();
        self.restart(fmu, t)?;
        if self.z_old.is_empty() {
            return Ok(Advance::Reached(t));
        }
        self.read_indicators(fmu, t, Buffer::New)?;
        match (0..self.z_new.len()).find(|&i| crossed(self.z_old[i], self.z_new[i])) {
            Some(indicator) => {
                let kind = EventKind::State { indicator };
                match self.handle_event(fmu, kind, on_event)? {
                    Some(end) => Ok(Advance::Terminated(end)),
                    None => Ok(Advance::Reached(t)),
                }
            }
            None => {
                self.z_old.copy_from_slice(&self.z_new);
                Ok(Advance::Reached(t))
            }
        }
    }

    /// Handles an event of `kind` at the stepper's time: counted, checked for chattering,
    /// told to `on_event`, the event iteration, continuous-time mode again. The time at which
    /// the FMU asked to end the run, if it did.
    fn handle_event<M: ModelExchangeCalls>(
        &mut self,
        fmu: &mut M,
        kind: EventKind,
        on_event: &mut dyn FnMut(&Event),
    ) -> Result<Option<f64>, MeError> {
        let t = self.t;
        match kind {
            EventKind::State { .. } => self.summary.state_events += 1,
            EventKind::Time => self.summary.time_events += 1,
            EventKind::Step => self.summary.step_events += 1,
        }
        if t - self.last_event_time <= event_time_tolerance(t) {
            self.events_here += 1;
            let bound = self.options.max_events_without_progress;
            if self.events_here > bound {
                return Err(MeError::Chattering {
                    fmu: self.name.clone(),
                    time: t,
                    events: self.events_here,
                    bound,
                    call: match kind {
                        EventKind::State { .. } => Call::GetEventIndicators,
                        EventKind::Time => Call::UpdateDiscreteStates,
                        EventKind::Step => Call::CompletedIntegratorStep,
                    }
                    .name(self.fmi3),
                });
            }
        } else {
            self.events_here = 1;
        }
        if t - self.last_event_time < close_event_spacing(t) {
            self.close_events += 1;
            let bound = self.options.max_close_events;
            if self.close_events > bound {
                return Err(MeError::CloseEvents {
                    fmu: self.name.clone(),
                    from: self.close_since,
                    time: t,
                    events: self.close_events,
                    spacing: close_event_spacing(t),
                    bound,
                });
            }
        } else {
            self.close_events = 1;
            self.close_since = t;
        }
        self.last_event_time = t;
        on_event(&Event { time: t, kind });
        // the event iteration may change the states
        self.placed.forget();
        fmu.enter_event_mode()
            .map_err(self.failed(Call::EnterEventMode, t))?;
        let update = self.iterate_events(fmu, t)?;
        self.next_event_time = update.next_event_time;
        if update.terminate_simulation {
            self.summary.terminated = true;
            return Ok(Some(t));
        }
        self.resume(fmu, t)?;
        Ok(None)
    }

    /// Integrates from the stepper's time to `t_end` (not before it), handling every event
    /// on the way (module docs of [`super`]); the FMU is left at the time reached with the
    /// states there. The inputs keep the values they have. A stepper made by [`simulate`]
    /// records its grid points on the way into `observer` (any other records nothing there).
    pub fn advance_to<M: ModelExchangeCalls>(
        &mut self,
        fmu: &mut M,
        t_end: f64,
        observer: &mut dyn Observer,
        on_event: &mut dyn FnMut(&Event),
    ) -> Result<Advance, MeError> {
        let n = self.x.len();
        let m = self.z_old.len();
        let mut steps_in_interval = 0usize;
        // the caller may have placed the FMU elsewhere since the last advance
        self.placed.forget();
        while self.t < t_end {
            let t = self.t;
            // A time event announced at or before the current time is due now: handled at `t`
            // without a step (an FMU that keeps announcing one is stopped as chattering).
            let time_event = self
                .next_event_time
                .filter(|&te| te <= t_end)
                .map(|te| te.max(t));
            let limit = time_event.unwrap_or(t_end);
            // One step (no states, or an event due now: straight to the next output point or
            // the limit).
            let t_new = if n == 0 || limit <= t {
                let next_output = self.recording.as_ref().and_then(Recording::next_point);
                next_output.map_or(limit, |point| limit.min(point))
            } else {
                steps_in_interval += 1;
                if steps_in_interval > self.options.max_steps_per_interval {
                    return Err(MeError::Solver {
                        fmu: self.name.clone(),
                        time: t,
                        reason: format!(
                            "more than {} steps without reaching an output point or an event",
                            self.options.max_steps_per_interval
                        ),
                    });
                }
                let mut plant = Plant {
                    fmu: &mut *fmu,
                    placed: &mut self.placed,
                };
                match self.solver.step(&mut plant, limit) {
                    Ok(t_new) => t_new,
                    Err(e) => return Err(self.solver_error(e)),
                }
            };
            // State events over (t, t_new].
            let mut state_event = None;
            let mut t_valid = t_new;
            if m > 0 {
                self.place(fmu, t_new)?;
                self.read_indicators(fmu, t_new, Buffer::New)?;
                if (0..m).any(|i| crossed(self.z_old[i], self.z_new[i])) {
                    let (t_event, indicator) = self.locate(fmu, t, t_new)?;
                    t_valid = t_event;
                    state_event = Some(indicator);
                }
            }
            // Output points before t_valid (at t_valid: after any event there).
            while let Some(t_out) = self.recording.as_ref().and_then(Recording::next_point) {
                if t_out >= t_valid {
                    break;
                }
                self.place(fmu, t_out)?;
                self.record(fmu, t_out, observer)?;
                if let Some(r) = &mut self.recording {
                    r.next += 1;
                }
                steps_in_interval = 0;
            }
            self.place(fmu, t_valid)?;
            self.t = t_valid;
            let mut step_event = false;
            if state_event.is_none() {
                let (enter, terminate) = fmu
                    .completed_integrator_step()
                    .map_err(self.failed(Call::CompletedIntegratorStep, t_valid))?;
                if terminate {
                    self.summary.terminated = true;
                    self.record(fmu, t_valid, observer)?;
                    return Ok(Advance::Terminated(t_valid));
                }
                step_event = enter;
            }
            let is_time_event = time_event.is_some_and(|te| te <= t_valid);
            let kind = match (state_event, is_time_event, step_event) {
                (Some(indicator), _, _) => Some(EventKind::State { indicator }),
                (None, true, _) => Some(EventKind::Time),
                (None, false, true) => Some(EventKind::Step),
                (None, false, false) => None,
            };
            if let Some(kind) = kind {
                if let Some(end) = self.handle_event(fmu, kind, on_event)? {
                    self.record(fmu, end, observer)?;
                    return Ok(Advance::Terminated(end));
                }
                steps_in_interval = 0;
            } else if m > 0 {
                // The indicators at the accepted point (t_valid = t_new here).
                self.z_old.copy_from_slice(&self.z_new);
            }
            let due = self.recording.as_ref().and_then(Recording::next_point);
            if due.is_some_and(|point| point <= self.t) {
                let t = self.t;
                self.record(fmu, t, observer)?;
                if let Some(r) = &mut self.recording {
                    r.next += 1;
                }
                steps_in_interval = 0;
            }
        }
        self.summary.end_time = self.t;
        Ok(Advance::Reached(self.t))
    }

    /// Terminates the instance (`fmi2Terminate`/`fmi3Terminate`) at the time reached and
    /// returns what the run did.
    pub fn finish<M: ModelExchangeCalls>(&mut self, fmu: &mut M) -> Result<Summary, MeError> {
        let t = self.t;
        fmu.terminate().map_err(self.failed(Call::Terminate, t))?;
        Ok(self.summary())
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
/// handled (module docs of [`super`]): a [`Stepper`] initialised and advanced to the stop
/// time. The instance is terminated at the end (also when the FMU asked to end early), not
/// when the run fails.
pub fn simulate<M: ModelExchangeCalls>(
    fmu: &mut M,
    layout: &Layout,
    options: &Options,
    observer: &mut dyn Observer,
    on_event: &mut dyn FnMut(&Event),
) -> Result<Summary, MeError> {
    let name = fmu.name();
    let fmi3 = fmu.is_fmi3();
    if !(options.stop >= options.start && options.output_interval > 0.0) {
        return Err(MeError::Layout {
            fmu: name,
            reason: format!(
                "the experiment runs from {} to {} recorded every {}: the stop time must not be before the start and the interval must be positive",
                options.start, options.stop, options.output_interval
            ),
        });
    }
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
    let (start, stop) = (options.start, options.stop);
    let mut stepper = Stepper::new(name, fmi3, layout, options);
    let columns = layout.recorded.len();
    stepper.recording = Some(Recording {
        groups,
        values: vec![0.0; columns],
        read: vec![0.0; columns],
        start,
        stop,
        interval: options.output_interval,
        intervals: ((stop - start) / options.output_interval - 1e-9)
            .ceil()
            .max(0.0) as u64,
        next: 1,
    });
    initialise(fmu, layout, options, &stepper)?;
    let names: Vec<String> = layout.recorded.iter().map(|r| r.0.clone()).collect();
    observer.start(&names)?;
    if let Advance::Reached(t) = stepper.initialise(fmu, start)? {
        stepper.record(fmu, t, observer)?;
        stepper.advance_to(fmu, stop, observer, on_event)?;
    } else {
        stepper.record(fmu, start, observer)?;
    }
    let summary = stepper.finish(fmu)?;
    observer.finish()?;
    Ok(summary)
}

/// The experiment set up, the start values set, initialisation mode entered and left
/// (FMI 2.0 §3.2.3 / FMI 3.0 §3.2.1); errors named as `stepper` names them. The instance is
/// then in event mode: [`Stepper::initialise`] goes on from there.
pub fn initialise<M: ModelExchangeCalls>(
    fmu: &mut M,
    layout: &Layout,
    options: &Options,
    stepper: &Stepper,
) -> Result<(), MeError> {
    let start = options.start;
    // An infinite stop (an estimator's run, open-ended) is no stop time: stopTimeDefined false.
    let experiment = Experiment {
        tolerance: Some(options.tolerance),
        start,
        stop: options.stop.is_finite().then_some(options.stop),
    };
    fmu.setup_experiment(experiment)
        .map_err(stepper.failed(Call::SetupExperiment, start))?;
    for (t, vr, value) in &layout.start_values {
        fmu.set(*t, &[*vr], &[*value])
            .map_err(stepper.failed(Call::Set, start))?;
    }
    fmu.enter_initialization_mode(experiment)
        .map_err(stepper.failed(Call::EnterInitializationMode, start))?;
    fmu.exit_initialization_mode()
        .map_err(stepper.failed(Call::ExitInitializationMode, start))?;
    Ok(())
}
