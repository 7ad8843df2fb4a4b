//! BouncingBall's tunable coefficient of restitution e (set in Event Mode), identified through
//! its bounces from its own Model Exchange run plus noise and 5 % outliers
//! (`spurio_identify::synthetic::BOUNCING_BALL`).

mod common;

#[test]
fn bouncing_ball_e_offline_within_one_percent_and_online_within_two_sigma() {
    let (online, offline) = common::check(&spurio_identify::synthetic::BOUNCING_BALL);
    assert!(online > 1.5 && offline > 1.5, "{online}, {offline}");
}
