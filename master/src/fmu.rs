//! Loading an FMI 2.0 Co-Simulation FMU on rust-fmi, with the checks a master owes its user.
//!
//! Before rust-fmi unpacks an archive, [`FmuFile::open`] reads it and rejects, naming the file:
//! an entry whose path would leave the unpack directory, a model description that is not
//! FMI 2.0 or declares no Co-Simulation interface, a missing `binaries/linux64/<id>.so`. The
//! GUID is checked by the FMU itself in `fmi2Instantiate`; when instantiation fails, the error
//! quotes what the FMU logged. Variables are indexed by name once, here, so the simulation can
//! work with value references only.

use crate::logging::LogKey;
use crate::xml::Tag;
use fmi::fmi2::import::Fmi2Import;
use fmi::fmi2::instance::InstanceCS;
use fmi::schema::fmi2::{
    Causality as SchemaCausality, ScalarVariableElement, Variability as SchemaVariability,
};
use std::collections::HashMap;
use std::io::Read;
use std::path::{Path, PathBuf};

/// What can go wrong when loading or instantiating an FMU.
#[derive(Debug, thiserror::Error)]
pub enum LoadError {
    #[error("{file}: cannot read the FMU archive: {reason}")]
    Archive { file: PathBuf, reason: String },
    #[error("{file}: archive entry `{entry}` would unpack outside the FMU's directory; refusing to load it")]
    UnsafeEntry { file: PathBuf, entry: String },
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
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum VarType {
    Real,
    Integer,
    Boolean,
    String,
    Enumeration,
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

fn archive_error(file: &Path, reason: impl ToString) -> LoadError {
    LoadError::Archive {
        file: file.to_path_buf(),
        reason: reason.to_string(),
    }
}

impl FmuFile {
    /// Opens, checks and imports `path`.
    pub fn open(path: &Path) -> Result<Self, LoadError> {
        let file = std::fs::File::open(path).map_err(|e| archive_error(path, e))?;
        let mut archive = zip::ZipArchive::new(file).map_err(|e| archive_error(path, e))?;
        let mut names = Vec::new();
        for i in 0..archive.len() {
            let entry = archive.by_index(i).map_err(|e| archive_error(path, e))?;
            let name = entry
                .name()
                .map_err(|e| archive_error(path, e))?
                .to_string();
            if entry.enclosed_name().is_none() {
                return Err(LoadError::UnsafeEntry {
                    file: path.to_path_buf(),
                    entry: name,
                });
            }
            names.push(name);
        }
        let mut xml = String::new();
        archive
            .by_name("modelDescription.xml")
            .map_err(|_| LoadError::NoModelDescription {
                file: path.to_path_buf(),
            })?
            .read_to_string(&mut xml)
            .map_err(|e| archive_error(path, e))?;
        let md: fmi::schema::fmi2::Fmi2ModelDescription =
            xml.parse()
                .map_err(|e: fmi::schema::Error| LoadError::ModelDescription {
                    file: path.to_path_buf(),
                    reason: e.to_string(),
                })?;
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
        let expected = format!("binaries/{PLATFORM}/{}.so", cs.model_identifier);
        if !names.iter().any(|n| n == &expected) {
            let found: Vec<&str> = names
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
        let dependencies =
            output_dependencies(&xml).map_err(|reason| LoadError::ModelDescription {
                file: path.to_path_buf(),
                reason,
            })?;
        let units = variable_units(&xml).map_err(|reason| LoadError::ModelDescription {
            file: path.to_path_buf(),
            reason,
        })?;
        let mut variables = Vec::with_capacity(md.model_variables.variables.len());
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
            variables.push(VariableInfo {
                name: v.name.clone(),
                value_reference: v.value_reference,
                var_type,
                causality,
                fixed,
                start,
                unit: units.get(i).cloned().flatten(),
                description: v.description.clone(),
                dependencies: dependencies
                    .get(&(i + 1))
                    .cloned()
                    .unwrap_or(None)
                    .map(|deps| deps.into_iter().map(|d| d - 1).collect()),
            });
        }
        let by_name = variables
            .iter()
            .enumerate()
            .map(|(i, v)| (v.name.clone(), i))
            .collect();
        let import: Fmi2Import = fmi::import::from_path(path).map_err(|e| LoadError::Import {
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

/// `ModelStructure/Outputs`: for each output's 1-based index, its 1-based dependencies, or
/// `None` when the attribute is absent (rust-fmi's schema cannot tell absent from empty).
fn output_dependencies(xml: &str) -> Result<HashMap<usize, Option<Vec<usize>>>, String> {
    let mut in_outputs = false;
    let mut map = HashMap::new();
    for tag in crate::xml::tags(xml) {
        match tag? {
            Tag::Start {
                element: e,
                empty: false,
            } if e.name().as_ref() == "Outputs" => in_outputs = true,
            Tag::End(e) if e.name().as_ref() == "Outputs" => in_outputs = false,
            Tag::Start { element: e, .. } if in_outputs && e.name().as_ref() == "Unknown" => {
                let mut index = None;
                let mut deps = None;
                for a in e.attributes().flatten() {
                    let value = a.value.to_string();
                    match a.key.as_ref() {
                        "index" => index = value.trim().parse::<usize>().ok(),
                        "dependencies" => {
                            deps = Some(
                                value
                                    .split_whitespace()
                                    .map(|d| d.parse::<usize>().map_err(|e| e.to_string()))
                                    .collect::<Result<Vec<_>, _>>()?,
                            )
                        }
                        _ => {}
                    }
                }
                if let Some(i) = index {
                    map.insert(i, deps);
                }
            }
            _ => {}
        }
    }
    Ok(map)
}

/// The unit of every `ScalarVariable`, in file order: its own `unit` attribute, else that of
/// its `declaredType` (rust-fmi's schema does not keep a variable's unit).
fn variable_units(xml: &str) -> Result<Vec<Option<String>>, String> {
    let attribute = |e: &quick_xml::events::BytesStart, key: &str| -> Option<String> {
        e.attributes()
            .flatten()
            .find(|a| a.key.as_ref() == key)
            .and_then(|a| {
                a.normalized_value(quick_xml::XmlVersion::Implicit1_0)
                    .ok()
                    .map(|v| v.to_string())
            })
    };
    let mut type_units: HashMap<String, String> = HashMap::new();
    let mut simple_type: Option<String> = None;
    let mut in_variable = false;
    // (own unit, declared type) per variable.
    let mut declared: Vec<(Option<String>, Option<String>)> = Vec::new();
    for tag in crate::xml::tags(xml) {
        match tag? {
            Tag::End(e) => match e.name().as_ref() {
                "SimpleType" => simple_type = None,
                "ScalarVariable" => in_variable = false,
                _ => {}
            },
            Tag::Start { element: e, empty } => match e.name().as_ref() {
                "SimpleType" if !empty => simple_type = attribute(&e, "name"),
                "ScalarVariable" => {
                    declared.push((None, None));
                    in_variable = !empty;
                }
                "Real" | "Integer" | "Enumeration" => {
                    if let Some(name) = &simple_type {
                        if let Some(unit) = attribute(&e, "unit") {
                            type_units.insert(name.clone(), unit);
                        }
                    } else if in_variable {
                        if let Some(last) = declared.last_mut() {
                            *last = (attribute(&e, "unit"), attribute(&e, "declaredType"));
                        }
                    }
                }
                _ => {}
            },
        }
    }
    Ok(declared
        .into_iter()
        .map(|(unit, declared_type)| {
            unit.or_else(|| declared_type.and_then(|t| type_units.get(&t).cloned()))
        })
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn output_dependencies_tell_absent_from_empty() {
        let xml = r#"<a><ModelStructure><Outputs>
            <Unknown index="2" dependencies=""/>
            <Unknown index="3" dependencies="1 4"/>
            <Unknown index="5"/>
        </Outputs></ModelStructure></a>"#;
        let d = output_dependencies(xml).unwrap();
        assert_eq!(d[&2], Some(vec![]));
        assert_eq!(d[&3], Some(vec![1, 4]));
        assert_eq!(d[&5], None);
    }

    #[test]
    fn units_come_from_the_variable_or_its_declared_type() {
        let xml = r#"<fmiModelDescription>
            <TypeDefinitions>
              <SimpleType name="Length"><Real quantity="Length" unit="m"/></SimpleType>
            </TypeDefinitions>
            <ModelVariables>
              <ScalarVariable name="x" valueReference="0"><Real declaredType="Length"/></ScalarVariable>
              <ScalarVariable name="F" valueReference="1"><Real unit="N" declaredType="Length"/></ScalarVariable>
              <ScalarVariable name="n" valueReference="2"><Integer/></ScalarVariable>
              <ScalarVariable name="v" valueReference="3"><Real unit="m/s"/></ScalarVariable>
            </ModelVariables></fmiModelDescription>"#;
        assert_eq!(
            variable_units(xml).unwrap(),
            vec![Some("m".into()), Some("N".into()), None, Some("m/s".into())]
        );
    }
}
