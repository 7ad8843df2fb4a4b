//! Robust-statistics Kalman filter (rsKF), docs/estimators.md §2.8; Cipra & Romera (1997), papers
//! 000 §V and 001 §2 ("Filtro de Kalman de estadística robusta").
//!
//! Same model, prediction and state update as the [`KalmanFilter`](super::KalmanFilter);
//! only the gain differs. With R = R^{1/2} R^{1/2ᵀ} (lower Cholesky factor):
//!
//! ```text
//! r   = R^{-1/2} (y_k − C x⁻ − D u_k)             standardised prior residual
//! w_j = ψ(r_j) / r_j     (w_j = 1 when r_j = 0)   W = diag(w)
//! R̃   = R^{1/2} W⁻¹ R^{1/2ᵀ}
//! K   = P⁻ Cᵀ (C P⁻ Cᵀ + R̃)⁻¹
//! x̂_k = x⁻ + K e,   P_k = (I − K C) P⁻ (I − K C)ᵀ + K R̃ Kᵀ  (= (I − K C) P⁻, robust K)
//! ```
//!
//! The papers print W instead of W⁻¹: that trusts outliers more, not less; W⁻¹ is the
//! M-estimator (docs/estimators.md §2.8). The robust K also enters the covariance update.
//!
//! ψ functions ([`InfluenceFunction`]): Huber ψ(z) = z for |z| ≤ c, c·sgn z otherwise
//! (c = 1.645, 5 % contamination), so w = min(1, c/|z|); Tukey bisquare
//! ψ(z) = z (1 − (z/c)²)² for |z| ≤ c, 0 otherwise (c = 4.685). A zero weight (Tukey beyond
//! c) would make W⁻¹ infinite, i.e. K = 0 for that channel: the weights are clamped to
//! [`MIN_WEIGHT`], which gives that channel a gain ~1e-12 of its nominal value, without NaN.
//! When every weight is exactly 1 the filter uses R itself, so it reproduces the sKF bit for
//! bit whenever no standardised residual exceeds c (Huber).

use super::kalman::{
    core_accessors, FilterCore, GaussianModel, KalmanFilter, ScalarCovariance, ScalarKalmanFilter,
};
use super::missing::MissingMask;
use super::{parameter_error, require_length, EstimationError, Saved, StateReader};
use crate::linalg::dense::{self, View};
use crate::state_space::StateSpace;
use nalgebra::{Cholesky, DMatrix, DVector};

/// Smallest weight used in W⁻¹ (see the module documentation).
pub const MIN_WEIGHT: f64 = 1e-12;

/// The ψ function of the M-estimator, with its tuning constant c (in standard deviations).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum InfluenceFunction {
    /// Huber: ψ(z) = z for |z| ≤ c, c·sgn(z) otherwise. Weight min(1, c/|z|).
    Huber {
        /// Threshold c (default 1.645: 5 % contamination).
        c: f64,
    },
    /// Tukey bisquare: ψ(z) = z (1 − (z/c)²)² for |z| ≤ c, 0 otherwise. Weight
    /// (1 − (z/c)²)² inside, 0 outside (clamped to [`MIN_WEIGHT`]).
    Tukey {
        /// Rejection point c (default 4.685: 95 % efficiency at the normal).
        c: f64,
    },
}

impl InfluenceFunction {
    /// Huber with c = 1.645.
    pub const fn huber() -> Self {
        Self::Huber { c: 1.645 }
    }
    /// Tukey bisquare with c = 4.685.
    pub const fn tukey() -> Self {
        Self::Tukey { c: 4.685 }
    }

    /// The tuning constant c.
    pub fn threshold(&self) -> f64 {
        match *self {
            Self::Huber { c } | Self::Tukey { c } => c,
        }
    }

    /// ψ(z).
    pub fn psi(&self, z: f64) -> f64 {
        match *self {
            Self::Huber { c } => z.clamp(-c, c),
            Self::Tukey { c } => {
                if z.abs() <= c {
                    let t = 1.0 - (z / c) * (z / c);
                    z * t * t
                } else {
                    0.0
                }
            }
        }
    }

    /// w(z) = ψ(z)/z, with w(0) = 1; not clamped.
    #[inline]
    pub fn weight(&self, z: f64) -> f64 {
        match *self {
            Self::Huber { c } => {
                if z.abs() <= c {
                    1.0
                } else {
                    c / z.abs()
                }
            }
            Self::Tukey { c } => {
                if z.abs() <= c {
                    let t = 1.0 - (z / c) * (z / c);
                    t * t
                } else {
                    0.0
                }
            }
        }
    }

    fn validate(&self) -> Result<(), EstimationError> {
        let c = self.threshold();
        if !(c.is_finite() && c > 0.0) {
            return Err(parameter_error(
                "c",
                format!("the ψ threshold must be a finite positive number, got {c}"),
            ));
        }
        Ok(())
    }
}

