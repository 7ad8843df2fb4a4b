//! Pins the wind-generator identification figures (paper 001 §5; needs `scripts/build-fmus`).

mod common;

use common::run_pinned;

#[test]
fn dkf_rskf_keeps_the_outliers_out_of_the_identified_output() {
    run_pinned("generator_identification", "gen", 100);
}
