//! The FMI 3.0 C ABI: raw pointers in, [`Instance`] calls out.
//!
//! The twin of [`crate::ffi`] for FMI 3.0, with the same guarantees: every function checks
//! its pointers, catches panics (the instance is then `Fatal`), checks the allowed-state mask
//! of [`super::functions`] before doing anything, and logs every error through the master's
//! `fmi3LogMessageCallback` (which takes the message as it is: no format string). Value
//! references are those of [`Layout`]: arrays are expanded to the instance's scalars here,
//! and `nValues` must equal the number of elements they name.

use super::arrays::{Layout, Target};
use super::description::type_name;
use super::functions;
use super::types::*;
use crate::description::{Config, CONFIG_FILE};
use crate::ffi::{guarded, slice, string_arg};
use crate::front::{self, free_slot, with_slot, ConfigFile, Fmi3, Kind};
use crate::instance::{Function, Instance, LogSink, Logger};
use crate::me::Hooks;
use crate::model::FmuModel;
use crate::types::Status;
use crate::variables::{Value, VariableType};
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

/// What an `fmi3Instance` points to: the shared slot with the FMI 3.0 variables (arrays)
/// over the instance's scalars.
pub type Slot<M> = crate::front::Slot<M, Layout>;

/// Boxes a slot as an `fmi3Instance`.
pub fn into_instance<M: FmuModel>(instance: Instance<M>) -> fmi3Instance {
    let layout = Layout::of(&instance.info().variables);
    Slot::new(instance, layout).into_handle()
}

/// Runs `body` on the slot behind `c` after the null and state checks, catching panics.
pub(crate) unsafe fn with_instance<M: FmuModel>(
    c: fmi3Instance,
    f: &Function,
    body: impl FnOnce(&mut Slot<M>) -> Status,
) -> fmi3Status {
    // SAFETY: `c` is NULL or was returned by `instantiate_co_simulation::<M>` (the master's
    // obligation).
    unsafe { with_slot::<M, Layout>(c, f, body) }
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
    let interface = Interface::CoSimulation { refusal, note };
    unsafe { instantiate("fmi3InstantiateCoSimulation", args, interface, me) }
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
    unsafe { instantiate(f, args, Interface::ModelExchange, me) }
}