impl Default for InfluenceFunction {
    fn default() -> Self {
        Self::huber()
    }
}

/// The rsKF's R̃ for one output ([`FilterCore::step_scalar`]): r = e / √R, w = ψ(r)/r
/// (clamped), R̃ = (√R / √w)² (R itself when w = 1), each stored into its slot.
struct ScalarWeight<'a> {
    psi: InfluenceFunction,
    /// R and its square root √R.
    r: f64,
    l: f64,
    z: &'a mut f64,
    w: &'a mut f64,
    r_effective: &'a mut f64,
}

impl ScalarCovariance for ScalarWeight<'_> {
    #[inline(always)]
    fn at(self, e: f64) -> f64 {
        let (l, z, w) = (self.l, self.z, self.w);
        *z = e / l;
        // Branches, not selects: on the common path (w = 1) R̃ = R does not wait for e, so
        // the correction overlaps the division e / √R (the step's latency chain). Huber's
        // |r| ≤ c (w = 1 exactly) is the one branch of that path; a down-weighted sample
        // mispredicts it once and goes on inline (no call, no spills) to R̃.
        if let InfluenceFunction::Huber { c } = self.psi {
            if z.abs() <= c {
                *w = 1.0;
                *self.r_effective = self.r;
                return self.r;
            }
        }
        *w = self.psi.weight(*z).max(MIN_WEIGHT);
        *self.r_effective = if *w == 1.0 {
            self.r
        } else {
            down_weighted(l, *w)
        };
        *self.r_effective
    }
    #[inline(always)]
    fn missing(self) {
        (*self.z, *self.w, *self.r_effective) = (0.0, 0.0, self.r);
    }
}

/// R̃ = (√R / √w)² for a weight w < 1 (the down-weighted path of [`ScalarWeight`]).
#[inline(always)]
fn down_weighted(l: f64, w: f64) -> f64 {
    let g = l * (1.0 / w.sqrt());
    g * g
}

/// Robust-statistics Kalman filter (rsKF). See the module documentation for the equations.
#[derive(Debug, Clone)]
pub struct RobustKalmanFilter {
    model: StateSpace,
    core: FilterCore,
    psi: InfluenceFunction,
    /// R^{1/2ᵀ} (upper triangular, p×p).
    r_sqrt_t: DMatrix<f64>,
    /// R^{1/2} (lower triangular).
    r_sqrt: DMatrix<f64>,
    standardized: DVector<f64>,
    weights: DVector<f64>,
    /// W^{-1/2} R^{1/2ᵀ}, then R̃ = (W^{-1/2} R^{1/2ᵀ})ᵀ (W^{-1/2} R^{1/2ᵀ}).
    work_g: DMatrix<f64>,
    r_effective: DMatrix<f64>,
    /// C_M, R_M of a sample with missing channels.
    missing: MissingMask,
    /// R_M^{1/2} and R_M^{1/2ᵀ} of that sample.
    missing_sqrt: DMatrix<f64>,
    missing_sqrt_t: DMatrix<f64>,
}

impl RobustKalmanFilter {
    /// Builds an rsKF; arguments as [`KalmanFilter::new`](super::KalmanFilter::new) plus the
    /// ψ function. Errors name the matrix ("A", "B", "C", "D", "Q", "R", "P0", "x0") or "c".
    pub fn new(model: GaussianModel, psi: InfluenceFunction) -> Result<Self, EstimationError> {
        psi.validate()?;
        let (model, core) = model.into_filter()?;
        let p = model.outputs();
        let r_sqrt = Cholesky::new(model.r.clone())
            .ok_or_else(|| parameter_error("R", "must be positive definite"))?
            .l();
        Ok(Self {
            r_sqrt_t: r_sqrt.transpose(),
            r_sqrt,
            standardized: DVector::zeros(p),
            weights: DVector::from_element(p, 1.0),
            work_g: DMatrix::zeros(p, p),
            r_effective: model.r.clone(),
            missing: MissingMask::new(p, model.states()),
            missing_sqrt: DMatrix::zeros(p, p),
            missing_sqrt_t: DMatrix::zeros(p, p),
            model,
            core,
            psi,
        })
    }

    /// A scalar-per-channel random-walk filter (A = C = I_p, B, D empty, Q = q I, R = r I,
    /// x̂₀ = 0, P₀ = p0 I): the outlier cleaner of the cosine experiment.
    pub fn random_walk(
        channels: usize,
        q: f64,
        r: f64,
        p0: f64,
        psi: InfluenceFunction,
    ) -> Result<Self, EstimationError> {
        let ones = DVector::from_element(channels, 1.0);
        let zeros = DVector::zeros(channels);
        Self::first_order_from(zeros.clone(), (&ones, &zeros), q, r, p0, psi)
    }

