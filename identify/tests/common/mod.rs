//! Data for the FMU identification tests: the Reference FMUs run by the master's own Model
//! Exchange stepper at the true parameters, plus seeded Gaussian noise and outliers.
#![allow(dead_code)]

use nalgebra::{DMatrix, DVector};
use spurio::estimation::likelihood::Record;
use spurio_identify::filter::{Filter, FilterSettings, Linearisation, Noise};
use spurio_identify::plant::{integration, FmuPlant, PlantSpec, Start};
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
    };
    Rc::new(RefCell::new(
        FmuPlant::open(&reference(model), &spec, integration(0.0, tolerance))
            .expect("the plant opens"),
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
        let start = Start {
            time: t0,
            states: &x,
            parameters: theta,
            inputs: &[],
            reference: None,
        };
        p.propagate(&start, t, &mut x_next, &mut y)
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

/// One identification case: a Reference FMU, one free parameter measured through `outputs`.
pub struct Case {
    pub model: &'static str,
    pub parameter: &'static str,
    pub outputs: &'static [&'static str],
    pub truth: f64,
    pub start: f64,
    pub sigma: f64,
    pub samples: usize,
    pub step: f64,
    /// P₀ of the states (x̂₀ the FMU's own initial states).
    pub state_variance: f64,
    /// Q_x per sample.
    pub state_noise: f64,
    /// The prior variance of the parameter in the online filter.
    pub parameter_variance: f64,
}

impl Case {
    /// The noisy measurements (5 % outliers of 20 σ, seed 28) at the sample times.
    pub fn data(&self) -> (Vec<f64>, Vec<Vec<f64>>) {
        let plant = plant(self.model, &[self.parameter], self.outputs, 1e-10);
        let t = times(self.samples, self.step);
        let clean = simulate(&plant, &[self.truth], &t);
        let (noisy, outliers) = corrupt(&clean, self.sigma, 0.05, 20.0, 28);
        assert!(outliers.len() >= 3, "{} outliers", outliers.len());
        (t, noisy)
    }

    fn initial_states(&self, plant: &Rc<RefCell<FmuPlant>>) -> Vec<f64> {
        plant
            .borrow_mut()
            .initial_states(&[self.start])
            .expect("initialised")
    }

    /// The filter's settings: Q_x, Q_θ (none, or 0 for the parameter), R = σ².
    pub fn settings(
        &self,
        states: usize,
        parameters: usize,
        robust: Option<spurio::estimation::InfluenceFunction>,
        linearisation: Linearisation,
    ) -> FilterSettings {
        FilterSettings {
            noise: Noise::new(
                self.state_noise,
                states,
                0.0,
                parameters,
                &vec![self.sigma * self.sigma; self.outputs.len()],
            ),
            robust,
            linearisation,
        }
    }

    /// The online estimate θ̂ and its standard deviation after the run.
    pub fn online(
        &self,
        robust: Option<spurio::estimation::InfluenceFunction>,
        linearisation: Linearisation,
    ) -> (f64, f64) {
        let (t, y) = self.data();
        let plant = plant(self.model, &[self.parameter], self.outputs, 1e-8);
        let x0 = self.initial_states(&plant);
        let n = x0.len();
        let settings = self.settings(n, 1, robust, linearisation);
        let mut p0 = vec![self.state_variance; n];
        p0.push(self.parameter_variance);
        let mut filter =
            Filter::new(plant, &[self.start], &[0], &x0, diag(&p0), &settings).expect("a filter");
        let trajectory = filter
            .run(&t, &vec![Vec::new(); t.len()], &y)
            .expect("the run");
        let last = trajectory.len() - 1;
        (
            trajectory.estimate(last, n),
            trajectory.standard_deviation(last, n),
        )
    }

    /// The offline estimate and its standard error: the prediction errors of the filter with
    /// a known initial state and no process noise, i.e. the output errors of a simulation
    /// (the data have no process noise; a filter that corrects the states of a hybrid model
    /// makes the loss rough in θ where a bounce crosses a sample time).
    pub fn offline(&self, loss: spurio_identify::fmu_model::Loss) -> (f64, Option<f64>) {
        let (t, y) = self.data();
        let plant = plant(self.model, &[self.parameter], self.outputs, 1e-10);
        let x0 = self.initial_states(&plant);
        let n = x0.len();
        let mut settings = self.settings(n, 0, None, Linearisation::UNSCENTED);
        settings.noise.process = vec![0.0; n];
        let model = spurio_identify::fmu_model::FmuModel::new(plant, t, settings, false, loss);
        let init = spurio::estimation::likelihood::Initialisation::Known {
            x0: DVector::from_column_slice(&x0),
            p0: diag(&vec![0.0; n]),
        };
        let fit = spurio_identify::maximise_likelihood(
            &model,
            &record(&y),
            &init,
            &[spurio_identify::FreeParameter::positive(
                self.parameter,
                &[self.start],
            )],
            &spurio_identify::Options {
                tolerance: 1e-8,
                max_iterations: 400,
                ..spurio_identify::Options::default()
            },
        )
        .expect("a fit");
        let e = fit.estimate(self.parameter).expect("the parameter");
        (e.value, e.standard_error)
    }

    /// Runs the five fits, prints them and asserts the done-when figures: offline (robust)
    /// within 1 % of the truth, online (robust UKF and EKF) within two standard deviations. The error
    /// ratios without/with the robust weights (online, offline) are returned.
    pub fn check(&self) -> (f64, f64) {
        use spurio_identify::fmu_model::Loss;
        let started = std::time::Instant::now();
        let (ml, se) = self.offline(Loss::Huber { c: 1.345 });
        let (ml_plain, se_plain) = self.offline(Loss::Gaussian);
        let huber = Some(spurio::estimation::InfluenceFunction::huber());
        let (ukf, sd) = self.online(huber, Linearisation::UNSCENTED);
        let (ukf_plain, sd_plain) = self.online(None, Linearisation::UNSCENTED);
        let (ekf, ekf_sd) = self.online(huber, Linearisation::Extended);
        let truth = self.truth;
        let ratio = |plain: f64, robust: f64| (plain - truth).abs() / (robust - truth).abs();
        let ratios = (ratio(ukf_plain, ukf), ratio(ml_plain, ml));
        println!(
            "{} {} (truth {truth}, start {}): offline Huber {ml:.6} ± {se:?}, Gaussian {ml_plain:.6} ± {se_plain:?}; online robust UKF {ukf:.6} ± {sd:.6}, plain {ukf_plain:.6} ± {sd_plain:.6}, robust EKF {ekf:.6} ± {ekf_sd:.6}; error ratio none/robust online {:.2}, offline {:.2}; {:.2} s",
            self.model,
            self.parameter,
            self.start,
            ratios.0,
            ratios.1,
            started.elapsed().as_secs_f64()
        );
        assert!((ml - truth).abs() < 0.01 * truth.abs(), "offline {ml}");
        assert!(
            se.is_some_and(|se| se > 0.0 && se < 0.01 * truth.abs()),
            "se {se:?}"
        );
        assert!((ukf - truth).abs() < 2.0 * sd, "online {ukf} ± {sd}");
        assert!(
            (ekf - truth).abs() < 2.0 * ekf_sd,
            "online EKF {ekf} ± {ekf_sd}"
        );
        ratios
    }
}
