//! Loading an FMI 2.0 Co-Simulation FMU on rust-fmi, with the checks a master owes its user.
//!
//! [`FmuFile::open`] unpacks the archive itself ([`archive`]) into a fresh temporary folder,
//! refusing entries that could reach outside it (absolute or `..` names, symbolic links,
//! anything but plain files and folders) and archives beyond the [`LoadLimits`]. It then
//! rejects, naming the file: a model description that is not FMI 2.0 or declares no
//! Co-Simulation interface, ambiguous variables or `ModelStructure` ([`checks`]), a missing
//! `binaries/linux64/<id>.so`, a library for another platform or one that lacks an fmi2
//! function ([`binary`]). Only then is the folder handed to rust-fmi. On any error the folder
//! is removed. The GUID is checked by the FMU itself in `fmi2Instantiate`; when instantiation
//! fails, the error quotes what the FMU logged. Variables are indexed by name once, here, so
//! the simulation can work with value references only.

mod archive;
pub mod binary;
mod checks;
mod xml;

use crate::logging::LogKey;
use fmi::fmi2::import::Fmi2Import;
use fmi::fmi2::instance::InstanceCS;
use fmi::schema::fmi2::{
    Causality as SchemaCausality, ScalarVariableElement, Variability as SchemaVariability,
};
use fmi::traits::FmiImport;
use std::collections::HashMap;
use std::path::{Path, PathBuf};

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
    #[error("{file}: fmiVersion is `{version}`; this master runs FMI 2.0 FMUs")]
    NotFmi2 { file: PathBuf, version: String },
    #[error("{file}: `{model}` is not a Co-Simulation FMU (its modelDescription.xml has no <CoSimulation> element)")]
    NotCoSimulation { file: PathBuf, model: String },
    #[error("{file}: the FMU has no binary for this platform: `{expected}` is missing (it has: {found})")]
    MissingBinary {
        file: PathBuf,
        expected: String,
        found: String,
    },
    #[error("{file}: `{library}` is {found}; this master needs {expected} (platform folder `{PLATFORM}`)")]
    WrongBinary {
        file: PathBuf,
        library: String,
        found: String,
        expected: String,
    },
    #[error("{file}: `{library}` does not export {}, which every FMI 2.0 Co-Simulation FMU must provide", .missing.join(", "))]
    MissingFunctions {
        file: PathBuf,
        library: String,
        missing: Vec<String>,
    },
    #[error("{file}: rust-fmi could not import the FMU: {reason}")]
    Import { file: PathBuf, reason: String },
    #[error("instance `{instance}` of {file}: fmi2Instantiate failed{log}")]
    Instantiate {
        instance: String,
        file: PathBuf,
        log: String,
    },
}

/// The FMI type of a variable.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum VarType {
    Real,
    Integer,
    Boolean,
    String,
    Enumeration,
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

    /// The type's element name in a model description (`Real`, `Integer`, …).
    pub fn name(self) -> &'static str {
        match self {
            VarType::Real => "Real",
            VarType::Integer => "Integer",
            VarType::Boolean => "Boolean",
            VarType::String => "String",
            VarType::Enumeration => "Enumeration",
        }
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
}

/// One variable of a loaded FMU.
#[derive(Debug, Clone, PartialEq)]
pub struct VariableInfo {
    pub name: String,
    pub value_reference: u32,
    pub var_type: VarType,
    pub causality: Causality,
    /// `variability="fixed"` or `"constant"`.
    pub fixed: bool,
    /// Start value of a Real/Integer/Boolean variable, as f64.
    pub start: Option<f64>,
    /// The unit (`unit` of the variable, or of its declared type), e.g. `m`.
    pub unit: Option<String>,
    /// The model description's `description` of the variable.
    pub description: Option<String>,
    /// For outputs: indices (into [`FmuFile::variables`]) of the inputs it depends on directly;
    /// `None` when the model description does not say (taken as: depends on every input).
    pub dependencies: Option<Vec<usize>>,
}

