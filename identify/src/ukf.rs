//! The robust unscented Kalman filter on an FMU (docs/estimators.md, "Unscented Kalman
//! filter on an FMU").
//!
//! **State.** z = [x; θ_a]: the FMU's continuous states x (n) and the parameters estimated
//! online θ_a (q, possibly none), each a random walk θ_{k+1} = θ_k + w_k, w_k ~ N(0, Q_θ)
//! (joint estimation). Parameters not in z are held at given values.
//!
//! **Sigma points** (scaled unscented transform, Van der Merwe): L = n + q,
//! λ = α²(L + κ) − L, χ₀ = ẑ, χ_{±i} = ẑ ± √(L + λ) Sᵢ with S the lower Cholesky factor of
//! P (column i); weights W₀ᵐ = λ/(L+λ), W₀ᶜ = W₀ᵐ + 1 − α² + β, Wᵢ = 1/(2(L+λ)). With
//! the defaults α = 1, β = 2, κ = max(0, 3 − L) every covariance weight is ≥ 0, so the
//! predicted covariance is a sum of positive semidefinite terms plus Q.
//!
//! **Prediction** from t_{k−1} to t_k: each χ through the FMU ([`FmuPlant::propagate`]: its
//! states and θ set, the inputs u_{k−1} held, the master's ME integration with its events),
//! which gives χ⁻ and the measured variables 𝒴 at t_k; ẑ⁻ = Σ Wᵐ χ⁻,
//! P⁻ = Σ Wᶜ (χ⁻ − ẑ⁻)(χ⁻ − ẑ⁻)ᵀ + Q, ŷ = Σ Wᵐ 𝒴, S = Σ Wᶜ (𝒴 − ŷ)(𝒴 − ŷ)ᵀ + R,
//! C = Σ Wᶜ (χ⁻ − ẑ⁻)(𝒴 − ŷ)ᵀ. (The first sample only evaluates 𝒴 at the prior.)
//! A sigma point whose event indicators at t_{k−1} lie on the other side of zero than the
//! mean's has crossed an event surface the mean has not (a ball a little below the floor):
//! the event is handled at t_{k−1} before it is integrated ([`Start::reference`]),
//! so that every sigma point follows the model's hybrid dynamics.
//!
//! **Robust correction** (the papers' rsKF, as `spurio`'s robust Kalman filter): over the
//! present channels (a NaN is a missing sample, left out; none present: no correction) the
//! innovation e = y − ŷ is standardised by its covariance, rⱼ = eⱼ/√Sⱼⱼ, weighted
//! wⱼ = ψ(rⱼ)/rⱼ (Huber or Tukey, clamped to [`MIN_WEIGHT`]) and the measurement variance
//! inflated, R̃ⱼⱼ = Rⱼⱼ / wⱼ: S̃ = S + R̃ − R, K = C S̃⁻¹, ẑ = ẑ⁻ + K e, P = P⁻ − K S̃ Kᵀ.
//!
//! **Positive definiteness.** P is symmetrised, ½(P + Pᵀ), after every prediction and
//! correction, and the sigma points need only a square root S of it (S Sᵀ = P): its
//! Cholesky factor, or, when the factorisation fails (P semidefinite, or indefinite by
//! rounding), V √Λ₊ from the symmetric eigen-decomposition P = V Λ Vᵀ with the negative
//! eigenvalues set to zero (the nearest positive semidefinite matrix's root). A P that is
//! not finite, or an innovation covariance S̃ (which holds R > 0) whose Cholesky
//! factorisation fails, stops the step with an error naming the sample
//! ([`UkfError::NotPositive`]). P = 0 (a known state, no process noise) is no failure:
//! every sigma point is the mean, the gain is zero and the filter simulates the FMU (the
//! prediction errors are then the output errors of a simulation).

use crate::plant::{FmuPlant, PlantError, Start};
use nalgebra::{Cholesky, DMatrix, DVector};
use spurio::estimation::{InfluenceFunction, MIN_WEIGHT};
use std::cell::RefCell;
use std::rc::Rc;

/// Why a filter step failed.
#[derive(Debug, thiserror::Error)]
pub enum UkfError {
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
    #[error("the filter's settings: {0}")]
    Settings(String),
}

