//! The FMI 3.0 C entry points of the life cycle: the C signatures of `fmi3Functions.h` mapped
//! onto the shared ABI ([`crate::abi`]) and the instance, with the masks of
//! [`crate::instance::state::fmi3`]; the twin of [`crate::fmi2::ffi`]. Every error goes
//! through the master's `fmi3LogMessageCallback` (which takes the message as it is: no
//! format string). The typed get/set functions are in [`super::values`], the Model Exchange
//! ones in [`super::model_exchange`] and [`crate::abi::model_exchange`].

use super::types::*;
use crate::abi::fmu_state::state_functions;
use crate::abi::instantiate::{self, Request, Resources, FMI3};
use crate::abi::kinds::Fmi3;
use crate::abi::pointers::string_arg;
use crate::abi::slot::{free_slot, with_slot};
use crate::description::Config;
use crate::guard::guarded;
use crate::instance::state::{fmi3 as functions, Function};
use crate::instance::{LogSink, Logger};
use crate::model::{FmuModel, Hooks};
use crate::types::Status;
use std::ffi::CString;
use std::os::raw::c_char;

/// Delivers log messages to the master's `fmi3LogMessageCallback`.
pub struct CallbackSink {
    log_message: fmi3LogMessageCallback,
    environment: fmi3InstanceEnvironment,
}

impl LogSink for CallbackSink {
    fn deliver(&self, _instance: &str, status: Status, category: &str, text: &str) {
        let Some(log_message) = self.log_message else {
            return;
        };
        let clean = |s: &str| CString::new(s.replace('\0', " ")).unwrap_or_default();
        let (category, text) = (clean(category), clean(text));
        // SAFETY: the master gave us this function pointer for exactly this call; both
        // strings are NUL-terminated and live until it returns.
        unsafe {
            log_message(
                self.environment,
                status.code(),
                category.as_ptr(),
                text.as_ptr(),
            )
        };
    }
}

/// What an `fmi3Instance` points to: the shared slot, marked as FMI 3.0's (the FMI 3.0
/// variables over the instance's scalars are in its shared interface).
pub type Slot<M> = crate::abi::slot::Slot<M, Fmi3>;

/// Runs `body` on the slot behind `c` after the null and state checks, catching panics.
pub(crate) unsafe fn with_instance<M: FmuModel>(
    c: fmi3Instance,
    f: &Function,
    body: impl FnOnce(&mut Slot<M>) -> Status,
) -> fmi3Status {
    // SAFETY: `c` is NULL or was returned by `instantiate_co_simulation::<M>` (the master's
    // obligation).
    unsafe { with_slot::<M, Fmi3>(c, f, body) }
}

/// `fmi3GetVersion`.
pub fn version() -> *const c_char {
    c"3.0".as_ptr()
}

/// The arguments every `fmi3Instantiate*` function has, in the order of the C functions:
/// instanceName, instantiationToken, resourcePath, loggingOn, instanceEnvironment,
/// logMessage.
#[derive(Clone, Copy)]
pub struct Instantiation(
    pub fmi3String,
    pub fmi3String,
    pub fmi3String,
    pub fmi3Boolean,
    pub fmi3InstanceEnvironment,
    pub fmi3LogMessageCallback,
);

/// `fmi3InstantiateCoSimulation`: its own arguments checked (`eventModeUsed` and the
/// intermediate variables refused: the FMU has no event mode and no intermediate update),
/// then the shared instantiation ([`instantiate::instantiate`]), with the model's Model
/// Exchange functions `me` for its directional derivatives.
///
/// # Safety
/// Pointer arguments must be NULL or valid as the FMI standard requires.
pub unsafe fn instantiate_co_simulation<M: FmuModel>(
    args: Instantiation,
    event_mode_used: fmi3Boolean,
    early_return_allowed: fmi3Boolean,
    n_required_intermediate: usize,
    me: Option<Hooks<M>>,
) -> fmi3Instance {
    // FMI 3.0.2 §4.3.1: eventModeUsed may be true only if hasEventMode is.
    let refusal = if event_mode_used != 0 {
        Some("eventModeUsed = true, but the FMU declares hasEventMode=\"false\": instantiate it with eventModeUsed = false (it never needs Event Mode)".to_string())
    } else if n_required_intermediate > 0 {
        Some(format!(
            "{n_required_intermediate} requiredIntermediateVariables given, but the FMU declares providesIntermediateUpdate=\"false\""
        ))
    } else {
        None
    };
    let note = (early_return_allowed != 0)
        .then_some("earlyReturnAllowed noted; the FMU never returns early");
    unsafe {
        instantiate(
            "fmi3InstantiateCoSimulation",
            args,
            (false, refusal, note),
            me,
        )
    }
}

