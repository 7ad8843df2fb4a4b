//! Offline identification: maximum likelihood of the innovations over named free parameters
//! (docs/estimators.md, "Maximum likelihood").
//!
//! The likelihood is `spurio`'s ([`spurio::estimation::likelihood`]: a Kalman filter's
//! prediction errors v_t and their covariances F_t, ℓ(θ) = −½ Σ (p_t log 2π + log det F_t +
//! v_tᵀ F_t⁻¹ v_t), a diffuse initial state, missing samples); this crate maximises it with
//! a well-kept optimiser (argmin's Nelder–Mead) and reads the standard errors off the
//! curvature at the optimum. It is a crate of its own so that the optimiser never enters an
//! FMU: every FMU links `spurio`, none links this crate.
//!
//! **Parametrisation.** A parameter declared [`Scale::Log`] (a variance) is searched as
//! ψ = ln θ, so every point the optimiser tries is positive; [`Scale::Linear`] ones as ψ = θ.
//!
//! **Search.** Nelder–Mead (argmin; reflection 1, expansion 2, contraction ½, shrink ½) from
//! every start of the Cartesian product of the parameters' start lists, the initial simplex
//! the start and the start moved by [`Options::initial_step`] along each ψ axis. A run ends
//! when the standard deviation of −ℓ over the simplex's vertices falls below
//! [`Options::tolerance`] (converged) or after [`Options::max_iterations`]. The best run's
//! optimum is then polished by Nelder–Mead restarted from it with a fresh simplex (step
//! [`Options::initial_step`]/10) until a restart gains less than the tolerance: a simplex can
//! collapse before it reaches the optimum, a fresh one cannot stay collapsed.
//!
//! **Standard errors.** The Hessian H_ψ of −ℓ in ψ at the optimum ψ̂ by central differences
//! (step [`Options::hessian_step`] on each ψ, relative for linear parameters), its inverse
//! Σ_ψ = H_ψ⁻¹ by Cholesky, and the delta method Σ_θ = J Σ_ψ J, J = diag(dθ/dψ) (θ̂_i for a
//! log parameter, 1 for a linear one): se(θ̂_i) = √(Σ_θ)_ii. At the optimum the gradient
//! vanishes, so H_θ = J⁻¹ H_ψ J⁻¹ is the Hessian in the natural parameters and Σ_θ = H_θ⁻¹
//! is the same covariance (the Nile test checks both against a Hessian taken in θ directly).
//! A Hessian that is not positive definite (a flat or saddle direction: a parameter the data
//! do not determine) is reported as such ([`Curvature::NotPositiveDefinite`]), without
//! standard errors.

use argmin::core::{CostFunction, Executor, State, TerminationReason};
use argmin::solver::neldermead::NelderMead;
use nalgebra::{Cholesky, DMatrix};
use spurio::estimation::likelihood::{
    log_likelihood, Initialisation, LikelihoodError, LogLikelihood, PredictionErrorModel, Record,
};

/// How a free parameter is searched.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Scale {
    /// θ > 0, searched as ψ = ln θ (variances, time constants).
    Log,
    /// θ real, searched as ψ = θ.
    Linear,
}

impl Scale {
    /// θ of ψ.
    fn natural(self, psi: f64) -> f64 {
        match self {
            Self::Log => psi.exp(),
            Self::Linear => psi,
        }
    }

    /// ψ of θ.
    fn search(self, theta: f64) -> f64 {
        match self {
            Self::Log => theta.ln(),
            Self::Linear => theta,
        }
    }

    /// dθ/dψ at θ.
    fn derivative(self, theta: f64) -> f64 {
        match self {
            Self::Log => theta,
            Self::Linear => 1.0,
        }
    }
}

/// A free parameter of the model, by name, with its start values and its scale.
#[derive(Debug, Clone, PartialEq)]
pub struct FreeParameter {
    /// The model's name for it ([`PredictionErrorModel::parameter_names`]).
    pub name: String,
    /// Start values: the fit runs from every combination of the parameters' starts.
    pub starts: Vec<f64>,
    /// How it is searched.
    pub scale: Scale,
}

