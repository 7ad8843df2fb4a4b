//! BouncingBall's tunable coefficient of restitution e (set in Event Mode), identified through
//! its bounces from its own Model Exchange run plus noise and 5 % outliers.

mod common;

#[test]
fn bouncing_ball_e_offline_within_one_percent_and_online_within_two_sigma() {
    let (online, offline) = common::Case {
        model: "BouncingBall",
        parameter: "e",
        outputs: &["h"],
        truth: 0.8,
        start: 0.7,
        sigma: 0.01,
        samples: 301,
        step: 0.01,
        state_variance: 1e-6,
        state_noise: 1e-8,
        parameter_variance: 0.01,
    }
    .check();
    assert!(online > 1.5 && offline > 1.5, "{online}, {offline}");
}
