//! A Model Exchange FMU as the model of an estimator (docs/estimators.md, "FMU models"): its
//! continuous states are the filter's states, parameters chosen by name are estimated,
//! inputs come from the data, chosen variables are the measurements.
//!
//! **Propagation.** [`FmuPlant::propagate`] takes the states x and the parameters θ at t₀,
//! the inputs u held over [t₀, t₁], and returns x(t₁) and the measured variables y(t₁): the
//! instance is placed at (t₀, x) ([`Stepper::place_at`]) and integrated to t₁ by the master's
//! own Model Exchange stepper (its solvers, its event handling), the same code as
//! `spurio run --interface me`.
//!
//! **Parameters.** A *tunable* parameter that changed since the last call is set in Event
//! Mode (FMI 2.0 §3.2.3: enter event mode, set, event iteration, continuous-time mode). A
//! *fixed* one can only be set before initialisation: the instance is reset (`fmi2Reset` /
//! `fmi3Reset`), every free parameter set, initialised again, and then placed at the states
//! asked for (which restores them). Consecutive calls at the same θ reset nothing. After a
//! failed call (an FMU that refuses a value, a run that stops) the instance is reset and
//! initialised again before its next use, so that an optimiser may try such points.
//!
//! **Checks before anything runs.** An FMU without Model Exchange, a free name that is not a
//! parameter (or not a number), a measured variable that does not exist or is not a
//! variable of the model (a parameter, an input), an input that is not an input: each is an
//! error naming it and the FMU.

use spurio_master::fmu::{
    me::MeInstance, Causality, FmuFile, Interface, LoadError, LoadOptions, Range, VarType,
    VariableInfo,
};
use spurio_master::model_exchange::{
    initialise, Advance, Layout, MeError, ModelExchangeCalls, Options, Stepper,
};
use spurio_master::NoRecording;
use std::path::{Path, PathBuf};

/// Where a propagation starts ([`FmuPlant::propagate`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Start<'a> {
    /// t₀.
    pub time: f64,
    /// x(t₀).
    pub states: &'a [f64],
    /// Every free parameter's value θ.
    pub parameters: &'a [f64],
    /// The inputs u, held over the interval.
    pub inputs: &'a [f64],
    /// The event indicators at t₀ of a state this one deviates from (a sigma point's mean),
    /// if any: an indicator of this state on the other side of zero is an event at t₀
    /// ([`Stepper::place_at`]).
    pub reference: Option<&'a [f64]>,
}

/// What the estimator takes from the FMU, by name.
#[derive(Debug, Clone, PartialEq)]
pub struct PlantSpec {
    /// The parameters estimated (causality `parameter`, Real).
    pub free: Vec<String>,
    /// The inputs set from the data (causality `input`), in the order of u.
    pub inputs: Vec<String>,
    /// The measured variables (outputs or local continuous variables), in the order of y.
    pub outputs: Vec<String>,
}

/// The master's Model Exchange settings for an estimator's propagations: the experiment
/// starting at `start` (the first sample's time), the default solver at relative tolerance
/// `tolerance`, no end.
pub fn integration(start: f64, tolerance: f64) -> Options {
    let mut options = Options::new(start, f64::INFINITY, 1.0);
    options.tolerance = tolerance;
    options
}

/// Keeps the plants' log messages (nothing printed) so that a failed call's error quotes what
/// the plant said: for a library running plants inside an FMU of its own (the estimator
/// FMU), whose host sees only that FMU's log. Once per process; an installed logger stays.
pub fn keep_plant_messages() {
    spurio_master::logging::install_quiet();
}

