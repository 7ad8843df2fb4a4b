//! The FMI 3.0 C ABI: raw pointers in, [`Instance`] calls out.
//!
//! The twin of [`crate::ffi`] for FMI 3.0, with the same guarantees: every function checks
//! its pointers, catches panics (the instance is then `Fatal`), checks the allowed-state mask
//! of [`super::functions`] before doing anything, and logs every error through the master's
//! `fmi3LogMessageCallback` (which takes the message as it is: no format string). Value
//! references are those of the shared [`Layout`](super::arrays::Layout) of the instance's
//! interface: arrays are expanded to the instance's scalars here, without a buffer, and
//! `nValues` must equal the number of elements they name.

use super::arrays::{Target, TIME};
use super::description::type_name;
use super::functions;
use super::types::*;
use crate::description::{Config, CONFIG_FILE};
use crate::ffi::{guarded, slice, slice_mut, string_arg};
use crate::front::{self, free_slot, with_slot, ConfigFile, Fmi3, Kind};
use crate::instance::{Access, Function, Instance, LogSink, Logger};
use crate::me::Hooks;
use crate::model::FmuModel;
use crate::types::Status;
use crate::variables::{Value, VariableType};
use std::ffi::CString;
use std::os::raw::c_char;
use std::sync::Arc;

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
pub type Slot<M> = crate::front::Slot<M, Fmi3>;

/// Boxes a slot as an `fmi3Instance`.
pub fn into_instance<M: FmuModel>(instance: Instance<M>) -> fmi3Instance {
    Slot::new(instance, Fmi3).into_handle()
}

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

/// `fmi3InstantiateCoSimulation`: checks the name, the instantiation token (the GUID) and
/// the resources (`variant.cfg` of a packaged variant), then creates the instance (with the
/// model's Model Exchange functions `me`, for its directional derivatives).
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
    let requested = Requested::CoSimulation { refusal, note };
    unsafe { instantiate("fmi3InstantiateCoSimulation", args, requested, me) }
}

/// `fmi3InstantiateModelExchange`: as [`instantiate_co_simulation`], for a model with Model
/// Exchange functions `me` whose description declares the interface (otherwise refused, the
/// reason logged).
///
/// # Safety
/// Pointer arguments must be NULL or valid as the FMI standard requires.
pub unsafe fn instantiate_model_exchange<M: FmuModel>(
    args: Instantiation,
    me: Option<Hooks<M>>,
) -> fmi3Instance {
    let f = "fmi3InstantiateModelExchange";
    unsafe { instantiate(f, args, Requested::ModelExchange, me) }
}

/// The interface an `fmi3Instantiate*` function asks for.
enum Requested {
    /// Co-Simulation: why its own arguments are refused, if they are, and what to log when
    /// the instance is created.
    CoSimulation {
        refusal: Option<String>,
        note: Option<&'static str>,
    },
    ModelExchange,
}

