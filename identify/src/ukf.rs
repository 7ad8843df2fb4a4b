//! The robust unscented Kalman filter on an FMU (docs/estimators.md, "Identifying an FMU",
//! "Unscented filter").
//!
//! The state z = [x; θ_a], the settings, the robust correction and the trajectory are
//! [`crate::filter`]'s; this module is the unscented prediction.
//!
//! **Sigma points** (scaled unscented transform, Van der Merwe): L = n + q,
//! λ = α²(L + κ) − L, χ₀ = ẑ, χ_{±i} = ẑ ± √(L + λ) Sᵢ with S the lower Cholesky factor of
//! P (column i); weights W₀ᵐ = λ/(L+λ), W₀ᶜ = W₀ᵐ + 1 − α² + β, Wᵢ = 1/(2(L+λ)). With
//! the defaults α = 1, β = 2, κ = max(0, 3 − L) every covariance weight is ≥ 0, so the
//! predicted covariance is a sum of positive semidefinite terms plus Q.
//!
//! **Prediction** from t_{k−1} to t_k: each χ through the FMU ([`crate::plant::FmuPlant::propagate`]: its
//! states and θ set, the inputs u_{k−1} held, the master's ME integration with its events),
//! which gives χ⁻ and the measured variables 𝒴 at t_k; ẑ⁻ = Σ Wᵐ χ⁻,
//! P⁻ = Σ Wᶜ (χ⁻ − ẑ⁻)(χ⁻ − ẑ⁻)ᵀ + Q, ŷ = Σ Wᵐ 𝒴, S = Σ Wᶜ (𝒴 − ŷ)(𝒴 − ŷ)ᵀ + R,
//! C = Σ Wᶜ (χ⁻ − ẑ⁻)(𝒴 − ŷ)ᵀ. (The first sample only evaluates 𝒴 at the prior.)
//! A sigma point whose event indicators at t_{k−1} lie on the other side of zero than the
//! mean's has crossed an event surface the mean has not (a ball a little below the floor):
//! the event is handled at t_{k−1} before it is integrated ([`Start::reference`]),
//! so that every sigma point follows the model's hybrid dynamics.
//!
//! **Positive definiteness.** P is symmetrised, ½(P + Pᵀ), after every prediction and
//! correction, and the sigma points need only a square root S of it (S Sᵀ = P): its
//! Cholesky factor, or, when the factorisation fails (P semidefinite, or indefinite by
//! rounding), V √Λ₊ from the symmetric eigen-decomposition P = V Λ Vᵀ with the negative
//! eigenvalues set to zero (the nearest positive semidefinite matrix's root). A P that is
//! not finite, or an innovation covariance S̃ (which holds R > 0) whose Cholesky
//! factorisation fails, stops the step with an error naming the sample
//! ([`FilterError::NotPositive`]). P = 0 (a known state, no process noise) is no failure:
//! every sigma point is the mean, the gain is zero and the filter simulates the FMU (the
//! prediction errors are then the output errors of a simulation); a sigma point equal to the
//! mean is not integrated again (its image is the mean's).

use crate::plant::Start;
use crate::prediction::{symmetrise, FilterError, Prediction, Step};
use nalgebra::{Cholesky, DMatrix, DVector};

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

/// The weights of the scaled unscented transform of L filter states (module documentation).
#[derive(Debug, Clone, PartialEq)]
pub struct SigmaPoints {
    wm: Vec<f64>,
    wc: Vec<f64>,
    /// √(L + λ).
    gamma: f64,
}

impl SigmaPoints {
    /// The weights for L states, α, β and κ (None: max(0, 3 − L)).
    pub fn new(l: usize, alpha: f64, beta: f64, kappa: Option<f64>) -> Result<Self, FilterError> {
        let lf = l as f64;
        let kappa = kappa.unwrap_or((3.0 - lf).max(0.0));
        let lambda = alpha * alpha * (lf + kappa) - lf;
        if lf + lambda <= 0.0 || (lf + lambda).is_nan() {
            return Err(FilterError::Settings(format!(
                "L + λ = {} must be positive",
                lf + lambda
            )));
        }
        let wi = 1.0 / (2.0 * (lf + lambda));
        let mut wm = vec![wi; 2 * l + 1];
        let mut wc = wm.clone();
        wm[0] = lambda / (lf + lambda);
        wc[0] = wm[0] + 1.0 - alpha * alpha + beta;
        Ok(Self {
            wm,
            wc,
            gamma: (lf + lambda).sqrt(),
        })
    }

