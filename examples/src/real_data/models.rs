//! The models the hair-dryer record is scored with, and the score: ARX models (batch least
//! squares, one-step prediction, free-run simulation), a state-space model in innovation form
//! (SLICOT's subspace estimate), and the fit 100·(1 − ‖y − ŷ‖/‖y − ȳ‖) (Ljung, *System
//! Identification*, 2nd ed., §16.6: the normalised root-mean-square fit MATLAB's `compare`
//! reports).

use crate::runner::median;
use anyhow::{anyhow, Result};
use nalgebra::{DMatrix, DVector};

/// The fit of `estimate` to `measured` in percent: 100·(1 − ‖y − ŷ‖/‖y − ȳ‖).
pub fn fit_percent(measured: &[f64], estimate: &[f64]) -> f64 {
    let mean = measured.iter().sum::<f64>() / measured.len() as f64;
    let error: f64 = measured
        .iter()
        .zip(estimate)
        .map(|(y, e)| (y - e).powi(2))
        .sum();
    let spread: f64 = measured.iter().map(|y| (y - mean).powi(2)).sum();
    100.0 * (1.0 - (error / spread).sqrt())
}

/// An ARX(na, nb, nk) model
/// y(k) = −a₁y(k−1) − … − a_na·y(k−na) + b₁u(k−nk) + … + b_nb·u(k−nk−nb+1) + e(k).
#[derive(Debug, Clone, PartialEq)]
pub struct Arx {
    /// a₁ … a_na.
    pub a: Vec<f64>,
    /// b₁ … b_nb.
    pub b: Vec<f64>,
    /// The input delay nk ≥ 1 in samples.
    pub delay: usize,
}

/// `v[k − lag]`, 0 before the start (zero initial conditions).
fn past(v: &[f64], k: usize, lag: usize) -> f64 {
    if k >= lag {
        v[k - lag]
    } else {
        0.0
    }
}

impl Arx {
    /// Its name, `ARX(2, 2, 3)`.
    pub fn order(&self) -> String {
        format!("ARX({}, {}, {})", self.a.len(), self.b.len(), self.delay)
    }

    /// The right-hand side at sample `k` from the outputs `y` and inputs `u` (zero before 0).
    fn regress(&self, y: &[f64], u: &[f64], k: usize) -> f64 {
        let ar: f64 = (1..=self.a.len())
            .map(|i| -self.a[i - 1] * past(y, k, i))
            .sum();
        let x: f64 = (0..self.b.len())
            .map(|j| self.b[j] * past(u, k, self.delay + j))
            .sum();
        ar + x
    }

    /// The batch least-squares ARX(na, nb, nk) of the record (`u`, `y`), over the samples whose
    /// regressors lie inside it (k ≥ max(na, nb + nk − 1)) and whose outputs y(k − na … k) are
    /// all `present` (an equation touching a missing sample is dropped): the normal equations
    /// ΦᵀΦ θ = Φᵀy solved by Cholesky (`spurio::linalg::cholesky_solve`).
    pub fn least_squares(
        u: &[f64],
        y: &[f64],
        present: &[bool],
        order: (usize, usize, usize),
    ) -> Result<Self> {
        Self::weighted_least_squares(u, y, present, order, |_| 1.0)
    }

    /// As [`Arx::least_squares`], equation k weighted by `weight(k)` ≥ 0: ΦᵀWΦ θ = ΦᵀWy.
    fn weighted_least_squares(
        u: &[f64],
        y: &[f64],
        present: &[bool],
        (na, nb, delay): (usize, usize, usize),
        weight: impl Fn(usize) -> f64,
    ) -> Result<Self> {
        let equations = Self::equations(y, present, (na, nb, delay));
        let rows = equations.len();
        let dim = na + nb;
        if rows <= dim || u.len() != y.len() {
            return Err(anyhow!(
                "ARX({na}, {nb}, {delay}): {rows} usable samples of {} are too few",
                y.len()
            ));
        }
        let root: Vec<f64> = equations.iter().map(|&k| weight(k).sqrt()).collect();
        let phi = DMatrix::from_fn(rows, dim, |r, c| {
            let k = equations[r];
            root[r]
                * if c < na {
                    -y[k - 1 - c]
                } else {
                    u[k - delay - (c - na)]
                }
        });
        let target =
            DVector::from_iterator(rows, equations.iter().zip(&root).map(|(&k, w)| w * y[k]));
        let normal = phi.transpose() * &phi;
        let rhs = DMatrix::from_column_slice(dim, 1, (phi.transpose() * target).as_slice());
        let theta = spurio::linalg::cholesky_solve(&normal, &rhs, "ΦᵀΦ of the ARX regressors")?;
        Ok(Self {
            a: theta.as_slice()[..na].to_vec(),
            b: theta.as_slice()[na..].to_vec(),
            delay,
        })
    }

