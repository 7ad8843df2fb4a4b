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
        rows.push(Row {
            name: &v.name,
            variable: v,
            alias_of: None,
            description: v.description.as_deref(),
        });
        rows.extend(v.aliases.iter().map(|a| Row {
            name: &a.name,
            variable: v,
            alias_of: Some(&v.name),
            description: a.description.as_deref().or(v.description.as_deref()),
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
        .map(|d| match (&d.start, &d.value_reference) {
            (Some(n), _) => n.clone(),
            (None, Some(vr)) => format!("#{vr}"),
            (None, None) => "?".into(),
        })
        .collect();
    format!("[{}]", extents.join(","))
}

/// `spurio info`: the summary and every variable, as text or JSON.
pub fn info(path: &Path, as_json: bool) -> Result<()> {
    let fmu = Fmu::open(path)?;
    let md = &fmu.model_description;
    let platforms = fmu.platforms();
    if as_json {
        say!(
            "{}",
            serde_json::to_string_pretty(&info_json(&fmu, &platforms))?
        );
        return Ok(());
    }
    let or_none = |s: &Option<String>| s.clone().unwrap_or_else(|| "-".into());
    let interfaces: Vec<String> = md
        .interfaces
        .iter()
        .map(|i| {
            format!(
                "{} ({})",
                i.kind.element(),
                i.model_identifier
                    .as_deref()
                    .unwrap_or("no modelIdentifier")
            )
        })
        .collect();
    let mut places = platforms.clone();
    if fmu.archive.has_sources() {
        places.push("sources".into());
    }
    let token = match md.version {
        spurio_inspect::Version::Fmi2 => "GUID",
        spurio_inspect::Version::Fmi3 => "instantiation token",
    };
    say!("{}", path.display());
    say!("  {:<20} {}", "FMI version", md.fmi_version);
    say!("  {:<20} {}", "interfaces", interfaces.join(", "));
    say!("  {:<20} {}", "model name", or_none(&md.model_name));
    say!("  {:<20} {}", "description", or_none(&md.description));
    say!("  {:<20} {}", token, or_none(&md.token));
    say!(
        "  {:<20} {}",
        "generation tool",
        or_none(&md.generation_tool)
    );
    say!(
        "  {:<20} {}",
        "platforms",
        if places.is_empty() {
            "none".into()
        } else {
            places.join(", ")
        }
    );
    let experiment = match &md.default_experiment {
        None => "none".to_string(),
        Some(e) => [
            ("start", &e.start_time),
            ("stop", &e.stop_time),
            ("step size", &e.step_size),
            ("tolerance", &e.tolerance),
        ]
        .iter()
        .filter_map(|(name, value)| value.as_ref().map(|v| format!("{name} {v}")))
        .collect::<Vec<_>>()
        .join(", "),
    };
    say!("  {:<20} {}", "default experiment", experiment);
    let rows = rows(md);
    say!("  {:<20} {}", "variables", rows.len());
    say!("");
    let header = [
        "name",
        "vr",
        "causality",
        "variability",
        "type",
        "unit",
        "start",
        "min",
        "max",
        "description",
    ];
    let table: Vec<[String; 10]> = rows
        .iter()
        .map(|r| {
            let v = r.variable;
            let description = match r.alias_of {
                Some(of) => format!("(alias of {of}) {}", r.description.unwrap_or_default()),
                None => r.description.unwrap_or_default().to_string(),
            };
            [
                r.name.to_string(),
                v.value_reference.clone().unwrap_or_default(),
                v.causality().to_string(),
                md.variability(v),
                format!("{}{}", v.type_name, shape(v)),
                md.unit_of(v).unwrap_or_default(),
                v.start.clone().unwrap_or_default(),
                v.min.clone().unwrap_or_default(),
                v.max.clone().unwrap_or_default(),
                description,
            ]
        })
        .collect();
    let mut widths = header.map(str::len);
    for row in &table {
        for (w, cell) in widths.iter_mut().zip(row) {
            *w = (*w).max(cell.chars().count());
        }
    }
    let line = |cells: &[String]| {
        let padded: Vec<String> = cells
            .iter()
            .zip(widths)
            .map(|(c, w)| format!("{c:<w$}"))
            .collect();
        padded.join("  ").trim_end().to_string()
    };
    say!("  {}", line(&header.map(String::from)));
    for row in &table {
        say!("  {}", line(row));
    }
    Ok(())
}

fn info_json(fmu: &Fmu, platforms: &[String]) -> Value {
    let md = &fmu.model_description;
    let variables: Vec<Value> = rows(md)
        .iter()
        .map(|r| {
            let v = r.variable;
            json!({
                "name": r.name,
                "alias_of": r.alias_of,
                "value_reference": v.value_reference,
                "causality": v.causality(),
                "variability": md.variability(v),
                "initial": md.initial(v),
                "type": v.type_name,
                "dimensions": shape(v),
                "unit": md.unit_of(v),
                "display_unit": v.display_unit,
                "start": v.start,
                "min": v.min,
                "max": v.max,
                "nominal": v.nominal,
                "derivative": v.derivative,
                "description": r.description,
            })
        })
        .collect();
    json!({
        "fmi_version": md.fmi_version,
        "interfaces": md.interfaces.iter().map(|i| json!({
            "kind": i.kind.short(),
            "model_identifier": i.model_identifier,
        })).collect::<Vec<_>>(),
        "model_name": md.model_name,
        "description": md.description,
        "token": md.token,
        "generation_tool": md.generation_tool,
        "platforms": platforms,
        "sources": fmu.archive.has_sources(),
        "default_experiment": md.default_experiment.as_ref().map(|e| json!({
            "start_time": e.start_time,
            "stop_time": e.stop_time,
            "step_size": e.step_size,
            "tolerance": e.tolerance,
        })),
        "variables": variables,
    })
}

/// `spurio validate`: every problem on stdout; fails when there is an error.
pub fn validate(path: &Path) -> Result<()> {
    let fmu = Fmu::open(path)?;
    let problems = fmu.validate()?;
    for p in &problems {
        say!("{p}");
    }
    let errors = problems
        .iter()
        .filter(|p| p.severity == Severity::Error)
        .count();
    let warnings = problems.len() - errors;
    let version = fmu.model_description.version.number();
    if errors > 0 {
        bail!(
            "{}: {errors} problem(s) against FMI {version}{}",
            path.display(),
            if warnings > 0 {
                format!(" and {warnings} warning(s)")
            } else {
                String::new()
            }
        );
    }
    say!(
        "{}: valid FMI {version} (the standard's schema and rules){}",
        path.display(),
        if warnings > 0 {
            format!(", {warnings} warning(s)")
        } else {
            String::new()
        }
    );
    Ok(())
}
