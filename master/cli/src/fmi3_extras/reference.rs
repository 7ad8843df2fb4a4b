//! The reference results of the layered standard `fmi-ls-ref` (schema
//! `fmi3LayeredStandardReferenceManifest.xsd`), laid out as the Reference FMUs (v0.0.41)
//! carry theirs: `extra/org.fmi-standard.fmi-ls-ref/` with `fmi-ls-manifest.xml`,
//! `<Model>_out.csv` and, for a model with inputs, `<Model>_in.csv`.
//!
//! They are the FMU's cross-check scenario (`fmus/<Id>/crosscheck/<Model>_in.csv`,
//! `_ref.csv`, `_ref.opt`; `scripts/crosscheck.py`), whose columns are the FMI 2.0 twin's
//! scalars: here each FMI 3.0 variable is one column, an array's elements in one cell
//! separated by spaces (row-major, as fmpy writes and reads arrays). The cells are copied as
//! written (17 significant digits), so they read back bit-identical. The FMI 3.0 FMU gives
//! the FMI 2.0 twin's outputs bit for bit (`tests/fmpy/test_fmi3.py`), so the same numbers
//! are its reference.
//!
//! The manifest names one `<Experiment>` (the scenario: start, stop, step size; its
//! `<Stimuli>` and `<References>`) as the schema requires, and, as the Reference FMUs do, the
//! results once more as a `<Related role="result">` for tools that read only those.

use super::{escape, Direction, ExtrasError, Signal};
use std::path::Path;

/// The folder of the layered standard in the archive.
pub const FOLDER: &str = "extra/org.fmi-standard.fmi-ls-ref";

/// The layered standard's version written (that of the schema in its repository).
pub const LS_VERSION: &str = "1.0.0-rc.1";

/// The `fmi-ls-description` the schema fixes.
const LS_DESCRIPTION: &str = "Layered Standard providing reference stimuli and results for an FMU.";

/// The experiment of a `_ref.opt` file.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Experiment {
    pub start: f64,
    pub stop: f64,
    pub step: f64,
    /// `RelTol`: the relative tolerance a comparison with the results allows.
    pub rel_tol: f64,
}

/// Reads a `_ref.opt` (`Key, value` lines).
pub fn read_opt(text: &str) -> Result<Experiment, String> {
    let value = |key: &str| -> Result<f64, String> {
        text.lines()
            .filter_map(|line| line.split_once(','))
            .find(|(k, _)| k.trim() == key)
            .ok_or_else(|| format!("no `{key}` line"))
            .and_then(|(_, v)| v.trim().parse::<f64>().map_err(|e| format!("`{key}`: {e}")))
    };
    Ok(Experiment {
        start: value("StartTime")?,
        stop: value("StopTime")?,
        step: value("StepSize")?,
        rel_tol: value("RelTol")?,
    })
}

/// A cross-check table (FMI 2.0 scalar columns) rewritten with the FMI 3.0 `signals` as
/// columns: `time`, then each signal's elements joined by spaces. Every signal must have
/// its columns, and every column must belong to a signal.
pub fn regroup(table: &str, signals: &[&Signal]) -> Result<String, String> {
    let mut reader = csv::ReaderBuilder::new()
        .has_headers(true)
        .from_reader(table.as_bytes());
    let header: Vec<String> = reader
        .headers()
        .map_err(|e| e.to_string())?
        .iter()
        .map(|h| h.to_string())
        .collect();
    if header.first().map(String::as_str) != Some("time") {
        return Err("the first column is not `time`".into());
    }
    let column = |name: &str| {
        header
            .iter()
            .position(|h| h == name)
            .ok_or_else(|| format!("no column `{name}`"))
    };
    let groups: Vec<Vec<usize>> = signals
        .iter()
        .map(|s| s.element_names().iter().map(|n| column(n)).collect())
        .collect::<Result<_, _>>()?;
    let used = 1 + groups.iter().map(Vec::len).sum::<usize>();
    if used != header.len() {
        let known: Vec<String> = signals.iter().flat_map(|s| s.element_names()).collect();
        let extra: Vec<&str> = header[1..]
            .iter()
            .filter(|h| !known.contains(h))
            .map(String::as_str)
            .collect();
        return Err(format!(
            "columns that are no {} of the model: {}",
            signals
                .first()
                .map_or("signal", |s| s.direction.causality()),
            extra.join(", ")
        ));
    }
    let mut writer = csv::WriterBuilder::new()
        .terminator(csv::Terminator::Any(b'\n'))
        .from_writer(Vec::new());
    let names = std::iter::once("time").chain(signals.iter().map(|s| s.name.as_str()));
    writer.write_record(names).map_err(|e| e.to_string())?;
    for (row, record) in reader.records().enumerate() {
        let record = record.map_err(|e| format!("row {}: {e}", row + 2))?;
        let cells = std::iter::once(record.get(0).unwrap_or("").to_string()).chain(
            groups.iter().map(|g| {
                g.iter()
                    .map(|&k| record.get(k).unwrap_or(""))
                    .collect::<Vec<_>>()
                    .join(" ")
            }),
        );
        writer.write_record(cells).map_err(|e| e.to_string())?;
    }
    let bytes = writer.into_inner().map_err(|e| e.to_string())?;
    String::from_utf8(bytes).map_err(|e| e.to_string())
}

