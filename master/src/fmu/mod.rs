//! Loading an FMI 2.0 or FMI 3.0 Co-Simulation FMU on rust-fmi, with the checks a master
//! owes its user.
//!
//! [`FmuFile::open`] unpacks the archive itself ([`archive`]) into a fresh temporary folder,
//! refusing entries that could reach outside it (absolute or `..` names, symbolic links,
//! anything but plain files and folders) and archives beyond the [`LoadLimits`]. It reads
//! `fmiVersion` and then rejects, naming the file: a model description that is neither FMI
//! 2.0 nor 3.0 or declares no Co-Simulation interface (an FMI 3.0 FMU with Scheduled
//! Execution and clocks only is named as such), ambiguous variables or `ModelStructure`
//! ([`checks`], [`v3`]), a missing `binaries/<platform>/<id>.so` (`linux64` for FMI 2.0,
//! `x86_64-linux` for FMI 3.0; on aarch64-linux `aarch64-linux`, on Windows
//! `win64`/`x86_64-windows` and `.dll`: [`PLATFORM`]), a library for another platform or one
//! that lacks a required function ([`binary`]). Only then is the folder handed to rust-fmi. On any error the folder
//! is removed. The GUID (FMI 3.0: instantiation token) is checked by the FMU itself when it
//! is instantiated; when instantiation fails, the error says what the FMU logged
//! ([`crate::logging::LogKey::failure_note`]).
//! Variables are indexed by name once, here, so the simulation can work with value
//! references only; an FMI 3.0 array is indexed as its elements (`x[1,2]`, 1-based,
//! row-major) and as a whole ([`FmuFile::array`]).

#[cfg(feature = "archive")]
mod archive;
pub mod binary;
mod checks;
mod folder;
mod instance;
pub mod me;
#[cfg(feature = "systems")]
mod table;
mod v3;
mod xml;

pub use instance::{CallError, Experiment, Instance, StepEnd, StepProblem};

use crate::logging::LogKey;
use fmi::fmi2::import::Fmi2Import;
use fmi::fmi2::instance::InstanceCS;
use fmi::fmi3::import::Fmi3Import;
use fmi::fmi3::Fmi3Model;
use fmi::schema::fmi2::{
    Causality as SchemaCausality, ScalarVariableElement, Variability as SchemaVariability,
};
use fmi::traits::FmiImport;
use std::collections::HashMap;
use std::path::{Path, PathBuf};

/// The FMI interface an FMU is loaded for: Co-Simulation (the engine steps it with
/// `DoStep`) or Model Exchange (the importer integrates its states, [`crate::model_exchange`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub enum Interface {
    #[default]
    CoSimulation,
    ModelExchange,
}

/// The FMI version of an FMU.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum FmiVersion {
    Fmi2,
    Fmi3,
}

impl FmiVersion {
    /// The name of a call in this version, from its FMI 2.0 name (`fmi2DoStep` →
    /// `fmi3DoStep`; `fmi2SetupExperiment` → `fmi3EnterInitializationMode`, which takes its
    /// arguments in FMI 3.0).
    pub fn call_name(self, fmi2: &'static str) -> &'static str {
        if self == FmiVersion::Fmi2 {
            return fmi2;
        }
        match fmi2 {
            "fmi2SetupExperiment" | "fmi2EnterInitializationMode" => "fmi3EnterInitializationMode",
            "fmi2ExitInitializationMode" => "fmi3ExitInitializationMode",
            "fmi2DoStep" => "fmi3DoStep",
            "fmi2Terminate" => "fmi3Terminate",
            "fmi2Set*" => "fmi3Set*",
            "fmi2Get*" => "fmi3Get*",
            "fmi2Set* (start value)" => "fmi3Set* (start value)",
            "fmi2Get* (initial outputs)" => "fmi3Get* (initial outputs)",
            other => other,
        }
    }

    /// `2.0` or `3.0`.
    pub fn number(self) -> &'static str {
        match self {
            Self::Fmi2 => "2.0",
            Self::Fmi3 => "3.0",
        }
    }

    /// The platform folder of the binaries this machine loads.
    pub fn platform(self) -> &'static str {
        match self {
            Self::Fmi2 => PLATFORM,
            Self::Fmi3 => PLATFORM_3,
        }
    }
}

