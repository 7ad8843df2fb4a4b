//! The explicit Dormand–Prince 5(4) pair with its continuous extension ([`crate::tableau`]):
//! for `ẋ = f(t, x)` and a step `h`, seven stages
//! `kᵢ = f(t₀ + cᵢh, x₀ + h Σⱼ aᵢⱼ kⱼ)` (`k₁ = f(t₀, x₀)`, `k₇ = f(t₁, x₁)`), the fifth-order
//! solution `x₁` (local extrapolation), the error estimate `h Σ eᵢ kᵢ` (order 4: the step
//! control's exponent is −1/5), and between `t₀` and `t₁` the dense output of order 4
//! (`r₁ … r₅` of [`crate::tableau::DP5_DENSE`]). Six evaluations of `f` per step: `k₇` is the
//! next step's `k₁`.

use crate::solver::{Norm, Outcome, Stepper, Trajectory};
use crate::tableau::{DP5_A, DP5_C, DP5_DENSE, DP5_E};
use crate::OdeSystem;

/// The stages and the dense-output coefficient of Dormand–Prince 5(4) for `n` states.
#[derive(Debug, Clone)]
pub struct Dopri5 {
    /// Stages `k₂ … k₇` (`k₁` is the trajectory's derivative).
    k: [Vec<f64>; 6],
    /// The stage argument, then the candidate `x₁`.
    y: Vec<f64>,
    x_new: Vec<f64>,
    error: Vec<f64>,
    /// `r₅` of the last accepted step.
    r5: Vec<f64>,
}

impl Dopri5 {
    /// The buffers for `n` states.
    pub fn new(n: usize) -> Self {
        Self {
            k: std::array::from_fn(|_| vec![0.0; n]),
            y: vec![0.0; n],
            x_new: vec![0.0; n],
            error: vec![0.0; n],
            r5: vec![0.0; n],
        }
    }
}

impl Stepper for Dopri5 {
    fn error_order(&self) -> f64 {
        5.0
    }

    fn pi_beta(&self) -> f64 {
        0.04
    }

    fn attempt<S: OdeSystem>(&mut self, tr: &mut Trajectory, sys: &mut S, h: f64) -> Norm<S> {
        let n = tr.n;
        for stage in 0..6 {
            let row = &DP5_A[stage];
            for i in 0..n {
                let mut sum = row[0] * tr.current.dx[i];
                for (j, a) in row.iter().enumerate().take(stage + 1).skip(1) {
                    sum += a * self.k[j - 1][i];
                }
                self.y[i] = tr.current.x[i] + h * sum;
            }
            if stage == 5 {
                self.x_new.copy_from_slice(&self.y);
            }
            let t_stage = tr.current.t + DP5_C[stage] * h;
            Trajectory::evaluate(
                &mut tr.statistics,
                sys,
                t_stage,
                &self.y,
                &mut self.k[stage],
            )?;
        }
        for i in 0..n {
            let mut e = DP5_E[0] * tr.current.dx[i];
            for (j, w) in DP5_E.iter().enumerate().skip(1) {
                e += w * self.k[j - 1][i];
            }
            self.error[i] = h * e;
        }
        Ok(tr.norm(&self.error, &self.x_new))
    }

    fn accept<S: OdeSystem>(&mut self, tr: &mut Trajectory, sys: &mut S, t_new: f64) -> Outcome<S> {
        let h = t_new - tr.current.t;
        // r₅ = h (d₁k₁ + d₃k₃ + d₄k₄ + d₅k₅ + d₆k₆ + d₇k₇)
        for i in 0..tr.n {
            let k = |s: usize| self.k[s - 2][i];
            self.r5[i] = h
                * (DP5_DENSE[0] * tr.current.dx[i]
                    + DP5_DENSE[1] * k(3)
                    + DP5_DENSE[2] * k(4)
                    + DP5_DENSE[3] * k(5)
                    + DP5_DENSE[4] * k(6)
                    + DP5_DENSE[5] * k(7));
        }
        tr.advance(&self.x_new, t_new);
        // k₇ = f(t₁, x₁): the next step's first stage
        tr.current.dx.copy_from_slice(&self.k[5]);
        tr.dx_valid = true;
        tr.ensure_derivative(sys)
    }

    fn interpolate(&self, tr: &Trajectory, t: f64, out: &mut [f64]) {
        let Some((h, theta)) = tr.fraction(t, out) else {
            return;
        };
        let theta1 = 1.0 - theta;
        let (start, end) = (&tr.previous, &tr.current);
        for i in 0..tr.n {
            let r1 = start.x[i];
            let r2 = end.x[i] - start.x[i];
            let r3 = h * start.dx[i] - r2;
            let r4 = r2 - h * end.dx[i] - r3;
            out[i] = r1 + theta * (r2 + theta1 * (r3 + theta * (r4 + theta1 * self.r5[i])));
        }
    }

    fn forget(&mut self) {}
}
