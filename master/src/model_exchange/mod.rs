//! Model Exchange import: the importer integrates an FMU's continuous states with its own
//! solvers ([`spurio_solvers`]) and handles its events, as FMI 2.0 §3 and FMI 3.0 §3 ask.
//!
//! The driver ([`simulate`]) is written against [`ModelExchangeCalls`], the few calls of the
//! interface, so that it runs any FMU of either version ([`crate::fmu::me::MeInstance`]) and,
//! later, a plant nested inside an estimator FMU; it knows no CLI and no batch tool.
//!
//! **Call sequence** (FMI 2.0 §3.2.2, FMI 3.0 §3.2): set up the experiment, set the start
//! values, enter and exit initialisation mode, then the event iteration (`fmi2NewDiscreteStates`
//! / `fmi3UpdateDiscreteStates` until no new iteration is needed), continuous-time mode, and
//! per solver step `SetTime`, `SetContinuousStates`, `GetDerivatives` for each stage; after an
//! accepted step the event indicators, then `CompletedIntegratorStep`. A time or states equal
//! (bit for bit) to those the FMU holds are not set again (the Jacobian's columns, the
//! indicators at the point the step's last derivative was taken at), so the FMU does not
//! evaluate its equations again for the same point.
//!
//! **Events.** A *state event* is a change of sign of an event indicator `zᵢ` over an accepted
//! step (from `zᵢ > 0` to `zᵢ ≤ 0` or from `zᵢ ≤ 0` to `zᵢ > 0`); its time is located on the
//! solver's dense output by regula falsi on the indicator whose crossing is estimated first,
//! the secant through the last two places of an end that moved twice in a row (so a convex
//! indicator is not approached from one side only), each estimate kept half the tolerance
//! inside the bracket (an estimate next to the root closes the bracket at the next
//! evaluation) and bisection when the bracket does not halve in four iterations, to a
//! bracket of [`event_time_tolerance`] `= 10⁻¹² · max(1, |t|)`, and taken at the bracket's
//! right end (the indicator has changed sign there, so the FMU sees the event); about four
//! indicator evaluations an event on WindGenerator's angle wraps. A *time event* happens at
//! the `nextEventTime` the FMU announced: the solver steps end exactly on it (one announced at
//! or before the current time is due at once, without a step; a NaN one is an error). A *step
//! event* is asked by `CompletedIntegratorStep`. After every event the continuous states and their
//! nominals are read again and the solver starts afresh from them. `terminateSimulation` ends
//! the run normally (recorded and said). More than [`Options::max_events_without_progress`]
//! events without the time moving on, or more than [`Options::max_close_events`] in a row each
//! less than [`close_event_spacing`] after the one before (chattering), or an event iteration
//! that does not settle within [`Options::max_event_iterations`], is an error naming the FMU, the call and the
//! time; so is an FMU call that fails, and derivatives that are not finite.

mod driver;
#[cfg(test)]
mod tests;

pub use driver::{
    close_event_spacing, event_time_tolerance, initialise, simulate, Advance, Event, EventKind,
    Layout, Options, Stepper, Summary,
};
pub use spurio_solvers::{Method, Statistics};

use crate::fmu::{CallError, Experiment, VarType};

/// What `fmi2NewDiscreteStates` / `fmi3UpdateDiscreteStates` said.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct EventUpdate {
    /// Another event iteration is needed.
    pub discrete_states_need_update: bool,
    /// The FMU asks to end the simulation.
    pub terminate_simulation: bool,
    /// The nominals of the continuous states changed.
    pub nominals_changed: bool,
    /// The continuous states changed (re-initialised).
    pub values_changed: bool,
    /// The time of the next time event, if any.
    pub next_event_time: Option<f64>,
}