/// What can go wrong when loading or instantiating an FMU.
#[derive(Debug, thiserror::Error)]
pub enum LoadError {
    #[error("{file}: cannot read the FMU archive: {reason}")]
    Archive { file: PathBuf, reason: String },
    #[error("{file}: not a valid FMU archive (an FMU is a zip file): {reason}")]
    NotZip { file: PathBuf, reason: String },
    #[error("{file}: archive entry `{entry}` is refused because {reason}; the FMU is not loaded")]
    UnsafeEntry {
        file: PathBuf,
        entry: String,
        reason: String,
    },
    #[error("{file}: {what}, beyond the loader's limit of {limit}; the FMU is not loaded")]
    TooLarge {
        file: PathBuf,
        what: String,
        limit: String,
    },
    #[error("{file}: cannot create a temporary folder in {folder}: {reason}")]
    TempDir {
        file: PathBuf,
        folder: PathBuf,
        reason: String,
    },
    #[error("{file}: cannot unpack archive entry `{entry}`: {reason}")]
    Unpack {
        file: PathBuf,
        entry: String,
        reason: String,
    },
    #[error("{file}: no modelDescription.xml in the archive")]
    NoModelDescription { file: PathBuf },
    #[error("{file}: modelDescription.xml: {reason}")]
    ModelDescription { file: PathBuf, reason: String },
    #[error("{file}: fmiVersion is `{version}`; this master runs FMI 2.0 and FMI 3.0 FMUs")]
    NotFmi2 { file: PathBuf, version: String },
    #[error("{file}: `{model}` is not a Co-Simulation FMU (its modelDescription.xml has no <CoSimulation> element{others})")]
    NotCoSimulation {
        file: PathBuf,
        model: String,
        /// What it declares instead, e.g. ": it declares Scheduled Execution (clocks), which this master does not run".
        others: String,
    },
    #[error("{file}: `{model}` is not a Model Exchange FMU (its modelDescription.xml has no <ModelExchange> element)")]
    NotModelExchange { file: PathBuf, model: String },
    #[error("{file}: the FMU has no binary for this platform: `{expected}` is missing (it has: {found})")]
    MissingBinary {
        file: PathBuf,
        expected: String,
        found: String,
    },
    #[error("{file}: `{library}` is {found}; this master needs {expected} (platform folder `{platform}`)")]
    WrongBinary {
        file: PathBuf,
        library: String,
        found: String,
        expected: String,
        platform: &'static str,
    },
    #[error("{file}: `{library}` does not export {}, which every FMI {version} {} FMU must provide", .missing.join(", "), if *.interface == Interface::ModelExchange { "Model Exchange" } else { "Co-Simulation" })]
    MissingFunctions {
        file: PathBuf,
        library: String,
        missing: Vec<String>,
        version: &'static str,
        interface: Interface,
    },
    #[error("{file}: rust-fmi could not import the FMU: {reason}")]
    Import { file: PathBuf, reason: String },
    #[error("instance `{instance}` of {file}: {call} failed{log}")]
    Instantiate {
        instance: String,
        file: PathBuf,
        /// `fmi2Instantiate` or `fmi3InstantiateCoSimulation`.
        call: &'static str,
        log: String,
    },
}

/// The FMI type of a variable. FMI 3.0's `Float64` is [`VarType::Real`] and its `Int32`
/// [`VarType::Integer`] (the same values as FMI 2.0's, so they connect across versions); the
/// other FMI 3.0 types are their own. The engine moves every number as an f64 (an Int64 or
/// UInt64 beyond 2^53 is rounded).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum VarType {
    Real,
    Integer,
    Boolean,
    String,
    Enumeration,
    Float32,
    Int8,
    UInt8,
    Int16,
    UInt16,
    UInt32,
    Int64,
    UInt64,
    Binary,
    Clock,
}

impl VarType {
    /// The type whose values this one's are: an Enumeration is an Integer (FMI 2.0 moves
    /// both through fmi2Get/SetInteger on one value-reference space; SSP names both Integer).
    pub fn base(self) -> VarType {
        match self {
            VarType::Enumeration => VarType::Integer,
            t => t,
        }
    }

    /// The type's element name in an FMI 2.0 model description (`Real`, `Integer`, …; for the
    /// FMI 3.0-only types, their FMI 3.0 name).
    pub fn name(self) -> &'static str {
        match self {
            VarType::Real => "Real",
            VarType::Integer => "Integer",
            VarType::Boolean => "Boolean",
            VarType::String => "String",
            VarType::Enumeration => "Enumeration",
            other => other.name_3(),
        }
    }

    /// The type's element name in an FMI 3.0 model description (`Float64`, `Int32`, …).
    pub fn name_3(self) -> &'static str {
        match self {
            VarType::Real => "Float64",
            VarType::Integer => "Int32",
            VarType::Boolean => "Boolean",
            VarType::String => "String",
            VarType::Enumeration => "Enumeration",
            VarType::Float32 => "Float32",
            VarType::Int8 => "Int8",
            VarType::UInt8 => "UInt8",
            VarType::Int16 => "Int16",
            VarType::UInt16 => "UInt16",
            VarType::UInt32 => "UInt32",
            VarType::Int64 => "Int64",
            VarType::UInt64 => "UInt64",
            VarType::Binary => "Binary",
            VarType::Clock => "Clock",
        }
    }

    /// Whether the engine moves values of this type (numbers and Booleans).
    pub fn is_numeric(self) -> bool {
        !matches!(self, VarType::String | VarType::Binary | VarType::Clock)
    }

    /// Whether values of this type are integers (set rounded).
    pub fn is_integer(self) -> bool {
        !matches!(
            self,
            VarType::Real
                | VarType::Float32
                | VarType::Boolean
                | VarType::String
                | VarType::Binary
                | VarType::Clock
        )
    }
}

