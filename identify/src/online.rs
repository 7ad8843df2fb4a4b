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

impl Method {
    /// The method's name on the command line and in an estimator FMU's configuration.
    pub fn name(self) -> &'static str {
        match self {
            Self::Ukf => "ukf",
            Self::Ekf => "ekf",
            Self::MaximumLikelihood => "ml",
        }
    }

    /// The method named `text` ([`Method::name`]).
    pub fn named(text: &str) -> Option<Self> {
        [Self::Ukf, Self::Ekf, Self::MaximumLikelihood]
            .into_iter()
            .find(|m| m.name() == text)
    }
}

impl Robust {
    /// The weights' name on the command line and in an estimator FMU's configuration.
    pub fn name(self) -> &'static str {
        match self {
            Self::None => "none",
            Self::Huber => "huber",
            Self::Tukey => "tukey",
        }
    }

    /// The weights named `text` ([`Robust::name`]).
    pub fn named(text: &str) -> Option<Self> {
        [Self::None, Self::Huber, Self::Tukey]
            .into_iter()
            .find(|r| r.name() == text)
    }
}
