//! The C ABI: raw pointers in, [`Instance`] calls out.
//!
//! This module (with the logger call in [`CallbackSink`]) is the only place in the product's
//! FMUs with `unsafe` code. Each function here is generic over the model; the
//! [`export_fmu!`](crate::export_fmu) macro instantiates them as the `fmi2*` symbols of one
//! FMU binary. Every function checks its pointers, catches panics (`catch_unwind`: a panic
//! never crosses the ABI; the instance is then `Fatal`) and checks the allowed-state mask
//! before doing anything.
//!
//! **Panic text goes to the FMI logger only.** A panic hook (installed once, by the first
//! call) captures the message and location of a panic raised inside one of these calls on
//! this thread and prints nothing; the catching site logs it as `fmi2Fatal`. Panics outside
//! an FMU call go to the hook that was there before. An FMU `cdylib` links its own `std`, so
//! the hook is the FMU's and never the importing tool's.
//!
//! How the hook knows that its thread is inside a call: a call on an instance marks the
//! instance's [`CallMarker`] with the identity of its thread (the thread pointer register,
//! read without a thread-local access: a `cdylib`'s thread-locals cost a `__tls_get_addr`
//! call each) and clears it on return; the hook, which runs only when a panic happens, looks
//! for its own thread among the markers of the live instances. The calls that have no
//! instance yet (`fmi2Instantiate`, the queries: [`guarded`]) set a thread-local flag instead.

use crate::description::{Config, CONFIG_FILE};
use crate::front::{self, free_slot, with_slot, ConfigFile, Fmi2, Kind};
use crate::instance::{functions, Function, Instance, LogSink, Logger};
use crate::me::Hooks;
use crate::model::FmuModel;
use crate::types::*;
use crate::uri::resource_path;
use crate::variables::VariableType;
use std::cell::{Cell, RefCell};
use std::ffi::{CStr, CString};
use std::os::raw::c_char;
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Arc, Mutex, Once};

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
pub type Slot<M> = crate::front::Slot<M>;

pub(crate) fn panic_message(payload: &(dyn std::any::Any + Send)) -> String {
    if let Some(s) = payload.downcast_ref::<&str>() {
        (*s).to_string()
    } else if let Some(s) = payload.downcast_ref::<String>() {
        s.clone()
    } else {
        "panic".to_string()
    }
}

thread_local! {
    /// This thread is inside an FMU call ([`guarded`]).
    static IN_CALL: Cell<bool> = const { Cell::new(false) };
    /// The text of the last panic raised inside an FMU call on this thread.
    static PANIC_TEXT: RefCell<Option<String>> = const { RefCell::new(None) };
}

static HOOK: Once = Once::new();

/// Which thread runs a call on one instance (0: none): the [`thread_identity`] of the caller
/// while [`guarded_call`] runs the call. Shared with [`MARKERS`], which the panic hook reads.
#[derive(Debug, Default)]
pub struct CallMarker(AtomicUsize);

/// The markers of the live instances (added when a handle is made, removed when it is freed).
static MARKERS: Mutex<Vec<Arc<CallMarker>>> = Mutex::new(Vec::new());

impl CallMarker {
    /// A marker, registered for the panic hook until [`CallMarker::unregister`].
    pub(crate) fn registered() -> Arc<Self> {
        let marker = Arc::new(Self::default());
        MARKERS
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .push(Arc::clone(&marker));
        marker
    }

    /// Removes the marker from the registry.
    pub(crate) fn unregister(marker: &Arc<Self>) {
        MARKERS
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .retain(|m| !Arc::ptr_eq(m, marker));
    }

    /// Whether a call on some live instance runs on thread `me` (the hook's question).
    fn any_runs_on(me: usize) -> bool {
        MARKERS
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .iter()
            .any(|m| m.0.load(Ordering::Relaxed) == me)
    }
}

/// Whether this thread is inside an FMU call (the panic hook's question).
fn inside_call() -> bool {
    IN_CALL.with(Cell::get) || CallMarker::any_runs_on(thread_identity())
}

