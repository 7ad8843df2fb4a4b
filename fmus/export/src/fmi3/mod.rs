//! The FMI 3.0 Co-Simulation front of the export layer.
//!
//! The same [`FmuModel`](crate::FmuModel), variable table, [`Instance`](crate::instance::Instance)
//! (state machine, argument checks, logging, FMU states) serve both versions; what is FMI 3.0
//! lives here:
//! - [`types`]: the C types of `fmi3PlatformTypes.h` / `fmi3FunctionTypes.h`;
//! - [`arrays`]: the FMI 3.0 variables of a table (structured scalars grouped into arrays,
//!   `time` as value reference 0);
//! - [`description`]: the FMI 3.0 `modelDescription.xml`;
//! - [`functions`]: the `fmi3*` functions and the states they are allowed in;
//! - [`ffi`]: the C entry points, generic over the model, that
//!   [`export_fmu!`](crate::export_fmu) instantiates as the `fmi3*` symbols (through
//!   [`export_fmi3!`](crate::export_fmi3)) beside the `fmi2*` ones, in one binary.
//!
//! FMI 3.0 Co-Simulation states map onto the shared machine: Instantiated, Initialization
//! Mode, Step Mode (the FMI 2.0 `StepComplete`), Terminated, and the error states. The FMUs
//! declare no event mode, no clocks, no structural parameters (dimensions stay packaging
//! variants: see the README), so Configuration Mode, Event Mode and the Model Exchange and
//! Scheduled Execution functions are exported but reject every call with a logged reason.

pub mod arrays;
pub mod description;
pub mod ffi;
pub mod me;
pub mod types;

/// Allowed-state masks of the FMI 3.0 functions (FMI 3.0.2 §4.3.4 Co-Simulation and §3.3
/// Model Exchange state machines; Step Mode is the shared machine's `StepComplete`).
pub mod functions {
    use crate::instance::{function as f, ModelState, CONTINUOUS_TIME_MODE, EVENT_MODE, ME_MODES};

    const INSTANTIATED: u32 = ModelState::Instantiated.bit();
    const INIT_MODE: u32 = ModelState::InitializationMode.bit();
    const STEP_MODE: u32 = ModelState::StepComplete.bit();
    const TERMINATED: u32 = ModelState::Terminated.bit();
    const ERROR: u32 = ModelState::Error.bit();
    const FATAL: u32 = ModelState::Fatal.bit();
    /// Every state of an instance that is not fatally broken.
    pub const ANY_LIVE: u32 = ME_MODES | INSTANTIATED | INIT_MODE | STEP_MODE | TERMINATED | ERROR;
    const GETTABLE: u32 = ME_MODES | INIT_MODE | STEP_MODE | TERMINATED | ERROR;
    const SETTABLE: u32 = ME_MODES | INSTANTIATED | INIT_MODE | STEP_MODE;
    const ME_AFTER_INIT: u32 = ME_MODES | INIT_MODE | TERMINATED | ERROR;

