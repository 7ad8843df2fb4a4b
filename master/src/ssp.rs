//! SSP 1.0 and 2.0: export a system as `<name>.ssp` (`SystemStructure.ssd` + the FMUs under
//! `resources/`) and import one back, so the same system runs in OMSimulator, fmpy's SSP
//! runner or this master.
//!
//! Both versions share the standard's namespaces (`http://ssp-standard.org/SSP1/...`) and,
//! in what is written here, differ only by the `version` attributes of the SSD and of the
//! parameter sets. Connectors and parameters are written as `Real`/`Integer`/`Boolean`/
//! `String`, which both schemas define: SSP 2.0 adds the sized types (`Float64`, `Int32`,
//! …), which are read, but OMSimulator 3.x's command line refuses a `Float64` connector
//! ("Failed to import connector … with type \"\"") and its own Python API writes `Real` in
//! SSP 2.0 files too. A connector of an FMI 3.0-only type is written with its own type in
//! SSP 2.0 (`Float32`, `Int8`, …); SSP 1.0 does not have them, so there it is written as the
//! SSP 1.0 type that holds every value (`Float32` → `Real`; `Int8`, `UInt8`, `Int16`,
//! `UInt16` → `Integer`), and an SSP 1.0 export with a connector no SSP 1.0 type holds
//! (`UInt32`, `Int64`, `UInt64`) is refused, naming it and `--ssp-version 2.0`
//! ([`connector_type`]).
//!
//! A component run with Model Exchange (integrated by this master) carries the SSP 1.0
//! attribute `implementation="ModelExchange"` (and one chosen for Co-Simulation
//! `implementation="CoSimulation"`); the import reads it as the instance's `interface`
//! (`any` or none: Co-Simulation when the FMU offers it). Its solver settings, for which SSP
//! has no place, go into the `org.spurio.simulation` annotation with the step multiples
//! (`solver`, `tolerance`, `maxStep`); another tool's SSP runs it with the defaults.
//!
//! Start values go into inline `ssv:ParameterSet`s of each component's `ParameterBindings`.
//! The standard has no place for a fixed step size, so the export writes it twice:
//! - on the system, OpenModelica's `org.openmodelica` annotation with an
//!   `oms:FixedStepMaster` (OMSimulator's fixed-step master, `stepSize`): with it
//!   `OMSimulator x.ssp --stopTime <stop>` runs the file (OMSimulator takes neither the
//!   `DefaultExperiment`'s stop time nor, without this annotation, a step size);
//! - on the `DefaultExperiment`, an `org.spurio.simulation` annotation with the step size,
//!   the algorithm, the recorded variables, the step multiples and the Model Exchange
//!   instances' solver settings.
//!
//! The import takes the step size from the first of: `org.spurio.simulation` `stepSize`,
//! `oms:FixedStepMaster` `stepSize` (OMSimulator 2.x and this export),
//! `oms:SimulationInformation` `stepSize` (a solver written by OMSimulator 3.x's Python
//! API), `osp:FixedStepAlgorithm` `baseStepSize` (the Open Simulation Platform's
//! `DefaultExperiment` annotation); with none of them it uses (stopTime − startTime)/100 and
//! says so in [`Imported::notes`].

use crate::description::{AlgorithmName, InstanceDescription, InterfaceName, SystemDescription};
use crate::fmu::{Causality, FmuFile, LoadLimits, VarType};
use crate::xml::Tag;
use quick_xml::events::{BytesDecl, Event};
use quick_xml::Writer;
use std::collections::BTreeMap;
use std::io::{Read, Write};
use std::path::{Path, PathBuf};

/// Errors of SSP import and export, naming the file.
#[derive(Debug, thiserror::Error)]
pub enum SspError {
    #[error("{file}: {reason}")]
    File { file: PathBuf, reason: String },
}

fn err(file: &Path, reason: impl ToString) -> SspError {
    SspError::File {
        file: file.to_path_buf(),
        reason: reason.to_string(),
    }
}

const ANNOTATION: &str = "org.spurio.simulation";
const OPENMODELICA: &str = "org.openmodelica";
const OMS_NAMESPACE: &str =
    "https://raw.githubusercontent.com/OpenModelica/OMSimulator/master/schema/oms.xsd";

/// The SSP version of a written file.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum SspVersion {
    /// SSP 1.0, the default: what every tool reads (fmpy's SSP runner reads 1.x only).
    #[default]
    V1_0,
    /// SSP 2.0, what OMSimulator 3.x writes.
    V2_0,
}

impl SspVersion {
    /// `1.0` or `2.0`, as in the files' `version` attributes.
    pub fn as_str(self) -> &'static str {
        match self {
            Self::V1_0 => "1.0",
            Self::V2_0 => "2.0",
        }
    }
}

impl std::fmt::Display for SspVersion {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.as_str())
    }
}

impl std::str::FromStr for SspVersion {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s.trim() {
            "1.0" | "1" => Ok(Self::V1_0),
            "2.0" | "2" => Ok(Self::V2_0),
            other => Err(format!("SSP version `{other}`: 1.0 and 2.0 are supported")),
        }
    }
}

/// An imported SSD: the system and what the import had to assume.
#[derive(Debug, Clone, PartialEq)]
pub struct Imported {
    pub description: SystemDescription,
    /// The SSD's `version` attribute.
    pub version: String,
    /// Where the step size came from (or which default was chosen), for the user.
    pub notes: Vec<String>,
}

/// `d` with every FMI 3.0 array parameter given whole (a TOML array) written as its elements
/// (`B[1,1]`, …, row-major): an SSP parameter is a scalar.
fn with_array_parameters_expanded(d: &SystemDescription, fmus: &[&FmuFile]) -> SystemDescription {
    let mut d = d.clone();
    for (inst, fmu) in d.instances.iter_mut().zip(fmus) {
        let mut parameters = BTreeMap::new();
        for (name, value) in std::mem::take(&mut inst.parameters) {
            match (&value, fmu.index_of(&name), fmu.array(&name)) {
                (toml::Value::Array(_), None, Some(array)) => {
                    let mut values = Vec::new();
                    flatten(&value, &mut values);
                    for (&e, v) in array.elements.iter().zip(values) {
                        parameters.insert(fmu.variables[e].head.name.clone(), v);
                    }
                }
                _ => {
                    parameters.insert(name, value);
                }
            }
        }
        inst.parameters = parameters;
    }
    d
}

