//! One FMU instance: the FMI 2.0 Co-Simulation state machine around a safe [`FmuModel`], which
//! the FMI 3.0 front ([`crate::fmi3`]) drives too (Step Mode is `StepComplete`; the methods
//! named `…_as` take the calling function, so messages name the `fmi3*` one).
//!
//! Every entry point is checked against an allowed-state mask (as the Reference-FMUs do in
//! `fmi2Functions.c`), every value reference against the variable table, every value against
//! the variable's type, causality, variability, bounds and finiteness — before anything is
//! changed, so a rejected call loses nothing. Errors are logged with the function's name and
//! the expected vs. actual value.
//!
//! Calls that the instance rejects (illegal call sequence, unknown value reference, a NaN
//! input, a value out of bounds, a step whose end `t + h` is not finite or that the model
//! refuses in [`FmuModel::check_step`]) return `fmi2Error` and leave the instance as it was; a
//! model that fails inside initialisation or a step moves the instance to the `Error` state,
//! from which `fmi2SetFMUstate`, `fmi2Reset` or `fmi2FreeInstance` lead on.
//!
//! **No non-finite value is ever published.** After every model call that computes values
//! (initialisation, a step, direct feedthrough, tunable parameters), every value the call may
//! write (outputs, locals, calculated parameters: [`Interface::computed`]; a model never writes
//! its parameters or inputs, checked in debug builds) is checked by a branch-free scan; a
//! NaN or ±∞ is `fmi2Error` naming the variable, the values go back to those before the call
//! (so `fmi2GetReal` in the `Error` state reads the last finite values, never the NaN), the
//! time does not advance, and the instance moves to the `Error` state (the model's internal
//! state may have advanced: as after any model error, `fmi2SetFMUstate` or `fmi2Reset` lead on).
//!
//! **A serialized state is checked before it is accepted**: format version, model identifier,
//! GUID, value count and types, a state-machine state that a saved state can carry
//! ([`ModelState::can_be_saved`]), finite time and stop time, finite Reals within their declared
//! bounds, then the model's own part ([`FmuModel::load_state`] validates what it reads).

use crate::bytes::{ByteReader, ByteWriter, StateFormatError};
use crate::description::ModelInfo;
use crate::front::{Interface, WINDOW};
use crate::me::Hooks;
use crate::model::{Cause, Context, Failure, FmuModel, LogMessage, EVENTS};
use crate::types::Status;
use crate::variables::{
    all_finite, first_non_finite, Causality, Initial, Value, Values, Variability, Variable,
    VariableType,
};
use std::fmt;
use std::sync::Arc;

/// The states of the FMI 2.0 Co-Simulation state machine.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ModelState {
    StartAndEnd,
    Instantiated,
    InitializationMode,
    StepComplete,
    StepInProgress,
    StepFailed,
    StepCanceled,
    Terminated,
    Error,
    Fatal,
    /// Model Exchange: Event Mode (discrete changes, event iteration).
    EventMode,
    /// Model Exchange: Continuous-Time Mode (the importer's solver integrates the states).
    ContinuousTimeMode,
}

impl ModelState {
    /// Every state, in the order of their indices in a serialized FMU state (new states go
    /// at the end, so saved states keep their meaning).
    const ALL: [ModelState; 12] = [
        ModelState::StartAndEnd,
        ModelState::Instantiated,
        ModelState::InitializationMode,
        ModelState::StepComplete,
        ModelState::StepInProgress,
        ModelState::StepFailed,
        ModelState::StepCanceled,
        ModelState::Terminated,
        ModelState::Error,
        ModelState::Fatal,
        ModelState::EventMode,
        ModelState::ContinuousTimeMode,
    ];

    /// This state's bit in the masks.
    pub const fn bit(self) -> u32 {
        1 << (self as u32)
    }

    fn from_bits_index(i: u64) -> Option<Self> {
        Self::ALL.get(usize::try_from(i).ok()?).copied()
    }

    /// Whether an instance can be in this state when `fmi2GetFMUstate` is called: steps are
    /// synchronous (never `StepInProgress`, `StepFailed` or `StepCanceled`), `Fatal` and
    /// `StartAndEnd` have no instance to save.
    pub fn can_be_saved(self) -> bool {
        matches!(
            self,
            ModelState::Instantiated
                | ModelState::InitializationMode
                | ModelState::StepComplete
                | ModelState::Terminated
                | ModelState::Error
                | ModelState::EventMode
                | ModelState::ContinuousTimeMode
        )
    }
}

impl fmt::Display for ModelState {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        fmt::Debug::fmt(self, f)
    }
}

/// The states' bits, for the masks of both versions' function tables.
pub(crate) mod bits {
    use super::ModelState;
    pub const INSTANTIATED: u32 = ModelState::Instantiated.bit();
    pub const INIT_MODE: u32 = ModelState::InitializationMode.bit();
    pub const STEP_COMPLETE: u32 = ModelState::StepComplete.bit();
    pub const STEP_IN_PROGRESS: u32 = ModelState::StepInProgress.bit();
    pub const STEP_FAILED: u32 = ModelState::StepFailed.bit();
    pub const STEP_CANCELED: u32 = ModelState::StepCanceled.bit();
    pub const TERMINATED: u32 = ModelState::Terminated.bit();
    pub const ERROR: u32 = ModelState::Error.bit();
    pub const FATAL: u32 = ModelState::Fatal.bit();
    pub const EVENT_MODE: u32 = ModelState::EventMode.bit();
    pub const CONTINUOUS_TIME_MODE: u32 = ModelState::ContinuousTimeMode.bit();
    /// The two states of a Model Exchange instance between initialization and termination.
    pub const ME_MODES: u32 = EVENT_MODE | CONTINUOUS_TIME_MODE;
    /// Where the Model Exchange getters may be called.
    pub const ME_AFTER_INIT: u32 = INIT_MODE | ME_MODES | TERMINATED | ERROR;
}
use bits::*;

/// An FMI function and the states in which it may be called.
#[derive(Debug, Clone, Copy)]
pub struct Function {
    pub name: &'static str,
    pub mask: u32,
}

/// `function! { ID, "fmiXName", MASK }` declares `pub const ID: Function`: the one form of
/// the FMI 2.0 and FMI 3.0 tables of allowed states.
macro_rules! function {
    ($id:ident, $name:expr, $mask:expr) => {
        pub const $id: $crate::instance::Function = $crate::instance::Function {
            name: $name,
            mask: $mask,
        };
    };
}
pub(crate) use function;

/// Declares, in a version's `functions` module, the functions both versions have under the
/// same name but for the prefix `$fmi` (and the spellings `$state` of "FMU state",
/// `$deserialize` of its deserialization, `$real` and `$integer` of the numeric types), with
/// the version's masks: every live state, where FMU states may be taken, where values may be
/// read and set, where the instance may be terminated.
macro_rules! shared_functions {
    (
        $fmi:literal, $state:literal, $deserialize:literal, $real:literal, $integer:literal,
        $any_live:expr, $state_ops:expr, $get:expr, $set:expr, $terminable:expr
    ) => {
        use $crate::instance::function as f;
        f! { SET_DEBUG_LOGGING, concat!($fmi, "SetDebugLogging"), $any_live }
        f! { FREE_INSTANCE, concat!($fmi, "FreeInstance"), $any_live | FATAL }
        f! { ENTER_INITIALIZATION_MODE, concat!($fmi, "EnterInitializationMode"), INSTANTIATED }
        f! { EXIT_INITIALIZATION_MODE, concat!($fmi, "ExitInitializationMode"), INIT_MODE }
        f! { RESET, concat!($fmi, "Reset"), $state_ops }
        f! { TERMINATE, concat!($fmi, "Terminate"), $terminable }
        f! { GET_REAL, concat!($fmi, "Get", $real), $get }
        f! { GET_INTEGER, concat!($fmi, "Get", $integer), $get }
        f! { SET_REAL, concat!($fmi, "Set", $real), $set }
        f! { SET_INTEGER, concat!($fmi, "Set", $integer), $set }
        f! { GET_BOOLEAN, concat!($fmi, "GetBoolean"), $get }
        f! { GET_STRING, concat!($fmi, "GetString"), $get }
        f! { SET_BOOLEAN, concat!($fmi, "SetBoolean"), $set }
        f! { SET_STRING, concat!($fmi, "SetString"), $set }
        f! { GET_FMU_STATE, concat!($fmi, "Get", $state), $state_ops }
        f! { SET_FMU_STATE, concat!($fmi, "Set", $state), $state_ops }
        f! { FREE_FMU_STATE, concat!($fmi, "Free", $state), $state_ops | FATAL }
        f! { SERIALIZED_FMU_STATE_SIZE, concat!($fmi, "Serialized", $state, "Size"), $state_ops }
        f! { SERIALIZE_FMU_STATE, concat!($fmi, "Serialize", $state), $state_ops }
        f! { DESERIALIZE_FMU_STATE, concat!($fmi, $deserialize), $state_ops }
        f! { DO_STEP, concat!($fmi, "DoStep"), STEP_COMPLETE }
        f! { GET_DIRECTIONAL_DERIVATIVE, concat!($fmi, "GetDirectionalDerivative"), $get }
        // Model Exchange (FMI 2.0.4 §3.2.3, FMI 3.0.2 §3.3).
        f! { SET_TIME, concat!($fmi, "SetTime"), ME_MODES }
        f! { SET_CONTINUOUS_STATES, concat!($fmi, "SetContinuousStates"), CONTINUOUS_TIME_MODE }
        f! { GET_CONTINUOUS_STATES, concat!($fmi, "GetContinuousStates"), ME_AFTER_INIT }
        f! { GET_EVENT_INDICATORS, concat!($fmi, "GetEventIndicators"), ME_AFTER_INIT }
        f! { GET_NOMINALS_OF_CONTINUOUS_STATES, concat!($fmi, "GetNominalsOfContinuousStates"), INSTANTIATED | ME_AFTER_INIT }
        f! { ENTER_EVENT_MODE, concat!($fmi, "EnterEventMode"), ME_MODES }
        f! { ENTER_CONTINUOUS_TIME_MODE, concat!($fmi, "EnterContinuousTimeMode"), EVENT_MODE }
        f! { COMPLETED_INTEGRATOR_STEP, concat!($fmi, "CompletedIntegratorStep"), CONTINUOUS_TIME_MODE }
    };
}
pub(crate) use shared_functions;

