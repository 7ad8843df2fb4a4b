//! SSP 1.0: export a system as `<name>.ssp` (`SystemStructure.ssd` + the FMUs under
//! `resources/`) and import one back, so the same system runs in OMSimulator, fmpy's SSP
//! runner or this master.
//!
//! Start values go into inline `ssv:ParameterSet`s of each component's `ParameterBindings`;
//! the step size, the algorithm and the step multiples (which SSP 1.0 does not define) go
//! into an `ssc:Annotation` of type `org.spurio.simulation`.

use crate::description::{Algorithm, InstanceDescription, SystemDescription};
use crate::fmu::{Causality, FmuFile, VarType};
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

/// The SSP connector kind and type of variable `name` of `fmu` (None: not a connector).
fn connector(fmu: &FmuFile, name: &str) -> Option<(&'static str, &'static str)> {
    let v = fmu.variable(name)?;
    let kind = match v.causality {
        Causality::Input => "input",
        Causality::Output => "output",
        Causality::Parameter => "parameter",
        Causality::CalculatedParameter => "calculatedParameter",
        _ => return None,
    };
    let ty = match v.var_type {
        VarType::Real => "Real",
        VarType::Integer | VarType::Enumeration => "Integer",
        VarType::Boolean => "Boolean",
        VarType::String => "String",
    };
    Some((kind, ty))
}

/// The `SystemStructure.ssd` text for `d`, written with quick-xml (which escapes every
/// attribute); `connectors[i]` are instance i's (name, kind, type), `sources[i]` the archive
/// path of its FMU.
pub fn ssd_text(
    d: &SystemDescription,
    connectors: &[Vec<(String, &'static str, &'static str)>],
    sources: &[String],
) -> Result<String, std::io::Error> {
    let name = if d.name.is_empty() {
        "system"
    } else {
        d.name.as_str()
    };
    let mut w = Writer::new_with_indent(Vec::new(), b' ', 2);
    w.write_event(Event::Decl(BytesDecl::new("1.0", Some("UTF-8"), None)))?;
    w.create_element("ssd:SystemStructureDescription")
        .with_attributes([
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
            ("version", "1.0"),
            ("name", name),
            ("generationTool", "spurio"),
        ])
        .write_inner_content(|w| {
            w.create_element("ssd:System")
                .with_attribute(("name", name))
                .write_inner_content(|w| {
                    w.create_element("ssd:Elements").write_inner_content(|w| {
                        for (i, inst) in d.instances.iter().enumerate() {
                            component(w, inst, &connectors[i], &sources[i])?;
                        }
                        Ok(())
                    })?;
                    if !d.connections.is_empty() {
                        w.create_element("ssd:Connections")
                            .write_inner_content(|w| {
                                for c in &d.connections {
                                    let Some((from, to)) = c.split_once("->") else {
                                        continue;
                                    };
                                    let (Some((fe, fc)), Some((te, tc))) =
                                        (from.trim().split_once('.'), to.trim().split_once('.'))
                                    else {
                                        continue;
                                    };
                                    w.create_element("ssd:Connection")
                                        .with_attributes([
                                            ("startElement", fe),
                                            ("startConnector", fc),
                                            ("endElement", te),
                                            ("endConnector", tc),
                                        ])
                                        .write_empty()?;
                                }
                                Ok(())
                            })?;
                    }
                    Ok(())
                })?;
            let (start, stop) = (format!("{:?}", d.start_time), format!("{:?}", d.stop_time));
            w.create_element("ssd:DefaultExperiment")
                .with_attributes([("startTime", start.as_str()), ("stopTime", stop.as_str())])
                .write_inner_content(|w| {
                    w.create_element("ssd:Annotations")
                        .write_inner_content(|w| {
                            w.create_element("ssc:Annotation")
                                .with_attribute(("type", ANNOTATION))
                                .write_inner_content(|w| simulation_annotation(w, d))?;
                            Ok(())
                        })?;
                    Ok(())
                })?;
            Ok(())
        })?;
    let mut text = String::from_utf8(w.into_inner()).map_err(std::io::Error::other)?;
    text.push('\n');
    Ok(text)
}

fn component(
    w: &mut Writer<Vec<u8>>,
    inst: &InstanceDescription,
    connectors: &[(String, &'static str, &'static str)],
    source: &str,
) -> std::io::Result<()> {
    w.create_element("ssd:Component")
        .with_attributes([
            ("name", inst.name.as_str()),
            ("type", "application/x-fmu-sharedlibrary"),
            ("source", source),
        ])
        .write_inner_content(|w| {
            if !connectors.is_empty() {
                w.create_element("ssd:Connectors")
                    .write_inner_content(|w| {
                        for (name, kind, ty) in connectors {
                            w.create_element("ssd:Connector")
                                .with_attributes([("name", name.as_str()), ("kind", *kind)])
                                .write_inner_content(|w| {
                                    w.create_element(format!("ssc:{ty}")).write_empty()?;
                                    Ok(())
                                })?;
                        }
                        Ok(())
                    })?;
            }
            if !inst.parameters.is_empty() {
                w.create_element("ssd:ParameterBindings")
                    .write_inner_content(|w| {
                        w.create_element("ssd:ParameterBinding")
                            .write_inner_content(|w| {
                                w.create_element("ssd:ParameterValues")
                                    .write_inner_content(|w| parameter_set(w, inst))?;
                                Ok(())
                            })?;
                        Ok(())
                    })?;
            }
            Ok(())
        })?;
    Ok(())
}

