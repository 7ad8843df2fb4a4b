//! Model Exchange on an instance, version-neutral: each call takes the calling
//! [`Function`] (an `fmi2*` or `fmi3*` one) so its messages name it, and is reached through
//! the same allowed-state masks, argument checks and non-finite guard as the Co-Simulation
//! calls. The continuous states live in the state variables' values, so FMU states (get, set,
//! serialize) carry them with everything else; the event indicators are computed when they
//! are read ([`Indicators`]).

use super::access::Access;
use super::common::{Indicators, Instance};
use super::state::{Function, ModelState};
use crate::description::model_exchange::ModelExchangeInfo;
use crate::model::{EventUpdate, FmuModel, Hooks};
use crate::types::Status;
use crate::values::first_non_finite;

/// Which indices of the Model Exchange interface a read takes (the states', the
/// derivatives', the event indicators').
type Pick = fn(&ModelExchangeInfo) -> &[usize];

impl<M: FmuModel> Instance<M> {
    /// Makes this instance a Model Exchange one driven by `hooks` (at instantiation).
    pub fn into_model_exchange(mut self, hooks: Hooks<M>) -> Self {
        self.me = Some(hooks);
        self.model_exchange = true;
        self.indicators = Indicators::new(self.event_indicator_count());
        self
    }

    /// Gives a Co-Simulation instance the model's Model Exchange functions (for its
    /// directional derivatives).
    pub fn with_hooks(mut self, hooks: Option<Hooks<M>>) -> Self {
        self.me = hooks;
        self
    }

    /// Whether the instance was instantiated for Model Exchange.
    pub fn is_model_exchange(&self) -> bool {
        self.model_exchange
    }

    /// The hooks of a Model Exchange instance; `Err` (logged) for a Co-Simulation one.
    fn model_exchange_hooks(&self, f: &Function) -> Result<Hooks<M>, Status> {
        match self.me {
            Some(hooks) if self.model_exchange => Ok(hooks),
            _ => Err(self.reject(
                f,
                "the instance was instantiated for Co-Simulation: Model Exchange functions are not available",
            )),
        }
    }

    /// The number of continuous states (0 for a model without Model Exchange).
    pub fn state_count(&self) -> usize {
        self.interface
            .info
            .model_exchange
            .as_ref()
            .map_or(0, |m| m.states.len())
    }

    /// The number of event indicators (0 for a model without Model Exchange).
    pub fn event_indicator_count(&self) -> usize {
        self.interface
            .info
            .model_exchange
            .as_ref()
            .map_or(0, |m| m.event_indicators.len())
    }

    /// Checks that the caller's array holds `n` elements where the model has `expected`.
    pub(crate) fn check_count(
        &self,
        f: &Function,
        what: &str,
        n: usize,
        expected: usize,
    ) -> Status {
        if n == expected {
            Status::Ok
        } else {
            self.reject(
                f,
                &format!(
                    "{what} = {n}, but {} has {expected}",
                    self.interface.info.model_identifier
                ),
            )
        }
    }

    /// Brings the outputs and derivatives up to date with the states, inputs and time (the
    /// model's `evaluate`; in Initialization Mode after `initialize`), when they changed. The
    /// event indicators are then pending: computed when read ([`Instance::indicators_for`]).
    pub(crate) fn evaluate(&mut self, f: &Function) -> Status {
        let Some(hooks) = self.me.filter(|_| self.model_exchange) else {
            return Status::Ok;
        };
        let mut status = Status::Ok;
        match self.core.state {
            ModelState::InitializationMode => {
                status = self.run_model(f, |m, ctx| m.initialize(ctx));
                if status > Status::Warning {
                    return status;
                }
            }
            state if state.computes() && self.core.inputs_changed => {}
            _ => return Status::Ok,
        }
        let evaluated = self.run_model(f, hooks.evaluate);
        if evaluated <= Status::Warning {
            self.core.inputs_changed = false;
            self.indicators.invalidate();
        }
        status.max(evaluated)
    }

    /// Before the variables at table indices `read` are read (a getter's references, after
    /// [`Instance::refresh_outputs`]): when the event indicators are pending and one of
    /// them is read, they are computed ([`Instance::write_event_indicators`]).
    pub(crate) fn indicators_for(
        &mut self,
        f: &Function,
        read: impl Iterator<Item = usize>,
    ) -> Status {
        if self.indicators.pending && self.names_indicator(read) {
            self.write_event_indicators(f)
        } else {
            Status::Ok
        }
    }