/// Allowed-state masks of the FMI 2.0 functions (FMI 2.0.4, §4.2.4 Co-Simulation and §3.2.3
/// Model Exchange state machines; a Co-Simulation instance never is in the Model Exchange
/// states and vice versa).
pub mod functions {
    use super::bits::*;
    const ANY_LIVE: u32 = ME_MODES
        | INSTANTIATED
        | INIT_MODE
        | STEP_COMPLETE
        | STEP_IN_PROGRESS
        | STEP_FAILED
        | STEP_CANCELED
        | TERMINATED
        | ERROR;
    const AFTER_INIT: u32 =
        ME_MODES | INIT_MODE | STEP_COMPLETE | STEP_FAILED | STEP_CANCELED | TERMINATED | ERROR;
    const STATE_OPS: u32 = ANY_LIVE & !STEP_IN_PROGRESS;
    /// Where `fmi2Set*` (and the input derivatives) may be called.
    const SETTABLE: u32 = ME_MODES | INSTANTIATED | INIT_MODE | STEP_COMPLETE;
    /// Where the `fmi2Get*Status` queries may be called: once stepping has begun.
    const STATUS_QUERIES: u32 =
        STEP_COMPLETE | STEP_IN_PROGRESS | STEP_FAILED | STEP_CANCELED | TERMINATED;

    const TERMINABLE: u32 = ME_MODES | STEP_COMPLETE | STEP_FAILED | STEP_CANCELED;
    super::shared_functions!(
        "fmi2",
        "FMUstate",
        "DeSerializeFMUstate",
        "Real",
        "Integer",
        ANY_LIVE,
        STATE_OPS,
        AFTER_INIT,
        SETTABLE,
        TERMINABLE
    );
    f! { SETUP_EXPERIMENT, "fmi2SetupExperiment", INSTANTIATED }
    f! { SET_REAL_INPUT_DERIVATIVES, "fmi2SetRealInputDerivatives", SETTABLE }
    f! { GET_REAL_OUTPUT_DERIVATIVES, "fmi2GetRealOutputDerivatives", STEP_COMPLETE | STEP_FAILED | STEP_CANCELED | TERMINATED | ERROR }
    f! { CANCEL_STEP, "fmi2CancelStep", STEP_IN_PROGRESS }
    f! { GET_STATUS, "fmi2GetStatus", STATUS_QUERIES }
    f! { GET_REAL_STATUS, "fmi2GetRealStatus", STATUS_QUERIES }
    f! { GET_INTEGER_STATUS, "fmi2GetIntegerStatus", STATUS_QUERIES }
    f! { GET_BOOLEAN_STATUS, "fmi2GetBooleanStatus", STATUS_QUERIES }
    f! { GET_STRING_STATUS, "fmi2GetStringStatus", STATUS_QUERIES }
    f! { GET_DERIVATIVES, "fmi2GetDerivatives", ME_AFTER_INIT }
    f! { NEW_DISCRETE_STATES, "fmi2NewDiscreteStates", EVENT_MODE }
}

/// The names of the states in `f`'s mask, in the vocabulary of `f`'s FMI version (FMI 3.0
/// calls `StepComplete` Step Mode).
fn state_names(f: &Function) -> String {
    ModelState::ALL
        .iter()
        .filter(|s| f.mask & s.bit() != 0)
        .map(|s| state_name(f, *s))
        .collect::<Vec<_>>()
        .join(", ")
}

/// ` (value reference N)` for a scalar of the table, in `f`'s messages; nothing for FMI 3.0,
/// whose value references name whole arrays (the element's name says which).
fn reference(f: &Function, vr: u32) -> String {
    if f.name.starts_with("fmi3") {
        String::new()
    } else {
        format!(" (value reference {vr})")
    }
}

/// The name of `state` as `f`'s FMI version calls it.
fn state_name(f: &Function, state: ModelState) -> String {
    match (f.name.starts_with("fmi3"), state) {
        (true, ModelState::StepComplete) => "StepMode".to_string(),
        _ => state.to_string(),
    }
}

/// Where log messages go: the master's callback (see [`crate::ffi`]) or memory (tests).
pub trait LogSink {
    /// Delivers one message.
    fn deliver(&self, instance: &str, status: Status, category: &str, text: &str);
}

/// The instance's logger: filters by `loggingOn` and categories, then hands to the sink.
/// Warnings, discards, errors and fatals are always delivered: a user must learn why a call
/// failed even with debug logging off.
pub struct Logger {
    sink: Box<dyn LogSink>,
    instance_name: String,
    logging_on: bool,
    /// Enabled categories; empty means all.
    categories: Vec<String>,
    /// Whether model events (`logEvents`, [`Context::log_event`]) are delivered: kept with
    /// `logging_on` and `categories`, so a model call asks no question of the logger.
    events: bool,
}

impl Logger {
    /// A logger for `instance_name` writing to `sink`.
    pub fn new(instance_name: &str, sink: Box<dyn LogSink>, logging_on: bool) -> Self {
        Self {
            sink,
            instance_name: instance_name.to_string(),
            logging_on,
            categories: Vec::new(),
            events: logging_on,
        }
    }
    /// Debug logging on or off, for `categories` (empty: all).
    pub fn configure(&mut self, logging_on: bool, categories: &[String]) {
        self.logging_on = logging_on;
        self.categories = categories.to_vec();
        self.events = self.enabled(Status::Ok, EVENTS);
    }
    /// Whether a message with `status` under `category` is delivered: always for warnings
    /// and worse, for `Ok` when debug logging is on and the category enabled.
    pub fn enabled(&self, status: Status, category: &str) -> bool {
        status != Status::Ok
            || (self.logging_on
                && (self.categories.is_empty()
                    || self
                        .categories
                        .iter()
                        .any(|c| c == category || c == "logAll")))
    }
    /// Logs `text` with `status` under `category`.
    pub fn log(&self, status: Status, category: &str, text: &str) {
        if self.enabled(status, category) {
            self.sink
                .deliver(&self.instance_name, status, category, text);
        }
    }
    /// Logs an error.
    pub fn error(&self, text: &str) {
        self.log(Status::Error, Status::Error.category(), text);
    }
    /// The instance name.
    pub fn instance_name(&self) -> &str {
        &self.instance_name
    }
}

/// The part of an instance that an FMU state captures.
#[derive(Clone)]
pub struct Core<M> {
    pub(crate) model: M,
    pub(crate) values: Values,
    pub(crate) time: f64,
    pub(crate) state: ModelState,
    stop_time: Option<f64>,
    /// Inputs were set since the outputs were last computed (Model Exchange: inputs, states
    /// or time were set since the derivatives were last evaluated).
    pub(crate) inputs_changed: bool,
}

const STATE_MAGIC: &str = "spurio-fmu-state/2";

/// How `fmi*Set*`/`fmi*Get*` may access one variable, precomputed from its declaration
/// (once per configuration, in [`Interface`]), so that a call checks a value in a few
/// instructions: its type, the states in which it may be set, and its bounds.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Access {
    /// The variable's type.
    pub variable_type: VariableType,
    /// In one word: the states ([`ModelState::bit`]) in which `fmi*Set*` may set it, its
    /// type's bit ([`Access::type_bit`]) and [`Access::INPUT`], [`Access::PARAMETER`]; a set
    /// is allowed when `bits & need == need` with `need` = state bit | type bit.
    pub bits: u32,
    /// Lower bound (−`f64::MAX` when none, so that `min <= x && x <= max` also says that
    /// `x` is finite: NaN fails both comparisons, ±∞ one).
    pub min: f64,
    /// Upper bound (`f64::MAX` when none).
    pub max: f64,
}

