//! `spurio info` and `spurio validate`: what an FMU says about itself, and whether it says it
//! by the standard (the work is `spurio-inspect`'s; this module lays it out).

use anyhow::{bail, Result};
use serde_json::{json, Value};
use spurio_inspect::{Fmu, ModelDescription, Severity, Variable};
use std::path::Path;

/// One row of the variable table: a variable, or an FMI 3.0 alias of one (`alias_of`).
struct Row<'a> {
    name: &'a str,
    variable: &'a Variable,
    alias_of: Option<&'a str>,
    description: Option<&'a str>,
}

fn rows(md: &ModelDescription) -> Vec<Row<'_>> {
    let mut rows = Vec::new();
    for v in &md.variables {
        let description = v.element.get("description");
        rows.push(Row {
            name: v.name(),
            variable: v,
            alias_of: None,
            description,
        });
        rows.extend(v.aliases.iter().map(|a| Row {
            name: a.get("name").unwrap_or_default(),
            variable: v,
            alias_of: Some(v.name()),
            description: a.get("description").or(description),
        }));
    }
    rows
}

/// The extent of an FMI 3.0 array (`[3,3]`, a structural parameter's value reference as
/// `#vr`), empty for a scalar.
fn shape(v: &Variable) -> String {
    if v.dimensions.is_empty() {
        return String::new();
    }
    let extents: Vec<String> = v
        .dimensions
        .iter()
        .map(|d| match (d.get("start"), d.get("valueReference")) {
            (Some(n), _) => n.to_string(),
            (None, Some(vr)) => format!("#{vr}"),
            (None, None) => "?".into(),
        })
        .collect();
    format!("[{}]", extents.join(","))
}

/// The attributes of a variable's row, as JSON keys and table columns: its own, then those
/// in force by the standard's defaults (causality, variability, initial) or its declared
/// type (unit).
const COLUMNS: [&str; 12] = [
    "name",
    "value_reference",
    "causality",
    "variability",
    "initial",
    "type",
    "unit",
    "start",
    "min",
    "max",
    "alias_of",
    "description",
];

/// The values of `row` in the order of [`COLUMNS`].
fn values(md: &ModelDescription, row: &Row) -> [Option<String>; 12] {
    let v = row.variable;
    let written = |name| v.element.text(name);
    [
        Some(row.name.to_string()),
        written("valueReference"),
        Some(v.causality().to_string()),
        Some(md.variability(v)),
        md.initial(v),
        Some(format!("{}{}", v.type_name, shape(v))),
        md.unit_of(v).map(str::to_string),
        written("start"),
        written("min"),
        written("max"),
        row.alias_of.map(str::to_string),
        row.description.map(str::to_string),
    ]
}

/// The FMU's summary: (JSON key, label, value).
fn summary(fmu: &Fmu) -> Vec<(&'static str, &'static str, Value)> {
    let md = &fmu.model_description;
    let interfaces: Vec<Value> = md
        .interfaces
        .iter()
        .map(|(kind, e)| json!({"kind": kind.short(), "element": kind.element(), "model_identifier": e.get("modelIdentifier")}))
        .collect();
    let experiment = md.default_experiment.as_ref().map(|e| {
        let given = ["startTime", "stopTime", "stepSize", "tolerance"]
            .iter()
            .filter_map(|name| e.get(name).map(|v| (name.to_string(), json!(v))));
        Value::Object(given.collect())
    });
    let token = match md.version {
        spurio_inspect::Version::Fmi2 => "GUID",
        spurio_inspect::Version::Fmi3 => "instantiation token",
    };
    let root = |name| json!(md.root.get(name));
    vec![
        ("fmi_version", "FMI version", root("fmiVersion")),
        ("interfaces", "interfaces", json!(interfaces)),
        ("model_name", "model name", root("modelName")),
        ("description", "description", root("description")),
        ("token", token, json!(md.token())),
        ("generation_tool", "generation tool", root("generationTool")),
        ("platforms", "platforms", json!(fmu.platforms())),
        ("sources", "C sources", json!(fmu.archive.has_sources())),
        (
            "default_experiment",
            "default experiment",
            json!(experiment),
        ),
    ]
}

/// A summary value as text: `-` for none, a list joined by commas, an interface as
/// `Element (identifier)`, the default experiment as `name value` pairs.
fn as_text(value: &Value) -> String {
    match value {
        Value::Null => "-".into(),
        Value::String(s) => s.clone(),
        Value::Array(items) if items.is_empty() => "none".into(),
        Value::Array(items) => items.iter().map(as_text).collect::<Vec<_>>().join(", "),
        Value::Object(map) if map.contains_key("element") => format!(
            "{} ({})",
            as_text(&map["element"]),
            as_text(&map["model_identifier"])
        ),
        Value::Object(map) => map
            .iter()
            .map(|(k, v)| format!("{k} {}", as_text(v)))
            .collect::<Vec<_>>()
            .join(", "),
        other => other.to_string(),
    }
}

/// `spurio info`: the summary and every variable, as text or JSON.
pub fn info(path: &Path, as_json: bool) -> Result<()> {
    let fmu = Fmu::open(path)?;
    let md = &fmu.model_description;
    let table: Vec<[Option<String>; 12]> = rows(md).iter().map(|r| values(md, r)).collect();
    if as_json {
        let mut out: serde_json::Map<String, Value> = summary(&fmu)
            .into_iter()
            .map(|(key, _, value)| (key.to_string(), value))
            .collect();
        let variables = table.iter().map(|row| {
            let fields = COLUMNS
                .iter()
                .zip(row)
                .map(|(k, v)| (k.to_string(), json!(v)));
            Value::Object(fields.collect())
        });
        out.insert("variables".into(), Value::Array(variables.collect()));
        say!("{}", serde_json::to_string_pretty(&out)?);
        return Ok(());
    }
    say!("{}", path.display());
    for (_, label, value) in summary(&fmu) {
        say!("  {label:<20} {}", as_text(&value));
    }
    say!("  {:<20} {}", "variables", table.len());
    say!("");
    let header = COLUMNS.map(|c| Some(c.replace('_', " ")));
    let mut widths = [0usize; 12];
    for row in std::iter::once(&header).chain(&table) {
        for (w, cell) in widths.iter_mut().zip(row) {
            *w = (*w).max(cell.as_deref().map_or(1, |c| c.chars().count()));
        }
    }
    for row in std::iter::once(&header).chain(&table) {
        let cells: Vec<String> = row
            .iter()
            .zip(widths)
            .map(|(c, w)| format!("{:<w$}", c.as_deref().unwrap_or("-")))
            .collect();
        say!("  {}", cells.join("  ").trim_end());
    }
    Ok(())
}

/// `spurio validate`: every problem on stdout; fails when there is an error.
pub fn validate(path: &Path) -> Result<()> {
    let fmu = Fmu::open(path)?;
    let problems = fmu.validate().map_err(|error| spurio_inspect::FmuError {
        file: path.to_path_buf(),
        error,
    })?;
    for p in &problems {
        say!("{p}");
    }
    let errors = problems
        .iter()
        .filter(|p| p.severity == Severity::Error)
        .count();
    let warnings = match problems.len() - errors {
        0 => String::new(),
        n => format!(", {n} warning(s)"),
    };
    let version = fmu.model_description.version.number();
    if errors > 0 {
        bail!(
            "{}: {errors} problem(s) against FMI {version}{warnings}",
            path.display()
        );
    }
    say!(
        "{}: valid FMI {version} (the standard's schema and rules){warnings}",
        path.display()
    );
    Ok(())
}
