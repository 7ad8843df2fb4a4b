//! Pins the crane free-swing figure (needs `scripts/build-fmus`).

use std::path::PathBuf;

#[test]
fn free_swing_period_is_within_half_a_percent_of_the_linear_model() {
    let repo = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..");
    let out = std::env::temp_dir().join(format!("spurio-exp-swing-{}", std::process::id()));
    let reports =
        spurio_experiments::run_all(&repo, &out, &["crane_free_swing".into()], 100, 0).unwrap();
    let report = &reports[0].1;
    assert!(report.all_goals_met(), "{}", report.to_markdown(""));
    let error = report.value("period_error").unwrap();
    assert!(error < 5e-3, "period error {error}");
    assert!(out.join("crane_free_swing/crane_free_swing.png").is_file());
    assert!(out.join("REPORT.md").is_file());
}