/// Why an FMU cannot be the model, or a propagation failed.
#[derive(Debug, thiserror::Error)]
pub enum PlantError {
    #[error(transparent)]
    Load(#[from] LoadError),
    #[error("{file}: `{name}` is not a variable of the FMU")]
    UnknownVariable { file: PathBuf, name: String },
    #[error("{file}: `{name}` cannot be estimated: it is {what}, not a parameter of type Real (the FMU's parameters are {known})")]
    NotAParameter {
        file: PathBuf,
        name: String,
        what: String,
        known: String,
    },
    #[error("{file}: `{name}` cannot be a measurement: it is {what} (measure an output or a local variable)")]
    NotMeasurable {
        file: PathBuf,
        name: String,
        what: String,
    },
    #[error("{file}: `{name}` is {what}, not an input of the FMU")]
    NotAnInput {
        file: PathBuf,
        name: String,
        what: String,
    },
    #[error("{file}: `{name}` cannot be set for the experiment: it is {what}, not a parameter of type Real")]
    NotSettable {
        file: PathBuf,
        name: String,
        what: String,
    },
    #[error("{what}: {given} given, the model has {expected}")]
    Length {
        what: &'static str,
        expected: usize,
        given: usize,
    },
    #[error("{fmu}: {call} failed: {reason}")]
    Call {
        fmu: String,
        call: &'static str,
        reason: String,
    },
    #[error("{fmu}: the FMU asked to end the simulation at t = {time}, before the samples' end")]
    Terminated { fmu: String, time: f64 },
    #[error(transparent)]
    Run(#[from] MeError),
}

/// A variable of the FMU by reference.
#[derive(Debug, Clone, PartialEq)]
struct Port {
    name: String,
    var_type: VarType,
    vr: u32,
}

/// A free parameter of the FMU.
#[derive(Debug, Clone, PartialEq)]
pub struct PlantParameter {
    pub name: String,
    /// Settable in Event Mode after initialisation (`variability="tunable"`).
    pub tunable: bool,
    /// The model description's start value.
    pub start: f64,
    /// Its unit, if declared.
    pub unit: Option<String>,
    /// The values the FMU accepts for it (`min`, `max`): the online filters hold their
    /// sigma points and estimates to it ([`crate::prediction::Step::parameters_of`]).
    pub range: Range,
    var_type: VarType,
    vr: u32,
}

/// One ME instance of an FMU, with the stepper that integrates it and the parameters set in
/// it (module documentation). Declared instance first: it is dropped before the FMU's
/// unpacked folder.
pub struct FmuPlant {
    instance: MeInstance,
    stepper: Stepper,
    fmu: FmuFile,
    layout: Layout,
    options: Options,
    parameters: Vec<PlantParameter>,
    inputs: Vec<Port>,
    outputs: Vec<Port>,
    /// The free parameters as set in the instance (meaningful when `initialised`).
    set: Vec<f64>,
    /// The instance was initialised with the parameters `set` (false: not yet, or reset).
    initialised: bool,
    /// The layout of an initialisation: `layout`'s start values, then the free parameters
    /// (rebuilt in place at each, nothing allocated once it has grown).
    initialisation: Layout,
    /// The unit seed of a directional derivative.
    seed: Vec<f64>,
    /// The inputs as last set.
    inputs_set: Vec<f64>,
    /// Instance resets so far (fixed parameters changed).
    resets: u64,
    /// A call failed: the instance is reset and initialised again before the next use.
    failed: bool,
    /// Events handled by the last propagation (at its start and on its way).
    events: usize,
}

impl std::fmt::Debug for FmuPlant {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "FmuPlant({})", self.fmu.path.display())
    }
}

/// What a variable is, for messages: "the input `u`", "a fixed parameter", ….
fn what_is(causality: Causality, fixed: bool, var_type: VarType) -> String {
    let kind = match causality {
        Causality::Parameter if fixed => "a fixed parameter",
        Causality::Parameter => "a tunable parameter",
        Causality::CalculatedParameter => "a calculated parameter",
        Causality::Input => "an input",
        Causality::Output => "an output",
        Causality::Local => "a local variable",
        Causality::Independent => "the independent variable (time)",
        Causality::StructuralParameter => "a structural parameter",
    };
    format!("{kind} of type {}", var_type.name())
}