    /// Whether a read of value references `vrs` (FMI 3.0 ones when `fmi3`, else FMI 2.0
    /// ones: table indices) must compute the event indicators first: they are pending and
    /// one of them is read. One flag test when none is pending (a Co-Simulation instance, or
    /// indicators already read).
    #[inline(always)]
    pub(crate) fn reads_pending_indicator(&self, vrs: &[u32], fmi3: bool) -> bool {
        self.indicators.pending && self.references_indicator(vrs, fmi3)
    }

    /// Whether one of value references `vrs` names an event indicator's variable (cold: the
    /// getters' fast paths prepare nothing for it).
    #[cold]
    #[inline(never)]
    fn references_indicator(&self, vrs: &[u32], fmi3: bool) -> bool {
        if fmi3 {
            self.names_indicator(self.interface.layout.indices_of(vrs))
        } else {
            self.names_indicator(vrs.iter().map(|&vr| vr as usize))
        }
    }

    /// Whether one of the table indices `read` is an event indicator's variable.
    fn names_indicator(&self, mut read: impl Iterator<Item = usize>) -> bool {
        self.interface
            .info
            .model_exchange
            .as_ref()
            .is_some_and(|me| read.any(|i| me.event_indicators.contains(&i)))
    }

    /// The model's event indicators into their variables, when they are pending and the
    /// instance is in a state where the model computes (Initialization, Event,
    /// Continuous-Time Mode, Terminated): so a read sees them consistent with the states,
    /// inputs and time. A non-finite one is `Error` naming it (the instance goes to state
    /// Error), and the variables keep their values.
    fn write_event_indicators(&mut self, f: &Function) -> Status {
        let Some(hooks) = self.me.filter(|_| self.model_exchange) else {
            return Status::Ok;
        };
        if !self.indicators.pending || !self.core.state.computes() {
            return Status::Ok;
        }
        let mut z = self.indicators.take();
        let status = self.run_model(f, |m, ctx| (hooks.event_indicators)(m, ctx, &mut z));
        let status = if status > Status::Warning {
            status
        } else if let Some((k, value)) = first_non_finite(&z) {
            self.core.state = ModelState::Error;
            self.reject(
                f,
                &format!(
                    "event indicator {} came out as {value}: not published",
                    k + 1
                ),
            )
        } else {
            if let Some(me) = self.interface.info.model_exchange.as_ref() {
                for (&i, value) in me.event_indicators.iter().zip(z.iter()) {
                    self.core.values.set_real(i, *value);
                }
            }
            self.indicators.pending = false;
            status
        };
        self.indicators.put_back(z);
        status
    }

    /// `fmi2SetTime`, `fmi3SetTime`.
    pub fn set_time(&mut self, f: &Function, time: f64) -> Status {
        if let Err(status) = self.model_exchange_hooks(f) {
            return status;
        }
        if !time.is_finite() {
            return self.reject(f, &format!("time must be finite, got {time}"));
        }
        self.core.time = time;
        self.core.inputs_changed = true;
        self.jacobian.forget();
        Status::Ok
    }

    /// `fmi2SetContinuousStates`, `fmi3SetContinuousStates`: every value is checked (count,
    /// finiteness) before any is set.
    pub fn set_continuous_states(&mut self, f: &Function, x: &[f64]) -> Status {
        if let Err(status) = self.model_exchange_hooks(f) {
            return status;
        }
        let status = self.check_count(f, "nx", x.len(), self.state_count());
        if status != Status::Ok {
            return status;
        }
        let Some(me) = self.interface.info.model_exchange.as_ref() else {
            return Status::Ok;
        };
        let states = &me.states;
        for (&i, value) in states.iter().zip(x) {
            if !value.is_finite() {
                return self.reject(
                    f,
                    &format!(
                        "state `{}`: {value} rejected, values must be finite",
                        self.interface.info.variables[i].name
                    ),
                );
            }
        }
        for (&i, value) in states.iter().zip(x) {
            self.core.values.set_real(i, *value);
        }
        self.core.inputs_changed = true;
        self.jacobian.forget();
        Status::Ok
    }

