//! One FMU instance: the state machine around a safe [`crate::model::FmuModel`] that both
//! fronts drive (FMI 3.0's Step Mode is the shared machine's `StepComplete`; the methods named
//! `…_as` take the calling function, so messages name the `fmi3*` one). Split by concern, as
//! rust-fmi's `fmi-export/src/fmi3/instance/`, each file one `impl Instance` or the table it
//! reads; the imports point one way, from the top of this list down:
//!
//! - [`model_exchange`]: the Model Exchange calls (states, derivatives, event indicators,
//!   directional derivatives);
//! - [`fmu_state`]: FMU states and their (de)serialisation, checked before accepted;
//! - [`step`]: every model call with its roll-back and finiteness check, and the step;
//! - [`get_set`]: values and their access checks, `fmi*Get*`/`fmi*Set*`;
//! - [`common`]: the instance ([`Instance`], [`Core`]), its creation, the state-mask check,
//!   rejections and the life-cycle calls;
//! - [`mod@interface`]: what the instances of one configuration share ([`Interface`]);
//! - [`access`]: how each variable may be accessed ([`Access`]);
//! - [`log`]: the logger ([`Logger`], [`LogSink`]);
//! - [`state`]: the states and both versions' allowed-state masks ([`state::fmi2`],
//!   [`state::fmi3`]).
//!
//! Every entry point is checked against an allowed-state mask (as the Reference-FMUs do in
//! `fmi2Functions.c`), every value reference against the variable table, every value against
//! the variable's type, causality, variability, bounds and finiteness — before anything is
//! changed, so a rejected call loses nothing. Errors are logged with the function's name and
//! the expected vs. actual value.
//!
//! Calls that the instance rejects (illegal call sequence, unknown value reference, a NaN
//! input, a value out of bounds, a step whose end `t + h` is not finite or that the model
//! refuses in `check_step`) return `fmi2Error` and leave the instance as it was; a model that
//! fails inside initialisation or a step moves the instance to the `Error` state, from which
//! `fmi2SetFMUstate`, `fmi2Reset` or `fmi2FreeInstance` lead on. No non-finite value is ever
//! published ([`step`]); a serialized state is checked before it is accepted ([`fmu_state`]).

pub mod access;
pub mod common;
pub mod fmu_state;
pub mod get_set;
pub mod interface;
pub mod log;
pub mod model_exchange;
pub mod state;
pub mod step;

pub use access::Access;
pub use common::{Core, Indicators, Instance};
pub use fmu_state::StateError;
pub use interface::{interface, Interface, Span, Window, WINDOW};
pub use log::{LogSink, Logger};
pub use state::{Function, ModelState};