impl FreeParameter {
    /// A positive parameter (searched on the log scale) with these starts.
    pub fn positive(name: &str, starts: &[f64]) -> Self {
        Self {
            name: name.to_string(),
            starts: starts.to_vec(),
            scale: Scale::Log,
        }
    }

    /// A real parameter (searched as it is) with these starts.
    pub fn real(name: &str, starts: &[f64]) -> Self {
        Self {
            name: name.to_string(),
            starts: starts.to_vec(),
            scale: Scale::Linear,
        }
    }
}

/// The settings of the search (module documentation).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Options {
    /// A run has converged when the standard deviation of −ℓ over the simplex is below this.
    pub tolerance: f64,
    /// The most Nelder–Mead iterations of one run.
    pub max_iterations: u64,
    /// The initial simplex's step along each ψ (0.5: a factor e^0.5 ≈ 1.65 on a log
    /// parameter).
    pub initial_step: f64,
    /// The central-difference step of the Hessian on each ψ.
    pub hessian_step: f64,
}

impl Default for Options {
    fn default() -> Self {
        Self {
            tolerance: 1e-10,
            max_iterations: 5_000,
            initial_step: 0.5,
            hessian_step: 1e-3,
        }
    }
}

/// Why a fit cannot be made.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum IdentifyError {
    /// A free parameter the model does not have.
    #[error("`{name}` is not a free parameter of the model; its free parameters are {known}")]
    UnknownParameter {
        /// The name given.
        name: String,
        /// The model's free parameters, comma-separated.
        known: String,
    },
    /// The model has no free parameter: nothing to estimate.
    #[error("the model has no free parameter: nothing to estimate")]
    NoFreeParameter,
    /// A free parameter of the model that was given no start.
    #[error(
        "free parameter `{name}` of the model is not given (every free parameter needs its starts)"
    )]
    MissingParameter {
        /// Its name.
        name: String,
    },
    /// A parameter given twice.
    #[error("free parameter `{name}` is given twice")]
    DuplicateParameter {
        /// Its name.
        name: String,
    },
    /// A start that cannot be used.
    #[error("free parameter `{name}`: start {value} {reason}")]
    BadStart {
        /// The parameter.
        name: String,
        /// The start.
        value: f64,
        /// Why not.
        reason: &'static str,
    },
    /// A setting out of range.
    #[error("option `{name}` = {value}: {reason}")]
    BadOption {
        /// Which option.
        name: &'static str,
        /// Its value.
        value: f64,
        /// What it must be.
        reason: &'static str,
    },
    /// No run reached a point where the likelihood can be evaluated.
    #[error("no start reached a finite log-likelihood ({runs} runs); the likelihood at the first start: {first}")]
    NoFiniteOptimum {
        /// Runs made.
        runs: usize,
        /// Why ℓ failed at the first start.
        first: String,
    },
    /// The likelihood at a point the fit needs.
    #[error(transparent)]
    Likelihood(#[from] LikelihoodError),
    /// The optimiser failed.
    #[error("the optimiser failed: {0}")]
    Optimiser(String),
}

/// One Nelder–Mead run.
#[derive(Debug, Clone, PartialEq)]
pub struct Run {
    /// θ it started from.
    pub start: Vec<f64>,
    /// θ it ended at.
    pub estimate: Vec<f64>,
    /// ℓ there (−∞ where it cannot be evaluated).
    pub log_likelihood: f64,
    /// Its Nelder–Mead iterations.
    pub iterations: u64,
    /// Whether it met the tolerance (rather than the iteration limit).
    pub converged: bool,
}

/// One parameter's estimate.
#[derive(Debug, Clone, PartialEq)]
pub struct Estimate {
    /// Its name.
    pub name: String,
    /// θ̂.
    pub value: f64,
    /// se(θ̂), None when the Hessian is not positive definite.
    pub standard_error: Option<f64>,
    /// The start of the best run.
    pub start: f64,
}