/// `causality` of a variable.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Causality {
    Parameter,
    CalculatedParameter,
    Input,
    Output,
    Local,
    Independent,
    /// FMI 3.0: a parameter that may change array dimensions (only in configuration mode,
    /// which this master does not use: its start value is taken).
    StructuralParameter,
}

impl Causality {
    /// The causality as a model description writes it.
    pub fn name(self) -> &'static str {
        match self {
            Causality::Parameter => "parameter",
            Causality::CalculatedParameter => "calculatedParameter",
            Causality::Input => "input",
            Causality::Output => "output",
            Causality::Local => "local",
            Causality::Independent => "independent",
            Causality::StructuralParameter => "structuralParameter",
        }
    }
}

/// What a scalar variable and an array variable alike declare: the name, the value
/// reference, the type and the causality.
#[derive(Debug, Clone, PartialEq)]
pub struct VariableHead {
    pub name: String,
    pub value_reference: u32,
    pub var_type: VarType,
    pub causality: Causality,
}

/// One variable of a loaded FMU.
#[derive(Debug, Clone, PartialEq)]
pub struct VariableInfo {
    pub head: VariableHead,
    /// `variability="fixed"` or `"constant"`.
    pub fixed: bool,
    /// Start value of a Real/Integer/Boolean variable, as f64.
    pub start: Option<f64>,
    /// The unit (`unit` of the variable, or of its declared type), e.g. `m`.
    pub unit: Option<String>,
    /// The values it may take (`min`, `max` of the variable, or of its declared type).
    pub range: Range,
    /// The model description's `description` of the variable.
    pub description: Option<String>,
    /// For outputs: indices (into [`FmuFile::variables`]) of the inputs it depends on directly;
    /// `None` when the model description does not say (taken as: depends on every input).
    pub dependencies: Option<Vec<usize>>,
    /// For an element of an FMI 3.0 array: (index into [`FmuFile::arrays`], position of the
    /// element among the array's values, row-major).
    pub element: Option<(usize, usize)>,
}

/// A numeric variable's declared `min` and `max` (FMI 2.0 §2.2.7, FMI 3.0 §2.4.7.4): the
/// values an FMU accepts for it and promises for it; either may be absent (no bound).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Range {
    pub min: Option<f64>,
    pub max: Option<f64>,
}

impl Range {
    /// `value` moved to the nearest bound when it lies outside the range: the projection
    /// onto [min, max].
    pub fn clamp(&self, value: f64) -> f64 {
        let above_min = self.min.map_or(value, |min| value.max(min));
        self.max.map_or(above_min, |max| above_min.min(max))
    }
}

/// An FMI 3.0 array variable: its elements are variables of their own (`x[1,2]`).
#[derive(Debug, Clone, PartialEq)]
pub struct ArrayInfo {
    pub head: VariableHead,
    /// The dimensions (a structural parameter's start value where one gives it).
    pub dimensions: Vec<usize>,
    /// Indices (into [`FmuFile::variables`]) of the elements, row-major.
    pub elements: Vec<usize>,
}

/// The rust-fmi import of an FMU, by version.
pub enum Import {
    Fmi2(Fmi2Import),
    Fmi3(Fmi3Import),
    /// None: a data instance's table, read by the engine ([`FmuFile::is_table`]).
    Table,
}

/// A loaded FMU: its archive, its rust-fmi import and its variables indexed by name.
pub struct FmuFile {
    pub path: PathBuf,
    pub version: FmiVersion,
    /// The interface it is loaded for (its `model_identifier` is that interface's).
    pub interface: Interface,
    pub import: Import,
    pub model_name: String,
    pub model_identifier: String,
    /// The GUID (FMI 2.0) or instantiation token (FMI 3.0).
    pub guid: String,
    /// Every scalar variable, and every element of every array variable.
    pub variables: Vec<VariableInfo>,
    /// The FMI 3.0 array variables (none for FMI 2.0).
    pub arrays: Vec<ArrayInfo>,
    /// An FMI 3.0 Co-Simulation FMU whose `<CoSimulation>` declares `hasEventMode="true"`:
    /// it is instantiated with `eventModeUsed = true` and the master runs its event
    /// iterations (FMI 3.0 §4.2; see [`Instance::do_step`]). False for FMI 2.0, for Model
    /// Exchange and for data tables.
    pub event_mode: bool,
    by_name: HashMap<String, usize>,
    arrays_by_name: HashMap<String, usize>,
}

