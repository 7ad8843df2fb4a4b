//! The safe trait an FMU implements: its interface, its initialisation and its step.
//!
//! Everything FMI — the state machine, argument checks, value-reference dispatch, logging,
//! FMU states — is done by [`crate::instance::Instance`]; a model only reads its parameters
//! and inputs from the [`Context`] and writes its outputs there.

use crate::bytes::{ByteReader, ByteWriter};
use crate::description::{Config, ModelInfo};
use crate::types::Status;
use crate::values::Values;

/// What went wrong, as the typed error of whoever found it (a parameter error of the
/// models, an estimation error, [`crate::bytes::StateFormatError`], a configuration error…);
/// the export layer logs its `Display` text, prefixed by the FMI function.
pub type Cause = Box<dyn std::error::Error + Send + Sync + 'static>;

/// Why a model call failed: the FMI status it gives and its cause.
#[derive(Debug)]
pub enum Failure {
    /// The step was not carried out but the instance is intact (`fmi2Discard`).
    Discard(Cause),
    /// The call failed (`fmi2Error`): bad parameters, a numerical failure.
    Error(Cause),
}

impl Failure {
    /// An `fmi2Error` failure with this cause (an error value or a message).
    pub fn error(cause: impl Into<Cause>) -> Self {
        Failure::Error(cause.into())
    }
    /// An `fmi2Discard` failure with this cause.
    pub fn discard(cause: impl Into<Cause>) -> Self {
        Failure::Discard(cause.into())
    }
    /// The cause, whichever the status.
    pub fn cause(&self) -> &Cause {
        match self {
            Failure::Discard(cause) | Failure::Error(cause) => cause,
        }
    }
}

impl std::fmt::Display for Failure {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}", self.cause())
    }
}

impl From<String> for Failure {
    fn from(message: String) -> Self {
        Failure::error(message)
    }
}

impl From<&str> for Failure {
    fn from(message: &str) -> Self {
        Failure::error(message)
    }
}

impl From<Cause> for Failure {
    fn from(cause: Cause) -> Self {
        Failure::Error(cause)
    }
}

/// A message a model wants logged.
#[derive(Debug, Clone, PartialEq)]
pub struct LogMessage {
    pub status: Status,
    pub category: &'static str,
    pub text: String,
}

/// What a model sees during a call: the values of its variables and a place to log.
#[derive(Debug)]
pub struct Context<'a> {
    /// Parameters, inputs and outputs, indexed like the variable table.
    pub values: &'a mut Values,
    pub(crate) messages: Vec<LogMessage>,
    time: f64,
    /// Whether events are logged (debug logging on, `logEvents` enabled): when not,
    /// [`Context::log_event`] keeps nothing (and allocates nothing).
    pub(crate) log_events: bool,
}

/// The log category of [`Context::log_event`].
pub(crate) const EVENTS: &str = "logEvents";

impl<'a> Context<'a> {
    /// A context over `values` at time 0.
    pub fn new(values: &'a mut Values) -> Self {
        Self::at(values, 0.0)
    }
    /// A context over `values` at simulation time `time`.
    pub fn at(values: &'a mut Values, time: f64) -> Self {
        Self {
            values,
            messages: Vec::new(),
            time,
            log_events: true,
        }
    }
    /// The instance's current communication point \[s\]: the start time (from
    /// `fmi2SetupExperiment`) during initialization, the start of the step in `do_step`, the
    /// last communication point in `update_outputs` and `parameters_changed`.
    pub fn time(&self) -> f64 {
        self.time
    }
    /// Logs an event (category `logEvents`; shown when debug logging is on, else dropped
    /// here). `text` is called only when the message will be shown, so an event costs no
    /// formatting and no allocation while logging is off (no allocation per step).
    pub fn log_event(&mut self, text: impl FnOnce() -> String) {
        if self.log_events {
            self.messages.push(LogMessage {
                status: Status::Ok,
                category: EVENTS,
                text: text(),
            });
        }
    }
    /// Whether [`Context::log_event`] messages are shown (debug logging on).
    pub fn logs_events(&self) -> bool {
        self.log_events
    }
    /// Logs a warning; the call then returns `fmi2Warning`.
    pub fn warn(&mut self, text: impl Into<String>) {
        self.messages.push(LogMessage {
            status: Status::Warning,
            category: "logStatusWarning",
            text: text.into(),
        });
    }
    /// The messages logged so far.
    pub fn messages(&self) -> &[LogMessage] {
        &self.messages
    }
    /// Takes the messages logged so far.
    pub fn take_messages(&mut self) -> Vec<LogMessage> {
        std::mem::take(&mut self.messages)
    }
}