impl Access {
    /// The bit of an input (setting it invalidates the direct-feedthrough outputs).
    pub const INPUT: u32 = 1 << 24;
    /// The bit of a parameter (setting it in Step Mode calls `parameters_changed`).
    pub const PARAMETER: u32 = 1 << 25;

    /// The bit of type `t` in [`Access::bits`] (above the state bits).
    #[inline(always)]
    pub const fn type_bit(t: VariableType) -> u32 {
        1 << (16 + t as u32)
    }

    /// Whether value `x` may be set where `need` (state bit | type bit, see [`Access::bits`])
    /// is asked: the state and type allowed, `x` finite and within the bounds.
    #[inline(always)]
    pub fn admits(&self, need: u32, x: f64) -> bool {
        self.bits & need == need && x >= self.min && x <= self.max
    }

    /// Whether the variable may be set in the state with bit `state`.
    pub fn settable_in(&self, state: u32) -> bool {
        self.bits & state != 0
    }

    /// Whether the variable is an input.
    pub fn is_input(&self) -> bool {
        self.bits & Self::INPUT != 0
    }

    /// Whether the variable is a parameter.
    pub fn is_parameter(&self) -> bool {
        self.bits & Self::PARAMETER != 0
    }

    /// The access rules of `v` (FMI 2.0.4 §3.2.3 / FMI 3.0.2 §2.4.7: what may be set when).
    pub fn of(v: &Variable) -> Self {
        let not_constant = v.variability != Variability::Constant;
        let input = v.causality == Causality::Input;
        let mut settable = 0;
        if not_constant && (input || matches!(v.initial, Some(Initial::Exact | Initial::Approx))) {
            settable |= INSTANTIATED;
        }
        if not_constant && (input || v.initial == Some(Initial::Exact)) {
            settable |= INIT_MODE;
        }
        if input || (v.causality == Causality::Parameter && v.variability == Variability::Tunable) {
            settable |= STEP_COMPLETE | EVENT_MODE;
        }
        // Continuous-Time Mode: continuous-time inputs only; a discrete input changes at
        // events alone (FMI 2.0.4 §3.2.3, FMI 3.0.2 §3.2.1).
        if input && v.variability == Variability::Continuous {
            settable |= CONTINUOUS_TIME_MODE;
        }
        let mut bits = settable | Self::type_bit(v.variable_type());
        if input {
            bits |= Self::INPUT;
        }
        if v.causality == Causality::Parameter {
            bits |= Self::PARAMETER;
        }
        Self {
            variable_type: v.variable_type(),
            bits,
            min: v.min.unwrap_or(-f64::MAX),
            max: v.max.unwrap_or(f64::MAX),
        }
    }
}

/// The value references [`Instance::set_spans`] keeps on the stack for a call of scalars:
/// the master's calls (the inputs of one instance) name at most this many.
const SCALARS: usize = 16;

/// An instance of model `M`.
pub struct Instance<M: FmuModel> {
    /// The model description and access table, shared by every instance of the configuration.
    pub(crate) interface: Arc<Interface>,
    logger: Logger,
    pub(crate) core: Core<M>,
    /// The model's Model Exchange functions, if it has them (directional derivatives serve
    /// Co-Simulation too).
    pub(crate) me: Option<Hooks<M>>,
    /// Whether the instance was instantiated for Model Exchange.
    pub(crate) model_exchange: bool,
    /// Model Exchange: the event indicators, computed when read.
    pub(crate) indicators: crate::me::Indicators,
    /// The values a model call may change ([`Interface::computed`]) as they were before the
    /// current call (a reused buffer), restored when the call produces a
    /// non-finite value; empty when the interface has a [`Interface::window`] (then
    /// `before_window` holds them).
    before: Vec<f64>,
    /// The values of the [`Interface::window`] before the current call, when it has one.
    before_window: [f64; WINDOW],
    /// The String texts before the current call, when a String is among the computed
    /// variables ([`Interface::computed_texts`]).
    before_texts: Vec<(usize, String)>,
    /// When the instance audits its model ([`Instance::audit_model_writes`]; always in debug
    /// builds): every value before the current call, to check that the model changed only
    /// computed ones.
    audit: Option<Box<Values>>,
}

impl<M: FmuModel> Instance<M> {
    /// A new instance in state `Instantiated`, with the start values of `info`.
    pub fn new(info: ModelInfo, logger: Logger) -> Result<Self, Cause> {
        Self::of(Arc::new(Interface::new(info)), logger)
    }

    /// A new instance of a shared interface (see [`crate::front::interface`]), in state
    /// `Instantiated` with its start values.
    pub fn of(interface: Arc<Interface>, logger: Logger) -> Result<Self, Cause> {
        let model = M::create(&interface.info)?;
        let values = Values::from_start(&interface.info.variables);
        Ok(Self {
            before: match interface.window {
                Some(_) => Vec::new(),
                None => vec![0.0; interface.computed_len()],
            },
            before_window: [0.0; WINDOW],
            interface,
            logger,
            me: None,
            model_exchange: false,
            indicators: Default::default(),
            before_texts: values.texts().clone(),
            audit: cfg!(debug_assertions).then(|| Box::new(values.clone())),
            core: Core {
                model,
                values,
                time: 0.0,
                state: ModelState::Instantiated,
                stop_time: None,
                inputs_changed: false,
            },
        })
    }

    /// The model description this instance was created from.
    pub fn info(&self) -> &ModelInfo {
        &self.interface.info
    }
    /// The shared interface: description, access table, FMI 3.0 arrays.
    pub fn interface(&self) -> &Arc<Interface> {
        &self.interface
    }
    /// The current values.
    pub fn values(&self) -> &Values {
        &self.core.values
    }
    /// The logger.
    pub fn logger(&self) -> &Logger {
        &self.logger
    }
    /// The current state of the state machine.
    pub fn state(&self) -> ModelState {
        self.core.state
    }
    /// The current simulation time.
    pub fn time(&self) -> f64 {
        self.core.time
    }
    /// The model (for tests and benchmarks).
    pub fn model(&self) -> &M {
        &self.core.model
    }

    /// Checks that `f` may be called now; logs and returns `false` when not.
    #[inline(always)]
    pub fn allows(&self, f: &Function) -> bool {
        f.mask & self.core.state.bit() != 0 || self.illegal_call(f)
    }

    /// Logs that `f` may not be called in the current state; `false`.
    #[cold]
    #[inline(never)]
    fn illegal_call(&self, f: &Function) -> bool {
        self.logger.error(&format!(
            "{}: illegal call sequence: not allowed in state {} (allowed in: {})",
            f.name,
            state_name(f, self.core.state),
            state_names(f)
        ));
        false
    }

    /// Logs an error for function `f` and returns `Status::Error`; the state is unchanged.
    #[cold]
    #[inline(never)]
    pub fn reject(&self, f: &Function, message: &str) -> Status {
        self.logger.error(&format!("{}: {}", f.name, message));
        Status::Error
    }

    /// Marks the instance as fatally broken (after a panic was caught).
    pub fn set_fatal(&mut self, f: &Function, message: &str) {
        self.core.state = ModelState::Fatal;
        self.logger.log(
            Status::Fatal,
            Status::Fatal.category(),
            &format!("{}: internal error: {message}", f.name),
        );
    }

    /// Runs one model call (initialisation, a step, direct feedthrough, parameters changed,
    /// a Model Exchange evaluation) on the values, then checks what it computed: the values
    /// a call may write ([`Interface::computed`]: outputs, locals, calculated parameters) are
    /// copied before it and scanned after it ([`crate::variables::all_finite`]); a non-finite
    /// one puts them back and is `Error` naming the variable. The model's messages are
    /// logged, its failure is the call's status.
    #[inline]
    pub(crate) fn run_model(
        &mut self,
        f: &Function,
        call: impl FnOnce(&mut M, &mut Context) -> Result<(), Failure>,
    ) -> Status {
        self.save_computed();
        let mut ctx = Context::at(&mut self.core.values, self.core.time);
        ctx.log_events = self.logger.events;
        let result = call(&mut self.core.model, &mut ctx);
        let status = if ctx.messages.is_empty() {
            Status::Ok
        } else {
            let messages = ctx.take_messages();
            self.deliver(&messages)
        };
        if self.audit.is_some() {
            if let Some(index) = self.changed_uncomputed() {
                return self.meddled(f, index);
            }
        }
        match result {
            Ok(()) if self.computed_finite() => status,
            Ok(()) => self.unpublish(f),
            Err(failure) => self.model_failed(f, failure),
        }
    }

