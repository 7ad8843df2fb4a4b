//! Fixed-step ODE integration used inside the plants' `fmi2DoStep`.
//!
//! A communication step `h` is cut into `n = ceil(h / h_max)` equal substeps, each taken
//! with the classical fourth-order Runge–Kutta method
//!
//! ```text
//! k1 = f(t, x)
//! k2 = f(t + h/2, x + h/2 k1)
//! k3 = f(t + h/2, x + h/2 k2)
//! k4 = f(t + h, x + h k3)
//! x⁺ = x + h/6 (k1 + 2 k2 + 2 k3 + k4)
//! ```
//!
//! When the communication step is a multiple of `h_max`, the internal grid does not depend on
//! the communication step, so a plant gives the same trajectory at common points whatever step
//! the master uses (up to round-off).
//!
//! **Bounded work.** One call integrates at most [`MAX_SUBSTEPS`] substeps: a caller checks a
//! step with [`check_substeps`] first and refuses it when it would need more (a huge step, a
//! tiny `h_max`); [`integrate`] itself never loops longer, whatever its arguments.
//!
//! Adaptive integrators with error control: [`integrate_adaptive`] (Dormand–Prince 5(4), here),
//! [`rosenbrock`] (linearly implicit, L-stable: stiff problems at loose tolerances) and
//! [`dop853`] (Dormand–Prince 8(5,3): tight tolerances, where a high order takes long steps).

mod adaptive;
pub mod dop853;
pub mod rosenbrock;

use crate::ParameterError;
use nalgebra::SVector;

/// The most RK4 substeps one communication step may take: 10⁵ (a few tens of milliseconds for
/// the plants here), so every `fmi2DoStep` returns in bounded time.
pub const MAX_SUBSTEPS: usize = 100_000;

/// One classical RK4 step of size `h` from `(t, x)` for `ẋ = f(t, x)`.
pub fn rk4_step<const N: usize>(
    f: &mut impl FnMut(f64, &SVector<f64, N>) -> SVector<f64, N>,
    t: f64,
    x: &SVector<f64, N>,
    h: f64,
) -> SVector<f64, N> {
    let k1 = f(t, x);
    let k2 = f(t + 0.5 * h, &(x + k1 * (0.5 * h)));
    let k3 = f(t + 0.5 * h, &(x + k2 * (0.5 * h)));
    let k4 = f(t + h, &(x + k3 * h));
    x + (k1 + k2 * 2.0 + k3 * 2.0 + k4) * (h / 6.0)
}

/// Number of equal substeps no longer than `h_max` that cover `h`.
///
/// A step that is a multiple of `h_max` up to round-off (e.g. 0.05 / 0.001 = 50.000000000000004)
/// is not given an extra substep.
/// A ratio that is not finite (or a count beyond `usize`) saturates at `usize::MAX`.
pub fn substep_count(h: f64, h_max: f64) -> usize {
    let ratio = h / h_max;
    if ratio.is_nan() {
        return usize::MAX;
    }
    let nearest = ratio.round();
    let n = if (ratio - nearest).abs() <= 1e-9 * nearest.max(1.0) {
        nearest
    } else {
        ratio.ceil()
    };
    (n as usize).max(1)
}

/// The number of substeps of a step `h` with substeps no longer than `h_max`, or an error
/// naming `h_max` when it exceeds [`MAX_SUBSTEPS`] (or `h`, `h_max` are not finite and > 0).
pub fn check_substeps(h: f64, h_max: f64) -> Result<usize, ParameterError> {
    let n = substep_count(h, h_max);
    if !(h.is_finite() && h > 0.0 && h_max.is_finite() && h_max > 0.0) || n > MAX_SUBSTEPS {
        return Err(ParameterError::new(
            "h_max",
            format!(
                "a step of {h} s in RK4 substeps of at most h_max = {h_max} s needs {} substeps, more than the {MAX_SUBSTEPS} one call may take: take shorter communication steps or a longer h_max",
                if n == usize::MAX { "too many".to_string() } else { n.to_string() }
            ),
        ));
    }
    Ok(n)
}

