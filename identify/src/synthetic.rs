//! Identification from synthetic data (docs/estimators.md, "Identifying an FMU";
//! docs/experiments.md §4.10): a Model Exchange FMU run by the master's own stepper at the
//! true parameters, plus seeded Gaussian noise and outliers, then one free parameter
//! identified online (the robust and the plain UKF, the robust EKF) and offline (maximum
//! likelihood of the output errors with Huber's loss and with the Gaussian one).
//!
//! **The data.** y_k = h(x(t_k); θ) + σ e_k + o_k at t_k = k Δ, e_k ~ N(0, 1) (SplitMix64 and
//! Box–Muller, [`Normal`]), and on a fraction of the samples (a uniform draw below it) an
//! outlier o_k = ±A σ of random sign on every output ([`corrupt`]).
//!
//! **Online:** the filter of [`crate::filter`] on the augmented state (x, θ), θ a random walk
//! with Q_θ = 0 and prior variance P_θ, started from θ₀ with x̂₀ the FMU's own initial states at
//! θ₀ (variance P_x), Q_x per sample, R = σ² I.
//! **Offline:** the prediction errors of the filter with a known initial state and no process
//! noise, i.e. the output errors of a simulation (the data have no process noise; a filter
//! that corrects the states of a hybrid model makes the loss rough in θ where a bounce crosses
//! a sample time), maximised by [`crate::maximise_likelihood`] from θ₀ (θ > 0, log scale).
//!
//! The three cases of the Reference FMUs ([`VAN_DER_POL`], [`BOUNCING_BALL`],
//! [`DAHLQUIST`]) are the ones the tests (identify/tests/fmu_*.rs) assert and the
//! `fmu_identification` experiment reports, so both show the same numbers.

use crate::filter::{Filter, FilterError, FilterSettings, Linearisation, Noise, Trajectory};
use crate::fmu_model::{FmuModel, Loss};
use crate::plant::{integration, FmuPlant, PlantError, PlantSpec, Start};
use crate::{maximise_likelihood, FreeParameter, IdentifyError, Options};
use nalgebra::{DMatrix, DVector};
use spurio::estimation::likelihood::{Initialisation, LikelihoodError, Record};
use spurio::estimation::InfluenceFunction;
use spurio::signals::rng::splitmix64;
use std::cell::RefCell;
use std::path::Path;
use std::rc::Rc;

/// Why a synthetic identification cannot be made.
#[derive(Debug, thiserror::Error)]
pub enum SyntheticError {
    /// The FMU cannot be opened, initialised or run.
    #[error("plant {model}: {source}")]
    Plant {
        /// The case's model.
        model: &'static str,
        /// Why.
        source: Box<PlantError>,
    },
    /// An online filter failed.
    #[error("online filter on {model}: {source}")]
    Filter {
        /// The case's model.
        model: &'static str,
        /// Why.
        source: Box<FilterError>,
    },
    /// The measurements are not a record (rows of unequal length, non-finite values).
    #[error("record of {model}: {source}")]
    Record {
        /// The case's model.
        model: &'static str,
        /// Why.
        source: Box<LikelihoodError>,
    },
    /// The offline fit failed.
    #[error("offline fit of {model}: {source}")]
    Fit {
        /// The case's model.
        model: &'static str,
        /// Why.
        source: Box<IdentifyError>,
    },
}

/// SplitMix64 and Box–Muller: a seeded normal sequence.
#[derive(Debug, Clone)]
pub struct Normal(u64);

impl Normal {
    /// The sequence of `seed`.
    pub fn new(seed: u64) -> Self {
        Self(seed)
    }

    /// A uniform draw in (0, 1): the 53 high bits of the next SplitMix64 output, centred.
    pub fn uniform(&mut self) -> f64 {
        ((splitmix64(&mut self.0) >> 11) as f64 + 0.5) / (1u64 << 53) as f64
    }

    /// A standard normal draw: √(−2 ln u₁) cos(2π u₂).
    pub fn sample(&mut self) -> f64 {
        let (a, b) = (self.uniform(), self.uniform());
        (-2.0 * a.ln()).sqrt() * (2.0 * std::f64::consts::PI * b).cos()
    }
}