    /// The number of indices `pick` takes of the Model Exchange interface (0 for a model
    /// without it).
    fn count_of(&self, pick: Pick) -> usize {
        self.interface
            .info
            .model_exchange
            .as_ref()
            .map_or(0, |m| pick(m).len())
    }

    /// Reads the Reals at the indices `pick` takes of the Model Exchange interface (`what`
    /// counts them: `nx`, `ni`) into `out` after evaluating (`fmi2GetContinuousStates`,
    /// `fmi2GetDerivatives`, `fmi2GetEventIndicators`; the indicators computed when
    /// `indicators`). No allocation.
    fn read_reals(
        &mut self,
        f: &Function,
        (what, pick, indicators): (&str, Pick, bool),
        out: &mut [f64],
    ) -> Status {
        if let Err(status) = self.model_exchange_hooks(f) {
            return status;
        }
        let status = self.check_count(f, what, out.len(), self.count_of(pick));
        if status != Status::Ok {
            return status;
        }
        let mut status = self.evaluate(f);
        if status > Status::Warning {
            return status;
        }
        if indicators {
            status = status.max(self.write_event_indicators(f));
            if status > Status::Warning {
                return status;
            }
        }
        if let Some(me) = self.interface.info.model_exchange.as_ref() {
            for (o, &i) in out.iter_mut().zip(pick(me)) {
                *o = self.core.values.real(i);
            }
        }
        status
    }

    /// `fmi2GetContinuousStates`, `fmi3GetContinuousStates`.
    pub fn get_continuous_states(&mut self, f: &Function, out: &mut [f64]) -> Status {
        self.read_reals(f, ("nx", |m| &m.states, false), out)
    }

    /// `fmi2GetDerivatives`, `fmi3GetContinuousStateDerivatives`; a non-finite derivative is
    /// `Error` naming it (the values keep those from before, see [`Instance`]).
    pub fn get_derivatives(&mut self, f: &Function, out: &mut [f64]) -> Status {
        self.read_reals(f, ("nx", |m| &m.derivatives, false), out)
    }

    /// `fmi2GetNominalsOfContinuousStates`, `fmi3GetNominalsOfContinuousStates`.
    pub fn get_nominals(&mut self, f: &Function, out: &mut [f64]) -> Status {
        if let Err(status) = self.model_exchange_hooks(f) {
            return status;
        }
        let info = &self.interface.info;
        let Some(me) = info.model_exchange.as_ref() else {
            return self.check_count(f, "nx", out.len(), 0);
        };
        let status = self.check_count(f, "nx", out.len(), me.states.len());
        if status == Status::Ok {
            for (to, nominal) in out.iter_mut().zip(me.nominals(&info.variables)) {
                *to = nominal;
            }
        }
        status
    }

    /// `fmi2GetEventIndicators`, `fmi3GetEventIndicators`: the indicators at the current
    /// states, inputs and time (a non-finite one is `Error` naming it, and `out` is left as
    /// it was).
    pub fn get_event_indicators(&mut self, f: &Function, out: &mut [f64]) -> Status {
        self.read_reals(f, ("ni", |m| &m.event_indicators, true), out)
    }

    /// `fmi2EnterEventMode`, `fmi3EnterEventMode`.
    pub fn enter_event_mode(&mut self, f: &Function) -> Status {
        if let Err(status) = self.model_exchange_hooks(f) {
            return status;
        }
        self.core.state = ModelState::EventMode;
        Status::Ok
    }

    /// `fmi2EnterContinuousTimeMode`, `fmi3EnterContinuousTimeMode`.
    pub fn enter_continuous_time_mode(&mut self, f: &Function) -> Status {
        if let Err(status) = self.model_exchange_hooks(f) {
            return status;
        }
        self.core.state = ModelState::ContinuousTimeMode;
        Status::Ok
    }

