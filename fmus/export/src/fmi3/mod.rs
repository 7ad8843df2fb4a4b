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
//! - [`export_fmi3!`](crate::export_fmi3): the `fmi3*` symbols of one FMU binary, emitted by
//!   [`export_fmu!`](crate::export_fmu) beside the `fmi2*` ones.
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

/// Emits, inside [`export_fmu!`](crate::export_fmu), the FMI 3.0 C API of the model type
/// `$model`: the Co-Simulation functions, and every other `fmi3*` function of the standard
/// headers rejecting its calls with a logged reason (or returning NULL, for the Model
/// Exchange and Scheduled Execution instantiation).
#[doc(hidden)]
#[macro_export]
macro_rules! export_fmi3 {
    ($model:ty) => {
        mod fmi3_exports {
            #![allow(unsafe_code, non_snake_case, clippy::missing_safety_doc)]
            #[allow(unused_imports)]
            use super::*;
            use $crate::abi::kinds::Fmi3;
            use $crate::fmi3::ffi;
            use $crate::fmi3::functions;
            use $crate::fmi3::model_exchange as me;
            use $crate::fmi3::types::*;
            type M = $model;

            #[no_mangle]
            pub extern "C" fn fmi3GetVersion() -> *const fmi3Char {
                ffi::version()
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3SetDebugLogging(
                c: fmi3Instance,
                on: fmi3Boolean,
                n: usize,
                categories: *const fmi3String,
            ) -> fmi3Status {
                unsafe { ffi::set_debug_logging::<M>(c, on, n, categories) }
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3InstantiateCoSimulation(
                name: fmi3String,
                token: fmi3String,
                resources: fmi3String,
                visible: fmi3Boolean,
                logging_on: fmi3Boolean,
                event_mode_used: fmi3Boolean,
                early_return_allowed: fmi3Boolean,
                required: *const fmi3ValueReference,
                n_required: usize,
                environment: fmi3InstanceEnvironment,
                log_message: fmi3LogMessageCallback,
                intermediate_update: fmi3IntermediateUpdateCallback,
            ) -> fmi3Instance {
                let _ = (visible, required, intermediate_update);
                let args = ffi::Instantiation(
                    name, token, resources, logging_on, environment, log_message,
                );
                let me = super::spurio_model_exchange();
                unsafe {
                    ffi::instantiate_co_simulation::<M>(
                        args,
                        event_mode_used,
                        early_return_allowed,
                        n_required,
                        me,
                    )
                }
            }
            $crate::fmi3_instantiation! {
                fmi3InstantiateModelExchange() => |args| {
                    ffi::instantiate_model_exchange::<M>(args, super::spurio_model_exchange())
                };
                fmi3InstantiateScheduledExecution(
                    clock_update: fmi3ClockUpdateCallback,
                    lock: fmi3PreemptionCallback,
                    unlock: fmi3PreemptionCallback,
                ) => |args| {
                    let _ = (clock_update, lock, unlock);
                    let f = "fmi3InstantiateScheduledExecution";
                    ffi::refuse_instantiation::<M>(f, "Scheduled Execution", args)
                };
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3FreeInstance(c: fmi3Instance) {
                unsafe { ffi::free_instance::<M>(c) }
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3EnterInitializationMode(
                c: fmi3Instance,
                tolerance_defined: fmi3Boolean,
                tolerance: fmi3Float64,
                start: fmi3Float64,
                stop_defined: fmi3Boolean,
                stop: fmi3Float64,
            ) -> fmi3Status {
                let _ = (tolerance_defined, tolerance);
                unsafe { ffi::enter_initialization_mode::<M>(c, start, stop_defined, stop) }
            }
            $crate::instance_entries!(fmi3Instance;
                fmi3ExitInitializationMode = exit_initialization_mode,
                fmi3Terminate = terminate, fmi3Reset = reset);
            #[no_mangle]
            pub unsafe extern "C" fn fmi3DoStep(
                c: fmi3Instance,
                t: fmi3Float64,
                h: fmi3Float64,
                no_set_prior: fmi3Boolean,
                event_handling_needed: *mut fmi3Boolean,
                terminate_simulation: *mut fmi3Boolean,
                early_return: *mut fmi3Boolean,
                last_successful_time: *mut fmi3Float64,
            ) -> fmi3Status {
                let _ = no_set_prior;
                unsafe {
                    ffi::do_step::<M>(
                        c,
                        t,
                        h,
                        event_handling_needed,
                        terminate_simulation,
                        early_return,
                        last_successful_time,
                    )
                }
            }
            $crate::fmi3_get_set!(fmi3GetFloat64, fmi3SetFloat64, Float64, fmi3Float64);
            $crate::fmi3_get_set!(fmi3GetInt32, fmi3SetInt32, Int32, fmi3Int32);
            $crate::fmi3_get_set!(fmi3GetBoolean, fmi3SetBoolean, Boolean, fmi3Boolean);
            #[no_mangle]
            pub unsafe extern "C" fn fmi3GetString(
                c: fmi3Instance,
                vr: *const fmi3ValueReference,
                nvr: usize,
                values: *mut fmi3String,
                n_values: usize,
            ) -> fmi3Status {
                unsafe { $crate::fmi3::values::get_string::<M>(c, vr, nvr, values, n_values) }
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3SetString(
                c: fmi3Instance,
                vr: *const fmi3ValueReference,
                nvr: usize,
                values: *const fmi3String,
                n_values: usize,
            ) -> fmi3Status {
                unsafe { $crate::fmi3::values::set_string::<M>(c, vr, nvr, values, n_values) }
            }
            $crate::fmu_state_entries!(
                fmi3Instance, fmi3FMUState, fmi3Byte;
                fmi3GetFMUState, fmi3SetFMUState, fmi3FreeFMUState,
                fmi3SerializedFMUStateSize, fmi3SerializeFMUState, fmi3DeserializeFMUState
            );
            $crate::fmi3_unsupported! {
                "the FMU declares only Float64, Int32, Boolean and String variables";
                fmi3GetFloat32(_v: *const fmi3ValueReference, _n: usize, _x: *mut fmi3Float32, _m: usize);
                fmi3SetFloat32(_v: *const fmi3ValueReference, _n: usize, _x: *const fmi3Float32, _m: usize);
                fmi3GetInt8(_v: *const fmi3ValueReference, _n: usize, _x: *mut fmi3Int8, _m: usize);
                fmi3SetInt8(_v: *const fmi3ValueReference, _n: usize, _x: *const fmi3Int8, _m: usize);
                fmi3GetUInt8(_v: *const fmi3ValueReference, _n: usize, _x: *mut fmi3UInt8, _m: usize);
                fmi3SetUInt8(_v: *const fmi3ValueReference, _n: usize, _x: *const fmi3UInt8, _m: usize);
                fmi3GetInt16(_v: *const fmi3ValueReference, _n: usize, _x: *mut fmi3Int16, _m: usize);
                fmi3SetInt16(_v: *const fmi3ValueReference, _n: usize, _x: *const fmi3Int16, _m: usize);
                fmi3GetUInt16(_v: *const fmi3ValueReference, _n: usize, _x: *mut fmi3UInt16, _m: usize);
                fmi3SetUInt16(_v: *const fmi3ValueReference, _n: usize, _x: *const fmi3UInt16, _m: usize);
                fmi3GetUInt32(_v: *const fmi3ValueReference, _n: usize, _x: *mut fmi3UInt32, _m: usize);
                fmi3SetUInt32(_v: *const fmi3ValueReference, _n: usize, _x: *const fmi3UInt32, _m: usize);
                fmi3GetInt64(_v: *const fmi3ValueReference, _n: usize, _x: *mut fmi3Int64, _m: usize);
                fmi3SetInt64(_v: *const fmi3ValueReference, _n: usize, _x: *const fmi3Int64, _m: usize);
                fmi3GetUInt64(_v: *const fmi3ValueReference, _n: usize, _x: *mut fmi3UInt64, _m: usize);
                fmi3SetUInt64(_v: *const fmi3ValueReference, _n: usize, _x: *const fmi3UInt64, _m: usize);
                fmi3GetBinary(_v: *const fmi3ValueReference, _n: usize, _s: *mut usize, _x: *mut fmi3Binary, _m: usize);
                fmi3SetBinary(_v: *const fmi3ValueReference, _n: usize, _s: *const usize, _x: *const fmi3Binary, _m: usize);
            }
            $crate::fmi3_unsupported! {
                "the FMU declares no clocks";
                fmi3GetClock(_v: *const fmi3ValueReference, _n: usize, _x: *mut fmi3Clock);
                fmi3SetClock(_v: *const fmi3ValueReference, _n: usize, _x: *const fmi3Clock);
                fmi3GetIntervalDecimal(_v: *const fmi3ValueReference, _n: usize, _x: *mut fmi3Float64, _q: *mut fmi3IntervalQualifier);
                fmi3GetIntervalFraction(_v: *const fmi3ValueReference, _n: usize, _counters: *mut fmi3UInt64, _r: *mut fmi3UInt64, _q: *mut fmi3IntervalQualifier);
                fmi3GetShiftDecimal(_v: *const fmi3ValueReference, _n: usize, _x: *mut fmi3Float64);
                fmi3GetShiftFraction(_v: *const fmi3ValueReference, _n: usize, _counters: *mut fmi3UInt64, _r: *mut fmi3UInt64);
                fmi3SetIntervalDecimal(_v: *const fmi3ValueReference, _n: usize, _x: *const fmi3Float64);
                fmi3SetIntervalFraction(_v: *const fmi3ValueReference, _n: usize, _counters: *const fmi3UInt64, _r: *const fmi3UInt64);
                fmi3SetShiftDecimal(_v: *const fmi3ValueReference, _n: usize, _x: *const fmi3Float64);
                fmi3SetShiftFraction(_v: *const fmi3ValueReference, _n: usize, _counters: *const fmi3UInt64, _r: *const fmi3UInt64);
                fmi3ActivateModelPartition(_clock: fmi3ValueReference, _t: fmi3Float64);
            }
            $crate::fmi3_unsupported! {
                "the FMU declares no structural parameters (its dimensions are packaging variants)";
                fmi3EnterConfigurationMode();
                fmi3ExitConfigurationMode();
            }
            $crate::fmi3_unsupported! {
                "the Co-Simulation interface has no event mode (hasEventMode=\"false\"): it is always in Step Mode after initialization";
                fmi3EnterStepMode();
                fmi3EvaluateDiscreteStates();
            }
            $crate::export_fmi3_model_exchange!();
            $crate::fmi3_unsupported! {
                "maxOutputDerivativeOrder=\"0\"";
                fmi3GetOutputDerivatives(_v: *const fmi3ValueReference, _n: usize, _o: *const fmi3Int32, _x: *mut fmi3Float64, _m: usize);
            }
            $crate::fmi3_unsupported! {
                "providesPerElementDependencies=\"false\": the dependencies are those of the model description's ModelStructure";
                fmi3GetNumberOfVariableDependencies(_v: fmi3ValueReference, _n: *mut usize);
                fmi3GetVariableDependencies(_v: fmi3ValueReference, _e: *mut usize, _i: *mut fmi3ValueReference, _ei: *mut usize, _k: *mut fmi3DependencyKind, _n: usize);
            }
        }
    };
}

/// Emits, inside [`export_fmi3!`], a typed getter and setter pair.
#[doc(hidden)]
#[macro_export]
macro_rules! fmi3_get_set {
    ($get:ident, $set:ident, $kind:ident, $c:ty) => {
        #[no_mangle]
        pub unsafe extern "C" fn $get(
            c: fmi3Instance,
            vr: *const fmi3ValueReference,
            nvr: usize,
            values: *mut $c,
            n_values: usize,
        ) -> fmi3Status {
            unsafe {
                $crate::fmi3::values::get::<M, $crate::fmi3::values::$kind>(
                    c, vr, nvr, values, n_values,
                )
            }
        }
        #[no_mangle]
        pub unsafe extern "C" fn $set(
            c: fmi3Instance,
            vr: *const fmi3ValueReference,
            nvr: usize,
            values: *const $c,
            n_values: usize,
        ) -> fmi3Status {
            unsafe {
                $crate::fmi3::values::set::<M, $crate::fmi3::values::$kind>(
                    c, vr, nvr, values, n_values,
                )
            }
        }
    };
}

/// Emits, inside [`export_fmi3!`], `fmi3*` functions of capabilities the FMUs do not have:
/// each rejects every call with `fmi3Error`, logging its name and the reason.
#[doc(hidden)]
#[macro_export]
macro_rules! fmi3_unsupported {
    ($reason:expr; $($name:ident($($arg:ident: $type:ty),* $(,)?);)+) => {
        $(
            #[no_mangle]
            pub unsafe extern "C" fn $name(c: fmi3Instance, $($arg: $type),*) -> fmi3Status {
                unsafe { ffi::unsupported::<M>(c, stringify!($name), $reason) }
            }
        )+
    };
}

/// Emits, inside [`export_fmi3!`], the FMI 3.0 Model Exchange functions and the directional
/// and adjoint derivatives (which serve Co-Simulation too) over [`me`].
#[doc(hidden)]
#[macro_export]
macro_rules! export_fmi3_model_exchange {
    () => {
        $crate::model_exchange_entries!(fmi3Instance, Fmi3, fmi3Boolean, functions;
            fmi3SetTime, fmi3SetContinuousStates, fmi3EnterEventMode, fmi3EnterContinuousTimeMode,
            fmi3CompletedIntegratorStep, fmi3GetContinuousStates, fmi3GetContinuousStateDerivatives,
            fmi3GetEventIndicators, fmi3GetNominalsOfContinuousStates);
        #[no_mangle]
        pub unsafe extern "C" fn fmi3UpdateDiscreteStates(
            c: fmi3Instance,
            need_update: *mut fmi3Boolean,
            terminate: *mut fmi3Boolean,
            nominals_changed: *mut fmi3Boolean,
            values_changed: *mut fmi3Boolean,
            next_defined: *mut fmi3Boolean,
            next_time: *mut fmi3Float64,
        ) -> fmi3Status {
            let flags = me::EventFlags {
                need_update,
                terminate,
                nominals_changed,
                values_changed,
                next_defined,
                next_time,
            };
            unsafe { me::update_discrete_states::<M>(c, flags) }
        }
        #[no_mangle]
        pub unsafe extern "C" fn fmi3GetNumberOfEventIndicators(
            c: fmi3Instance,
            n: *mut usize,
        ) -> fmi3Status {
            unsafe { me::number_of::<M>(c, me::Count::EventIndicators, n) }
        }
        #[no_mangle]
        pub unsafe extern "C" fn fmi3GetNumberOfContinuousStates(
            c: fmi3Instance,
            n: *mut usize,
        ) -> fmi3Status {
            unsafe { me::number_of::<M>(c, me::Count::ContinuousStates, n) }
        }
        $crate::fmi3_derivative!(fmi3GetDirectionalDerivative, me::Derivative::Directional);
        $crate::fmi3_derivative!(fmi3GetAdjointDerivative, me::Derivative::Adjoint);
    };
}

/// Emits, inside [`export_fmi3!`], `fmi3GetDirectionalDerivative` or
/// `fmi3GetAdjointDerivative`.
#[doc(hidden)]
#[macro_export]
macro_rules! fmi3_derivative {
    ($name:ident, $kind:expr) => {
        #[no_mangle]
        pub unsafe extern "C" fn $name(
            c: fmi3Instance,
            unknowns: *const fmi3ValueReference,
            n_unknowns: usize,
            knowns: *const fmi3ValueReference,
            n_knowns: usize,
            seed: *const fmi3Float64,
            n_seed: usize,
            sensitivity: *mut fmi3Float64,
            n_sensitivity: usize,
        ) -> fmi3Status {
            let call = me::DerivativeCall {
                unknowns,
                n_unknowns,
                knowns,
                n_knowns,
                seed,
                n_seed,
                sensitivity,
                n_sensitivity,
            };
            unsafe { me::derivative::<M>(c, call, $kind) }
        }
    };
}

/// Emits, inside [`export_fmi3!`], the `fmi3Instantiate*` functions whose arguments start with
/// the common ones (name, token, resources, visible, loggingOn, environment, logMessage) and
/// end with `$extra`; `$body` sees the common ones as `$args` (an [`ffi::Instantiation`]).
#[doc(hidden)]
#[macro_export]
macro_rules! fmi3_instantiation {
    ($($name:ident($($extra:ident: $type:ty),* $(,)?) => |$args:ident| $body:block;)+) => {
        $(
            #[no_mangle]
            pub unsafe extern "C" fn $name(
                name: fmi3String,
                token: fmi3String,
                resources: fmi3String,
                visible: fmi3Boolean,
                logging_on: fmi3Boolean,
                environment: fmi3InstanceEnvironment,
                log_message: fmi3LogMessageCallback,
                $($extra: $type),*
            ) -> fmi3Instance {
                let _ = visible;
                let $args = ffi::Instantiation(
                    name, token, resources, logging_on, environment, log_message,
                );
                unsafe { $body }
            }
        )+
    };
}
