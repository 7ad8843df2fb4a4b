//! The FMI 2.0 C entry points: the C signatures of `fmi2Functions.h` mapped onto the shared
//! ABI ([`crate::abi`]) and the instance, with the masks of
//! [`crate::instance::state::fmi2`]. Each function is generic over the model; the
//! [`export_fmi2!`](crate::export_fmi2) macro instantiates them as the `fmi2*` symbols of one
//! FMU binary.

use crate::abi::fmu_state::state_functions;
use crate::abi::instantiate::{self, Request, Resources, FMI2};
use crate::abi::kinds::{Fmi2, Kind};
use crate::abi::pointers::{slice, slice_mut, string_arg};
use crate::abi::slot::{free_slot, string_values, with_slot, write_out};
use crate::instance::state::{fmi2 as functions, Function};
use crate::instance::{Instance, LogSink};
use crate::model::{FmuModel, Hooks};
use crate::types::*;
use crate::variables::VariableType;
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

/// `fmi2SetDebugLogging`.
///
/// # Safety
/// FMI pointer contract.
pub unsafe fn set_debug_logging<M: FmuModel>(
    c: fmi2Component,
    logging_on: fmi2Boolean,
    n: usize,
    categories: *const fmi2String,
) -> fmi2Status {
    unsafe {
        with_instance::<M>(c, &functions::SET_DEBUG_LOGGING, |s| {
            let Some(raw) = slice(categories, n) else {
                return s
                    .instance
                    .reject(&functions::SET_DEBUG_LOGGING, "categories is NULL");
            };
            let names: Vec<String> = raw
                .iter()
                .map(|p| string_arg(*p).unwrap_or_default())
                .collect();
            s.instance.set_debug_logging(logging_on != 0, &names)
        })
    }
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

/// The numeric FMI 2.0 types exchanged through `fmi2Get*`/`fmi2Set*` (the shared value
/// kinds of [`crate::abi::kinds`]).
pub use crate::abi::kinds::{Boolean, Integer, Real};

/// The value references of a get call, after its pointer checks (`Err`: the rejection's
/// status).
///
/// # Safety
/// FMI pointer contract.
unsafe fn get_references<'a, M: FmuModel>(
    s: &Slot<M>,
    f: &Function,
    vr: *const fmi2ValueReference,
    n: usize,
    out_is_null: bool,
) -> Result<&'a [fmi2ValueReference], Status> {
    // SAFETY: forwarded from the caller.
    let Some(vrs) = (unsafe { slice(vr, n) }) else {
        return Err(s.instance.reject(f, "vr is NULL"));
    };
    if n > 0 && out_is_null {
        return Err(s.instance.reject(f, "value is NULL"));
    }
    Ok(vrs)
}

/// `fmi2GetReal`, `fmi2GetInteger`, `fmi2GetBoolean`: the values into a C array.
///
/// # Safety
/// FMI pointer contract.
pub unsafe fn get<M: FmuModel, T: Kind<Fmi2>>(
    c: fmi2Component,
    vr: *const fmi2ValueReference,
    n: usize,
    out: *mut T::C,
) -> fmi2Status {
    let f = T::GET;
    unsafe {
        with_instance::<M>(c, f, |s| {
            // SAFETY: `vr` and `out` are NULL or hold `n` elements (FMI contract).
            match (slice(vr, n), slice_mut(out, n)) {
                (Some(vrs), Some(out)) => s.instance.get_array(f, T::TYPE, vrs, out, T::to_c),
                _ => match get_references(s, f, vr, n, out.is_null()) {
                    Err(status) => status,
                    Ok(_) => Status::Error,
                },
            }
        })
    }
}

/// `fmi2GetString`.
///
/// # Safety
/// FMI pointer contract.
pub unsafe fn get_string<M: FmuModel>(
    c: fmi2Component,
    vr: *const fmi2ValueReference,
    n: usize,
    value: *mut fmi2String,
) -> fmi2Status {
    let f = &functions::GET_STRING;
    unsafe {
        with_instance::<M>(c, f, |s| {
            let vrs = match get_references(s, f, vr, n, value.is_null()) {
                Ok(vrs) => vrs,
                Err(status) => return status,
            };
            let mut values = Vec::with_capacity(n);
            let status = s
                .instance
                .get_values(f, vrs, VariableType::String, |_, all, index| {
                    values.push(all.string(index).to_string())
                });
            // SAFETY: `value` points to `n` slots and `values` has at most `n` elements.
            s.return_strings(&values, value);
            status
        })
    }
}

/// `fmi2SetReal`, `fmi2SetInteger`, `fmi2SetBoolean`: the values from a C array.
///
/// # Safety
/// FMI pointer contract.
pub unsafe fn set<M: FmuModel, T: Kind<Fmi2>>(
    c: fmi2Component,
    vr: *const fmi2ValueReference,
    n: usize,
    value: *const T::C,
) -> fmi2Status {
    let f = T::SET;
    unsafe {
        with_instance::<M>(c, f, |s| {
            let (Some(vrs), Some(values)) = (slice(vr, n), slice(value, n)) else {
                return s.instance.reject(f, "vr or value is NULL");
            };
            s.instance
                .set_array(f, T::TYPE, (vrs, values), T::to_number)
        })
    }
}

/// `fmi2SetString`.
///
/// # Safety
/// FMI pointer contract.
pub unsafe fn set_string<M: FmuModel>(
    c: fmi2Component,
    vr: *const fmi2ValueReference,
    n: usize,
    value: *const fmi2String,
) -> fmi2Status {
    let f = &functions::SET_STRING;
    unsafe {
        with_instance::<M>(c, f, |s| {
            let (Some(vrs), Some(raw)) = (slice(vr, n), slice(value, n)) else {
                return s.instance.reject(f, "vr or value is NULL");
            };
            match string_values(s, f, raw) {
                Ok(values) => s.instance.set_values(f, vrs.iter().copied().zip(values)),
                Err(status) => status,
            }
        })
    }
}

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