/// A loaded FMU: its archive, its rust-fmi import and its variables indexed by name.
pub struct FmuFile {
    pub path: PathBuf,
    pub import: Fmi2Import,
    pub model_name: String,
    pub model_identifier: String,
    pub guid: String,
    pub variables: Vec<VariableInfo>,
    by_name: HashMap<String, usize>,
}

impl std::fmt::Debug for FmuFile {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "FmuFile({})", self.path.display())
    }
}

/// The platform folder of FMI 2.0 binaries on this machine.
pub const PLATFORM: &str = "linux64";

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

    /// Opens, checks and imports `path`.
    pub fn open_with(path: &Path, options: &LoadOptions) -> Result<Self, LoadError> {
        let temp_root = options.temp_dir.clone().unwrap_or_else(std::env::temp_dir);
        // From here on, returning drops `unpacked.dir`, which removes the folder.
        let unpacked = archive::unpack(path, &options.limits, &temp_root)?;
        let xml = &unpacked.model_description;
        let md: fmi::schema::fmi2::Fmi2ModelDescription = xml
            .parse()
            .map_err(|e: fmi::schema::Error| md_error(path, e))?;
        if !md.fmi_version.starts_with("2.") {
            return Err(LoadError::NotFmi2 {
                file: path.to_path_buf(),
                version: md.fmi_version.clone(),
            });
        }
        let Some(cs) = md.co_simulation.as_ref() else {
            return Err(LoadError::NotCoSimulation {
                file: path.to_path_buf(),
                model: md.model_name.clone(),
            });
        };
        let xml::VariableExtras { units, has_start } =
            xml::variable_extras(xml).map_err(|e| md_error(path, e))?;
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
                name: v.name.clone(),
                value_reference: v.value_reference,
                var_type,
                causality,
                fixed,
                start,
                unit: units.get(i).cloned().flatten(),
                description: v.description.clone(),
                dependencies: None,
            });
        }
        checks::variables(&variables, &has_start, &constant).map_err(|e| md_error(path, e))?;
        let dependencies =
            checks::model_structure(&variables, &structure).map_err(|e| md_error(path, e))?;
        for (i, deps) in dependencies {
            variables[i].dependencies = deps;
        }
        let expected = format!("binaries/{PLATFORM}/{}.so", cs.model_identifier);
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
        match binary::check(&library) {
            Ok(()) => {}
            Err(binary::LibraryProblem::WrongKind { found, expected: e }) => {
                return Err(LoadError::WrongBinary {
                    file: path.to_path_buf(),
                    library: expected,
                    found,
                    expected: e,
                })
            }
            Err(binary::LibraryProblem::MissingFunctions(missing)) => {
                return Err(LoadError::MissingFunctions {
                    file: path.to_path_buf(),
                    library: expected,
                    missing: missing.into_iter().map(String::from).collect(),
                })
            }
        }
        drop(library);
        let by_name = variables
            .iter()
            .enumerate()
            .map(|(i, v)| (v.name.clone(), i))
            .collect();
        let import = Fmi2Import::new(unpacked.dir, xml).map_err(|e| LoadError::Import {
            file: path.to_path_buf(),
            reason: e.to_string(),
        })?;
        Ok(Self {
            path: path.to_path_buf(),
            model_name: md.model_name.clone(),
            model_identifier: cs.model_identifier.clone(),
            guid: md.guid.clone(),
            import,
            variables,
            by_name,
        })
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
    /// [`crate::logging`]). On failure the error quotes what the FMU logged.
    pub fn instantiate(
        &self,
        instance: &str,
        logging_on: bool,
    ) -> Result<(InstanceCS, LogKey), LoadError> {
        let key = LogKey::new(instance);
        match self
            .import
            .instantiate_cs(key.instance_name(), false, logging_on)
        {
            Ok(cs) => Ok((cs, key)),
            Err(e) => {
                let said = key.recent_messages();
                let log = if said.is_empty() {
                    format!(" ({e})")
                } else {
                    format!(": {}", said.join("; "))
                };
                Err(LoadError::Instantiate {
                    instance: instance.to_string(),
                    file: self.path.clone(),
                    log,
                })
            }
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