    /// A first-order model per channel driven by an input of its own, started at x̂₀ =
    /// `start`: x_j(k) = a_j x_j(k−1) + b_j v_j(k−1), y_j = x_j (A = diag(a), B = diag(b),
    /// C = I_p, D = 0, Q = q I, R = r I, P₀ = p0 I; the filter applies B to the input of the
    /// previous step). With every b_j = 0 the filter has no input (B is p×0), and with a = 1
    /// as well it is the random walk of [`RobustKalmanFilter::random_walk`] started at `start`:
    /// the cleaner of the DKF-rsKF, started at the DKF's initial output, input-driven or not
    /// (docs/estimators.md §2.10).
    pub fn first_order_from(
        start: DVector<f64>,
        (a, b): (&DVector<f64>, &DVector<f64>),
        q: f64,
        r: f64,
        p0: f64,
        psi: InfluenceFunction,
    ) -> Result<Self, EstimationError> {
        let channels = start.len();
        require_length("a", a, channels, "one entry per channel")?;
        require_length("b", b, channels, "one entry per channel")?;
        let eye = DMatrix::<f64>::identity(channels, channels);
        let driven = b.iter().any(|v| *v != 0.0);
        Self::new(
            GaussianModel {
                system: StateSpace {
                    a: DMatrix::from_diagonal(a),
                    b: if driven {
                        DMatrix::from_diagonal(b)
                    } else {
                        DMatrix::zeros(channels, 0)
                    },
                    c: eye.clone(),
                    d: DMatrix::zeros(channels, if driven { channels } else { 0 }),
                    q: &eye * q,
                    r: &eye * r,
                },
                x0: start,
                p0: &eye * p0,
            },
            psi,
        )
    }

    /// Everything that evolves from step to step (see
    /// [`KalmanFilter::dynamic_state`](super::KalmanFilter::dynamic_state)): the filter core,
    /// the standardised residuals, the weights and the effective measurement covariance.
    pub fn dynamic_state(&self) -> Vec<f64> {
        self.saved()
    }

    /// Restores what [`RobustKalmanFilter::dynamic_state`] returned.
    pub fn set_dynamic_state(&mut self, state: &[f64]) -> Result<(), EstimationError> {
        self.restore_saved(state)
    }

    /// Processes one sample (see [`KalmanFilter::step`](super::KalmanFilter::step)).
    pub fn step(&mut self, u: &DVector<f64>, y: &DVector<f64>) -> Result<(), EstimationError> {
        let m = &self.model;
        if let ([r], [l], [z], [w], [r_effective]) = (
            m.r.as_slice(),
            self.r_sqrt.as_slice(),
            self.standardized.as_mut_slice(),
            self.weights.as_mut_slice(),
            self.r_effective.as_mut_slice(),
        ) {
            // One output: r = e / √R, R̃ = (√R / √w)² (R itself when w = 1).
            let effective = ScalarWeight {
                psi: self.psi,
                r: *r,
                l: *l,
                z,
                w,
                r_effective,
            };
            if let Some(result) = self.core.step_scalar(m, u, y, effective) {
                return result;
            }
        }
        if self.core.predict_and_innovate(m, u, y)? {
            return self.step_missing(u, y);
        }
        self.weigh(false)?;
        let m = &self.model;
        let (c, d) = (View::of(&m.c), View::of(&m.d));
        self.core.correct(c, &self.r_effective)?;
        self.core.finish(c, d, u);
        Ok(())
    }

    /// The rest of a step whose sample has missing channels (the prediction and the
    /// innovation made, e_j = 0 for a missing y_j): the rsKF of the present channels, with
    /// R_M and its Cholesky factor in place of R ([`MissingMask`]), so that the present
    /// channels are standardised and weighted with R_W^{1/2} and a missing channel has r_j = 0
    /// and R̃ = 1 on its diagonal, uncoupled. Its reported weight w_j is then 0 (it did not
    /// enter the correction); with every channel missing x̂ = x⁻, P = P⁻.
    fn step_missing(&mut self, u: &DVector<f64>, y: &DVector<f64>) -> Result<(), EstimationError> {
        let p = y.len();
        if self
            .missing
            .select(View::of(&self.model.c), &self.model.r, y)
            == p
        {
            self.core.predict_only()?;
        } else {
            // R_M^{1/2}: the Cholesky factor (lower triangle), the strict upper one zero.
            self.missing_sqrt.copy_from(&self.missing.r);
            let l = self.missing_sqrt.as_mut_slice();
            if !dense::cholesky(l, p) {
                return Err(EstimationError::Factorisation {
                    what: "measurement covariance R of the present channels",
                    step: self.core.steps,
                });
            }
            for j in 1..p {
                for i in 0..j {
                    l[i + j * p] = 0.0;
                }
            }
            self.missing_sqrt_t.tr_copy_from(&self.missing_sqrt);
            self.weigh(true)?;
            self.core
                .correct(View::of(&self.missing.c), &self.r_effective)?;
        }
        let weights = self.weights.iter_mut().zip(self.standardized.iter_mut());
        for ((w, z), y) in weights.zip(y) {
            if y.is_nan() {
                (*w, *z) = (0.0, 0.0);
            }
        }
        let m = &self.model;
        self.core.finish(View::of(&m.c), View::of(&m.d), u);
        self.core.check_output()
    }

