//! The Model Exchange interface a model declares in its variable table: the continuous states,
//! their derivatives and the event indicators, checked for consistency (the instance's calls
//! are `crate::instance::model_exchange`).
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
//! only when they are read: `crate::instance::Indicators`), checks every result
//! for finiteness (a non-finite derivative, output or event indicator is an error naming it,
//! never published), and refuses the Model Exchange functions on a Co-Simulation instance.
//! Directional derivatives serve Co-Simulation instances too, at the values of the last step.

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

    /// The nominal of each state (its declared `nominal`, 1 by default), in the order of
    /// `states`, without allocating (`fmi2GetNominalsOfContinuousStates` is called at every
    /// restart of an importer's integration).
    pub fn nominals<'a>(&'a self, variables: &'a [Variable]) -> impl Iterator<Item = f64> + 'a {
        self.states
            .iter()
            .map(|&i| variables[i].nominal.unwrap_or(1.0))
    }
}