/// A number that identifies the running thread among the live ones, never 0: the thread
/// pointer (x86-64 Linux `fs:0`, x86-64 Windows `gs:[0x30]`, the self pointers of the TCB and
/// the TEB; AArch64 `tpidr_el0`), read with one instruction; elsewhere the address of a
/// thread-local.
#[inline(always)]
fn thread_identity() -> usize {
    #[cfg(all(target_arch = "x86_64", target_os = "linux"))]
    {
        let tp: usize;
        // SAFETY: the x86-64 System V TLS ABI keeps the thread pointer at fs:0 on every
        // thread; the read has no other effect.
        unsafe {
            std::arch::asm!("mov {}, fs:0", out(reg) tp, options(nostack, readonly, preserves_flags))
        };
        tp
    }
    #[cfg(all(target_arch = "x86_64", target_os = "windows"))]
    {
        let tp: usize;
        // SAFETY: on x86-64 Windows gs:[0x30] is the running thread's TEB self pointer; the
        // read has no other effect.
        unsafe {
            std::arch::asm!("mov {}, gs:[0x30]", out(reg) tp, options(nostack, readonly, preserves_flags))
        };
        tp
    }
    #[cfg(all(target_arch = "aarch64", target_os = "linux"))]
    {
        let tp: usize;
        // SAFETY: tpidr_el0 holds the running thread's thread pointer; reading it has no
        // other effect.
        unsafe {
            std::arch::asm!("mrs {}, tpidr_el0", out(reg) tp, options(nostack, nomem, preserves_flags))
        };
        tp
    }
    #[cfg(not(any(
        all(
            target_arch = "x86_64",
            any(target_os = "linux", target_os = "windows")
        ),
        all(target_arch = "aarch64", target_os = "linux")
    )))]
    {
        thread_local! {
            static ANCHOR: u8 = const { 0 };
        }
        ANCHOR.with(|a| a as *const u8 as usize)
    }
}

/// Installs (once) the hook that keeps panics inside FMU calls off stderr (module docs).
/// Called by [`guarded`] and, for the calls on an instance ([`guarded_call`]), once when the
/// instance handle is made ([`crate::front::Slot::into_handle`]).
pub(crate) fn install_panic_hook() {
    HOOK.call_once(|| {
        let previous = std::panic::take_hook();
        std::panic::set_hook(Box::new(move |info| {
            if inside_call() {
                let mut text = panic_message(info.payload());
                if let Some(location) = info.location() {
                    text.push_str(&format!(" (at {location})"));
                }
                PANIC_TEXT.with(|t| *t.borrow_mut() = Some(text));
            } else {
                previous(info);
            }
        }));
    });
}

/// Runs `body` as an FMU call: panics are caught and their text (message and location)
/// returned instead of printed.
pub fn guarded<T>(body: impl FnOnce() -> T) -> Result<T, String> {
    install_panic_hook();
    guarded_flagged(body).map_err(|payload| panic_text(payload.as_ref()))
}

/// What a caught panic carries; [`panic_text`] turns it into the message to log.
pub(crate) type Payload = Box<dyn std::any::Any + Send>;

/// [`guarded`] once the hook is installed (without the thread-local flag).
#[inline(always)]
fn guarded_flagged<T>(body: impl FnOnce() -> T) -> Result<T, Payload> {
    let flag: *const Cell<bool> = IN_CALL.with(|flag| flag as *const Cell<bool>);
    // SAFETY: the flag is this thread's, alive as long as the thread, which runs this call;
    // nothing else borrows it across the call (a `Cell`: no reference is handed out).
    let outer = unsafe { (*flag).replace(true) };
    let result = catch_unwind(AssertUnwindSafe(body));
    // SAFETY: as above.
    unsafe { (*flag).set(outer) };
    result
}

/// The path of every call on an instance, whose handle installed the hook: `marker` (the
/// instance's) holds this thread's identity while `body` runs, then what it held before (a
/// load and two stores, no thread-local access), and the unwinding landing pad; the panic's
/// text is fetched on the cold path ([`panic_text`]).
#[inline(always)]
pub(crate) fn guarded_call<T>(marker: &CallMarker, body: impl FnOnce() -> T) -> Result<T, Payload> {
    let outer = marker.0.load(Ordering::Relaxed);
    marker.0.store(thread_identity(), Ordering::Relaxed);
    let result = catch_unwind(AssertUnwindSafe(body));
    marker.0.store(outer, Ordering::Relaxed);
    result
}

