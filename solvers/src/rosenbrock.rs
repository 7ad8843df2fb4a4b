//! Linearly implicit Rosenbrock methods ([`crate::tableau::RosenbrockTableau`]: RODAS4 with
//! its continuous extension; RODAS3 and Shampine's order-4 method) for stiff problems. For
//! `ẋ = f(t, x)` and a step `h`, with `J = ∂f/∂x(t₀, x₀)`, `fₜ = ∂f/∂t(t₀, x₀)` and
//! `G = I/(γh) − J`:
//!
//! ```text
//! G kᵢ = f(t₀ + αᵢh, x₀ + Σⱼ<ᵢ aᵢⱼ kⱼ) + Σⱼ<ᵢ cᵢⱼ kⱼ / h + γᵢ h fₜ     (i = 1 … s)
//! x₁ = x₀ + Σ bᵢ kᵢ,   error estimate Σ eᵢ kᵢ
//! ```
//!
//! `G` is factorised once per attempt by LU with partial pivoting ([`crate::lu`]) and every
//! stage is a forward and backward substitution; no inverse is formed. `J` is formed once per
//! accepted state (a rejected step reuses it), column by column: `J eⱼ` from the model's
//! Jacobian–vector products when [`OdeSystem::jacobian_times`] gives them, otherwise the
//! forward difference `(f(t, x + δⱼeⱼ) − f(t, x))/δⱼ` with
//! `δⱼ = √(ε · nominalⱼ · max(|xⱼ|, 10⁻⁵ nominalⱼ))` (Hairer & Wanner's RODAS: a state far
//! below its nominal is perturbed in proportion to its size, not to the nominal, which
//! would change it by orders of magnitude and spoil `J` where the model is nonlinear). `fₜ` is the forward difference in `t` with
//! `δₜ = √ε · max(|t|, 1)` (one evaluation, skipped when the model says it is autonomous).
//!
//! Dense output: the method's continuous extension from its stages when it has one (RODAS4:
//! `(1 − θ) x₀ + θ (x₁ + (1 − θ) (r₁ + θ r₂))`, `r_m = Σ dₘᵢ kᵢ`, order 3, see
//! [`crate::tableau::RosenbrockTableau`]); otherwise the cubic Hermite polynomial through
//! `(t₀, x₀, f₀)` and `(t₁, x₁, f₁)`. The Hermite cubic is accurate on a smooth solution but
//! multiplies a stiff component's distance from its slow manifold by the eigenvalue through
//! `f₁`; the continuous extension does not, which is why RODAS4 is the stiff default.

use crate::lu;
use crate::solver::{Norm, Outcome, Stepper, Trajectory};
use crate::tableau::{RosenbrockTableau, MAX_STAGES};
use crate::{OdeSystem, SolverError, SolverErrorKind};

/// A Rosenbrock method with its buffers for `n` states.
#[derive(Debug, Clone)]
pub struct Rosenbrock {
    method: RosenbrockTableau,
    n: usize,
    /// `J` at the trajectory's state, column-major, valid when `jacobian_valid`.
    jacobian: Vec<f64>,
    jacobian_valid: bool,
    /// Whether the model answered a Jacobian–vector product (`None`: not asked yet).
    products: Option<bool>,
    /// Whether `f` does not depend on `t` (no `fₜ`).
    autonomous: bool,
    /// `∂f/∂t`.
    f_t: Vec<f64>,
    /// `G`, then its LU factors.
    g: Vec<f64>,
    rows: Vec<usize>,
    k: [Vec<f64>; MAX_STAGES],
    /// `r₁`, `r₂` of the continuous extension of the last accepted step.
    dense: [Vec<f64>; 2],
    y: Vec<f64>,
    f: Vec<f64>,
    rhs: Vec<f64>,
    x_new: Vec<f64>,
    error: Vec<f64>,
    /// A unit vector for the Jacobian–vector products.
    seed: Vec<f64>,
}