/// The filter's tuning (module documentation).
#[derive(Debug, Clone, PartialEq)]
pub struct UkfSettings {
    /// Q_x: the variance added to each state per sample.
    pub state_noise: Vec<f64>,
    /// Q_θ: the random-walk variance of each parameter of z per sample.
    pub parameter_noise: Vec<f64>,
    /// R: the variance of each measured variable.
    pub measurement_variance: Vec<f64>,
    /// The robust weights (None: the plain UKF).
    pub robust: Option<InfluenceFunction>,
    pub alpha: f64,
    pub beta: f64,
    /// κ; None: max(0, 3 − L).
    pub kappa: Option<f64>,
}

/// What one sample gave.
#[derive(Debug, Clone, PartialEq)]
pub struct UkfSample {
    pub time: f64,
    /// ẑ after the correction: [x̂; θ̂_a].
    pub estimate: Vec<f64>,
    /// √diag P after the correction.
    pub standard_deviation: Vec<f64>,
    /// e = y − ŷ per measured variable (NaN where missing).
    pub innovation: Vec<f64>,
    /// √Sⱼⱼ, the innovation's standard deviation (before the robust inflation).
    pub innovation_sd: Vec<f64>,
    /// The robust weight wⱼ (1 without robust weighting, NaN where missing).
    pub weight: Vec<f64>,
}

/// The unscented Kalman filter on an FMU (module documentation).
#[derive(Debug)]
pub struct Ukf {
    plant: Rc<RefCell<FmuPlant>>,
    n: usize,
    /// Indices (into the plant's free parameters) of the parameters in z.
    augmented: Vec<usize>,
    /// Every free parameter's value (those in z overwritten from ẑ for each sigma point).
    theta: Vec<f64>,
    z: DVector<f64>,
    p: DMatrix<f64>,
    q: DVector<f64>,
    r: DVector<f64>,
    robust: Option<InfluenceFunction>,
    wm: Vec<f64>,
    wc: Vec<f64>,
    gamma: f64,
    /// Time and inputs of the last sample (None before the first).
    last: Option<(f64, Vec<f64>)>,
    sample: usize,
}

/// ½(P + Pᵀ).
fn symmetrise(p: &mut DMatrix<f64>) {
    let t = p.transpose();
    *p += t;
    *p *= 0.5;
}

/// A square root S of `p` (S Sᵀ = P, module documentation): the lower Cholesky factor, or,
/// when P is only semidefinite in floating point, V √Λ₊ from its symmetric eigen-decomposition
/// with negative eigenvalues set to zero; None when P is not finite.
fn factor(p: &DMatrix<f64>) -> Option<DMatrix<f64>> {
    if !p.iter().all(|v| v.is_finite()) {
        return None;
    }
    if let Some(c) = Cholesky::new(p.clone()) {
        return Some(c.l());
    }
    let eigen = p.clone().symmetric_eigen();
    let roots = eigen.eigenvalues.map(|l| l.max(0.0).sqrt());
    Some(&eigen.eigenvectors * DMatrix::from_diagonal(&roots))
}