    /// Copies the values a model call may change into the roll-back buffer.
    #[inline(always)]
    fn save_computed(&mut self) {
        let numbers = self.core.values.numbers();
        let mut to = self.before.as_mut_slice();
        if let Some(window) = &self.interface.window {
            // a fixed block (two vector moves), whatever the run's length
            if let Some(from) = numbers.get(window.start..window.start + WINDOW) {
                self.before_window.copy_from_slice(from);
            }
        } else {
            match &self.interface.computed[..] {
                // the common table: outputs in one block (no loop, one copy)
                [run] => {
                    if let Some(from) = numbers.get(run.clone()) {
                        if from.len() == to.len() && !copy_short(to, from) {
                            to.copy_from_slice(from);
                        }
                    }
                }
                runs => {
                    for run in runs {
                        let (Some(from), Some((head, tail))) =
                            (numbers.get(run.clone()), to.split_at_mut_checked(run.len()))
                        else {
                            break;
                        };
                        head.copy_from_slice(from);
                        to = tail;
                    }
                }
            }
        }
        if self.interface.computed_texts {
            self.before_texts.clone_from(self.core.values.texts());
        }
        if let Some(all) = &mut self.audit {
            (**all).clone_from(&self.core.values);
        }
    }

    /// Puts back the values [`Instance::save_computed`] copied.
    fn restore_computed(&mut self) {
        let numbers = self.core.values.numbers_mut();
        let mut from = self.before.as_slice();
        if let Some(window) = &self.interface.window {
            if let Some(to) = numbers.get_mut(window.start..window.start + WINDOW) {
                for ((to, from), lane) in to.iter_mut().zip(self.before_window).zip(window.lanes) {
                    if lane {
                        *to = from;
                    }
                }
            }
        } else {
            for run in &self.interface.computed {
                let (Some(to), Some((head, tail))) = (
                    numbers.get_mut(run.clone()),
                    from.split_at_checked(run.len()),
                ) else {
                    break;
                };
                to.copy_from_slice(head);
                from = tail;
            }
        }
        if self.interface.computed_texts {
            self.core.values.texts_mut().clone_from(&self.before_texts);
        }
    }

    /// Whether every value a model call may change is finite (branch-free scan).
    #[inline(always)]
    fn computed_finite(&self) -> bool {
        let numbers = self.core.values.numbers();
        if let Some(window) = &self.interface.window {
            // Branch-free, a few vector instructions: a lane of the run times 0 is ±0 when it
            // is finite and NaN when not; the other lanes are masked to +0 first.
            let Some(xs) = numbers
                .get(window.start..)
                .and_then(|n| n.first_chunk::<WINDOW>())
            else {
                return true;
            };
            let z: [f64; WINDOW] =
                std::array::from_fn(|k| f64::from_bits(xs[k].to_bits() & window.keep[k]) * 0.0);
            // (lanes 0 + 2 and 1 + 3: two vector halves added as they are, no shuffle)
            return (z[0] + z[2]) + (z[1] + z[3]) == 0.0;
        }
        match &self.interface.computed[..] {
            [run] => numbers.get(run.clone()).is_none_or(|xs| match xs.len() {
                // a short run (a scalar filter's outputs) value by value, no lanes to set up
                0..=SHORT_RUN => xs.iter().all(|x| x.is_finite()),
                _ => all_finite(xs),
            }),
            runs => runs
                .iter()
                .all(|run| numbers.get(run.clone()).is_none_or(all_finite)),
        }
    }

    /// Checks, from now on, after every model call that the model wrote only the values it
    /// computes — the contract [`Instance::run_model`] relies on (parameters and inputs are
    /// the master's) — at the cost of a copy of every value per call: for tests (the
    /// [`crate::harness::Harness`] turns it on; debug builds always do).
    pub fn audit_model_writes(&mut self) {
        self.audit = Some(Box::new(self.core.values.clone()));
    }

    /// Under the audit: the first value outside [`Interface::computed`] the last model call
    /// changed.
    #[cold]
    #[inline(never)]
    fn changed_uncomputed(&self) -> Option<usize> {
        let before = self.audit.as_deref()?;
        let (now, was) = (self.core.values.numbers(), before.numbers());
        (0..now.len()).find(|&i| {
            now[i].to_bits() != was[i].to_bits()
                && !self.interface.computed.iter().any(|run| run.contains(&i))
        })
    }

    /// A model call that changed the parameter or input at `index`: every value back to
    /// before the call, `Error` naming the variable (a bug of the model).
    #[cold]
    #[inline(never)]
    fn meddled(&mut self, f: &Function, index: usize) -> Status {
        if let Some(before) = &self.audit {
            self.core.values.clone_from(&**before);
        }
        self.core.state = ModelState::Error;
        let name = self
            .interface
            .info
            .variables
            .get(index)
            .map_or("?", |v| v.name.as_str());
        self.logger.error(&format!(
            "{}: internal error: the model changed variable `{name}` (value reference {index}), a parameter or input that only the master sets",
            f.name
        ));
        Status::Error
    }

    /// Logs the model's messages; the worst status among them.
    #[cold]
    #[inline(never)]
    fn deliver(&self, messages: &[LogMessage]) -> Status {
        let mut status = Status::Ok;
        for m in messages {
            self.logger.log(m.status, m.category, &m.text);
            status = status.max(m.status);
        }
        status
    }

    /// After a model call produced a non-finite value: the values back, `Error` naming the
    /// first such variable.
    #[cold]
    #[inline(never)]
    fn unpublish(&mut self, f: &Function) -> Status {
        let numbers = self.core.values.numbers();
        let found = self.interface.computed.iter().find_map(|run| {
            let (k, x) = first_non_finite(numbers.get(run.clone())?)?;
            Some((run.start + k, x))
        });
        self.restore_computed();
        self.core.state = ModelState::Error;
        let (index, value) = found.unwrap_or((usize::MAX, f64::NAN));
        self.logger.error(&format!(
            "{}: variable `{}` (value reference {index}) came out as {value}: not published (the variables keep their values from before the call; fmi2Reset or fmi2SetFMUstate lead on)",
            f.name,
            self.interface.info.variables.get(index).map_or("?", |v| v.name.as_str())
        ));
        Status::Error
    }

    /// A model call that failed: `Discard` (the instance intact) or `Error` (the instance
    /// in the `Error` state), the cause logged.
    #[cold]
    #[inline(never)]
    fn model_failed(&mut self, f: &Function, failure: Failure) -> Status {
        match failure {
            Failure::Discard(message) => {
                self.logger.log(
                    Status::Discard,
                    Status::Discard.category(),
                    &format!("{}: {message}", f.name),
                );
                Status::Discard
            }
            Failure::Error(message) => {
                self.logger.error(&format!("{}: {message}", f.name));
                self.core.state = ModelState::Error;
                Status::Error
            }
        }
    }

    /// `fmi2SetDebugLogging`.
    pub fn set_debug_logging(&mut self, logging_on: bool, categories: &[String]) -> Status {
        self.set_debug_logging_as(&functions::SET_DEBUG_LOGGING, logging_on, categories)
    }

    /// `fmi2SetDebugLogging` or its FMI 3.0 twin `f`.
    pub fn set_debug_logging_as(
        &mut self,
        f: &Function,
        logging_on: bool,
        categories: &[String],
    ) -> Status {
        for c in categories {
            if !crate::description::LOG_CATEGORIES
                .iter()
                .any(|(n, _)| n == c)
            {
                let known: Vec<&str> = crate::description::LOG_CATEGORIES
                    .iter()
                    .map(|(n, _)| *n)
                    .collect();
                return self.reject(
                    f,
                    &format!("unknown log category `{c}` (known: {})", known.join(", ")),
                );
            }
        }
        self.logger.configure(logging_on, categories);
        Status::Ok
    }

    /// `fmi2SetupExperiment`.
    pub fn setup_experiment(&mut self, start_time: f64, stop_time: Option<f64>) -> Status {
        self.setup_experiment_as(&functions::SETUP_EXPERIMENT, start_time, stop_time)
    }

    /// The experiment set up by `f` (`fmi2SetupExperiment`, `fmi3EnterInitializationMode`).
    pub fn setup_experiment_as(
        &mut self,
        f: &Function,
        start_time: f64,
        stop_time: Option<f64>,
    ) -> Status {
        if !start_time.is_finite() {
            return self.reject(f, &format!("startTime must be finite, got {start_time}"));
        }
        if let Some(stop) = stop_time {
            if !stop.is_finite() || stop < start_time {
                return self.reject(
                    f,
                    &format!(
                        "stopTime = {stop:.16} must be finite and not before startTime = {start_time:.16}"
                    ),
                );
            }
        }
        self.core.time = start_time;
        self.core.stop_time = stop_time;
        Status::Ok
    }