    /// The samples k whose ARX equation lies inside the record and touches no missing output.
    fn equations(
        y: &[f64],
        present: &[bool],
        (na, nb, delay): (usize, usize, usize),
    ) -> Vec<usize> {
        let first = na.max(nb + delay - 1);
        (first..y.len().min(present.len()))
            .filter(|&k| present[k - na..=k].iter().all(|p| *p))
            .collect()
    }

    /// The robust (M-estimate) ARX of the record: iteratively reweighted least squares with
    /// Tukey's bisquare on the residuals standardised by their robust scale
    /// σ̂ = 1.4826·MAD (c = 4.685, 95 % efficiency under Gaussian errors; Maronna, Martin &
    /// Yohai, *Robust Statistics*, §4.4), from the least-squares start, `iterations` passes.
    /// Gives the model and σ̂ of its final residuals: the one-step prediction error of the
    /// model on the record with its outliers discounted.
    pub fn robust(
        u: &[f64],
        y: &[f64],
        present: &[bool],
        order: (usize, usize, usize),
        iterations: usize,
    ) -> Result<(Self, f64)> {
        const TUKEY_C: f64 = 4.685;
        let equations = Self::equations(y, present, order);
        let mut model = Self::least_squares(u, y, present, order)?;
        let mut weights = vec![1.0; y.len()];
        let mut scale = model.residual_scale(u, y, &equations);
        for _ in 0..iterations {
            if scale.is_nan() || scale <= 0.0 {
                break;
            }
            for &k in &equations {
                let z = (y[k] - model.regress(y, u, k)) / (TUKEY_C * scale);
                weights[k] = if z.abs() < 1.0 {
                    (1.0 - z * z).powi(2)
                } else {
                    0.0
                };
            }
            model = Self::weighted_least_squares(u, y, present, order, |k| weights[k])?;
            scale = model.residual_scale(u, y, &equations);
        }
        Ok((model, scale))
    }

    /// 1.4826·MAD of the residuals y(k) − ŷ(k) over `equations` (the normal-consistent robust
    /// scale).
    fn residual_scale(&self, u: &[f64], y: &[f64], equations: &[usize]) -> f64 {
        let residuals: Vec<f64> = equations
            .iter()
            .map(|&k| y[k] - self.regress(y, u, k))
            .collect();
        let centre = median(&residuals);
        let deviations: Vec<f64> = residuals.iter().map(|r| (r - centre).abs()).collect();
        1.4826 * median(&deviations)
    }

    /// One-step-ahead predictions ŷ(k|k−1) of the record (`u`, `y`), zero before its start.
    pub fn predict(&self, u: &[f64], y: &[f64]) -> Vec<f64> {
        (0..y.len()).map(|k| self.regress(y, u, k)).collect()
    }

    /// The free-run simulation from `u` alone, zero initial conditions.
    pub fn simulate(&self, u: &[f64]) -> Vec<f64> {
        let mut y = vec![0.0; u.len()];
        for k in 0..u.len() {
            y[k] = self.regress(&y, u, k);
        }
        y
    }
}

/// A single-input single-output state-space model in innovation form:
/// x(k+1) = A x(k) + B u(k) + K e(k), y(k) = C x(k) + D u(k) + e(k).
#[derive(Debug, Clone, PartialEq)]
pub struct InnovationModel {
    /// A (n×n).
    pub a: DMatrix<f64>,
    /// B (n×1).
    pub b: DVector<f64>,
    /// C (1×n), as a column.
    pub c: DVector<f64>,
    /// D.
    pub d: f64,
    /// The Kalman gain K (n×1).
    pub k: DVector<f64>,
}

impl InnovationModel {
    /// One-step-ahead predictions: the steady Kalman predictor x̂(k+1) = A x̂ + B u + K (y − ŷ),
    /// ŷ(k) = C x̂(k) + D u(k), from x̂(0) = 0.
    pub fn predict(&self, u: &[f64], y: &[f64]) -> Vec<f64> {
        self.run(u, Some(y))
    }

    /// The free-run simulation (K unused) from x(0) = 0.
    pub fn simulate(&self, u: &[f64]) -> Vec<f64> {
        self.run(u, None)
    }

