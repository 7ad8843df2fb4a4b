//! The plant opened from an FMU unpacked into a folder, as an estimator FMU carries it in its
//! `resources/`: the build without default features (no zip reader, no optimiser) runs it,
//! and a build with them gives the same trajectory from the `.fmu` archive; the estimator
//! of an FMU ([`Estimator`]) on it, sample by sample.

use nalgebra::DMatrix;
use spurio_identify::estimator::{Estimator, EstimatorError};
use spurio_identify::filter::Linearisation;
use spurio_identify::online::{joint_filter, simulate};
use spurio_identify::plant::{integration, FmuPlant, PlantSpec};
use std::cell::RefCell;
use std::path::{Path, PathBuf};
use std::rc::Rc;

#[global_allocator]
static ALLOCATOR: spurio_counting_allocator::CountingAllocator =
    spurio_counting_allocator::CountingAllocator;

fn van_der_pol() -> PathBuf {
    let fmu = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../tests/third_party/reference-fmus/fmi2/VanDerPol.fmu");
    assert!(fmu.is_file(), "{} is missing", fmu.display());
    fmu
}

fn mu_spec() -> PlantSpec {
    PlantSpec {
        free: vec!["mu".into()],
        inputs: Vec::new(),
        outputs: vec!["x0".into()],
    }
}

/// The unpacked VanDerPol (the folder is removed when the guard is dropped).
fn unpacked() -> tempfile::TempDir {
    let folder = tempfile::tempdir().unwrap();
    let status = std::process::Command::new("unzip")
        .arg("-q")
        .arg(van_der_pol())
        .arg("-d")
        .arg(folder.path())
        .status()
        .expect("unzip runs");
    assert!(status.success());
    folder
}

/// x0 at t = 0.1, 0.2, …, 2.0 with μ = 1.5, from the FMU's own initial states.
fn x0_trajectory(fmu: &Path) -> Vec<f64> {
    let mut plant =
        FmuPlant::open(fmu, &mu_spec(), integration(0.0, 1e-8)).expect("the plant opens");
    let times: Vec<f64> = (0..=20).map(|k| 0.1 * k as f64).collect();
    let rows = simulate(&mut plant, &[1.5], &times, &[]).expect("simulated");
    rows.iter().map(|y| y[0]).collect()
}

#[test]
fn an_unpacked_plant_runs_and_matches_its_archive() {
    let folder = unpacked();
    let unpacked = x0_trajectory(folder.path());
    // VanDerPol starts at x0 = 2 and, with μ = 1.5, falls through zero before t = 2
    // (the relaxation oscillation's slow branch, then its fast drop).
    assert!((unpacked[0] - 2.0).abs() < 0.05, "{unpacked:?}");
    assert!(unpacked.iter().all(|v| v.is_finite()));
    assert!(unpacked[19] < unpacked[0] - 0.5, "{unpacked:?}");
    #[cfg(feature = "offline")]
    assert_eq!(unpacked, x0_trajectory(&van_der_pol()));
}

