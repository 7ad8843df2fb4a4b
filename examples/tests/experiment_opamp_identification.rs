//! Pins the op-amp identification figures of paper 002 (needs `scripts/build-fmus`).

mod common;

use common::run_pinned;

#[test]
fn steiglitz_mcbride_identifies_the_filter_from_a_step_and_a_prbs() {
    run_pinned("opamp_identification", "opamp", 100);
}