/// The scalar variable `name` of `fmu` when it is a Real parameter; else Err(what it is),
/// for the caller's message. An unknown name is an error naming it.
fn real_parameter<'a>(
    fmu: &'a FmuFile,
    name: &str,
) -> Result<Result<&'a VariableInfo, String>, PlantError> {
    let v = fmu
        .variable(name)
        .filter(|v| v.element.is_none())
        .ok_or_else(|| PlantError::UnknownVariable {
            file: fmu.path.clone(),
            name: name.to_string(),
        })?;
    let h = &v.head;
    Ok(
        if h.causality == Causality::Parameter && h.var_type.base() == VarType::Real {
            Ok(v)
        } else {
            Err(what_is(h.causality, v.fixed, h.var_type))
        },
    )
}

impl FmuPlant {
    /// Opens `path` for Model Exchange and checks `spec` against it (module documentation);
    /// `options` are the master's settings of its integration ([`integration`]).
    pub fn open(path: &Path, spec: &PlantSpec, options: Options) -> Result<Self, PlantError> {
        let fmu = FmuFile::open_for(path, &LoadOptions::default(), Interface::ModelExchange)?;
        let file = fmu.path.clone();
        let lookup = |name: &str| {
            fmu.variable(name)
                .filter(|v| v.element.is_none())
                .ok_or_else(|| PlantError::UnknownVariable {
                    file: file.clone(),
                    name: name.to_string(),
                })
        };
        let known_parameters = || {
            let names: Vec<&str> = fmu
                .variables
                .iter()
                .filter(|v| {
                    v.head.causality == Causality::Parameter && v.head.var_type == VarType::Real
                })
                .map(|v| v.head.name.as_str())
                .collect();
            if names.is_empty() {
                "none".to_string()
            } else {
                names.join(", ")
            }
        };
        let mut parameters = Vec::new();
        for name in &spec.free {
            let v = real_parameter(&fmu, name)?.map_err(|what| PlantError::NotAParameter {
                file: file.clone(),
                name: name.clone(),
                what,
                known: known_parameters(),
            })?;
            let h = &v.head;
            parameters.push(PlantParameter {
                name: name.clone(),
                tunable: !v.fixed,
                start: v.start.unwrap_or(0.0),
                unit: v.unit.clone(),
                range: v.range,
                var_type: h.var_type,
                vr: h.value_reference,
            });
        }
        // A measured variable or an input: numeric, of an accepted causality, else `refuse`d.
        let port = |name: &String,
                    accepted: &dyn Fn(Causality) -> bool,
                    refuse: &dyn Fn(String) -> PlantError| {
            let v = lookup(name)?;
            let h = &v.head;
            if !(accepted(h.causality) && h.var_type.is_numeric()) {
                return Err(refuse(what_is(h.causality, v.fixed, h.var_type)));
            }
            Ok(Port {
                name: name.clone(),
                var_type: h.var_type,
                vr: h.value_reference,
            })
        };
        let outputs = spec
            .outputs
            .iter()
            .map(|name| {
                port(
                    name,
                    &|c| matches!(c, Causality::Output | Causality::Local),
                    &|what| PlantError::NotMeasurable {
                        file: file.clone(),
                        name: name.clone(),
                        what,
                    },
                )
            })
            .collect::<Result<Vec<_>, _>>()?;
        let inputs = spec
            .inputs
            .iter()
            .map(|name| {
                port(name, &|c| c == Causality::Input, &|what| {
                    PlantError::NotAnInput {
                        file: file.clone(),
                        name: name.clone(),
                        what,
                    }
                })
            })
            .collect::<Result<Vec<_>, _>>()?;
        let instance = fmu.instantiate_model_exchange("plant", false)?;
        let layout = Layout {
            states: instance.description().states,
            event_indicators: instance.description().event_indicators,
            recorded: Vec::new(),
            start_values: Vec::new(),
        };
        let stepper = Stepper::new(instance.name(), instance.is_fmi3(), &layout, &options);
        let inputs_set = vec![f64::NAN; inputs.len()];
        let (initialisation, seed) = (layout.clone(), vec![0.0; layout.states]);
        let set = vec![0.0; parameters.len()];
        Ok(Self {
            instance,
            stepper,
            fmu,
            layout,
            initialisation,
            seed,
            options,
            parameters,
            inputs,
            outputs,
            set,
            initialised: false,
            inputs_set,
            resets: 0,
            failed: false,
            events: 0,
        })
    }

