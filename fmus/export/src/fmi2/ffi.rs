//! The FMI 2.0 C entry points of the life cycle: the C signatures of `fmi2Functions.h` mapped
//! onto the shared ABI ([`crate::abi`]) and the instance, with the masks of
//! [`crate::instance::state::fmi2`]. Each function is generic over the model;
//! [`fmi2_life_cycle_entries!`](crate::fmi2_life_cycle_entries), below them, emits their
//! `fmi2*` symbols in one FMU binary. The typed get/set functions are in [`super::values`],
//! the Model Exchange ones in [`super::model_exchange`] and [`crate::abi::model_exchange`].

use crate::abi::fmu_state::state_functions;
use crate::abi::instantiate::{self, Request, Resources, FMI2};
use crate::abi::pointers::string_arg;
use crate::abi::slot::{free_slot, with_slot, write_out};
use crate::instance::state::{fmi2 as functions, Function};
use crate::instance::{Instance, LogSink};
use crate::model::{FmuModel, Hooks};
use crate::types::*;
use std::ffi::CString;
use std::os::raw::c_char;

/// Delivers log messages to the master's `fmi2CallbackLogger`, always with the format `"%s"`.
pub struct CallbackSink {
    logger: fmi2CallbackLogger,
    environment: fmi2ComponentEnvironment,
}

impl LogSink for CallbackSink {
    fn deliver(&self, instance: &str, status: Status, category: &str, text: &str) {
        let Some(logger) = self.logger else { return };
        let clean = |s: &str| CString::new(s.replace('\0', " ")).unwrap_or_default();
        let (name, category, text) = (clean(instance), clean(category), clean(text));
        // SAFETY: the master gave us this function pointer for exactly this call; every string
        // is NUL-terminated and lives until the call returns; the format is "%s" with one
        // `char*` argument.
        unsafe {
            logger(
                self.environment,
                name.as_ptr(),
                status.code(),
                category.as_ptr(),
                c"%s".as_ptr(),
                text.as_ptr(),
            );
        }
    }
}

/// What an `fmi2Component` points to.
pub type Slot<M> = crate::abi::slot::Slot<M>;

/// Runs `body` on the instance behind `c` after the null and state checks, catching panics.
pub(crate) unsafe fn with_instance<M: FmuModel>(
    c: fmi2Component,
    f: &Function,
    body: impl FnOnce(&mut Slot<M>) -> Status,
) -> fmi2Status {
    // SAFETY: `c` is NULL or was returned by `instantiate::<M>` (the master's obligation).
    unsafe { with_slot::<M, ()>(c, f, body) }
}

/// `fmi2GetTypesPlatform`.
pub fn types_platform() -> *const c_char {
    c"default".as_ptr()
}

/// `fmi2GetVersion`.
pub fn version() -> *const c_char {
    c"2.0".as_ptr()
}

/// `fmi2Instantiate`: the callbacks checked, the type read (`fmi2CoSimulation`, or
/// `fmi2ModelExchange` for a model with Model Exchange functions `me` whose description
/// declares it), then the shared instantiation ([`instantiate::instantiate`]).
///
/// # Safety
/// Pointer arguments must be NULL or valid as the FMI standard requires.
#[allow(clippy::too_many_arguments)]
pub unsafe fn instantiate<M: FmuModel>(
    instance_name: fmi2String,
    fmu_type: fmi2Type,
    guid: fmi2String,
    resource_location: fmi2String,
    functions: *const fmi2CallbackFunctions,
    _visible: fmi2Boolean,
    logging_on: fmi2Boolean,
    me: Option<Hooks<M>>,
) -> fmi2Component {
    if functions.is_null() {
        return std::ptr::null_mut();
    }
    // SAFETY: checked non-null; the master keeps the struct alive (FMI 2.0.4 §2.1.5 asks the
    // FMU to copy what it needs: we copy the two fields we use).
    let callbacks = unsafe { &*functions };
    let (logger, environment) = (callbacks.logger, callbacks.componentEnvironment);
    let sink = || -> Box<dyn LogSink> {
        Box::new(CallbackSink {
            logger,
            environment,
        })
    };
    let request = || Request {
        function: "fmi2Instantiate",
        spelling: &FMI2,
        // SAFETY: FMI strings are NULL or NUL-terminated.
        name: unsafe { string_arg(instance_name) },
        token: unsafe { string_arg(guid) },
        resources: Resources::Uri(unsafe { string_arg(resource_location) }),
        logging_on: logging_on != 0,
        model_exchange: fmu_type == fmi2ModelExchange,
        refusal: (fmu_type != fmi2ModelExchange && fmu_type != fmi2CoSimulation).then(|| {
            format!("fmuType must be fmi2ModelExchange (0) or fmi2CoSimulation (1), got {fmu_type}")
        }),
        note: None,
    };
    instantiate::instantiate::<M, ()>(request, sink, me, ())
}