impl Rosenbrock {
    /// `method` for `n` states, taking `f` as time-dependent.
    pub fn new(method: impl Into<RosenbrockTableau>, n: usize) -> Self {
        let method = method.into();
        let zeros = || vec![0.0; n];
        let stage = |i: usize| {
            if i < method.stages {
                zeros()
            } else {
                Vec::new()
            }
        };
        let dense = |_| {
            if method.dense.is_some() {
                zeros()
            } else {
                Vec::new()
            }
        };
        Self {
            method,
            n,
            jacobian: vec![0.0; n * n],
            jacobian_valid: false,
            products: None,
            autonomous: false,
            f_t: zeros(),
            g: vec![0.0; n * n],
            rows: vec![0; n],
            k: std::array::from_fn(stage),
            dense: std::array::from_fn(dense),
            y: zeros(),
            f: zeros(),
            rhs: zeros(),
            x_new: zeros(),
            error: zeros(),
            seed: zeros(),
        }
    }

    /// Declares `f` independent of `t` (no `∂f/∂t` is formed).
    pub fn set_autonomous(&mut self, autonomous: bool) {
        self.autonomous = autonomous;
    }

    /// Forms `J` (and `fₜ`) at the trajectory's state.
    fn form_jacobian<S: OdeSystem>(
        &mut self,
        tr: &mut Trajectory,
        system: &mut S,
    ) -> Result<(), SolverError<S::Error>> {
        let n = self.n;
        tr.statistics.jacobians += 1;
        let point = &tr.current;
        if self.products != Some(false) {
            let mut given = true;
            for j in 0..n {
                self.seed.fill(0.0);
                self.seed[j] = 1.0;
                tr.statistics.jacobian_products += 1;
                let column = &mut self.jacobian[j * n..(j + 1) * n];
                let at = crate::Direction {
                    t: point.t,
                    x: &point.x,
                    v: &self.seed,
                };
                given = system
                    .jacobian_times(at, column)
                    .map_err(|source| SolverError::at(point.t, SolverErrorKind::Model(source)))?;
                if !given {
                    tr.statistics.jacobian_products -= 1;
                    break;
                }
            }
            self.products = Some(given);
        }
        if self.products == Some(false) {
            for j in 0..n {
                let scale = tr.tolerance.nominal[j];
                let delta = (f64::EPSILON * scale * point.x[j].abs().max(1e-5 * scale)).sqrt();
                self.y.copy_from_slice(&point.x);
                self.y[j] += delta;
                let delta = self.y[j] - point.x[j];
                Trajectory::evaluate(&mut tr.statistics, system, point.t, &self.y, &mut self.f)?;
                for i in 0..n {
                    self.jacobian[i + j * n] = (self.f[i] - point.dx[i]) / delta;
                }
            }
        }
        if self.autonomous {
            self.f_t.fill(0.0);
        } else {
            let delta = f64::EPSILON.sqrt() * point.t.abs().max(1.0);
            let t = point.t + delta;
            let delta = t - point.t;
            Trajectory::evaluate(&mut tr.statistics, system, t, &point.x, &mut self.f)?;
            for i in 0..n {
                self.f_t[i] = (self.f[i] - point.dx[i]) / delta;
            }
        }
        self.jacobian_valid = true;
        Ok(())
    }

    /// Solves stage `i`: `G kᵢ = f + Σⱼ<ᵢ (cᵢⱼ/h) kⱼ + γᵢ h fₜ` with `f` in `self.f`.
    fn stage(&mut self, i: usize, h: f64) {
        let c = &self.method.c;
        // cᵢⱼ for j < i: row i of the strictly lower triangle, packed (c₂₁, c₃₁, c₃₂, …).
        let first = i * (i.saturating_sub(1)) / 2;
        let gamma_t = self.method.gamma_t[i] * h;
        for r in 0..self.n {
            let mut v = self.f[r] + gamma_t * self.f_t[r];
            for j in 0..i {
                v += c[first + j] / h * self.k[j][r];
            }
            self.rhs[r] = v;
        }
        lu::solve(&self.g, self.n, &self.rows, &self.rhs, &mut self.k[i]);
    }

    /// `y = x₀ + Σⱼ<ᵢ aᵢⱼ kⱼ` for stage `i` (packed as `c`).
    fn stage_point(&mut self, x: &[f64], i: usize) {
        let a = &self.method.a;
        let first = i * (i.saturating_sub(1)) / 2;
        for r in 0..self.n {
            let mut v = x[r];
            for j in 0..i {
                v += a[first + j] * self.k[j][r];
            }
            self.y[r] = v;
        }
    }
}