/// Integrates `ẋ = f(t, x)` over `[t, t + h]` with RK4 substeps no longer than `h_max`.
///
/// `after_substep` runs after every substep and may modify the state (used for hard
/// constraints such as a rail end stop). At most [`MAX_SUBSTEPS`] substeps are taken (longer
/// ones when `h / h_max` asks for more: callers refuse such steps with [`check_substeps`]).
pub fn integrate<const N: usize>(
    mut f: impl FnMut(f64, &SVector<f64, N>) -> SVector<f64, N>,
    mut after_substep: impl FnMut(f64, &mut SVector<f64, N>),
    t: f64,
    x: &SVector<f64, N>,
    h: f64,
    h_max: f64,
) -> SVector<f64, N> {
    let n = substep_count(h, h_max).min(MAX_SUBSTEPS);
    let dt = h / n as f64;
    let mut state = *x;
    for i in 0..n {
        let ti = t + i as f64 * dt;
        state = rk4_step(&mut f, ti, &state, dt);
        after_substep(ti + dt, &mut state);
    }
    state
}

// Dormand–Prince 5(4) tableau (the one table of `spurio_solvers::tableau`): nodes `c`, stage
// weights `a` (row `i` for stage `i + 1`), the fifth-order weights (the last row of `a`, first
// same as last) and the error weights `e = b₅ − b₄`.
use spurio_solvers::tableau::{DP5_A as DP_A, DP5_C as DP_C, DP5_E as DP_E};

/// The error control of [`integrate_adaptive`]: its tolerance and the step to try next.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StepControl {
    /// Mixed absolute/relative error tolerance per step.
    pub tolerance: f64,
    /// The step to try first (carried from call to call; ≤ 0 or not finite: the whole span).
    pub next_step: f64,
}

