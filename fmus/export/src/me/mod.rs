//! Model Exchange, shared by the FMI 2.0 and FMI 3.0 fronts: the continuous states and
//! derivatives a model declares in its variable table, and the [`ModelExchange`] calls an
//! instance makes.
//!
//! A model offers Model Exchange by marking the Real variables that are continuous states
//! ([`Variable::state`]), declaring one derivative variable per state
//! ([`Variable::derivative_of`]) and one local variable per event indicator
//! ([`Variable::event_indicator`]), declaring the interface in its description
//! ([`crate::ModelInfo::with_model_exchange`]) and
//! exporting with `export_fmu!(Model, model_exchange)`. The layer derives everything else
//! from the one table: the number and order of the states (value-reference order), their
//! nominals, the `derivative="…"` attributes and the ModelStructure of both versions
//! (`<Derivatives>`/`<ContinuousStateDerivative>` with the dependencies declared by
//! `depends_on` — states and inputs —, `<InitialUnknowns>` with the states and derivatives,
//! FMI 3.0 `<EventIndicator>`s).
//!
//! ```ignore
//! declare_variables! { pub fn variables() { table: [
//!     U = rows::input("U", 0.0, "N", "Force on the cart"),
//!     X = rows::output("x", "m", "Cart position").state().nominal(0.1).depends_on(&[vr::X]),
//!     V = rows::output("v", "m/s", "Cart velocity").state().depends_on(&[vr::V]),
//!     DER_X = rows::derivative("der(x)", vr::X, "m/s", "").depends_on(&[vr::V]),
//!     DER_V = rows::derivative("der(v)", vr::V, "m/s2", "").depends_on(&[vr::U]),
//!     TO_STOP = rows::event_indicator("to_stop", "m", "Distance to the rail stop"),
//! ] } }
//! // describe: ModelInfo::new(…, variables(), …).with_model_exchange()?
//! // impl ModelExchange for Model { evaluate, event_indicators, update_discrete_states,
//! //     type Jacobian, jacobian, partial } (the layer forms J·seed from the partials)
//! spurio_export::export_fmu!(Model, model_exchange);
//! ```
//!
//! The instance keeps the states in the variable values (so FMU states carry them), evaluates
//! the model when states, inputs or time changed and something is read (the event indicators
//! only when they are read: [`Indicators`]), checks every result
//! for finiteness (a non-finite derivative, output or event indicator is an error naming it,
//! never published), and refuses the Model Exchange functions on a Co-Simulation instance.
//! Directional derivatives serve Co-Simulation instances too, at the values of the last step.

pub mod ffi;
pub mod instance;

use crate::model::{Context, EventUpdate, Failure, ModelExchange};
use crate::variables::{Causality, Variability, Variable, VariableType};
use std::fmt;

/// The Model Exchange interface of a model, derived from its variable table.
#[derive(Debug, Clone, PartialEq)]
pub struct ModelExchangeInfo {
    /// The indices of the event indicators, in table order.
    pub event_indicators: Vec<usize>,
    /// The indices of the continuous states, in value-reference order (the state vector's).
    pub states: Vec<usize>,
    /// The index of each state's derivative, in the order of `states`.
    pub derivatives: Vec<usize>,
}

/// Why a variable table does not declare a consistent Model Exchange interface.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum DeclarationError {
    /// A state that is not a continuous Real output or local.
    NotAContinuousReal(String),
    /// A state without a derivative.
    NoDerivative(String),
    /// A state with more than one derivative.
    TwoDerivatives {
        state: String,
        first: String,
        second: String,
    },
    /// A derivative whose `derivative_of` index is not a declared state.
    NotAState { derivative: String, index: usize },
    /// A derivative that is not a continuous Real local or output.
    BadDerivative(String),
    /// An event indicator that is not a continuous Real local.
    BadEventIndicator(String),
    /// No state at all.
    NoState,
}

