//! The one instantiation routine of both fronts (`fmi2Instantiate`,
//! `fmi3InstantiateCoSimulation`, `fmi3InstantiateModelExchange`): the instance name, the
//! front's own refusal, the variant configuration (from `resources/variant.cfg`), the GUID
//! (FMI 3.0's instantiation token is the same GUID), the interface asked for, then the
//! instance in its slot. A front reads its C arguments into a [`Request`]; every decision and
//! every message is here, once.
//!
//! Only an FMU whose GUID is that of the default configuration may go without a variant
//! configuration; any other failure to read it is an error that names the file (or the
//! resource location) and the reason.

use super::slot::Slot;
use crate::description::{Config, ModelInfo, CONFIG_FILE};
use crate::guard::guarded;
use crate::instance::{interface, Instance, LogSink, Logger};
use crate::model::{FmuModel, Hooks};
use crate::types::Status;
use crate::uri::resource_path;
use std::os::raw::c_void;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// How a version names what instantiation is given, in its messages.
pub struct Spelling {
    /// The GUID argument: `GUID` (FMI 2.0), `instantiationToken` (FMI 3.0).
    pub token: &'static str,
    /// The resources argument: `fmuResourceLocation` (a URI), `resourcePath` (a path).
    pub resources: &'static str,
}

/// FMI 2.0's names.
pub const FMI2: Spelling = Spelling {
    token: "GUID",
    resources: "fmuResourceLocation",
};
/// FMI 3.0's names.
pub const FMI3: Spelling = Spelling {
    token: "instantiationToken",
    resources: "resourcePath",
};

/// Where the resources are: FMI 2.0 gives a `file:` URI, FMI 3.0 a path (each NULL or empty
/// when not given).
pub enum Resources {
    /// `fmuResourceLocation`.
    Uri(Option<String>),
    /// `resourcePath`.
    Path(Option<String>),
}

/// What a front's instantiate function was asked, its C arguments read.
pub struct Request {
    /// The C function (`fmi2Instantiate`, …), for the messages.
    pub function: &'static str,
    /// The version's names of the arguments.
    pub spelling: &'static Spelling,
    /// `instanceName`.
    pub name: Option<String>,
    /// `GUID` / `instantiationToken`.
    pub token: Option<String>,
    /// Where the resources are.
    pub resources: Resources,
    /// `loggingOn`.
    pub logging_on: bool,
    /// Whether the master asks for Model Exchange (else Co-Simulation).
    pub model_exchange: bool,
    /// Why the front refuses its own arguments (an `fmuType` that is neither interface,
    /// `eventModeUsed` …), checked right after the name.
    pub refusal: Option<String>,
    /// What to log (`logEvents`) when the instance is created.
    pub note: Option<&'static str>,
}

/// Instantiates `M` as `request` asks, with the model's Model Exchange functions `me`, and
/// boxes the instance with the front's data `extra` as a handle; NULL (the reason logged
/// through `sink`) when it cannot. Panics are caught: NULL.
pub fn instantiate<M: FmuModel, X>(
    request: impl FnOnce() -> Request,
    sink: impl Fn() -> Box<dyn LogSink>,
    me: Option<Hooks<M>>,
    extra: X,
) -> *mut c_void {
    guarded(|| match create::<M>(request(), &sink, me) {
        Some(instance) => Slot::new(instance, extra).into_handle(),
        None => std::ptr::null_mut(),
    })
    .unwrap_or(std::ptr::null_mut())
}

/// The instance `request` asks for; `None` (logged) when it cannot be made.
fn create<M: FmuModel>(
    request: Request,
    sink: &dyn Fn() -> Box<dyn LogSink>,
    me: Option<Hooks<M>>,
) -> Option<Instance<M>> {
    let function = request.function;
    let logger = Logger::new(
        request.name.as_deref().unwrap_or("?"),
        sink(),
        request.logging_on,
    );
    let fail = |message: String| {
        logger.error(&format!("{function}: {message}"));
        None
    };
    if request.name.as_deref().is_none_or(str::is_empty) {
        return fail("instanceName must be a non-empty string".into());
    }
    if let Some(refusal) = request.refusal {
        return fail(refusal);
    }
    let given = request.token.unwrap_or_default();
    let config = match variant_config::<M>(&given, request.spelling, &request.resources) {
        Ok(config) => config,
        Err(message) => return fail(message),
    };
    let interface = match interface::<M>(&config) {
        Ok(interface) => interface,
        Err(e) => return fail(format!("invalid variant configuration: {e}")),
    };
    let info = &interface.info;
    if given != info.guid {
        return fail(format!(
            "{} mismatch: the modelDescription.xml gives {given} but this binary of {} implements {} (the binary and the XML come from different builds or variants)",
            request.spelling.token, info.model_identifier, info.guid
        ));
    }
    let offered = me.filter(|_| info.model_exchange.is_some());
    if request.model_exchange && offered.is_none() {
        return fail(format!(
            "{} is a Co-Simulation FMU only: it does not implement Model Exchange",
            info.model_identifier
        ));
    }
    if let Some(note) = request.note {
        logger.log(Status::Ok, "logEvents", &format!("{function}: {note}"));
    }
    let resources = match located(&request.resources) {
        Some(Ok(dir)) => Some(dir),
        _ => None,
    };
    match Instance::<M>::with_resources(Arc::clone(&interface), logger, resources) {
        Ok(instance) => Some(match offered.filter(|_| request.model_exchange) {
            Some(hooks) => instance.into_model_exchange(hooks),
            None => instance.with_hooks(me),
        }),
        Err(e) => {
            // The logger moved into the failed constructor call; report through a new one.
            Logger::new("?", sink(), true).error(&format!("{function}: {e}"));
            None
        }
    }
}