impl std::fmt::Debug for FmuFile {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "FmuFile({})", self.path.display())
    }
}

/// The platform folder of FMI 2.0 binaries and the platform tuple of FMI 3.0 binaries on
/// this machine (FMI 3.0 §2.5.1.1): `linux64`/`x86_64-linux`, `win64`/`x86_64-windows`, or
/// `aarch64-linux` for both (the folder of FMPy, the FMI cross-check and `spurio package`;
/// FMI 2.0 names no folder for Linux on AArch64).
#[cfg(not(any(windows, all(target_os = "linux", target_arch = "aarch64"))))]
const PLATFORMS: (&str, &str) = ("linux64", "x86_64-linux");
#[cfg(windows)]
const PLATFORMS: (&str, &str) = ("win64", "x86_64-windows");
#[cfg(all(target_os = "linux", target_arch = "aarch64"))]
const PLATFORMS: (&str, &str) = ("aarch64-linux", "aarch64-linux");

/// The platform folder of FMI 2.0 binaries on this machine (the first of the pair above).
pub const PLATFORM: &str = PLATFORMS.0;
/// The platform tuple of FMI 3.0 binaries on this machine (the second of the pair above).
pub const PLATFORM_3: &str = PLATFORMS.1;

/// Where rust-fmi loads an FMI 2.0 binary from, when that is not [`PLATFORM`]: on Linux on
/// AArch64 it reads `binaries/linux64/`, so the loader puts the `aarch64-linux` binary there
/// in its own copy of the FMU ([`rust_fmi_place`]).
const RUST_FMI_PLATFORM: Option<&str> = if cfg!(all(target_os = "linux", target_arch = "aarch64")) {
    Some("linux64")
} else {
    None
};

/// How much an FMU archive may hold; beyond it the loader stops with [`LoadError::TooLarge`]
/// naming the file and the limit. Sizes are checked as declared in the archive and again as
/// counted while inflating.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct LoadLimits {
    /// Bytes of all entries together, unpacked (default 2 GiB).
    pub max_unpacked: u64,
    /// Bytes of `modelDescription.xml`, unpacked (default 64 MiB).
    pub max_model_description: u64,
    /// Number of entries in the archive (default 10 000).
    pub max_entries: usize,
}

impl Default for LoadLimits {
    fn default() -> Self {
        Self {
            max_unpacked: 2 << 30,
            max_model_description: 64 << 20,
            max_entries: 10_000,
        }
    }
}

/// How to load an FMU: the limits, and where its temporary folder goes.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct LoadOptions {
    pub limits: LoadLimits,
    /// The folder the FMU is unpacked under (in a fresh `spurio-fmu-*` folder, removed when the
    /// [`FmuFile`] is dropped or loading fails); `None`: the system's temporary folder.
    pub temp_dir: Option<PathBuf>,
}

/// The FMU `path` in a fresh temporary folder: a folder (an FMU already unpacked) is copied,
/// a file is unpacked as a `.fmu` archive (feature `archive`).
fn unpack(
    path: &Path,
    limits: &LoadLimits,
    temp_root: &Path,
) -> Result<folder::Unpacked, LoadError> {
    if path.is_dir() {
        return folder::copy(path, limits, temp_root);
    }
    #[cfg(feature = "archive")]
    return archive::unpack(path, limits, temp_root);
    #[cfg(not(feature = "archive"))]
    Err(LoadError::Archive {
        file: path.to_path_buf(),
        reason: "this build opens FMUs unpacked into a folder only (without the `archive` feature)"
            .into(),
    })
}

fn md_error(file: &Path, reason: impl ToString) -> LoadError {
    LoadError::ModelDescription {
        file: file.to_path_buf(),
        reason: reason.to_string(),
    }
}

impl FmuFile {
    /// Opens, checks and imports `path` with the default [`LoadOptions`].
    pub fn open(path: &Path) -> Result<Self, LoadError> {
        Self::open_with(path, &LoadOptions::default())
    }

    /// Opens, checks and imports `path` for Co-Simulation.
    pub fn open_with(path: &Path, options: &LoadOptions) -> Result<Self, LoadError> {
        Self::open_for(path, options, Interface::CoSimulation)
    }

    /// Opens `path` for `interface` when one is asked, else for Co-Simulation when the FMU
    /// offers it and for Model Exchange otherwise (an FMU that offers neither is refused
    /// with the Co-Simulation error, which says what it declares).
    pub fn open_preferring(
        path: &Path,
        options: &LoadOptions,
        interface: Option<Interface>,
    ) -> Result<Self, LoadError> {
        if let Some(interface) = interface {
            return Self::open_for(path, options, interface);
        }
        match Self::open_for(path, options, Interface::CoSimulation) {
            Err(e @ LoadError::NotCoSimulation { .. }) => {
                Self::open_for(path, options, Interface::ModelExchange).map_err(|_| e)
            }
            other => other,
        }
    }