/// What the discrete change at an event did (`fmi2NewDiscreteStates`' `fmi2EventInfo`,
/// `fmi3UpdateDiscreteStates`' flags). The default: nothing changed, no next time event.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct EventUpdate {
    /// Another event iteration is needed at this time (`newDiscreteStatesNeeded`).
    pub discrete_states_need_update: bool,
    /// The model asks to end the simulation (`terminateSimulation`).
    pub terminate_simulation: bool,
    /// The continuous states were changed (`valuesOfContinuousStatesChanged`: a velocity
    /// reset, say), so the solver restarts from them.
    pub states_changed: bool,
    /// The nominals of the states changed (`nominalsOfContinuousStatesChanged`).
    pub nominals_changed: bool,
    /// The time of the next time event, if there is one (`nextEventTime`).
    pub next_event_time: Option<f64>,
}

/// The Model Exchange side of a model: the importer's solver integrates its continuous
/// states (the variables declared [`crate::Variable::state`], in value-reference order) from
/// their derivatives (the variables declared [`crate::Variable::derivative_of`]).
///
/// The layer keeps the states in the variable values: `fmi2SetContinuousStates` writes them
/// there, [`FmuModel::initialize`] sets their initial values there, and
/// [`ModelExchange::update_discrete_states`] changes them there at an event. A model offers
/// the interface by declaring it in [`FmuModel::describe`]
/// ([`crate::ModelInfo::with_model_exchange`]) and exporting with `export_fmu!(Model, model_exchange)`.
///
/// Value references here are the indices of the variable table (the FMI 2.0 value
/// references, the `vr::…` constants of `declare_variables!`), also for FMI 3.0 calls.
/// Non-finite results are caught by the layer (`fmi2Error` naming the variable).
pub trait ModelExchange: FmuModel {
    /// Reads the states, inputs and parameters from `ctx` at `ctx.time()` and writes the
    /// derivative variables `der(…)` and the outputs. Pure: no internal state changes, so
    /// calling it any number of times with the same values gives the same result.
    fn evaluate(&mut self, ctx: &mut Context) -> Result<(), Failure>;

    /// The event indicators `z` (one per variable declared
    /// [`crate::Variable::event_indicator`], in table order; the layer writes them there) from the same
    /// values as [`ModelExchange::evaluate`] (called after it); a sign change of one is a
    /// state event the solver locates.
    fn event_indicators(&mut self, ctx: &mut Context, z: &mut [f64]) -> Result<(), Failure>;

    /// In event mode (after initialization, at a state or time event, after
    /// `fmi2CompletedIntegratorStep` asked for one): the discrete change — a velocity reset at
    /// a rail stop, a mode switch — written into the state values in `ctx`.
    fn update_discrete_states(&mut self, ctx: &mut Context) -> Result<EventUpdate, Failure>;

    /// What [`ModelExchange::partial`] reads its entries from, computed by
    /// [`ModelExchange::jacobian`]: the Jacobian matrices at the current values, the
    /// saturation slopes, the mode (`()` where the entries need nothing precomputed). The
    /// layer keeps it for the directional derivatives that follow at the same values
    /// ([`JacobianCache`]).
    type Jacobian: 'static;

    /// The [`ModelExchange::Jacobian`] at the current values (after
    /// [`ModelExchange::evaluate`]), for the calls of [`ModelExchange::partial`] that follow.
    /// Allocation-free (fixed-size matrices), as every call of the directional derivative.
    fn jacobian(&mut self, ctx: &Context) -> Result<Self::Jacobian, Failure>;

    /// The exact (analytic) partial derivative `∂unknown/∂known` of an unknown (a derivative
    /// or an output) with respect to a known (a state or an input), from `jacobian`; an
    /// `Err` names a value reference that is not one.
    fn partial(
        &self,
        jacobian: &Self::Jacobian,
        unknown: usize,
        known: usize,
    ) -> Result<f64, Failure>;

