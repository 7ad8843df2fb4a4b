//! One instance: what it holds ([`Core`], the part an FMU state captures, and the roll-back
//! buffers), how it is created from a shared [`Interface`], the state-mask check every call
//! passes, the rejection every failed check logs, and the life-cycle calls (debug logging,
//! experiment, initialization, termination, reset). Values, stepping, FMU states and Model
//! Exchange are the other files of [`crate::instance`], each an `impl Instance` of its own.

use super::interface::{Interface, WINDOW};
use super::log::Logger;
use super::state::{fmi2 as functions, state_name, state_names, Function, ModelState};
use crate::description::ModelInfo;
use crate::model::{Cause, FmuModel, Hooks, JacobianCache};
use crate::types::Status;
use crate::values::Values;
use std::path::PathBuf;
use std::sync::Arc;

/// The part of an instance that an FMU state captures.
#[derive(Clone)]
pub struct Core<M> {
    pub(crate) model: M,
    pub(crate) values: Values,
    pub(crate) time: f64,
    pub(crate) state: ModelState,
    pub(crate) stop_time: Option<f64>,
    /// Inputs were set since the outputs were last computed (Model Exchange: inputs, states
    /// or time were set since the derivatives were last evaluated).
    pub(crate) inputs_changed: bool,
}

/// An instance of model `M`.
pub struct Instance<M: FmuModel> {
    /// The model description and access table, shared by every instance of the configuration.
    pub(crate) interface: Arc<Interface>,
    pub(super) logger: Logger,
    pub(crate) core: Core<M>,
    /// The model's Model Exchange functions, if it has them (directional derivatives serve
    /// Co-Simulation too).
    pub(crate) me: Option<Hooks<M>>,
    /// Whether the instance was instantiated for Model Exchange.
    pub(crate) model_exchange: bool,
    /// Model Exchange: the event indicators, computed when read.
    pub(crate) indicators: Indicators,
    /// The values a model call may change ([`Interface::computed`]) as they were before the
    /// current call (a reused buffer), restored when the call produces a
    /// non-finite value; empty when the interface has a [`Interface::window`] (then
    /// `before_window` holds them).
    pub(super) before: Vec<f64>,
    /// The values of the [`Interface::window`] before the current call, when it has one.
    pub(super) before_window: [f64; WINDOW],
    /// The String texts before the current call, when a String is among the computed
    /// variables ([`Interface::computed_texts`]).
    pub(super) before_texts: Vec<(usize, String)>,
    /// When the instance audits its model ([`Instance::audit_model_writes`]; always in debug
    /// builds): every value before the current call, to check that the model changed only
    /// computed ones.
    pub(super) audit: Option<Box<Values>>,
    /// The unpacked `resources/` folder the importer gave, from which the model was created
    /// (and is created again by `fmi2Reset`).
    pub(crate) resources: Option<PathBuf>,
    /// The directional derivative's result before it is checked and published (a reused
    /// buffer: one element per Real variable, so no call allocates).
    pub(crate) directional: Vec<f64>,
    /// The Jacobian the model formed last, while the values it was formed at hold.
    pub(crate) jacobian: JacobianCache,
}

/// The event indicators of a Model Exchange instance, computed when they are read: by
/// `fmi2GetEventIndicators`/`fmi3GetEventIndicators`, or by a getter of an indicator's
/// variable. An evaluation (after states, inputs or time changed) only marks them pending, so
/// an integration loop that reads derivatives alone makes one model call per evaluation.
#[derive(Debug, Clone, Default)]
pub struct Indicators {
    /// Where the model writes them (one element per indicator, allocated at instantiation:
    /// no allocation when they are computed).
    buffer: Vec<f64>,
    /// The indicators' variables are older than the last evaluation (never set for a model
    /// without indicators).
    pub(crate) pending: bool,
}

impl Indicators {
    /// The buffer for `n` indicators, none pending.
    pub fn new(n: usize) -> Self {
        Self {
            buffer: vec![0.0; n],
            pending: false,
        }
    }

    /// After an evaluation or a restored FMU state: the indicators' variables are stale (if
    /// the model has any).
    pub(crate) fn invalidate(&mut self) {
        self.pending = !self.buffer.is_empty();
    }

    /// The buffer the model writes into, moved out for the model call (the instance is
    /// borrowed by it); [`Indicators::put_back`] returns it.
    pub(crate) fn take(&mut self) -> Vec<f64> {
        std::mem::take(&mut self.buffer)
    }

    /// Returns the buffer [`Indicators::take`] lent.
    pub(crate) fn put_back(&mut self, buffer: Vec<f64>) {
        self.buffer = buffer;
    }
}

impl<M: FmuModel> Instance<M> {
    /// A new instance in state `Instantiated`, with the start values of `info`.
    pub fn new(info: ModelInfo, logger: Logger) -> Result<Self, Cause> {
        Self::of(Arc::new(Interface::new(info)), logger)
    }

    /// A new instance of a shared interface (see [`super::interface::interface`]), in state
    /// `Instantiated` with its start values.
    pub fn of(interface: Arc<Interface>, logger: Logger) -> Result<Self, Cause> {
        Self::with_resources(interface, logger, None)
    }

    /// A new instance of a shared interface whose unpacked `resources/` folder is
    /// `resources` ([`FmuModel::create_with_resources`]), in state `Instantiated` with its
    /// start values.
    pub fn with_resources(
        interface: Arc<Interface>,
        logger: Logger,
        resources: Option<PathBuf>,
    ) -> Result<Self, Cause> {
        let model = M::create_with_resources(&interface.info, resources.as_deref())?;
        let values = Values::from_start(&interface.info.variables);
        Ok(Self {
            before: match interface.window {
                Some(_) => Vec::new(),
                None => vec![0.0; interface.computed_len()],
            },
            before_window: [0.0; WINDOW],
            directional: Vec::with_capacity(interface.info.variables.len()),
            jacobian: JacobianCache::default(),
            interface,
            logger,
            me: None,
            model_exchange: false,
            indicators: Default::default(),
            before_texts: values.texts().clone(),
            audit: cfg!(debug_assertions).then(|| Box::new(values.clone())),
            resources,
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
        match M::create_with_resources(&self.interface.info, self.resources.as_deref()) {
            Ok(model) => {
                self.jacobian.forget();
                let mut values = std::mem::take(&mut self.core.values);
                values.reset_to_start(&self.interface.info.variables);
                self.core = Core {
                    model,
                    values,
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

    /// `fmi2GetRealStatus(fmi2LastSuccessfulTime)`.
    pub fn last_successful_time(&self) -> f64 {
        self.core.time
    }
}
