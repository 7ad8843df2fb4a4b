//! Pins the crane free-swing figure (needs `scripts/build-fmus`).

mod common;

use common::run_experiment;

#[test]
fn free_swing_period_is_within_half_a_percent_of_the_linear_model() {
    let (report, out) = run_experiment("crane_free_swing", "swing", 100);
    let report = &report;
    assert!(report.all_goals_met(), "{}", report.to_markdown(""));
    let error = report.value("period_error").unwrap();
    assert!(error < 5e-3, "period error {error}");
    assert!(out.join("crane_free_swing/crane_free_swing.png").is_file());
    assert!(out.join("REPORT.md").is_file());
}