fn parameter_set(w: &mut Writer<Vec<u8>>, inst: &InstanceDescription) -> std::io::Result<()> {
    w.create_element("ssv:ParameterSet")
        .with_attributes([("version", "1.0"), ("name", inst.name.as_str())])
        .write_inner_content(|w| {
            w.create_element("ssv:Parameters")
                .write_inner_content(|w| {
                    for (name, value) in &inst.parameters {
                        let (ty, text) = match value {
                            toml::Value::Float(f) => ("ssv:Real", format!("{f:?}")),
                            toml::Value::Integer(n) => ("ssv:Integer", n.to_string()),
                            toml::Value::Boolean(b) => ("ssv:Boolean", b.to_string()),
                            other => ("ssv:String", other.to_string()),
                        };
                        w.create_element("ssv:Parameter")
                            .with_attribute(("name", name.as_str()))
                            .write_inner_content(|w| {
                                w.create_element(ty)
                                    .with_attribute(("value", text.as_str()))
                                    .write_empty()?;
                                Ok(())
                            })?;
                    }
                    Ok(())
                })?;
            Ok(())
        })?;
    Ok(())
}

/// What SSP 1.0 has no place for: step size, algorithm, record, step multiples, logging.
fn simulation_annotation(w: &mut Writer<Vec<u8>>, d: &SystemDescription) -> std::io::Result<()> {
    let algorithm = match d.algorithm {
        Algorithm::GaussSeidel => "gauss-seidel",
        Algorithm::Jacobi => "jacobi",
    };
    let step = format!("{:?}", d.step_size);
    let record = d.record.join(" ");
    w.create_element("Simulation")
        .with_attributes([
            ("stepSize", step.as_str()),
            ("algorithm", algorithm),
            ("record", record.as_str()),
        ])
        .write_inner_content(|w| {
            for inst in &d.instances {
                let multiple = inst.step_multiple.to_string();
                let logging = inst.logging.to_string();
                w.create_element("Instance")
                    .with_attributes([
                        ("name", inst.name.as_str()),
                        ("stepMultiple", multiple.as_str()),
                        ("logging", logging.as_str()),
                    ])
                    .write_empty()?;
            }
            Ok(())
        })?;
    Ok(())
}