    /// r = R^{-1/2} e, w_j = ψ(r_j)/r_j (clamped) and R̃ = R^{1/2} W⁻¹ R^{1/2ᵀ} (R itself
    /// when every weight is 1) from the innovation of the step; with `masked` R is the
    /// [`MissingMask`]'s R_M and R^{1/2} its factor.
    fn weigh(&mut self, masked: bool) -> Result<(), EstimationError> {
        let (r, r_sqrt, r_sqrt_t) = if masked {
            (&self.missing.r, &self.missing_sqrt, &self.missing_sqrt_t)
        } else {
            (&self.model.r, &self.r_sqrt, &self.r_sqrt_t)
        };
        // r = R^{-1/2} e.
        let z = self.standardized.as_mut_slice();
        for (z, e) in z.iter_mut().zip(self.core.innovation.as_slice()) {
            *z = *e;
        }
        let p = z.len();
        if !dense::solve_lower(r_sqrt.as_slice(), p, z) {
            return Err(EstimationError::Factorisation {
                what: "measurement covariance R",
                step: self.core.steps,
            });
        }
        let mut all_one = true;
        for (w, &z) in self.weights.as_mut_slice().iter_mut().zip(z.iter()) {
            *w = self.psi.weight(z).max(MIN_WEIGHT);
            all_one &= *w == 1.0;
        }
        if all_one {
            let r_effective = self.r_effective.as_mut_slice();
            for (r_effective, r) in r_effective.iter_mut().zip(r.as_slice()) {
                *r_effective = *r;
            }
        } else {
            // G = W^{-1/2} R^{1/2ᵀ}: row j of R^{1/2ᵀ} scaled by 1/√w_j; R̃ = Gᵀ G, its lower
            // triangle as dot products of the columns of G, mirrored.
            self.work_g.copy_from(r_sqrt_t);
            for (j, w) in self.weights.iter().enumerate() {
                let scale = 1.0 / w.sqrt();
                for g in self.work_g.row_mut(j).iter_mut() {
                    *g *= scale;
                }
            }
            let (g, r_effective) = (self.work_g.as_slice(), self.r_effective.as_mut_slice());
            for (j, g_j) in g.chunks_exact(p).enumerate() {
                for (i, g_i) in g.chunks_exact(p).enumerate().skip(j) {
                    if let Some(r) = r_effective.get_mut(i + j * p) {
                        *r = dense::dot(g_i, g_j);
                    }
                }
            }
            dense::mirror_lower(r_effective, p);
        }
        Ok(())
    }

    /// The same filter on plain numbers when the model has one state, one output and at
    /// most one input ([`ScalarRobustKalmanFilter`]); `None` otherwise.
    pub fn to_scalar(&self) -> Option<ScalarRobustKalmanFilter> {
        let filter = KalmanFilter::scalar_parts(&self.model, &self.core)?;
        match (
            self.r_sqrt.as_slice(),
            self.standardized.as_slice(),
            self.weights.as_slice(),
            self.r_effective.as_slice(),
        ) {
            ([l], [z], [w], [r_effective]) => Some(ScalarRobustKalmanFilter {
                filter,
                psi: self.psi,
                l: *l,
                z: *z,
                w: *w,
                r_effective: *r_effective,
            }),
            _ => None,
        }
    }

    core_accessors!();
    /// Standardised residual r = R^{-1/2} e of the last step.
    pub fn standardized_residual(&self) -> &DVector<f64> {
        &self.standardized
    }
    /// Weights w_j = ψ(r_j)/r_j of the last step (clamped to [`MIN_WEIGHT`]); 1 = trusted.
    pub fn weights(&self) -> &DVector<f64> {
        &self.weights
    }
    /// The effective measurement covariance R̃ = R^{1/2} W⁻¹ R^{1/2ᵀ} of the last step.
    pub fn effective_measurement_covariance(&self) -> &DMatrix<f64> {
        &self.r_effective
    }
    /// The ψ function in use.
    pub fn influence_function(&self) -> InfluenceFunction {
        self.psi
    }
}