    /// Sets parameters that are not estimated (`x0 = 0.2`: the experiment's initial cart
    /// position) at every initialisation from now on, by name: each a Real parameter of the
    /// FMU, else an error naming it. The instance is initialised again at its next use.
    pub fn set_values(&mut self, values: &[(String, f64)]) -> Result<(), PlantError> {
        let file = self.fmu.path.clone();
        for (name, value) in values {
            let v = real_parameter(&self.fmu, name)?.map_err(|what| PlantError::NotSettable {
                file: file.clone(),
                name: name.clone(),
                what,
            })?;
            let h = &v.head;
            self.layout
                .start_values
                .push((h.var_type, h.value_reference, *value));
        }
        if self.initialised {
            // Initialised before: reset and initialised again at the next use.
            self.failed = true;
        }
        Ok(())
    }

    /// The free parameters, in the order of θ.
    pub fn parameters(&self) -> &[PlantParameter] {
        &self.parameters
    }

    /// The parameters' start values (the model description's).
    pub fn parameter_starts(&self) -> Vec<f64> {
        self.parameters.iter().map(|p| p.start).collect()
    }

    /// Number of continuous states n.
    pub fn states(&self) -> usize {
        self.layout.states
    }

    /// The measured variables' names, in the order of y.
    pub fn output_names(&self) -> Vec<String> {
        self.outputs.iter().map(|p| p.name.clone()).collect()
    }

    /// The inputs' names, in the order of u.
    pub fn input_names(&self) -> Vec<String> {
        self.inputs.iter().map(|p| p.name.clone()).collect()
    }

    /// The FMU's file.
    pub fn path(&self) -> &Path {
        &self.fmu.path
    }

    /// How many times the instance was reset for a fixed parameter.
    pub fn resets(&self) -> u64 {
        self.resets
    }

    /// The error for `call` failing with `e` (which quotes what the instance logged).
    fn call_failed(&self, call: &'static str, e: spurio_master::fmu::CallError) -> PlantError {
        PlantError::Call {
            fmu: self.instance.name(),
            call,
            reason: e.0,
        }
    }

    fn check(what: &'static str, expected: usize, given: usize) -> Result<(), PlantError> {
        if expected == given {
            Ok(())
        } else {
            Err(PlantError::Length {
                what,
                expected,
                given,
            })
        }
    }