/// Writes `target` (.ssp) for the system `d` whose instance i runs `fmus[i]` (loaded from
/// `d.instances[i].fmu`): the SSD, and every FMU under `resources/`. The connectors are the
/// variables used by a connection or a record.
pub fn export(d: &SystemDescription, fmus: &[&FmuFile], target: &Path) -> Result<(), SspError> {
    if fmus.len() != d.instances.len() {
        return Err(err(
            target,
            format!("{} FMUs for {} instances", fmus.len(), d.instances.len()),
        ));
    }
    let mut used: Vec<BTreeMap<String, (&'static str, &'static str)>> =
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
    let connectors: Vec<Vec<(String, &'static str, &'static str)>> = used
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
    let ssd = ssd_text(d, &connectors, &sources).map_err(|e| err(target, e))?;
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
/// (FMU paths relative to `out_dir`).
pub fn import(ssp: &Path, out_dir: &Path) -> Result<SystemDescription, SspError> {
    let file = std::fs::File::open(ssp).map_err(|e| err(ssp, e))?;
    let mut archive = zip::ZipArchive::new(file).map_err(|e| err(ssp, e))?;
    let mut ssd = String::new();
    archive
        .by_name("SystemStructure.ssd")
        .map_err(|_| err(ssp, "no SystemStructure.ssd in the archive"))?
        .read_to_string(&mut ssd)
        .map_err(|e| err(ssp, e))?;
    let mut d = parse_ssd(&ssd).map_err(|e| err(ssp, format!("SystemStructure.ssd: {e}")))?;
    std::fs::create_dir_all(out_dir).map_err(|e| err(out_dir, e))?;
    for inst in &mut d.instances {
        let source = inst.fmu.to_string_lossy().to_string();
        let mut entry = archive.by_name(&source).map_err(|_| {
            err(
                ssp,
                format!(
                    "component `{}`: `{source}` is not in the archive",
                    inst.name
                ),
            )
        })?;
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
        let mut bytes = Vec::new();
        entry.read_to_end(&mut bytes).map_err(|e| err(ssp, e))?;
        std::fs::write(&target, bytes).map_err(|e| err(&target, e))?;
        inst.fmu = PathBuf::from(source);
    }
    Ok(d)
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

/// Parses a `SystemStructure.ssd` (the subset this master exports, which is also what simple
/// tools write: components, connectors, connections, inline parameter sets).
pub fn parse_ssd(text: &str) -> Result<SystemDescription, String> {
    let mut reader = quick_xml::Reader::from_str(text);
    let mut d = SystemDescription {
        name: String::new(),
        start_time: 0.0,
        stop_time: 1.0,
        step_size: 0.0,
        algorithm: Algorithm::GaussSeidel,
        instances: Vec::new(),
        connections: Vec::new(),
        record: Vec::new(),
    };
    let mut parameter: Option<String> = None;
    let mut depth_component = false;
    loop {
        let event = reader.read_event().map_err(|e| e.to_string())?;
        let (e, is_empty) = match &event {
            Event::Start(e) => (e.clone(), false),
            Event::Empty(e) => (e.clone(), true),
            Event::End(e) => {
                match e.local_name().as_ref() {
                    "Component" => depth_component = false,
                    "Parameter" => parameter = None,
                    _ => {}
                }
                continue;
            }
            Event::Eof => break,
            _ => continue,
        };
        let _ = is_empty;
        match e.local_name().as_ref() {
            "SystemStructureDescription" => {
                if let Some(v) = attr(&e, "version") {
                    if !v.starts_with("1.") {
                        return Err(format!("SSP version {v} is not supported (1.x only)"));
                    }
                }
                d.name = attr(&e, "name").unwrap_or_default();
            }
            "Component" => {
                depth_component = true;
                d.instances.push(InstanceDescription {
                    name: attr(&e, "name").ok_or("a Component has no name")?,
                    fmu: PathBuf::from(attr(&e, "source").ok_or("a Component has no source")?),
                    parameters: BTreeMap::new(),
                    step_multiple: 1,
                    logging: false,
                });
            }
            "Parameter" if depth_component => parameter = attr(&e, "name"),
            "Real" | "Integer" | "Boolean" | "String" if parameter.is_some() => {
                let value = attr(&e, "value").unwrap_or_default();
                let v = match e.local_name().as_ref() {
                    "Real" => toml::Value::Float(
                        value.parse().map_err(|_| format!("bad Real `{value}`"))?,
                    ),
                    "Integer" => toml::Value::Integer(
                        value
                            .parse()
                            .map_err(|_| format!("bad Integer `{value}`"))?,
                    ),
                    "Boolean" => toml::Value::Boolean(value == "true" || value == "1"),
                    _ => toml::Value::String(value),
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
                if let Some(v) = attr(&e, "startTime") {
                    d.start_time = v.parse().map_err(|_| format!("bad startTime `{v}`"))?;
                }
                if let Some(v) = attr(&e, "stopTime") {
                    d.stop_time = v.parse().map_err(|_| format!("bad stopTime `{v}`"))?;
                }
            }
            "Simulation" => {
                if let Some(v) = attr(&e, "stepSize") {
                    d.step_size = v.parse().map_err(|_| format!("bad stepSize `{v}`"))?;
                }
                if attr(&e, "algorithm").as_deref() == Some("jacobi") {
                    d.algorithm = Algorithm::Jacobi;
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
                }
            }
            _ => {}
        }
    }
    if d.step_size <= 0.0 {
        d.step_size = (d.stop_time - d.start_time) / 100.0;
    }
    Ok(d)
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
            algorithm: Algorithm::Jacobi,
            instances: vec![
                InstanceDescription {
                    name: "crane".into(),
                    fmu: PathBuf::from("resources/GantryCrane.fmu"),
                    parameters,
                    step_multiple: 1,
                    logging: false,
                },
                InstanceDescription {
                    name: "sensor".into(),
                    fmu: PathBuf::from("resources/Sensor2.fmu"),
                    parameters: BTreeMap::new(),
                    step_multiple: 2,
                    logging: true,
                },
            ],
            connections: vec!["crane.x -> sensor.u[1]".into()],
            record: vec!["crane.x".into(), "sensor.y[1]".into()],
        };
        let connectors = vec![
            vec![("x".to_string(), "output", "Real")],
            vec![("u[1]".to_string(), "input", "Real")],
        ];
        let sources = vec![
            "resources/GantryCrane.fmu".to_string(),
            "resources/Sensor2.fmu".to_string(),
        ];
        let text = ssd_text(&d, &connectors, &sources).unwrap();
        assert!(text.starts_with("<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n"));
        assert!(
            text.contains(r#"name="crane &amp; &quot;sensor&quot; &lt;1&gt;""#),
            "{text}"
        );
        assert!(text.contains(r#"<ssd:Connector name="u[1]" kind="input">"#));
        assert_eq!(parse_ssd(&text).unwrap(), d);
    }
}