    /// The directional derivative `out = J · seed` of the `unknowns` (derivatives and outputs)
    /// with respect to the `knowns` (states and inputs), at the current values (after
    /// [`ModelExchange::evaluate`]): `out[i] = Σ_k ∂unknowns[i]/∂knowns[k] · seed[k]` from
    /// [`ModelExchange::partial`]; `seed.len() == knowns.len()`, `out.len() == unknowns.len()`.
    /// Exact, not finite differences. The layer serves `fmi2GetDirectionalDerivative`,
    /// `fmi3GetDirectionalDerivative` and (with the unknowns and knowns swapped by the
    /// caller) `fmi3GetAdjointDerivative`, also from the Co-Simulation interface, where the
    /// states are the values the last step left, by the same sum over a Jacobian it keeps
    /// between calls ([`JacobianCache`]). Models supply the entries, not this sum.
    fn directional_derivative(
        &mut self,
        ctx: &mut Context,
        unknowns: &[usize],
        knowns: &[usize],
        seed: &[f64],
        out: &mut [f64],
    ) -> Result<(), Failure> {
        let jacobian = self.jacobian(ctx)?;
        jacobian_times_seed(self, &jacobian, (unknowns, knowns, seed), out)
    }
}

/// `out[i] = Σ_k ∂unknowns[i]/∂knowns[k] · seed[k]` from `model`'s
/// [`ModelExchange::partial`]s of `jacobian` (`request`: the unknowns, the knowns, the seed).
fn jacobian_times_seed<M: ModelExchange>(
    model: &M,
    jacobian: &M::Jacobian,
    (unknowns, knowns, seed): (&[usize], &[usize], &[f64]),
    out: &mut [f64],
) -> Result<(), Failure> {
    out.fill(0.0);
    // a column whose seed is 0 adds nothing (a unit seed, as Jacobian columns are asked for,
    // reads one entry per unknown); each sum runs over the knowns in their order
    for (&known, &s) in knowns.iter().zip(seed).filter(|(_, &s)| s != 0.0) {
        for (o, &unknown) in out.iter_mut().zip(unknowns) {
            *o += model.partial(jacobian, unknown, known)? * s;
        }
    }
    Ok(())
}

/// The [`ModelExchange::Jacobian`] an instance formed last, kept for the directional
/// derivatives that follow at the same values. An importer forms `J` column by column (one
/// `fmi2GetDirectionalDerivative` per unit seed: a Rosenbrock solver's `n` calls a step); each
/// call would otherwise form the whole of `J` again. Type-erased (the instance does not name
/// the model's `Jacobian` type); its box is allocated at the first directional derivative
/// and reused. The instance forgets it whenever the values or the model may have changed: at
/// every other model call, every value set (time, states, inputs, parameters), an FMU state
/// set and a reset.
#[derive(Debug, Default)]
pub struct JacobianCache {
    slot: Option<Box<dyn std::any::Any>>,
    /// Whether `slot` holds the Jacobian at the instance's current values.
    valid: bool,
}

impl JacobianCache {
    /// The values changed: the next directional derivative forms the Jacobian again.
    #[inline(always)]
    pub fn forget(&mut self) {
        self.valid = false;
    }
}

/// [`ModelExchange::directional_derivative`] with the Jacobian taken from `cache` when it
/// is valid, formed (and kept there) otherwise.
fn directional_derivative_cached<M: ModelExchange>(
    model: &mut M,
    ctx: &mut Context,
    cache: &mut JacobianCache,
    (unknowns, knowns): (&[usize], &[usize]),
    seed: &[f64],
    out: &mut [f64],
) -> Result<(), Failure> {
    let valid = std::mem::take(&mut cache.valid);
    let request = (unknowns, knowns, seed);
    if let Some(jacobian) = cache
        .slot
        .as_mut()
        .and_then(|slot| slot.downcast_mut::<M::Jacobian>())
    {
        if !valid {
            *jacobian = model.jacobian(ctx)?;
        }
        cache.valid = true;
        return jacobian_times_seed(model, jacobian, request, out);
    }
    let jacobian = Box::new(model.jacobian(ctx)?);
    let result = jacobian_times_seed(model, &jacobian, request, out);
    cache.slot = Some(jacobian);
    cache.valid = true;
    result
}

