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
use crate::prediction::{symmetrise, FilterError, Prediction, Sizes, Step};
use nalgebra::{Cholesky, DMatrix, DVector};

/// A square root S of `p` (S Sᵀ = P, module documentation) into `root`: the lower Cholesky
/// factor (in `root`'s storage, nothing allocated), or, when P is only semidefinite in
/// floating point, V √Λ₊ from its symmetric eigen-decomposition with negative eigenvalues set
/// to zero (allocated: that rare case's price); false when P is not finite.
fn factor(p: &DMatrix<f64>, root: &mut DMatrix<f64>) -> bool {
    if !p.iter().all(|v| v.is_finite()) {
        return false;
    }
    let mut storage = std::mem::take(root);
    storage.copy_from(p);
    match Cholesky::new(storage) {
        Some(c) => *root = c.unpack(),
        None => {
            let eigen = p.clone().symmetric_eigen();
            let roots = eigen.eigenvalues.map(|l| l.max(0.0).sqrt());
            *root = &eigen.eigenvectors * DMatrix::from_diagonal(&roots);
        }
    }
    true
}

/// The unscented prediction's work buffers, made once for the filter's dimensions.
#[derive(Debug, Clone)]
pub(crate) struct UnscentedWork {
    /// √P (L × L).
    root: DMatrix<f64>,
    /// The sigma points χ, their images χ⁻ (L × (2L + 1)) and measured variables 𝒴
    /// (p × (2L + 1)).
    chi: DMatrix<f64>,
    propagated: DMatrix<f64>,
    outputs: DMatrix<f64>,
    /// θ of a sigma point, x(t₁) and y(t₁) of a propagation.
    theta: Vec<f64>,
    x_out: Vec<f64>,
    y_out: Vec<f64>,
    /// The mean's event indicators at t₀ (the sigma points' reference).
    reference: Vec<f64>,
    /// χ⁻ − ẑ⁻ and 𝒴 − ŷ of one sigma point.
    dz: DVector<f64>,
    dy: DVector<f64>,
}

impl UnscentedWork {
    pub fn new(sizes: &Sizes) -> Self {
        let (n, l, p) = (sizes.states, sizes.filter_states, sizes.measured);
        Self {
            root: DMatrix::zeros(l, l),
            chi: DMatrix::zeros(l, 2 * l + 1),
            propagated: DMatrix::zeros(l, 2 * l + 1),
            outputs: DMatrix::zeros(p, 2 * l + 1),
            theta: vec![0.0; sizes.parameters],
            x_out: vec![0.0; n],
            y_out: vec![0.0; p],
            reference: Vec::with_capacity(sizes.indicators),
            dz: DVector::zeros(l),
            dy: DVector::zeros(p),
        }
    }
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

    /// The sigma points of (ẑ, P), one per column, into `work.chi`.
    fn points(&self, step: &Step, work: &mut UnscentedWork) -> Result<(), FilterError> {
        let (z, l) = (step.z, step.z.len());
        if !factor(step.p, &mut work.root) {
            return Err(FilterError::NotPositive {
                what: "state covariance P",
                sample: step.sample,
                time: step.t1,
            });
        }
        let (s, chi) = (&work.root, &mut work.chi);
        chi.set_column(0, z);
        for i in 0..l {
            for r in 0..l {
                let d = s[(r, i)] * self.gamma;
                chi[(r, 1 + i)] = z[r] + d;
                chi[(r, 1 + l + i)] = z[r] - d;
            }
        }
        Ok(())
    }

    /// Σ Wᵐ of the columns of `m`, into `mean`.
    fn mean(&self, m: &DMatrix<f64>, mean: &mut DVector<f64>) {
        mean.fill(0.0);
        for (c, w) in self.wm.iter().enumerate() {
            for r in 0..m.nrows() {
                mean[r] += m[(r, c)] * *w;
            }
        }
    }

    /// The unscented prediction over the step's interval (module documentation), into
    /// `out`.
    pub(crate) fn predict(
        &self,
        step: &mut Step,
        work: &mut UnscentedWork,
        out: &mut Prediction,
    ) -> Result<(), FilterError> {
        let n = step.states;
        let l = step.z.len();
        self.points(step, work)?;
        let UnscentedWork {
            chi,
            propagated,
            outputs,
            theta,
            x_out,
            y_out,
            reference,
            dz,
            dy,
            ..
        } = work;
        let count = chi.ncols();
        for c in 0..count {
            // A sigma point on the mean (a zero column of √P: P = 0 in that direction, as
            // in the likelihood's simulation) has the mean's image: not integrated again.
            if c > 0 && chi.column(c) == chi.column(0) {
                for r in 0..l {
                    propagated[(r, c)] = propagated[(r, 0)];
                }
                for r in 0..outputs.nrows() {
                    outputs[(r, c)] = outputs[(r, 0)];
                }
                continue;
            }
            let point = chi.column(c);
            step.parameters_of(point.as_slice(), theta);
            let start = Start {
                time: step.t0,
                states: &point.as_slice()[..n],
                parameters: theta,
                inputs: step.u,
                reference: (c > 0).then_some(&reference[..]),
            };
            step.plant.propagate(&start, step.t1, x_out, y_out)?;
            if c == 0 {
                reference.clear();
                reference.extend_from_slice(step.plant.event_indicators());
            }
            propagated
                .column_mut(c)
                .rows_mut(0, n)
                .copy_from_slice(x_out);
            for k in n..l {
                propagated[(k, c)] = chi[(k, c)];
            }
            outputs.column_mut(c).copy_from_slice(y_out);
        }
        let Prediction {
            z, p, y, s, cross, ..
        } = out;
        self.mean(propagated, z);
        self.mean(outputs, y);
        p.fill(0.0);
        s.fill(0.0);
        cross.fill(0.0);
        for (c, w) in self.wc.iter().enumerate() {
            for r in 0..l {
                dz[r] = propagated[(r, c)] - z[r];
            }
            for r in 0..dy.len() {
                dy[r] = outputs[(r, c)] - y[r];
            }
            // Each term as (d dᵀ) · w, added.
            for j in 0..l {
                for i in 0..l {
                    p[(i, j)] += dz[i] * dz[j] * *w;
                }
            }
            for j in 0..dy.len() {
                for i in 0..dy.len() {
                    s[(i, j)] += dy[i] * dy[j] * *w;
                }
                for i in 0..l {
                    cross[(i, j)] += dz[i] * dy[j] * *w;
                }
            }
        }
        if let Some(q) = step.q {
            for i in 0..l {
                p[(i, i)] += q[i];
            }
        }
        symmetrise(p);
        for (j, r) in step.r.iter().enumerate() {
            s[(j, j)] += r;
        }
        Ok(())
    }
}
