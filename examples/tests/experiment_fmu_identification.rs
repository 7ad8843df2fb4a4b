//! Pins the identification of the Reference FMUs' parameters and of the Nile local level
//! (≈ 2 s in release): offline within 1 % of the truth, online within 2 σ, `--robust none`
//! worse, the Nile's variances and log-likelihood to three significant digits
//! (examples/tests/pinned.toml).

mod common;

use common::run_pinned;

#[test]
fn reference_fmu_parameters_and_the_nile_are_identified() {
    // Every goal met, and the figures identify/tests/fmu_*.rs and nile.rs print (pinned.toml).
    let (report, out) = run_pinned("fmu_identification", "fmu-identification", 1);
    // Three goals per parameter (offline, online, the ratio) and three of the Nile.
    let goals = report.rows.iter().filter(|r| r.met == Some(true)).count();
    assert_eq!(goals, 12, "{}", report.to_markdown(""));
    // Three panels per model: the measurements, θ̂ ± σ over the run and over its second half.
    let (width, height) = png_size(&out.join("fmu_identification/BouncingBall_e.png"));
    assert_eq!((width, height), (1100, 840));
}

/// A PNG's width and height from its IHDR chunk.
fn png_size(path: &std::path::Path) -> (u32, u32) {
    let bytes = std::fs::read(path).unwrap();
    assert_eq!(&bytes[1..4], b"PNG", "{} is not a PNG", path.display());
    let word = |at: usize| u32::from_be_bytes(bytes[at..at + 4].try_into().unwrap());
    (word(16), word(20))
}