impl Ukf {
    /// A filter on `plant` with every free parameter at `theta`, those of `augmented` (indices
    /// into θ) estimated in z, started at ẑ₀ = [x0; θ_a], P₀ = `p0` ((n+q)×(n+q)).
    pub fn new(
        plant: Rc<RefCell<FmuPlant>>,
        theta: &[f64],
        augmented: &[usize],
        x0: &[f64],
        p0: DMatrix<f64>,
        settings: &UkfSettings,
    ) -> Result<Self, UkfError> {
        let (n, free, outputs) = {
            let pl = plant.borrow();
            (pl.states(), pl.parameters().len(), pl.output_names().len())
        };
        let l = n + augmented.len();
        let bad = |s: String| Err(UkfError::Settings(s));
        if theta.len() != free || x0.len() != n || p0.shape() != (l, l) {
            return bad(format!(
                "{} parameters, {} states and a {}×{} P₀ given; the model has {free} parameters, {n} states and {l} filter states",
                theta.len(),
                x0.len(),
                p0.nrows(),
                p0.ncols()
            ));
        }
        if augmented.iter().any(|&i| i >= free) {
            return bad("an estimated parameter's index is out of range".into());
        }
        if settings.state_noise.len() != n
            || settings.parameter_noise.len() != augmented.len()
            || settings.measurement_variance.len() != outputs
        {
            return bad(format!(
                "{} state noises, {} parameter noises and {} measurement variances given; {n}, {} and {outputs} needed",
                settings.state_noise.len(),
                settings.parameter_noise.len(),
                settings.measurement_variance.len(),
                augmented.len()
            ));
        }
        let nonnegative = settings
            .state_noise
            .iter()
            .chain(&settings.parameter_noise)
            .all(|v| v.is_finite() && *v >= 0.0);
        if !nonnegative
            || !settings
                .measurement_variance
                .iter()
                .all(|v| v.is_finite() && *v > 0.0)
        {
            return bad("the noise variances must be finite, ≥ 0 (Q) and > 0 (R)".into());
        }
        let lf = l as f64;
        let kappa = settings.kappa.unwrap_or((3.0 - lf).max(0.0));
        let (alpha, beta) = (settings.alpha, settings.beta);
        let lambda = alpha * alpha * (lf + kappa) - lf;
        if lf + lambda <= 0.0 || (lf + lambda).is_nan() {
            return bad(format!("L + λ = {} must be positive", lf + lambda));
        }
        let wi = 1.0 / (2.0 * (lf + lambda));
        let w0m = lambda / (lf + lambda);
        let mut wm = vec![wi; 2 * l + 1];
        let mut wc = wm.clone();
        wm[0] = w0m;
        wc[0] = w0m + 1.0 - alpha * alpha + beta;
        let mut z = DVector::zeros(l);
        z.rows_mut(0, n).copy_from_slice(x0);
        for (k, &i) in augmented.iter().enumerate() {
            z[n + k] = theta[i];
        }
        let mut q = DVector::zeros(l);
        q.rows_mut(0, n).copy_from_slice(&settings.state_noise);
        q.rows_mut(n, augmented.len())
            .copy_from_slice(&settings.parameter_noise);
        Ok(Self {
            plant,
            n,
            augmented: augmented.to_vec(),
            theta: theta.to_vec(),
            z,
            p: p0,
            q,
            r: DVector::from_column_slice(&settings.measurement_variance),
            robust: settings.robust,
            wm,
            wc,
            gamma: (lf + lambda).sqrt(),
            last: None,
            sample: 0,
        })
    }

    /// ẑ now.
    pub fn estimate(&self) -> &DVector<f64> {
        &self.z
    }

    /// P now.
    pub fn covariance(&self) -> &DMatrix<f64> {
        &self.p
    }

    /// The sigma points of (ẑ, P), one per column.
    fn sigma_points(&self, time: f64) -> Result<DMatrix<f64>, UkfError> {
        let l = self.z.len();
        let s = factor(&self.p).ok_or(UkfError::NotPositive {
            what: "state covariance P",
            sample: self.sample,
            time,
        })?;
        let mut chi = DMatrix::zeros(l, 2 * l + 1);
        chi.set_column(0, &self.z);
        for i in 0..l {
            let d = s.column(i) * self.gamma;
            chi.set_column(1 + i, &(&self.z + &d));
            chi.set_column(1 + l + i, &(&self.z - &d));
        }
        Ok(chi)
    }

