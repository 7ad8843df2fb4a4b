//! SSP 1.0: export a system as `<name>.ssp` (`SystemStructure.ssd` + the FMUs under
//! `resources/`) and import one back, so the same system runs in OMSimulator, fmpy's SSP
//! runner or this master.
//!
//! Start values go into inline `ssv:ParameterSet`s of each component's `ParameterBindings`;
//! the step size, the algorithm and the step multiples (which SSP 1.0 does not define) go
//! into an `ssc:Annotation` of type `org.spurio.simulation`.

use crate::system::{Algorithm, InstanceDescription, SystemDescription};
use quick_xml::events::Event;
use std::collections::BTreeMap;
use std::fmt::Write as _;
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

fn esc(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

const ANNOTATION: &str = "org.spurio.simulation";

/// The `SystemStructure.ssd` text for `d`; `sources[i]` is the archive path of instance i's FMU.
pub fn ssd_text(
    d: &SystemDescription,
    connectors: &[Vec<(String, &'static str, &'static str)>],
    sources: &[String],
) -> String {
    let mut x = String::new();
    let name = if d.name.is_empty() {
        "system"
    } else {
        d.name.as_str()
    };
    let _ = writeln!(x, r#"<?xml version="1.0" encoding="UTF-8"?>"#);
    let _ = writeln!(
        x,
        r#"<ssd:SystemStructureDescription xmlns:ssc="http://ssp-standard.org/SSP1/SystemStructureCommon" xmlns:ssd="http://ssp-standard.org/SSP1/SystemStructureDescription" xmlns:ssv="http://ssp-standard.org/SSP1/SystemStructureParameterValues" version="1.0" name="{}" generationTool="spurio">"#,
        esc(name)
    );
    let _ = writeln!(x, r#"  <ssd:System name="{}">"#, esc(name));
    let _ = writeln!(x, "    <ssd:Elements>");
    for (i, inst) in d.instances.iter().enumerate() {
        let _ = writeln!(
            x,
            r#"      <ssd:Component name="{}" type="application/x-fmu-sharedlibrary" source="{}">"#,
            esc(&inst.name),
            esc(&sources[i])
        );
        if !connectors[i].is_empty() {
            let _ = writeln!(x, "        <ssd:Connectors>");
            for (cname, kind, ty) in &connectors[i] {
                let _ = writeln!(
                    x,
                    r#"          <ssd:Connector name="{}" kind="{kind}"><ssc:{ty}/></ssd:Connector>"#,
                    esc(cname)
                );
            }
            let _ = writeln!(x, "        </ssd:Connectors>");
        }
        if !inst.parameters.is_empty() {
            let _ = writeln!(x, "        <ssd:ParameterBindings>");
            let _ = writeln!(x, "          <ssd:ParameterBinding>");
            let _ = writeln!(x, "            <ssd:ParameterValues>");
            let _ = writeln!(
                x,
                r#"              <ssv:ParameterSet version="1.0" name="{}">"#,
                esc(&inst.name)
            );
            let _ = writeln!(x, "                <ssv:Parameters>");
            for (pname, value) in &inst.parameters {
                let typed = match value {
                    toml::Value::Float(f) => format!(r#"<ssv:Real value="{f:?}"/>"#),
                    toml::Value::Integer(n) => format!(r#"<ssv:Integer value="{n}"/>"#),
                    toml::Value::Boolean(b) => format!(r#"<ssv:Boolean value="{b}"/>"#),
                    other => format!(r#"<ssv:String value="{}"/>"#, esc(&other.to_string())),
                };
                let _ = writeln!(
                    x,
                    r#"                  <ssv:Parameter name="{}">{typed}</ssv:Parameter>"#,
                    esc(pname)
                );
            }
            let _ = writeln!(x, "                </ssv:Parameters>");
            let _ = writeln!(x, "              </ssv:ParameterSet>");
            let _ = writeln!(x, "            </ssd:ParameterValues>");
            let _ = writeln!(x, "          </ssd:ParameterBinding>");
            let _ = writeln!(x, "        </ssd:ParameterBindings>");
        }
        let _ = writeln!(x, "      </ssd:Component>");
    }
    let _ = writeln!(x, "    </ssd:Elements>");
    if !d.connections.is_empty() {
        let _ = writeln!(x, "    <ssd:Connections>");
        for c in &d.connections {
            if let Some((from, to)) = c.split_once("->") {
                if let (Some((fe, fc)), Some((te, tc))) =
                    (from.trim().split_once('.'), to.trim().split_once('.'))
                {
                    let _ = writeln!(
                        x,
                        r#"      <ssd:Connection startElement="{}" startConnector="{}" endElement="{}" endConnector="{}"/>"#,
                        esc(fe),
                        esc(fc),
                        esc(te),
                        esc(tc)
                    );
                }
            }
        }
        let _ = writeln!(x, "    </ssd:Connections>");
    }
    let _ = writeln!(x, "  </ssd:System>");
    let _ = writeln!(
        x,
        r#"  <ssd:DefaultExperiment startTime="{:?}" stopTime="{:?}">"#,
        d.start_time, d.stop_time
    );
    let _ = writeln!(x, "    <ssd:Annotations>");
    let _ = writeln!(x, r#"      <ssc:Annotation type="{ANNOTATION}">"#);
    let algorithm = match d.algorithm {
        Algorithm::GaussSeidel => "gauss-seidel",
        Algorithm::Jacobi => "jacobi",
    };
    let record = d.record.join(" ");
    let _ = writeln!(
        x,
        r#"        <Simulation stepSize="{:?}" algorithm="{algorithm}" record="{}">"#,
        d.step_size,
        esc(&record)
    );
    for inst in &d.instances {
        let _ = writeln!(
            x,
            r#"          <Instance name="{}" stepMultiple="{}" logging="{}"/>"#,
            esc(&inst.name),
            inst.step_multiple,
            inst.logging
        );
    }
    let _ = writeln!(x, "        </Simulation>");
    let _ = writeln!(x, "      </ssc:Annotation>");
    let _ = writeln!(x, "    </ssd:Annotations>");
    let _ = writeln!(x, "  </ssd:DefaultExperiment>");
    let _ = writeln!(x, "</ssd:SystemStructureDescription>");
    x
}

/// Writes `target` (.ssp) for the system file `system_file`.
pub fn export(system_file: &Path, target: &Path) -> Result<(), SspError> {
    let d = SystemDescription::read(system_file).map_err(|e| err(system_file, e))?;
    let system = crate::system::System::from_file(system_file).map_err(|e| err(system_file, e))?;
    let base = system_file.parent().unwrap_or(Path::new("."));
    // Connectors: every variable used by a connection or given a start value.
    let mut used: Vec<BTreeMap<String, (&'static str, &'static str)>> =
        vec![BTreeMap::new(); d.instances.len()];
    let kind_of = |i: usize, name: &str| -> Option<(&'static str, &'static str)> {
        let v = system.instances[i].fmu.variable(name)?;
        let kind = match v.causality {
            crate::fmu::Causality::Input => "input",
            crate::fmu::Causality::Output => "output",
            crate::fmu::Causality::Parameter => "parameter",
            crate::fmu::Causality::CalculatedParameter => "calculatedParameter",
            _ => return None,
        };
        let ty = match v.var_type {
            crate::fmu::VarType::Real => "Real",
            crate::fmu::VarType::Integer | crate::fmu::VarType::Enumeration => "Integer",
            crate::fmu::VarType::Boolean => "Boolean",
            crate::fmu::VarType::String => "String",
        };
        Some((kind, ty))
    };
    let index = |name: &str| d.instances.iter().position(|i| i.name == name);
    for c in &d.connections {
        if let Some((from, to)) = c.split_once("->") {
            for end in [from, to] {
                if let Some((e, v)) = end.trim().split_once('.') {
                    if let Some(i) = index(e) {
                        if let Some(k) = kind_of(i, v) {
                            used[i].insert(v.to_string(), k);
                        }
                    }
                }
            }
        }
    }
    for r in &d.record {
        if let Some((e, v)) = r.trim().split_once('.') {
            if let Some(i) = index(e) {
                if let Some(k) = kind_of(i, v) {
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
        let path = base.join(&inst.fmu);
        let file_name = path
            .file_name()
            .map(|f| f.to_string_lossy().to_string())
            .ok_or_else(|| err(&path, "not a file"))?;
        let source = format!("resources/{file_name}");
        if let Some(previous) = files.get(&source) {
            if previous != &path {
                return Err(err(
                    &path,
                    format!("two different FMUs are both called {file_name}"),
                ));
            }
        }
        files.insert(source.clone(), path);
        sources.push(source);
    }
    let ssd = ssd_text(&d, &connectors, &sources);
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