/// Integrates `ẋ = f(t, x)` from `x` over the span `(t, h)`, `[t, t + h]`, with the
/// Dormand–Prince 5(4) pair and error
/// control: a step is accepted when every component's error estimate is at most
/// `tolerance · (1 + max(|xᵢ|, |xᵢ⁺|))` (mixed absolute/relative), and the next step is
/// `0.9 · err^(−1/5)` times the last (between 0.2× and 5×). `control.next_step` is the step
/// to try first and receives the one to try next. The last step is cut to end exactly at
/// `t + h`.
///
/// `after_step` runs after every accepted step and may modify the state (a hard constraint such
/// as a rail end stop). At most [`MAX_SUBSTEPS`] steps, accepted or rejected, are tried: more
/// (a tolerance too tight for the problem, a step shrinking below round-off) is an error naming
/// `tolerance`, and nothing is returned.
pub fn integrate_adaptive<const N: usize>(
    mut f: impl FnMut(f64, &SVector<f64, N>) -> SVector<f64, N>,
    mut after_step: impl FnMut(f64, &mut SVector<f64, N>),
    control: &mut StepControl,
    (t, h): (f64, f64),
    x: &SVector<f64, N>,
) -> Result<SVector<f64, N>, ParameterError> {
    let tolerance = control.tolerance;
    let end = t + h;
    let mut time = t;
    let mut state = *x;
    let mut step = if control.next_step.is_finite() && control.next_step > 0.0 {
        control.next_step.min(h)
    } else {
        h
    };
    let mut k1 = f(time, &state);
    let mut tries = 0;
    while time < end {
        tries += 1;
        if tries > MAX_SUBSTEPS || step.is_nan() || step <= f64::EPSILON * time.abs().max(h) {
            return Err(ParameterError::new(
                "tolerance",
                format!("the adaptive integrator could not reach t = {end} from t = {time} within {MAX_SUBSTEPS} steps at tolerance {tolerance}: loosen the tolerance or use RK4"),
            ));
        }
        let last = time + step >= end;
        let dt = if last { end - time } else { step };
        let mut k = [k1; 7];
        for stage in 0..6 {
            let mut y = state;
            for (j, a) in DP_A[stage].iter().enumerate().take(stage + 1) {
                if *a != 0.0 {
                    y += k[j] * (dt * a);
                }
            }
            if stage == 5 {
                // the fifth-order solution; its derivative is the error stage and next k1
                k[6] = f(time + dt, &y);
                let mut error: f64 = 0.0;
                for i in 0..N {
                    let mut e = 0.0;
                    for (j, w) in DP_E.iter().enumerate() {
                        e += w * k[j][i];
                    }
                    let scale = tolerance * (1.0 + state[i].abs().max(y[i].abs()));
                    error = error.max((dt * e).abs() / scale);
                }
                let factor = if error == 0.0 {
                    5.0
                } else {
                    (0.9 * error.powf(-0.2)).clamp(0.2, 5.0)
                };
                if error.is_finite() && error <= 1.0 {
                    time = if last { end } else { time + dt };
                    let before = y;
                    after_step(time, &mut y);
                    state = y;
                    k1 = if state == before {
                        k[6]
                    } else {
                        f(time, &state)
                    };
                    // a cut last step does not shrink the next call's first step
                    if !last || dt >= step {
                        step = dt * factor;
                    }
                } else {
                    step = dt * factor.min(1.0);
                }
            } else {
                k[stage + 1] = f(time + DP_C[stage] * dt, &y);
            }
        }
    }
    control.next_step = step;
    Ok(state)
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Vector2;

    #[test]
    fn harmonic_oscillator_matches_the_analytic_solution() {
        // ẍ = −x, x(0) = 1, ẋ(0) = 0  →  x = cos t.
        let f = |_t: f64, x: &Vector2<f64>| Vector2::new(x[1], -x[0]);
        let x = integrate(f, |_, _| {}, 0.0, &Vector2::new(1.0, 0.0), 1.0, 1e-3);
        assert!((x[0] - 1f64.cos()).abs() < 1e-12);
        assert!((x[1] + 1f64.sin()).abs() < 1e-12);
    }

    #[test]
    fn rk4_is_fourth_order() {
        let f = |_t: f64, x: &Vector2<f64>| Vector2::new(x[1], -x[0]);
        let err = |h_max: f64| {
            let x = integrate(f, |_, _| {}, 0.0, &Vector2::new(1.0, 0.0), 2.0, h_max);
            (x[0] - 2f64.cos()).abs()
        };
        let ratio = err(0.1) / err(0.05);
        assert!((ratio - 16.0).abs() < 1.0, "error ratio {ratio}");
    }

    #[test]
    fn the_adaptive_integrator_meets_its_tolerance_and_is_fifth_order() {
        let f = |_t: f64, x: &Vector2<f64>| Vector2::new(x[1], -x[0]);
        let run = |tolerance: f64| {
            let mut control = StepControl {
                tolerance,
                next_step: 0.0,
            };
            let mut x = Vector2::new(1.0, 0.0);
            for k in 0..20 {
                x = integrate_adaptive(f, |_, _| {}, &mut control, (k as f64 * 0.5, 0.5), &x)
                    .unwrap();
            }
            (x[0] - 10f64.cos()).abs().max((x[1] + 10f64.sin()).abs())
        };
        for tolerance in [1e-6, 1e-9, 1e-12] {
            let error = run(tolerance);
            assert!(
                error < 20.0 * tolerance,
                "error {error:e} at tolerance {tolerance:e}"
            );
        }
        // a ten times tighter tolerance: about 10^(4/5)… 10 times smaller errors, not more
        let ratio = run(1e-8) / run(1e-9);
        assert!((2.0..30.0).contains(&ratio), "ratio {ratio}");
        // an impossible tolerance ends in an error, quickly
        let mut control = StepControl {
            tolerance: 1e-300,
            next_step: 0.0,
        };
        let e = integrate_adaptive(
            f,
            |_, _| {},
            &mut control,
            (0.0, 1e3),
            &Vector2::new(1.0, 0.0),
        )
        .unwrap_err();
        assert_eq!(e.parameter, "tolerance");
    }

    #[test]
    fn substep_count_ignores_round_off() {
        assert_eq!(substep_count(0.05, 0.001), 50);
        assert_eq!(substep_count(0.009999999999999998, 0.001), 10);
        assert_eq!(substep_count(0.0015, 0.001), 2);
        assert_eq!(substep_count(1e-5, 0.001), 1);
    }

    #[test]
    fn huge_steps_and_tiny_substeps_are_bounded() {
        assert_eq!(substep_count(1e308, 1e-300), usize::MAX);
        assert_eq!(check_substeps(0.05, 1e-3), Ok(50));
        assert_eq!(check_substeps(100.0, 1e-3), Ok(MAX_SUBSTEPS));
        for (h, h_max) in [(100.001, 1e-3), (1e308, 1e-3), (1.0, 1e-300), (1.0, 0.0)] {
            let e = check_substeps(h, h_max).unwrap_err();
            assert_eq!(e.parameter, "h_max");
            assert!(e.reason.contains("more than the 100000"), "{e}");
        }
        // integrate itself stops at MAX_SUBSTEPS whatever it is given
        let start = std::time::Instant::now();
        let f = |_t: f64, x: &Vector2<f64>| Vector2::new(x[1], -x[0]);
        let _ = integrate(f, |_, _| {}, 0.0, &Vector2::new(1.0, 0.0), 1e308, 1e-300);
        assert!(start.elapsed().as_secs_f64() < 1.0);
    }
}