    /// Opens, checks and imports `path` for `interface` (an FMU that does not offer it is
    /// refused, naming the interface).
    pub fn open_for(
        path: &Path,
        options: &LoadOptions,
        interface: Interface,
    ) -> Result<Self, LoadError> {
        let temp_root = options.temp_dir.clone().unwrap_or_else(std::env::temp_dir);
        // From here on, returning drops `unpacked.dir`, which removes the folder.
        let unpacked = unpack(path, &options.limits, &temp_root)?;
        let version = fmi_version(&unpacked.model_description).map_err(|e| md_error(path, e))?;
        if version.starts_with("3.") {
            return Self::open_3(path, unpacked, interface);
        }
        if !version.starts_with("2.") {
            return Err(LoadError::NotFmi2 {
                file: path.to_path_buf(),
                version,
            });
        }
        let xml = &unpacked.model_description;
        // Well-formed to the end first, so ill-formed XML is said with its line.
        for tag in crate::xml::tags(xml) {
            tag.map_err(|e| md_error(path, e))?;
        }
        let md: fmi::schema::fmi2::Fmi2ModelDescription =
            xml.parse().map_err(|e: fmi::schema::Error| {
                md_error(
                    path,
                    match xml::fmi3_shape(xml) {
                        Some(why) => format!(
                            "fmiVersion is `{version}`, but the description is FMI 3.0: {why}; \
                             correct fmiVersion to 3.0"
                        ),
                        None => xml::schema_error(&e),
                    },
                )
            })?;
        let model_identifier = match interface {
            Interface::CoSimulation => md.co_simulation.as_ref().map(|i| &i.model_identifier),
            Interface::ModelExchange => md.model_exchange.as_ref().map(|i| &i.model_identifier),
        };
        let Some(model_identifier) = model_identifier.cloned() else {
            return Err(not_offered(path, interface, &md.model_name, String::new()));
        };
        let xml::VariableExtras {
            units,
            ranges,
            has_start,
        } = xml::variable_extras(xml).map_err(|e| md_error(path, e))?;
        let structure = xml::model_structure(xml).map_err(|e| md_error(path, e))?;
        let mut variables = Vec::with_capacity(md.model_variables.variables.len());
        let mut constant = Vec::with_capacity(md.model_variables.variables.len());
        for (i, v) in md.model_variables.variables.iter().enumerate() {
            let (var_type, start) = match &v.elem {
                ScalarVariableElement::Real(r) => (VarType::Real, r.start),
                ScalarVariableElement::Integer(r) => (VarType::Integer, r.start.map(f64::from)),
                ScalarVariableElement::Boolean(r) => {
                    (VarType::Boolean, r.start.map(|b| if b { 1.0 } else { 0.0 }))
                }
                ScalarVariableElement::String => (VarType::String, None),
                ScalarVariableElement::Enumeration => (VarType::Enumeration, None),
            };
            let causality = match v.causality {
                SchemaCausality::Parameter => Causality::Parameter,
                SchemaCausality::CalculatedParameter => Causality::CalculatedParameter,
                SchemaCausality::Input => Causality::Input,
                SchemaCausality::Output => Causality::Output,
                SchemaCausality::Independent => Causality::Independent,
                _ => Causality::Local,
            };
            let fixed = matches!(
                v.variability,
                Some(SchemaVariability::Fixed) | Some(SchemaVariability::Constant)
            );
            constant.push(matches!(v.variability, Some(SchemaVariability::Constant)));
            variables.push(VariableInfo {
                head: VariableHead {
                    name: v.name.clone(),
                    value_reference: v.value_reference,
                    var_type,
                    causality,
                },
                fixed,
                start,
                unit: units.get(i).cloned().flatten(),
                range: ranges.get(i).copied().unwrap_or_default(),
                description: v.description.clone(),
                dependencies: None,
                element: None,
            });
        }
        checks::variables(&variables, &has_start, &constant).map_err(|e| md_error(path, e))?;
        let dependencies =
            checks::model_structure(&variables, &structure).map_err(|e| md_error(path, e))?;
        for (i, deps) in dependencies {
            variables[i].dependencies = deps;
        }
        check_library(
            path,
            &unpacked,
            FmiVersion::Fmi2,
            interface,
            &model_identifier,
        )?;
        rust_fmi_place(path, &unpacked, &model_identifier)?;
        let by_name = variables
            .iter()
            .enumerate()
            .map(|(i, v)| (v.head.name.clone(), i))
            .collect();
        let import = Fmi2Import::new(unpacked.dir, xml).map_err(|e| LoadError::Import {
            file: path.to_path_buf(),
            reason: e.to_string(),
        })?;
        Ok(Self {
            path: path.to_path_buf(),
            version: FmiVersion::Fmi2,
            interface,
            model_name: md.model_name.clone(),
            model_identifier,
            guid: md.guid.clone(),
            import: Import::Fmi2(import),
            variables,
            arrays: Vec::new(),
            event_mode: false,
            by_name,
            arrays_by_name: HashMap::new(),
        })
    }