    f! { SET_DEBUG_LOGGING, "fmi3SetDebugLogging", ANY_LIVE }
    f! { FREE_INSTANCE, "fmi3FreeInstance", ANY_LIVE | FATAL }
    f! { ENTER_INITIALIZATION_MODE, "fmi3EnterInitializationMode", INSTANTIATED }
    f! { EXIT_INITIALIZATION_MODE, "fmi3ExitInitializationMode", INIT_MODE }
    f! { TERMINATE, "fmi3Terminate", STEP_MODE | ME_MODES }
    f! { RESET, "fmi3Reset", ANY_LIVE }
    f! { GET_FLOAT64, "fmi3GetFloat64", GETTABLE }
    f! { GET_INT32, "fmi3GetInt32", GETTABLE }
    f! { GET_BOOLEAN, "fmi3GetBoolean", GETTABLE }
    f! { GET_STRING, "fmi3GetString", GETTABLE }
    f! { SET_FLOAT64, "fmi3SetFloat64", SETTABLE }
    f! { SET_INT32, "fmi3SetInt32", SETTABLE }
    f! { SET_BOOLEAN, "fmi3SetBoolean", SETTABLE }
    f! { SET_STRING, "fmi3SetString", SETTABLE }
    f! { GET_FMU_STATE, "fmi3GetFMUState", ANY_LIVE }
    f! { SET_FMU_STATE, "fmi3SetFMUState", ANY_LIVE }
    f! { FREE_FMU_STATE, "fmi3FreeFMUState", ANY_LIVE | FATAL }
    f! { SERIALIZED_FMU_STATE_SIZE, "fmi3SerializedFMUStateSize", ANY_LIVE }
    f! { SERIALIZE_FMU_STATE, "fmi3SerializeFMUState", ANY_LIVE }
    f! { DESERIALIZE_FMU_STATE, "fmi3DeserializeFMUState", ANY_LIVE }
    f! { DO_STEP, "fmi3DoStep", STEP_MODE }
    // Model Exchange (FMI 3.0.2 §3.3).
    f! { SET_TIME, "fmi3SetTime", ME_MODES }
    f! { SET_CONTINUOUS_STATES, "fmi3SetContinuousStates", CONTINUOUS_TIME_MODE }
    f! { GET_CONTINUOUS_STATES, "fmi3GetContinuousStates", ME_AFTER_INIT }
    f! { GET_CONTINUOUS_STATE_DERIVATIVES, "fmi3GetContinuousStateDerivatives", ME_AFTER_INIT }
    f! { GET_EVENT_INDICATORS, "fmi3GetEventIndicators", ME_AFTER_INIT }
    f! { GET_NOMINALS_OF_CONTINUOUS_STATES, "fmi3GetNominalsOfContinuousStates", INSTANTIATED | ME_AFTER_INIT }
    f! { GET_NUMBER_OF_EVENT_INDICATORS, "fmi3GetNumberOfEventIndicators", ANY_LIVE }
    f! { GET_NUMBER_OF_CONTINUOUS_STATES, "fmi3GetNumberOfContinuousStates", ANY_LIVE }
    f! { ENTER_EVENT_MODE, "fmi3EnterEventMode", ME_MODES }
    f! { UPDATE_DISCRETE_STATES, "fmi3UpdateDiscreteStates", EVENT_MODE }
    f! { ENTER_CONTINUOUS_TIME_MODE, "fmi3EnterContinuousTimeMode", EVENT_MODE }
    f! { COMPLETED_INTEGRATOR_STEP, "fmi3CompletedIntegratorStep", CONTINUOUS_TIME_MODE }
    f! { GET_DIRECTIONAL_DERIVATIVE, "fmi3GetDirectionalDerivative", GETTABLE }
    f! { GET_ADJOINT_DERIVATIVE, "fmi3GetAdjointDerivative", GETTABLE }
}

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
            use $crate::fmi3::ffi;
            use $crate::fmi3::functions;
            use $crate::fmi3::me;
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
                unsafe {
                    ffi::instantiate_co_simulation::<M>(
                        name,
                        token,
                        resources,
                        logging_on,
                        event_mode_used,
                        early_return_allowed,
                        n_required,
                        environment,
                        log_message,
                        super::spurio_model_exchange(),
                    )
                }
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3InstantiateModelExchange(
                name: fmi3String,
                token: fmi3String,
                resources: fmi3String,
                visible: fmi3Boolean,
                logging_on: fmi3Boolean,
                environment: fmi3InstanceEnvironment,
                log_message: fmi3LogMessageCallback,
            ) -> fmi3Instance {
                let _ = visible;
                unsafe {
                    ffi::instantiate_model_exchange::<M>(
                        name,
                        token,
                        resources,
                        logging_on,
                        environment,
                        log_message,
                        super::spurio_model_exchange(),
                    )
                }
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3InstantiateScheduledExecution(
                name: fmi3String,
                token: fmi3String,
                resources: fmi3String,
                visible: fmi3Boolean,
                logging_on: fmi3Boolean,
                environment: fmi3InstanceEnvironment,
                log_message: fmi3LogMessageCallback,
                clock_update: fmi3ClockUpdateCallback,
                lock: fmi3PreemptionCallback,
                unlock: fmi3PreemptionCallback,
            ) -> fmi3Instance {
                let _ = (name, token, resources, visible, logging_on);
                let _ = (clock_update, lock, unlock);
                unsafe {
                    ffi::refuse_instantiation::<M>(
                        "fmi3InstantiateScheduledExecution",
                        "Scheduled Execution",
                        environment,
                        log_message,
                    )
                }
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
            #[no_mangle]
            pub unsafe extern "C" fn fmi3ExitInitializationMode(c: fmi3Instance) -> fmi3Status {
                unsafe { ffi::exit_initialization_mode::<M>(c) }
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3Terminate(c: fmi3Instance) -> fmi3Status {
                unsafe { ffi::terminate::<M>(c) }
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3Reset(c: fmi3Instance) -> fmi3Status {
                unsafe { ffi::reset::<M>(c) }
            }
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
                unsafe { ffi::get_string::<M>(c, vr, nvr, values, n_values) }
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3SetString(
                c: fmi3Instance,
                vr: *const fmi3ValueReference,
                nvr: usize,
                values: *const fmi3String,
                n_values: usize,
            ) -> fmi3Status {
                unsafe { ffi::set_string::<M>(c, vr, nvr, values, n_values) }
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3GetFMUState(
                c: fmi3Instance,
                state: *mut fmi3FMUState,
            ) -> fmi3Status {
                unsafe { ffi::get_fmu_state::<M>(c, state) }
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3SetFMUState(
                c: fmi3Instance,
                state: fmi3FMUState,
            ) -> fmi3Status {
                unsafe { ffi::set_fmu_state::<M>(c, state) }
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3FreeFMUState(
                c: fmi3Instance,
                state: *mut fmi3FMUState,
            ) -> fmi3Status {
                unsafe { ffi::free_fmu_state::<M>(c, state) }
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3SerializedFMUStateSize(
                c: fmi3Instance,
                state: fmi3FMUState,
                size: *mut usize,
            ) -> fmi3Status {
                unsafe { ffi::serialized_fmu_state_size::<M>(c, state, size) }
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3SerializeFMUState(
                c: fmi3Instance,
                state: fmi3FMUState,
                bytes: *mut fmi3Byte,
                size: usize,
            ) -> fmi3Status {
                unsafe { ffi::serialize_fmu_state::<M>(c, state, bytes, size) }
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3DeserializeFMUState(
                c: fmi3Instance,
                bytes: *const fmi3Byte,
                size: usize,
                state: *mut fmi3FMUState,
            ) -> fmi3Status {
                unsafe { ffi::deserialize_fmu_state::<M>(c, bytes, size, state) }
            }
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
            unsafe { ffi::get::<M, ffi::$kind>(c, vr, nvr, values, n_values) }
        }
        #[no_mangle]
        pub unsafe extern "C" fn $set(
            c: fmi3Instance,
            vr: *const fmi3ValueReference,
            nvr: usize,
            values: *const $c,
            n_values: usize,
        ) -> fmi3Status {
            unsafe { ffi::set::<M, ffi::$kind>(c, vr, nvr, values, n_values) }
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
        #[no_mangle]
        pub unsafe extern "C" fn fmi3EnterEventMode(c: fmi3Instance) -> fmi3Status {
            unsafe { me::enter_event_mode::<M>(c) }
        }
        #[no_mangle]
        pub unsafe extern "C" fn fmi3EnterContinuousTimeMode(c: fmi3Instance) -> fmi3Status {
            unsafe { me::enter_continuous_time_mode::<M>(c) }
        }
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
        pub unsafe extern "C" fn fmi3CompletedIntegratorStep(
            c: fmi3Instance,
            no_set_prior: fmi3Boolean,
            enter_event_mode: *mut fmi3Boolean,
            terminate: *mut fmi3Boolean,
        ) -> fmi3Status {
            let _ = no_set_prior;
            unsafe { me::completed_integrator_step::<M>(c, enter_event_mode, terminate) }
        }
        #[no_mangle]
        pub unsafe extern "C" fn fmi3SetTime(c: fmi3Instance, time: fmi3Float64) -> fmi3Status {
            unsafe { me::set_time::<M>(c, time) }
        }
        #[no_mangle]
        pub unsafe extern "C" fn fmi3SetContinuousStates(
            c: fmi3Instance,
            x: *const fmi3Float64,
            n: usize,
        ) -> fmi3Status {
            unsafe { me::set_continuous_states::<M>(c, x, n) }
        }
        $crate::fmi3_array_getter!(fmi3GetContinuousStates, get_continuous_states);
        $crate::fmi3_array_getter!(fmi3GetContinuousStateDerivatives, get_derivatives);
        $crate::fmi3_array_getter!(fmi3GetEventIndicators, get_event_indicators);
        $crate::fmi3_array_getter!(fmi3GetNominalsOfContinuousStates, get_nominals);
        #[no_mangle]
        pub unsafe extern "C" fn fmi3GetNumberOfEventIndicators(
            c: fmi3Instance,
            n: *mut usize,
        ) -> fmi3Status {
            unsafe { me::number_of_event_indicators::<M>(c, n) }
        }
        #[no_mangle]
        pub unsafe extern "C" fn fmi3GetNumberOfContinuousStates(
            c: fmi3Instance,
            n: *mut usize,
        ) -> fmi3Status {
            unsafe { me::number_of_continuous_states::<M>(c, n) }
        }
        $crate::fmi3_derivative!(fmi3GetDirectionalDerivative, me::Derivative::Directional);
        $crate::fmi3_derivative!(fmi3GetAdjointDerivative, me::Derivative::Adjoint);
    };
}

/// Emits, inside [`export_fmi3!`], an FMI 3.0 Model Exchange function that fills the
/// caller's Float64 array.
#[doc(hidden)]
#[macro_export]
macro_rules! fmi3_array_getter {
    ($name:ident, $function:ident) => {
        #[no_mangle]
        pub unsafe extern "C" fn $name(
            c: fmi3Instance,
            out: *mut fmi3Float64,
            n: usize,
        ) -> fmi3Status {
            unsafe { me::array::<M>(c, out, n, me::Array::$function) }
        }
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