/// An FMI 2.0 Co-Simulation model.
///
/// `Clone` is how FMU states are taken (`fmi2GetFMUstate`); `save_state`/`load_state` are how
/// they are serialized. Implementations must not panic on any input (a panic is caught and
/// reported as `fmi2Fatal`, but that is a bug). A call writes only the variables the model
/// computes — outputs, locals, calculated parameters — never its parameters or inputs, which
/// the master sets: the layer keeps and checks only the former around a call (a debug build
/// panics, as `fmi2Fatal`, on a model that writes the latter).
pub trait FmuModel: Clone + 'static {
    /// The interface for `config` (empty for FMUs of fixed dimensions). Called when packaging
    /// and in `fmi2Instantiate`, with the configuration read from the FMU's resources.
    fn describe(config: &Config) -> Result<ModelInfo, Cause>;

    /// A new model for an instance of `info`.
    fn create(info: &ModelInfo) -> Result<Self, Cause>;

    /// A new model for an instance of `info` whose unpacked `resources/` folder is
    /// `resources` (`None` when the importer gives no resource location): for a model that
    /// reads a file there at instantiation (a table). The default ignores it:
    /// [`FmuModel::create`].
    fn create_with_resources(
        info: &ModelInfo,
        resources: Option<&std::path::Path>,
    ) -> Result<Self, Cause> {
        let _ = resources;
        Self::create(info)
    }

    /// Reads and checks the parameters, sets the initial state and computes the initial
    /// outputs. Called in initialization mode (possibly more than once: when outputs are read
    /// there) and at `fmi2ExitInitializationMode`; it must give the same result each time.
    fn initialize(&mut self, ctx: &mut Context) -> Result<(), Failure>;

    /// Whether the model can take the step from `time` over `step` within its bounded work
    /// per call (a cap on RK4 substeps, say). Called by `fmi2DoStep` before [`FmuModel::do_step`];
    /// an `Err` refuses the step: `fmi2Error` with the cause logged, and the instance stays as
    /// it was (state machine, time, values and model). The default accepts every step.
    fn check_step(&self, ctx: &Context, time: f64, step: f64) -> Result<(), Cause> {
        let _ = (ctx, time, step);
        Ok(())
    }

    /// Advances from `time` to `time + step` with the current inputs, then writes the outputs.
    fn do_step(&mut self, ctx: &mut Context, time: f64, step: f64) -> Result<(), Failure>;

    /// Recomputes the outputs that depend directly on the inputs (those declared with
    /// `depends_on`), after inputs were set and before they are read, without advancing time
    /// (FMI 2.0 CS direct feedthrough). Must not change the model's future: calling it any
    /// number of times between two steps gives the same result. The default does nothing
    /// (outputs keep their values from the last step).
    fn update_outputs(&mut self, ctx: &mut Context) -> Result<(), Failure> {
        let _ = ctx;
        Ok(())
    }

    /// Called after tunable parameters were set between steps.
    fn parameters_changed(&mut self, ctx: &mut Context) -> Result<(), Failure> {
        let _ = ctx;
        Ok(())
    }

    /// Writes the model's internal state (not the variable values, which are saved apart).
    fn save_state(&self, out: &mut ByteWriter);

    /// Restores what [`FmuModel::save_state`] wrote.
    fn load_state(&mut self, input: &mut ByteReader) -> Result<(), Cause>;
}

/// The [`ModelExchange`] functions of a model, as plain function pointers: what
/// `export_fmu!(Model, model_exchange)` hands the version-neutral instance, so the shared code
/// needs no `ModelExchange` bound and models without it export the same symbols (which then
/// refuse Model Exchange with a logged reason).
pub struct Hooks<M> {
    /// [`ModelExchange::evaluate`].
    pub evaluate: fn(&mut M, &mut Context) -> Result<(), Failure>,
    /// [`ModelExchange::event_indicators`].
    pub event_indicators: fn(&mut M, &mut Context, &mut [f64]) -> Result<(), Failure>,
    /// [`ModelExchange::update_discrete_states`].
    pub update_discrete_states: fn(&mut M, &mut Context) -> Result<EventUpdate, Failure>,
    /// [`ModelExchange::directional_derivative`] over the Jacobian kept in the cache:
    /// (model, context, cache, (unknowns, knowns), seed, out).
    #[allow(clippy::type_complexity)]
    pub directional_derivative: fn(
        &mut M,
        &mut Context,
        &mut JacobianCache,
        (&[usize], &[usize]),
        &[f64],
        &mut [f64],
    ) -> Result<(), Failure>,
}

impl<M> Clone for Hooks<M> {
    fn clone(&self) -> Self {
        *self
    }
}
impl<M> Copy for Hooks<M> {}

/// The hooks of a [`ModelExchange`] model.
pub fn hooks<M: ModelExchange>() -> Hooks<M> {
    Hooks {
        evaluate: M::evaluate,
        event_indicators: M::event_indicators,
        update_discrete_states: M::update_discrete_states,
        directional_derivative: directional_derivative_cached::<M>,
    }
}