    /// The instance at the parameters θ (module documentation): initialised with them when a
    /// fixed one changed (reset first), the tunable ones set in Event Mode otherwise.
    fn ensure_parameters(&mut self, theta: &[f64]) -> Result<(), PlantError> {
        Self::check("parameters", self.parameters.len(), theta.len())?;
        let (fixed_changed, tunable_changed) = if self.failed || !self.initialised {
            (true, true)
        } else {
            let changed = |tunable: bool| {
                self.parameters
                    .iter()
                    .zip(self.set.iter().zip(theta))
                    .any(|(p, (a, b))| p.tunable == tunable && a != b)
            };
            (changed(false), changed(true))
        };
        if fixed_changed {
            if self.initialised || self.failed {
                let reset = self.instance.reset();
                reset.map_err(|e| self.call_failed("Reset", e))?;
                self.resets += 1;
            }
            self.initialised = false;
            // The values set by name ([`FmuPlant::set_values`]), then the free parameters.
            let starts = &mut self.initialisation.start_values;
            starts.clear();
            starts.extend_from_slice(&self.layout.start_values);
            starts.extend(
                self.parameters
                    .iter()
                    .zip(theta)
                    .map(|(p, &value)| (p.var_type, p.vr, value)),
            );
            // A stepper as new, its buffers kept.
            self.stepper.renew();
            let layout = &self.initialisation;
            initialise(&mut self.instance, layout, &self.options, &self.stepper)?;
            if let Advance::Terminated(time) = self
                .stepper
                .initialise(&mut self.instance, self.options.start)?
            {
                return Err(self.terminated(time));
            }
            self.inputs_set.fill(f64::NAN);
            self.failed = false;
        } else if tunable_changed {
            let entered = self.instance.enter_event_mode();
            entered.map_err(|e| self.call_failed("EnterEventMode", e))?;
            for (p, &value) in self.parameters.iter().zip(theta) {
                if p.tunable {
                    let set = self.instance.set(p.var_type, &[p.vr], &[value]);
                    set.map_err(|e| self.call_failed("Set* (a tunable parameter)", e))?;
                }
            }
            if let Advance::Terminated(time) =
                self.stepper.values_set_in_event_mode(&mut self.instance)?
            {
                return Err(self.terminated(time));
            }
        }
        self.set.copy_from_slice(theta);
        self.initialised = true;
        Ok(())
    }

    fn terminated(&self, time: f64) -> PlantError {
        PlantError::Terminated {
            fmu: self.instance.name(),
            time,
        }
    }

    fn set_inputs(&mut self, u: &[f64]) -> Result<(), PlantError> {
        Self::check("inputs", self.inputs.len(), u.len())?;
        for (j, port) in self.inputs.iter().enumerate() {
            if self.inputs_set[j] != u[j] {
                let set = self.instance.set(port.var_type, &[port.vr], &u[j..=j]);
                set.map_err(|e| self.call_failed("Set* (an input)", e))?;
                self.inputs_set[j] = u[j];
            }
        }
        Ok(())
    }

    /// The continuous states right after initialisation at θ (the experiment's start).
    pub fn initial_states(&mut self, theta: &[f64]) -> Result<Vec<f64>, PlantError> {
        // A fresh initialisation: the states are the FMU's own start values.
        if self.initialised || self.failed {
            let reset = self.instance.reset();
            reset.map_err(|e| self.call_failed("Reset", e))?;
            self.resets += 1;
            self.initialised = false;
            self.failed = false;
        }
        self.ensure_parameters(theta)?;
        let mut x = vec![0.0; self.layout.states];
        let read = self.instance.get_continuous_states(&mut x);
        read.map_err(|e| self.call_failed("GetContinuousStates", e))?;
        Ok(x)
    }

    /// The event indicators at the state last placed (before integrating), for
    /// [`Start::reference`].
    pub fn placed_indicators(&self) -> Vec<f64> {
        self.event_indicators().to_vec()
    }

    /// [`FmuPlant::placed_indicators`], borrowed (nothing allocated).
    pub fn event_indicators(&self) -> &[f64] {
        self.stepper.event_indicators()
    }

    /// Makes the next call start from a fresh instance (reset and initialised again): a
    /// filter run over a record starts so, since events may change variables of the FMU that
    /// are neither states nor parameters (BouncingBall at rest sets its own gravity to 0).
    pub fn start_afresh(&mut self) {
        self.failed = true;
    }

    /// x(t₁) and y(t₁) into `x_out`, `y_out` from `start` (module documentation);
    /// `t1 == start.time` only evaluates y there.
    pub fn propagate(
        &mut self,
        start: &Start,
        t1: f64,
        x_out: &mut [f64],
        y_out: &mut [f64],
    ) -> Result<(), PlantError> {
        let result = self.advance(start, t1, (x_out, y_out));
        if result.is_err() {
            // The instance may be left in any state: the next call resets it.
            self.failed = true;
        }
        result
    }

