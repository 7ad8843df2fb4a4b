//! Dahlquist's fixed parameter k (ẋ = −k x) identified from its own Model Exchange run plus
//! noise and 5 % outliers (`spurio_identify::synthetic::DAHLQUIST`): offline (robust maximum
//! likelihood) within 1 % of the truth, online (robust UKF, k a random-walk state) within two
//! standard deviations; without the robust weights the same data give a worse estimate.

mod common;

#[test]
fn dahlquist_k_offline_within_one_percent_and_online_within_two_sigma() {
    let (online, offline) = common::check(&spurio_identify::synthetic::DAHLQUIST);
    assert!(online > 3.0 && offline > 3.0, "{online}, {offline}");
}