    fn run(&self, u: &[f64], y: Option<&[f64]>) -> Vec<f64> {
        let mut x = DVector::zeros(self.a.nrows());
        let mut out = Vec::with_capacity(u.len());
        for (k, &uk) in u.iter().enumerate() {
            let estimate = self.c.dot(&x) + self.d * uk;
            out.push(estimate);
            let mut next = &self.a * &x + &self.b * uk;
            if let Some(y) = y {
                next += &self.k * (y[k] - estimate);
            }
            x = next;
        }
        out
    }

    /// The static gain C (I − A)⁻¹ B + D.
    pub fn dc_gain(&self) -> Result<f64> {
        let n = self.a.nrows();
        let steady = (DMatrix::identity(n, n) - &self.a)
            .lu()
            .solve(&self.b)
            .ok_or_else(|| anyhow!("I − A is singular"))?;
        Ok(self.c.dot(&steady) + self.d)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn least_squares_recovers_a_noise_free_arx() {
        let truth = Arx {
            a: vec![-1.2, 0.4],
            b: vec![0.07, 0.04],
            delay: 3,
        };
        // A deterministic, persistently exciting input.
        let u: Vec<f64> = (0..300)
            .map(|k| ((k * 7919) % 13) as f64 / 13.0 - 0.5)
            .collect();
        let y = truth.simulate(&u);
        let found = Arx::least_squares(&u, &y, &[true; 300], (2, 2, 3)).unwrap();
        for (f, t) in found
            .a
            .iter()
            .chain(&found.b)
            .zip(truth.a.iter().chain(&truth.b))
        {
            assert!((f - t).abs() < 1e-9, "{found:?}");
        }
        assert!((fit_percent(&y, &found.simulate(&u)) - 100.0).abs() < 1e-6);
        assert!((fit_percent(&y, &found.predict(&u, &y)) - 100.0).abs() < 1e-6);
    }

    /// The Tukey M-estimate ignores gross outliers that spoil least squares: a first-order
    /// ARX with small deterministic "noise" (robust scale ≈ its size) and every 17th output
    /// moved by ±2.
    #[test]
    fn the_robust_fit_ignores_outliers_and_gives_the_noise_scale() {
        let (a, b) = (0.9, 0.12);
        let u: Vec<f64> = (0..500)
            .map(|k| if (k / 9) % 2 == 0 { 1.0 } else { -1.0 })
            .collect();
        let mut y = vec![0.0; 500];
        for k in 3..500 {
            let noise = 0.01 * (((k * 7919) % 13) as f64 / 6.0 - 1.0);
            y[k] = a * y[k - 1] + b * u[k - 3] + noise;
        }
        let mut measured = y.clone();
        for k in (10..500).step_by(17) {
            measured[k] += if k % 2 == 0 { 2.0 } else { -2.0 };
        }
        let present = vec![true; 500];
        let plain = Arx::least_squares(&u, &measured, &present, (1, 1, 3)).unwrap();
        let (robust, scale) = Arx::robust(&u, &measured, &present, (1, 1, 3), 20).unwrap();
        println!("least squares {plain:?}, robust {robust:?}, σ̂ = {scale}");
        assert!((plain.a[0] + a).abs() > 0.05, "{plain:?}");
        assert!((robust.a[0] + a).abs() < 2e-3, "{robust:?}");
        assert!((robust.b[0] - b).abs() < 2e-3, "{robust:?}");
        assert!(scale > 0.003 && scale < 0.012, "σ̂ = {scale}");
    }

    #[test]
    fn the_fit_of_the_mean_is_zero_and_of_the_record_a_hundred() {
        let y = [1.0, 3.0, 2.0, 6.0];
        assert!((fit_percent(&y, &[3.0; 4])).abs() < 1e-12);
        assert!((fit_percent(&y, &y) - 100.0).abs() < 1e-12);
    }

    #[test]
    fn an_innovation_model_of_an_arx_predicts_like_it() {
        // y(k) = 0.5 y(k−1) + u(k−1) + e(k): A = 0.5, B = 1, C = 1, D = 0, K = 0.5.
        let model = InnovationModel {
            a: DMatrix::from_element(1, 1, 0.5),
            b: DVector::from_element(1, 1.0),
            c: DVector::from_element(1, 1.0),
            d: 0.0,
            k: DVector::from_element(1, 0.5),
        };
        let arx = Arx {
            a: vec![-0.5],
            b: vec![1.0],
            delay: 1,
        };
        let u = [1.0, -1.0, 0.5, 2.0, 0.0];
        let y = [0.1, 1.2, -0.4, 0.7, 2.1];
        for (p, q) in model.predict(&u, &y).iter().zip(arx.predict(&u, &y)) {
            assert!((p - q).abs() < 1e-12);
        }
        assert!((model.dc_gain().unwrap() - 2.0).abs() < 1e-12);
    }
}