    /// The FMI 3.0 half of [`FmuFile::open_with`].
    fn open_3(
        path: &Path,
        unpacked: folder::Unpacked,
        interface: Interface,
    ) -> Result<Self, LoadError> {
        let xml = &unpacked.model_description;
        let d = v3::read(xml).map_err(|e| md_error(path, e))?;
        if interface == Interface::ModelExchange && d.model_exchange.is_none() {
            return Err(not_offered(path, interface, &d.model_name, String::new()));
        }
        let offered = match interface {
            Interface::CoSimulation => d.co_simulation.clone(),
            Interface::ModelExchange => d.model_exchange.clone(),
        };
        let Some(model_identifier) = offered else {
            let others = if d.other_interfaces.is_empty() {
                String::new()
            } else {
                format!(
                    "; it declares {} only, which this master does not run{}",
                    d.other_interfaces.join(" and "),
                    if d.other_interfaces.contains(&"Scheduled Execution") {
                        " (Scheduled Execution and clocks)"
                    } else {
                        ""
                    }
                )
            };
            return Err(LoadError::NotCoSimulation {
                file: path.to_path_buf(),
                model: d.model_name,
                others,
            });
        };
        check_library(
            path,
            &unpacked,
            FmiVersion::Fmi3,
            interface,
            &model_identifier,
        )?;
        let mut by_name: HashMap<String, usize> = d
            .variables
            .iter()
            .enumerate()
            .map(|(i, v)| (v.head.name.clone(), i))
            .collect();
        by_name.extend(d.aliases.iter().cloned());
        let arrays_by_name = d
            .arrays
            .iter()
            .enumerate()
            .map(|(i, a)| (a.head.name.clone(), i))
            .collect();
        resource_path_workaround(path, &unpacked)?;
        // rust-fmi 0.8's FMI 3.0 schema refuses attributes the standard allows (`unit`,
        // `quantity`, `nominal` … on variables): it gets only what instantiation needs, the
        // full description having been read and checked here (v3).
        let minimal = format!(
            r#"<?xml version="1.0" encoding="UTF-8"?><fmiModelDescription fmiVersion="{}" modelName="{}" instantiationToken="{}"><{} modelIdentifier="{}"/><ModelVariables/><ModelStructure/></fmiModelDescription>"#,
            quick_xml::escape::escape(d.version.as_str()),
            quick_xml::escape::escape(d.model_name.as_str()),
            quick_xml::escape::escape(d.instantiation_token.as_str()),
            match interface {
                Interface::CoSimulation => "CoSimulation",
                Interface::ModelExchange => "ModelExchange",
            },
            quick_xml::escape::escape(model_identifier.as_str()),
        );
        let import = Fmi3Import::new(unpacked.dir, &minimal).map_err(|e| LoadError::Import {
            file: path.to_path_buf(),
            reason: e.to_string(),
        })?;
        Ok(Self {
            path: path.to_path_buf(),
            version: FmiVersion::Fmi3,
            interface,
            model_name: d.model_name,
            model_identifier,
            guid: d.instantiation_token,
            import: Import::Fmi3(import),
            variables: d.variables,
            arrays: d.arrays,
            event_mode: interface == Interface::CoSimulation && d.co_simulation_event_mode,
            by_name,
            arrays_by_name,
        })
    }

    /// The FMI 3.0 array variable called `name` (whole).
    pub fn array(&self, name: &str) -> Option<&ArrayInfo> {
        self.arrays_by_name.get(name).map(|&i| &self.arrays[i])
    }

    /// The variable called `name`.
    pub fn variable(&self, name: &str) -> Option<&VariableInfo> {
        self.by_name.get(name).map(|&i| &self.variables[i])
    }

    /// Index of the variable called `name`.
    pub fn index_of(&self, name: &str) -> Option<usize> {
        self.by_name.get(name).copied()
    }

