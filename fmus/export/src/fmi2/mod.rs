//! The FMI 2.0 front: the `fmi2*` C entry points (Co-Simulation and, for the models that offer
//! it, Model Exchange) over the shared ABI ([`crate::abi`]) and the instance, with the masks
//! of [`crate::instance::state::fmi2`] ([`functions`]).
//!
//! - [`ffi`]: the entry points of the life cycle (instantiation, initialization, step, FMU
//!   states, status queries, the capabilities the FMUs do not declare);
//! - [`values`]: the typed get/set functions;
//! - [`model_exchange`]: the Model Exchange functions and `fmi2GetDirectionalDerivative`
//!   (those both versions have alike are [`crate::abi::model_exchange`]'s);
//!
//! Each file holds its functions, generic over the model, and beside them the macro that emits
//! their `#[no_mangle]` symbols in one FMU binary ([`export_fmu!`](crate::export_fmu) calls
//! it): adding a function touches the file of its concern and, for
//! its allowed states, [`crate::instance::state::fmi2`]. The shape of [`crate::fmi3`].

pub mod ffi;
pub mod model_exchange;
pub mod values;

pub use crate::instance::state::fmi2 as functions;
