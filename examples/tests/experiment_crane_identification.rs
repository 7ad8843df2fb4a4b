//! Pins the crane's identification as a physical model (needs `scripts/build-fmus`):
//! M, l, f_c of the GantryCrane ME FMU offline within 2 % and online within 5 % at 40 s from
//! the recorded closed-loop run with 20 dB noise and 5 % outliers (≈ 11 s in release).

mod common;

use common::{run_pinned, value};

#[test]
fn crane_mass_length_and_friction_are_identified_offline_and_online() {
    let (report, _) = run_pinned("crane_identification", "crane-identification", 1);
    for name in ["M", "l", "f_c"] {
        let offline = value(&report, &format!("{name}_offline_error"));
        let online = value(&report, &format!("{name}_online_error"));
        assert!(
            offline < 0.02 && online < 0.05,
            "{name}: {offline}, {online}"
        );
    }
}