/// The manifest of the scenario `model` (with `_in.csv` when `stimuli`).
pub fn manifest(model: &str, experiment: &Experiment, stimuli: bool) -> String {
    let model = escape(model);
    let stimuli = if stimuli {
        format!("\n    <Stimuli source=\"{model}_in.csv\"/>")
    } else {
        String::new()
    };
    format!(
        r#"<?xml version="1.0" encoding="UTF-8"?>
<fmiReferences
    xmlns:fmi-ls="http://fmi-standard.org/fmi-ls-manifest"
    fmi-ls:fmi-ls-name="org.fmi-standard.fmi-ls-ref"
    fmi-ls:fmi-ls-version="{LS_VERSION}"
    fmi-ls:fmi-ls-description="{LS_DESCRIPTION}">
  <Experiment name="crosscheck" description="The FMU's cross-check scenario: the inputs held over each step, the outputs after the start and after every step (equal to a relative tolerance of {rel_tol:e})" startTime="{start:?}" stopTime="{stop:?}" stepSize="{step:?}">{stimuli}
    <References source="{model}_out.csv"/>
  </Experiment>
  <Related type="text/csv" source="{model}_out.csv" role="result" description="Outputs of the cross-check scenario"/>
</fmiReferences>
"#,
        rel_tol = experiment.rel_tol,
        start = experiment.start,
        stop = experiment.stop,
        step = experiment.step,
    )
}

/// The files of `extra/org.fmi-standard.fmi-ls-ref/` (path in the archive, text) for the
/// model `model` with the FMI 3.0 `signals`, from the cross-check files in `crosscheck`
/// (`<model>_ref.opt`, `_ref.csv`, `_in.csv`); none when the model has no `_ref.csv` (a
/// variant packaged on request).
pub fn files(
    model: &str,
    signals: &[Signal],
    crosscheck: &Path,
) -> Result<Vec<(String, String)>, ExtrasError> {
    let path = |suffix: &str| crosscheck.join(format!("{model}{suffix}"));
    if !path("_ref.csv").is_file() {
        return Ok(Vec::new());
    }
    let read = |suffix: &str| {
        std::fs::read_to_string(path(suffix)).map_err(|e| ExtrasError::CrossCheck {
            model: model.to_string(),
            file: path(suffix).display().to_string(),
            reason: e.to_string(),
        })
    };
    let fail = |suffix: &str, reason: String| ExtrasError::CrossCheck {
        model: model.to_string(),
        file: path(suffix).display().to_string(),
        reason,
    };
    let experiment = read_opt(&read("_ref.opt")?).map_err(|r| fail("_ref.opt", r))?;
    let of = |direction| -> Vec<&Signal> {
        signals
            .iter()
            .filter(|s| s.direction == direction)
            .collect()
    };
    let outputs =
        regroup(&read("_ref.csv")?, &of(Direction::Output)).map_err(|r| fail("_ref.csv", r))?;
    let inputs = of(Direction::Input);
    let mut files = Vec::new();
    if !inputs.is_empty() {
        let table = regroup(&read("_in.csv")?, &inputs).map_err(|r| fail("_in.csv", r))?;
        files.push((format!("{FOLDER}/{model}_in.csv"), table));
    }
    files.push((format!("{FOLDER}/{model}_out.csv"), outputs));
    files.push((
        format!("{FOLDER}/fmi-ls-manifest.xml"),
        manifest(model, &experiment, !inputs.is_empty()),
    ));
    Ok(files)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn signal(name: &str, direction: Direction, dims: &[usize]) -> Signal {
        Signal {
            name: name.into(),
            direction,
            type_name: "Float64".into(),
            dimensions: dims.to_vec(),
            description: None,
        }
    }

    #[test]
    fn scalar_columns_are_regrouped_into_arrays_cell_for_cell() {
        let table =
            "time,\"L[1,1]\",\"L[1,2]\",n\n0.0,0.1,0.2,3\n0.5,1.0000000000000002,-2e-300,4\n";
        let l = signal("L", Direction::Output, &[1, 2]);
        let n = signal("n", Direction::Output, &[]);
        let out = regroup(table, &[&l, &n]).unwrap();
        assert_eq!(
            out,
            "time,L,n\n0.0,0.1 0.2,3\n0.5,1.0000000000000002 -2e-300,4\n"
        );
        let err = regroup(table, &[&l]).unwrap_err();
        assert!(
            err.contains("columns that are no output") && err.contains('n'),
            "{err}"
        );
        let m = signal("m", Direction::Output, &[]);
        assert_eq!(regroup(table, &[&l, &n, &m]).unwrap_err(), "no column `m`");
    }

    #[test]
    fn the_manifest_names_the_experiment_and_its_files() {
        let opt = "StartTime, 0.0\nStopTime, 10.0\nStepSize, 0.05\nRelTol, 1e-06\n";
        let e = read_opt(opt).unwrap();
        assert_eq!(
            (e.start, e.stop, e.step, e.rel_tol),
            (0.0, 10.0, 0.05, 1e-6)
        );
        let m = manifest("GantryCrane", &e, true);
        assert!(
            m.contains(r#"startTime="0.0" stopTime="10.0" stepSize="0.05">"#),
            "{m}"
        );
        assert!(m.contains(r#"<Stimuli source="GantryCrane_in.csv"/>"#));
        assert!(m.contains(r#"<References source="GantryCrane_out.csv"/>"#));
        assert!(m.contains("relative tolerance of 1e-6"));
        assert!(!manifest("SignalSource", &e, false).contains("Stimuli"));
        assert!(read_opt("StartTime, 0\n").unwrap_err().contains("StopTime"));
    }
}
