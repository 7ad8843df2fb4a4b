//! The export layer shared by every spurio FMU: the FMI 2.0 and FMI 3.0 fronts, Co-Simulation
//! and (for the models that offer it) Model Exchange.
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
//! - [`me`]: Model Exchange for both versions — the states, derivatives and event indicators
//!   a model declares in its table, the [`ModelExchange`] calls of an instance (the Model
//!   Exchange state machine: Instantiated → Initialization → Event ↔ Continuous-Time →
//!   Terminated), and the entry points both fronts share;
//! - [`fmi3`]: the FMI 3.0 front over the same model, instance and table (arrays, its model
//!   description, the `fmi3*` entry points);
//! - [`query`]: the non-FMI questions a packager asks a built library (bundled variants,
//!   model description of a configuration);
//! - [`testing`]: the checks every FMU crate runs on itself;
//! - [`export_fmu!`]: emits the `fmi2*`, `fmi3*` and query symbols of one FMU binary for a
//!   model type, with its bundled variants.
//!
//! One piece of process-wide state: the interfaces ([`front::interface`]: the model
//! description, the access table of the get/set checks, the FMI 3.0 arrays), built once per
//! model and configuration and shared read-only by their instances; everything else an
//! instance owns, so any number of instances of any number of FMUs live in one process.
//! Once initialised, an instance's set/step/get calls allocate nothing in this layer
//! (`tests/allocations.rs`; every FMU: `tests/allocations/run`).

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
            $crate::instance_entries!(fmi2Component;
                fmi2EnterInitializationMode = enter_initialization_mode,
                fmi2ExitInitializationMode = exit_initialization_mode,
                fmi2Terminate = terminate, fmi2Reset = reset);
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
            $crate::fmu_state_entries!(
                fmi2Component, fmi2FMUstate, fmi2Byte;
                fmi2GetFMUstate, fmi2SetFMUstate, fmi2FreeFMUstate,
                fmi2SerializedFMUstateSize, fmi2SerializeFMUstate, fmi2DeSerializeFMUstate
            );
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
                let (u, k) = ((unknowns, n_unknowns), (knowns, n_knowns));
                unsafe { me::get_directional_derivative::<M>(c, u, k, seed, out) }
            }
            $crate::model_exchange_entries!(fmi2Component, (), fmi2Boolean, functions;
                fmi2SetTime, fmi2SetContinuousStates, fmi2EnterEventMode, fmi2EnterContinuousTimeMode,
                fmi2CompletedIntegratorStep, fmi2GetContinuousStates, fmi2GetDerivatives,
                fmi2GetEventIndicators, fmi2GetNominalsOfContinuousStates);
            #[no_mangle]
            pub unsafe extern "C" fn fmi2NewDiscreteStates(
                c: fmi2Component,
                event_info: *mut me::fmi2EventInfo,
            ) -> fmi2Status {
                unsafe { me::new_discrete_states::<M>(c, event_info) }
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
            $crate::fmi2_status_queries! {
                fmi2GetStatus(c, kind, value: fmi2Status) => {
                    let _ = value;
                    ffi::get_status::<M>(c, &functions::GET_STATUS, kind)
                };
                fmi2GetRealStatus(c, kind, value: fmi2Real) => ffi::get_real_status::<M>(c, kind, value);
                fmi2GetIntegerStatus(c, kind, value: fmi2Integer) => {
                    let _ = value;
                    ffi::get_status::<M>(c, &functions::GET_INTEGER_STATUS, kind)
                };
                fmi2GetBooleanStatus(c, kind, value: fmi2Boolean) => ffi::get_boolean_status::<M>(c, kind, value);
                fmi2GetStringStatus(c, kind, value: fmi2String) => ffi::get_string_status::<M>(c, kind, value);
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

/// Emits, inside [`export_fmu!`] or [`export_fmi3!`], the Model Exchange functions both
/// versions have alike (`fmi2SetTime`/`fmi3SetTime`, …, and those that fill the caller's Real
/// array: `fmi2GetDerivatives`, `fmi3GetContinuousStateDerivatives`, …) for the front's handle
/// type, slot data, Boolean type and `functions` module; the names in the standard's order.
#[doc(hidden)]
#[macro_export]
macro_rules! model_exchange_entries {
    (
        $handle:ty, $extra:ty, $boolean:ty, $functions:ident;
        $set_time:ident, $set_states:ident, $event_mode:ident, $continuous_mode:ident,
        $completed:ident, $states:ident, $derivatives:ident, $indicators:ident, $nominals:ident
    ) => {
        #[no_mangle]
        pub unsafe extern "C" fn $set_time(c: $handle, time: f64) -> ::std::os::raw::c_int {
            let f = &$functions::SET_TIME;
            unsafe { $crate::me::ffi::set_time::<M, $extra>(c, f, time) }
        }
        #[no_mangle]
        pub unsafe extern "C" fn $set_states(
            c: $handle,
            x: *const f64,
            n: usize,
        ) -> ::std::os::raw::c_int {
            let f = &$functions::SET_CONTINUOUS_STATES;
            unsafe { $crate::me::ffi::set_continuous_states::<M, $extra>(c, f, x, n) }
        }
        #[no_mangle]
        pub unsafe extern "C" fn $event_mode(c: $handle) -> ::std::os::raw::c_int {
            let f = &$functions::ENTER_EVENT_MODE;
            unsafe { $crate::me::ffi::enter_mode::<M, $extra>(c, f, true) }
        }
        #[no_mangle]
        pub unsafe extern "C" fn $continuous_mode(c: $handle) -> ::std::os::raw::c_int {
            let f = &$functions::ENTER_CONTINUOUS_TIME_MODE;
            unsafe { $crate::me::ffi::enter_mode::<M, $extra>(c, f, false) }
        }
        #[no_mangle]
        pub unsafe extern "C" fn $completed(
            c: $handle,
            no_set_prior: $boolean,
            enter_event_mode: *mut $boolean,
            terminate_simulation: *mut $boolean,
        ) -> ::std::os::raw::c_int {
            let _ = no_set_prior;
            let f = &$functions::COMPLETED_INTEGRATOR_STEP;
            let (event, stop) = (enter_event_mode, terminate_simulation);
            unsafe { $crate::me::ffi::completed_integrator_step::<M, $extra, _>(c, f, event, stop) }
        }
        $crate::model_exchange_entries!(@array $handle, $extra, $functions;
            $states = GET_CONTINUOUS_STATES, ContinuousStates;
            $derivatives = GET_DERIVATIVES, Derivatives;
            $indicators = GET_EVENT_INDICATORS, EventIndicators;
            $nominals = GET_NOMINALS_OF_CONTINUOUS_STATES, Nominals;
        );
    };
    (@array $handle:ty, $extra:ty, $functions:ident; $($name:ident = $function:ident, $array:ident;)+) => {
        $(
            #[no_mangle]
            pub unsafe extern "C" fn $name(c: $handle, out: *mut f64, n: usize) -> ::std::os::raw::c_int {
                let (f, which) = (&$functions::$function, $crate::me::ffi::Array::$array);
                unsafe { $crate::me::ffi::get_array::<M, $extra>(c, f, which, out, n) }
            }
        )+
    };
}

/// Emits, inside [`export_fmu!`] or [`export_fmi3!`], the six FMU-state functions of a front
/// (its handle, FMU-state and byte types; the names in the standard's order) over the `ffi`
/// module in scope.
#[doc(hidden)]
#[macro_export]
macro_rules! fmu_state_entries {
    (
        $handle:ty, $state:ty, $byte:ty;
        $get:ident, $set:ident, $free:ident, $size:ident, $serialize:ident, $deserialize:ident
    ) => {
        #[no_mangle]
        pub unsafe extern "C" fn $get(c: $handle, state: *mut $state) -> ::std::os::raw::c_int {
            unsafe { ffi::get_fmu_state::<M>(c, state) }
        }
        #[no_mangle]
        pub unsafe extern "C" fn $set(c: $handle, state: $state) -> ::std::os::raw::c_int {
            unsafe { ffi::set_fmu_state::<M>(c, state) }
        }
        #[no_mangle]
        pub unsafe extern "C" fn $free(c: $handle, state: *mut $state) -> ::std::os::raw::c_int {
            unsafe { ffi::free_fmu_state::<M>(c, state) }
        }
        #[no_mangle]
        pub unsafe extern "C" fn $size(
            c: $handle,
            state: $state,
            size: *mut usize,
        ) -> ::std::os::raw::c_int {
            unsafe { ffi::serialized_fmu_state_size::<M>(c, state, size) }
        }
        #[no_mangle]
        pub unsafe extern "C" fn $serialize(
            c: $handle,
            state: $state,
            bytes: *mut $byte,
            size: usize,
        ) -> ::std::os::raw::c_int {
            unsafe { ffi::serialize_fmu_state::<M>(c, state, bytes, size) }
        }
        #[no_mangle]
        pub unsafe extern "C" fn $deserialize(
            c: $handle,
            bytes: *const $byte,
            size: usize,
            state: *mut $state,
        ) -> ::std::os::raw::c_int {
            unsafe { ffi::deserialize_fmu_state::<M>(c, bytes, size, state) }
        }
    };
}

/// Emits, inside [`export_fmu!`], the `fmi2Get*Status` functions: each name with its
/// parameters' names and value type, and the call that answers it.
#[doc(hidden)]
#[macro_export]
macro_rules! fmi2_status_queries {
    ($($name:ident($c:ident, $kind:ident, $value:ident: $t:ty) => $body:expr;)+) => {
        $(
            #[no_mangle]
            pub unsafe extern "C" fn $name(
                $c: fmi2Component,
                $kind: fmi2StatusKind,
                $value: *mut $t,
            ) -> fmi2Status {
                unsafe { $body }
            }
        )+
    };
}

/// Emits, inside [`export_fmu!`] or [`export_fmi3!`], the entry points that take only the
/// instance: each name with the function of the `ffi` module in scope that it calls.
#[doc(hidden)]
#[macro_export]
macro_rules! instance_entries {
    ($handle:ty; $($name:ident = $function:ident),+ $(,)?) => {
        $(
            #[no_mangle]
            pub unsafe extern "C" fn $name(c: $handle) -> ::std::os::raw::c_int {
                unsafe { ffi::$function::<M>(c) }
            }
        )+
    };
}