/// The curvature of −ℓ at the optimum.
#[derive(Debug, Clone, PartialEq)]
pub enum Curvature {
    /// H positive definite: the covariance Σ_θ of the estimates.
    PositiveDefinite {
        /// Σ_θ = J H_ψ⁻¹ J (module documentation).
        covariance: DMatrix<f64>,
    },
    /// H is not positive definite (its Cholesky factorisation fails): some direction is flat
    /// or a saddle, no standard error.
    NotPositiveDefinite,
}

/// The maximum-likelihood fit.
#[derive(Debug, Clone, PartialEq)]
pub struct Fit {
    /// θ̂ with standard errors, in the model's order.
    pub estimates: Vec<Estimate>,
    /// ℓ(θ̂) and what went into it.
    pub log_likelihood: LogLikelihood,
    /// Every run, in the order of the starts.
    pub runs: Vec<Run>,
    /// The index of the best run in `runs`.
    pub best_run: usize,
    /// Iterations of the polishing restarts from the best run.
    pub polish_iterations: u64,
    /// The Hessian of −ℓ in the natural parameters θ at θ̂: J⁻¹ H_ψ J⁻¹.
    pub hessian: DMatrix<f64>,
    /// Whether it is positive definite, and then the covariance of θ̂.
    pub curvature: Curvature,
}

impl Fit {
    /// The estimate of the parameter `name`.
    pub fn estimate(&self, name: &str) -> Option<&Estimate> {
        self.estimates.iter().find(|e| e.name == name)
    }
}

/// −ℓ as a function of ψ, for argmin; +∞ where ℓ cannot be evaluated (a point the
/// optimiser then leaves), never NaN.
struct NegativeLogLikelihood<'a, M> {
    model: &'a M,
    record: &'a Record,
    initialisation: &'a Initialisation,
    scales: &'a [Scale],
}

impl<M: PredictionErrorModel> NegativeLogLikelihood<'_, M> {
    fn theta(&self, psi: &[f64]) -> Vec<f64> {
        psi.iter()
            .zip(self.scales)
            .map(|(psi, scale)| scale.natural(*psi))
            .collect()
    }

    fn evaluate(&self, psi: &[f64]) -> Result<LogLikelihood, LikelihoodError> {
        log_likelihood(
            self.model,
            &self.theta(psi),
            self.record,
            self.initialisation,
        )
    }

    fn value(&self, psi: &[f64]) -> f64 {
        match self.evaluate(psi) {
            Ok(ll) if ll.value.is_finite() => -ll.value,
            _ => f64::INFINITY,
        }
    }
}

impl<M: PredictionErrorModel> CostFunction for NegativeLogLikelihood<'_, M> {
    type Param = Vec<f64>;
    type Output = f64;

    fn cost(&self, psi: &Vec<f64>) -> Result<f64, argmin::core::Error> {
        Ok(self.value(psi))
    }
}

/// The parameters in the model's order, checked against its names.
fn in_model_order<'a, M: PredictionErrorModel>(
    model: &M,
    parameters: &'a [FreeParameter],
) -> Result<Vec<&'a FreeParameter>, IdentifyError> {
    let names = model.parameter_names();
    if names.is_empty() {
        return Err(IdentifyError::NoFreeParameter);
    }
    for (i, parameter) in parameters.iter().enumerate() {
        if !names.contains(&parameter.name) {
            return Err(IdentifyError::UnknownParameter {
                name: parameter.name.clone(),
                known: names.join(", "),
            });
        }
        if parameters[..i].iter().any(|p| p.name == parameter.name) {
            return Err(IdentifyError::DuplicateParameter {
                name: parameter.name.clone(),
            });
        }
    }
    let ordered = names
        .iter()
        .map(|name| {
            parameters
                .iter()
                .find(|p| &p.name == name)
                .ok_or_else(|| IdentifyError::MissingParameter { name: name.clone() })
        })
        .collect::<Result<Vec<_>, _>>()?;
    for parameter in &ordered {
        let bad = |value, reason| IdentifyError::BadStart {
            name: parameter.name.clone(),
            value,
            reason,
        };
        if parameter.starts.is_empty() {
            return Err(bad(f64::NAN, "is missing: the list of starts is empty"));
        }
        for &value in &parameter.starts {
            if !value.is_finite() {
                return Err(bad(value, "is not finite"));
            }
            if parameter.scale == Scale::Log && value <= 0.0 {
                return Err(bad(value, "must be positive (a log-scale parameter)"));
            }
        }
    }
    Ok(ordered)
}

