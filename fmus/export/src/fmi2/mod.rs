//! The FMI 2.0 front: the `fmi2*` C entry points (Co-Simulation and, for the models that offer
//! it, Model Exchange) over the shared ABI ([`crate::abi`]) and the instance, with the masks
//! of [`crate::instance::state::fmi2`] ([`functions`]).
//!
//! - [`ffi`]: the entry points, generic over the model (instantiation, life cycle, get/set,
//!   step, FMU states, status queries);
//! - [`model_exchange`]: `fmi2NewDiscreteStates`, `fmi2GetDirectionalDerivative`;
//! - [`export_fmi2!`](crate::export_fmi2): the `fmi2*` symbols of one FMU binary, emitted by
//!   [`export_fmu!`](crate::export_fmu) beside the `fmi3*` ones.
//!
//! The shape of [`crate::fmi3`]; adding a function is a symbol in [`export_fmi2!`](crate::export_fmi2), its
//! function in [`ffi`] and its mask in [`crate::instance::state::fmi2`].

pub mod ffi;
pub mod model_exchange;

pub use crate::instance::state::fmi2 as functions;

/// Emits, inside [`export_fmu!`](crate::export_fmu), the FMI 2.0 C API of the model type
/// `$model`: the Co-Simulation functions (`fmi2GetTypesPlatform` … `fmi2GetStringStatus`),
/// the Model Exchange ones (refusing their calls on a Co-Simulation instance), and those of
/// the capabilities the FMUs do not declare, rejecting every call with a logged reason.
#[doc(hidden)]
#[macro_export]
macro_rules! export_fmi2 {
    ($model:ty) => {
        mod fmi2_exports {
            #![allow(unsafe_code, non_snake_case, clippy::missing_safety_doc)]
            #[allow(unused_imports)]
            use super::*;
            use $crate::fmi2::ffi;
            use $crate::fmi2::functions;
            use $crate::fmi2::model_exchange as me;
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
}

/// Emits, inside [`export_fmu!`](crate::export_fmu), an `fmi2*` entry point of a capability the FMUs do not
/// declare: it rejects every call, naming the capability's attribute.
#[doc(hidden)]
#[macro_export]
macro_rules! unsupported_fmi2_function {
    ($name:ident($($arg:ident: $type:ty),* $(,)?) => $function:ident, $capability:expr) => {
        #[no_mangle]
        pub unsafe extern "C" fn $name(c: fmi2Component, $($arg: $type),*) -> fmi2Status {
            unsafe { $crate::fmi2::ffi::unsupported::<M>(c, &functions::$function, $capability) }
        }
    };
}

/// Emits, inside [`export_fmu!`](crate::export_fmu), the `fmi2Get*Status` functions: each name with its
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