/// The calls of the Model Exchange interface the driver makes, on one instance (FMI 2.0 or
/// 3.0). Every call returns the FMU's failure as a [`CallError`]; the driver adds the FMU's
/// name, the call and the time.
pub trait ModelExchangeCalls {
    /// The FMU's name (its file and instance) for messages.
    fn name(&self) -> String;
    /// Whether this is an FMI 3.0 instance (for the names of its calls).
    fn is_fmi3(&self) -> bool;
    /// FMI 2.0 `fmi2SetupExperiment` (FMI 3.0: nothing, the experiment goes with
    /// `fmi3EnterInitializationMode`).
    fn setup_experiment(&mut self, experiment: Experiment) -> Result<(), CallError>;
    /// Sets values (start values, inputs) of type `t`.
    fn set(&mut self, t: VarType, vrs: &[u32], values: &[f64]) -> Result<(), CallError>;
    /// Reads values of type `t`.
    fn get(&mut self, t: VarType, vrs: &[u32], out: &mut [f64]) -> Result<(), CallError>;
    /// Enters initialisation mode (FMI 3.0 with the experiment).
    fn enter_initialization_mode(&mut self, experiment: Experiment) -> Result<(), CallError>;
    fn exit_initialization_mode(&mut self) -> Result<(), CallError>;
    fn enter_event_mode(&mut self) -> Result<(), CallError>;
    fn update_discrete_states(&mut self) -> Result<EventUpdate, CallError>;
    fn enter_continuous_time_mode(&mut self) -> Result<(), CallError>;
    /// `CompletedIntegratorStep`: (enter event mode, terminate simulation).
    fn completed_integrator_step(&mut self) -> Result<(bool, bool), CallError>;
    fn set_time(&mut self, time: f64) -> Result<(), CallError>;
    fn set_continuous_states(&mut self, x: &[f64]) -> Result<(), CallError>;
    fn get_continuous_states(&mut self, x: &mut [f64]) -> Result<(), CallError>;
    fn get_nominals(&mut self, nominals: &mut [f64]) -> Result<(), CallError>;
    fn get_derivatives(&mut self, dx: &mut [f64]) -> Result<(), CallError>;
    fn get_event_indicators(&mut self, z: &mut [f64]) -> Result<(), CallError>;
    /// The directional derivative `∂ẋ/∂x · seed` at the current time and states into `out`;
    /// `Ok(false)` when the FMU gives none.
    fn directional_derivative(&mut self, seed: &[f64], out: &mut [f64]) -> Result<bool, CallError>;
    fn terminate(&mut self) -> Result<(), CallError>;
}

/// The calls, named as each version names them.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Call {
    SetupExperiment,
    Set,
    Get,
    EnterInitializationMode,
    ExitInitializationMode,
    EnterEventMode,
    UpdateDiscreteStates,
    EnterContinuousTimeMode,
    CompletedIntegratorStep,
    SetTime,
    SetContinuousStates,
    GetContinuousStates,
    GetNominalsOfContinuousStates,
    GetDerivatives,
    GetEventIndicators,
    GetDirectionalDerivative,
    Terminate,
}

impl Call {
    /// The function's name in FMI 2.0 or (`fmi3`) FMI 3.0: `fmi2` or `fmi3` and the variant's
    /// name, but for the functions that FMI 3.0 renamed or folded into another.
    pub fn name(self, fmi3: bool) -> String {
        let function = match (self, fmi3) {
            (Call::Set, _) => "Set*".to_string(),
            (Call::Get, _) => "Get*".to_string(),
            (Call::UpdateDiscreteStates, false) => "NewDiscreteStates".to_string(),
            (Call::GetDerivatives, true) => "GetContinuousStateDerivatives".to_string(),
            (Call::SetupExperiment, true) => "EnterInitializationMode".to_string(),
            (call, _) => format!("{call:?}"),
        };
        format!("fmi{}{function}", if fmi3 { 3 } else { 2 })
    }
}

/// Why a Model Exchange run stopped before its end.
#[derive(Debug, thiserror::Error)]
pub enum MeError {
    #[error("{fmu}: {call} failed at t = {time}: {reason}")]
    Call {
        fmu: String,
        call: String,
        time: f64,
        reason: String,
    },
    #[error("{fmu}: {call} gave a value that is not finite ({what}) at t = {time}")]
    NotFinite {
        fmu: String,
        call: String,
        time: f64,
        what: String,
    },
    #[error("{fmu}: the solver stopped at t = {time}: {reason}")]
    Solver {
        fmu: String,
        time: f64,
        reason: String,
    },
    #[error("{fmu}: {events} events at t = {time} without the time moving on (chattering; the bound is {bound}); the events come from {call}")]
    Chattering {
        fmu: String,
        time: f64,
        events: usize,
        bound: usize,
        call: String,
    },
    #[error("{fmu}: {events} events from t = {from} to t = {time}, each less than {spacing:e} s after the one before (chattering; the bound is {bound} in a row): the model switches back and forth at an event surface")]
    CloseEvents {
        fmu: String,
        from: f64,
        time: f64,
        events: usize,
        spacing: f64,
        bound: usize,
    },
    #[error("{fmu}: the event iteration at t = {time} did not settle: {call} still asked for another iteration after {iterations}")]
    EventIteration {
        fmu: String,
        call: String,
        time: f64,
        iterations: usize,
    },
    #[error("{fmu}: the layout does not fit the FMU: {reason}")]
    Layout { fmu: String, reason: String },
    /// The I/O error's text is the message's, not a source (said once).
    #[error("cannot record the results: {0}")]
    Output(std::io::Error),
}

impl From<std::io::Error> for MeError {
    fn from(e: std::io::Error) -> Self {
        Self::Output(e)
    }
}