/// The [`RobustKalmanFilter`] of a model with one state, one output and at most one input,
/// on plain numbers ([`RobustKalmanFilter::to_scalar`]): the same equations in the same
/// order (r = e / √R, w = ψ(r)/r clamped, R̃ = (√R / √w)², R itself when w = 1), so the same
/// results bit for bit. Its [`ScalarRobustKalmanFilter::dynamic_state`] is the
/// [`RobustKalmanFilter`]'s.
#[derive(Debug, Clone, PartialEq)]
pub struct ScalarRobustKalmanFilter {
    filter: ScalarKalmanFilter,
    psi: InfluenceFunction,
    /// √R.
    l: f64,
    /// The standardised residual, the weight and R̃ of the last step.
    z: f64,
    w: f64,
    r_effective: f64,
}

impl ScalarRobustKalmanFilter {
    /// Processes one sample (see [`RobustKalmanFilter::step`]); `u` is the input u_k
    /// (unused when the model has none).
    #[inline]
    pub fn step(&mut self, u: f64, y: f64) -> Result<(), EstimationError> {
        let effective = ScalarWeight {
            psi: self.psi,
            r: self.filter.r,
            l: self.l,
            z: &mut self.z,
            w: &mut self.w,
            r_effective: &mut self.r_effective,
        };
        let f = &mut self.filter;
        f.estimate.step(&f.model, u, y, effective)
    }
    /// The filter's estimates (state, output, innovation, gain: [`ScalarKalmanFilter`]).
    pub fn filter(&self) -> &ScalarKalmanFilter {
        &self.filter
    }
    /// Standardised residual r = e / √R of the last step.
    pub fn standardized_residual(&self) -> f64 {
        self.z
    }
    /// Weight w = ψ(r)/r of the last step (clamped to [`MIN_WEIGHT`]); 1 = trusted.
    pub fn weight(&self) -> f64 {
        self.w
    }
    /// The effective measurement covariance R̃ of the last step.
    pub fn effective_measurement_covariance(&self) -> f64 {
        self.r_effective
    }
    /// What [`RobustKalmanFilter::dynamic_state`] gives for the same filter.
    pub fn dynamic_state(&self) -> Vec<f64> {
        self.saved()
    }
    /// Restores what [`ScalarRobustKalmanFilter::dynamic_state`] returned.
    pub fn set_dynamic_state(&mut self, state: &[f64]) -> Result<(), EstimationError> {
        self.restore_saved(state)
    }
}

impl Saved for ScalarRobustKalmanFilter {
    fn save(&self, out: &mut Vec<f64>) {
        self.filter.save(out);
        out.extend_from_slice(&[self.z, self.w, self.r_effective]);
    }

    fn restore(&mut self, input: &mut StateReader<'_>) -> Result<(), EstimationError> {
        let mut restored = self.clone();
        restored.filter.restore(input)?;
        for v in [&mut restored.z, &mut restored.w, &mut restored.r_effective] {
            input.fill(std::slice::from_mut(v))?;
        }
        *self = restored;
        Ok(())
    }
}

impl Saved for RobustKalmanFilter {
    fn save(&self, out: &mut Vec<f64>) {
        self.core.save(out);
        out.extend_from_slice(self.standardized.as_slice());
        out.extend_from_slice(self.weights.as_slice());
        out.extend_from_slice(self.r_effective.as_slice());
    }

    fn restore(&mut self, input: &mut StateReader<'_>) -> Result<(), EstimationError> {
        self.core.restore(input)?;
        input.fill(self.standardized.as_mut_slice())?;
        input.fill(self.weights.as_mut_slice())?;
        input.fill(self.r_effective.as_mut_slice())
    }
}

#[cfg(test)]
pub(crate) mod test_rng {
    //! SplitMix64 + Box–Muller: a small deterministic generator for the tests only.

    pub(crate) struct TestRng {
        state: u64,
        spare: Option<f64>,
    }

    impl TestRng {
        pub(crate) fn new(seed: u64) -> Self {
            Self {
                state: seed,
                spare: None,
            }
        }
        pub(crate) fn next_u64(&mut self) -> u64 {
            self.state = self.state.wrapping_add(0x9E37_79B9_7F4A_7C15);
            let mut z = self.state;
            z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
            z ^ (z >> 31)
        }
        /// Uniform in [0, 1).
        pub(crate) fn uniform(&mut self) -> f64 {
            (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
        }
        /// Standard normal.
        pub(crate) fn normal(&mut self) -> f64 {
            if let Some(z) = self.spare.take() {
                return z;
            }
            let u1 = 1.0 - self.uniform();
            let u2 = self.uniform();
            let radius = (-2.0 * u1.ln()).sqrt();
            let angle = 2.0 * std::f64::consts::PI * u2;
            self.spare = Some(radius * angle.sin());
            radius * angle.cos()
        }
        /// Uniform integer in 0..n.
        pub(crate) fn below(&mut self, n: usize) -> usize {
            (self.uniform() * n as f64) as usize % n
        }
    }

