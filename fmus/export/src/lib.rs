//! The export layer shared by every spurio FMU: the FMI 2.0 and FMI 3.0 Co-Simulation fronts.
//!
//! One implementation of the FMI plumbing for all FMUs, with no dependencies:
//! - [`types`]: the C types of the standard headers;
//! - [`variables`]: the variable table (value reference = index) and the instance values;
//! - [`description`]: the model identity and `modelDescription.xml`, generated from the table
//!   (so the XML and the binary cannot disagree), with a GUID hashed from the interface;
//! - [`model`]: the safe trait a model implements (`describe`, `create`, `initialize`,
//!   `do_step`, state save/load);
//! - [`instance`]: the state machine with allowed-state masks per function, argument checks,
//!   the logger (always `"%s"` + message), FMU states;
//! - [`ffi`]: the raw C entry points, each wrapped in `catch_unwind`;
//! - [`fmi3`]: the FMI 3.0 front over the same model, instance and table (arrays, its model
//!   description, the `fmi3*` entry points);
//! - [`query`]: the non-FMI questions a packager asks a built library (bundled variants,
//!   model description of a configuration);
//! - [`testing`]: the checks every FMU crate runs on itself;
//! - [`export_fmu!`]: emits the `fmi2*`, `fmi3*` and query symbols of one FMU binary for a
//!   model type, with its bundled variants.
//!
//! No global state: every instance owns all it uses, so any number of instances of any
//! number of FMUs live in one process.

pub mod bytes;
pub mod description;
pub mod ffi;
pub mod fmi3;
pub mod front;
pub mod harness;
pub mod instance;
pub mod me;
pub mod model;
pub mod query;
pub mod testing;
pub mod types;
pub mod uri;
pub mod variables;

pub use bytes::{ByteReader, ByteWriter};
pub use description::{Config, DefaultExperiment, ModelInfo};
pub use me::ModelExchangeInfo;
pub use model::{Cause, Context, EventUpdate, Failure, FmuModel, ModelExchange};
pub use variables::{
    rows, Causality, Initial, Value, Values, Variability, Variable, VariableTable, VariableType,
};

