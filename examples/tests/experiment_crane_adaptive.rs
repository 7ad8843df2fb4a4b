//! Pins the adaptive-crane figures (paper 000 §VII-B, Figs. 7–8; needs `scripts/build-fmus`).
//! 30 seeds keep it short; the bounds leave room for the seed-to-seed spread but not for a
//! regression (e.g. the cleaner starting at 0 again, which saturates some runs at 17 N).

mod common;

use common::run_experiment;

#[test]
fn dkf_rskf_brings_the_crane_to_rest_where_the_dkf_alone_does_not() {
    let (report, out) = run_experiment("crane_adaptive", "crane-adaptive", 30);
    let report = &report;
    let text = report.to_markdown("");
    assert!(report.all_goals_met(), "{text}");
    let v = |key: &str| report.value(key).unwrap_or_else(|| panic!("no {key}"));
    let within = |key: &str, lo: f64, hi: f64| {
        let x = v(key);
        assert!(
            (lo..=hi).contains(&x),
            "{key} = {x}, expected [{lo}, {hi}]\n{text}"
        );
    };
    assert_eq!(v("runs"), 30.0);
    // The reference design on the true states (and the sensor settings derived from it).
    within("reference_rest", 4.1, 4.2);
    within("x_rms", 0.0559, 0.0560);
    within("theta_rms", 0.00375, 0.00377);
    // Fig. 8: DKF-rsKF with 5 % outliers.
    assert_eq!(v("rskf_at_rest_fraction"), 1.0);
    within("rskf_before_15s_fraction", 0.95, 1.0);
    within("rskf_rest_mean", 6.0, 9.0);
    within("rskf_rest_std", 0.5, 3.0);
    within("rskf_effort_mean", 0.021, 0.025);
    within("rskf_max_force", 0.27, 0.30);
    // Fig. 7 with outliers: the DKF alone hardly ever comes to rest.
    within("dkf_at_rest_fraction", 0.0, 0.2);
    within("dkf_censored_rest_mean", 37.0, 40.0);
    within("rest_ratio", 0.0, 0.3);
    within("dkf_effort_mean", 0.03, 0.06);
    within("dkf_max_force", 0.27, 17.0);
    // Smoother control, quieter angle with the rsKF.
    assert!(
        v("rskf_variation_mean") < 0.4 * v("dkf_variation_mean"),
        "{text}"
    );
    assert!(
        v("rskf_late_theta_rms") < 0.4 * v("dkf_late_theta_rms"),
        "{text}"
    );
    // The parameter filter (papers' r_theta = 0.5) keeps the initial model.
    within("initial_model_error", 0.12, 0.13);
    within("rskf_model_error", 0.11, 0.14);
    // Without outliers the DKF alone settles; from the exact model the DKF-rsKF is faster.
    assert_eq!(v("dkf_clean_at_rest_fraction"), 1.0);
    within("dkf_clean_rest_mean", 6.5, 8.0);
    within("rskf_exact_rest_mean", 3.0, 4.5);
    within("dkf_exact_at_rest_fraction", 0.0, 0.3);
    // The representative run and the files.
    within("representative_rskf_rest", 5.0, 10.0);
    assert!(v("representative_rskf_effort") < v("representative_dkf_effort"));
    for file in [
        "crane_adaptive.png",
        "crane_adaptive_estimates.png",
        "dkf.csv",
        "dkf_rskf.csv",
        "reference.csv",
        "monte_carlo.csv",
        "report.md",
    ] {
        assert!(out.join("crane_adaptive").join(file).is_file(), "{file}");
    }
}
