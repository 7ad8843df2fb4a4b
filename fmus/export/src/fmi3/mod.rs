//! The FMI 3.0 front of the export layer: the `fmi3*` C entry points over the same model,
//! variable table and [`Instance`](crate::instance::Instance) (state machine, argument checks,
//! logging, FMU states) as FMI 2.0, with the masks of [`crate::instance::state::fmi3`]
//! ([`functions`]). The shape of [`crate::fmi2`]:
//! - [`ffi`]: the entry points of the life cycle (instantiation, initialization, step,
//!   FMU states), generic over the model;
//! - [`values`]: the typed get/set functions over arrays;
//! - [`model_exchange`]: the Model Exchange functions FMI 2.0 has not in the same form (the
//!   counts, `fmi3UpdateDiscreteStates`, directional and adjoint derivatives over arrays);
//! - [`types`]: the C types of `fmi3PlatformTypes.h` / `fmi3FunctionTypes.h`;
//!
//! Each file holds its functions, generic over the model, and beside them the macro that emits
//! their `#[no_mangle]` symbols in one FMU binary ([`export_fmu!`](crate::export_fmu) calls
//! it): adding a function touches the file of its concern and, for
//! its allowed states, [`crate::instance::state::fmi3`].
//!
//! FMI 3.0 Co-Simulation states map onto the shared machine: Instantiated, Initialization
//! Mode, Step Mode (the FMI 2.0 `StepComplete`), Terminated, and the error states; Model
//! Exchange onto its Event and Continuous-Time Modes. `fmi3InstantiateModelExchange` creates
//! a Model Exchange instance for a model that offers the interface
//! (`export_fmu!(Model, model_exchange)`) and refuses, with a logged reason, for one that does
//! not. The FMUs declare no Co-Simulation event mode, no clocks, no structural parameters
//! (dimensions stay packaging variants: see the README), so Configuration Mode, the
//! Co-Simulation Event Mode and Scheduled Execution are exported but refuse every call with a
//! logged reason.

pub mod ffi;
pub mod model_exchange;
pub mod types;
pub mod values;

pub use crate::instance::state::fmi3 as functions;