impl fmt::Display for DeclarationError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::NotAContinuousReal(name) => write!(
                f,
                "state `{name}` must be a continuous Real output or local variable"
            ),
            Self::NoDerivative(name) => write!(
                f,
                "state `{name}` has no derivative: declare `der({name})` with derivative_of"
            ),
            Self::TwoDerivatives {
                state,
                first,
                second,
            } => write!(
                f,
                "state `{state}` has two derivatives, `{first}` and `{second}`"
            ),
            Self::NotAState { derivative, index } => write!(
                f,
                "derivative `{derivative}` is declared of index {index}, which is not a variable marked .state()"
            ),
            Self::BadDerivative(name) => write!(
                f,
                "derivative `{name}` must be a continuous Real output or local variable"
            ),
            Self::BadEventIndicator(name) => write!(
                f,
                "event indicator `{name}` must be a continuous Real local variable"
            ),
            Self::NoState => write!(f, "a Model Exchange model needs at least one state"),
        }
    }
}

impl std::error::Error for DeclarationError {}

/// A continuous Real that the model calculates (output or local).
fn continuous_real(v: &Variable) -> bool {
    v.variable_type() == VariableType::Real
        && v.variability == Variability::Continuous
        && matches!(v.causality, Causality::Output | Causality::Local)
}

impl ModelExchangeInfo {
    /// The interface the table `variables` declares.
    pub fn from_table(variables: &[Variable]) -> Result<Self, DeclarationError> {
        let mut states = Vec::new();
        let mut derivatives = Vec::new();
        for (i, v) in variables.iter().enumerate().filter(|(_, v)| v.state) {
            if !continuous_real(v) {
                return Err(DeclarationError::NotAContinuousReal(v.name.clone()));
            }
            let mut of_this = variables
                .iter()
                .enumerate()
                .filter(|(_, d)| d.derivative_of == Some(i));
            let Some((d, _)) = of_this.next() else {
                return Err(DeclarationError::NoDerivative(v.name.clone()));
            };
            if let Some((e, _)) = of_this.next() {
                return Err(DeclarationError::TwoDerivatives {
                    state: v.name.clone(),
                    first: variables[d].name.clone(),
                    second: variables[e].name.clone(),
                });
            }
            states.push(i);
            derivatives.push(d);
        }
        for d in variables.iter().filter(|d| d.derivative_of.is_some()) {
            let index = d.derivative_of.unwrap_or(usize::MAX);
            if !variables.get(index).is_some_and(|s| s.state) {
                return Err(DeclarationError::NotAState {
                    derivative: d.name.clone(),
                    index,
                });
            }
            if !continuous_real(d) {
                return Err(DeclarationError::BadDerivative(d.name.clone()));
            }
        }
        if states.is_empty() {
            return Err(DeclarationError::NoState);
        }
        let mut event_indicators = Vec::new();
        for (i, v) in variables
            .iter()
            .enumerate()
            .filter(|(_, v)| v.event_indicator)
        {
            if !(continuous_real(v) && v.causality == Causality::Local) {
                return Err(DeclarationError::BadEventIndicator(v.name.clone()));
            }
            event_indicators.push(i);
        }
        Ok(Self {
            event_indicators,
            states,
            derivatives,
        })
    }

    /// The nominal of each state (its declared `nominal`, 1 by default).
    pub fn nominals(&self, variables: &[Variable]) -> Vec<f64> {
        self.states
            .iter()
            .map(|&i| variables[i].nominal.unwrap_or(1.0))
            .collect()
    }
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
    /// [`ModelExchange::directional_derivative`].
    #[allow(clippy::type_complexity)]
    pub directional_derivative:
        fn(&mut M, &mut Context, &[usize], &[usize], &[f64], &mut [f64]) -> Result<(), Failure>,
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
        directional_derivative: M::directional_derivative,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::description::{Config, ModelInfo};

    /// x (output, state), v (local state), u (input), der(x) = v, der(v) = u − x, z = x
    /// (der(v)'s dependencies declared out of order and twice: the descriptions sort them).
    fn table() -> Vec<Variable> {
        vec![
            Variable::output("x").state().nominal(0.5).depends_on(&[0]),
            Variable::derivative("v", 0).state().describe("velocity"),
            Variable::input("u", 0.0),
            Variable::derivative("der(v)", 1).depends_on(&[2, 0, 2]),
            Variable::event_indicator("z"),
        ]
    }

    fn info(variables: Vec<Variable>) -> Result<ModelInfo, DeclarationError> {
        ModelInfo::new("Osc", "", variables, None, Config::new()).with_model_exchange()
    }