    pub(crate) fn mean_std(values: &[f64]) -> (f64, f64) {
        let n = values.len() as f64;
        let mean = values.iter().sum::<f64>() / n;
        let var = values.iter().map(|v| (v - mean) * (v - mean)).sum::<f64>() / (n - 1.0);
        (mean, var.sqrt())
    }
}

#[cfg(test)]
mod tests {
    use super::test_rng::{mean_std, TestRng};
    use super::*;
    use crate::estimation::kalman::tests::{
        random_scalar_model, scalar_filter, step_both_bit_for_bit,
    };
    use crate::state_space::StateSpace;

    fn scalar(v: f64) -> DMatrix<f64> {
        DMatrix::from_element(1, 1, v)
    }

    #[test]
    fn the_scalar_robust_filter_on_numbers_equals_the_general_path_bit_for_bit() {
        let mut rng = TestRng::new(43);
        for (m, psi) in [
            (0, InfluenceFunction::huber()),
            (1, InfluenceFunction::huber()),
            (0, InfluenceFunction::tukey()),
            (1, InfluenceFunction::Tukey { c: 2.0 }),
        ] {
            let model = random_scalar_model(&mut rng, m);
            let mut general = RobustKalmanFilter::new(model, psi).unwrap();
            general.core.general_only = true;
            let mut fast = general.to_scalar().unwrap();
            let bits = |v: Vec<f64>| v.into_iter().map(f64::to_bits).collect::<Vec<_>>();
            assert_eq!(bits(fast.dynamic_state()), bits(general.dynamic_state()));
            let mut down_weighted = 0;
            for k in 0..5000 {
                let u = rng.normal();
                // a measurement with an outlier one time in five
                let outlier = if rng.uniform() < 0.2 { 50.0 } else { 0.0 };
                let y = rng.normal() + outlier * rng.normal();
                step_both_bit_for_bit(
                    &mut general,
                    &mut fast,
                    ScalarRobustKalmanFilter::step,
                    (m, u, y),
                    format_args!("m = {m}, {psi:?}, step {k}"),
                );
                assert_eq!(fast.weight(), general.weights()[0]);
                assert_eq!(fast.filter().state(), general.state()[0]);
                assert_eq!(fast.filter().output(), general.output()[0]);
                assert!(fast.filter().covariance() > 0.0);
                down_weighted += usize::from(fast.weight() < 1.0);
            }
            assert!(down_weighted > 500, "{down_weighted}");
            let mut restored = fast.clone();
            restored.step(0.5, 1.0).unwrap();
            restored.set_dynamic_state(&fast.dynamic_state()).unwrap();
            assert_eq!(restored, fast);
            assert!(restored.set_dynamic_state(&[0.0; 2]).is_err());
        }
    }

    #[test]
    fn weights_of_huber_and_tukey() {
        let huber = InfluenceFunction::huber();
        assert_eq!(huber.weight(0.0), 1.0);
        assert_eq!(huber.weight(1.0), 1.0);
        assert!((huber.weight(-3.29) - 0.5).abs() < 1e-12);
        assert!((huber.psi(10.0) - 1.645).abs() < 1e-15);
        let tukey = InfluenceFunction::tukey();
        assert_eq!(tukey.weight(0.0), 1.0);
        assert_eq!(tukey.weight(5.0), 0.0);
        assert!((tukey.psi(1.0) - tukey.weight(1.0)).abs() < 1e-15);
    }

    #[test]
    fn equals_standard_filter_when_no_residual_exceeds_threshold() {
        let a = DMatrix::from_row_slice(2, 2, &[0.95, 0.1, -0.1, 0.9]);
        let b = DMatrix::from_row_slice(2, 1, &[0.0, 1.0]);
        let c = DMatrix::from_row_slice(2, 2, &[1.0, 0.0, 0.5, 1.0]);
        let d = DMatrix::zeros(2, 1);
        let q = DMatrix::identity(2, 2) * 0.01;
        let r = DMatrix::from_row_slice(2, 2, &[0.04, 0.01, 0.01, 0.09]);
        let x0 = DVector::zeros(2);
        let p0 = DMatrix::identity(2, 2) * 0.01;
        let mut standard = KalmanFilter::new(GaussianModel {
            system: StateSpace {
                a: a.clone(),
                b: b.clone(),
                c: c.clone(),
                d: d.clone(),
                q: q.clone(),
                r: r.clone(),
            },
            x0: x0.clone(),
            p0: p0.clone(),
        })
        .unwrap();
        let mut robust = RobustKalmanFilter::new(
            GaussianModel {
                system: StateSpace { a, b, c, d, q, r },
                x0,
                p0,
            },
            InfluenceFunction::huber(),
        )
        .unwrap();
        let mut rng = TestRng::new(7);
        let mut truth = DVector::zeros(2);
        for k in 0..300 {
            let u = DVector::from_element(1, (0.05 * k as f64).sin());
            truth = DMatrix::from_row_slice(2, 2, &[0.95, 0.1, -0.1, 0.9]) * truth
                + DVector::from_vec(vec![0.0, u[0]]);
            // Small noise so that no standardised residual exceeds 1.645.
            let y = DMatrix::from_row_slice(2, 2, &[1.0, 0.0, 0.5, 1.0]) * &truth
                + DVector::from_vec(vec![0.01 * rng.normal(), 0.01 * rng.normal()]);
            standard.step(&u, &y).unwrap();
            robust.step(&u, &y).unwrap();
            assert!(robust.standardized_residual().amax() <= 1.645);
            assert_eq!(robust.state(), standard.state(), "step {k}");
            assert_eq!(robust.covariance(), standard.covariance());
            assert!(robust.weights().iter().all(|&w| w == 1.0));
        }
    }