/// The FMU at `fmu` with `free` estimated and `outputs` measured, no inputs, integrated to
/// `tolerance`.
pub fn plant(
    fmu: &Path,
    free: &[&str],
    outputs: &[&str],
    tolerance: f64,
) -> Result<Rc<RefCell<FmuPlant>>, PlantError> {
    let spec = PlantSpec {
        free: free.iter().map(|s| s.to_string()).collect(),
        inputs: Vec::new(),
        outputs: outputs.iter().map(|s| s.to_string()).collect(),
    };
    Ok(Rc::new(RefCell::new(FmuPlant::open(
        fmu,
        &spec,
        integration(0.0, tolerance),
    )?)))
}

/// The measured variables at `times` from the FMU's own initial states at `theta`.
pub fn simulate(
    plant: &Rc<RefCell<FmuPlant>>,
    theta: &[f64],
    times: &[f64],
) -> Result<Vec<Vec<f64>>, PlantError> {
    let mut p = plant.borrow_mut();
    let mut x = p.initial_states(theta)?;
    let mut x_next = x.clone();
    let outputs = p.output_names().len();
    let mut rows = Vec::with_capacity(times.len());
    let mut t0 = times.first().copied().unwrap_or(0.0);
    for &t in times {
        let mut y = vec![0.0; outputs];
        let start = Start {
            time: t0,
            states: &x,
            parameters: theta,
            inputs: &[],
            reference: None,
        };
        p.propagate(&start, t, &mut x_next, &mut y)?;
        x.copy_from_slice(&x_next);
        t0 = t;
        rows.push(y);
    }
    Ok(rows)
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
pub fn record(rows: &[Vec<f64>]) -> Result<Record, LikelihoodError> {
    Record::new(
        vec![DVector::zeros(0); rows.len()],
        rows.iter().map(|r| DVector::from_column_slice(r)).collect(),
    )
}

/// A diagonal matrix.
pub fn diag(values: &[f64]) -> DMatrix<f64> {
    DMatrix::from_diagonal(&DVector::from_column_slice(values))
}

/// `count` sample times from 0 every `step`.
pub fn times(count: usize, step: f64) -> Vec<f64> {
    (0..count).map(|k| k as f64 * step).collect()
}

/// The fraction of the samples that carry an outlier.
pub const OUTLIER_FRACTION: f64 = 0.05;
/// An outlier's size in σ.
pub const OUTLIER_SIZE: f64 = 20.0;
/// The seed of the noise and the outliers.
pub const SEED: u64 = 28;
/// The integration tolerance of the data (the filters integrate to 10⁻⁸ online).
pub const DATA_TOLERANCE: f64 = 1e-10;
/// Huber's tuning constant (95 % efficiency at the normal).
pub const HUBER_C: f64 = 1.345;

/// One identification case: an FMU, one free parameter measured through `outputs`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Case {
    /// The Reference FMU's name (`<model>.fmu`).
    pub model: &'static str,
    /// The free parameter.
    pub parameter: &'static str,
    /// The measured outputs.
    pub outputs: &'static [&'static str],
    /// The parameter's true value (the data's).
    pub truth: f64,
    /// θ₀, where both fits start.
    pub start: f64,
    /// The noise's standard deviation σ.
    pub sigma: f64,
    /// How many samples.
    pub samples: usize,
    /// The sample step Δ.
    pub step: f64,
    /// P₀ of the states (x̂₀ the FMU's own initial states).
    pub state_variance: f64,
    /// Q_x per sample.
    pub state_noise: f64,
    /// The prior variance of the parameter in the online filter.
    pub parameter_variance: f64,
}

/// Van der Pol's fixed parameter μ (set only before initialisation: every new μ resets the
/// instance), measured through x0.
pub const VAN_DER_POL: Case = Case {
    model: "VanDerPol",
    parameter: "mu",
    outputs: &["x0"],
    truth: 1.3,
    start: 1.0,
    sigma: 0.02,
    samples: 201,
    step: 0.05,
    state_variance: 1e-4,
    state_noise: 1e-8,
    parameter_variance: 0.25,
};