    /// [`FmuPlant::propagate`]'s work, into (x(t₁), y(t₁)).
    fn advance(
        &mut self,
        start: &Start,
        t1: f64,
        out: (&mut [f64], &mut [f64]),
    ) -> Result<(), PlantError> {
        let (x_out, y_out) = out;
        let Start {
            time: t0,
            states: x,
            parameters: theta,
            inputs: u,
            reference,
        } = *start;
        Self::check("states", self.layout.states, x.len())?;
        Self::check("states out", self.layout.states, x_out.len())?;
        Self::check("measurements", self.outputs.len(), y_out.len())?;
        self.ensure_parameters(theta)?;
        self.set_inputs(u)?;
        let mut events = 0;
        let placed = self
            .stepper
            .place_at(&mut self.instance, t0, x, reference, &mut |_| events += 1)?;
        if let Advance::Terminated(time) = placed {
            return Err(self.terminated(time));
        }
        if t1 > t0 {
            let advanced =
                self.stepper
                    .advance_to(&mut self.instance, t1, &mut NoRecording, &mut |_| {
                        events += 1
                    })?;
            if let Advance::Terminated(time) = advanced {
                return Err(self.terminated(time));
            }
        }
        self.events = events;
        if !x_out.is_empty() {
            let read = self.instance.get_continuous_states(x_out);
            read.map_err(|e| self.call_failed("GetContinuousStates", e))?;
        }
        for (j, port) in self.outputs.iter().enumerate() {
            let read = self
                .instance
                .get(port.var_type, &[port.vr], &mut y_out[j..=j]);
            read.map_err(|e| self.call_failed("Get* (a measured variable)", e))?;
        }
        Ok(())
    }

    /// Events the last [`FmuPlant::propagate`] handled (an event at its start included).
    pub fn events_in_last_propagation(&self) -> usize {
        self.events
    }

    /// ∂ẋ/∂x (n×n) at `start` (the instance placed at its time, states, parameters and
    /// inputs) from the FMU's directional derivatives (FMI 2.0 `fmi2GetDirectionalDerivative`
    /// with the states as knowns and the derivatives as unknowns, one unit seed per column,
    /// through the master's importer); None when the FMU gives none.
    pub fn state_jacobian(&mut self, start: &Start) -> Result<Option<Vec<f64>>, PlantError> {
        let mut jacobian = vec![0.0; self.layout.states.pow(2)];
        let given = self.state_jacobian_into(start, &mut jacobian)?;
        Ok(given.then_some(jacobian))
    }

    /// [`FmuPlant::state_jacobian`] into `jacobian` (n×n, column-major; nothing allocated):
    /// false when the FMU gives none.
    pub fn state_jacobian_into(
        &mut self,
        start: &Start,
        jacobian: &mut [f64],
    ) -> Result<bool, PlantError> {
        let n = self.layout.states;
        Self::check("states", n, start.states.len())?;
        Self::check("Jacobian entries", n * n, jacobian.len())?;
        self.ensure_parameters(start.parameters)?;
        self.set_inputs(start.inputs)?;
        let placed = self.stepper.place_at(
            &mut self.instance,
            start.time,
            start.states,
            start.reference,
            &mut |_| {},
        );
        if let Advance::Terminated(time) = placed.inspect_err(|_| self.failed = true)? {
            return Err(self.terminated(time));
        }
        for (i, column) in jacobian.chunks_exact_mut(n.max(1)).enumerate().take(n) {
            self.seed.fill(0.0);
            self.seed[i] = 1.0;
            match self.instance.directional_derivative(&self.seed, column) {
                Ok(true) => {}
                Ok(false) => return Ok(false),
                Err(e) => {
                    self.failed = true;
                    return Err(self.call_failed("GetDirectionalDerivative", e));
                }
            }
        }
        Ok(true)
    }
}