fn check_options(options: &Options) -> Result<(), IdentifyError> {
    for (name, value) in [
        ("tolerance", options.tolerance),
        ("initial_step", options.initial_step),
        ("hessian_step", options.hessian_step),
    ] {
        if !(value.is_finite() && value > 0.0) {
            return Err(IdentifyError::BadOption {
                name,
                value,
                reason: "must be finite and positive",
            });
        }
    }
    if options.max_iterations == 0 {
        return Err(IdentifyError::BadOption {
            name: "max_iterations",
            value: 0.0,
            reason: "must be at least 1",
        });
    }
    Ok(())
}

/// Every combination of the parameters' starts (the Cartesian product, the first parameter
/// varying slowest).
fn start_grid(parameters: &[&FreeParameter]) -> Vec<Vec<f64>> {
    parameters.iter().fold(vec![Vec::new()], |grid, parameter| {
        grid.iter()
            .flat_map(|head| {
                parameter.starts.iter().map(move |&start| {
                    let mut point = head.clone();
                    point.push(start);
                    point
                })
            })
            .collect()
    })
}

/// The step along each ψ axis for a nominal `step`: `step` on a log parameter (a relative
/// change of θ), `step`·max(|ψ_i|, 1) on a linear one.
fn axis_steps(psi: &[f64], scales: &[Scale], step: f64) -> Vec<f64> {
    psi.iter()
        .zip(scales)
        .map(|(psi, scale)| match scale {
            Scale::Log => step,
            Scale::Linear => step * psi.abs().max(1.0),
        })
        .collect()
}

/// One Nelder–Mead run from ψ₀ with simplex step `step` ([`axis_steps`]): (ψ̂, −ℓ(ψ̂), iterations, converged).
fn nelder_mead<M: PredictionErrorModel>(
    objective: NegativeLogLikelihood<'_, M>,
    psi0: &[f64],
    step: f64,
    options: &Options,
) -> Result<(Vec<f64>, f64, u64, bool), IdentifyError> {
    let mut simplex = vec![psi0.to_vec()];
    for (i, h) in axis_steps(psi0, objective.scales, step)
        .into_iter()
        .enumerate()
    {
        let mut vertex = psi0.to_vec();
        vertex[i] += h;
        simplex.push(vertex);
    }
    let optimiser = |e: argmin::core::Error| IdentifyError::Optimiser(e.to_string());
    let solver = NelderMead::new(simplex)
        .with_sd_tolerance(options.tolerance)
        .map_err(optimiser)?;
    let result = Executor::new(objective, solver)
        .configure(|state| state.max_iters(options.max_iterations))
        .run()
        .map_err(optimiser)?;
    let state = result.state();
    let psi = state
        .get_best_param()
        .cloned()
        .unwrap_or_else(|| psi0.to_vec());
    let converged = matches!(
        state.get_termination_reason(),
        Some(TerminationReason::SolverConverged)
    );
    Ok((psi, state.get_best_cost(), state.get_iter(), converged))
}

/// The most polishing restarts after the best run.
const MAX_POLISH_RESTARTS: usize = 5;

