//! One identification from recorded data, as `spurio identify` runs it (docs/estimators.md,
//! "spurio identify"): the FMU's free parameters estimated on the first part of the record
//! (online by the robust UKF or EKF, or offline by maximum likelihood), then judged on the rest
//! (one-step and simulation fit, residual whiteness, outliers), written as `estimates.csv`
//! and `report.md`.
//!
//! **Fit.** On the validation samples, fit = 100 (1 − ‖y − ŷ‖ / ‖y − ȳ‖) % over the present
//! samples that are not outliers (as MATLAB's `compare`), ŷ the one-step prediction of the
//! filter at θ̂ (states only) or the simulation from the initial state at θ̂.
//!
//! **Outliers.** A sample whose one-step innovation, standardised by its standard
//! deviation, exceeds [`OUTLIER_THRESHOLD`] in magnitude.
//!
//! **Whiteness.** The sample autocorrelation ρ̂(τ), τ = 1 … 20, of the standardised one-step
//! innovations of the validation part (outliers left out): white residuals keep
//! |ρ̂(τ)| ≤ 1.96/√N at 95 % for each lag; the report gives the lags outside the band and
//! the Ljung–Box statistic Q = N(N+2) Σ ρ̂(τ)²/(N−τ) against χ²₂₀'s 95 % quantile 31.41.

use crate::filter::{Filter, FilterError, FilterSettings, Trajectory};
use crate::fmu_model::{variance_name, FmuModel, Loss};
use crate::online;
use crate::plant::{integration, FmuPlant, PlantError, PlantSpec};
use crate::{maximise_likelihood, Estimate, FreeParameter, IdentifyError, Options};
use nalgebra::{DMatrix, DVector};
use spurio::estimation::likelihood::{Initialisation, LikelihoodError, Record};
use spurio::estimation::InfluenceFunction;
use std::cell::RefCell;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::rc::Rc;

pub use crate::online::{Method, Robust, PARAMETER_PRIOR};

/// |standardised innovation| above which a sample is an outlier.
pub const OUTLIER_THRESHOLD: f64 = 3.0;
/// Lags of the whiteness test.
pub const WHITENESS_LAGS: usize = 20;
/// χ²₂₀'s 95 % quantile.
const CHI2_20_95: f64 = 31.410;

/// The recorded data: sample times, inputs and measured variables per sample (NaN missing).
#[derive(Debug, Clone, PartialEq)]
pub struct Data {
    pub time: Vec<f64>,
    pub inputs: Vec<Vec<f64>>,
    pub outputs: Vec<Vec<f64>>,
}

impl Data {
    /// The record of the likelihood: per sample, u and y as vectors (NaN missing).
    pub fn record(&self) -> Result<Record, LikelihoodError> {
        let column = |rows: &[Vec<f64>]| {
            rows.iter()
                .map(|row| DVector::from_column_slice(row))
                .collect()
        };
        Record::new(column(&self.inputs), column(&self.outputs))
    }
}

/// What to identify and how.
#[derive(Debug, Clone, PartialEq)]
pub struct Request {
    pub fmu: PathBuf,
    /// The FMU's free parameters, inputs (in the order of the data's inputs) and measured
    /// variables (in the order of the data's outputs).
    pub plant: PlantSpec,
    /// The relative tolerance of the FMU's integration.
    pub tolerance: f64,
    pub robust: Robust,
    pub method: Method,
    /// The fraction of the record (at its end) kept for validation, in [0, 1).
    pub validate: f64,
    /// The measurement variances (None: from the data, and estimated by `ml`).
    pub noise: Option<Vec<f64>>,
    /// Start values of free parameters by name (the others start at the FMU's).
    pub starts: Vec<(String, f64)>,
    /// Parameters that are not estimated, set by name (the experiment's own values).
    pub set: Vec<(String, f64)>,
}