#[test]
fn the_estimator_runs_the_identify_filter_sample_by_sample_with_finite_outputs() {
    let folder = unpacked();
    // x0 measured at t = 0, 0.1, …, 2.0 (μ = 1.5), the sample at 0.5 s missing.
    let mut y: Vec<f64> = std::iter::once(2.0)
        .chain(x0_trajectory(folder.path()))
        .collect();
    y[5] = f64::NAN;
    let robust = Some(spurio::estimation::InfluenceFunction::Huber { c: 1.645 });
    // The filter as `spurio identify --method ukf` sets it up.
    let filter = || {
        let plant = FmuPlant::open(folder.path(), &mu_spec(), integration(0.0, 1e-8)).unwrap();
        let plant = Rc::new(RefCell::new(plant));
        let x0 = plant.borrow_mut().initial_states(&[1.2]).unwrap();
        joint_filter(
            &plant,
            &[1.2],
            &x0,
            &[1e-4],
            robust,
            Linearisation::UNSCENTED,
        )
        .unwrap()
    };
    let mut estimator = Estimator::new(filter(), 0);
    assert_eq!((estimator.filter_states(), estimator.outputs()), (3, 9));
    let mut columns = Vec::new();
    for (k, yk) in y.iter().enumerate() {
        let out = estimator
            .step(0.1 * k as f64, &[], &[*yk])
            .expect("a sample");
        assert!(out.iter().all(|v| v.is_finite()), "sample {k}: {out:?}");
        columns.push(out.to_vec());
    }
    // An input the plant does not have is refused, naming the counts.
    let e = estimator.step(2.1, &[1.0], &[0.0]).err().unwrap();
    assert!(
        matches!(
            e,
            EstimatorError::Sample {
                given: 1,
                inputs: 0,
                ..
            }
        ),
        "{e}"
    );
    // The missing sample: innovation, its deviation and weight 0.
    assert_eq!(&columns[5][6..9], &[0.0, 0.0, 0.0]);
    // The same filter run over the whole record.
    let mut filter = filter();
    let times: Vec<f64> = (0..y.len()).map(|k| 0.1 * k as f64).collect();
    let rows: Vec<Vec<f64>> = y.iter().map(|v| vec![*v]).collect();
    let run = filter
        .run(&times, &vec![Vec::new(); y.len()], &rows)
        .unwrap();
    for (k, column) in columns.iter().enumerate() {
        // ẑ and √diag P, bit for bit.
        assert_eq!(
            column[..6],
            run.values.column(k).as_slice()[..6],
            "sample {k}"
        );
    }
    // θ̂ = μ̂ moves from the start 1.2 towards the truth 1.5.
    let last = &columns[y.len() - 1];
    let (mu, sd) = (last[2], last[5]);
    let trajectory = DMatrix::from_fn(1, y.len(), |_, k| columns[k][2]);
    // Measured: 1.49864 ± 0.0141 after 2 s (from 1.2 ± 0.24).
    assert!(
        (mu - 1.5).abs() < 0.01 && (mu - 1.5).abs() < 3.0 * sd,
        "μ̂ = {mu} ± {sd}, {trajectory}"
    );
    assert!(sd < 0.03, "σ(μ̂) = {sd} from the prior 0.24");
}

/// The estimator of `linearisation` (robust, Huber) over x0 of VanDerPol with a missing
/// sample (0.5 s) and an outlier (+1 at 1.2 s): the heap allocations of each sample's step
/// (the first sizes the filter's work buffers) and the last output vector.
fn allocations_per_sample(folder: &Path, linearisation: Linearisation) -> (Vec<u64>, Vec<f64>) {
    let mut y: Vec<f64> = std::iter::once(2.0).chain(x0_trajectory(folder)).collect();
    y[5] = f64::NAN;
    y[12] += 1.0;
    let robust = Some(spurio::estimation::InfluenceFunction::Huber { c: 1.645 });
    let plant = FmuPlant::open(folder, &mu_spec(), integration(0.0, 1e-8)).unwrap();
    let plant = Rc::new(RefCell::new(plant));
    let x0 = plant.borrow_mut().initial_states(&[1.2]).unwrap();
    let filter = joint_filter(&plant, &[1.2], &x0, &[1e-4], robust, linearisation).unwrap();
    let mut estimator = Estimator::new(filter, 0);
    let mut out = vec![0.0; estimator.outputs()];
    let mut allocations = Vec::new();
    for (k, yk) in y.iter().enumerate() {
        let (step, counts) = spurio_counting_allocator::count(|| {
            estimator
                .step(0.1 * k as f64, &[], &[*yk])
                .map(|column| out.copy_from_slice(column))
        });
        step.unwrap_or_else(|e| panic!("sample {k}: {e}"));
        allocations.push(counts.allocations);
        // The outlier is down-weighted (w < 1), the missing sample has weight 0.
        let w = out[2 * 3 + 2];
        match k {
            5 => assert_eq!(w, 0.0),
            12 => assert!(w < 0.5, "the outlier's weight {w}"),
            _ => {}
        }
    }
    (allocations, out)
}

#[test]
fn the_estimator_allocates_nothing_after_its_first_sample() {
    let folder = unpacked();
    let runs = [Linearisation::UNSCENTED, Linearisation::Extended].map(|linearisation| {
        (
            linearisation,
            allocations_per_sample(folder.path(), linearisation),
        )
    });
    for (linearisation, (allocations, _)) in &runs {
        println!("{linearisation:?}: allocations per sample {allocations:?}");
    }
    for (linearisation, (allocations, last)) in runs {
        // μ̂ still moves to the truth 1.5 through the outlier.
        assert!(
            (last[2] - 1.5).abs() < 0.05,
            "{linearisation:?}: μ̂ = {}",
            last[2]
        );
        // Neither filter allocates: not the filter, the plant or the stepper (measured
        // before: 245–290 a sample for either), nor the EKF's matrix exponential of Φ_xx
        // (nalgebra's `DMatrix::exp` made 30–37 a sample here).
        assert!(
            allocations[1..].iter().all(|&a| a == 0),
            "{linearisation:?}: allocations per sample {allocations:?}"
        );
    }
}
