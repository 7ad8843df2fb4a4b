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
