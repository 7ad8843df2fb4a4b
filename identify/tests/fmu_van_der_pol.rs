//! Van der Pol's fixed parameter μ (set only before initialisation: every new μ resets the
//! instance) identified from its own Model Exchange run plus noise and 5 % outliers.

mod common;

#[test]
fn van_der_pol_mu_offline_within_one_percent_and_online_within_two_sigma() {
    let (online, offline) = common::Case {
        model: "VanDerPol",
        parameter: "mu",
        outputs: &["x0"],
        truth: 1.3,
        start: 1.0,
        sigma: 0.02,
        samples: 201,
        step: 0.05,
        state_variance: 1e-4,
        state_noise: 1e-8,
        parameter_variance: 0.25,
    }
    .check();
    assert!(online > 1.5 && offline > 1.5, "{online}, {offline}");
}