    /// A Co-Simulation instance called `instance`, created on the calling thread (rust-fmi
    /// instances are `!Send`), with the key its log messages are kept under (see
    /// [`crate::logging`]). An FMI 3.0 instance is created with `eventModeUsed` as its
    /// `hasEventMode` ([`FmuFile::event_mode`]; if the FMU refuses it, again without), without
    /// early return or intermediate update. On failure the error says what the FMU logged.
    pub fn instantiate(&self, instance: &str, logging_on: bool) -> Result<Instance, LoadError> {
        let key = LogKey::new(instance);
        let mut event_mode_used = self.event_mode;
        let (created, call) = match &self.import {
            Import::Fmi2(import) => (
                import
                    .instantiate_cs(key.instance_name(), false, logging_on)
                    .map(|i| CsInstance::Fmi2(Box::new(i))),
                "fmi2Instantiate",
            ),
            Import::Fmi3(import) => {
                let create = |event_mode: bool| {
                    crate::logging::speaking(&key, || {
                        import.instantiate_cs(
                            key.instance_name(),
                            false,
                            logging_on,
                            event_mode,
                            false,
                            &[],
                        )
                    })
                };
                let mut created = create(event_mode_used);
                if created.is_err() && event_mode_used {
                    // Some FMUs declare hasEventMode="true" and yet refuse eventModeUsed =
                    // true (the Reference FMU Roberts: "Event Mode is not supported"): they
                    // run without event mode, handling their events inside fmi3DoStep.
                    log::warn!(
                        "instance `{instance}` ({}): fmi3InstantiateCoSimulation with \
                         eventModeUsed = true failed although the FMU declares \
                         hasEventMode=\"true\"; instantiated without event mode",
                        self.path.display()
                    );
                    event_mode_used = false;
                    created = create(false);
                }
                (
                    created.map(|i| CsInstance::Fmi3(Box::new(i))),
                    "fmi3InstantiateCoSimulation",
                )
            }
            Import::Table => {
                return Err(LoadError::Instantiate {
                    instance: instance.to_string(),
                    file: self.path.clone(),
                    call: "fmi2Instantiate",
                    log: " (a data table is read by the engine, not instantiated)".into(),
                })
            }
        };
        match created {
            Ok(CsInstance::Fmi2(cs)) => Ok(Instance::fmi2(*cs, key)),
            Ok(CsInstance::Fmi3(cs)) => Ok(Instance::fmi3(*cs, key, event_mode_used)),
            Err(e) => Err(LoadError::Instantiate {
                instance: instance.to_string(),
                file: self.path.clone(),
                call,
                log: key.failed_call(e),
            }),
        }
    }
}

/// The error for an FMU that does not offer `interface`.
fn not_offered(path: &Path, interface: Interface, model: &str, others: String) -> LoadError {
    match interface {
        Interface::CoSimulation => LoadError::NotCoSimulation {
            file: path.to_path_buf(),
            model: model.to_string(),
            others,
        },
        Interface::ModelExchange => LoadError::NotModelExchange {
            file: path.to_path_buf(),
            model: model.to_string(),
        },
    }
}

/// A rust-fmi instance of either FMI version: `F2` the FMI 2.0 type, `F3` the FMI 3.0 one
/// (Co-Simulation: [`CsInstance`]; Model Exchange: the [`me`] module's), boxed.
pub(crate) enum Versioned<F2, F3> {
    Fmi2(Box<F2>),
    Fmi3(Box<F3>),
}

/// A rust-fmi Co-Simulation instance of either version.
type CsInstance = Versioned<InstanceCS, fmi::fmi3::instance::InstanceCS>;

/// rust-fmi 0.8 passes FMI 3.0's `resourcePath` without the trailing separator the standard
/// requires (`…/resources`, not `…/resources/`), so an FMU that appends a file name to it
/// (`resourcePath + "y.txt"`, as the Reference FMU `Resource` does) looks for
/// `…/resourcesy.txt`. Until rust-fmi passes the separator, every entry `resources/<e>` is
/// also made reachable as `resources<e>` beside it (a hard link for a file, falling back to
/// a copy; a symbolic link for a folder), inside the FMU's own temporary folder. An FMU that
/// joins the path with a separator itself is not affected.
fn resource_path_workaround(path: &Path, unpacked: &folder::Unpacked) -> Result<(), LoadError> {
    let dir = unpacked.dir.path();
    let Ok(entries) = std::fs::read_dir(dir.join("resources")) else {
        return Ok(());
    };
    let fail = |entry: &str, e: std::io::Error| LoadError::Unpack {
        file: path.to_path_buf(),
        entry: format!("resources/{entry} (made reachable as resources{entry})"),
        reason: e.to_string(),
    };
    for entry in entries.flatten() {
        let name = entry.file_name().to_string_lossy().into_owned();
        let target = dir.join(format!("resources{name}"));
        if target.exists() {
            continue;
        }
        let source = entry.path();
        if source.is_dir() {
            #[cfg(unix)]
            std::os::unix::fs::symlink(&source, &target).map_err(|e| fail(&name, e))?;
        } else if std::fs::hard_link(&source, &target).is_err() {
            std::fs::copy(&source, &target).map_err(|e| fail(&name, e))?;
        }
    }
    Ok(())
}