    /// `fmi2EnterInitializationMode`.
    pub fn enter_initialization_mode(&mut self) -> Status {
        self.core.state = ModelState::InitializationMode;
        Status::Ok
    }

    /// `fmi2ExitInitializationMode`: the model reads its parameters and computes its outputs.
    pub fn exit_initialization_mode(&mut self) -> Status {
        self.exit_initialization_mode_as(&functions::EXIT_INITIALIZATION_MODE)
    }

    /// `fmi2ExitInitializationMode` or its FMI 3.0 twin `f` (into Step Mode).
    pub fn exit_initialization_mode_as(&mut self, f: &Function) -> Status {
        let status = self.run_model(f, |m, ctx| m.initialize(ctx));
        if status <= Status::Warning {
            self.core.state = if self.model_exchange {
                self.core.inputs_changed = true;
                ModelState::EventMode
            } else {
                ModelState::StepComplete
            };
        }
        status
    }

    /// `fmi2Terminate`.
    pub fn terminate(&mut self) -> Status {
        self.core.state = ModelState::Terminated;
        Status::Ok
    }

    /// `fmi2Reset`: back to `Instantiated` with the start values.
    pub fn reset(&mut self) -> Status {
        self.reset_as(&functions::RESET)
    }

    /// `fmi2Reset` or its FMI 3.0 twin `f`.
    pub fn reset_as(&mut self, f: &Function) -> Status {
        match M::create(&self.interface.info) {
            Ok(model) => {
                self.core = Core {
                    model,
                    values: Values::from_start(&self.interface.info.variables),
                    time: 0.0,
                    state: ModelState::Instantiated,
                    stop_time: None,
                    inputs_changed: false,
                };
                Status::Ok
            }
            Err(e) => self.reject(f, &e.to_string()),
        }
    }

    /// `fmi2Get{Real,Integer,Boolean,String}`: checks every reference, then hands each
    /// value's position in the call, the values and its index to `out`, in order.
    pub fn get_values(
        &mut self,
        f: &Function,
        vrs: &[u32],
        expected: VariableType,
        mut out: impl FnMut(usize, &Values, usize),
    ) -> Status {
        if let Some(&vr) = vrs.iter().find(|vr| !self.is_of_type(**vr, expected)) {
            return self.reject(f, &self.type_error(vr, expected));
        }
        let status = self.refresh_for(f, vrs.iter().map(|&vr| vr as usize));
        if status > Status::Warning {
            return status;
        }
        let values = &self.core.values;
        for (i, vr) in vrs.iter().enumerate() {
            out(i, values, *vr as usize);
        }
        status
    }

    /// `fmi2Get{Real,Integer,Boolean}` into the C array `out` (as long as `vrs`), each
    /// number ([`Values::numbers`]) turned into the C type by `to_c`. The path of a master's
    /// every step: one tight pass (bounds and type of the reference, one load, one store a
    /// value); the references are checked first only when the model computes before the
    /// read; on an error the values already written are undefined, as FMI 2.0.4 §2.1.3
    /// allows.
    #[inline(always)]
    pub fn get_array<C>(
        &mut self,
        f: &Function,
        expected: VariableType,
        vrs: &[u32],
        out: &mut [C],
        to_c: impl Fn(f64) -> C,
    ) -> Status {
        let mut status = Status::Ok;
        if self.needs_refresh() || self.reads_pending_indicator(vrs, false) {
            status = self.refresh_before_get(f, vrs, expected);
            if status > Status::Warning {
                return status;
            }
        }
        let access: &[Access] = &self.interface.access;
        let Some(numbers) = self.core.values.numbers().get(..access.len()) else {
            return self.reject(f, "internal: the values do not match the variable table");
        };
        for (o, &vr) in out.iter_mut().zip(vrs) {
            match access.get(vr as usize) {
                Some(a) if a.variable_type == expected => *o = to_c(numbers[vr as usize]),
                _ => return self.reject(f, &self.type_error(vr, expected)),
            }
        }
        status
    }

    /// Before a get of `vrs` that needs values computed first: the references checked (so
    /// that a rejected read computes nothing), then [`Instance::refresh_outputs`].
    #[inline(never)]
    pub(crate) fn refresh_before_get(
        &mut self,
        f: &Function,
        vrs: &[u32],
        expected: VariableType,
    ) -> Status {
        if let Some(&vr) = vrs.iter().find(|vr| !self.is_of_type(**vr, expected)) {
            return self.reject(f, &self.type_error(vr, expected));
        }
        self.refresh_for(f, vrs.iter().map(|&vr| vr as usize))
    }

    /// Before values are read by `f`: in Initialization Mode the model computes the outputs
    /// and calculated parameters from the current parameters; in Step Mode, after inputs
    /// were set, it recomputes the direct-feedthrough outputs; a Model Exchange instance
    /// evaluates its derivatives and outputs when states, inputs or time changed. Otherwise
    /// nothing to do.
    pub fn refresh_outputs(&mut self, f: &Function) -> Status {
        if self.model_exchange {
            // Outputs and derivatives from the current states, inputs and time.
            return self.evaluate(f);
        }
        if !self.needs_refresh() {
            return Status::Ok;
        }
        if self.core.state == ModelState::InitializationMode {
            self.run_model(f, |m, ctx| m.initialize(ctx))
        } else if self.core.inputs_changed && self.core.state == ModelState::StepComplete {
            let status = self.run_model(f, |m, ctx| m.update_outputs(ctx));
            if status <= Status::Warning {
                self.core.inputs_changed = false;
            }
            status
        } else {
            Status::Ok
        }
    }

    /// Before `f` reads the variables at table indices `read`: [`Instance::refresh_outputs`],
    /// then the event indicators when one of them is read ([`Instance::indicators_for`]).
    pub(crate) fn refresh_for(
        &mut self,
        f: &Function,
        read: impl Iterator<Item = usize>,
    ) -> Status {
        let status = self.refresh_outputs(f);
        if status > Status::Warning {
            return status;
        }
        status.max(self.indicators_for(f, read))
    }

    /// Whether values must be computed before they are read ([`Instance::refresh_outputs`]).
    /// The event indicators are not among them: a read computes them only when it names one
    /// ([`Instance::reads_pending_indicator`]).
    #[inline]
    pub(crate) fn needs_refresh(&self) -> bool {
        let state = self.core.state;
        state == ModelState::InitializationMode
            || (self.core.inputs_changed
                && (state == ModelState::StepComplete || (self.model_exchange && state.computes())))
    }

    /// Whether value reference `vr` names a variable of type `expected`.
    #[inline]
    pub fn is_of_type(&self, vr: u32, expected: VariableType) -> bool {
        self.interface
            .access
            .get(vr as usize)
            .is_some_and(|a| a.variable_type == expected)
    }

    /// Why FMI 2.0 value reference `vr` names no variable.
    pub(crate) fn unknown_reference(&self, vr: usize) -> String {
        let info = &self.interface.info;
        format!(
            "unknown value reference {vr} ({} has value references 0 to {})",
            info.model_identifier,
            info.variables.len().saturating_sub(1)
        )
    }

    /// Why `vr` is not a variable of type `expected` (unknown, or of another type).
    fn type_error(&self, vr: u32, expected: VariableType) -> String {
        let info = &self.interface.info;
        match info.variables.get(vr as usize) {
            None => self.unknown_reference(vr as usize),
            Some(v) => format!(
                "variable `{}` (value reference {vr}) is of type {}, not {expected}",
                v.name,
                v.variable_type()
            ),
        }
    }

    /// Why the variable at `vr` cannot be set by `f` in the current state.
    fn not_settable(&self, f: &Function, vr: u32) -> String {
        let v = &self.interface.info.variables[vr as usize];
        let what = match (v.causality, v.variability) {
            (Causality::Parameter, Variability::Fixed) if f.name.starts_with("fmi3") => {
                "a fixed parameter: it can be set only before fmi3ExitInitializationMode"
            }
            (Causality::Parameter, Variability::Fixed) => {
                "a fixed parameter: it can be set only before fmi2ExitInitializationMode"
            }
            (Causality::Output, _) => "an output: the FMU computes it",
            (Causality::CalculatedParameter, _) => "a calculated parameter: the FMU computes it",
            _ => "not settable now",
        };
        format!(
            "variable `{}`{} is {what} (state {})",
            v.name,
            reference(f, vr),
            state_name(f, self.core.state)
        )
    }

    /// Checks that `f` may set the variable at `vr` to a value of type `actual` (`number`: its
    /// value as a number, for the finiteness and bounds checks) in the current state (its
    /// bit `bit`); its access rules, or the rejection's status.
    #[inline(always)]
    fn check_set(
        &self,
        f: &Function,
        bit: u32,
        vr: u32,
        actual: VariableType,
        number: Option<f64>,
    ) -> Result<&Access, Status> {
        let need = bit | Access::type_bit(actual);
        match self.interface.access.get(vr as usize) {
            Some(a) if number.map_or(a.bits & need == need, |x| a.admits(need, x)) => Ok(a),
            _ => Err(self.reject_set(f, vr, actual, number)),
        }
    }