/// The interface an `fmi3Instantiate*` function asks for.
enum Interface {
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
    interface: Interface,
    me: Option<Hooks<M>>,
) -> fmi3Instance {
    let Instantiation(instance_name, token, resource_path, logging_on, environment, log_message) =
        args;
    let (refusal, note, model_exchange) = match interface {
        Interface::CoSimulation { refusal, note } => (refusal, note, false),
        Interface::ModelExchange => (None, None, true),
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
        let info = match M::describe(&config) {
            Ok(info) => info,
            Err(e) => return fail(format!("invalid variant configuration: {e}")),
        };
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
        match Instance::<M>::new(info, logger) {
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
    environment: fmi3InstanceEnvironment,
    log_message: fmi3LogMessageCallback,
) -> fmi3Instance {
    let _ = guarded(|| {
        let id = M::describe(&Config::new())
            .map(|i| i.model_identifier)
            .unwrap_or_default();
        let sink = CallbackSink {
            log_message,
            environment,
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
    unsafe { free_slot::<M, Layout>(c) }
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

/// An element a value reference of a call names.
#[derive(Debug, Clone, Copy)]
pub(crate) enum Element {
    Time,
    Scalar(u32),
}

/// Expands `vrs` into the elements they name (arrays row-major), checking every reference,
/// its type and that `n_values` is their number.
pub(crate) fn expand<M: FmuModel>(
    slot: &Slot<M>,
    vrs: &[u32],
    expected: VariableType,
    n_values: usize,
) -> Result<Vec<Element>, String> {
    let info = slot.instance.info();
    let mut elements = Vec::with_capacity(n_values);
    for &vr in vrs {
        let (name, actual) = match slot.extra.target(vr) {
            None => {
                return Err(format!(
                    "unknown value reference {vr} ({} has value references 0 to {})",
                    info.model_identifier,
                    slot.extra.max_value_reference()
                ))
            }
            Some(Target::Time) => {
                elements.push(Element::Time);
                ("time", VariableType::Real)
            }
            Some(Target::Variable(v)) => {
                elements.extend(v.indices().map(|i| Element::Scalar(i as u32)));
                (v.name.as_str(), info.variables[v.first].variable_type())
            }
        };
        if actual != expected {
            return Err(format!(
                "variable `{name}` (value reference {vr}) is of type {}, not {}",
                type_name(actual),
                type_name(expected)
            ));
        }
    }
    if elements.len() != n_values {
        return Err(format!(
            "nValues = {n_values}, but the {} value references name {} values",
            vrs.len(),
            elements.len()
        ));
    }
    Ok(elements)
}

/// The scalar indices among `elements`.
fn scalars(elements: &[Element]) -> Vec<u32> {
    elements
        .iter()
        .filter_map(|e| match e {
            Element::Scalar(i) => Some(*i),
            Element::Time => None,
        })
        .collect()
}

/// Reads the values `elements` name (after the instance computed what it must).
fn read_values<M: FmuModel>(
    slot: &mut Slot<M>,
    f: &Function,
    elements: &[Element],
    expected: VariableType,
) -> Result<(Vec<Value>, Status), Status> {
    let indices = scalars(elements);
    let mut got = Vec::with_capacity(indices.len());
    let status = slot
        .instance
        .get_values(f, &indices, expected, |_, v| got.push(v.clone()));
    if status > Status::Warning {
        return Err(status);
    }
    let time = slot.instance.time();
    let mut scalars = got.into_iter();
    let values: Vec<Value> = elements
        .iter()
        .map(|e| match e {
            Element::Time => Value::Real(time),
            Element::Scalar(_) => scalars.next().unwrap_or(Value::Real(f64::NAN)),
        })
        .collect();
    for (value, element) in values.iter().zip(elements) {
        if let (Value::Real(x), Element::Scalar(i)) = (value, element) {
            if !x.is_finite() {
                let name = &slot.instance.info().variables[*i as usize].name;
                return Err(slot.instance.reject(
                    f,
                    &format!("variable `{name}` is {x}: a non-finite value is never returned"),
                ));
            }
        }
    }
    Ok((values, status))
}

/// The FMI 3.0 types exchanged through `fmi3Get*`/`fmi3Set*` (the shared value kinds of
/// [`crate::front`]): `fmi3Float64`, `fmi3Int32`, `fmi3Boolean`.
pub use crate::front::{Boolean, Integer as Int32, Real as Float64};

/// A get call: checks the pointers and the references, reads the values `vr` name (arrays
/// row-major; `n_values` of them) and hands them to `write` unless the read failed.
///
/// # Safety
/// FMI pointer contract.
#[allow(clippy::too_many_arguments)]
unsafe fn get_call<M: FmuModel>(
    c: fmi3Instance,
    f: &Function,
    vr: *const fmi3ValueReference,
    nvr: usize,
    out_is_null: bool,
    n_values: usize,
    expected: VariableType,
    write: impl FnOnce(&mut Slot<M>, &[Value]),
) -> fmi3Status {
    unsafe {
        with_instance::<M>(c, f, |s| {
            let Some(vrs) = slice(vr, nvr) else {
                return s.instance.reject(f, "valueReferences is NULL");
            };
            if n_values > 0 && out_is_null {
                return s.instance.reject(f, "values is NULL");
            }
            let elements = match expand(s, vrs, expected, n_values) {
                Ok(e) => e,
                Err(message) => return s.instance.reject(f, &message),
            };
            match read_values(s, f, &elements, expected) {
                Ok((values, status)) => {
                    write(s, &values);
                    status
                }
                Err(status) => status,
            }
        })
    }
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
    let null = out.is_null();
    unsafe {
        get_call::<M>(c, K::GET, vr, nvr, null, n_values, K::TYPE, |_, values| {
            for (i, v) in values.iter().enumerate() {
                // SAFETY: `out` holds `n_values` elements (FMI contract) and
                // `values.len() == n_values` (checked by `expand`).
                *out.add(i) = K::to_c(v);
            }
        })
    }
}

/// Checks a set call's references and values, then hands them to the instance.
fn write_values<M: FmuModel>(
    slot: &mut Slot<M>,
    f: &Function,
    vrs: &[u32],
    expected: VariableType,
    values: Vec<Value>,
) -> Status {
    let elements = match expand(slot, vrs, expected, values.len()) {
        Ok(e) => e,
        Err(message) => return slot.instance.reject(f, &message),
    };
    if elements.iter().any(|e| matches!(e, Element::Time)) {
        return slot.instance.reject(
            f,
            "variable `time` (value reference 0) is the independent variable: the master sets it through fmi3EnterInitializationMode and fmi3DoStep",
        );
    }
    slot.instance.set_values(f, &scalars(&elements), values)
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
            let values = raw.iter().map(|v| K::from_c(*v)).collect();
            write_values(s, f, vrs, K::TYPE, values)
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
        get_call::<M>(
            c,
            f,
            vr,
            nvr,
            null,
            n_values,
            VariableType::String,
            |s, values| {
                // SAFETY: `out` holds `n_values` slots, the number of `values`.
                s.return_strings(values, out)
            },
        )
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
                Ok(texts) => write_values(s, f, vrs, VariableType::String, texts),
                Err(status) => status,
            }
        })
    }
}

front::state_functions!(fmi3Instance, fmi3FMUState, fmi3Byte, Layout, "FMUState");

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