    #[test]
    fn the_interface_comes_from_the_table() {
        let info = info(table()).unwrap();
        let me = info.model_exchange.as_ref().unwrap();
        assert_eq!(
            (me.states.clone(), me.derivatives.clone()),
            (vec![0, 1], vec![1, 3])
        );
        assert_eq!(me.event_indicators, [4]);
        assert_eq!(me.nominals(&info.variables), [0.5, 1.0]);
        // the GUID covers the interface
        let cs = ModelInfo::new("Osc", "", table(), None, Config::new());
        assert_ne!(cs.guid, info.guid);
    }

    #[test]
    fn both_descriptions_declare_it() {
        let info = info(table()).unwrap();
        let x = info.to_xml();
        crate::description::tests::assert_in_order(
            &x,
            &[
                "numberOfEventIndicators=\"1\"",
                "<ModelExchange modelIdentifier=\"Osc\"",
                "<CoSimulation",
            ],
        );
        assert!(x.contains(r#"providesDirectionalDerivative="true"/>"#));
        assert!(x.contains(r#"<Real nominal="0.5"/>"#));
        assert!(x.contains(r#"name="v" valueReference="1" description="velocity" causality="local" variability="continuous" initial="calculated">"#));
        assert!(x.contains(r#"<Real derivative="1"/>"#));
        assert!(x.contains(r#"<Real derivative="2"/>"#));
        let structure = &x[x.find("<ModelStructure>").unwrap()..];
        crate::description::tests::assert_in_order(
            structure,
            &[
                "<Outputs>",
                r#"<Unknown index="1" dependencies="1"/>"#,
                "<Derivatives>",
                r#"<Unknown index="2"/>"#,
                r#"<Unknown index="4" dependencies="1 3"/>"#,
                "<InitialUnknowns>",
            ],
        );
        let initial = &structure[structure.find("<InitialUnknowns>").unwrap()..];
        crate::description::tests::assert_in_order(
            initial,
            &[
                r#"<Unknown index="1"/>"#,
                r#"<Unknown index="2"/>"#,
                r#"<Unknown index="4"/>"#,
                "</InitialUnknowns>",
            ],
        );
        assert!(
            !initial.contains(r#"index="5""#),
            "an event indicator is no initial unknown"
        );
        let x3 = crate::fmi3::description::model_description(&info);
        crate::description::tests::assert_in_order(
            &x3,
            &[
                r#"<ModelExchange modelIdentifier="Osc""#,
                r#"providesDirectionalDerivatives="true" providesAdjointDerivatives="true""#,
                "<CoSimulation",
                r#"name="x" valueReference="1""#,
                r#"name="v" valueReference="2""#,
                r#"derivative="1""#,
                r#"name="der(v)" valueReference="4""#,
                r#"derivative="2""#,
                r#"<Output valueReference="1" dependencies="1"/>"#,
                r#"<ContinuousStateDerivative valueReference="2"/>"#,
                r#"<ContinuousStateDerivative valueReference="4" dependencies="1 3"/>"#,
                r#"<InitialUnknown valueReference="1"/>"#,
                r#"<EventIndicator valueReference="5"/>"#,
            ],
        );
    }

    #[test]
    fn inconsistent_declarations_are_errors() {
        use crate::variables::Causality;
        type Edit = fn(&mut Vec<Variable>);
        let cases: [(Edit, &str); 8] = [
            (|t| t[3].derivative_of = None, "state `v` has no derivative"),
            (
                |t| t[4].derivative_of = Some(1),
                "state `v` has two derivatives",
            ),
            (
                |t| t[3].derivative_of = Some(2),
                "state `v` has no derivative: declare `der(v)` with derivative_of",
            ),
            (
                |t| t[2].state = true,
                "state `u` must be a continuous Real output or local variable",
            ),
            (
                |t| t.push(Variable::parameter("k", 1.0).derivative_of(0)),
                "state `x` has two derivatives, `v` and `k`",
            ),
            (
                |t| t.push(Variable::output("w").derivative_of(2)),
                "derivative `w` is declared of index 2",
            ),
            (
                |t| t[4].causality = Causality::Output,
                "event indicator `z` must be a continuous Real local",
            ),
            (
                |t| t.retain(|v| !v.state && v.derivative_of.is_none()),
                "at least one state",
            ),
        ];
        for (edit, message) in cases {
            let mut t = table();
            edit(&mut t);
            let e = info(t).unwrap_err().to_string();
            assert!(e.contains(message), "{e}");
        }
    }
}