    /// The sigma points of (ẑ, P), one per column.
    fn points(&self, step: &Step) -> Result<DMatrix<f64>, FilterError> {
        let (z, l) = (step.z, step.z.len());
        let s = factor(step.p).ok_or(FilterError::NotPositive {
            what: "state covariance P",
            sample: step.sample,
            time: step.t1,
        })?;
        let mut chi = DMatrix::zeros(l, 2 * l + 1);
        chi.set_column(0, z);
        for i in 0..l {
            let d = s.column(i) * self.gamma;
            chi.set_column(1 + i, &(z + &d));
            chi.set_column(1 + l + i, &(z - &d));
        }
        Ok(chi)
    }

    /// Σ Wᵐ of the columns of `m`.
    fn mean(&self, m: &DMatrix<f64>) -> DVector<f64> {
        let mut mean = DVector::zeros(m.nrows());
        for (c, w) in self.wm.iter().enumerate() {
            mean += m.column(c) * *w;
        }
        mean
    }

    /// The unscented prediction over the step's interval (module documentation).
    pub(crate) fn predict(&self, step: &mut Step) -> Result<Prediction, FilterError> {
        let n = step.states;
        let l = step.z.len();
        let p_out = step.r.len();
        let chi = self.points(step)?;
        let count = chi.ncols();
        let mut propagated = DMatrix::zeros(l, count);
        let mut outputs = DMatrix::zeros(p_out, count);
        let mut theta = step.theta.to_vec();
        let mut x_out = vec![0.0; n];
        let mut y_out = vec![0.0; p_out];
        let mut reference: Option<Vec<f64>> = None;
        for c in 0..count {
            // A sigma point on the mean (a zero column of √P: P = 0 in that direction, as
            // in the likelihood's simulation) has the mean's image: not integrated again.
            if c > 0 && chi.column(c) == chi.column(0) {
                propagated.set_column(c, &propagated.column(0).clone_owned());
                outputs.set_column(c, &outputs.column(0).clone_owned());
                continue;
            }
            let point = chi.column(c);
            step.parameters_of(point.as_slice(), &mut theta);
            let start = Start {
                time: step.t0,
                states: &point.as_slice()[..n],
                parameters: &theta,
                inputs: step.u,
                reference: reference.as_deref(),
            };
            step.plant
                .propagate(&start, step.t1, &mut x_out, &mut y_out)?;
            if c == 0 {
                reference = Some(step.plant.placed_indicators());
            }
            propagated
                .column_mut(c)
                .rows_mut(0, n)
                .copy_from_slice(&x_out);
            for k in n..l {
                propagated[(k, c)] = chi[(k, c)];
            }
            outputs.column_mut(c).copy_from_slice(&y_out);
        }
        let z = self.mean(&propagated);
        let y = self.mean(&outputs);
        let mut p = DMatrix::zeros(l, l);
        let mut s = DMatrix::zeros(p_out, p_out);
        let mut cross = DMatrix::zeros(l, p_out);
        for (c, w) in self.wc.iter().enumerate() {
            let dz = propagated.column(c) - &z;
            let dy = outputs.column(c) - &y;
            p += &dz * dz.transpose() * *w;
            s += &dy * dy.transpose() * *w;
            cross += &dz * dy.transpose() * *w;
        }
        if let Some(q) = step.q {
            for i in 0..l {
                p[(i, i)] += q[i];
            }
        }
        symmetrise(&mut p);
        for (j, r) in step.r.iter().enumerate() {
            s[(j, j)] += r;
        }
        Ok(Prediction {
            z,
            p,
            y,
            s,
            cross,
            jacobian: None,
        })
    }
}
