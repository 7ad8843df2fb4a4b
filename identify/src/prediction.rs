//! What a prediction of the online filters on an FMU is (docs/estimators.md, "Identifying an
//! FMU"): the point it starts from ([`Step`]: ẑ, P, the parameters outside z, the inputs held
//! over [t₀, t₁]), what it hands to the correction ([`Prediction`]: ẑ⁻, P⁻, ŷ, S, C and, for
//! the extended filter, H) and the errors a step can end with. The unscented
//! ([`crate::ukf`]) and extended ([`crate::ekf`]) predictions take a [`Step`] and give a
//! [`Prediction`]; [`crate::filter`] chooses between them and corrects: imports point from the
//! filter to the predictions to this module, never back.

use crate::plant::{FmuPlant, PlantError};
use nalgebra::{DMatrix, DVector};

/// Why a filter step failed.
#[derive(Debug, thiserror::Error)]
pub enum FilterError {
    #[error(transparent)]
    Plant(#[from] PlantError),
    #[error(
        "at sample {sample} (t = {time}): the {what} is not positive definite (or not finite)"
    )]
    NotPositive {
        what: &'static str,
        sample: usize,
        time: f64,
    },
    #[error("the state-transition matrix Φ_xx = exp(½h(A(t₀) + A(t₁))) to t = {time}: {source}")]
    TransitionMatrix {
        time: f64,
        source: spurio::linalg::LinalgError,
    },
    #[error("the filter's settings: {0}")]
    Settings(String),
}

/// ½(P + Pᵀ), in place (each entry (Pᵢⱼ + Pⱼᵢ) · ½, as P + Pᵀ then · ½ gives it).
pub(crate) fn symmetrise(p: &mut DMatrix<f64>) {
    let n = p.nrows().min(p.ncols());
    for j in 0..n {
        for i in j..n {
            let mean = (p[(i, j)] + p[(j, i)]) * 0.5;
            p[(i, j)] = mean;
            p[(j, i)] = mean;
        }
    }
}

/// The prediction a filter hands to its correction ([`crate::filter`]): made once for the
/// filter's L states and p measured variables, written by every prediction.
#[derive(Debug, Clone)]
pub(crate) struct Prediction {
    /// ẑ⁻ and P⁻.
    pub z: DVector<f64>,
    pub p: DMatrix<f64>,
    /// ŷ, S = cov(y) + R and C = cov(z, y).
    pub y: DVector<f64>,
    pub s: DMatrix<f64>,
    pub cross: DMatrix<f64>,
    /// H, for the Joseph form (EKF).
    pub jacobian: Option<DMatrix<f64>>,
}

impl Prediction {
    /// Room for the prediction of L = `l` states and p = `p` measured variables, with H when
    /// `extended`.
    pub fn new(l: usize, p: usize, extended: bool) -> Self {
        Self {
            z: DVector::zeros(l),
            p: DMatrix::zeros(l, l),
            y: DVector::zeros(p),
            s: DMatrix::zeros(p, p),
            cross: DMatrix::zeros(l, p),
            jacobian: extended.then(|| DMatrix::zeros(p, l)),
        }
    }
}

/// The dimensions a prediction's work buffers are made for.
pub(crate) struct Sizes {
    /// n.
    pub states: usize,
    /// L = n + q.
    pub filter_states: usize,
    /// p.
    pub measured: usize,
    /// Every free parameter (θ).
    pub parameters: usize,
    /// The FMU's event indicators.
    pub indicators: usize,
}

/// The point a prediction starts from: the filter's ẑ, P, the parameters outside z, the
/// inputs held and the interval.
pub(crate) struct Step<'a> {
    pub plant: &'a mut FmuPlant,
    /// n.
    pub states: usize,
    /// Indices (into θ) of the parameters in z.
    pub augmented: &'a [usize],
    /// Every free parameter's value (those in z taken from ẑ).
    pub theta: &'a [f64],
    pub z: &'a DVector<f64>,
    pub p: &'a DMatrix<f64>,
    /// R.
    pub r: &'a [f64],
    /// diag Q, added to P⁻ (None at the first sample, which only evaluates y at the prior).
    pub q: Option<&'a DVector<f64>>,
    /// [t₀, t₁] (t₀ = t₁ at the first sample: y evaluated at the prior) and u held over it.
    pub t0: f64,
    pub t1: f64,
    pub u: &'a [f64],
    /// The sample, for messages.
    pub sample: usize,
}

impl Step<'_> {
    /// θ with the parameters of z taken from `z`, into `theta`, each held to its declared
    /// range: Π(θ)ᵢ = min(max(θᵢ, minᵢ), maxᵢ). The filters' model is f(x, Π(θ)), so a sigma
    /// point or a difference step beyond a bound sees the plant at the bound instead of a
    /// value the FMU refuses (docs/estimators.md, "Parameters within their declared range").
    pub fn parameters_of(&self, z: &[f64], theta: &mut [f64]) {
        theta.copy_from_slice(self.theta);
        let declared = self.plant.parameters();
        for (k, &i) in self.augmented.iter().enumerate() {
            theta[i] = declared[i].range.clamp(z[self.states + k]);
        }
    }
}