/// The variant configuration of an instantiation whose GUID is `given`, read from
/// `resources/variant.cfg`; `Err` with the message when it cannot be read, or is missing
/// and `given` is not the GUID of the default configuration.
fn variant_config<M: FmuModel>(
    given: &str,
    spelling: &Spelling,
    resources: &Resources,
) -> Result<Config, String> {
    let default = interface::<M>(&Config::new()).ok();
    let default = default.as_ref().map(|i| &i.info);
    if default.is_some_and(|info| info.guid == given) {
        // the default configuration needs no file; one that is there is still read
        return match located(resources) {
            Some(Ok(dir)) => match read_config(&dir)? {
                ConfigFile::Found(config) => Ok(config),
                ConfigFile::Missing(_) => Ok(Config::new()),
            },
            _ => Ok(Config::new()),
        };
    }
    let reason = match located(resources) {
        Some(Ok(dir)) => match read_config(&dir)? {
            ConfigFile::Found(config) => return Ok(config),
            ConfigFile::Missing(e) => format!(
                "the variant configuration {} cannot be read: {e}",
                dir.join(CONFIG_FILE).display()
            ),
        },
        Some(Err((location, e))) => format!(
            "resources/{CONFIG_FILE} cannot be located: {} `{location}`: {e}",
            spelling.resources
        ),
        None => format!(
            "no {} is given to read resources/{CONFIG_FILE} from",
            spelling.resources
        ),
    };
    Err(without_config(default, given, spelling, &reason))
}

/// Why an instantiation whose GUID is not the default configuration's found no variant
/// configuration.
fn without_config(
    default: Option<&ModelInfo>,
    given: &str,
    spelling: &Spelling,
    reason: &str,
) -> String {
    let (id, guid) = default.map_or(("this FMU", "?"), |i| {
        (i.model_identifier.as_str(), i.guid.as_str())
    });
    let token = spelling.token;
    format!(
        "{token} mismatch or missing variant configuration: the modelDescription.xml gives {given}, not the {token} {guid} of {id} without a variant configuration, and {reason}"
    )
}

/// The resources directory: `None` when none is given, `Err` (the location and why) when a
/// URI names no local directory.
fn located(resources: &Resources) -> Option<Result<PathBuf, (String, String)>> {
    match resources {
        Resources::Uri(uri) => uri
            .as_deref()
            .filter(|s| !s.is_empty())
            .map(|uri| resource_path(uri).map_err(|e| (uri.to_string(), e.to_string()))),
        Resources::Path(path) => path
            .as_deref()
            .filter(|s| !s.is_empty())
            .map(|path| Ok(PathBuf::from(path))),
    }
}

/// What the resources directory holds of a variant configuration.
enum ConfigFile {
    /// `variant.cfg`, parsed.
    Found(Config),
    /// No `variant.cfg` (the error that says so).
    Missing(std::io::Error),
}

/// The variant configuration in the resources directory `dir`; `Err` with the message if it
/// cannot be read or parsed.
fn read_config(dir: &Path) -> Result<ConfigFile, String> {
    let path = dir.join(CONFIG_FILE);
    match std::fs::read_to_string(&path) {
        Ok(text) => Config::parse(&text)
            .map(ConfigFile::Found)
            .map_err(|e| format!("cannot read {}: {e}", path.display())),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(ConfigFile::Missing(e)),
        Err(e) => Err(format!(
            "cannot read the variant configuration {}: {e}",
            path.display()
        )),
    }
}