/// The shared part of the `fmi3Instantiate*` functions: name, refusal, token, resources,
/// interface, then the instance (for Model Exchange if asked, with the model's functions
/// `me`).
///
/// # Safety
/// Pointer arguments must be NULL or valid as the FMI standard requires.
unsafe fn instantiate<M: FmuModel>(
    function: &str,
    args: Instantiation,
    requested: Requested,
    me: Option<Hooks<M>>,
) -> fmi3Instance {
    let Instantiation(instance_name, token, resource_path, logging_on, environment, log_message) =
        args;
    let (refusal, note, model_exchange) = match requested {
        Requested::CoSimulation { refusal, note } => (refusal, note, false),
        Requested::ModelExchange => (None, None, true),
    };
    let result = guarded(|| {
        let sink = || CallbackSink {
            log_message,
            environment,
        };
        // SAFETY: FMI strings are NULL or NUL-terminated.
        let name = unsafe { string_arg(instance_name) };
        let logger = Logger::new(
            name.as_deref().unwrap_or("?"),
            Box::new(sink()),
            logging_on != 0,
        );
        let fail = |message: String| {
            logger.error(&format!("{function}: {message}"));
            std::ptr::null_mut()
        };
        if name.as_deref().is_none_or(str::is_empty) {
            return fail("instanceName must be a non-empty string".into());
        }
        if let Some(refusal) = refusal {
            return fail(refusal);
        }
        // SAFETY: as above.
        let given = unsafe { string_arg(token) }.unwrap_or_default();
        let resources = unsafe { string_arg(resource_path) }.filter(|s| !s.is_empty());
        let config = match resources.as_deref() {
            Some(dir) => match front::read_config(std::path::Path::new(dir)) {
                Ok(ConfigFile::Found(config)) => config,
                Ok(ConfigFile::Missing(_)) => Config::new(),
                Err(message) => return fail(message),
            },
            None => Config::new(),
        };
        let interface = match front::interface::<M>(&config) {
            Ok(interface) => interface,
            Err(e) => return fail(format!("invalid variant configuration: {e}")),
        };
        let info = &interface.info;
        if given != info.guid {
            let hint = if config.is_empty() {
                format!(
                    " (a variant FMU needs its resources/{CONFIG_FILE}: resourcePath is {})",
                    resources.as_deref().unwrap_or("NULL")
                )
            } else {
                String::new()
            };
            return fail(format!(
                "instantiationToken mismatch: the modelDescription.xml gives {given} but this binary of {} implements {}{hint}",
                info.model_identifier, info.guid
            ));
        }
        let offered = me.filter(|_| info.model_exchange.is_some());
        if model_exchange && offered.is_none() {
            return fail(format!(
                "{} is a Co-Simulation FMU only: it does not implement Model Exchange",
                info.model_identifier
            ));
        }
        if let Some(note) = note {
            logger.log(Status::Ok, "logEvents", &format!("{function}: {note}"));
        }
        match Instance::<M>::of(Arc::clone(&interface), logger) {
            Ok(instance) => into_instance(match offered.filter(|_| model_exchange) {
                Some(hooks) => instance.into_model_exchange(hooks),
                None => instance.with_hooks(me),
            }),
            Err(e) => {
                Logger::new("?", Box::new(sink()), true).error(&format!("{function}: {e}"));
                std::ptr::null_mut()
            }
        }
    });
    result.unwrap_or(std::ptr::null_mut())
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
/// `c` must be NULL or an instance from [`instantiate_co_simulation`] not freed yet.
pub unsafe fn free_instance<M: FmuModel>(c: fmi3Instance) {
    // SAFETY: forwarded from the caller.
    unsafe { free_slot::<M, Fmi3>(c) }
}

/// `fmi3SetDebugLogging`.
///
/// # Safety
/// FMI pointer contract.
pub unsafe fn set_debug_logging<M: FmuModel>(
    c: fmi3Instance,
    logging_on: fmi3Boolean,
    n: usize,
    categories: *const fmi3String,
) -> fmi3Status {
    let f = &functions::SET_DEBUG_LOGGING;
    unsafe {
        with_instance::<M>(c, f, |s| {
            let Some(raw) = slice(categories, n) else {
                return s.instance.reject(f, "categories is NULL");
            };
            let names: Vec<String> = raw
                .iter()
                .map(|p| string_arg(*p).unwrap_or_default())
                .collect();
            s.instance.set_debug_logging_as(f, logging_on != 0, &names)
        })
    }
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

/// Why FMI 3.0 value reference `vr` names nothing.
pub(super) fn unknown_reference(interface: &front::Interface, vr: u32) -> String {
    format!(
        "unknown value reference {vr} ({} has value references 0 to {})",
        interface.info.model_identifier,
        interface.layout.max_value_reference()
    )
}

/// Checks the value references of a call: every one known and naming variables of type
/// `expected`, and `n_values` the number of values they name (arrays row-major); `Err` with
/// the message. Allocates nothing unless it fails.
fn check_references<M: FmuModel>(
    slot: &Slot<M>,
    vrs: &[u32],
    expected: VariableType,
    n_values: usize,
) -> Result<(), String> {
    let interface = slot.instance.interface();
    let mut count = 0;
    for &vr in vrs {
        let (name, actual, len) = match interface.layout.target(vr) {
            None => return Err(unknown_reference(interface, vr)),
            Some(Target::Time) => ("time", VariableType::Real, 1),
            Some(Target::Variable(v)) => (
                v.name.as_str(),
                interface.access[v.first].variable_type,
                v.len(),
            ),
        };
        if actual != expected {
            return Err(format!(
                "variable `{name}` (value reference {vr}) is of type {}, not {}",
                type_name(actual),
                type_name(expected)
            ));
        }
        count += len;
    }
    if count != n_values {
        return Err(format!(
            "nValues = {n_values}, but the {} value references name {count} values",
            vrs.len()
        ));
    }
    Ok(())
}

/// The FMI 3.0 types exchanged through `fmi3Get*`/`fmi3Set*` (the shared value kinds of
/// [`crate::front`]): `fmi3Float64`, `fmi3Int32`, `fmi3Boolean`.
pub use crate::front::{Boolean, Integer as Int32, Real as Float64};

/// A get call on the slot: checks the pointers and the references, lets the instance compute
/// what it must, then hands the `n_values` values `vr` names (arrays row-major) to `write`:
/// their positions and values (`time` for value reference 0). No buffer.
///
/// # Safety
/// FMI pointer contract.
#[allow(clippy::too_many_arguments)]
unsafe fn read<M: FmuModel>(
    s: &mut Slot<M>,
    f: &Function,
    vr: *const fmi3ValueReference,
    nvr: usize,
    out_is_null: bool,
    n_values: usize,
    expected: VariableType,
    mut write: impl FnMut(usize, Element<'_>),
) -> Status {
    // SAFETY: forwarded from the caller.
    let Some(vrs) = (unsafe { slice(vr, nvr) }) else {
        return s.instance.reject(f, "valueReferences is NULL");
    };
    if n_values > 0 && out_is_null {
        return s.instance.reject(f, "values is NULL");
    }
    if let Err(message) = check_references(s, vrs, expected, n_values) {
        return s.instance.reject(f, &message);
    }
    let interface = Arc::clone(s.instance.interface());
    let status = s.instance.refresh_for(f, interface.layout.indices_of(vrs));
    if status > Status::Warning {
        return status;
    }
    let (interface, values) = (s.instance.interface(), s.instance.values());
    let (numbers, time) = (values.numbers(), s.instance.time());
    let texts = expected == VariableType::String;
    let mut k = 0;
    for &vr in vrs {
        match interface.layout.target(vr) {
            Some(Target::Time) => {
                write(k, Element::Number(time));
                k += 1;
            }
            Some(Target::Variable(v)) if texts => {
                for index in v.indices() {
                    write(k, Element::Text(values.string(index)));
                    k += 1;
                }
            }
            Some(Target::Variable(v)) => {
                for &x in numbers.get(v.indices()).unwrap_or_default() {
                    write(k, Element::Number(x));
                    k += 1;
                }
            }
            None => {}
        }
    }
    status
}

/// The get call's fast path: when nothing must be computed first and every reference names
/// variables of type `expected` whose values fill `out` exactly, the values (arrays
/// row-major, `time` for value reference 0) into `out`, each through `to_c`; `None`
/// otherwise, and [`read`] checks again and says why (the values written are then undefined,
/// as FMI 3.0 allows for a failed get). A span lookup and a slice copy per reference; for the
/// common call, scalars only (`nValues = nvr`), a span lookup and a load, and a call that
/// names an array goes on from it, not from the start.
#[inline(always)]
fn read_fast<M: FmuModel, C>(
    s: &Slot<M>,
    expected: VariableType,
    vrs: &[u32],
    out: &mut [C],
    to_c: impl Fn(f64) -> C,
) -> Option<Status> {
    let instance = &s.instance;
    if instance.needs_refresh() || instance.reads_pending_indicator(vrs, true) {
        return None;
    }
    let (spans, numbers) = (&instance.interface().spans, instance.values().numbers());
    let type_bit = Access::type_bit(expected);
    // the scalars ahead of the first other reference (all of the master's call): the value
    // at the same position as its reference
    let done = 'scalars: {
        if vrs.len() != out.len() {
            break 'scalars 0;
        }
        for (i, (o, &vr)) in out.iter_mut().zip(vrs).enumerate() {
            match spans.get(vr as usize) {
                Some(span) if span.len == 1 && span.type_bit == type_bit => {
                    *o = to_c(*numbers.get(span.first as usize)?);
                }
                _ => break 'scalars i,
            }
        }
        return Some(Status::Ok);
    };
    // the rest, from the first array, `time` or reference of another type
    let mut k = done;
    for &vr in vrs.get(done..)? {
        let span = spans.get(vr as usize)?;
        if span.type_bit != type_bit {
            return None;
        }
        let first = span.first as usize;
        k += match span.len as usize {
            0 => {
                *out.get_mut(k)? = to_c(instance.time());
                1
            }
            1 => {
                *out.get_mut(k)? = to_c(*numbers.get(first)?);
                1
            }
            len => {
                let xs = numbers.get(first..first + len)?;
                for (o, &x) in out.get_mut(k..k + len)?.iter_mut().zip(xs) {
                    *o = to_c(x);
                }
                len
            }
        };
    }
    (k == out.len()).then_some(Status::Ok)
}

/// A value a get call reads: a number ([`crate::Values::numbers`]) or a String's text.
enum Element<'a> {
    Number(f64),
    Text(&'a str),
}

/// `fmi3GetFloat64`, `fmi3GetInt32`, `fmi3GetBoolean`: the values (arrays row-major) into a C
/// array of `n_values` elements.
///
/// # Safety
/// FMI pointer contract.
pub unsafe fn get<M: FmuModel, K: Kind<Fmi3>>(
    c: fmi3Instance,
    vr: *const fmi3ValueReference,
    nvr: usize,
    out: *mut K::C,
    n_values: usize,
) -> fmi3Status {
    let (f, null) = (K::GET, out.is_null());
    unsafe {
        with_instance::<M>(c, f, |s| {
            // SAFETY: `vr` and `out` are NULL or hold `nvr` and `n_values` elements (FMI
            // contract).
            if let (Some(vrs), Some(to)) = (slice(vr, nvr), slice_mut(out, n_values)) {
                if let Some(status) = read_fast(s, K::TYPE, vrs, to, K::to_c) {
                    return status;
                }
            }
            read(s, f, vr, nvr, null, n_values, K::TYPE, |i, value| {
                if let Element::Number(x) = value {
                    // SAFETY: `out` holds `n_values` elements (FMI contract) and `i < n_values`
                    // (checked by `check_references`).
                    *out.add(i) = K::to_c(x)
                }
            })
        })
    }
}

/// Checks a set call's references, then hands the `(scalar index, value)` pairs they name
/// (arrays row-major; the `k`-th value is `value_at(k)`) to the instance. No buffer.
fn write_values<M: FmuModel, T>(
    slot: &mut Slot<M>,
    f: &Function,
    vrs: &[u32],
    expected: VariableType,
    n_values: usize,
    value_at: impl Fn(usize) -> T + Clone,
    store: impl Store<T>,
) -> Status {
    if let Err(message) = check_references(slot, vrs, expected, n_values) {
        return slot.instance.reject(f, &message);
    }
    if vrs.contains(&TIME) {
        return slot.instance.reject(
            f,
            "variable `time` (value reference 0) is the independent variable: the master sets it through fmi3EnterInitializationMode and fmi3DoStep",
        );
    }
    let interface = Arc::clone(slot.instance.interface());
    let targets = interface
        .layout
        .indices_of(vrs)
        .enumerate()
        .map(|(k, index)| (index as u32, value_at(k)));
    store.store(&mut slot.instance, f, targets)
}

/// How the values of a set call reach the instance: numbers of one type, or values.
trait Store<T> {
    fn store<M: FmuModel, I>(self, instance: &mut Instance<M>, f: &Function, targets: I) -> Status
    where
        I: Iterator<Item = (u32, T)> + Clone;
}

/// Numbers of one type ([`Instance::set_numbers`]).
struct AsNumbers(VariableType);
impl Store<f64> for AsNumbers {
    fn store<M: FmuModel, I>(self, instance: &mut Instance<M>, f: &Function, targets: I) -> Status
    where
        I: Iterator<Item = (u32, f64)> + Clone,
    {
        instance.set_numbers(f, self.0, targets)
    }
}

/// Values ([`Instance::set_values`]).
struct AsValues;
impl Store<Value> for AsValues {
    fn store<M: FmuModel, I>(self, instance: &mut Instance<M>, f: &Function, targets: I) -> Status
    where
        I: Iterator<Item = (u32, Value)> + Clone,
    {
        instance.set_values(f, targets)
    }
}

/// `fmi3SetFloat64`, `fmi3SetInt32`, `fmi3SetBoolean`: the values (arrays row-major) from a
/// C array of `n_values` elements.
///
/// # Safety
/// FMI pointer contract.
pub unsafe fn set<M: FmuModel, K: Kind<Fmi3>>(
    c: fmi3Instance,
    vr: *const fmi3ValueReference,
    nvr: usize,
    values: *const K::C,
    n_values: usize,
) -> fmi3Status {
    let f = K::SET;
    unsafe {
        with_instance::<M>(c, f, |s| {
            let (Some(vrs), Some(raw)) = (slice(vr, nvr), slice(values, n_values)) else {
                return s.instance.reject(f, "valueReferences or values is NULL");
            };
            if let Some(status) = s.instance.set_spans(f, K::TYPE, vrs, raw, K::to_number) {
                return status;
            }
            let number = |k: usize| K::to_number(raw[k]);
            write_values(s, f, vrs, K::TYPE, n_values, number, AsNumbers(K::TYPE))
        })
    }
}

/// `fmi3GetString`.
///
/// # Safety
/// FMI pointer contract.
pub unsafe fn get_string<M: FmuModel>(
    c: fmi3Instance,
    vr: *const fmi3ValueReference,
    nvr: usize,
    out: *mut fmi3String,
    n_values: usize,
) -> fmi3Status {
    let (f, null) = (&functions::GET_STRING, out.is_null());
    unsafe {
        with_instance::<M>(c, f, |s| {
            let mut values = Vec::with_capacity(n_values);
            let status = read(
                s,
                f,
                vr,
                nvr,
                null,
                n_values,
                VariableType::String,
                |_, value| {
                    if let Element::Text(text) = value {
                        values.push(text.to_string())
                    }
                },
            );
            if status <= Status::Warning {
                // SAFETY: `out` holds `n_values` slots, the number of `values`.
                s.return_strings(&values, out);
            }
            status
        })
    }
}

/// `fmi3SetString`.
///
/// # Safety
/// FMI pointer contract.
pub unsafe fn set_string<M: FmuModel>(
    c: fmi3Instance,
    vr: *const fmi3ValueReference,
    nvr: usize,
    values: *const fmi3String,
    n_values: usize,
) -> fmi3Status {
    let f = &functions::SET_STRING;
    unsafe {
        with_instance::<M>(c, f, |s| {
            let (Some(vrs), Some(raw)) = (slice(vr, nvr), slice(values, n_values)) else {
                return s.instance.reject(f, "valueReferences or values is NULL");
            };
            match front::string_values(s, f, raw) {
                Ok(texts) => {
                    let text = |k: usize| texts[k].clone();
                    write_values(s, f, vrs, VariableType::String, n_values, text, AsValues)
                }
                Err(status) => status,
            }
        })
    }
}

front::state_functions!(fmi3Instance, fmi3FMUState, fmi3Byte, Fmi3, "FMUState");

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
