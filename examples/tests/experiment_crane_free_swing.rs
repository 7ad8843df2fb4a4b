//! Pins the crane free-swing figure (needs `scripts/build-fmus`).

mod common;

use common::{run_pinned, value};

#[test]
fn free_swing_period_is_within_half_a_percent_of_the_linear_model() {
    let (report, out) = run_pinned("crane_free_swing", "swing", 100);
    let error = value(&report, "period_error");
    assert!(error < 5e-3, "period error {error}");
    assert!(out.join("REPORT.md").is_file());
}
