//! The state machine shared by both versions: the states, their bits, an FMI function with
//! the states it may be called in, and the two tables of allowed-state masks — FMI 2.0's
//! ([`fmi2`]) and FMI 3.0's ([`fmi3`]), as Reference-FMUs' `fmi2Functions.c` and
//! `fmi3Functions.c` each open with their own `MASK_*` table. A call is allowed when its
//! function's mask has the bit of the instance's state ([`crate::instance::Instance::allows`]).

use std::fmt;

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
    pub(crate) const ALL: [ModelState; 12] = [
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

    pub(crate) fn from_bits_index(i: u64) -> Option<Self> {
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

impl ModelState {
    /// Whether a Model Exchange model computes in this state (Initialization, Event,
    /// Continuous-Time Mode, Terminated): an evaluation after states, inputs or time changed,
    /// the event indicators when read.
    #[inline(always)]
    pub(crate) fn computes(self) -> bool {
        matches!(
            self,
            ModelState::InitializationMode
                | ModelState::EventMode
                | ModelState::ContinuousTimeMode
                | ModelState::Terminated
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
        pub const $id: $crate::instance::state::Function = $crate::instance::state::Function {
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
        use super::function as f;
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

/// Allowed-state masks of the FMI 2.0 functions (FMI 2.0.4, §4.2.4 Co-Simulation and §3.2.3
/// Model Exchange state machines; a Co-Simulation instance never is in the Model Exchange
/// states and vice versa).
pub mod fmi2 {
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
    shared_functions!(
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

/// Allowed-state masks of the FMI 3.0 functions (FMI 3.0.2 §4.3.4 Co-Simulation and §3.3
/// Model Exchange state machines; Step Mode is the shared machine's `StepComplete`).
pub mod fmi3 {
    use super::bits::*;
    /// Every state of an instance that is not fatally broken.
    pub const ANY_LIVE: u32 =
        ME_MODES | INSTANTIATED | INIT_MODE | STEP_COMPLETE | TERMINATED | ERROR;
    const GETTABLE: u32 = ME_MODES | INIT_MODE | STEP_COMPLETE | TERMINATED | ERROR;
    const SETTABLE: u32 = ME_MODES | INSTANTIATED | INIT_MODE | STEP_COMPLETE;

    shared_functions!(
        "fmi3",
        "FMUState",
        "DeserializeFMUState",
        "Float64",
        "Int32",
        ANY_LIVE,
        ANY_LIVE,
        GETTABLE,
        SETTABLE,
        STEP_COMPLETE | ME_MODES
    );
    f! { GET_DERIVATIVES, "fmi3GetContinuousStateDerivatives", ME_AFTER_INIT }
    f! { GET_NUMBER_OF_EVENT_INDICATORS, "fmi3GetNumberOfEventIndicators", ANY_LIVE }
    f! { GET_NUMBER_OF_CONTINUOUS_STATES, "fmi3GetNumberOfContinuousStates", ANY_LIVE }
    f! { UPDATE_DISCRETE_STATES, "fmi3UpdateDiscreteStates", EVENT_MODE }
    f! { GET_ADJOINT_DERIVATIVE, "fmi3GetAdjointDerivative", GETTABLE }
}

/// The names of the states in `f`'s mask, in the vocabulary of `f`'s FMI version (FMI 3.0
/// calls `StepComplete` Step Mode).
pub(crate) fn state_names(f: &Function) -> String {
    ModelState::ALL
        .iter()
        .filter(|s| f.mask & s.bit() != 0)
        .map(|s| state_name(f, *s))
        .collect::<Vec<_>>()
        .join(", ")
}

/// ` (value reference N)` for a scalar of the table, in `f`'s messages; nothing for FMI 3.0,
/// whose value references name whole arrays (the element's name says which).
pub(crate) fn reference(f: &Function, vr: u32) -> String {
    if f.name.starts_with("fmi3") {
        String::new()
    } else {
        format!(" (value reference {vr})")
    }
}

/// The name of `state` as `f`'s FMI version calls it.
pub(crate) fn state_name(f: &Function, state: ModelState) -> String {
    match (f.name.starts_with("fmi3"), state) {
        (true, ModelState::StepComplete) => "StepMode".to_string(),
        _ => state.to_string(),
    }
}