/// Maximises ℓ(θ) of `record` under `model` over the free parameters (module
/// documentation): every parameter of the model given once by name with its starts.
pub fn maximise_likelihood<M: PredictionErrorModel>(
    model: &M,
    record: &Record,
    initialisation: &Initialisation,
    parameters: &[FreeParameter],
    options: &Options,
) -> Result<Fit, IdentifyError> {
    check_options(options)?;
    let ordered = in_model_order(model, parameters)?;
    let scales: Vec<Scale> = ordered.iter().map(|p| p.scale).collect();
    let objective = || NegativeLogLikelihood {
        model,
        record,
        initialisation,
        scales: &scales,
    };
    let to_psi = |theta: &[f64]| -> Vec<f64> {
        theta
            .iter()
            .zip(&scales)
            .map(|(theta, scale)| scale.search(*theta))
            .collect()
    };
    let mut runs = Vec::new();
    let mut best: Option<(usize, Vec<f64>, f64)> = None;
    for start in start_grid(&ordered) {
        let (psi, cost, iterations, converged) =
            nelder_mead(objective(), &to_psi(&start), options.initial_step, options)?;
        if cost.is_finite() && best.as_ref().is_none_or(|(_, _, c)| cost < *c) {
            best = Some((runs.len(), psi.clone(), cost));
        }
        runs.push(Run {
            start,
            estimate: objective().theta(&psi),
            log_likelihood: -cost,
            iterations,
            converged,
        });
    }
    let Some((best_run, mut psi, mut cost)) = best else {
        let first = runs
            .first()
            .and_then(|run| objective().evaluate(&to_psi(&run.start)).err())
            .map_or_else(|| "finite".to_string(), |e| e.to_string());
        return Err(IdentifyError::NoFiniteOptimum {
            runs: runs.len(),
            first,
        });
    };
    let mut polish_iterations = 0;
    for _ in 0..MAX_POLISH_RESTARTS {
        let (next, next_cost, iterations, _) =
            nelder_mead(objective(), &psi, options.initial_step / 10.0, options)?;
        polish_iterations += iterations;
        let gain = cost - next_cost;
        if next_cost < cost {
            (psi, cost) = (next, next_cost);
        }
        if gain.is_nan() || gain < options.tolerance {
            break;
        }
    }
    let log_likelihood = objective().evaluate(&psi)?;
    let theta = objective().theta(&psi);
    let hessian_psi = hessian(&objective(), &psi, options.hessian_step)?;
    let jacobian: Vec<f64> = theta
        .iter()
        .zip(&scales)
        .map(|(theta, scale)| scale.derivative(*theta))
        .collect();
    let hessian = DMatrix::from_fn(psi.len(), psi.len(), |i, j| {
        hessian_psi[(i, j)] / (jacobian[i] * jacobian[j])
    });
    let curvature = match Cholesky::new(hessian_psi) {
        Some(factor) => {
            let inverse = factor.inverse();
            Curvature::PositiveDefinite {
                covariance: DMatrix::from_fn(psi.len(), psi.len(), |i, j| {
                    jacobian[i] * inverse[(i, j)] * jacobian[j]
                }),
            }
        }
        None => Curvature::NotPositiveDefinite,
    };
    let estimates = ordered
        .iter()
        .zip(&theta)
        .enumerate()
        .map(|(i, (parameter, value))| Estimate {
            name: parameter.name.clone(),
            value: *value,
            standard_error: match &curvature {
                Curvature::PositiveDefinite { covariance } => Some(covariance[(i, i)].sqrt()),
                Curvature::NotPositiveDefinite => None,
            },
            start: runs[best_run].start.get(i).copied().unwrap_or(f64::NAN),
        })
        .collect();
    Ok(Fit {
        estimates,
        log_likelihood,
        runs,
        best_run,
        polish_iterations,
        hessian,
        curvature,
    })
}

