//! Van der Pol's fixed parameter μ (set only before initialisation: every new μ resets the
//! instance) identified from its own Model Exchange run plus noise and 5 % outliers
//! (`spurio_identify::synthetic::VAN_DER_POL`).

mod common;

#[test]
fn van_der_pol_mu_offline_within_one_percent_and_online_within_two_sigma() {
    let (online, offline) = common::check(&spurio_identify::synthetic::VAN_DER_POL);
    assert!(online > 1.5 && offline > 1.5, "{online}, {offline}");
}
