//! Pins the distributed-observer figures (paper 004 §5; needs `scripts/build-fmus`).

mod common;

use common::{run_pinned, value};

#[test]
fn lq_gains_are_the_papers_and_the_local_gain_is_near_the_central_filter() {
    let (report, _) = run_pinned("distributed_observer", "obs", 100);
    let v = |key: &str| value(&report, key);
    assert!(v("e_ac_central_filtered") < v("e_ac_central_prediction"));
    // Only ρ/λ matters.
    assert!(v("rho_lambda_spread") < 1e-9, "{}", v("rho_lambda_spread"));
}