/// The text of the panic just caught: the one the hook captured (message and location), or
/// the payload's.
#[cold]
#[inline(never)]
pub(crate) fn panic_text(payload: &(dyn std::any::Any + Send)) -> String {
    PANIC_TEXT
        .with(|t| t.borrow_mut().take())
        .unwrap_or_else(|| panic_message(payload))
}

/// Runs `body` on the instance behind `c` after the null and state checks, catching panics.
pub(crate) unsafe fn with_instance<M: FmuModel>(
    c: fmi2Component,
    f: &Function,
    body: impl FnOnce(&mut Slot<M>) -> Status,
) -> fmi2Status {
    // SAFETY: `c` is NULL or was returned by `instantiate::<M>` (the master's obligation).
    unsafe { with_slot::<M, ()>(c, f, body) }
}

/// Reads `n` elements behind `p` as a slice; `None` if `p` is NULL while `n > 0`.
pub(crate) unsafe fn slice<'a, T>(p: *const T, n: usize) -> Option<&'a [T]> {
    if n == 0 {
        Some(&[])
    } else if p.is_null() {
        None
    } else {
        // SAFETY: the caller guarantees `p` points to `n` valid elements (FMI contract).
        Some(unsafe { std::slice::from_raw_parts(p, n) })
    }
}

/// The `n` writable elements behind `p` (empty when `n` is 0); `None` for NULL with `n > 0`.
///
/// # Safety
/// `p` is NULL or points to `n` writable elements (FMI contract).
pub(crate) unsafe fn slice_mut<'a, T>(p: *mut T, n: usize) -> Option<&'a mut [T]> {
    if n == 0 {
        Some(&mut [])
    } else if p.is_null() {
        None
    } else {
        // SAFETY: the caller's obligation.
        Some(unsafe { std::slice::from_raw_parts_mut(p, n) })
    }
}

pub(crate) unsafe fn string_arg(s: fmi2String) -> Option<String> {
    if s.is_null() {
        None
    } else {
        // SAFETY: FMI strings are NUL-terminated.
        Some(unsafe { CStr::from_ptr(s) }.to_string_lossy().into_owned())
    }
}

/// `fmi2GetTypesPlatform`.
pub fn types_platform() -> *const c_char {
    c"default".as_ptr()
}

/// `fmi2GetVersion`.
pub fn version() -> *const c_char {
    c"2.0".as_ptr()
}

