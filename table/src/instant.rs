//! When two times are the same instant: the one rule of the master's data source, the
//! `TimeTable` FMU and every discrete-time FMU's sample clock (`spurio_fmu_common::clock`).
//!
//! A time τ and an instant t_k (the k-th sample, k counted from the first) are the same when
//! |τ − t_k| ≤ tolerance(k)·Δ, Δ the sampling interval there:
//!
//! ```text
//! tolerance(k) = min(10⁻⁹ + k²·ε, 10⁻³)      ε = f64::EPSILON
//! ```
//!
//! A master that accumulates its time by addition (`t += h`, as OMSimulator does) drifts from
//! k·h by up to about k²·ε/2 intervals after k steps (measured: 4·10⁻⁵ Δ after 2·10⁶ steps of
//! 0.001 s), so a fixed tolerance would, late in a long run, let the drift cross it and a
//! step take two samples or none; this one grows with that bound and stays far below any
//! step a master takes on purpose. A master that computes t_0 + k·h (spurio) is within 10⁻⁹
//! intervals throughout.

/// The tolerance near the start, in sampling intervals.
pub const TOLERANCE: f64 = 1e-9;

/// The largest tolerance, in sampling intervals (reached after about 2·10⁶ samples).
pub const MAX_TOLERANCE: f64 = 1e-3;

/// The tolerance around instant `k`, in sampling intervals: `min(10⁻⁹ + k²·ε, 10⁻³)`.
#[inline]
pub fn tolerance(k: f64) -> f64 {
    (TOLERANCE + k * k * f64::EPSILON).min(MAX_TOLERANCE)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_tolerance_grows_with_the_drift_and_is_capped() {
        assert_eq!(tolerance(0.0), 1e-9);
        // After 2·10⁶ steps the drift bound k²ε/2 ≈ 4.4·10⁻⁴ is within it.
        assert!(tolerance(2e6) >= 2e6 * 2e6 * f64::EPSILON / 2.0);
        assert_eq!(tolerance(1e9), MAX_TOLERANCE);
    }
}
