//! A parameter identified near the edge of its declared range (the packaged GantryCrane):
//! the GantryCrane ME FMU refuses a value outside [min, max] (`f_c` ≥ 0), so an online filter
//! whose sigma points, or whose corrected mean, leave the range would stop with the plant's
//! error. A well-greased rail (f_c = 0.02 N·s/m) started from the FMU's default 0.67 takes the
//! estimate through that edge: the filters evaluate the plant at the parameter held to its
//! range and keep θ̂ inside it (docs/estimators.md, "Parameters within their declared range").

use spurio::estimation::InfluenceFunction;
use spurio_identify::filter::Linearisation;
use spurio_identify::online::{joint_filter, simulate};
use spurio_identify::plant::{integration, FmuPlant, PlantSpec};
use spurio_identify::synthetic::Normal;
use std::cell::RefCell;
use std::path::PathBuf;
use std::rc::Rc;

const TRUTH: f64 = 0.02;
const START: f64 = 0.67;
const SIGMA: [f64; 2] = [1e-3, 1e-3];
const STEP: f64 = 0.02;
const SAMPLES: usize = 501;

#[path = "../../master/tests/common/packaged_fmus.rs"]
mod packaged_fmus;

fn crane() -> Rc<RefCell<FmuPlant>> {
    let repo = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..");
    let fmu = packaged_fmus::packaged_fmus(&repo).join("GantryCrane.fmu");
    spurio_identify::plant::keep_plant_messages();
    let spec = PlantSpec {
        free: vec!["f_c".into()],
        inputs: vec!["U".into()],
        outputs: vec!["x".into(), "theta".into()],
    };
    let mut plant = FmuPlant::open(&fmu, &spec, integration(0.0, 1e-8))
        .unwrap_or_else(|e| panic!("{}: {e}", fmu.display()));
    plant.set_values(&[("x0".into(), 0.0)]).unwrap();
    Rc::new(RefCell::new(plant))
}

/// The record: a ±0.3 N square wave of period 2 s (its first half period cut short, so the
/// cart swings about the rail's centre) from rest there, x and θ
/// with noise of standard deviation 1 mm and 1 mrad (seeded).
fn record(plant: &Rc<RefCell<FmuPlant>>) -> (Vec<f64>, Vec<Vec<f64>>, Vec<Vec<f64>>) {
    let time: Vec<f64> = (0..SAMPLES).map(|k| k as f64 * STEP).collect();
    let force = |t: f64| {
        if (t + 0.5).floor() as i64 % 2 == 0 {
            0.3
        } else {
            -0.3
        }
    };
    let inputs: Vec<Vec<f64>> = time.iter().map(|t| vec![force(*t)]).collect();
    let clean = simulate(&mut plant.borrow_mut(), &[TRUTH], &time, &inputs).unwrap();
    let mut noise = Normal::new(30);
    let first = plant.borrow_mut().initial_states(&[TRUTH]).unwrap();
    let mut outputs = vec![vec![first[0], first[1]]];
    outputs.extend(clean.iter().map(|y| {
        y.iter()
            .zip(SIGMA)
            .map(|(v, s)| v + s * noise.sample())
            .collect()
    }));
    let largest = clean.iter().map(|y| y[0].abs()).fold(0.0, f64::max);
    assert!(largest < 0.45, "the cart reaches {largest} m: a rail stop");
    (time, inputs, outputs)
}

/// θ̂ and its standard deviation at the end, and the smallest θ̂ on the way, of the robust
/// online filter `linearisation` from the default 0.67 (prior sd 20 %).
fn identify(linearisation: Linearisation) -> (f64, f64, f64) {
    let plant = crane();
    let (time, inputs, outputs) = record(&plant);
    let x0 = plant.borrow_mut().initial_states(&[START]).unwrap();
    let variances: Vec<f64> = SIGMA.iter().map(|s| s * s).collect();
    let mut filter = joint_filter(
        &plant,
        &[START],
        &x0,
        &variances,
        Some(InfluenceFunction::huber()),
        linearisation,
    )
    .unwrap();
    let trajectory = filter
        .run(&time, &inputs, &outputs)
        .unwrap_or_else(|e| panic!("{linearisation:?}: {e}"));
    let n = x0.len();
    let lowest = (0..time.len())
        .map(|k| trajectory.estimate(k, n))
        .fold(f64::INFINITY, f64::min);
    let last = time.len() - 1;
    (
        trajectory.estimate(last, n),
        trajectory.standard_deviation(last, n),
        lowest,
    )
}

/// θ̂ reaches the bound 0 on its way down (the projection acts), never passes it, and ends
/// within 2 σ of the truth with σ < 0.005.
fn check(linearisation: Linearisation) {
    let (estimate, sd, lowest) = identify(linearisation);
    println!(
        "{linearisation:?}: f_c at the end {estimate:.4} ± {sd:.4}, lowest on the way {lowest:.4}"
    );
    assert!((0.0..TRUTH / 2.0).contains(&lowest), "lowest θ̂ {lowest}");
    assert!(
        (estimate - TRUTH).abs() < 2.0 * sd && sd < 0.005,
        "{estimate} ± {sd}"
    );
}

#[test]
fn a_friction_near_zero_is_identified_by_the_ukf_within_its_range() {
    check(Linearisation::UNSCENTED);
}

#[test]
fn a_friction_near_zero_is_identified_by_the_ekf_within_its_range() {
    check(Linearisation::Extended);
}