/// `fmi2Instantiate`: checks the type, the GUID and the resources, then creates the instance
/// (for Model Exchange if the model has its functions `me` and its description declares it).
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
    let result = guarded(|| {
        if functions.is_null() {
            return std::ptr::null_mut();
        }
        // SAFETY: checked non-null; the master keeps the struct alive (FMI 2.0.4 §2.1.5 asks
        // the FMU to copy what it needs: we copy the two fields we use).
        let callbacks = unsafe { &*functions };
        let sink = CallbackSink {
            logger: callbacks.logger,
            environment: callbacks.componentEnvironment,
        };
        let name = unsafe { string_arg(instance_name) };
        let logger = Logger::new(
            name.as_deref().unwrap_or("?"),
            Box::new(sink),
            logging_on != 0,
        );
        let fail = |message: String| {
            logger.error(&format!("fmi2Instantiate: {message}"));
            std::ptr::null_mut()
        };
        let Some(name) = name.filter(|n| !n.is_empty()) else {
            return fail("instanceName must be a non-empty string".into());
        };
        let _ = name;
        // The variant configuration, from `resources/variant.cfg`. Only an FMU whose GUID is
        // that of the default configuration may go without one; any other failure to read it
        // is an error that names the file (or the URI) and the reason.
        let given = unsafe { string_arg(guid) }.unwrap_or_default();
        let default = front::interface::<M>(&Config::new()).ok();
        let default = default.as_ref().map(|i| &i.info);
        let is_default = default.is_some_and(|info| info.guid == given);
        let without_config = |reason: String| {
            let (id, guid) = default.map_or(("this FMU", "?"), |i| {
                (i.model_identifier.as_str(), i.guid.as_str())
            });
            fail(format!(
                "GUID mismatch or missing variant configuration: the modelDescription.xml gives {given}, not the GUID {guid} of {id} without a variant configuration, and {reason}"
            ))
        };
        let location = unsafe { string_arg(resource_location) }.filter(|s| !s.is_empty());
        let config = match location.as_deref().map(resource_path) {
            Some(Ok(dir)) => match front::read_config(&dir) {
                Ok(ConfigFile::Found(config)) => config,
                Ok(ConfigFile::Missing(e)) if !is_default => {
                    return without_config(format!(
                        "the variant configuration {} cannot be read: {e}",
                        dir.join(CONFIG_FILE).display()
                    ))
                }
                Ok(ConfigFile::Missing(_)) => Config::new(),
                Err(message) => return fail(message),
            },
            Some(Err(e)) if !is_default => {
                return without_config(format!(
                    "resources/{CONFIG_FILE} cannot be located: fmuResourceLocation `{}`: {e}",
                    location.as_deref().unwrap_or_default()
                ))
            }
            None if !is_default => {
                return without_config(format!(
                    "no fmuResourceLocation is given to read resources/{CONFIG_FILE} from"
                ))
            }
            _ => Config::new(),
        };
        let interface = match front::interface::<M>(&config) {
            Ok(interface) => interface,
            Err(e) => return fail(format!("invalid variant configuration: {e}")),
        };
        let info = &interface.info;
        let offered = me.filter(|_| info.model_exchange.is_some());
        let model_exchange = match (fmu_type, offered) {
            (t, _) if t == fmi2CoSimulation => None,
            (t, Some(hooks)) if t == fmi2ModelExchange => Some(hooks),
            (_, None) => {
                return fail(format!(
                    "{} is a Co-Simulation FMU only: fmuType must be fmi2CoSimulation (1), got {fmu_type}",
                    info.model_identifier
                ))
            }
            (_, Some(_)) => {
                return fail(format!(
                    "fmuType must be fmi2ModelExchange (0) or fmi2CoSimulation (1), got {fmu_type}"
                ))
            }
        };
        if given != info.guid {
            return fail(format!(
                "GUID mismatch: the modelDescription.xml gives {given} but this binary of {} implements {} (the binary and the XML come from different builds or variants)",
                info.model_identifier, info.guid
            ));
        }
        match Instance::<M>::of(Arc::clone(&interface), logger) {
            Ok(instance) => into_component(match model_exchange {
                Some(hooks) => instance.into_model_exchange(hooks),
                None => instance.with_hooks(me),
            }),
            Err(e) => {
                // The logger moved into the failed constructor call; report through a new one.
                let sink = CallbackSink {
                    logger: callbacks.logger,
                    environment: callbacks.componentEnvironment,
                };
                Logger::new("?", Box::new(sink), true).error(&format!("fmi2Instantiate: {e}"));
                std::ptr::null_mut()
            }
        }
    });
    result.unwrap_or(std::ptr::null_mut())
}

/// Boxes an instance as an `fmi2Component` (what `fmi2Instantiate` returns).
pub fn into_component<M: FmuModel>(instance: Instance<M>) -> fmi2Component {
    Slot::new(instance, ()).into_handle()
}

