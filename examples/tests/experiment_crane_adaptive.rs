//! Pins the adaptive-crane figures (paper 000 §VII-B, Figs. 7–8; needs `scripts/build-fmus`).
//! 30 seeds keep it short; the bounds leave room for the seed-to-seed spread but not for a
//! regression (e.g. the cleaner starting at 0 again, which saturates some runs at 17 N).

mod common;

use common::{run_pinned, value};

#[test]
fn dkf_rskf_brings_the_crane_to_rest_where_the_dkf_alone_does_not() {
    let (report, _) = run_pinned("crane_adaptive", "crane-adaptive", 30);
    let v = |key: &str| value(&report, key);
    // Smoother control, quieter angle with the rsKF.
    for key in ["variation_mean", "late_theta_rms"] {
        let (rskf, dkf) = (v(&format!("rskf_{key}")), v(&format!("dkf_{key}")));
        assert!(rskf < 0.4 * dkf, "rsKF {key} {rskf} vs DKF {dkf}");
    }
    // The representative run.
    assert!(v("representative_rskf_effort") < v("representative_dkf_effort"));
}