/// BouncingBall's tunable coefficient of restitution e (set in Event Mode), identified
/// through its bounces from the height h.
pub const BOUNCING_BALL: Case = Case {
    model: "BouncingBall",
    parameter: "e",
    outputs: &["h"],
    truth: 0.8,
    start: 0.7,
    sigma: 0.01,
    samples: 301,
    step: 0.01,
    state_variance: 1e-6,
    state_noise: 1e-8,
    parameter_variance: 0.01,
};

/// Dahlquist's fixed parameter k (ẋ = −k x), measured through x.
pub const DAHLQUIST: Case = Case {
    model: "Dahlquist",
    parameter: "k",
    outputs: &["x"],
    truth: 1.5,
    start: 1.0,
    sigma: 0.005,
    samples: 101,
    step: 0.05,
    state_variance: 1e-6,
    state_noise: 0.0,
    parameter_variance: 0.25,
};

/// The synthetic data of a case.
#[derive(Debug, Clone, PartialEq)]
pub struct Data {
    /// The sample times.
    pub time: Vec<f64>,
    /// The outputs at the true parameter, one row per sample.
    pub clean: Vec<Vec<f64>>,
    /// The measurements: `clean` plus noise and outliers.
    pub measured: Vec<Vec<f64>>,
    /// The samples that carry an outlier.
    pub outliers: Vec<usize>,
}

/// An offline estimate: θ̂ and its standard error (None where the curvature gives none).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Offline {
    /// θ̂.
    pub value: f64,
    /// se(θ̂).
    pub standard_error: Option<f64>,
}

/// The five fits of a case ([`Case::identify`]).
#[derive(Debug, Clone)]
pub struct Identified {
    /// The data they were made from.
    pub data: Data,
    /// Maximum likelihood with Huber's loss.
    pub offline_robust: Offline,
    /// Maximum likelihood with the Gaussian loss (`--robust none`).
    pub offline_plain: Offline,
    /// The robust UKF (Huber weights) over the data.
    pub ukf_robust: Trajectory,
    /// The plain UKF (`--robust none`).
    pub ukf_plain: Trajectory,
    /// The robust EKF.
    pub ekf_robust: Trajectory,
    /// Wall-clock seconds of the five fits.
    pub seconds: f64,
}

/// θ̂ ± σ of an online trajectory at sample `k`: the parameter is the last filter state.
pub fn parameter_at(trajectory: &Trajectory, k: usize) -> (f64, f64) {
    let row = trajectory.filter_states.saturating_sub(1);
    (
        trajectory.estimate(k, row),
        trajectory.standard_deviation(k, row),
    )
}

/// θ̂ ± σ of an online trajectory at its last sample.
pub fn parameter_at_end(trajectory: &Trajectory) -> (f64, f64) {
    parameter_at(trajectory, trajectory.len().saturating_sub(1))
}

impl Case {
    fn plant(&self, fmu: &Path, tolerance: f64) -> Result<Rc<RefCell<FmuPlant>>, SyntheticError> {
        plant(fmu, &[self.parameter], self.outputs, tolerance).map_err(|e| self.plant_error(e))
    }

    fn plant_error(&self, source: PlantError) -> SyntheticError {
        SyntheticError::Plant {
            model: self.model,
            source: Box::new(source),
        }
    }

    /// The FMU's run at the truth (tolerance [`DATA_TOLERANCE`]) at the sample times, with
    /// [`OUTLIER_FRACTION`] outliers of [`OUTLIER_SIZE`] σ (seed [`SEED`]).
    pub fn data(&self, fmu: &Path) -> Result<Data, SyntheticError> {
        let plant = self.plant(fmu, DATA_TOLERANCE)?;
        let time = times(self.samples, self.step);
        let clean = simulate(&plant, &[self.truth], &time).map_err(|e| self.plant_error(e))?;
        let (measured, outliers) =
            corrupt(&clean, self.sigma, OUTLIER_FRACTION, OUTLIER_SIZE, SEED);
        Ok(Data {
            time,
            clean,
            measured,
            outliers,
        })
    }

    fn initial_states(&self, plant: &Rc<RefCell<FmuPlant>>) -> Result<Vec<f64>, SyntheticError> {
        plant
            .borrow_mut()
            .initial_states(&[self.start])
            .map_err(|e| self.plant_error(e))
    }