    #[test]
    fn the_scalar_step_and_the_effective_covariance_match_the_former_kernels_bit_for_bit() {
        let mut rng = TestRng::new(11);
        for psi in [InfluenceFunction::huber(), InfluenceFunction::tukey()] {
            // One output, with and without an input: the scalar step against the general path.
            for m in [0, 1] {
                let mut fast = RobustKalmanFilter::new(
                    GaussianModel {
                        system: StateSpace {
                            a: scalar(0.97),
                            b: DMatrix::from_element(1, m, 0.3),
                            c: scalar(1.5),
                            d: DMatrix::from_element(1, m, -0.2),
                            q: scalar(1e-3),
                            r: scalar(1e-2),
                        },
                        x0: DVector::zeros(1),
                        p0: scalar(1.0),
                    },
                    psi,
                )
                .unwrap();
                let mut general = fast.clone();
                general.core.general_only = true;
                for k in 0..2000 {
                    let u = DVector::from_element(m, (0.01 * k as f64).sin());
                    let outlier = if rng.uniform() < 0.1 { 5.0 } else { 0.0 };
                    let y = DVector::from_element(1, 0.1 * rng.normal() + outlier);
                    fast.step(&u, &y).unwrap();
                    general.step(&u, &y).unwrap();
                    assert_eq!(fast.dynamic_state(), general.dynamic_state(), "step {k}");
                }
                assert!(fast.weights()[0] <= 1.0);
            }
            // Two correlated outputs: R̃ = Gᵀ G on one triangle against nalgebra's product.
            let r = DMatrix::from_row_slice(2, 2, &[0.04, 0.01, 0.01, 0.09]);
            let mut filter = RobustKalmanFilter::new(
                GaussianModel {
                    system: StateSpace {
                        a: DMatrix::identity(2, 2),
                        b: DMatrix::zeros(2, 0),
                        c: DMatrix::identity(2, 2),
                        d: DMatrix::zeros(2, 0),
                        q: DMatrix::identity(2, 2) * 1e-3,
                        r: r.clone(),
                    },
                    x0: DVector::zeros(2),
                    p0: DMatrix::identity(2, 2),
                },
                psi,
            )
            .unwrap();
            let l_t = Cholesky::new(r).unwrap().l().transpose();
            let mut changed = 0;
            for _ in 0..2000 {
                let outlier = if rng.uniform() < 0.1 { 3.0 } else { 0.0 };
                let y = DVector::from_fn(2, |_, _| 0.2 * rng.normal() + outlier);
                filter.step(&DVector::zeros(0), &y).unwrap();
                if filter.weights().iter().any(|&w| w != 1.0) {
                    let mut g = l_t.clone();
                    for (j, w) in filter.weights().iter().enumerate() {
                        g.row_mut(j).scale_mut(1.0 / w.sqrt());
                    }
                    let mut expected = DMatrix::zeros(2, 2);
                    expected.gemm_tr(1.0, &g, &g, 0.0);
                    assert_eq!(filter.effective_measurement_covariance(), &expected);
                    changed += 1;
                }
            }
            assert!(changed > 100, "{changed}");
        }
    }

    struct CosineRun {
        clean: Vec<f64>,
        measured: Vec<f64>,
    }

    /// docs/experiments.md §4: y_k = cos(2π·4k/1000) + N(0, 0.01), 50 outliers at distinct random indices
    /// adding U(−4.8, 4.8).
    fn cosine_with_outliers(seed: u64) -> CosineRun {
        let samples = 1000;
        let mut rng = TestRng::new(seed);
        let clean: Vec<f64> = (0..samples)
            .map(|k| (2.0 * std::f64::consts::PI * 4.0 * k as f64 / samples as f64).cos())
            .collect();
        let mut measured: Vec<f64> = clean.iter().map(|c| c + 0.1 * rng.normal()).collect();
        let mut chosen = vec![false; samples];
        let mut placed = 0;
        while placed < 50 {
            let index = rng.below(samples);
            if !chosen[index] {
                chosen[index] = true;
                measured[index] += -4.8 + 9.6 * rng.uniform();
                placed += 1;
            }
        }
        CosineRun { clean, measured }
    }