/// The values of a TOML array, nested arrays flattened in order (a scalar: itself).
pub(crate) fn flatten(value: &toml::Value, out: &mut Vec<toml::Value>) {
    match value {
        toml::Value::Array(items) => items.iter().for_each(|v| flatten(v, out)),
        other => out.push(other.clone()),
    }
}

/// The SSP connector kind and type of variable `name` of `fmu` (None: not a connector). An
/// FMI 3.0 array element is a connector named as the master names it (`y[2]`, 1-based,
/// row-major), a whole array one named by the array (`y`).
fn connector(fmu: &FmuFile, name: &str) -> Option<(&'static str, VarType)> {
    let (causality, var_type) = match fmu.variable(name) {
        Some(v) => (v.head.causality, v.head.var_type),
        None => fmu
            .array(name)
            .map(|a| (a.head.causality, a.head.var_type))?,
    };
    let kind = match causality {
        Causality::Input => "input",
        Causality::Output => "output",
        Causality::Parameter => "parameter",
        Causality::CalculatedParameter => "calculatedParameter",
        _ => return None,
    };
    Some((kind, var_type))
}

/// The SSP type element (`ssc:<name>`) of a connector of FMI type `ty` in SSP `version`.
/// SSP 2.0 has every FMI type (an Enumeration written as Integer). SSP 1.0 has `Real`,
/// `Integer` (32 bits), `Boolean`, `String`, `Enumeration` and `Binary`: an FMI 3.0 type
/// goes to the one that holds all its values (`Float32` → `Real`; `Int8`, `UInt8`, `Int16`,
/// `UInt16` → `Integer`), and one that none holds (`UInt32`, `Int64`, `UInt64`, `Clock`)
/// has no SSP 1.0 type: None.
pub fn connector_type(ty: VarType, version: SspVersion) -> Option<&'static str> {
    match version {
        SspVersion::V2_0 => Some(ty.base().name()),
        SspVersion::V1_0 => match ty.base() {
            VarType::Real | VarType::Float32 => Some("Real"),
            VarType::Integer
            | VarType::Int8
            | VarType::UInt8
            | VarType::Int16
            | VarType::UInt16 => Some("Integer"),
            VarType::Boolean => Some("Boolean"),
            VarType::String => Some("String"),
            VarType::Binary => Some("Binary"),
            _ => None,
        },
    }
}

/// The `ssc:` element of connector `name` (type `ty`) of component `component` in SSP
/// `version`, or the reason it has none, with the fix.
fn connector_element(
    component: &str,
    name: &str,
    ty: VarType,
    version: SspVersion,
) -> std::io::Result<String> {
    connector_type(ty, version)
        .map(|t| format!("ssc:{t}"))
        .ok_or_else(|| {
            std::io::Error::new(
                std::io::ErrorKind::InvalidInput,
                format!(
                    "component `{component}`, connector `{name}`: its type {} has no lossless \
                     SSP {version} type (SSP {version} has Real, Integer of 32 bits, Boolean, \
                     String, Enumeration, Binary); export SSP 2.0 instead (`spurio ssp-export \
                     … --ssp-version 2.0`)",
                    ty.name_3()
                ),
            )
        })
}

