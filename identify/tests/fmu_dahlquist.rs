//! Dahlquist's fixed parameter k (ẋ = −k x) identified from its own Model Exchange run plus
//! noise and 5 % outliers: offline (robust maximum likelihood) within 1 % of the truth,
//! online (robust UKF, k a random-walk state) within two standard deviations; without the
//! robust weights the same data give a worse estimate.

mod common;

#[test]
fn dahlquist_k_offline_within_one_percent_and_online_within_two_sigma() {
    let (online, offline) = common::Case {
        model: "Dahlquist",
        parameter: "k",
        outputs: &["x"],
        truth: 1.5,
        start: 1.0,
        sigma: 0.005,
        samples: 101,
        step: 0.05,
        state_variance: 1e-6,
        state_noise: 0.0,
        parameter_variance: 0.25,
    }
    .check();
    assert!(online > 3.0 && offline > 3.0, "{online}, {offline}");
}