    /// Processes the sample at `time` with inputs `u` and measurements `y` (NaN: missing):
    /// prediction from the last sample, robust correction (module documentation). Also
    /// gives the prediction error of the present channels and its covariance S (without the
    /// robust inflation), for the likelihood.
    pub fn step(
        &mut self,
        time: f64,
        u: &[f64],
        y: &[f64],
    ) -> Result<(UkfSample, DVector<f64>, DMatrix<f64>), UkfError> {
        let (n, l) = (self.n, self.z.len());
        let p_out = self.r.len();
        if y.len() != p_out {
            return Err(UkfError::Settings(format!(
                "{} measurements given at sample {}, the filter has {p_out}",
                y.len(),
                self.sample
            )));
        }
        let (t0, u_held) = match &self.last {
            Some((t0, u0)) => (*t0, u0.clone()),
            None => (time, u.to_vec()),
        };
        let chi = self.sigma_points(time)?;
        let count = chi.ncols();
        let mut propagated = DMatrix::zeros(l, count);
        let mut outputs = DMatrix::zeros(p_out, count);
        let mut theta = self.theta.clone();
        let mut x_out = vec![0.0; n];
        let mut y_out = vec![0.0; p_out];
        {
            let mut plant = self.plant.borrow_mut();
            let mut reference: Option<Vec<f64>> = None;
            for c in 0..count {
                for (k, &i) in self.augmented.iter().enumerate() {
                    theta[i] = chi[(n + k, c)];
                }
                let x: Vec<f64> = chi.column(c).rows(0, n).iter().copied().collect();
                let start = Start {
                    time: t0,
                    states: &x,
                    parameters: &theta,
                    inputs: &u_held,
                    reference: reference.as_deref(),
                };
                plant.propagate(&start, time, &mut x_out, &mut y_out)?;
                if c == 0 {
                    reference = Some(plant.placed_indicators());
                }
                propagated
                    .column_mut(c)
                    .rows_mut(0, n)
                    .copy_from_slice(&x_out);
                for k in 0..self.augmented.len() {
                    propagated[(n + k, c)] = chi[(n + k, c)];
                }
                outputs.column_mut(c).copy_from_slice(&y_out);
            }
        }
        let weighted_mean = |m: &DMatrix<f64>| {
            let mut mean = DVector::zeros(m.nrows());
            for c in 0..count {
                mean += m.column(c) * self.wm[c];
            }
            mean
        };
        let z_prior = weighted_mean(&propagated);
        let y_hat = weighted_mean(&outputs);
        let mut p_prior = DMatrix::zeros(l, l);
        let mut s_full = DMatrix::zeros(p_out, p_out);
        let mut cross = DMatrix::zeros(l, p_out);
        for c in 0..count {
            let dz = propagated.column(c) - &z_prior;
            let dy = outputs.column(c) - &y_hat;
            p_prior += &dz * dz.transpose() * self.wc[c];
            s_full += &dy * dy.transpose() * self.wc[c];
            cross += &dz * dy.transpose() * self.wc[c];
        }
        if self.last.is_some() {
            for i in 0..l {
                p_prior[(i, i)] += self.q[i];
            }
        }
        symmetrise(&mut p_prior);
        for j in 0..p_out {
            s_full[(j, j)] += self.r[j];
        }
        let present: Vec<usize> = (0..p_out).filter(|&j| !y[j].is_nan()).collect();
        let mut innovation = vec![f64::NAN; p_out];
        let mut weight = vec![f64::NAN; p_out];
        let innovation_sd: Vec<f64> = (0..p_out).map(|j| s_full[(j, j)].sqrt()).collect();
        let k_present = present.len();
        let mut v = DVector::zeros(k_present);
        let mut f = DMatrix::zeros(k_present, k_present);
        if k_present == 0 {
            self.z = z_prior;
            self.p = p_prior;
        } else {
            let mut inflated = DMatrix::zeros(k_present, k_present);
            let mut c_present = DMatrix::zeros(l, k_present);
            for (a, &ja) in present.iter().enumerate() {
                v[a] = y[ja] - y_hat[ja];
                innovation[ja] = v[a];
                for (b, &jb) in present.iter().enumerate() {
                    f[(a, b)] = s_full[(ja, jb)];
                }
                c_present.set_column(a, &cross.column(ja));
            }
            inflated.copy_from(&f);
            for (a, &ja) in present.iter().enumerate() {
                let w = match self.robust {
                    Some(psi) => psi.weight(v[a] / f[(a, a)].sqrt()).max(MIN_WEIGHT),
                    None => 1.0,
                };
                weight[ja] = w;
                if w < 1.0 {
                    inflated[(a, a)] += self.r[ja] * (1.0 / w - 1.0);
                }
            }
            let chol = Cholesky::new(inflated.clone()).ok_or(UkfError::NotPositive {
                what: "innovation covariance S",
                sample: self.sample,
                time,
            })?;
            // K = C S̃⁻¹ = (S̃⁻¹ Cᵀ)ᵀ (S̃ symmetric).
            let gain = chol.solve(&c_present.transpose()).transpose();
            self.z = &z_prior + &gain * &v;
            self.p = &p_prior - &gain * &inflated * gain.transpose();
            symmetrise(&mut self.p);
        }
        if let Some(i) = self.z.iter().position(|v| !v.is_finite()) {
            return Err(UkfError::Settings(format!(
                "the estimate of filter state {i} is not finite at sample {} (t = {time})",
                self.sample
            )));
        }
        for (k, &i) in self.augmented.iter().enumerate() {
            self.theta[i] = self.z[n + k];
        }
        self.last = Some((time, u.to_vec()));
        self.sample += 1;
        let sample = UkfSample {
            time,
            estimate: self.z.iter().copied().collect(),
            standard_deviation: self
                .p
                .diagonal()
                .iter()
                .map(|v| v.max(0.0).sqrt())
                .collect(),
            innovation,
            innovation_sd,
            weight,
        };
        Ok((sample, v, f))
    }
}