/// The `SystemStructure.ssd` text (SSP `version`) for `d`, written with quick-xml (which
/// escapes every attribute); `connectors[i]` are instance i's (name, kind, type),
/// `sources[i]` the archive path of its FMU. A connector whose type SSP `version` does not
/// have (see [`connector_type`]) is an error (`InvalidInput`) naming the component, the
/// connector, its type and the fix.
pub fn ssd_text(
    d: &SystemDescription,
    connectors: &[Vec<(String, &'static str, VarType)>],
    sources: &[String],
    version: SspVersion,
) -> Result<String, std::io::Error> {
    let name = if d.name.is_empty() {
        "system"
    } else {
        d.name.as_str()
    };
    let mut w = Writer::new_with_indent(Vec::new(), b' ', 2);
    w.write_event(Event::Decl(BytesDecl::new("1.0", Some("UTF-8"), None)))?;
    let root = [
        (
            "xmlns:ssc",
            "http://ssp-standard.org/SSP1/SystemStructureCommon",
        ),
        (
            "xmlns:ssd",
            "http://ssp-standard.org/SSP1/SystemStructureDescription",
        ),
        (
            "xmlns:ssv",
            "http://ssp-standard.org/SSP1/SystemStructureParameterValues",
        ),
        ("xmlns:oms", OMS_NAMESPACE),
        ("version", version.as_str()),
        ("name", name),
        ("generationTool", "spurio"),
    ];
    element(&mut w, "ssd:SystemStructureDescription", &root, |w| {
        element(w, "ssd:System", &[("name", name)], |w| {
            element(w, "ssd:Elements", &[], |w| {
                for (i, inst) in d.instances.iter().enumerate() {
                    component(w, inst, &connectors[i], &sources[i], version)?;
                }
                Ok(())
            })?;
            if !d.connections.is_empty() {
                element(w, "ssd:Connections", &[], |w| {
                    for c in &d.connections {
                        let Some((from, to)) = c.split_once("->") else {
                            continue;
                        };
                        let (Some((fe, fc)), Some((te, tc))) =
                            (from.trim().split_once('.'), to.trim().split_once('.'))
                        else {
                            continue;
                        };
                        let ends = [
                            ("startElement", fe),
                            ("startConnector", fc),
                            ("endElement", te),
                            ("endConnector", tc),
                        ];
                        empty(w, "ssd:Connection", &ends)?;
                    }
                    Ok(())
                })?;
            }
            openmodelica_annotation(w, d)
        })?;
        let (start, stop) = (format!("{:?}", d.start_time), format!("{:?}", d.stop_time));
        let times = [("startTime", start.as_str()), ("stopTime", stop.as_str())];
        element(w, "ssd:DefaultExperiment", &times, |w| {
            element(w, "ssd:Annotations", &[], |w| {
                element(w, "ssc:Annotation", &[("type", ANNOTATION)], |w| {
                    simulation_annotation(w, d)
                })
            })
        })
    })?;
    let mut text = String::from_utf8(w.into_inner()).map_err(std::io::Error::other)?;
    text.push('\n');
    Ok(text)
}

type Xml = Writer<Vec<u8>>;

/// Writes the element `name` with `attributes`, its content written by `content`.
fn element(
    w: &mut Xml,
    name: &str,
    attributes: &[(&str, &str)],
    content: impl FnOnce(&mut Xml) -> std::io::Result<()>,
) -> std::io::Result<()> {
    w.create_element(name)
        .with_attributes(attributes.iter().copied())
        .write_inner_content(content)?;
    Ok(())
}

/// Writes the empty element `name` with `attributes`.
fn empty(w: &mut Xml, name: &str, attributes: &[(&str, &str)]) -> std::io::Result<()> {
    w.create_element(name)
        .with_attributes(attributes.iter().copied())
        .write_empty()?;
    Ok(())
}

/// OpenModelica's fixed-step master annotation of a system: what OMSimulator's command line
/// needs to run the file with a fixed step (`oms-ma`, its master algorithm; the tolerances
/// are those OMSimulator writes itself and do not apply to a fixed-step master).
fn openmodelica_annotation(w: &mut Xml, d: &SystemDescription) -> std::io::Result<()> {
    let step = format!("{:?}", d.step_size);
    let master = [
        ("description", "oms-ma"),
        ("stepSize", step.as_str()),
        ("absoluteTolerance", "0.0001"),
        ("relativeTolerance", "0.0001"),
    ];
    element(w, "ssd:Annotations", &[], |w| {
        element(w, "ssc:Annotation", &[("type", OPENMODELICA)], |w| {
            element(w, "oms:Annotations", &[], |w| {
                element(w, "oms:SimulationInformation", &[], |w| {
                    empty(w, "oms:FixedStepMaster", &master)
                })
            })
        })
    })
}

fn component(
    w: &mut Xml,
    inst: &InstanceDescription,
    connectors: &[(String, &'static str, VarType)],
    source: &str,
    version: SspVersion,
) -> std::io::Result<()> {
    let mut attributes = vec![
        ("name", inst.name.as_str()),
        ("type", "application/x-fmu-sharedlibrary"),
        ("source", source),
    ];
    // SSP 1.0 §5.3.2: which FMU interface the component is run with.
    match inst.interface {
        Some(InterfaceName::ModelExchange) => attributes.push(("implementation", "ModelExchange")),
        Some(InterfaceName::CoSimulation) => attributes.push(("implementation", "CoSimulation")),
        None => {}
    }
    element(w, "ssd:Component", &attributes, |w| {
        if !connectors.is_empty() {
            element(w, "ssd:Connectors", &[], |w| {
                for (name, kind, ty) in connectors {
                    let ty = connector_element(&inst.name, name, *ty, version)?;
                    let attributes = [("name", name.as_str()), ("kind", *kind)];
                    element(w, "ssd:Connector", &attributes, |w| empty(w, &ty, &[]))?;
                }
                Ok(())
            })?;
        }
        if !inst.parameters.is_empty() {
            element(w, "ssd:ParameterBindings", &[], |w| {
                element(w, "ssd:ParameterBinding", &[], |w| {
                    element(w, "ssd:ParameterValues", &[], |w| {
                        parameter_set(w, inst, version)
                    })
                })
            })?;
        }
        Ok(())
    })
}

fn parameter_set(
    w: &mut Xml,
    inst: &InstanceDescription,
    version: SspVersion,
) -> std::io::Result<()> {
    let attributes = [("version", version.as_str()), ("name", inst.name.as_str())];
    element(w, "ssv:ParameterSet", &attributes, |w| {
        element(w, "ssv:Parameters", &[], |w| {
            for (name, value) in &inst.parameters {
                let (ty, text) = match value {
                    toml::Value::Float(f) => (VarType::Real, format!("{f:?}")),
                    toml::Value::Integer(n) => (VarType::Integer, n.to_string()),
                    toml::Value::Boolean(b) => (VarType::Boolean, b.to_string()),
                    toml::Value::String(s) => (VarType::String, s.clone()),
                    other => (VarType::String, other.to_string()),
                };
                element(w, "ssv:Parameter", &[("name", name.as_str())], |w| {
                    let value = [("value", text.as_str())];
                    empty(w, &format!("ssv:{}", ty.base().name()), &value)
                })?;
            }
            Ok(())
        })
    })
}

/// What SSP has no place for: step size, algorithm, record, step multiples, logging, and a
/// Model Exchange instance's `solver`, `tolerance` and `max_step` (`maxStep`), when given.
fn simulation_annotation(w: &mut Xml, d: &SystemDescription) -> std::io::Result<()> {
    let algorithm = match d.algorithm {
        AlgorithmName::GaussSeidel => "gauss-seidel",
        AlgorithmName::Jacobi => "jacobi",
    };
    let step = format!("{:?}", d.step_size);
    let record = d.record.join(" ");
    let attributes = [
        ("stepSize", step.as_str()),
        ("algorithm", algorithm),
        ("record", record.as_str()),
    ];
    element(w, "Simulation", &attributes, |w| {
        for inst in &d.instances {
            let multiple = inst.step_multiple.to_string();
            let logging = inst.logging.to_string();
            let tolerance = inst.tolerance.map(|t| format!("{t:?}"));
            let max_step = inst.max_step.map(|t| format!("{t:?}"));
            let mut attributes = vec![
                ("name", inst.name.as_str()),
                ("stepMultiple", multiple.as_str()),
                ("logging", logging.as_str()),
            ];
            let solver_keys = [
                ("solver", inst.solver.map(|m| m.name())),
                ("tolerance", tolerance.as_deref()),
                ("maxStep", max_step.as_deref()),
            ];
            attributes.extend(solver_keys.iter().filter_map(|(k, v)| v.map(|v| (*k, v))));
            empty(w, "Instance", &attributes)?;
        }
        Ok(())
    })
}

/// Writes `target` (.ssp, SSP `version`) for the system `d` whose instance i runs `fmus[i]`
/// (loaded from `d.instances[i].fmu`): the SSD, and every FMU under `resources/`. The
/// connectors are the variables used by a connection or a record.
pub fn export(
    d: &SystemDescription,
    fmus: &[&FmuFile],
    target: &Path,
    version: SspVersion,
) -> Result<(), SspError> {
    if fmus.len() != d.instances.len() {
        return Err(err(
            target,
            format!("{} FMUs for {} instances", fmus.len(), d.instances.len()),
        ));
    }
    let expanded = with_array_parameters_expanded(d, fmus);
    let d = &expanded;
    let mut used: Vec<BTreeMap<String, (&'static str, VarType)>> =
        vec![BTreeMap::new(); d.instances.len()];
    let index = |name: &str| d.instances.iter().position(|i| i.name == name);
    let ends = d
        .connections
        .iter()
        .filter_map(|c| c.split_once("->"))
        .flat_map(|(from, to)| [from, to])
        .chain(d.record.iter().map(String::as_str));
    for end in ends {
        if let Some((e, v)) = end.trim().split_once('.') {
            if let Some(i) = index(e) {
                if let Some(k) = connector(fmus[i], v) {
                    used[i].insert(v.to_string(), k);
                }
            }
        }
    }
    let connectors: Vec<Vec<(String, &'static str, VarType)>> = used
        .into_iter()
        .map(|m| m.into_iter().map(|(n, (k, t))| (n, k, t)).collect())
        .collect();
    let mut sources = Vec::new();
    let mut files: BTreeMap<String, PathBuf> = BTreeMap::new();
    for inst in &d.instances {
        let path = &inst.fmu;
        let file_name = path
            .file_name()
            .map(|f| f.to_string_lossy().to_string())
            .ok_or_else(|| err(path, "not a file"))?;
        let source = format!("resources/{file_name}");
        if let Some(previous) = files.get(&source) {
            if previous != path {
                return Err(err(
                    path,
                    format!("two different FMUs are both called {file_name}"),
                ));
            }
        }
        files.insert(source.clone(), path.clone());
        sources.push(source);
    }
    let ssd = ssd_text(d, &connectors, &sources, version).map_err(|e| err(target, e))?;
    let file = std::fs::File::create(target).map_err(|e| err(target, e))?;
    let mut zip = zip::ZipWriter::new(file);
    let options = zip::write::SimpleFileOptions::default()
        .compression_method(zip::CompressionMethod::Deflated);
    zip.start_file("SystemStructure.ssd", options)
        .map_err(|e| err(target, e))?;
    zip.write_all(ssd.as_bytes()).map_err(|e| err(target, e))?;
    for (source, path) in &files {
        let bytes = std::fs::read(path).map_err(|e| err(path, e))?;
        zip.start_file(source.as_str(), options)
            .map_err(|e| err(target, e))?;
        zip.write_all(&bytes).map_err(|e| err(target, e))?;
    }
    zip.finish().map_err(|e| err(target, e))?;
    Ok(())
}

/// Reads `ssp`, extracting its FMUs into `out_dir`, and returns the system description
/// (FMU paths relative to `out_dir`) with the import's notes; within the default
/// [`LoadLimits`] (see [`import_with`]).
pub fn import(ssp: &Path, out_dir: &Path) -> Result<Imported, SspError> {
    import_with(ssp, out_dir, &LoadLimits::default())
}

/// [`import`] within `limits`, the FMU loader's: at most `max_entries` entries,
/// `SystemStructure.ssd` at most `max_model_description` bytes, the FMUs it names at most
/// `max_unpacked` bytes together. Sizes are checked as the archive declares them before
/// anything is inflated, then counted while inflating (a declared size can lie).
pub fn import_with(ssp: &Path, out_dir: &Path, limits: &LoadLimits) -> Result<Imported, SspError> {
    let file = std::fs::File::open(ssp).map_err(|e| err(ssp, e))?;
    let mut archive = zip::ZipArchive::new(file).map_err(|e| err(ssp, e))?;
    if archive.len() > limits.max_entries {
        return Err(err(
            ssp,
            format!(
                "the archive has {} entries, more than the limit of {} (max_entries)",
                archive.len(),
                limits.max_entries
            ),
        ));
    }
    let ssd_limit = limits.max_model_description;
    let ssd_entry = archive
        .by_name("SystemStructure.ssd")
        .map_err(|_| err(ssp, "no SystemStructure.ssd in the archive"))?;
    let ssd_declared = ssd_entry.size();
    let ssd_bytes = read_bounded(ssd_entry, ssd_declared, ssd_limit).map_err(|e| {
        err(
            ssp,
            format!("SystemStructure.ssd: {e} (max_model_description)"),
        )
    })?;
    let ssd = String::from_utf8(ssd_bytes)
        .map_err(|e| err(ssp, format!("SystemStructure.ssd is not UTF-8 text: {e}")))?;
    let mut imported =
        parse_ssd(&ssd).map_err(|e| err(ssp, format!("SystemStructure.ssd: {e}")))?;
    // The FMUs' declared sizes, before any is inflated.
    let mut declared: u64 = 0;
    let mut indices = Vec::with_capacity(imported.description.instances.len());
    for inst in &imported.description.instances {
        let source = inst.fmu.to_string_lossy().to_string();
        let index = archive.index_for_name(&source).ok_or_else(|| {
            err(
                ssp,
                format!(
                    "component `{}`: `{source}` is not in the archive",
                    inst.name
                ),
            )
        })?;
        indices.push(index);
        let entry = archive.by_index_raw(index).map_err(|e| err(ssp, e))?;
        declared = declared.saturating_add(entry.size());
        if declared > limits.max_unpacked {
            return Err(err(
                ssp,
                format!(
                    "its FMUs declare more than {} bytes unpacked (reached at `{source}`, \
                     {} bytes), beyond the limit (max_unpacked); nothing was unpacked",
                    limits.max_unpacked,
                    entry.size()
                ),
            ));
        }
    }
    std::fs::create_dir_all(out_dir).map_err(|e| err(out_dir, e))?;
    let mut written: u64 = 0;
    for (inst, index) in imported.description.instances.iter_mut().zip(indices) {
        let source = inst.fmu.to_string_lossy().to_string();
        let entry = archive.by_index(index).map_err(|e| err(ssp, e))?;
        let Some(relative) = entry.enclosed_name() else {
            return Err(err(
                ssp,
                format!("entry `{source}` would unpack outside the target folder"),
            ));
        };
        let target = out_dir.join(relative);
        if let Some(parent) = target.parent() {
            std::fs::create_dir_all(parent).map_err(|e| err(parent, e))?;
        }
        let mut out = std::fs::File::create(&target).map_err(|e| err(&target, e))?;
        let room = limits.max_unpacked - written.min(limits.max_unpacked);
        let copied = std::io::copy(&mut entry.take(room.saturating_add(1)), &mut out)
            .map_err(|e| err(ssp, format!("`{source}`: {e}")))?;
        written = written.saturating_add(copied);
        if written > limits.max_unpacked {
            drop(out);
            // The partial file is of no use; a failure to remove it changes nothing here.
            let _ = std::fs::remove_file(&target);
            return Err(err(
                ssp,
                format!(
                    "its FMUs inflate to more than {} bytes (at `{source}`, more than its \
                     entry declares), beyond the limit (max_unpacked)",
                    limits.max_unpacked
                ),
            ));
        }
        inst.fmu = PathBuf::from(source);
    }
    Ok(imported)
}

/// The bytes of `entry`, an archive entry that declares `declared` bytes: refused, before
/// anything is inflated, when `declared` is over `limit`, and refused when it inflates to
/// more than `limit` bytes.
pub(crate) fn read_bounded(entry: impl Read, declared: u64, limit: u64) -> Result<Vec<u8>, String> {
    if declared > limit {
        return Err(format!(
            "declares {declared} bytes unpacked, more than the limit of {limit}; not inflated"
        ));
    }
    let mut bytes = Vec::new();
    entry
        .take(limit.saturating_add(1))
        .read_to_end(&mut bytes)
        .map_err(|e| e.to_string())?;
    if bytes.len() as u64 > limit {
        return Err(format!(
            "inflates to more than {limit} bytes (more than it declares, {declared}), \
             beyond the limit"
        ));
    }
    Ok(bytes)
}

fn attr(e: &quick_xml::events::BytesStart, key: &str) -> Option<String> {
    e.attributes()
        .flatten()
        .find(|a| a.key.as_ref() == key || a.key.local_name().as_ref() == key)
        .map(|a| {
            a.normalized_value(quick_xml::XmlVersion::Implicit1_0)
                .map(|v| v.to_string())
                .unwrap_or_default()
        })
}

/// Where an SSD gave the step size.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
enum StepSource {
    /// `org.spurio.simulation` `Simulation stepSize` (this master's export).
    Spurio,
    /// `org.openmodelica` `oms:FixedStepMaster stepSize`.
    OmsFixedStepMaster,
    /// `org.openmodelica` `oms:SimulationInformation stepSize` (OMSimulator 3.x solvers).
    OmsSolver,
    /// `org.open-simulation-platform` `osp:FixedStepAlgorithm baseStepSize`.
    Osp,
}

impl StepSource {
    fn describe(self) -> &'static str {
        match self {
            Self::Spurio => "the org.spurio.simulation annotation (stepSize)",
            Self::OmsFixedStepMaster => "OMSimulator's oms:FixedStepMaster (stepSize)",
            Self::OmsSolver => "OMSimulator's solver, oms:SimulationInformation (stepSize)",
            Self::Osp => "the Open Simulation Platform's osp:FixedStepAlgorithm (baseStepSize)",
        }
    }
}

fn number(e: &quick_xml::events::BytesStart, key: &str) -> Result<Option<f64>, String> {
    attr(e, key)
        .map(|v| {
            v.trim()
                .parse::<f64>()
                .map_err(|_| format!("bad {key} `{v}`"))
        })
        .transpose()
}

/// Parses a `SystemStructure.ssd` of SSP 1.0 or 2.0: the components of the top system (FMUs)
/// with their connectors and inline parameter sets, the connections between them, the
/// default experiment and the step size (see the module documentation for its sources).
pub fn parse_ssd(text: &str) -> Result<Imported, String> {
    let mut d = SystemDescription {
        name: String::new(),
        start_time: 0.0,
        stop_time: 1.0,
        step_size: 0.0,
        algorithm: AlgorithmName::GaussSeidel,
        instances: Vec::new(),
        connections: Vec::new(),
        record: Vec::new(),
    };
    let mut version = String::new();
    let mut steps: Vec<(StepSource, f64)> = Vec::new();
    let mut stop_given = false;
    let mut parameter: Option<String> = None;
    let mut depth_component = false;
    // Depth of `ssd:System` elements: only the top system's components are this system's.
    let mut system_depth = 0usize;
    for tag in crate::xml::tags(text) {
        let (e, is_empty) = match tag? {
            Tag::Start { element, empty } => (element, empty),
            Tag::End(e) => {
                match e.local_name().as_ref() {
                    "Component" => depth_component = false,
                    "Parameter" => parameter = None,
                    "System" => system_depth = system_depth.saturating_sub(1),
                    _ => {}
                }
                continue;
            }
        };
        match e.local_name().as_ref() {
            "SystemStructureDescription" => {
                version = attr(&e, "version").unwrap_or_default();
                if !(version.starts_with("1.") || version.starts_with("2.")) {
                    return Err(format!(
                        "SSP version `{version}` is not supported (1.0 and 2.0 are)"
                    ));
                }
                d.name = attr(&e, "name").unwrap_or_default();
            }
            "System" => {
                if system_depth > 0 {
                    return Err(format!(
                        "nested system `{}`: only a flat system of FMU components is supported",
                        attr(&e, "name").unwrap_or_default()
                    ));
                }
                if !is_empty {
                    system_depth += 1;
                }
            }
            "Component" => {
                depth_component = !is_empty;
                let name = attr(&e, "name").ok_or("a Component has no name")?;
                if let Some(kind) = attr(&e, "type") {
                    if kind != "application/x-fmu-sharedlibrary" {
                        return Err(format!(
                            "component `{name}` is of type `{kind}`; only FMUs \
                             (application/x-fmu-sharedlibrary) are supported"
                        ));
                    }
                }
                let interface = match attr(&e, "implementation").as_deref() {
                    None | Some("any") => None,
                    Some("ModelExchange") => Some(InterfaceName::ModelExchange),
                    Some("CoSimulation") => Some(InterfaceName::CoSimulation),
                    Some(other) => {
                        return Err(format!(
                            "component `{name}` has implementation=\"{other}\"; SSP 1.0 \
                             allows ModelExchange, CoSimulation or any"
                        ))
                    }
                };
                let source = attr(&e, "source")
                    .ok_or_else(|| format!("component `{name}` has no source"))?;
                d.instances.push(InstanceDescription {
                    interface,
                    ..InstanceDescription::new(name, source)
                });
            }
            "ParameterBinding" if depth_component => {
                if let Some(source) = attr(&e, "source") {
                    return Err(format!(
                        "component `{}`: parameter values from a separate file (`{source}`) \
                         are not supported; inline ssv:ParameterSet only",
                        d.instances.last().map(|i| i.name.as_str()).unwrap_or("")
                    ));
                }
            }
            "Parameter" if depth_component => parameter = attr(&e, "name"),
            kind if parameter.is_some() => {
                let value = attr(&e, "value").unwrap_or_default();
                let v = match kind {
                    "Real" | "Float64" | "Float32" => toml::Value::Float(
                        value
                            .trim()
                            .parse()
                            .map_err(|_| format!("bad {kind} `{value}`"))?,
                    ),
                    "Integer" | "Int8" | "UInt8" | "Int16" | "UInt16" | "Int32" | "UInt32"
                    | "Int64" | "UInt64" | "Enumeration" => toml::Value::Integer(
                        value
                            .trim()
                            .parse()
                            .map_err(|_| format!("bad {kind} `{value}`"))?,
                    ),
                    "Boolean" => toml::Value::Boolean(value == "true" || value == "1"),
                    "String" => toml::Value::String(value),
                    _ => continue,
                };
                if let (Some(inst), Some(p)) = (d.instances.last_mut(), parameter.clone()) {
                    inst.parameters.insert(p, v);
                }
            }
            "Connection" => {
                let get = |k| attr(&e, k).ok_or_else(|| format!("a Connection has no {k}"));
                d.connections.push(format!(
                    "{}.{} -> {}.{}",
                    get("startElement")?,
                    get("startConnector")?,
                    get("endElement")?,
                    get("endConnector")?
                ));
            }
            "DefaultExperiment" => {
                if let Some(v) = number(&e, "startTime")? {
                    d.start_time = v;
                }
                if let Some(v) = number(&e, "stopTime")? {
                    d.stop_time = v;
                    stop_given = true;
                }
            }
            "Simulation" => {
                if let Some(v) = number(&e, "stepSize")? {
                    steps.push((StepSource::Spurio, v));
                }
                if attr(&e, "algorithm").as_deref() == Some("jacobi") {
                    d.algorithm = AlgorithmName::Jacobi;
                }
                if let Some(r) = attr(&e, "record") {
                    d.record = r.split_whitespace().map(str::to_string).collect();
                }
            }
            "Instance" => {
                let name = attr(&e, "name").unwrap_or_default();
                if let Some(inst) = d.instances.iter_mut().find(|i| i.name == name) {
                    inst.step_multiple = attr(&e, "stepMultiple")
                        .and_then(|v| v.parse().ok())
                        .unwrap_or(1);
                    inst.logging = attr(&e, "logging").as_deref() == Some("true");
                    if let Some(solver) = attr(&e, "solver") {
                        inst.solver = Some(solver.parse().map_err(|reason| {
                            format!("instance `{name}` of the spurio annotation: {reason}")
                        })?);
                    }
                    for (key, value) in [
                        ("tolerance", &mut inst.tolerance),
                        ("maxStep", &mut inst.max_step),
                    ] {
                        *value = number(&e, key)?;
                        if value.is_some_and(|v| !(v.is_finite() && v > 0.0)) {
                            return Err(format!(
                                "instance `{name}` of the spurio annotation: `{key}` must be a positive number"
                            ));
                        }
                    }
                }
            }
            "FixedStepMaster" => {
                if let Some(v) = number(&e, "stepSize")? {
                    steps.push((StepSource::OmsFixedStepMaster, v));
                }
            }
            "SimulationInformation" => {
                if let Some(v) = number(&e, "stepSize")? {
                    steps.push((StepSource::OmsSolver, v));
                }
            }
            "FixedStepAlgorithm" => {
                if let Some(v) = number(&e, "baseStepSize")? {
                    steps.push((StepSource::Osp, v));
                }
            }
            _ => {}
        }
    }
    if version.is_empty() {
        return Err(
            "no <ssd:SystemStructureDescription> element: this is not a System Structure \
             Description"
                .to_string(),
        );
    }
    if d.instances.is_empty() {
        return Err(format!(
            "system `{}` has no <ssd:Component> (an FMU): nothing to simulate",
            d.name
        ));
    }
    let mut notes = Vec::new();
    if !stop_given {
        notes.push(format!(
            "the SSD gives no DefaultExperiment stopTime; using {}",
            d.stop_time
        ));
    }
    steps.sort_by_key(|(source, _)| *source);
    match steps.first() {
        Some((source, h)) => {
            d.step_size = *h;
            notes.push(format!("step size {h} from {}", source.describe()));
        }
        None => {
            d.step_size = (d.stop_time - d.start_time) / 100.0;
            notes.push(format!(
                "the SSD gives no step size (no org.spurio.simulation, oms:FixedStepMaster, \
                 oms:SimulationInformation or osp:FixedStepAlgorithm annotation); using \
                 (stopTime - startTime)/100 = {}",
                d.step_size
            ));
        }
    }
    Ok(Imported {
        description: d,
        version,
        notes,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_ssd_reads_back_as_the_system_it_was_written_from() {
        let mut parameters = BTreeMap::new();
        parameters.insert("x0".to_string(), toml::Value::Float(0.2));
        parameters.insert("seed".to_string(), toml::Value::Integer(7));
        parameters.insert("use_snr[1]".to_string(), toml::Value::Boolean(true));
        let d = SystemDescription {
            name: "crane & \"sensor\" <1>".into(),
            start_time: 0.5,
            stop_time: 2.0,
            step_size: 0.01,
            algorithm: AlgorithmName::Jacobi,
            instances: vec![
                InstanceDescription {
                    parameters,
                    ..InstanceDescription::new("crane", "resources/GantryCrane.fmu")
                },
                InstanceDescription {
                    step_multiple: 2,
                    logging: true,
                    interface: Some(InterfaceName::ModelExchange),
                    solver: Some(spurio_solvers::Method::Rodas3),
                    tolerance: Some(1e-8),
                    max_step: Some(0.01),
                    ..InstanceDescription::new("sensor", "resources/Sensor2.fmu")
                },
            ],
            connections: vec!["crane.x -> sensor.u[1]".into()],
            record: vec!["crane.x".into(), "sensor.y[1]".into()],
        };
        let connectors = vec![
            vec![("x".to_string(), "output", VarType::Real)],
            vec![("u[1]".to_string(), "input", VarType::Real)],
        ];
        let sources = vec![
            "resources/GantryCrane.fmu".to_string(),
            "resources/Sensor2.fmu".to_string(),
        ];
        for version in [SspVersion::V1_0, SspVersion::V2_0] {
            let text = ssd_text(&d, &connectors, &sources, version).unwrap();
            assert!(text.starts_with("<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n"));
            assert!(
                text.contains(r#"name="crane &amp; &quot;sensor&quot; &lt;1&gt;""#),
                "{text}"
            );
            assert!(
                text.contains(&format!(r#"version="{version}" name="#)),
                "{text}"
            );
            assert!(text.contains(r#"<ssd:Connector name="u[1]" kind="input">"#));
            assert!(text.contains("<ssc:Real/>"), "{text}");
            assert!(text.contains(r#"<ssv:Real value="0.2"/>"#), "{text}");
            assert!(
                text.contains(&format!(r#"<ssv:ParameterSet version="{version}""#)),
                "{text}"
            );
            // OMSimulator's fixed-step master, with the step size.
            assert!(
                text.contains(r#"<oms:FixedStepMaster description="oms-ma" stepSize="0.01""#),
                "{text}"
            );
            let imported = parse_ssd(&text).unwrap();
            assert_eq!(imported.description, d);
            assert_eq!(imported.version, version.as_str());
            assert_eq!(
                imported.notes,
                ["step size 0.01 from the org.spurio.simulation annotation (stepSize)"]
            );
        }
    }

    /// A component's connectors as [`ssd_text`] takes them: (name, kind, type).
    type Connectors = Vec<(String, &'static str, VarType)>;

    /// A system of one component `c` whose connectors are `connectors`.
    fn one_component(connectors: Connectors) -> (SystemDescription, Vec<Connectors>) {
        let d = SystemDescription {
            name: "s".into(),
            start_time: 0.0,
            stop_time: 1.0,
            step_size: 0.1,
            algorithm: AlgorithmName::GaussSeidel,
            instances: vec![InstanceDescription::new("c", "resources/Feedthrough.fmu")],
            connections: vec![],
            record: vec![],
        };
        (d, vec![connectors])
    }

    #[test]
    fn ssp_1_0_writes_the_fmi_3_types_it_holds_as_real_and_integer() {
        let types = [
            (VarType::Real, "Real", "Real"),
            (VarType::Float32, "Real", "Float32"),
            (VarType::Int8, "Integer", "Int8"),
            (VarType::UInt8, "Integer", "UInt8"),
            (VarType::Int16, "Integer", "Int16"),
            (VarType::UInt16, "Integer", "UInt16"),
            (VarType::Integer, "Integer", "Integer"),
            (VarType::Enumeration, "Integer", "Integer"),
            (VarType::Boolean, "Boolean", "Boolean"),
            (VarType::String, "String", "String"),
        ];
        let connectors = types
            .iter()
            .map(|(t, _, _)| (format!("{}_out", t.name_3()), "output", *t))
            .collect();
        let (d, connectors) = one_component(connectors);
        let sources = vec!["resources/Feedthrough.fmu".to_string()];
        for (version, column) in [(SspVersion::V1_0, 1), (SspVersion::V2_0, 2)] {
            let text = ssd_text(&d, &connectors, &sources, version).unwrap();
            for t in &types {
                let written = if column == 1 { t.1 } else { t.2 };
                let expected = format!(
                    "<ssd:Connector name=\"{}_out\" kind=\"output\">\n            <ssc:{written}/>",
                    t.0.name_3()
                );
                assert!(text.contains(&expected), "{version}: {expected}\n{text}");
            }
            // and it reads back, each connector as a connector
            assert_eq!(parse_ssd(&text).unwrap().description, d);
        }
    }

    #[test]
    fn ssp_1_0_refuses_a_connector_no_ssp_1_0_type_holds_naming_it_and_the_fix() {
        let sources = vec!["resources/Feedthrough.fmu".to_string()];
        for ty in [
            VarType::UInt32,
            VarType::Int64,
            VarType::UInt64,
            VarType::Clock,
        ] {
            let (d, connectors) = one_component(vec![
                ("Float64_out".into(), "output", VarType::Real),
                (format!("{}_in", ty.name_3()), "input", ty),
            ]);
            let e = ssd_text(&d, &connectors, &sources, SspVersion::V1_0).unwrap_err();
            assert_eq!(e.kind(), std::io::ErrorKind::InvalidInput);
            assert_eq!(
                e.to_string(),
                format!(
                    "component `c`, connector `{0}_in`: its type {0} has no lossless SSP 1.0 \
                     type (SSP 1.0 has Real, Integer of 32 bits, Boolean, String, Enumeration, \
                     Binary); export SSP 2.0 instead (`spurio ssp-export … --ssp-version 2.0`)",
                    ty.name_3()
                )
            );
            // SSP 2.0 writes it with its own type
            let text = ssd_text(&d, &connectors, &sources, SspVersion::V2_0).unwrap();
            assert!(text.contains(&format!("<ssc:{}/>", ty.name_3())), "{text}");
        }
    }

    /// The shape OMSimulator 3.x's Python API writes (SSP 2.0, a solver with a step size
    /// on the system, types of either version), and OMSimulator 2.x's fixed-step master.
    #[test]
    fn step_sizes_come_from_every_annotation_a_real_ssd_carries() {
        let oms3 = r#"<?xml version='1.0' encoding='utf-8'?>
<ssd:SystemStructureDescription xmlns:ssc="http://ssp-standard.org/SSP1/SystemStructureCommon" xmlns:ssd="http://ssp-standard.org/SSP1/SystemStructureDescription" xmlns:ssv="http://ssp-standard.org/SSP1/SystemStructureParameterValues" xmlns:oms="https://raw.githubusercontent.com/OpenModelica/OMSimulator/master/schema/oms.xsd" name="default" version="2.0">
  <ssd:System name="default">
    <ssd:Elements>
      <ssd:Component name="vdp" type="application/x-fmu-sharedlibrary" source="resources/VanDerPol.fmu">
        <ssd:Connectors><ssd:Connector name="x0" kind="output"><ssc:Real/></ssd:Connector></ssd:Connectors>
        <ssd:ParameterBindings><ssd:ParameterBinding><ssd:ParameterValues>
          <ssv:ParameterSet version="2.0" name="parameters"><ssv:Parameters>
            <ssv:Parameter name="mu"><ssv:Float64 value="1.5"/></ssv:Parameter>
            <ssv:Parameter name="n"><ssv:Int32 value="3"/></ssv:Parameter>
          </ssv:Parameters></ssv:ParameterSet>
        </ssd:ParameterValues></ssd:ParameterBinding></ssd:ParameterBindings>
      </ssd:Component>
      <ssd:Component name="ft" source="resources/Feedthrough.fmu"/>
    </ssd:Elements>
    <ssd:Connections>
      <ssd:Connection startElement="vdp" startConnector="x0" endElement="ft" endConnector="Float64_continuous_input"/>
    </ssd:Connections>
    <ssd:Annotations><ssc:Annotation type="org.openmodelica"><oms:Annotations>
      <oms:SimulationInformation name="solver1" method="oms-ma" stepSize="0.1"/>
    </oms:Annotations></ssc:Annotation></ssd:Annotations>
  </ssd:System>
  <ssd:DefaultExperiment startTime="0.0" stopTime="10.0"/>
</ssd:SystemStructureDescription>"#;
        let imported = parse_ssd(oms3).unwrap();
        let d = &imported.description;
        assert_eq!(imported.version, "2.0");
        assert_eq!((d.start_time, d.stop_time, d.step_size), (0.0, 10.0, 0.1));
        assert_eq!(d.instances.len(), 2);
        assert_eq!(d.instances[0].parameters["mu"], toml::Value::Float(1.5));
        assert_eq!(d.instances[0].parameters["n"], toml::Value::Integer(3));
        assert_eq!(d.connections, ["vdp.x0 -> ft.Float64_continuous_input"]);
        assert!(imported.notes[0].contains("oms:SimulationInformation"));

        let oms2 = oms3
            .replace(
                r#"<oms:SimulationInformation name="solver1" method="oms-ma" stepSize="0.1"/>"#,
                r#"<oms:SimulationInformation><oms:FixedStepMaster description="oms-ma" stepSize="0.025"/></oms:SimulationInformation>"#,
            )
            .replace(r#"version="2.0" name="default""#, r#"version="1.0" name="default""#);
        let imported = parse_ssd(&oms2).unwrap();
        assert_eq!(imported.description.step_size, 0.025);
        assert!(
            imported.notes[0].contains("oms:FixedStepMaster"),
            "{:?}",
            imported.notes
        );

        let osp = oms3.replace(
            r#"<oms:SimulationInformation name="solver1" method="oms-ma" stepSize="0.1"/>"#,
            "",
        );
        let osp = osp.replace(
            r#"<ssd:DefaultExperiment startTime="0.0" stopTime="10.0"/>"#,
            r#"<ssd:DefaultExperiment startTime="0.0" stopTime="10.0"><ssd:Annotations><ssc:Annotation type="org.open-simulation-platform"><osp:Algorithm xmlns:osp="http://opensimulationplatform.com/SSP/OSPAnnotations"><osp:FixedStepAlgorithm baseStepSize="0.05"/></osp:Algorithm></ssc:Annotation></ssd:Annotations></ssd:DefaultExperiment>"#,
        );
        assert_eq!(parse_ssd(&osp).unwrap().description.step_size, 0.05);

        // No step size anywhere: the default, said.
        let none = oms3.replace(
            r#"<oms:SimulationInformation name="solver1" method="oms-ma" stepSize="0.1"/>"#,
            "",
        );
        let imported = parse_ssd(&none).unwrap();
        assert_eq!(imported.description.step_size, 0.1);
        assert!(
            imported.notes[0].contains("no step size") && imported.notes[0].contains("= 0.1"),
            "{:?}",
            imported.notes
        );
    }

    /// Well-formedness is checked to the end of the text, the line named; a text with no
    /// SSD root or no component is refused in the SSD's terms.
    #[test]
    fn ill_formed_or_empty_ssds_are_refused_naming_the_line() {
        let good = "<ssd:SystemStructureDescription version=\"1.0\" name=\"s\">\n\
                    <ssd:System name=\"s\"><ssd:Elements>\n\
                    <ssd:Component name=\"c\" source=\"resources/c.fmu\"/>\n\
                    </ssd:Elements></ssd:System>\n\
                    </ssd:SystemStructureDescription>\n";
        assert_eq!(parse_ssd(good).unwrap().description.instances.len(), 1);
        let cases = [
            (
                good.replace("</ssd:SystemStructureDescription>\n", &"<a>".repeat(100_000)),
                "ill-formed XML at line 5: the text ends with <a> still open (100001 element(s) unclosed)",
            ),
            (
                format!("{good}<a>"),
                "ill-formed XML at line 6: <a> after the root element has ended",
            ),
            (
                good.replace("</ssd:Elements>", "</ssd:Element>"),
                "ill-formed XML at line 4: ",
            ),
            (
                format!("{good}<ssd:SystemStructureDescription/>"),
                "ill-formed XML at line 6: <ssd:SystemStructureDescription> after the root element has ended",
            ),
            (String::new(), "ill-formed XML at line 1: no root element"),
            (
                "<ssd:SystemStructureDescription version=\"1.0\" name=\"s\"/>".to_string(),
                "system `s` has no <ssd:Component> (an FMU): nothing to simulate",
            ),
            (
                "<other/>".to_string(),
                "no <ssd:SystemStructureDescription> element: this is not a System Structure Description",
            ),
        ];
        for (text, expected) in cases {
            let e = parse_ssd(&text).unwrap_err();
            assert!(e.starts_with(expected), "{e}");
        }
    }

    #[test]
    fn versions_other_than_1_and_2_are_refused() {
        let e =
            parse_ssd(r#"<ssd:SystemStructureDescription version="3.0" name="x"/>"#).unwrap_err();
        assert_eq!(e, "SSP version `3.0` is not supported (1.0 and 2.0 are)");
        assert_eq!("1.0".parse::<SspVersion>(), Ok(SspVersion::V1_0));
        assert!("1.1".parse::<SspVersion>().is_err());
    }
}