impl Stepper for Rosenbrock {
    fn error_order(&self) -> f64 {
        self.method.error_order
    }

    fn attempt<S: OdeSystem>(&mut self, tr: &mut Trajectory, sys: &mut S, h: f64) -> Norm<S> {
        let n = self.n;
        if !self.jacobian_valid {
            self.form_jacobian(tr, sys)?;
        }
        let diagonal = 1.0 / (self.method.gamma * h);
        for (g, j) in self.g.iter_mut().zip(&self.jacobian) {
            *g = -j;
        }
        for i in 0..n {
            self.g[i + i * n] += diagonal;
        }
        tr.statistics.factorisations += 1;
        if !lu::factorise(&mut self.g, n, &mut self.rows) {
            // Singular (or not finite): a shorter step moves 1/(γh) off J's spectrum.
            return Ok(f64::NAN);
        }
        let (a, alpha) = (self.method.a, self.method.alpha);
        for i in 0..self.method.stages {
            if i == 0 {
                self.f.copy_from_slice(&tr.current.dx);
            } else {
                // A stage at the previous stage's point reuses its f.
                let packed = i * (i - 1) / 2;
                let previous = (i - 1) * (i.saturating_sub(2)) / 2;
                let same_point = i >= 2
                    && alpha[i] == alpha[i - 1]
                    && a[packed + i - 1] == 0.0
                    && (0..i - 1).all(|j| a[packed + j] == a[previous + j]);
                let at_start = alpha[i] == 0.0 && (0..i).all(|j| a[packed + j] == 0.0);
                if at_start {
                    self.f.copy_from_slice(&tr.current.dx);
                } else if !same_point {
                    self.stage_point(&tr.current.x, i);
                    let t = tr.current.t + alpha[i] * h;
                    Trajectory::evaluate(&mut tr.statistics, sys, t, &self.y, &mut self.f)?;
                }
            }
            self.stage(i, h);
        }
        let (b, e) = (self.method.b, self.method.e);
        for r in 0..n {
            let mut next = tr.current.x[r];
            let mut error = 0.0;
            for j in 0..self.method.stages {
                next += b[j] * self.k[j][r];
                error += e[j] * self.k[j][r];
            }
            self.x_new[r] = next;
            self.error[r] = error;
        }
        Ok(tr.norm(&self.error, &self.x_new))
    }

    fn accept<S: OdeSystem>(&mut self, tr: &mut Trajectory, sys: &mut S, t_new: f64) -> Outcome<S> {
        if let Some(d) = &self.method.dense {
            for (r, d) in self.dense.iter_mut().zip(d) {
                for i in 0..self.n {
                    r[i] = (0..self.method.stages).map(|j| d[j] * self.k[j][i]).sum();
                }
            }
        }
        tr.advance(&self.x_new, t_new);
        tr.dx_valid = false;
        self.jacobian_valid = false;
        tr.ensure_derivative(sys)
    }

    fn interpolate(&self, tr: &Trajectory, t: f64, out: &mut [f64]) {
        let Some((h, s)) = tr.fraction(t, out) else {
            return;
        };
        let (start, end) = (&tr.previous, &tr.current);
        if self.method.dense.is_some() {
            let [r1, r2] = &self.dense;
            for i in 0..tr.n {
                out[i] = (1.0 - s) * start.x[i] + s * (end.x[i] + (1.0 - s) * (r1[i] + s * r2[i]));
            }
            return;
        }
        // Cubic Hermite basis in s = (t − t₀)/h.
        let h00 = (1.0 + 2.0 * s) * (1.0 - s) * (1.0 - s);
        let h10 = s * (1.0 - s) * (1.0 - s);
        let h01 = s * s * (3.0 - 2.0 * s);
        let h11 = s * s * (s - 1.0);
        for i in 0..tr.n {
            out[i] =
                h00 * start.x[i] + h10 * h * start.dx[i] + h01 * end.x[i] + h11 * h * end.dx[i];
        }
    }

    fn forget(&mut self) {
        self.jacobian_valid = false;
    }
}