    /// The rejection of a value [`Instance::check_set`] refuses.
    #[cold]
    #[inline(never)]
    pub(crate) fn reject_set(
        &self,
        f: &Function,
        vr: u32,
        actual: VariableType,
        x: Option<f64>,
    ) -> Status {
        let bit = self.core.state.bit();
        let message = match self.interface.access.get(vr as usize) {
            Some(a) if a.variable_type == actual && !a.settable_in(bit) => self.not_settable(f, vr),
            Some(a) if a.variable_type == actual => {
                self.out_of_range(f, vr, x.unwrap_or(f64::NAN), a)
            }
            _ => self.type_error(vr, actual),
        };
        self.reject(f, &message)
    }

    /// Why `x` is not a value the variable at `vr` accepts: not finite or out of its bounds.
    fn out_of_range(&self, f: &Function, vr: u32, x: f64, a: &Access) -> String {
        let name = &self.interface.info.variables[vr as usize].name;
        if !x.is_finite() {
            format!(
                "variable `{name}`{}: {x} rejected, values must be finite",
                reference(f, vr)
            )
        } else if x < a.min {
            format!("variable `{name}` = {x} is below its minimum {}", a.min)
        } else {
            format!("variable `{name}` = {x} is above its maximum {}", a.max)
        }
    }

    /// After values were set (`flags`: the [`Access::bits`] of the variables set, or-ed):
    /// inputs changed (the direct-feedthrough outputs are stale), parameters changed in Step
    /// Mode (the model is told).
    #[inline(always)]
    pub(crate) fn values_set(&mut self, f: &Function, flags: u32) -> Status {
        let parameters = flags & Access::PARAMETER != 0;
        // Model Exchange: a tunable parameter set in Event Mode changes the derivatives and
        // outputs read next, as an input does.
        self.core.inputs_changed |= flags & Access::INPUT != 0 || parameters && self.model_exchange;
        if parameters {
            return self.parameters_set(f);
        }
        Status::Ok
    }

    /// After parameters were set: in Step Mode (Event Mode), the model is told.
    #[inline(never)]
    fn parameters_set(&mut self, f: &Function) -> Status {
        if matches!(
            self.core.state,
            ModelState::StepComplete | ModelState::EventMode
        ) {
            return self.run_model(f, |m, ctx| m.parameters_changed(ctx));
        }
        Status::Ok
    }

    /// `fmi2Set{Real,Integer,Boolean,String}`: the `(value reference, value)` pairs of
    /// `targets`. Checks every value first (reference, type, whether it may be set in this
    /// state, finiteness, bounds: from the precomputed [`Access`] table), then sets them all,
    /// so a rejected call changes nothing. `targets` is walked twice (hence `Clone`): no
    /// buffer.
    pub fn set_values<I>(&mut self, f: &Function, targets: I) -> Status
    where
        I: Iterator<Item = (u32, Value)> + Clone,
    {
        let bit = self.core.state.bit();
        let mut flags = 0;
        for (vr, value) in targets.clone() {
            let number = match value {
                Value::Real(x) => Some(x),
                Value::Integer(i) => Some(f64::from(i)),
                _ => None,
            };
            match self.check_set(f, bit, vr, value.variable_type(), number) {
                Ok(a) => flags |= a.bits,
                Err(status) => return status,
            }
        }
        for (vr, value) in targets {
            self.core.values.set(vr as usize, value);
        }
        self.values_set(f, flags)
    }

    /// `fmi2Set{Real,Integer,Boolean}`: as [`Instance::set_values`] for values of type
    /// `actual` given as numbers ([`Values::numbers`]), the path of a master's every step:
    /// no value enum, stored in place.
    pub fn set_numbers<I>(&mut self, f: &Function, actual: VariableType, targets: I) -> Status
    where
        I: Iterator<Item = (u32, f64)> + Clone,
    {
        let bit = self.core.state.bit();
        let mut flags = 0;
        for (vr, x) in targets.clone() {
            match self.check_set(f, bit, vr, actual, Some(x)) {
                Ok(a) => flags |= a.bits,
                Err(status) => return status,
            }
        }
        let numbers = self.core.values.numbers_mut();
        for (vr, x) in targets {
            if let Some(slot) = numbers.get_mut(vr as usize) {
                *slot = x;
            }
        }
        self.values_set(f, flags)
    }

    /// `fmi2Set{Real,Integer,Boolean}` from the C arrays: value references `vrs`, values
    /// `values` (of the same length) of a C type that `to_number` turns into stored numbers.
    /// As [`Instance::set_numbers`], in two tight passes over the arrays: the first checks
    /// each value with one load of its [`Access`] (`bits & need == need` for type and state,
    /// `min <= x <= max` for bounds and finiteness), the second stores (one value: checked,
    /// then stored, no loop); any failure goes to the cold path that names the variable and
    /// the reason.
    #[inline(always)]
    pub fn set_array<C: Copy>(
        &mut self,
        f: &Function,
        actual: VariableType,
        (vrs, values): (&[u32], &[C]),
        to_number: impl Fn(C) -> f64,
    ) -> Status {
        let need = self.core.state.bit() | Access::type_bit(actual);
        let access: &[Access] = &self.interface.access;
        if let ([vr], [v]) = (vrs, values) {
            // one value (a master's common call): checked and stored in one go, no loops
            let (vr, x) = (*vr, to_number(*v));
            return match (access.get(vr as usize), self.core.values.numbers_mut()) {
                (Some(a), numbers) if a.admits(need, x) => {
                    let flags = a.bits;
                    if let Some(slot) = numbers.get_mut(vr as usize) {
                        *slot = x;
                    }
                    self.values_set(f, flags)
                }
                _ => self.reject_set(f, vr, actual, Some(x)),
            };
        }
        let mut flags = 0;
        for (&vr, &v) in vrs.iter().zip(values) {
            let x = to_number(v);
            match access.get(vr as usize) {
                Some(a) if a.admits(need, x) => flags |= a.bits,
                _ => return self.reject_set(f, vr, actual, Some(x)),
            }
        }
        let numbers = self.core.values.numbers_mut();
        for (&vr, &v) in vrs.iter().zip(values) {
            if let Some(slot) = numbers.get_mut(vr as usize) {
                *slot = to_number(v);
            }
        }
        self.values_set(f, flags)
    }

    /// `fmi3Set{Float64,Int32,Boolean}`'s fast path: the values `values` (arrays row-major)
    /// for the FMI 3.0 value references `vrs` ([`crate::front::Span`]s), each checked with
    /// its [`Access`] as in [`Instance::set_array`], then stored; `None` when a reference is
    /// unknown or `time`, the count is not `values.len()` or a value is refused: nothing is
    /// changed then, and the full path checks again and says why.
    ///
    /// The master's call, every reference a scalar (`values.len() = vrs.len()`, at most
    /// [`SCALARS`] references), looks each reference up once: its table index is kept on the
    /// stack between the check and the store. A call naming an array is checked, then
    /// stored, span by span.
    #[inline(always)]
    pub(crate) fn set_spans<C: Copy>(
        &mut self,
        f: &Function,
        actual: VariableType,
        vrs: &[u32],
        values: &[C],
        to_number: impl Fn(C) -> f64,
    ) -> Option<Status> {
        let need = self.core.state.bit() | Access::type_bit(actual);
        let (access, spans) = (&self.interface.access, &self.interface.spans);
        let mut flags = 0;
        if vrs.len() == values.len() && vrs.len() <= SCALARS {
            let mut at = [0u32; SCALARS];
            let mut scalars = true;
            for ((index, &vr), &v) in at.iter_mut().zip(vrs).zip(values) {
                let span = spans.get(vr as usize)?;
                if span.len != 1 {
                    scalars = false;
                    break;
                }
                let (a, x) = (access.get(span.first as usize)?, to_number(v));
                if !a.admits(need, x) {
                    return None;
                }
                flags |= a.bits;
                *index = span.first;
            }
            if scalars {
                let numbers = self.core.values.numbers_mut();
                for (&index, &v) in at.iter().zip(values) {
                    if let Some(slot) = numbers.get_mut(index as usize) {
                        *slot = to_number(v);
                    }
                }
                return Some(self.values_set(f, flags));
            }
            flags = 0;
        }
        let mut k = 0;
        for &vr in vrs {
            let span = spans.get(vr as usize).filter(|span| span.len > 0)?;
            let (first, len) = (span.first as usize, span.len as usize);
            if len == 1 {
                let (a, x) = (access.get(first)?, to_number(*values.get(k)?));
                if !a.admits(need, x) {
                    return None;
                }
                flags |= a.bits;
                k += 1;
                continue;
            }
            let xs = values.get(k..k + len)?;
            for (a, &v) in access.get(first..first + len)?.iter().zip(xs) {
                let x = to_number(v);
                if !a.admits(need, x) {
                    return None;
                }
                flags |= a.bits;
            }
            k += len;
        }
        if k != values.len() {
            return None;
        }
        let numbers = self.core.values.numbers_mut();
        let mut k = 0;
        for &vr in vrs {
            if let Some(span) = spans.get(vr as usize) {
                let (first, len) = (span.first as usize, span.len as usize);
                if len == 1 {
                    if let (Some(slot), Some(&v)) = (numbers.get_mut(first), values.get(k)) {
                        *slot = to_number(v);
                    }
                    k += 1;
                    continue;
                }
                if let (Some(to), Some(xs)) =
                    (numbers.get_mut(first..first + len), values.get(k..k + len))
                {
                    for (slot, &v) in to.iter_mut().zip(xs) {
                        *slot = to_number(v);
                    }
                }
                k += len;
            }
        }
        Some(self.values_set(f, flags))
    }