    /// `fmi2NewDiscreteStates`, `fmi3UpdateDiscreteStates`: the model's discrete change at
    /// the current time. A next event time must be finite and not in the past.
    pub fn update_discrete_states(&mut self, f: &Function) -> (Status, EventUpdate) {
        let hooks = match self.model_exchange_hooks(f) {
            Ok(hooks) => hooks,
            Err(status) => return (status, EventUpdate::default()),
        };
        let status = self.evaluate(f);
        if status > Status::Warning {
            return (status, EventUpdate::default());
        }
        let mut update = EventUpdate::default();
        let status = status.max(self.run_model(f, |m, ctx| {
            update = (hooks.update_discrete_states)(m, ctx)?;
            Ok(())
        }));
        if status > Status::Warning {
            return (status, EventUpdate::default());
        }
        let time = self.core.time;
        if let Some(next) = update.next_event_time {
            if !next.is_finite() || next < time {
                self.core.state = ModelState::Error;
                let message = format!(
                    "the model's next event time {next} is not a finite time after the current time {time:.16}"
                );
                return (self.reject(f, &message), EventUpdate::default());
            }
        }
        self.core.inputs_changed = true;
        (status, update)
    }

    /// `fmi2CompletedIntegratorStep`, `fmi3CompletedIntegratorStep`: the model has no step
    /// events, so (enterEventMode, terminateSimulation) are both false.
    pub fn completed_integrator_step(&mut self, f: &Function) -> (Status, bool, bool) {
        match self.model_exchange_hooks(f) {
            Ok(_) => (Status::Ok, false, false),
            Err(status) => (status, false, false),
        }
    }

    /// `fmi2GetDirectionalDerivative`, `fmi3GetDirectionalDerivative` (on table indices):
    /// `out = J · seed` of the `unknowns` (derivatives, outputs) with respect to the
    /// `knowns` (states, inputs), after checking every index and value.
    pub fn directional_derivative(
        &mut self,
        f: &Function,
        unknowns: &[usize],
        knowns: &[usize],
        seed: &[f64],
        out: &mut [f64],
    ) -> Status {
        let Some(hooks) = self.me else {
            return self.reject(f, "not supported: providesDirectionalDerivative=\"false\"");
        };
        if seed.len() != knowns.len() || out.len() != unknowns.len() {
            return self.reject(
                f,
                &format!(
                    "{} seed values for {} knowns, {} results for {} unknowns",
                    seed.len(),
                    knowns.len(),
                    out.len(),
                    unknowns.len()
                ),
            );
        }
        // one bit test an index (the roles are set once per configuration, in the access
        // table); the message is built only for the index that fails
        let access = &self.interface.access;
        let fits = |i: usize, role: u32| access.get(i).is_some_and(|a| a.bits & role != 0);
        let refused = unknowns
            .iter()
            .map(|&i| (i, Access::UNKNOWN))
            .chain(knowns.iter().map(|&i| (i, Access::KNOWN)))
            .find(|&(i, role)| !fits(i, role));
        if let Some((i, role)) = refused {
            let Some(v) = self.interface.info.variables.get(i) else {
                return self.reject(f, &self.unknown_reference(i));
            };
            let what = if role == Access::UNKNOWN {
                "an unknown must be a Real output or state derivative"
            } else {
                "a known must be a Real input or continuous state"
            };
            return self.reject(f, &format!("variable `{}`: {what}", v.name));
        }
        if let Some(x) = seed.iter().find(|x| !x.is_finite()) {
            return self.reject(
                f,
                &format!("seed value {x} rejected, values must be finite"),
            );
        }
        // the values the derivatives are taken at: in Initialization Mode those the current
        // parameters give (also on a Co-Simulation instance), else the last evaluation's
        let mut status = self.refresh_outputs(f);
        if status > Status::Warning {
            return status;
        }
        let mut result = std::mem::take(&mut self.directional);
        result.clear();
        result.resize(out.len(), 0.0);
        // the Jacobian kept from the last call at the same values (a model call forgets it:
        // taken out around this one)
        let mut jacobian = std::mem::take(&mut self.jacobian);
        status = status.max(self.run_model(f, |m, ctx| {
            let request = (unknowns, knowns);
            (hooks.directional_derivative)(m, ctx, &mut jacobian, request, seed, &mut result)
        }));
        self.jacobian = jacobian;
        let published = if status > Status::Warning {
            Err(status)
        } else {
            first_non_finite(&result).map_or(Ok(()), |(k, value)| {
                let name = &self.interface.info.variables[unknowns[k]].name;
                Err(self.reject(
                    f,
                    &format!(
                        "the directional derivative of `{name}` came out as {value}: not published"
                    ),
                ))
            })
        };
        if published.is_ok() {
            out.copy_from_slice(&result);
        }
        self.directional = result;
        published.err().unwrap_or(status)
    }
}
