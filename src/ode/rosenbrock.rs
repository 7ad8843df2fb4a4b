//! An adaptive, linearly implicit integrator for stiff plants: the L-stable Rosenbrock method
//! RODAS3 of Sandu et al. (1997, "Benchmarking stiff ODE solvers for atmospheric chemistry
//! problems II: Rosenbrock solvers", Atmos. Environ. 31, table of RODAS3; the method of
//! Hairer & Wanner, *Solving ODEs II*, §IV.7, in their notation) with its embedded
//! second-order solution for error control, using the plant's analytic Jacobian.
//!
//! For `ẋ = f(x)` (the inputs held over the step) and a step `h`, with `J = ∂f/∂x(x₀)`,
//! `γ = 1/2` and `G = I/(γh) − J` (one LU factorisation per step):
//!
//! ```text
//! G k₁ = f(x₀)
//! G k₂ = f(x₀) + 4 k₁/h
//! G k₃ = f(x₀ + 2k₁) + (k₁ − k₂)/h
//! G k₄ = f(x₀ + 2k₁ + k₃) + (k₁ − k₂ − 8/3 k₃)/h
//! x₁ = x₀ + 2k₁ + k₃ + k₄          (order 3, stiffly accurate, L-stable)
//! error estimate: k₄                (x₁ minus the embedded order-2 solution)
//! ```
//!
//! Three evaluations of `f` and one of `J` per step. A step is accepted when the weighted
//! RMS norm `‖k₄ / (atol + rtol·max(|x₀|, |x₁|))‖ ≤ 1`; the next step is
//! `h · clamp(0.9 ‖·‖^(−1/3), 0.2, 6)` (no growth right after a rejection). The stiff modes
//! cost nothing once they have decayed: the step is set by the accuracy of the slow ones.
//!
//! **Bounded work**: one call takes at most [`MAX_ATTEMPTS`] step attempts and refuses a step
//! shorter than [`MIN_STEP_FRACTION`] of the interval, so every `fmi2DoStep` returns in
//! bounded time; a failure leaves the caller's state untouched (it gets an error, not a
//! state). Allocation-free: fixed-size matrices only.

use super::adaptive::{Attempt, Embedded};
pub use super::adaptive::{Statistics, StepError, MAX_ATTEMPTS, MIN_STEP_FRACTION};
use nalgebra::{SMatrix, SVector};
use spurio_solvers::lu;

/// Error tolerances: relative `rtol` and absolute per state `atol`. An infinite absolute
/// tolerance leaves that state out of the error norm (a state nothing depends on).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Tolerance<const N: usize> {
    /// Relative tolerance.
    pub relative: f64,
    /// Absolute tolerance of each state (its units).
    pub absolute: SVector<f64, N>,
}

impl<const N: usize> Tolerance<N> {
    /// The states in the error norm (finite absolute tolerance), each with its error scale
    /// `atolᵢ + rtol · max(|xᵢ|, |nextᵢ|)` for a step from `x` to `next`.
    #[inline]
    pub(crate) fn scales<'a>(
        &'a self,
        x: &'a SVector<f64, N>,
        next: &'a SVector<f64, N>,
    ) -> impl Iterator<Item = (usize, f64)> + 'a {
        (0..N)
            .filter(|&i| self.absolute[i].is_finite())
            .map(|i| (i, self.scale(i, x[i], next[i])))
    }

    /// The error scale `atolᵢ + rtol · max(|xᵢ|, |nextᵢ|)` of state `i` for a step from `x`
    /// to `next` (its components `i`).
    #[inline(always)]
    pub(crate) fn scale(&self, i: usize, x: f64, next: f64) -> f64 {
        self.absolute[i] + self.relative * x.abs().max(next.abs())
    }

    /// Which states are in the error norm (finite absolute tolerance), and how many.
    pub(crate) fn controlled(&self) -> ([bool; N], usize) {
        let controlled = self.absolute.data.0[0].map(f64::is_finite);
        let count = controlled.iter().filter(|&&c| c).count();
        (controlled, count)
    }
}