/// Boxes an instance as an `fmi2Component` (what `fmi2Instantiate` returns).
pub fn into_component<M: FmuModel>(instance: Instance<M>) -> fmi2Component {
    Slot::new(instance, ()).into_handle()
}

/// `fmi2FreeInstance`.
///
/// # Safety
/// `c` must be NULL or a component from [`instantiate()`] not freed yet.
pub unsafe fn free_instance<M: FmuModel>(c: fmi2Component) {
    // SAFETY: forwarded from the caller.
    unsafe { free_slot::<M, ()>(c) }
}

/// `fmi2SetupExperiment`.
///
/// # Safety
/// FMI pointer contract.
pub unsafe fn setup_experiment<M: FmuModel>(
    c: fmi2Component,
    _tolerance_defined: fmi2Boolean,
    _tolerance: fmi2Real,
    start_time: fmi2Real,
    stop_time_defined: fmi2Boolean,
    stop_time: fmi2Real,
) -> fmi2Status {
    unsafe {
        with_instance::<M>(c, &functions::SETUP_EXPERIMENT, |s| {
            s.instance
                .setup_experiment(start_time, (stop_time_defined != 0).then_some(stop_time))
        })
    }
}

macro_rules! simple_call {
    ($(#[$doc:meta])* $fn_name:ident, $function:expr, $method:ident) => {
        $(#[$doc])*
        ///
        /// # Safety
        /// FMI pointer contract.
        pub unsafe fn $fn_name<M: FmuModel>(c: fmi2Component) -> fmi2Status {
            unsafe { with_instance::<M>(c, &$function, |s| s.instance.$method()) }
        }
    };
}

simple_call!(
    /// `fmi2EnterInitializationMode`.
    enter_initialization_mode, functions::ENTER_INITIALIZATION_MODE, enter_initialization_mode);
simple_call!(
    /// `fmi2ExitInitializationMode`.
    exit_initialization_mode, functions::EXIT_INITIALIZATION_MODE, exit_initialization_mode);
simple_call!(
    /// `fmi2Terminate`.
    terminate, functions::TERMINATE, terminate);
simple_call!(
    /// `fmi2Reset`.
    reset, functions::RESET, reset);

/// `fmi2DoStep`.
///
/// # Safety
/// FMI pointer contract.
pub unsafe fn do_step<M: FmuModel>(
    c: fmi2Component,
    current_time: fmi2Real,
    step: fmi2Real,
    _no_set_prior: fmi2Boolean,
) -> fmi2Status {
    unsafe {
        with_instance::<M>(c, &functions::DO_STEP, |s| {
            s.instance.do_step(current_time, step)
        })
    }
}

/// `fmi2CancelStep` (steps are synchronous: the mask rejects every call).
///
/// # Safety
/// FMI pointer contract.
pub unsafe fn cancel_step<M: FmuModel>(c: fmi2Component) -> fmi2Status {
    unsafe { with_instance::<M>(c, &functions::CANCEL_STEP, |_| Status::Ok) }
}

state_functions!(fmi2Component, fmi2FMUstate, fmi2Byte, (), "FMUstate");

/// Functions of capabilities the FMUs do not declare: rejected with a reason.
///
/// # Safety
/// FMI pointer contract.
pub unsafe fn unsupported<M: FmuModel>(
    c: fmi2Component,
    f: &'static Function,
    capability: &'static str,
) -> fmi2Status {
    unsafe {
        with_instance::<M>(c, f, |s| {
            s.instance
                .reject(f, &format!("not supported: the FMU declares {capability}"))
        })
    }
}

/// `fmi2GetStatus`: steps are never asynchronous, so there is no pending status to report.
///
/// # Safety
/// FMI pointer contract.
pub unsafe fn get_status<M: FmuModel>(
    c: fmi2Component,
    f: &'static Function,
    kind: fmi2StatusKind,
) -> fmi2Status {
    unsafe {
        with_instance::<M>(c, f, |s| {
            s.instance.logger().log(
                Status::Discard,
                Status::Discard.category(),
                &format!(
                    "{}: status kind {kind} is not available (fmi2DoStep never returns fmi2Pending)",
                    f.name
                ),
            );
            Status::Discard
        })
    }
}

/// A status query that answers the one `kind` it knows with `answer` and every other kind as
/// [`get_status`] does.
///
/// # Safety
/// FMI pointer contract.
unsafe fn get_known_status<M: FmuModel, T>(
    c: fmi2Component,
    f: &'static Function,
    kind: fmi2StatusKind,
    known: fmi2StatusKind,
    value: *mut T,
    answer: impl FnOnce(&Slot<M>) -> T,
) -> fmi2Status {
    unsafe {
        if kind != known {
            return get_status::<M>(c, f, kind);
        }
        write_out::<M, (), T>(c, f, (value, "value"), answer)
    }
}

/// `fmi2GetRealStatus`: `fmi2LastSuccessfulTime`.
///
/// # Safety
/// FMI pointer contract.
pub unsafe fn get_real_status<M: FmuModel>(
    c: fmi2Component,
    kind: fmi2StatusKind,
    value: *mut fmi2Real,
) -> fmi2Status {
    let f = &functions::GET_REAL_STATUS;
    unsafe {
        get_known_status::<M, _>(c, f, kind, fmi2LastSuccessfulTime, value, |s| {
            s.instance.last_successful_time()
        })
    }
}

/// `fmi2GetBooleanStatus`: `fmi2Terminated` (the FMUs never ask to stop early).
///
/// # Safety
/// FMI pointer contract.
pub unsafe fn get_boolean_status<M: FmuModel>(
    c: fmi2Component,
    kind: fmi2StatusKind,
    value: *mut fmi2Boolean,
) -> fmi2Status {
    let f = &functions::GET_BOOLEAN_STATUS;
    unsafe { get_known_status::<M, _>(c, f, kind, fmi2Terminated, value, |_| fmi2False) }
}

/// `fmi2GetStringStatus`: no pending status, ever.
///
/// # Safety
/// FMI pointer contract.
pub unsafe fn get_string_status<M: FmuModel>(
    c: fmi2Component,
    kind: fmi2StatusKind,
    value: *mut fmi2String,
) -> fmi2Status {
    unsafe {
        if !value.is_null() {
            *value = c"".as_ptr();
        }
        get_status::<M>(c, &functions::GET_STRING_STATUS, kind)
    }
}

/// Emits, inside [`export_fmu!`](crate::export_fmu), the `fmi2*` symbols of the life cycle,
/// the step, the FMU states, the status queries and the capabilities the FMUs do not declare,
/// each calling its function of this module.
#[doc(hidden)]
#[macro_export]
macro_rules! fmi2_life_cycle_entries {
    () => {
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
            let f = &functions::SET_DEBUG_LOGGING;
            unsafe { $crate::abi::slot::set_debug_logging::<M, ()>(c, f, on != 0, (categories, n)) }
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
        $crate::fmu_state_entries!(
            fmi2Component, fmi2FMUstate, fmi2Byte;
            fmi2GetFMUstate, fmi2SetFMUstate, fmi2FreeFMUstate,
            fmi2SerializedFMUstateSize, fmi2SerializeFMUstate, fmi2DeSerializeFMUstate
        );
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