/// `fmi2FreeInstance`.
///
/// # Safety
/// `c` must be NULL or a component from [`instantiate`] not freed yet.
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
/// kinds of [`crate::front`]).
pub use crate::front::{Boolean, Integer, Real};

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
            match front::string_values(s, f, raw) {
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

front::state_functions!(fmi2Component, fmi2FMUstate, fmi2Byte, (), "FMUstate");

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
        crate::front::write_out::<M, (), T>(c, f, (value, "value"), answer)
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

/// Copies `answer` into `out` (at most `capacity` bytes) and returns its length.
unsafe fn write_answer(answer: &str, out: *mut u8, capacity: usize) -> usize {
    let bytes = answer.as_bytes();
    if !out.is_null() && capacity > 0 {
        let n = bytes.len().min(capacity);
        // SAFETY: the caller gives a writable buffer of `capacity` bytes (query contract).
        unsafe { std::ptr::copy_nonoverlapping(bytes.as_ptr(), out, n) };
    }
    bytes.len()
}

/// `spurio_variants`: the bundled variants as [`crate::query::variants_text`].
///
/// # Safety
/// `out` is NULL or points to `capacity` writable bytes.
pub unsafe fn query_variants(
    variants: fn() -> Vec<crate::query::Variant>,
    out: *mut u8,
    capacity: usize,
) -> usize {
    let text = guarded(variants)
        .map(|v| crate::query::variants_text(&v))
        .unwrap_or_default();
    // SAFETY: forwarded from the caller.
    unsafe { write_answer(&text, out, capacity) }
}

/// `spurio_describe`: the model description for a configuration text, or minus the length of
/// the error message.
///
/// # Safety
/// `config` is NULL or a NUL-terminated string; `out` is NULL or points to `capacity`
/// writable bytes.
pub unsafe fn query_describe<M: FmuModel>(
    config: *const c_char,
    out: *mut u8,
    capacity: usize,
) -> isize {
    // SAFETY: forwarded from the caller.
    unsafe { query_describe_with(crate::query::describe::<M>, config, out, capacity) }
}

/// `spurio_describe` (FMI 2.0) or `spurio_describe3` (FMI 3.0): the answer of `describe` for
/// a configuration text, or minus the length of the error message.
///
/// # Safety
/// As [`query_describe`].
pub unsafe fn query_describe_with(
    describe: fn(&str) -> Result<String, crate::model::Cause>,
    config: *const c_char,
    out: *mut u8,
    capacity: usize,
) -> isize {
    // SAFETY: `config` is NULL or a NUL-terminated string (query contract).
    let text = unsafe { string_arg(config) }.unwrap_or_default();
    let answer = guarded(|| describe(&text)).unwrap_or_else(|m| Err(m.into()));
    let (text, sign) = match answer {
        Ok(xml) => (xml, 1),
        Err(cause) => (cause.to_string(), -1),
    };
    // SAFETY: forwarded from the caller.
    let length = unsafe { write_answer(&text, out, capacity) };
    sign * isize::try_from(length).unwrap_or(isize::MAX)
}

#[cfg(test)]
mod marker_tests {
    use super::*;
    use std::sync::mpsc;

    #[test]
    fn a_thread_is_inside_a_call_exactly_while_it_runs_one() {
        install_panic_hook();
        let marker = CallMarker::registered();
        assert!(!inside_call());
        assert_eq!(guarded_call(&marker, inside_call).ok(), Some(true));
        assert!(!inside_call());
        // a nested call on the same marker leaves it marked until the outer one returns
        let nested = guarded_call(&marker, || {
            let inner = guarded_call(&marker, inside_call).ok();
            (inner, inside_call())
        });
        assert_eq!(nested.ok(), Some((Some(true), true)));
        // a panic caught by the call clears the mark too
        assert!(guarded_call(&marker, || panic!("caught")).is_err());
        assert!(!inside_call());
        assert!(panic_text(&()).contains("caught"));
        // another thread inside a call on another instance: it is, this one is not
        let other = CallMarker::registered();
        let (entered, wait) = (mpsc::channel(), mpsc::channel::<()>());
        let worker = {
            let other = Arc::clone(&other);
            let (entered, wait) = (entered.0, wait.1);
            std::thread::spawn(move || {
                guarded_call(&other, || {
                    entered.send((thread_identity(), inside_call())).unwrap();
                    wait.recv().unwrap();
                })
                .is_ok()
            })
        };
        let (identity, inside) = entered.1.recv().unwrap();
        assert!(inside);
        assert_ne!(identity, thread_identity());
        assert_ne!(identity, 0);
        assert!(!inside_call(), "the other thread's call is not this one's");
        wait.0.send(()).unwrap();
        assert!(worker.join().unwrap());
        // an unregistered marker is not looked at
        CallMarker::unregister(&marker);
        assert!(guarded_call(&marker, inside_call).is_ok_and(|inside| !inside));
        CallMarker::unregister(&other);
    }
}