/// An LU factorisation with partial pivoting of a fixed-size matrix (`P A = L U`), by the
/// one routine of [`spurio_solvers::lu`] on the matrix's column-major storage.
struct Lu<const N: usize> {
    lu: SMatrix<f64, N, N>,
    rows: [usize; N],
}

impl<const N: usize> Lu<N> {
    /// Factorises `a`; `None` when a pivot is zero or not finite (singular).
    fn new(mut a: SMatrix<f64, N, N>) -> Option<Self> {
        let mut rows = [0; N];
        lu::factorise(a.as_mut_slice(), N, &mut rows).then_some(Self { lu: a, rows })
    }

    /// `A⁻¹ b`.
    fn solve(&self, b: &SVector<f64, N>) -> SVector<f64, N> {
        let mut x = SVector::<f64, N>::zeros();
        lu::solve(
            self.lu.as_slice(),
            N,
            &self.rows,
            b.as_slice(),
            x.as_mut_slice(),
        );
        x
    }
}

/// A four-stage Rosenbrock method (the one table of [`spurio_solvers::tableau`]; the
/// fixed-size integrator here takes `f` as autonomous, so it does not use `α` and `γᵢ`).
pub use spurio_solvers::tableau::RosenbrockMethod as Method;
/// RODAS3 (module docs): order 3, L-stable, stiffly accurate.
pub use spurio_solvers::tableau::RODAS3;
/// Shampine's fourth-order Kaps–Rentrop parameters (order 4, embedded order 3, A-stable).
pub use spurio_solvers::tableau::SHAMPINE4;

/// One step of `method` of size `h` from `x`: the new state and the error estimate.
fn rosenbrock_step<const N: usize>(
    method: &Method,
    f: &mut impl FnMut(&SVector<f64, N>) -> SVector<f64, N>,
    jacobian: &SMatrix<f64, N, N>,
    x: &SVector<f64, N>,
    h: f64,
) -> Option<(SVector<f64, N>, SVector<f64, N>)> {
    let g = SMatrix::<f64, N, N>::identity() / (method.gamma * h) - jacobian;
    let lu = Lu::new(g)?;
    let (a, c) = (&method.a, &method.c);
    let f1 = f(x);
    let k1 = lu.solve(&f1);
    let y2 = x + k1 * a[0];
    let f2 = if a[0] == 0.0 { f1 } else { f(&y2) };
    let k2 = lu.solve(&(f2 + k1 * (c[0] / h)));
    let y3 = x + k1 * a[1] + k2 * a[2];
    let f3 = f(&y3);
    let k3 = lu.solve(&(f3 + (k1 * c[1] + k2 * c[2]) / h));
    let same_point = a[3] == a[1] && a[4] == a[2] && a[5] == 0.0;
    let f4 = if same_point {
        f3
    } else {
        f(&(x + k1 * a[3] + k2 * a[4] + k3 * a[5]))
    };
    let k4 = lu.solve(&(f4 + (k1 * c[3] + k2 * c[4] + k3 * c[5]) / h));
    let (b, e) = (&method.b, &method.e);
    let next = x + k1 * b[0] + k2 * b[1] + k3 * b[2] + k4 * b[3];
    let error = k1 * e[0] + k2 * e[1] + k3 * e[2] + k4 * e[3];
    Some((next, error))
}

/// Integrates `ẋ = f(x)` over an interval of `length` from `x`, with adaptive RODAS3 steps
/// (module docs) and `jacobian(x) = ∂f/∂x`. `step` is the step to try first and, on return,
/// the one the error control proposes next (carry it from one call to the next). The state
/// is returned as it is at the interval's end (no discrete change in between: a caller that
/// wraps an angle does so after the call).
#[allow(clippy::too_many_arguments)]
pub fn integrate<const N: usize>(
    method: &Method,
    f: impl FnMut(&SVector<f64, N>) -> SVector<f64, N>,
    jacobian: impl FnMut(&SVector<f64, N>) -> SMatrix<f64, N, N>,
    x: &SVector<f64, N>,
    length: f64,
    tolerance: &Tolerance<N>,
    step: &mut f64,
    statistics: &mut Statistics,
) -> Result<SVector<f64, N>, StepError> {
    let mut stepper = Stepper {
        method,
        f,
        jacobian,
        tolerance,
    };
    super::adaptive::drive(&mut stepper, x, length, step, statistics)
}

