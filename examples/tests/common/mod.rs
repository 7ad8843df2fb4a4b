//! What the pinned experiment tests share: running one experiment into a fresh folder (the
//! packaged FMUs built first if they are missing) and checking its figures of merit and files
//! against `examples/tests/pinned.toml`.

use spurio_experiments::Report;
use std::path::PathBuf;

#[path = "../../../master/tests/common/packaged_fmus.rs"]
mod packaged_fmus;

/// Runs the experiment `name` with `seeds` Monte-Carlo runs into
/// `<tmp>/spurio-exp-<tag>-<pid>/`, asserts that its report meets every goal but those
/// `pinned.toml` pins as unmet (and not those) and that its figures and files are the ones it
/// pins, and returns the report and that folder.
pub fn run_pinned(name: &str, tag: &str, seeds: usize) -> (Report, PathBuf) {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    packaged_fmus::packaged_fmus(&root.join(".."));
    let out = std::env::temp_dir().join(format!("spurio-exp-{tag}-{}", std::process::id()));
    let mut reports = spurio_experiments::run_all(&root.join(".."), &out, &[name.into()], seeds, 0)
        .unwrap_or_else(|e| panic!("experiment {name}: {e:?}"));
    let report = reports.remove(0).1;
    let text = report.to_markdown("");
    let pinned: toml::Table = std::fs::read_to_string(root.join("tests/pinned.toml"))
        .unwrap()
        .parse()
        .unwrap();
    let pinned = pinned[name].as_table().unwrap();
    // The goals pinned as not met (`unmet`: quantity prefixes); every other goal is met.
    let unmet: Vec<&str> = pinned
        .get("unmet")
        .map(|v| {
            v.as_array()
                .unwrap()
                .iter()
                .map(|q| q.as_str().unwrap())
                .collect()
        })
        .unwrap_or_default();
    for row in report.rows.iter().filter(|r| r.met.is_some()) {
        let expected = !unmet.iter().any(|q| row.quantity.starts_with(q));
        assert_eq!(
            row.met,
            Some(expected),
            "goal of `{}`: expected {}\n{text}",
            row.quantity,
            if expected { "met" } else { "not met" }
        );
    }
    for (key, expected, tolerance) in pairs(pinned, "close") {
        let x = value(&report, &key);
        assert!(
            (x - expected).abs() <= tolerance,
            "{key} = {x}, expected {expected} ± {tolerance}\n{text}"
        );
    }
    for (key, low, high) in pairs(pinned, "within") {
        let x = value(&report, &key);
        assert!(
            (low..=high).contains(&x),
            "{key} = {x}, expected [{low}, {high}]\n{text}"
        );
    }
    for file in pinned["files"].as_array().unwrap() {
        let path = out.join(name).join(file.as_str().unwrap());
        assert!(path.is_file(), "no {}", path.display());
    }
    (report, out)
}

/// The figure of merit `key`.
pub fn value(report: &Report, key: &str) -> f64 {
    report
        .value(key)
        .unwrap_or_else(|| panic!("no {key}\n{}", report.to_markdown("")))
}

/// The `key = [a, b]` entries of the table `section` (none if it is absent).
fn pairs(pinned: &toml::Table, section: &str) -> Vec<(String, f64, f64)> {
    let Some(table) = pinned.get(section) else {
        return Vec::new();
    };
    let number = |v: &toml::Value| v.as_float().unwrap_or_else(|| panic!("{section}: {v}"));
    table
        .as_table()
        .unwrap()
        .iter()
        .map(|(key, pair)| {
            let pair = pair.as_array().unwrap();
            assert_eq!(pair.len(), 2, "{section}.{key}");
            (key.clone(), number(&pair[0]), number(&pair[1]))
        })
        .collect()
}