/// The `fmiVersion` attribute of a model description's root element.
fn fmi_version(xml: &str) -> Result<String, String> {
    for tag in crate::xml::tags(xml) {
        if let crate::xml::Tag::Start { element, .. } = tag? {
            if element.name().as_ref() == "fmiModelDescription" {
                return element
                    .attributes()
                    .flatten()
                    .find(|a| a.key.as_ref() == "fmiVersion")
                    .map(|a| a.value.to_string())
                    .ok_or_else(|| "<fmiModelDescription> has no fmiVersion".to_string());
            }
        }
    }
    Err("no <fmiModelDescription> element".into())
}

/// Copies the FMI 2.0 binary of [`PLATFORM`] to the folder rust-fmi loads it from
/// ([`RUST_FMI_PLATFORM`]), in the loader's own copy of the FMU, where the two differ.
fn rust_fmi_place(
    path: &Path,
    unpacked: &folder::Unpacked,
    model_identifier: &str,
) -> Result<(), LoadError> {
    let Some(folder) = RUST_FMI_PLATFORM else {
        return Ok(());
    };
    let name = format!("{model_identifier}{}", std::env::consts::DLL_SUFFIX);
    let binaries = unpacked.dir.path().join("binaries");
    let to = binaries.join(folder);
    std::fs::create_dir_all(&to)
        .and_then(|()| std::fs::copy(binaries.join(PLATFORM).join(&name), to.join(&name)))
        .map(|_| ())
        .map_err(|e| LoadError::Unpack {
            file: path.to_path_buf(),
            entry: format!("binaries/{folder}/{name}"),
            reason: e.to_string(),
        })
}

/// Checks that the archive holds this platform's library of `model_identifier` and that it
/// is a library this process loads, exporting every function the version requires.
fn check_library(
    path: &Path,
    unpacked: &folder::Unpacked,
    version: FmiVersion,
    interface: Interface,
    model_identifier: &str,
) -> Result<(), LoadError> {
    let platform = version.platform();
    let expected = format!(
        "binaries/{platform}/{model_identifier}{}",
        std::env::consts::DLL_SUFFIX
    );
    if !unpacked.names.iter().any(|n| n == &expected) {
        let found: Vec<&str> = unpacked
            .names
            .iter()
            .filter(|n| n.starts_with("binaries/"))
            .map(|n| n.as_str())
            .collect();
        return Err(LoadError::MissingBinary {
            file: path.to_path_buf(),
            expected,
            found: if found.is_empty() {
                "no binaries at all".into()
            } else {
                found.join(", ")
            },
        });
    }
    let library =
        std::fs::read(unpacked.dir.path().join(&expected)).map_err(|e| LoadError::Unpack {
            file: path.to_path_buf(),
            entry: expected.clone(),
            reason: e.to_string(),
        })?;
    let model_exchange;
    let required: &[&'static str] = match (version, interface) {
        (FmiVersion::Fmi2, Interface::CoSimulation) => &binary::REQUIRED_FUNCTIONS,
        (FmiVersion::Fmi3, Interface::CoSimulation) => &binary::REQUIRED_FUNCTIONS_3,
        (_, Interface::ModelExchange) => {
            model_exchange = binary::required_model_exchange(version == FmiVersion::Fmi3);
            &model_exchange
        }
    };
    match binary::check(&library, required) {
        Ok(()) => Ok(()),
        Err(binary::LibraryProblem::WrongKind { found, expected: e }) => {
            Err(LoadError::WrongBinary {
                file: path.to_path_buf(),
                library: expected,
                found,
                expected: e,
                platform,
            })
        }
        Err(binary::LibraryProblem::MissingFunctions(missing)) => {
            Err(LoadError::MissingFunctions {
                file: path.to_path_buf(),
                library: expected,
                missing: missing.into_iter().map(String::from).collect(),
                version: version.number(),
                interface,
            })
        }
    }
}

/// Whether an instance whose `fmi2DoStep` returned `fmi2Discard` asks to end the simulation:
/// `Some(last successful time)` when `fmi2GetBooleanStatus(fmi2Terminated)` says so (the time
/// from `fmi2GetRealStatus(fmi2LastSuccessfulTime)`, `None` if the FMU does not give it),
/// `None` when it does not ask or cannot say (the discard is then an error).
///
/// rust-fmi's `pending_status()` always returns "" (it reads into a constant), so only the
/// boolean and real status calls are used here.
pub fn termination_requested(instance: &mut InstanceCS) -> Option<Option<f64>> {
    use fmi::fmi2::instance::CoSimulation;
    match instance.terminated() {
        Ok(true) => Some(
            instance
                .last_successful_time()
                .ok()
                .filter(|t| t.is_finite()),
        ),
        _ => None,
    }
}