/// The Hessian of −ℓ in ψ at ψ̂ by central differences, steps h_i of [`axis_steps`]:
/// H_ii = (f(ψ + h_i e_i) − 2 f(ψ) + f(ψ − h_i e_i)) / h_i²,
/// H_ij = (f(+,+) − f(+,−) − f(−,+) + f(−,−)) / (4 h_i h_j). Errors when ℓ cannot be
/// evaluated at a point of the stencil.
fn hessian<M: PredictionErrorModel>(
    objective: &NegativeLogLikelihood<'_, M>,
    psi: &[f64],
    step: f64,
) -> Result<DMatrix<f64>, IdentifyError> {
    let h = axis_steps(psi, objective.scales, step);
    let f = |moves: &[(usize, f64)]| -> Result<f64, IdentifyError> {
        let mut point = psi.to_vec();
        for &(i, sign) in moves {
            point[i] += sign * h[i];
        }
        Ok(-objective.evaluate(&point)?.value)
    };
    let center = f(&[])?;
    let n = psi.len();
    let mut hessian = DMatrix::zeros(n, n);
    for i in 0..n {
        hessian[(i, i)] = (f(&[(i, 1.0)])? - 2.0 * center + f(&[(i, -1.0)])?) / (h[i] * h[i]);
        for j in 0..i {
            let value = (f(&[(i, 1.0), (j, 1.0)])?
                - f(&[(i, 1.0), (j, -1.0)])?
                - f(&[(i, -1.0), (j, 1.0)])?
                + f(&[(i, -1.0), (j, -1.0)])?)
                / (4.0 * h[i] * h[j]);
            hessian[(i, j)] = value;
            hessian[(j, i)] = value;
        }
    }
    Ok(hessian)
}

/// The Nile record of Durbin & Koopman's local-level example (data/nile/README.md: statsmodels
/// 0.14.6, originally Cobb 1978; public domain), embedded.
pub mod nile {
    use super::{maximise_likelihood, Fit, FreeParameter, IdentifyError, Options};
    use spurio::estimation::likelihood::{Initialisation, LinearGaussianModel, Record};

    /// Durbin & Koopman's estimates (§2.10): σ²_ε, σ²_η.
    pub const DURBIN_KOOPMAN: [f64; 2] = [15099.0, 1469.1];

    /// The local-level model x⁺ = x + η, y = x + ε fitted to `flows` by maximum likelihood
    /// with a diffuse initial state (the first term left out), σ²_ε and σ²_η free (log
    /// scale) from the nine starts {10³, 10⁴, 10⁵} × {10², 10³, 10⁴}, default [`Options`].
    pub fn fit(flows: &[f64]) -> Result<Fit, IdentifyError> {
        let record = Record::of_output(flows)?;
        maximise_likelihood(
            &LinearGaussianModel::local_level(),
            &record,
            &Initialisation::Diffuse { kappa: None },
            &[
                FreeParameter::positive("sigma2_epsilon", &[1e3, 1e4, 1e5]),
                FreeParameter::positive("sigma2_eta", &[1e2, 1e3, 1e4]),
            ],
            &Options::default(),
        )
    }

    /// `data/nile/nile.csv`: header `year,volume`, then one row per year 1871–1970.
    pub const CSV: &str = include_str!("../../data/nile/nile.csv");

    /// The annual flows (10⁸ m³) and their years, from [`CSV`]; errors name the line that
    /// is not `year,volume` of two numbers.
    pub fn flows() -> Result<(Vec<f64>, Vec<f64>), String> {
        let mut years = Vec::new();
        let mut volumes = Vec::new();
        let mut lines = CSV.lines().enumerate();
        match lines.next() {
            Some((_, "year,volume")) => {}
            other => {
                return Err(format!(
                    "line 1: expected the header year,volume, got {other:?}"
                ))
            }
        }
        for (index, line) in lines.filter(|(_, line)| !line.trim().is_empty()) {
            let parsed = line.split_once(',').and_then(|(year, volume)| {
                Some((year.trim().parse().ok()?, volume.trim().parse().ok()?))
            });
            let Some((year, volume)) = parsed else {
                return Err(format!("line {}: `{line}` is not two numbers", index + 1));
            };
            years.push(year);
            volumes.push(volume);
        }
        Ok((years, volumes))
    }
}
