//! What the pinned experiment tests share: running one experiment into a fresh folder, and
//! comparing a figure of merit with its pinned value.

#![allow(dead_code)]

use spurio_experiments::Report;
use std::path::PathBuf;

/// Runs the experiment `name` with `seeds` Monte-Carlo runs into
/// `<tmp>/spurio-exp-<tag>-<pid>/` and returns its report and that folder.
pub fn run_experiment(name: &str, tag: &str, seeds: usize) -> (Report, PathBuf) {
    let repo = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..");
    let out = std::env::temp_dir().join(format!("spurio-exp-{tag}-{}", std::process::id()));
    let mut reports = spurio_experiments::run_all(&repo, &out, &[name.into()], seeds, 0).unwrap();
    (reports.remove(0).1, out)
}

/// Asserts that the figure of merit `key` is `expected` within `tolerance`.
pub fn close(report: &Report, key: &str, expected: f64, tolerance: f64) {
    let value = report.value(key).unwrap();
    assert!(
        (value - expected).abs() <= tolerance,
        "{key} = {value}, expected {expected} ± {tolerance}"
    );
}
