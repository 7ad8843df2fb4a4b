//! Pins the op-amp identification figures of paper 002 (needs `scripts/build-fmus`).

mod common;

use common::{close, run_experiment};

#[test]
fn steiglitz_mcbride_identifies_the_filter_from_a_step_and_a_prbs() {
    let (report, out) = run_experiment("opamp_identification", "opamp", 100);
    let report = &report;
    assert!(report.all_goals_met(), "{}", report.to_markdown(""));
    // Unit step (paper 002): mean relative errors over 100 seeds, in percent.
    close(report, "step_wn_error", 1.73, 0.3);
    close(report, "step_zeta_error", 1.66, 0.3);
    close(report, "step_overshoot_error", 4.05, 0.5);
    close(report, "step_settling_error", 2.45, 0.5);
    close(report, "step_zeta", 0.4953, 0.003);
    close(report, "step_converged", 100.0, 0.0);
    // PRBS: a better-exciting input, errors below 2 %.
    close(report, "prbs_wn_error", 0.44, 0.15);
    close(report, "prbs_zeta_error", 0.70, 0.2);
    close(report, "prbs_overshoot_error", 1.69, 0.4);
    close(report, "prbs_settling_error", 0.72, 0.2);
    close(report, "prbs_converged", 100.0, 0.0);
    // Plain least squares has no continuous equivalent on this noisy record.
    close(report, "step_plain_available", 0.0, 0.0);
    for file in [
        "step_fit.png",
        "prbs_fit.png",
        "step_seed1.csv",
        "prbs_seed1.csv",
    ] {
        assert!(
            out.join("opamp_identification").join(file).is_file(),
            "{file}"
        );
    }
}