    /// The filter's settings: Q_x, Q_θ (none, or 0 for the parameter), R = σ².
    pub fn settings(
        &self,
        states: usize,
        parameters: usize,
        robust: Option<InfluenceFunction>,
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

    /// The online filter's trajectory over `data` (the plant integrated to 10⁻⁸); the
    /// parameter is its row after the plant's states.
    pub fn online(
        &self,
        fmu: &Path,
        data: &Data,
        robust: Option<InfluenceFunction>,
        linearisation: Linearisation,
    ) -> Result<Trajectory, SyntheticError> {
        let plant = self.plant(fmu, 1e-8)?;
        let x0 = self.initial_states(&plant)?;
        let n = x0.len();
        let settings = self.settings(n, 1, robust, linearisation);
        let mut p0 = vec![self.state_variance; n];
        p0.push(self.parameter_variance);
        let filter_error = |source| SyntheticError::Filter {
            model: self.model,
            source: Box::new(source),
        };
        let mut filter = Filter::new(plant, &[self.start], &[0], &x0, diag(&p0), &settings)
            .map_err(filter_error)?;
        filter
            .run(
                &data.time,
                &vec![Vec::new(); data.time.len()],
                &data.measured,
            )
            .map_err(filter_error)
    }

    /// The offline estimate and its standard error under `loss` (module documentation).
    pub fn offline(&self, fmu: &Path, data: &Data, loss: Loss) -> Result<Offline, SyntheticError> {
        let plant = self.plant(fmu, DATA_TOLERANCE)?;
        let x0 = self.initial_states(&plant)?;
        let n = x0.len();
        let mut settings = self.settings(n, 0, None, Linearisation::UNSCENTED);
        settings.noise.process = vec![0.0; n];
        let model = FmuModel::new(plant, data.time.clone(), settings, false, loss);
        let init = Initialisation::Known {
            x0: DVector::from_column_slice(&x0),
            p0: diag(&vec![0.0; n]),
        };
        let record = record(&data.measured).map_err(|source| SyntheticError::Record {
            model: self.model,
            source: Box::new(source),
        })?;
        let fit_error = |source| SyntheticError::Fit {
            model: self.model,
            source: Box::new(source),
        };
        let fit = maximise_likelihood(
            &model,
            &record,
            &init,
            &[FreeParameter::positive(self.parameter, &[self.start])],
            &Options {
                tolerance: 1e-8,
                max_iterations: 400,
                ..Options::default()
            },
        )
        .map_err(fit_error)?;
        // The one free parameter's estimate.
        let estimate = fit
            .estimates
            .first()
            .ok_or_else(|| fit_error(IdentifyError::NoFreeParameter))?;
        Ok(Offline {
            value: estimate.value,
            standard_error: estimate.standard_error,
        })
    }

    /// The data of the FMU at `fmu` and the five fits: offline with Huber's loss (c =
    /// [`HUBER_C`]) and the Gaussian one, online the robust and the plain UKF and the robust
    /// EKF.
    pub fn identify(&self, fmu: &Path) -> Result<Identified, SyntheticError> {
        let started = std::time::Instant::now();
        let data = self.data(fmu)?;
        let offline_robust = self.offline(fmu, &data, Loss::Huber { c: HUBER_C })?;
        let offline_plain = self.offline(fmu, &data, Loss::Gaussian)?;
        let huber = Some(InfluenceFunction::huber());
        let ukf_robust = self.online(fmu, &data, huber, Linearisation::UNSCENTED)?;
        let ukf_plain = self.online(fmu, &data, None, Linearisation::UNSCENTED)?;
        let ekf_robust = self.online(fmu, &data, huber, Linearisation::Extended)?;
        Ok(Identified {
            data,
            offline_robust,
            offline_plain,
            ukf_robust,
            ukf_plain,
            ekf_robust,
            seconds: started.elapsed().as_secs_f64(),
        })
    }

    /// The error ratio |plain − θ| / |robust − θ|: how much worse `--robust none` is.
    pub fn error_ratio(&self, plain: f64, robust: f64) -> f64 {
        (plain - self.truth).abs() / (robust - self.truth).abs()
    }
}