/// A Rosenbrock method with its right-hand side and Jacobian, for the shared
/// step-size loop.
struct Stepper<'a, F, J, const N: usize> {
    method: &'a Method,
    f: F,
    jacobian: J,
    tolerance: &'a Tolerance<N>,
}

impl<F, J, const N: usize> Embedded<N> for Stepper<'_, F, J, N>
where
    F: FnMut(&SVector<f64, N>) -> SVector<f64, N>,
    J: FnMut(&SVector<f64, N>) -> SMatrix<f64, N, N>,
{
    fn attempt(&mut self, state: &SVector<f64, N>, (h, done): (f64, f64)) -> Attempt<N> {
        let j = (self.jacobian)(state);
        let (next, error) = rosenbrock_step(self.method, &mut self.f, &j, state, h)
            .ok_or(StepError::Singular { at: done })?;
        let (mut sum, mut controlled) = (0.0, 0);
        for (i, scale) in self.tolerance.scales(state, &next) {
            sum += (error[i] / scale).powi(2);
            controlled += 1;
        }
        Ok((next, (sum / controlled.max(1) as f64).sqrt()))
    }

    fn accept(&mut self, next: SVector<f64, N>, _at: f64) -> Result<SVector<f64, N>, StepError> {
        Ok(next)
    }

    fn factor(&self, error: f64) -> f64 {
        (0.9 * error.powf(-1.0 / self.method.error_order)).clamp(0.2, 6.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Matrix2, Vector2};

    /// Van der Pol with μ (stiff for large μ): right-hand side and Jacobian.
    struct VanDerPol(f64);

    impl VanDerPol {
        fn f(&self, x: &Vector2<f64>) -> Vector2<f64> {
            Vector2::new(x[1], self.0 * (1.0 - x[0] * x[0]) * x[1] - x[0])
        }
        fn jacobian(&self, x: &Vector2<f64>) -> Matrix2<f64> {
            let mu = self.0;
            Matrix2::new(
                0.0,
                1.0,
                -2.0 * mu * x[0] * x[1] - 1.0,
                mu * (1.0 - x[0] * x[0]),
            )
        }
    }

    /// Fixed steps (tolerances so loose every step is accepted).
    fn fixed_steps(method: &Method, n: usize) -> Vector2<f64> {
        let vdp = VanDerPol(1.0);
        let (f, j) = (
            |x: &Vector2<f64>| vdp.f(x),
            |x: &Vector2<f64>| vdp.jacobian(x),
        );
        let mut x = Vector2::new(2.0, 0.0);
        let h = 1.0 / n as f64;
        let loose = Tolerance {
            relative: 1e30,
            absolute: Vector2::repeat(1e30),
        };
        for _ in 0..n {
            let mut step = h;
            x = integrate(
                method,
                &f,
                &j,
                &x,
                h,
                &loose,
                &mut step,
                &mut Statistics::default(),
            )
            .unwrap();
        }
        x
    }

    #[test]
    fn lu_solves_with_pivoting() {
        let a = Matrix2::new(1e-20, 1.0, 1.0, 1.0);
        let x = Lu::new(a).unwrap().solve(&Vector2::new(1.0, 2.0));
        assert!((a * x - Vector2::new(1.0, 2.0)).norm() < 1e-15);
        assert!(Lu::new(Matrix2::new(1.0, 2.0, 2.0, 4.0)).is_none());
    }

    #[test]
    fn rodas3_is_third_order_and_shampine4_fourth() {
        for (method, order) in [(&RODAS3, 3), (&SHAMPINE4, 4)] {
            let reference = fixed_steps(method, 20_000);
            let err = |n| (fixed_steps(method, n) - reference).norm();
            let (e1, e2, e3) = (err(40), err(80), err(160));
            let (r1, r2) = (e1 / e2, e2 / e3);
            let expected = f64::from(1 << order);
            eprintln!("order {order}: error ratios on halving the step: {r1:.3}, {r2:.3}");
            assert!(
                (r1 / expected - 1.0).abs() < 0.2 && (r2 / expected - 1.0).abs() < 0.1,
                "{r1} {r2}"
            );
        }
    }

    #[test]
    fn stiff_mode_costs_nothing_once_on_its_slow_manifold() {
        // ẋ₀ = −10⁶ (x₀ − x₁), ẋ₁ = −x₁ from the slow solution x₀ = a x₁, a = 10⁶/(10⁶ − 1):
        // the fast mode (10⁻⁶ s) is not excited, so the steps follow the slow one.
        let f = |x: &Vector2<f64>| Vector2::new(-1e6 * (x[0] - x[1]), -x[1]);
        let j = |_: &Vector2<f64>| Matrix2::new(-1e6, 1e6, 0.0, -1.0);
        let a = 1e6 / (1e6 - 1.0);
        let tolerance = Tolerance {
            relative: 1e-8,
            absolute: Vector2::repeat(1e-12),
        };
        let mut step = 1e-3;
        let mut stats = Statistics::default();
        let x = integrate(
            &RODAS3,
            f,
            j,
            &Vector2::new(a, 1.0),
            1.0,
            &tolerance,
            &mut step,
            &mut stats,
        )
        .unwrap();
        let exact = (-1f64).exp();
        assert!((x[1] - exact).abs() < 1e-8 * exact, "{}", x[1]);
        assert!((x[0] - a * exact).abs() < 1e-8 * exact, "{}", x[0]);
        // An explicit method would need ~10⁶ steps (stability); this takes a few hundred.
        assert!(stats.accepted < 1000, "{stats:?}");
        eprintln!("stiff linear: {stats:?}");
    }

    #[test]
    fn error_control_meets_the_tolerance_on_a_stiff_van_der_pol() {
        let vdp = VanDerPol(100.0);
        let (f, j) = (
            |x: &Vector2<f64>| vdp.f(x),
            |x: &Vector2<f64>| vdp.jacobian(x),
        );
        let run = |rtol: f64| {
            let tolerance = Tolerance {
                relative: rtol,
                absolute: Vector2::repeat(rtol),
            };
            let mut step = 1e-3;
            let mut stats = Statistics::default();
            let x = integrate(
                &RODAS3,
                &f,
                &j,
                &Vector2::new(2.0, 0.0),
                50.0,
                &tolerance,
                &mut step,
                &mut stats,
            )
            .unwrap();
            (x, stats)
        };
        let (reference, _) = run(1e-12);
        for rtol in [1e-5, 1e-7, 1e-9] {
            let (x, stats) = run(rtol);
            let error = (x - reference).amax() / reference.amax();
            eprintln!("rtol {rtol:e}: error {error:.2e}, {stats:?}");
            assert!(error < 100.0 * rtol, "rtol {rtol}: {error}");
        }
    }

    #[test]
    fn bounded_work_and_typed_failures() {
        // ẋ = 1 with a right-hand side that is not finite beyond x = 2: the steps shrink at
        // x = 2 until the integrator gives up, with an error saying where.
        let f = |x: &Vector2<f64>| Vector2::new(if x[0] > 2.0 { f64::NAN } else { 1.0 }, 0.0);
        let j = |_: &Vector2<f64>| Matrix2::zeros();
        let tolerance = Tolerance {
            relative: 1e-10,
            absolute: Vector2::repeat(1e-10),
        };
        let mut step = 0.1;
        let result = integrate(
            &RODAS3,
            f,
            j,
            &Vector2::new(1.0, 0.0),
            2.0,
            &tolerance,
            &mut step,
            &mut Statistics::default(),
        );
        let Err(StepError::NonFinite { at }) = result else {
            panic!("{result:?}")
        };
        assert!((at - 1.0).abs() < 1e-6, "{at}");
        assert!(result.unwrap_err().to_string().contains("s into the step"));
    }
}