    /// `fmi2DoStep`.
    pub fn do_step(&mut self, current_time: f64, step: f64) -> Status {
        self.do_step_as(&functions::DO_STEP, current_time, step)
    }

    /// `fmi2DoStep` or its FMI 3.0 twin `f`: the arguments checked (a step that is finite,
    /// positive and moves the time, from the current communication point, not past the stop
    /// time), the model's [`FmuModel::check_step`], then the step.
    #[inline]
    pub fn do_step_as(&mut self, f: &Function, current_time: f64, step: f64) -> Status {
        let time = self.core.time;
        let end = current_time + step;
        // `end > current_time` also refuses a NaN, `end < ∞` the rest of a non-finite end
        // (−∞ cannot pass the first)
        let valid = step > 0.0
            && (current_time - time).abs() <= 1e-9 * time.abs().max(1.0)
            && end > current_time
            && end < f64::INFINITY
            && self
                .core
                .stop_time
                .is_none_or(|stop| end <= stop + 1e-9 * stop.abs().max(1.0));
        if !valid {
            return self.reject_step(f, current_time, step);
        }
        let refusal = {
            let ctx = Context::at(&mut self.core.values, current_time);
            self.core.model.check_step(&ctx, current_time, step)
        };
        if let Err(cause) = refusal {
            return self.reject(f, &format!("step refused: {cause}"));
        }
        let status = self.run_model(f, |m, ctx| m.do_step(ctx, current_time, step));
        if status <= Status::Warning {
            self.core.time = end;
            self.core.inputs_changed = false;
        }
        status
    }

    /// The rejection of the arguments of a step [`Instance::do_step_as`] refuses, with the
    /// first reason.
    #[cold]
    #[inline(never)]
    fn reject_step(&self, f: &Function, current_time: f64, step: f64) -> Status {
        let time = self.core.time;
        let end = current_time + step;
        let message = if !step.is_finite() || step <= 0.0 {
            format!("communicationStepSize must be finite and > 0, got {step:.16}")
        } else if !current_time.is_finite()
            || (current_time - time).abs() > 1e-9 * time.abs().max(1.0)
        {
            format!("expected currentCommunicationPoint = {time:.16} but was {current_time:.16}")
        } else if !end.is_finite() {
            format!(
                "the step ends at currentCommunicationPoint + communicationStepSize = {current_time:.16} + {step:.16} = {end}, not a finite time"
            )
        } else if end <= current_time {
            format!(
                "communicationStepSize = {step:.16} is below the time resolution at currentCommunicationPoint = {current_time:.16}: the time would not advance"
            )
        } else {
            let stop = self.core.stop_time.unwrap_or(f64::NAN);
            format!("the step to {end:.16} would pass stopTime = {stop:.16}")
        };
        self.reject(f, &message)
    }

    /// `fmi2GetRealStatus(fmi2LastSuccessfulTime)`.
    pub fn last_successful_time(&self) -> f64 {
        self.core.time
    }

    /// `fmi2GetFMUstate`: a copy of everything that determines the future of the instance.
    pub fn get_state(&self) -> Box<Core<M>> {
        Box::new(self.core.clone())
    }

    /// `fmi2SetFMUstate`.
    pub fn set_state(&mut self, core: &Core<M>) {
        self.core = core.clone();
        self.indicators.invalidate();
    }

    /// `fmi2SerializeFMUstate`: the bytes of a state.
    pub fn serialize(&self, core: &Core<M>) -> Vec<u8> {
        let mut w = ByteWriter::new();
        w.put_str(STATE_MAGIC);
        w.put_str(&self.interface.info.model_identifier);
        w.put_str(&self.interface.info.guid);
        w.put_u64(
            ModelState::ALL
                .iter()
                .position(|s| *s == core.state)
                .unwrap_or(0) as u64,
        );
        w.put_f64(core.time);
        w.put_bool(core.stop_time.is_some());
        w.put_f64(core.stop_time.unwrap_or(0.0));
        w.put_bool(core.inputs_changed);
        w.put_u64(core.values.len() as u64);
        core.values.save(&mut w);
        core.model.save_state(&mut w);
        w.into_bytes()
    }

    /// `fmi2DeSerializeFMUstate`: a state from bytes written by [`Instance::serialize`] of an
    /// instance of the same FMU.
    pub fn deserialize(&self, bytes: &[u8]) -> Result<Box<Core<M>>, StateError> {
        let mut r = ByteReader::new(bytes);
        match r.string() {
            Ok(magic) if magic == STATE_MAGIC => {}
            Ok(magic) if magic.starts_with("spurio-fmu-state/") => {
                return Err(StateError::Version {
                    saved: magic,
                    this: STATE_MAGIC,
                })
            }
            _ => return Err(StateError::NotAState),
        }
        let model = r.string()?;
        if model != self.interface.info.model_identifier {
            return Err(StateError::OtherModel {
                saved: model,
                this: self.interface.info.model_identifier.clone(),
            });
        }
        let guid = r.string()?;
        if guid != self.interface.info.guid {
            return Err(StateError::OtherFmu {
                saved: guid,
                this: self.interface.info.guid.clone(),
            });
        }
        let index = r.u64()?;
        let state = ModelState::from_bits_index(index)
            .filter(|s| s.can_be_saved())
            .filter(|s| {
                let me_only = s.bit() & ME_MODES != 0;
                let cs_only = *s == ModelState::StepComplete;
                !(me_only && !self.model_exchange || cs_only && self.model_exchange)
            })
            .ok_or(StateError::MachineState(index))?;
        let time = r.f64()?;
        if !time.is_finite() {
            return Err(StateError::Time("time", time));
        }
        let has_stop = r.bool()?;
        let stop = r.f64()?;
        if has_stop && (!stop.is_finite() || stop < time - 1e-9 * time.abs().max(1.0)) {
            return Err(StateError::Time("stop time", stop));
        }
        let inputs_changed = r.bool()?;
        let n = r.u64()?;
        if n != self.interface.info.variables.len() as u64 {
            return Err(StateError::ValueCount {
                saved: n,
                variables: self.interface.info.variables.len(),
            });
        }
        let mut values = Values::from_start(&self.interface.info.variables);
        values.load(&mut r)?;
        for (i, v) in self.interface.info.variables.iter().enumerate() {
            let x = match values.variable_type(i) {
                Some(VariableType::Real | VariableType::Integer) => values.number(i),
                _ => continue,
            };
            if !x.is_finite()
                || v.min.is_some_and(|min| x < min)
                || v.max.is_some_and(|max| x > max)
            {
                return Err(StateError::Value {
                    name: v.name.clone(),
                    value: x,
                });
            }
        }
        let mut model = self.core.model.clone();
        model.load_state(&mut r).map_err(StateError::Model)?;
        if r.remaining() != 0 {
            return Err(StateError::LeftOver(r.remaining()));
        }
        Ok(Box::new(Core {
            model,
            values,
            time,
            state,
            stop_time: has_stop.then_some(stop),
            inputs_changed,
        }))
    }
}