    fn residual_error(run: &CosineRun, mut step: impl FnMut(f64) -> f64) -> f64 {
        let mut sum = 0.0;
        for (clean, measured) in run.clean.iter().zip(&run.measured) {
            let estimate = step(*measured);
            sum += (clean - estimate) * (clean - estimate);
        }
        sum / run.clean.len() as f64
    }

    fn cosine_scores(psi: InfluenceFunction) -> (Vec<f64>, Vec<f64>) {
        let mut standard_scores = Vec::new();
        let mut robust_scores = Vec::new();
        let none = DVector::zeros(0);
        for seed in 0..100 {
            let run = cosine_with_outliers(1000 + seed);
            let mut standard = scalar_filter(1.0, 1e-4, 1e-4, 0.0);
            let mut robust = RobustKalmanFilter::random_walk(1, 1e-4, 1e-4, 0.0, psi).unwrap();
            standard_scores.push(residual_error(&run, |y| {
                standard.step(&none, &DVector::from_element(1, y)).unwrap();
                standard.output()[0]
            }));
            robust_scores.push(residual_error(&run, |y| {
                robust.step(&none, &DVector::from_element(1, y)).unwrap();
                robust.output()[0]
            }));
        }
        (standard_scores, robust_scores)
    }

    #[test]
    fn cosine_with_outliers_residual_error_over_100_seeds() {
        let (standard, robust) = cosine_scores(InfluenceFunction::huber());
        let (s_mean, s_std) = mean_std(&standard);
        let (r_mean, r_std) = mean_std(&robust);
        println!("E_res sKF  = {s_mean:.4} ± {s_std:.4} (reference 0.179 ± 0.023)");
        println!("E_res rsKF = {r_mean:.5} ± {r_std:.5} (reference 0.0121 ± 0.0006)");
        assert!((0.15..=0.21).contains(&s_mean), "sKF mean {s_mean}");
        assert!(r_mean <= 0.0124, "rsKF mean {r_mean}");
    }

    #[test]
    fn tukey_rejects_outliers_without_nan() {
        // A redescending ψ needs a sensible R (here the true noise variance 0.01) and start
        // (x̂₀ = y₀ = 1): with the experiment's R = 1e-4 every ordinary sample sits ~10σ
        // out and Tukey rejects it (E_res ≈ 0.5).
        let none = DVector::zeros(0);
        let (mut standard_scores, mut robust_scores) = (Vec::new(), Vec::new());
        for seed in 0..100 {
            let run = cosine_with_outliers(1000 + seed);
            let make = |psi| {
                RobustKalmanFilter::new(
                    GaussianModel {
                        system: StateSpace {
                            a: scalar(1.0),
                            b: DMatrix::zeros(1, 0),
                            c: scalar(1.0),
                            d: DMatrix::zeros(1, 0),
                            q: scalar(1e-3),
                            r: scalar(1e-2),
                        },
                        x0: DVector::from_element(1, 1.0),
                        p0: scalar(1e-2),
                    },
                    psi,
                )
                .unwrap()
            };
            // Huber with a huge c is the sKF.
            let mut standard = make(InfluenceFunction::Huber { c: 1e300 });
            let mut robust = make(InfluenceFunction::tukey());
            standard_scores.push(residual_error(&run, |y| {
                standard.step(&none, &DVector::from_element(1, y)).unwrap();
                standard.output()[0]
            }));
            robust_scores.push(residual_error(&run, |y| {
                robust.step(&none, &DVector::from_element(1, y)).unwrap();
                assert!(robust.weights()[0] >= MIN_WEIGHT);
                robust.output()[0]
            }));
        }
        let (s_mean, s_std) = mean_std(&standard_scores);
        let (r_mean, r_std) = mean_std(&robust_scores);
        println!("Q = 1e-3, R = 1e-2: sKF E_res = {s_mean:.4} ± {s_std:.4}, rsKF (Tukey) = {r_mean:.5} ± {r_std:.5}");
        assert!(robust_scores.iter().all(|v| v.is_finite()));
        assert!(r_mean < 0.2 * s_mean);
    }

    #[test]
    fn zero_weight_channel_gets_no_correction() {
        let mut robust =
            RobustKalmanFilter::random_walk(2, 1e-4, 1e-4, 1e-4, InfluenceFunction::tukey())
                .unwrap();
        let none = DVector::zeros(0);
        robust
            .step(&none, &DVector::from_vec(vec![0.001, 1e6]))
            .unwrap();
        assert!(robust.weights()[1] <= MIN_WEIGHT);
        assert!(robust.state()[1].abs() < 1e-3, "{}", robust.state());
        assert!(robust.state()[0] > 0.0);
        assert!(robust.covariance().iter().all(|v| v.is_finite()));
    }
}