/// Emits, in the crate that builds an FMU's `cdylib`, the FMI 2.0 Co-Simulation C API
/// (`fmi2GetTypesPlatform` … `fmi2GetStringStatus`) and the FMI 3.0 one (`fmi3GetVersion` …,
/// see [`fmi3`]) for the model type `$model`, the query
/// symbols of [`query`] and `pub fn bundled_variants()`, and a test that the committed model
/// descriptions of those variants are up to date.
///
/// The variants are `(file stem, configuration)` pairs; without any, the FMU has one: its
/// default configuration, named by its model identifier.
///
/// ```ignore
/// spurio_export::export_fmu!(GantryCraneFmu);
/// spurio_export::export_fmu!(SensorFmu, variants = [("Sensor", Config::new()), ("Sensor2", two)]);
/// // Model Exchange too (the model implements `ModelExchange` and its description says
/// // `.with_model_exchange()`):
/// spurio_export::export_fmu!(GantryCraneFmu, model_exchange);
/// spurio_export::export_fmu!(LinearSystemFmu, model_exchange, variants = [("LinearSystem", c)]);
/// ```
#[macro_export]
macro_rules! export_fmu {
    (@with $model:ty, $me:expr, variants = [$(($stem:expr, $config:expr)),* $(,)?]) => {
        /// The Model Exchange functions of this FMU's model, if it offers the interface.
        #[doc(hidden)]
        pub fn spurio_model_exchange() -> ::std::option::Option<$crate::me::Hooks<$model>> {
            $me
        }

        /// The variants of this FMU that are bundled and whose model descriptions are
        /// committed: (file stem, configuration).
        pub fn bundled_variants() -> Vec<$crate::query::Variant> {
            let declared: Vec<$crate::query::Variant> =
                vec![$((::std::string::ToString::to_string(&$stem), $config)),*];
            if declared.is_empty() {
                $crate::query::default_variants::<$model>()
            } else {
                declared
            }
        }

        #[cfg(test)]
        mod bundled_variants_tests {
            #[allow(unused_imports)]
            use super::*;
            #[test]
            fn committed_model_descriptions_match_the_declaration() {
                $crate::testing::check_bundled_variants::<$model>(
                    &super::bundled_variants(),
                    ::std::path::Path::new(env!("CARGO_MANIFEST_DIR")),
                );
            }
            #[test]
            fn model_exchange_is_declared_where_it_is_exported() {
                $crate::testing::check_interfaces::<$model>(
                    &super::bundled_variants(),
                    super::spurio_model_exchange().is_some(),
                );
            }
        }

        mod query_exports {
            #![allow(unsafe_code, clippy::missing_safety_doc)]
            #[allow(unused_imports)]
            use super::*;

            #[no_mangle]
            pub unsafe extern "C" fn spurio_variants(out: *mut u8, capacity: usize) -> usize {
                unsafe { $crate::ffi::query_variants(super::bundled_variants, out, capacity) }
            }
            #[no_mangle]
            pub unsafe extern "C" fn spurio_describe(
                config: *const ::std::os::raw::c_char,
                out: *mut u8,
                capacity: usize,
            ) -> isize {
                unsafe { $crate::ffi::query_describe::<$model>(config, out, capacity) }
            }
            #[no_mangle]
            pub unsafe extern "C" fn spurio_describe3(
                config: *const ::std::os::raw::c_char,
                out: *mut u8,
                capacity: usize,
            ) -> isize {
                unsafe {
                    $crate::ffi::query_describe_with(
                        $crate::query::describe3::<$model>,
                        config,
                        out,
                        capacity,
                    )
                }
            }
        }

        $crate::export_fmi3!($model);

        mod fmi2_exports {
            #![allow(unsafe_code, non_snake_case, clippy::missing_safety_doc)]
            #[allow(unused_imports)]
            use super::*;
            use $crate::ffi;
            use $crate::instance::functions;
            use $crate::me::ffi as me;
            use $crate::types::*;
            type M = $model;

            #[no_mangle]
            pub extern "C" fn fmi2GetTypesPlatform() -> *const fmi2Char {
                ffi::types_platform()
            }
            #[no_mangle]
            pub extern "C" fn fmi2GetVersion() -> *const fmi2Char {
                ffi::version()
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2SetDebugLogging(
                c: fmi2Component,
                on: fmi2Boolean,
                n: usize,
                categories: *const fmi2String,
            ) -> fmi2Status {
                unsafe { ffi::set_debug_logging::<M>(c, on, n, categories) }
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2Instantiate(
                name: fmi2String,
                kind: fmi2Type,
                guid: fmi2String,
                resources: fmi2String,
                callbacks: *const fmi2CallbackFunctions,
                visible: fmi2Boolean,
                logging_on: fmi2Boolean,
            ) -> fmi2Component {
                unsafe {
                    ffi::instantiate::<M>(
                        name,
                        kind,
                        guid,
                        resources,
                        callbacks,
                        visible,
                        logging_on,
                        super::spurio_model_exchange(),
                    )
                }
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2FreeInstance(c: fmi2Component) {
                unsafe { ffi::free_instance::<M>(c) }
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2SetupExperiment(
                c: fmi2Component,
                tolerance_defined: fmi2Boolean,
                tolerance: fmi2Real,
                start: fmi2Real,
                stop_defined: fmi2Boolean,
                stop: fmi2Real,
            ) -> fmi2Status {
                unsafe {
                    ffi::setup_experiment::<M>(
                        c,
                        tolerance_defined,
                        tolerance,
                        start,
                        stop_defined,
                        stop,
                    )
                }
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2EnterInitializationMode(c: fmi2Component) -> fmi2Status {
                unsafe { ffi::enter_initialization_mode::<M>(c) }
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2ExitInitializationMode(c: fmi2Component) -> fmi2Status {
                unsafe { ffi::exit_initialization_mode::<M>(c) }
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2Terminate(c: fmi2Component) -> fmi2Status {
                unsafe { ffi::terminate::<M>(c) }
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2Reset(c: fmi2Component) -> fmi2Status {
                unsafe { ffi::reset::<M>(c) }
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2GetReal(
                c: fmi2Component,
                vr: *const fmi2ValueReference,
                n: usize,
                value: *mut fmi2Real,
            ) -> fmi2Status {
                unsafe { ffi::get::<M, ffi::Real>(c, vr, n, value) }
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2GetInteger(
                c: fmi2Component,
                vr: *const fmi2ValueReference,
                n: usize,
                value: *mut fmi2Integer,
            ) -> fmi2Status {
                unsafe { ffi::get::<M, ffi::Integer>(c, vr, n, value) }
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2GetBoolean(
                c: fmi2Component,
                vr: *const fmi2ValueReference,
                n: usize,
                value: *mut fmi2Boolean,
            ) -> fmi2Status {
                unsafe { ffi::get::<M, ffi::Boolean>(c, vr, n, value) }
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2GetString(
                c: fmi2Component,
                vr: *const fmi2ValueReference,
                n: usize,
                value: *mut fmi2String,
            ) -> fmi2Status {
                unsafe { ffi::get_string::<M>(c, vr, n, value) }
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2SetReal(
                c: fmi2Component,
                vr: *const fmi2ValueReference,
                n: usize,
                value: *const fmi2Real,
            ) -> fmi2Status {
                unsafe { ffi::set::<M, ffi::Real>(c, vr, n, value) }
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2SetInteger(
                c: fmi2Component,
                vr: *const fmi2ValueReference,
                n: usize,
                value: *const fmi2Integer,
            ) -> fmi2Status {
                unsafe { ffi::set::<M, ffi::Integer>(c, vr, n, value) }
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2SetBoolean(
                c: fmi2Component,
                vr: *const fmi2ValueReference,
                n: usize,
                value: *const fmi2Boolean,
            ) -> fmi2Status {
                unsafe { ffi::set::<M, ffi::Boolean>(c, vr, n, value) }
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2SetString(
                c: fmi2Component,
                vr: *const fmi2ValueReference,
                n: usize,
                value: *const fmi2String,
            ) -> fmi2Status {
                unsafe { ffi::set_string::<M>(c, vr, n, value) }
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2GetFMUstate(
                c: fmi2Component,
                state: *mut fmi2FMUstate,
            ) -> fmi2Status {
                unsafe { ffi::get_fmu_state::<M>(c, state) }
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2SetFMUstate(
                c: fmi2Component,
                state: fmi2FMUstate,
            ) -> fmi2Status {
                unsafe { ffi::set_fmu_state::<M>(c, state) }
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2FreeFMUstate(
                c: fmi2Component,
                state: *mut fmi2FMUstate,
            ) -> fmi2Status {
                unsafe { ffi::free_fmu_state::<M>(c, state) }
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2SerializedFMUstateSize(
                c: fmi2Component,
                state: fmi2FMUstate,
                size: *mut usize,
            ) -> fmi2Status {
                unsafe { ffi::serialized_fmu_state_size::<M>(c, state, size) }
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2SerializeFMUstate(
                c: fmi2Component,
                state: fmi2FMUstate,
                bytes: *mut fmi2Byte,
                size: usize,
            ) -> fmi2Status {
                unsafe { ffi::serialize_fmu_state::<M>(c, state, bytes, size) }
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2DeSerializeFMUstate(
                c: fmi2Component,
                bytes: *const fmi2Byte,
                size: usize,
                state: *mut fmi2FMUstate,
            ) -> fmi2Status {
                unsafe { ffi::deserialize_fmu_state::<M>(c, bytes, size, state) }
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2GetDirectionalDerivative(
                c: fmi2Component,
                unknowns: *const fmi2ValueReference,
                n_unknowns: usize,
                knowns: *const fmi2ValueReference,
                n_knowns: usize,
                seed: *const fmi2Real,
                out: *mut fmi2Real,
            ) -> fmi2Status {
                unsafe {
                    me::get_directional_derivative::<M>(
                        c, unknowns, n_unknowns, knowns, n_knowns, seed, out,
                    )
                }
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2SetTime(c: fmi2Component, time: fmi2Real) -> fmi2Status {
                unsafe { me::set_time::<M>(c, time) }
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2SetContinuousStates(
                c: fmi2Component,
                x: *const fmi2Real,
                nx: usize,
            ) -> fmi2Status {
                unsafe { me::set_continuous_states::<M>(c, x, nx) }
            }
            $crate::fmi2_array_getter!(fmi2GetContinuousStates, get_continuous_states);
            $crate::fmi2_array_getter!(fmi2GetDerivatives, get_derivatives);
            $crate::fmi2_array_getter!(fmi2GetEventIndicators, get_event_indicators);
            $crate::fmi2_array_getter!(
                fmi2GetNominalsOfContinuousStates,
                get_nominals_of_continuous_states
            );
            #[no_mangle]
            pub unsafe extern "C" fn fmi2EnterEventMode(c: fmi2Component) -> fmi2Status {
                unsafe { me::enter_event_mode::<M>(c) }
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2NewDiscreteStates(
                c: fmi2Component,
                event_info: *mut me::fmi2EventInfo,
            ) -> fmi2Status {
                unsafe { me::new_discrete_states::<M>(c, event_info) }
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2EnterContinuousTimeMode(c: fmi2Component) -> fmi2Status {
                unsafe { me::enter_continuous_time_mode::<M>(c) }
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2CompletedIntegratorStep(
                c: fmi2Component,
                no_set_prior: fmi2Boolean,
                enter_event_mode: *mut fmi2Boolean,
                terminate_simulation: *mut fmi2Boolean,
            ) -> fmi2Status {
                unsafe {
                    me::completed_integrator_step::<M>(
                        c,
                        no_set_prior,
                        enter_event_mode,
                        terminate_simulation,
                    )
                }
            }
            $crate::unsupported_fmi2_function!(
                fmi2SetRealInputDerivatives(
                    _vr: *const fmi2ValueReference,
                    _n: usize,
                    _order: *const fmi2Integer,
                    _value: *const fmi2Real,
                ) => SET_REAL_INPUT_DERIVATIVES, "canInterpolateInputs=\"false\""
            );
            $crate::unsupported_fmi2_function!(
                fmi2GetRealOutputDerivatives(
                    _vr: *const fmi2ValueReference,
                    _n: usize,
                    _order: *const fmi2Integer,
                    _value: *mut fmi2Real,
                ) => GET_REAL_OUTPUT_DERIVATIVES, "maxOutputDerivativeOrder=\"0\""
            );
            #[no_mangle]
            pub unsafe extern "C" fn fmi2DoStep(
                c: fmi2Component,
                t: fmi2Real,
                h: fmi2Real,
                no_set_prior: fmi2Boolean,
            ) -> fmi2Status {
                unsafe { ffi::do_step::<M>(c, t, h, no_set_prior) }
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2CancelStep(c: fmi2Component) -> fmi2Status {
                unsafe { ffi::cancel_step::<M>(c) }
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2GetStatus(
                c: fmi2Component,
                kind: fmi2StatusKind,
                value: *mut fmi2Status,
            ) -> fmi2Status {
                let _ = value;
                unsafe { ffi::get_status::<M>(c, &functions::GET_STATUS, kind) }
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2GetRealStatus(
                c: fmi2Component,
                kind: fmi2StatusKind,
                value: *mut fmi2Real,
            ) -> fmi2Status {
                unsafe { ffi::get_real_status::<M>(c, kind, value) }
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2GetIntegerStatus(
                c: fmi2Component,
                kind: fmi2StatusKind,
                value: *mut fmi2Integer,
            ) -> fmi2Status {
                let _ = value;
                unsafe { ffi::get_status::<M>(c, &functions::GET_INTEGER_STATUS, kind) }
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2GetBooleanStatus(
                c: fmi2Component,
                kind: fmi2StatusKind,
                value: *mut fmi2Boolean,
            ) -> fmi2Status {
                unsafe { ffi::get_boolean_status::<M>(c, kind, value) }
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2GetStringStatus(
                c: fmi2Component,
                kind: fmi2StatusKind,
                value: *mut fmi2String,
            ) -> fmi2Status {
                unsafe { ffi::get_string_status::<M>(c, kind, value) }
            }
        }
    };
    ($model:ty) => {
        $crate::export_fmu!(@with $model, None, variants = []);
    };
    ($model:ty, model_exchange) => {
        $crate::export_fmu!(@with $model, Some($crate::me::hooks::<$model>()), variants = []);
    };
    ($model:ty, variants = [$($variants:tt)*]) => {
        $crate::export_fmu!(@with $model, None, variants = [$($variants)*]);
    };
    ($model:ty, model_exchange, variants = [$($variants:tt)*]) => {
        $crate::export_fmu!(
            @with $model,
            Some($crate::me::hooks::<$model>()),
            variants = [$($variants)*]
        );
    };
}

/// Emits, inside [`export_fmu!`], an `fmi2*` entry point of a capability the FMUs do not
/// declare: it rejects every call, naming the capability's attribute.
#[doc(hidden)]
#[macro_export]
macro_rules! unsupported_fmi2_function {
    ($name:ident($($arg:ident: $type:ty),* $(,)?) => $function:ident, $capability:expr) => {
        #[no_mangle]
        pub unsafe extern "C" fn $name(c: fmi2Component, $($arg: $type),*) -> fmi2Status {
            unsafe { $crate::ffi::unsupported::<M>(c, &functions::$function, $capability) }
        }
    };
}

/// Emits, inside [`export_fmu!`], an FMI 2.0 Model Exchange function that fills the caller's
/// Real array (`fmi2GetDerivatives`, …).
#[doc(hidden)]
#[macro_export]
macro_rules! fmi2_array_getter {
    ($name:ident, $function:ident) => {
        #[no_mangle]
        pub unsafe extern "C" fn $name(
            c: fmi2Component,
            out: *mut fmi2Real,
            n: usize,
        ) -> fmi2Status {
            unsafe { me::$function::<M>(c, out, n) }
        }
    };
}