/// Why serialized bytes are not a state of this FMU (`fmi2DeSerializeFMUstate`).
#[derive(Debug)]
pub enum StateError {
    /// The bytes do not start with the spurio state header.
    NotAState,
    /// The state was written by another version of the state format.
    Version { saved: String, this: &'static str },
    /// The state belongs to another model.
    OtherModel { saved: String, this: String },
    /// The state belongs to an FMU with another GUID.
    OtherFmu { saved: String, this: String },
    /// The saved state-machine state (its index) is unknown or one no saved state can carry.
    MachineState(u64),
    /// The saved time or stop time is not finite (or the stop time is before the time).
    Time(&'static str, f64),
    /// A saved value is not finite or outside its variable's declared bounds.
    Value { name: String, value: f64 },
    /// The number of saved values is not the number of variables.
    ValueCount { saved: u64, variables: usize },
    /// The bytes are malformed.
    Format(StateFormatError),
    /// The model could not read its part.
    Model(Cause),
    /// Bytes remain after the state.
    LeftOver(usize),
}

impl std::fmt::Display for StateError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::NotAState => write!(f, "the bytes are not a serialized spurio FMU state"),
            Self::Version { saved, this } => write!(
                f,
                "serialized FMU state of format {saved}, this FMU reads {this}"
            ),
            Self::OtherModel { saved, this } => write!(
                f,
                "the state was serialized by model {saved}, this FMU is {this}"
            ),
            Self::OtherFmu { saved, this } => write!(
                f,
                "the state was serialized by an FMU with GUID {saved}, this one is {this}"
            ),
            Self::MachineState(index) => write!(
                f,
                "serialized FMU state: state machine state {index} is not one a saved state can carry ({})",
                ModelState::ALL
                    .iter()
                    .filter(|s| s.can_be_saved())
                    .map(|s| s.to_string())
                    .collect::<Vec<_>>()
                    .join(", ")
            ),
            Self::Time(what, value) => {
                write!(f, "serialized FMU state: its {what} {value} is not valid")
            }
            Self::Value { name, value } => write!(
                f,
                "serialized FMU state: variable `{name}` = {value} is not finite or outside its declared bounds"
            ),
            Self::ValueCount { saved, variables } => write!(
                f,
                "serialized FMU state has {saved} values, the FMU has {variables} variables"
            ),
            Self::Format(e) => write!(f, "{e}"),
            Self::Model(e) => write!(f, "{e}"),
            Self::LeftOver(n) => write!(f, "serialized FMU state has {n} bytes left over"),
        }
    }
}

impl std::error::Error for StateError {}

impl From<StateFormatError> for StateError {
    fn from(e: StateFormatError) -> Self {
        StateError::Format(e)
    }
}

/// The longest run of computed values [`Instance`] copies and scans value by value (no call of
/// the library copy, no lanes of [`all_finite`] to set up): a scalar filter's outputs.
const SHORT_RUN: usize = 4;

/// Copies `from` into `to` when both hold the same number of values, at most [`SHORT_RUN`],
/// entry by entry; `false` (nothing copied) otherwise.
#[inline(always)]
fn copy_short(to: &mut [f64], from: &[f64]) -> bool {
    match (to, from) {
        ([a], [x]) => *a = *x,
        ([a, b], [x, y]) => (*a, *b) = (*x, *y),
        ([a, b, c], [x, y, z]) => (*a, *b, *c) = (*x, *y, *z),
        ([a, b, c, d], [x, y, z, w]) => (*a, *b, *c, *d) = (*x, *y, *z, *w),
        _ => return false,
    }
    true
}

#[cfg(test)]
mod short_run_tests {
    use super::*;

    #[test]
    fn short_runs_are_copied_entry_by_entry_and_longer_ones_refused() {
        let from = [1.5, -2.0, f64::NAN, 4.0, 5.0];
        for n in 1..=SHORT_RUN {
            let mut to = [0.0; 5];
            assert!(copy_short(&mut to[..n], &from[..n]), "{n}");
            for (k, (t, f)) in to.iter().zip(from).enumerate() {
                let expected = if k < n { f.to_bits() } else { 0 };
                assert_eq!(t.to_bits(), expected, "{n} {k}");
            }
        }
        let mut to = [0.0; 5];
        assert!(!copy_short(&mut to, &from));
        assert!(!copy_short(&mut to[..2], &from[..3]));
        assert!(!copy_short(&mut to[..0], &from[..0]));
        assert_eq!(to, [0.0; 5]);
    }
}

#[cfg(test)]
mod window_tests {
    use crate::front::{Window, WINDOW};
    use crate::harness::Harness;
    use crate::types::Status;
    use crate::variables::computed_runs;
    use crate::{ByteReader, ByteWriter, Cause, Config, Context, Failure, FmuModel, ModelInfo};
    use crate::{Variable, VariableType};

    /// Outputs `y[k] = gain · u + k` at the variables the configuration `names` puts them
    /// (`u`, `gain`, `y1`…); `y[last]` comes out NaN when `u = 7`.
    #[derive(Debug, Clone)]
    struct Short {
        u: usize,
        gain: usize,
        y: Vec<usize>,
    }

    fn layout(config: &Config) -> Vec<String> {
        config
            .get("names")
            .unwrap_or("u gain y y y")
            .split(' ')
            .map(str::to_string)
            .collect()
    }

    impl FmuModel for Short {
        fn describe(config: &Config) -> Result<ModelInfo, Cause> {
            let variables = layout(config)
                .iter()
                .enumerate()
                .map(|(k, name)| match name.as_str() {
                    "u" => Variable::input("u", 0.0),
                    "y" => Variable::output(&format!("y{k}")),
                    other => Variable::parameter(&format!("{other}{k}"), 2.0),
                })
                .collect();
            Ok(ModelInfo::new(
                "Short",
                "short",
                variables,
                None,
                config.clone(),
            ))
        }
        fn create(info: &ModelInfo) -> Result<Self, Cause> {
            let names = layout(&info.config);
            let at = |n: &str| names.iter().position(|m| m == n).unwrap_or(0);
            Ok(Self {
                u: at("u"),
                gain: at("gain"),
                y: (0..names.len()).filter(|&k| names[k] == "y").collect(),
            })
        }
        fn initialize(&mut self, ctx: &mut Context) -> Result<(), Failure> {
            self.do_step(ctx, 0.0, 0.0)
        }
        fn do_step(&mut self, ctx: &mut Context, _: f64, _: f64) -> Result<(), Failure> {
            let (u, gain) = (ctx.values.real(self.u), ctx.values.real(self.gain));
            for (k, &y) in self.y.iter().enumerate() {
                let last = k + 1 == self.y.len();
                let v = if last && u == 7.0 {
                    f64::NAN
                } else {
                    gain * u + k as f64
                };
                ctx.values.set_real(y, v);
            }
            Ok(())
        }
        fn save_state(&self, out: &mut ByteWriter) {
            out.put_u64(self.y.len() as u64);
        }
        fn load_state(&mut self, input: &mut ByteReader) -> Result<(), Cause> {
            match input.u64()? {
                n if n == self.y.len() as u64 => Ok(()),
                n => Err(format!("{n} outputs saved, {} here", self.y.len()).into()),
            }
        }
    }

    #[test]
    fn a_short_run_is_checked_in_its_window_and_a_failed_step_loses_nothing() {
        for (names, window) in [
            ("u gain y y y", Some((1, [false, true, true, true]))),
            ("y u gain", None),
            ("u y gain gain", Some((0, [false, true, false, false]))),
            (
                "gain gain u gain y y",
                Some((2, [false, false, true, true])),
            ),
            ("gain y y y y u", Some((1, [true, true, true, true]))),
            ("u y y y y y", None),
        ] {
            let mut config = Config::new();
            config.set("names", names);
            let info = Short::describe(&config).unwrap();
            let runs = computed_runs(&info.variables);
            let found = Window::of(&runs, info.variables.len());
            assert_eq!(found.map(|w| (w.start, w.lanes)), window, "{names}");
            if let Some(w) = found {
                // the lanes are exactly the run
                let lanes: Vec<usize> = (0..WINDOW)
                    .filter(|&k| w.lanes[k])
                    .map(|k| w.start + k)
                    .collect();
                assert_eq!(lanes, runs[0].clone().collect::<Vec<_>>(), "{names}");
            }
            let mut h = Harness::<Short>::new(&config).unwrap();
            let u = info.index_of("u").unwrap() as u32;
            h.initialize(0.0).unwrap();
            h.set_real(&[u], &[1.5]).unwrap();
            h.do_step(0.0, 1.0).unwrap();
            let reals: Vec<u32> = (0..info.variables.len() as u32).collect();
            let read = |h: &mut Harness<Short>| {
                let mut out = vec![0.0; reals.len()];
                h.get_real(&reals, &mut out).unwrap();
                out
            };
            let before = read(&mut h);
            assert!(before.iter().all(|v| v.is_finite()));
            h.set_real(&[u], &[7.0]).unwrap();
            assert_eq!(h.do_step(1.0, 1.0), Err(Status::Error), "{names}");
            let mut after = read(&mut h);
            after[u as usize] = 1.5;
            assert_eq!(after, before, "{names}: the outputs as they were");
            let last_y = info
                .variables
                .iter()
                .rposition(|v| v.name.starts_with('y'))
                .unwrap();
            let (_, _, text) = h.log().pop().unwrap();
            assert!(
                text.contains(&format!(
                    "variable `y{last_y}` (value reference {last_y}) came out as NaN"
                )),
                "{names}: {text}"
            );
            assert!(info
                .variables
                .iter()
                .all(|v| v.variable_type() == VariableType::Real));
        }
    }
}
