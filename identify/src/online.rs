//! The joint online filter as `spurio identify --method ukf|ekf` and the estimator FMU
//! (fmus/PlantEstimator) both set it up, so that both give the same θ̂ on the same record
//! (docs/estimators.md, "Identifying an FMU"): z = [x; θ] with every free parameter a
//! random-walk state, ẑ₀ = [x₀(θ₀); θ₀], P₀ = diag(σ²_x, σ²_θ) with σ_x,i = 1 % of
//! max(|x₀,i|, 1) and σ_θ,i = [`PARAMETER_PRIOR`] · max(|θ₀,i|, 10⁻³), Q = diag(Q_x, 0) with
//! Q_x = [`STATE_PROCESS_NOISE`] per sample (the model is trusted; θ drifts only through the
//! corrections).

use crate::filter::{Filter, FilterError, FilterSettings, Linearisation, Noise};
use crate::plant::FmuPlant;
use nalgebra::{DMatrix, DVector};
use spurio::estimation::InfluenceFunction;
use std::cell::RefCell;
use std::rc::Rc;

/// The online filter's prior standard deviation of a parameter, relative to its start value:
/// wider, the sigma points of a hybrid model's parameter leave its meaningful range
/// (BouncingBall's e from 0.7 ± 0.6 bounces with gain).
pub const PARAMETER_PRIOR: f64 = 0.2;

/// Q_x: the variance added to each state per sample.
pub const STATE_PROCESS_NOISE: f64 = 1e-10;

/// x̂₀'s variance per state: (1 % of max(|x₀|, 1))².
pub fn state_variance(x0: &[f64]) -> Vec<f64> {
    x0.iter()
        .map(|x| (0.01 * x.abs().max(1.0)).powi(2))
        .collect()
}

/// The settings of a filter on n states and `augmented` parameters in z: Q_x = `state` on
/// the states, 0 on the parameters, R = diag(`measurement`).
pub fn settings(
    state: f64,
    n: usize,
    augmented: usize,
    measurement: &[f64],
    robust: Option<InfluenceFunction>,
    linearisation: Linearisation,
) -> FilterSettings {
    FilterSettings {
        noise: Noise::new(state, n, 0.0, augmented, measurement),
        robust,
        linearisation,
    }
}

/// The joint filter on `plant` (afresh) from the parameters' starts `theta0` and the
/// states `x0` they give, every free parameter in z (module documentation).
pub fn joint_filter(
    plant: &Rc<RefCell<FmuPlant>>,
    theta0: &[f64],
    x0: &[f64],
    measurement: &[f64],
    robust: Option<InfluenceFunction>,
    linearisation: Linearisation,
) -> Result<Filter, FilterError> {
    let mut p0 = state_variance(x0);
    p0.extend(
        theta0
            .iter()
            .map(|s| (PARAMETER_PRIOR * s.abs().max(1e-3)).powi(2)),
    );
    let augmented: Vec<usize> = (0..theta0.len()).collect();
    plant.borrow_mut().start_afresh();
    let p0 = DMatrix::from_diagonal(&DVector::from_vec(p0));
    let online = settings(
        STATE_PROCESS_NOISE,
        x0.len(),
        augmented.len(),
        measurement,
        robust,
        linearisation,
    );
    Filter::new(plant.clone(), theta0, &augmented, x0, p0, &online)
}

/// The measured variables of `plant` at θ = `theta` from its initial states at θ, at the
/// times `times[1..]`, the inputs `inputs[k]` held over [t_k, t_{k+1}] (no noise): a
/// record to test an estimator on. Row k − 1 is y(t_k).
pub fn simulate(
    plant: &mut FmuPlant,
    theta: &[f64],
    times: &[f64],
    inputs: &[Vec<f64>],
) -> Result<Vec<Vec<f64>>, crate::plant::PlantError> {
    let mut x = plant.initial_states(theta)?;
    let mut next = x.clone();
    let mut rows = Vec::with_capacity(times.len());
    for (k, pair) in times.windows(2).enumerate() {
        let mut y = vec![0.0; plant.output_names().len()];
        let start = crate::plant::Start {
            time: pair[0],
            states: &x,
            parameters: theta,
            inputs: inputs.get(k).map_or(&[][..], Vec::as_slice),
            reference: None,
        };
        plant.propagate(&start, pair[1], &mut next, &mut y)?;
        x.copy_from_slice(&next);
        rows.push(y);
    }
    Ok(rows)
}

/// The estimator.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Method {
    /// The robust UKF, the parameters random-walk states.
    Ukf,
    /// The robust EKF, the parameters random-walk states.
    Ekf,
    /// Maximum likelihood (Huber loss when robust) of the output errors.
    MaximumLikelihood,
}

/// The robust weights of the online filter (and the loss of the offline fit).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Robust {
    /// The plain filter and the Gaussian likelihood.
    None,
    /// Huber's weights (c = 1.645) online, Huber's loss (c = 1.345) offline.
    Huber,
    /// Tukey's bisquare weights (c = 4.685) online, Huber's loss offline.
    Tukey,
}

impl Method {
    /// How the method's filters (online, and those judging the fit) carry the covariance:
    /// linearised for the EKF, unscented otherwise.
    pub fn linearisation(self) -> Linearisation {
        match self {
            Self::Ekf => Linearisation::Extended,
            Self::Ukf | Self::MaximumLikelihood => Linearisation::UNSCENTED,
        }
    }
}

impl Robust {
    /// The ψ function of the online filter.
    pub fn influence(self) -> Option<InfluenceFunction> {
        match self {
            Self::None => None,
            Self::Huber => Some(InfluenceFunction::huber()),
            Self::Tukey => Some(InfluenceFunction::tukey()),
        }
    }
}

/// The methods by their names on the command line and in an estimator FMU's configuration.
const METHODS: [(Method, &str); 3] = [
    (Method::Ukf, "ukf"),
    (Method::Ekf, "ekf"),
    (Method::MaximumLikelihood, "ml"),
];

/// The robust weights by their names.
const WEIGHTS: [(Robust, &str); 3] = [
    (Robust::None, "none"),
    (Robust::Huber, "huber"),
    (Robust::Tukey, "tukey"),
];

/// The name of `value` in `table`.
fn name_in<T: PartialEq + Copy>(table: &[(T, &'static str)], value: T) -> &'static str {
    table
        .iter()
        .find(|(v, _)| *v == value)
        .map_or("", |(_, name)| name)
}

/// The value named `text` in `table`.
fn named_in<T: Copy>(table: &[(T, &str)], text: &str) -> Option<T> {
    table
        .iter()
        .find(|(_, name)| *name == text)
        .map(|(v, _)| *v)
}

impl Method {
    /// The method's name (`ukf`, `ekf`, `ml`).
    pub fn name(self) -> &'static str {
        name_in(&METHODS, self)
    }

    /// The method named `text` ([`Method::name`]).
    pub fn named(text: &str) -> Option<Self> {
        named_in(&METHODS, text)
    }
}

impl Robust {
    /// The weights' name (`none`, `huber`, `tukey`).
    pub fn name(self) -> &'static str {
        name_in(&WEIGHTS, self)
    }

    /// The weights named `text` ([`Robust::name`]).
    pub fn named(text: &str) -> Option<Self> {
        named_in(&WEIGHTS, text)
    }
}
