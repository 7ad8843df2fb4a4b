//! Data for the FMU identification tests: the Reference FMUs run by the master's own Model
//! Exchange stepper at the true parameters, plus seeded Gaussian noise and outliers.
#![allow(dead_code)]

use nalgebra::{DMatrix, DVector};
use spurio::estimation::likelihood::Record;
use spurio_identify::plant::{FmuPlant, PlantSpec};
use std::cell::RefCell;
use std::path::PathBuf;
use std::rc::Rc;

/// The FMI 2.0 Reference FMU `model` of the repository's third-party folder.
pub fn reference(model: &str) -> PathBuf {
    let fmu = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../tests/third_party/reference-fmus/fmi2")
        .join(format!("{model}.fmu"));
    assert!(fmu.is_file(), "{} is missing", fmu.display());
    fmu
}

/// The FMU `model` with `free` estimated and `outputs` measured, no inputs.
pub fn plant(
    model: &str,
    free: &[&str],
    outputs: &[&str],
    tolerance: f64,
) -> Rc<RefCell<FmuPlant>> {
    let spec = PlantSpec {
        free: free.iter().map(|s| s.to_string()).collect(),
        inputs: Vec::new(),
        outputs: outputs.iter().map(|s| s.to_string()).collect(),
        tolerance,
        start: 0.0,
    };
    Rc::new(RefCell::new(
        FmuPlant::open(&reference(model), &spec).expect("the plant opens"),
    ))
}

/// SplitMix64 and Box–Muller: a seeded normal sequence.
pub struct Normal(u64);

impl Normal {
    pub fn new(seed: u64) -> Self {
        Self(seed)
    }
    pub fn uniform(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^= z >> 31;
        ((z >> 11) as f64 + 0.5) / (1u64 << 53) as f64
    }
    pub fn sample(&mut self) -> f64 {
        let (a, b) = (self.uniform(), self.uniform());
        (-2.0 * a.ln()).sqrt() * (2.0 * std::f64::consts::PI * b).cos()
    }
}

/// The measured variables at `times` from the FMU's own initial states at `theta`.
pub fn simulate(plant: &Rc<RefCell<FmuPlant>>, theta: &[f64], times: &[f64]) -> Vec<Vec<f64>> {
    let mut p = plant.borrow_mut();
    let mut x = p.initial_states(theta).expect("initialised");
    let mut x_next = x.clone();
    let outputs = p.output_names().len();
    let mut rows = Vec::new();
    let mut t0 = times[0];
    for &t in times {
        let mut y = vec![0.0; outputs];
        p.propagate(t0, &x, theta, &[], t, &mut x_next, &mut y)
            .expect("propagated");
        x.copy_from_slice(&x_next);
        t0 = t;
        rows.push(y);
    }
    rows
}

/// `clean` plus N(0, σ²) noise and, on a fraction `outliers` of the samples (seeded), an
/// outlier of ±`outlier` σ; the indices of the outliers.
pub fn corrupt(
    clean: &[Vec<f64>],
    sigma: f64,
    outliers: f64,
    outlier: f64,
    seed: u64,
) -> (Vec<Vec<f64>>, Vec<usize>) {
    let mut normal = Normal::new(seed);
    let mut hit = Vec::new();
    let rows = clean
        .iter()
        .enumerate()
        .map(|(k, row)| {
            let wild = normal.uniform() < outliers;
            if wild {
                hit.push(k);
            }
            row.iter()
                .map(|v| {
                    let sign = if normal.uniform() < 0.5 { -1.0 } else { 1.0 };
                    v + sigma * normal.sample() + if wild { sign * outlier * sigma } else { 0.0 }
                })
                .collect()
        })
        .collect();
    (rows, hit)
}

/// The record of measured rows (no inputs).
pub fn record(rows: &[Vec<f64>]) -> Record {
    Record::new(
        vec![DVector::zeros(0); rows.len()],
        rows.iter().map(|r| DVector::from_column_slice(r)).collect(),
    )
    .expect("a valid record")
}

/// A diagonal matrix.
pub fn diag(values: &[f64]) -> DMatrix<f64> {
    DMatrix::from_diagonal(&DVector::from_column_slice(values))
}

/// `count` sample times from 0 every `step`.
pub fn times(count: usize, step: f64) -> Vec<f64> {
    (0..count).map(|k| k as f64 * step).collect()
}