/// `fmi3InstantiateModelExchange`: the shared instantiation, for a model with Model Exchange
/// functions `me` whose description declares the interface (otherwise refused, the reason
/// logged).
///
/// # Safety
/// Pointer arguments must be NULL or valid as the FMI standard requires.
pub unsafe fn instantiate_model_exchange<M: FmuModel>(
    args: Instantiation,
    me: Option<Hooks<M>>,
) -> fmi3Instance {
    unsafe { instantiate("fmi3InstantiateModelExchange", args, (true, None, None), me) }
}

/// The arguments of an `fmi3Instantiate*` function as a [`Request`] (`asked`: whether Model
/// Exchange is, the function's refusal, its note), through the shared instantiation.
///
/// # Safety
/// Pointer arguments must be NULL or valid as the FMI standard requires.
unsafe fn instantiate<M: FmuModel>(
    function: &'static str,
    args: Instantiation,
    (model_exchange, refusal, note): (bool, Option<String>, Option<&'static str>),
    me: Option<Hooks<M>>,
) -> fmi3Instance {
    let Instantiation(name, token, resource_path, logging_on, environment, log_message) = args;
    let sink = || -> Box<dyn LogSink> {
        Box::new(CallbackSink {
            log_message,
            environment,
        })
    };
    let request = || Request {
        function,
        spelling: &FMI3,
        // SAFETY: FMI strings are NULL or NUL-terminated.
        name: unsafe { string_arg(name) },
        token: unsafe { string_arg(token) },
        resources: Resources::Path(unsafe { string_arg(resource_path) }),
        logging_on: logging_on != 0,
        model_exchange,
        refusal,
        note,
    };
    instantiate::instantiate::<M, Fmi3>(request, sink, me, Fmi3)
}

/// `fmi3InstantiateScheduledExecution`: logs why not and returns NULL.
///
/// # Safety
/// `log_message` is NULL or a valid callback.
pub unsafe fn refuse_instantiation<M: FmuModel>(
    function: &str,
    interface: &str,
    args: Instantiation,
) -> fmi3Instance {
    let _ = guarded(|| {
        let id = M::describe(&Config::new())
            .map(|i| i.model_identifier)
            .unwrap_or_default();
        let sink = CallbackSink {
            log_message: args.5,
            environment: args.4,
        };
        Logger::new("?", Box::new(sink), true)
            .error(&format!("{function}: {id} does not implement {interface}"));
    });
    std::ptr::null_mut()
}

/// `fmi3FreeInstance`.
///
/// # Safety
/// `c` must be NULL or an instance from [`instantiate_co_simulation`] or [`instantiate_model_exchange`] not freed yet.
pub unsafe fn free_instance<M: FmuModel>(c: fmi3Instance) {
    // SAFETY: forwarded from the caller.
    unsafe { free_slot::<M, Fmi3>(c) }
}

/// `fmi3EnterInitializationMode`: the experiment (start and stop time; the tolerance is not
/// used by fixed-step models) and Initialization Mode.
///
/// # Safety
/// FMI pointer contract.
pub unsafe fn enter_initialization_mode<M: FmuModel>(
    c: fmi3Instance,
    start_time: fmi3Float64,
    stop_time_defined: fmi3Boolean,
    stop_time: fmi3Float64,
) -> fmi3Status {
    let f = &functions::ENTER_INITIALIZATION_MODE;
    unsafe {
        with_instance::<M>(c, f, |s| {
            let stop = (stop_time_defined != 0).then_some(stop_time);
            let status = s.instance.setup_experiment_as(f, start_time, stop);
            if status > Status::Warning {
                return status;
            }
            s.instance.enter_initialization_mode().max(status)
        })
    }
}

/// `fmi3ExitInitializationMode`: into Step Mode (no event mode).
///
/// # Safety
/// FMI pointer contract.
pub unsafe fn exit_initialization_mode<M: FmuModel>(c: fmi3Instance) -> fmi3Status {
    let f = &functions::EXIT_INITIALIZATION_MODE;
    unsafe { with_instance::<M>(c, f, |s| s.instance.exit_initialization_mode_as(f)) }
}

/// `fmi3Terminate`.
///
/// # Safety
/// FMI pointer contract.
pub unsafe fn terminate<M: FmuModel>(c: fmi3Instance) -> fmi3Status {
    unsafe { with_instance::<M>(c, &functions::TERMINATE, |s| s.instance.terminate()) }
}

/// `fmi3Reset`.
///
/// # Safety
/// FMI pointer contract.
pub unsafe fn reset<M: FmuModel>(c: fmi3Instance) -> fmi3Status {
    let f = &functions::RESET;
    unsafe { with_instance::<M>(c, f, |s| s.instance.reset_as(f)) }
}

/// `fmi3DoStep`: one step; the FMU has no events and never returns early, so
/// `eventHandlingNeeded`, `terminateSimulation` and `earlyReturn` are false and
/// `lastSuccessfulTime` is the end of the step (or the start, when it failed).
///
/// # Safety
/// FMI pointer contract; the output pointers may be NULL.
pub unsafe fn do_step<M: FmuModel>(
    c: fmi3Instance,
    current_time: fmi3Float64,
    step: fmi3Float64,
    event_handling_needed: *mut fmi3Boolean,
    terminate_simulation: *mut fmi3Boolean,
    early_return: *mut fmi3Boolean,
    last_successful_time: *mut fmi3Float64,
) -> fmi3Status {
    let f = &functions::DO_STEP;
    unsafe {
        with_instance::<M>(c, f, |s| {
            let status = s.instance.do_step_as(f, current_time, step);
            for flag in [event_handling_needed, terminate_simulation, early_return] {
                if !flag.is_null() {
                    // SAFETY: a non-NULL output argument points to one fmi3Boolean.
                    *flag = fmi3False;
                }
            }
            if !last_successful_time.is_null() {
                // SAFETY: as above, one fmi3Float64.
                *last_successful_time = s.instance.last_successful_time();
            }
            status
        })
    }
}

state_functions!(fmi3Instance, fmi3FMUState, fmi3Byte, Fmi3, "FMUState");

/// A function of a capability the FMUs do not have: rejected with `reason`, logged.
///
/// # Safety
/// FMI pointer contract.
pub unsafe fn unsupported<M: FmuModel>(
    c: fmi3Instance,
    name: &'static str,
    reason: &'static str,
) -> fmi3Status {
    let f = Function {
        name,
        mask: functions::ANY_LIVE,
    };
    unsafe {
        with_instance::<M>(c, &f, |s| {
            s.instance.reject(&f, &format!("not supported: {reason}"))
        })
    }
}

/// Emits, inside [`export_fmu!`](crate::export_fmu), the `fmi3*` symbols of the life cycle,
/// the step, the FMU states and the capabilities the FMUs do not have (refusing every call
/// with a logged reason), each calling its function of this module.
#[doc(hidden)]
#[macro_export]
macro_rules! fmi3_life_cycle_entries {
    () => {
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
            let f = &functions::SET_DEBUG_LOGGING;
            unsafe { $crate::abi::slot::set_debug_logging::<M, Fmi3>(c, f, on != 0, (categories, n)) }
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
        $crate::fmi3_unsupported! {
            "maxOutputDerivativeOrder=\"0\"";
            fmi3GetOutputDerivatives(_v: *const fmi3ValueReference, _n: usize, _o: *const fmi3Int32, _x: *mut fmi3Float64, _m: usize);
        }
        $crate::fmi3_unsupported! {
            "providesPerElementDependencies=\"false\": the dependencies are those of the model description's ModelStructure";
            fmi3GetNumberOfVariableDependencies(_v: fmi3ValueReference, _n: *mut usize);
            fmi3GetVariableDependencies(_v: fmi3ValueReference, _e: *mut usize, _i: *mut fmi3ValueReference, _ei: *mut usize, _k: *mut fmi3DependencyKind, _n: usize);
        }
    };
}

/// Emits, inside [`export_fmu!`](crate::export_fmu), `fmi3*` functions of capabilities the FMUs do not have:
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

/// Emits, inside [`export_fmu!`](crate::export_fmu), the `fmi3Instantiate*` functions whose arguments start with
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