/// Why an identification cannot be made.
#[derive(Debug, thiserror::Error)]
pub enum SessionError {
    #[error("the data: {0}")]
    Data(String),
    /// The FMU (its names, its calls) or a filter on it.
    #[error(transparent)]
    Filter(#[from] FilterError),
    /// The offline fit (its likelihood included).
    #[error(transparent)]
    Fit(#[from] IdentifyError),
    #[error("cannot write {path}: {source}")]
    Write {
        path: PathBuf,
        source: std::io::Error,
    },
}

impl From<PlantError> for SessionError {
    fn from(e: PlantError) -> Self {
        Self::Filter(FilterError::Plant(e))
    }
}

/// How the identified model fits one measured variable on the validation part.
#[derive(Debug, Clone, PartialEq)]
pub struct ChannelFit {
    /// One-step and simulation fit (%).
    pub one_step: f64,
    pub simulation: f64,
    /// ρ̂(1 … 20) of the standardised one-step innovations, and their Ljung–Box Q.
    pub autocorrelation: Vec<f64>,
    pub ljung_box: f64,
}

/// What an identification gave.
#[derive(Debug, Clone, PartialEq)]
pub struct Outcome {
    /// Each parameter's estimate (its standard error: the filter's σ online, the curvature's
    /// offline).
    pub estimates: Vec<Estimate>,
    /// The online filter's outputs over the estimation part (online methods only).
    pub trajectory: Option<Trajectory>,
    /// Per measured variable.
    pub fit: Vec<ChannelFit>,
    /// Indices of the samples taken as outliers.
    pub outliers: Vec<usize>,
    /// The samples estimated on (the first ones) and validated on (the last ones).
    pub samples: (usize, usize),
    pub seconds: f64,
}

/// σ² of each measured variable from the data: (1.4826 MAD(Δy))² / 2, a robust estimate of
/// the noise of a smooth signal sampled densely.
fn noise_from_data(outputs: &[Vec<f64>], p: usize) -> Vec<f64> {
    (0..p)
        .map(|j| {
            let present: Vec<f64> = outputs
                .iter()
                .map(|y| y[j])
                .filter(|v| !v.is_nan())
                .collect();
            let mut d: Vec<f64> = present.windows(2).map(|w| w[1] - w[0]).collect();
            let median = |v: &mut Vec<f64>| {
                v.sort_by(f64::total_cmp);
                v.get(v.len() / 2).copied().unwrap_or(0.0)
            };
            let m = median(&mut d);
            let mut dev: Vec<f64> = d.iter().map(|x| (x - m).abs()).collect();
            let mad = median(&mut dev);
            let variance = (1.4826 * mad).powi(2) / 2.0;
            if variance > 0.0 {
                variance
            } else {
                1e-12
            }
        })
        .collect()
}

/// Runs the filter at fixed θ over every sample, from P₀ = diag(`p0`): its trajectory.
fn filter_run(
    plant: &Rc<RefCell<FmuPlant>>,
    theta: &[f64],
    x0: &[f64],
    p0: &[f64],
    settings: &FilterSettings,
    data: &Data,
) -> Result<Trajectory, SessionError> {
    plant.borrow_mut().start_afresh();
    let p0 = DMatrix::from_diagonal(&DVector::from_column_slice(p0));
    let mut filter = Filter::new(plant.clone(), theta, &[], x0, p0, settings)?;
    Ok(filter.run(&data.time, &data.inputs, &data.outputs)?)
}

/// 100 (1 − ‖e‖/‖y − ȳ‖) over the samples that are present and kept (`keep`).
fn fit_percent(y: &[f64], e: &[f64], keep: &[bool]) -> f64 {
    let pairs: Vec<(f64, f64)> = y
        .iter()
        .zip(e)
        .zip(keep)
        .filter(|((y, e), keep)| **keep && !y.is_nan() && !e.is_nan())
        .map(|((y, e), _)| (*y, *e))
        .collect();
    let n = pairs.len().max(1) as f64;
    let mean = pairs.iter().map(|p| p.0).sum::<f64>() / n;
    let spread = pairs
        .iter()
        .map(|p| (p.0 - mean).powi(2))
        .sum::<f64>()
        .sqrt();
    let error = pairs.iter().map(|p| p.1 * p.1).sum::<f64>().sqrt();
    100.0 * (1.0 - error / spread.max(f64::MIN_POSITIVE))
}

/// ρ̂(1 … lags) of `r` (NaN entries left out as gaps) and the Ljung–Box Q.
fn autocorrelation(r: &[f64], lags: usize) -> (Vec<f64>, f64) {
    let present: Vec<f64> = r.iter().copied().filter(|v| !v.is_nan()).collect();
    let n = present.len() as f64;
    let mean = present.iter().sum::<f64>() / n.max(1.0);
    let c0: f64 = r
        .iter()
        .filter(|v| !v.is_nan())
        .map(|v| (v - mean).powi(2))
        .sum::<f64>()
        .max(f64::MIN_POSITIVE);
    let mut rho = Vec::with_capacity(lags);
    let mut q = 0.0;
    for tau in 1..=lags {
        let c: f64 = (tau..r.len())
            .filter(|&k| !r[k].is_nan() && !r[k - tau].is_nan())
            .map(|k| (r[k] - mean) * (r[k - tau] - mean))
            .sum();
        let value = c / c0;
        rho.push(value);
        if n > tau as f64 {
            q += value * value / (n - tau as f64);
        }
    }
    (rho, n * (n + 2.0) * q)
}

/// Opens the FMU and checks the names of `request` against it (before any data are read):
/// the number of its continuous states.
pub fn check(request: &Request) -> Result<usize, SessionError> {
    let mut plant = FmuPlant::open(
        &request.fmu,
        &request.plant,
        integration(0.0, request.tolerance),
    )?;
    plant.set_values(&request.set)?;
    Ok(plant.states())
}

/// Identifies `request.plant.free` from `data` (module documentation).
pub fn identify(request: &Request, data: &Data) -> Result<Outcome, SessionError> {
    let started = std::time::Instant::now();
    let n_samples = data.time.len();
    if n_samples < 3 || data.inputs.len() != n_samples || data.outputs.len() != n_samples {
        return Err(SessionError::Data(format!(
            "{n_samples} sample times, {} input rows and {} output rows: at least 3 samples, one row each",
            data.inputs.len(),
            data.outputs.len()
        )));
    }
    if !(0.0..1.0).contains(&request.validate) {
        return Err(SessionError::Data(format!(
            "--validate {} must be in [0, 1)",
            request.validate
        )));
    }
    let plant = Rc::new(RefCell::new(FmuPlant::open(
        &request.fmu,
        &request.plant,
        integration(data.time[0], request.tolerance),
    )?));
    let p = request.plant.outputs.len();
    plant.borrow_mut().set_values(&request.set)?;
    let mut starts = plant.borrow().parameter_starts();
    for (name, value) in &request.starts {
        let i = request.plant.free.iter().position(|f| f == name);
        let i = i.ok_or_else(|| {
            SessionError::Data(format!(
                "a start for `{name}`, which is not among the free parameters {}",
                request.plant.free.join(", ")
            ))
        })?;
        starts[i] = *value;
    }
    let x0 = plant.borrow_mut().initial_states(&starts)?;
    let n = x0.len();
    let estimation = ((1.0 - request.validate) * n_samples as f64).round() as usize;
    let estimation = estimation.clamp(2, n_samples);
    let head = Data {
        time: data.time[..estimation].to_vec(),
        inputs: data.inputs[..estimation].to_vec(),
        outputs: data.outputs[..estimation].to_vec(),
    };
    let mut noise = match &request.noise {
        Some(v) if v.len() == p => v.clone(),
        Some(v) => {
            return Err(SessionError::Data(format!(
                "{} noise variances for {p} measured variables",
                v.len()
            )))
        }
        None => noise_from_data(&head.outputs, p),
    };
    let free = starts.len();
    let linearisation = request.method.linearisation();
    // Q_x per sample on the states, Q_θ = 0 on `q` parameters in z.
    let settings = |state: f64, q: usize, robust, noise: &[f64]| {
        online::settings(state, n, q, noise, robust, linearisation)
    };
    let mut estimates = Vec::new();
    let mut trajectory = None;
    let theta: Vec<f64> = match request.method {
        Method::Ukf | Method::Ekf => {
            let mut filter = online::joint_filter(
                &plant,
                &starts,
                &x0,
                &noise,
                request.robust.influence(),
                linearisation,
            )?;
            let run = filter.run(&head.time, &head.inputs, &head.outputs)?;
            let last = run.len().checked_sub(1);
            for (i, name) in request.plant.free.iter().enumerate() {
                let (value, sd) = last.map_or((starts[i], None), |k| {
                    (
                        run.estimate(k, n + i),
                        Some(run.standard_deviation(k, n + i)),
                    )
                });
                estimates.push(Estimate {
                    name: name.clone(),
                    value,
                    standard_error: sd,
                    start: starts[i],
                });
            }
            trajectory = Some(run);
            estimates.iter().map(|e| e.value).collect()
        }
        Method::MaximumLikelihood => {
            let loss = match request.robust {
                Robust::None => Loss::Gaussian,
                Robust::Huber | Robust::Tukey => Loss::Huber { c: 1.345 },
            };
            let model = FmuModel::new(
                plant.clone(),
                head.time.clone(),
                settings(0.0, 0, None, &noise),
                request.noise.is_none(),
                loss,
            );
            let record = head.record().map_err(IdentifyError::from)?;
            let init = Initialisation::Known {
                x0: DVector::from_column_slice(&x0),
                p0: DMatrix::zeros(n, n),
            };
            let mut parameters: Vec<FreeParameter> = request
                .plant
                .free
                .iter()
                .zip(&starts)
                .map(|(name, &s)| {
                    if s > 0.0 {
                        FreeParameter::positive(name, &[s])
                    } else {
                        FreeParameter::real(name, &[s])
                    }
                })
                .collect();
            if request.noise.is_none() {
                let names = plant.borrow().output_names();
                for (name, v) in names.iter().zip(&noise) {
                    parameters.push(FreeParameter::positive(&variance_name(name), &[*v]));
                }
            }
            let fit = maximise_likelihood(
                &model,
                &record,
                &init,
                &parameters,
                &Options {
                    tolerance: 1e-8,
                    max_iterations: 1000,
                    ..Options::default()
                },
            )?;
            estimates = fit.estimates;
            if request.noise.is_none() {
                noise = estimates[free..].iter().map(|e| e.value).collect();
            }
            estimates[..free].iter().map(|e| e.value).collect()
        }
    };
    // Judged on the validation part (all samples when none is kept).
    let from = if estimation < n_samples {
        estimation
    } else {
        0
    };
    let x0 = plant.borrow_mut().initial_states(&theta)?;
    let one_step = filter_run(
        &plant,
        &theta,
        &x0,
        &online::state_variance(&x0),
        &settings(
            online::STATE_PROCESS_NOISE,
            0,
            request.robust.influence(),
            &noise,
        ),
        data,
    )?;
    let simulation = filter_run(
        &plant,
        &theta,
        &x0,
        &vec![0.0; n],
        &settings(0.0, 0, None, &noise),
        data,
    )?;
    let standardised =
        |k: usize, j: usize| one_step.innovation(k, j) / one_step.innovation_sd(k, j);
    let outliers: Vec<usize> = (0..n_samples)
        .filter(|&k| (0..p).any(|j| standardised(k, j).abs() > OUTLIER_THRESHOLD))
        .collect();
    let keep: Vec<bool> = (0..n_samples)
        .map(|k| k >= from && outliers.binary_search(&k).is_err())
        .collect();
    let fit = (0..p)
        .map(|j| {
            let y: Vec<f64> = data.outputs.iter().map(|y| y[j]).collect();
            let e1: Vec<f64> = (0..n_samples).map(|k| one_step.innovation(k, j)).collect();
            let es: Vec<f64> = (0..n_samples)
                .map(|k| simulation.innovation(k, j))
                .collect();
            let r: Vec<f64> = (from..n_samples)
                .map(|k| {
                    if keep[k] {
                        standardised(k, j)
                    } else {
                        f64::NAN
                    }
                })
                .collect();
            let (autocorrelation, ljung_box) = autocorrelation(&r, WHITENESS_LAGS);
            ChannelFit {
                one_step: fit_percent(&y, &e1, &keep),
                simulation: fit_percent(&y, &es, &keep),
                autocorrelation,
                ljung_box,
            }
        })
        .collect();
    Ok(Outcome {
        estimates,
        trajectory,
        fit,
        outliers,
        samples: (estimation, n_samples - from),
        seconds: started.elapsed().as_secs_f64(),
    })
}

fn write(path: &Path, text: &str) -> Result<(), SessionError> {
    std::fs::write(path, text).map_err(|source| SessionError::Write {
        path: path.to_path_buf(),
        source,
    })
}

/// Writes `estimates.csv` (parameter, estimate, standard_error, start), `report.md` and, for
/// the online methods, `trajectory.csv` (time, x̂, θ̂, their standard deviations, innovations, weights)
/// into `dir`; the report's text is returned.
pub fn write_outcome(
    request: &Request,
    outcome: &Outcome,
    state_count: usize,
    dir: &Path,
) -> Result<String, SessionError> {
    std::fs::create_dir_all(dir).map_err(|source| SessionError::Write {
        path: dir.to_path_buf(),
        source,
    })?;
    // estimates.csv and the report's table of estimates, row by row.
    let mut csv = String::from("parameter,estimate,standard_error,start\n");
    let mut table =
        String::from("| parameter | estimate | ± standard error | start |\n|---|---|---|---|\n");
    for e in &outcome.estimates {
        let (se_csv, se_md) = match e.standard_error {
            Some(se) => (format!("{se:e}"), format!("{se:.3e}")),
            None => (String::new(), "—".to_string()),
        };
        csv += &format!("{},{:e},{se_csv},{:e}\n", e.name, e.value, e.start);
        table += &format!(
            "| `{}` | {:.6} | {se_md} | {} |\n",
            e.name, e.value, e.start
        );
    }
    write(&dir.join("estimates.csv"), &csv)?;
    if let Some(trajectory) = &outcome.trajectory {
        let mut header = vec!["time".to_string()];
        header.extend((0..state_count).map(|i| format!("x{i}")));
        header.extend(request.plant.free.iter().cloned());
        header.extend((0..state_count).map(|i| format!("sd(x{i})")));
        header.extend(request.plant.free.iter().map(|f| format!("sd({f})")));
        for what in ["innovation", "sd(innovation", "weight"] {
            let close = if what.starts_with("sd(") { "))" } else { ")" };
            header.extend(
                request
                    .plant
                    .outputs
                    .iter()
                    .map(|o| format!("{what}({o}{close}")),
            );
        }
        let mut text = header.join(",") + "\n";
        // A row per sample: its column of the trajectory, every entry in that order.
        for (t, column) in trajectory.time.iter().zip(trajectory.values.column_iter()) {
            let mut row = vec![format!("{t}")];
            row.extend(column.iter().map(|v| format!("{v:e}")));
            text += &(row.join(",") + "\n");
        }
        write(&dir.join("trajectory.csv"), &text)?;
    }
    let mut md = String::new();
    let method = match request.method {
        Method::Ukf => "online: robust unscented Kalman filter, parameters as random-walk states",
        Method::Ekf => "online: robust extended Kalman filter, parameters as random-walk states",
        Method::MaximumLikelihood => "offline: maximum likelihood of the output errors",
    };
    let robust = match (request.method, request.robust.influence()) {
        (_, None) => "none (Gaussian)".to_string(),
        (Method::MaximumLikelihood, Some(_)) => "Huber's loss, c = 1.345".to_string(),
        (_, Some(InfluenceFunction::Huber { c })) => format!("Huber weights, c = {c}"),
        (_, Some(InfluenceFunction::Tukey { c })) => format!("Tukey bisquare weights, c = {c}"),
    };
    let _ = write!(
        md,
        "# Identification of {}\n\nMethod: {method}. Robustness: {robust}. {} samples estimated on, {} validated on; {:.2} s.\n\n## Estimates\n\n{table}",
        request.fmu.display(),
        outcome.samples.0,
        outcome.samples.1,
        outcome.seconds
    );
    let _ = writeln!(md, "\n## Fit on the validation part\n\n| measured | one-step fit | simulation fit | Ljung–Box Q (20 lags; white below {CHI2_20_95}) | lags with |ρ̂| > 1.96/√N |\n|---|---|---|---|---|");
    for (j, name) in request.plant.outputs.iter().enumerate() {
        let fit = &outcome.fit[j];
        let n = outcome.samples.1.max(1) as f64;
        let band = 1.96 / n.sqrt();
        let outside: Vec<String> = fit
            .autocorrelation
            .iter()
            .enumerate()
            .filter(|(_, r)| r.abs() > band)
            .map(|(tau, _)| (tau + 1).to_string())
            .collect();
        let _ = writeln!(
            md,
            "| `{name}` | {:.1} % | {:.1} % | {:.1} ({}) | {} |",
            fit.one_step,
            fit.simulation,
            fit.ljung_box,
            if fit.ljung_box <= CHI2_20_95 {
                "white"
            } else {
                "not white"
            },
            if outside.is_empty() {
                "none".to_string()
            } else {
                outside.join(", ")
            }
        );
    }
    let _ = writeln!(
        md,
        "\n## Outliers\n\n{} samples with a standardised one-step innovation beyond {OUTLIER_THRESHOLD}: {}.",
        outcome.outliers.len(),
        if outcome.outliers.is_empty() {
            "none".to_string()
        } else {
            outcome.outliers.iter().map(|k| k.to_string()).collect::<Vec<_>>().join(", ")
        }
    );
    write(&dir.join("report.md"), &md)?;
    Ok(md)
}
