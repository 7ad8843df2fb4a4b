//! The plant opened from an FMU unpacked into a folder, as an estimator FMU carries it in its
//! `resources/`: the build without default features (no zip reader, no optimiser) runs it,
//! and a build with them gives the same trajectory from the `.fmu` archive.

use spurio_identify::plant::{integration, FmuPlant, PlantSpec, Start};
use std::path::{Path, PathBuf};

fn van_der_pol() -> PathBuf {
    let fmu = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../tests/third_party/reference-fmus/fmi2/VanDerPol.fmu");
    assert!(fmu.is_file(), "{} is missing", fmu.display());
    fmu
}

/// x0 at t = 0.1, 0.2, …, 2.0 with μ = 1.5, from the FMU's own initial states.
fn x0_trajectory(fmu: &Path) -> Vec<f64> {
    let spec = PlantSpec {
        free: vec!["mu".into()],
        inputs: Vec::new(),
        outputs: vec!["x0".into()],
    };
    let mut plant = FmuPlant::open(fmu, &spec, integration(0.0, 1e-8)).expect("the plant opens");
    let theta = [1.5];
    let mut x = plant.initial_states(&theta).expect("initialised");
    let mut x_next = x.clone();
    let mut y = [0.0];
    let mut out = Vec::new();
    for k in 0..20 {
        let start = Start {
            time: 0.1 * k as f64,
            states: &x,
            parameters: &theta,
            inputs: &[],
            reference: None,
        };
        plant
            .propagate(&start, 0.1 * (k + 1) as f64, &mut x_next, &mut y)
            .expect("propagated");
        x.copy_from_slice(&x_next);
        out.push(y[0]);
    }
    out
}

#[test]
fn an_unpacked_plant_runs_and_matches_its_archive() {
    let folder = tempfile::tempdir().unwrap();
    let status = std::process::Command::new("unzip")
        .arg("-q")
        .arg(van_der_pol())
        .arg("-d")
        .arg(folder.path())
        .status()
        .expect("unzip runs");
    assert!(status.success());
    let unpacked = x0_trajectory(folder.path());
    // VanDerPol starts at x0 = 2 and, with μ = 1.5, falls through zero before t = 2
    // (the relaxation oscillation's slow branch, then its fast drop).
    assert!((unpacked[0] - 2.0).abs() < 0.05, "{unpacked:?}");
    assert!(unpacked.iter().all(|v| v.is_finite()));
    assert!(unpacked[19] < unpacked[0] - 0.5, "{unpacked:?}");
    #[cfg(feature = "offline")]
    assert_eq!(unpacked, x0_trajectory(&van_der_pol()));
}
