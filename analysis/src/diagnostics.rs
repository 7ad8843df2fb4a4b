//! Outlier diagnostics on recorded results (docs/diagnostics.md §3; paper 000 §VII-A Table 2, paper 001 §5
//! eqs 18–19).
//!
//! * **Grubbs test**, two-sided, for one outlier in a sample `y₁ … y_N` assumed normal:
//!   `G = max_i |y_i − ȳ| / s` (s: sample standard deviation, N − 1 denominator), rejected
//!   when `G > G_crit` with
//!
//!   ```text
//!   G_crit = ((N − 1)/√N) · √( t² / (N − 2 + t²) ),   t = t_{1 − α/(2N), N − 2}
//!   ```
//!
//!   the upper `α/(2N)` quantile of Student's t with N − 2 degrees of freedom. (Paper 000
//!   prints `N/√N`, a typo.) α = 0.05 gives 4.0400 for N = 1000 (the paper's 4.04) and 2.2900
//!   for N = 10. [`grubbs_iterative`] removes the rejected value and repeats.
//! * **Student's t** CDF and quantile from `statrs` (the upper tail is
//!   `P(T > t) = ½ I_{ν/(ν+t²)}(ν/2, ½)`, with the regularised incomplete beta function
//!   `I_x(a, b)`; the quantile inverts it on the tail).
//! * **Sample moments**: mean `ȳ`, standard deviation `s` (N − 1), and the paper 001 moment
//!   estimators (population, 1/N, *biased* forms):
//!
//!   ```text
//!   κ = m₄ / m₂² − 3   (excess kurtosis, eq. 18),     γ = m₃ / m₂^{3/2}   (skewness, eq. 19),
//!   m_k = (1/N) Σ (y_i − ȳ)^k
//!   ```
//! * **Residual error** `E_res = (1/N) ‖y_clean − y_est‖²` (paper 001 §5).
//! * **Histogram** `(edges, counts)` and the band `ȳ ± 2 s` drawn over it (paper 000 Fig. 3).
//!
//! Every function checks its input and returns [`DiagnosticsError`] instead of NaN.

use statrs::distribution::{ContinuousCDF, StudentsT};
use std::fmt;

/// Why a diagnostic could not be computed.
#[derive(Debug, Clone, PartialEq)]
pub enum DiagnosticsError {
    /// Not enough samples for the statistic.
    TooFewSamples {
        /// Minimum needed.
        needed: usize,
        /// Samples given.
        got: usize,
    },
    /// A sample is NaN or infinite.
    NonFinite {
        /// Index of the first non-finite sample.
        index: usize,
    },
    /// All samples are equal, so the statistic (skewness, kurtosis) is undefined.
    ZeroVariance,
    /// The significance level is not in (0, 1).
    InvalidSignificance(f64),
    /// A probability argument is not in (0, 1).
    InvalidProbability(f64),
    /// Degrees of freedom not finite and positive.
    InvalidDegreesOfFreedom(f64),
    /// A non-finite argument to a distribution function.
    InvalidArgument(f64),
    /// A histogram needs at least one bin.
    ZeroBins,
    /// Clean and estimated signals differ in length.
    LengthMismatch {
        /// Length of the clean signal.
        clean: usize,
        /// Length of the estimate.
        estimate: usize,
    },
}

impl fmt::Display for DiagnosticsError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::TooFewSamples { needed, got } => {
                write!(f, "need at least {needed} samples, got {got}")
            }
            Self::NonFinite { index } => write!(f, "sample {index} is NaN or infinite"),
            Self::ZeroVariance => write!(f, "all samples are equal (zero variance)"),
            Self::InvalidSignificance(alpha) => {
                write!(f, "significance level must be in (0, 1), got {alpha}")
            }
            Self::InvalidProbability(p) => write!(f, "probability must be in (0, 1), got {p}"),
            Self::InvalidDegreesOfFreedom(nu) => {
                write!(f, "degrees of freedom must be finite and > 0, got {nu}")
            }
            Self::InvalidArgument(x) => write!(f, "argument must be finite, got {x}"),
            Self::ZeroBins => write!(f, "a histogram needs at least one bin"),
            Self::LengthMismatch { clean, estimate } => write!(
                f,
                "clean signal has {clean} samples but the estimate has {estimate}"
            ),
        }
    }
}

impl std::error::Error for DiagnosticsError {}

fn check_samples(data: &[f64], needed: usize) -> Result<(), DiagnosticsError> {
    if data.len() < needed {
        return Err(DiagnosticsError::TooFewSamples {
            needed,
            got: data.len(),
        });
    }
    match data.iter().position(|v| !v.is_finite()) {
        Some(index) => Err(DiagnosticsError::NonFinite { index }),
        None => Ok(()),
    }
}

// ---------------------------------------------------------------------------------------
// Special functions and Student's t
// ---------------------------------------------------------------------------------------

fn check_dof(dof: f64) -> Result<(), DiagnosticsError> {
    if dof.is_finite() && dof > 0.0 {
        Ok(())
    } else {
        Err(DiagnosticsError::InvalidDegreesOfFreedom(dof))
    }
}

/// The standard Student's t distribution with `dof` degrees of freedom (statrs).
fn student_t(dof: f64) -> Result<StudentsT, DiagnosticsError> {
    check_dof(dof)?;
    StudentsT::new(0.0, 1.0, dof).map_err(|_| DiagnosticsError::InvalidDegreesOfFreedom(dof))
}

/// Student's t cumulative distribution `P(T ≤ t)` with `dof` degrees of freedom.
pub fn student_t_cdf(t: f64, dof: f64) -> Result<f64, DiagnosticsError> {
    let distribution = student_t(dof)?;
    if t.is_nan() {
        return Err(DiagnosticsError::InvalidArgument(t));
    }
    if t.is_infinite() {
        return Ok(if t > 0.0 { 1.0 } else { 0.0 });
    }
    Ok(distribution.cdf(t))
}

/// Student's t quantile: the `t` with `P(T ≤ t) = p`, for `0 < p < 1` (statrs, which
/// inverts the regularised incomplete beta function on the tail, so small tail
/// probabilities such as α/(2N) = 2.5e-5 keep their accuracy).
pub fn student_t_quantile(p: f64, dof: f64) -> Result<f64, DiagnosticsError> {
    let distribution = student_t(dof)?;
    if !(p > 0.0 && p < 1.0) {
        return Err(DiagnosticsError::InvalidProbability(p));
    }
    if p == 0.5 {
        return Ok(0.0);
    }
    Ok(distribution.inverse_cdf(p))
}

// ---------------------------------------------------------------------------------------
// Grubbs
// ---------------------------------------------------------------------------------------

/// Two-sided Grubbs critical value for `n` samples at significance `alpha` (module doc).
pub fn grubbs_critical_value(n: usize, alpha: f64) -> Result<f64, DiagnosticsError> {
    if n < 3 {
        return Err(DiagnosticsError::TooFewSamples { needed: 3, got: n });
    }
    if !(alpha > 0.0 && alpha < 1.0) {
        return Err(DiagnosticsError::InvalidSignificance(alpha));
    }
    let nf = n as f64;
    let t = student_t_quantile(1.0 - alpha / (2.0 * nf), nf - 2.0)?;
    let t2 = t * t;
    Ok((nf - 1.0) / nf.sqrt() * (t2 / (nf - 2.0 + t2)).sqrt())
}

/// Result of one two-sided Grubbs test.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GrubbsOutcome {
    /// Number of samples tested.
    pub samples: usize,
    /// Sample mean ȳ.
    pub mean: f64,
    /// Sample standard deviation s (N − 1 denominator).
    pub std_dev: f64,
    /// Statistic `G = max |y_i − ȳ| / s` (0 when all samples are equal).
    pub statistic: f64,
    /// Critical value `G_crit`.
    pub critical_value: f64,
    /// Index (in the tested slice) of the sample farthest from the mean.
    pub suspect_index: usize,
    /// Its value.
    pub suspect_value: f64,
    /// `G > G_crit`: the suspect is an outlier at level α.
    pub is_outlier: bool,
}

/// Two-sided Grubbs test for one outlier (at least 3 finite samples, `0 < alpha < 1`).
pub fn grubbs_test(data: &[f64], alpha: f64) -> Result<GrubbsOutcome, DiagnosticsError> {
    check_samples(data, 3)?;
    let critical_value = grubbs_critical_value(data.len(), alpha)?;
    let mean = mean(data)?;
    let std_dev = std_dev(data)?;
    let (suspect_index, deviation) =
        data.iter()
            .map(|y| (y - mean).abs())
            .enumerate()
            .fold(
                (0, -1.0),
                |best, (i, d)| if d > best.1 { (i, d) } else { best },
            );
    let statistic = if std_dev > 0.0 {
        deviation / std_dev
    } else {
        0.0
    };
    Ok(GrubbsOutcome {
        samples: data.len(),
        mean,
        std_dev,
        statistic,
        critical_value,
        suspect_index,
        suspect_value: data[suspect_index],
        is_outlier: statistic > critical_value,
    })
}

/// Iterated Grubbs test: while the test rejects, remove the suspect and test again (at the
/// same α, with the critical value for the remaining N). Returns the indices (into `data`)
/// of the rejected samples, in the order they were rejected. Stops when the test accepts or
/// fewer than 3 samples remain.
pub fn grubbs_iterative(data: &[f64], alpha: f64) -> Result<Vec<usize>, DiagnosticsError> {
    check_samples(data, 3)?;
    if !(alpha > 0.0 && alpha < 1.0) {
        return Err(DiagnosticsError::InvalidSignificance(alpha));
    }
    let mut remaining: Vec<(usize, f64)> = data.iter().copied().enumerate().collect();
    let mut rejected = Vec::new();
    while remaining.len() >= 3 {
        let values: Vec<f64> = remaining.iter().map(|(_, v)| *v).collect();
        let outcome = grubbs_test(&values, alpha)?;
        if !outcome.is_outlier {
            break;
        }
        let (original_index, _) = remaining.remove(outcome.suspect_index);
        rejected.push(original_index);
    }
    Ok(rejected)
}

// ---------------------------------------------------------------------------------------
// Moments, residual error, histogram
// ---------------------------------------------------------------------------------------

/// Sample mean `ȳ = (1/N) Σ y_i` (at least one finite sample).
pub fn mean(data: &[f64]) -> Result<f64, DiagnosticsError> {
    check_samples(data, 1)?;
    Ok(data.iter().sum::<f64>() / data.len() as f64)
}

/// Sample standard deviation `s = √( Σ (y_i − ȳ)² / (N − 1) )` (at least two samples).
pub fn std_dev(data: &[f64]) -> Result<f64, DiagnosticsError> {
    check_samples(data, 2)?;
    let m = mean(data)?;
    let sum_sq: f64 = data.iter().map(|y| (y - m) * (y - m)).sum();
    Ok((sum_sq / (data.len() - 1) as f64).sqrt())
}

/// Central moments `(m₂, m₃, m₄)` with the 1/N normalisation.
fn central_moments(data: &[f64]) -> Result<(f64, f64, f64), DiagnosticsError> {
    let m = mean(data)?;
    let n = data.len() as f64;
    let (mut m2, mut m3, mut m4) = (0.0, 0.0, 0.0);
    for y in data {
        let d = y - m;
        let d2 = d * d;
        m2 += d2;
        m3 += d2 * d;
        m4 += d2 * d2;
    }
    Ok((m2 / n, m3 / n, m4 / n))
}

/// Sample skewness `γ = m₃ / m₂^{3/2}` (paper 001 eq. 19; biased 1/N moments).
pub fn skewness(data: &[f64]) -> Result<f64, DiagnosticsError> {
    check_samples(data, 2)?;
    let (m2, m3, _) = central_moments(data)?;
    if m2 <= 0.0 {
        return Err(DiagnosticsError::ZeroVariance);
    }
    Ok(m3 / m2.powf(1.5))
}

/// Sample excess kurtosis `κ = m₄ / m₂² − 3` (paper 001 eq. 18; biased 1/N moments; 0 for a
/// Gaussian).
pub fn excess_kurtosis(data: &[f64]) -> Result<f64, DiagnosticsError> {
    check_samples(data, 2)?;
    let (m2, _, m4) = central_moments(data)?;
    if m2 <= 0.0 {
        return Err(DiagnosticsError::ZeroVariance);
    }
    Ok(m4 / (m2 * m2) - 3.0)
}

/// Summary statistics of a sample (see the module doc for the estimators).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SampleMoments {
    /// Number of samples N.
    pub samples: usize,
    /// Mean ȳ.
    pub mean: f64,
    /// Standard deviation s (N − 1 denominator).
    pub std_dev: f64,
    /// Skewness γ (paper 001 eq. 19).
    pub skewness: f64,
    /// Excess kurtosis κ (paper 001 eq. 18).
    pub excess_kurtosis: f64,
}

/// Mean, standard deviation, skewness and excess kurtosis (at least two samples, not all
/// equal).
pub fn sample_moments(data: &[f64]) -> Result<SampleMoments, DiagnosticsError> {
    Ok(SampleMoments {
        samples: data.len(),
        mean: mean(data)?,
        std_dev: std_dev(data)?,
        skewness: skewness(data)?,
        excess_kurtosis: excess_kurtosis(data)?,
    })
}

/// Residual error `E_res = (1/N) ‖y_clean − y_est‖²` (paper 001 §5).
pub fn residual_error(clean: &[f64], estimate: &[f64]) -> Result<f64, DiagnosticsError> {
    if clean.len() != estimate.len() {
        return Err(DiagnosticsError::LengthMismatch {
            clean: clean.len(),
            estimate: estimate.len(),
        });
    }
    check_samples(clean, 1)?;
    check_samples(estimate, 1)?;
    let sum_sq: f64 = clean
        .iter()
        .zip(estimate)
        .map(|(c, e)| (c - e) * (c - e))
        .sum();
    Ok(sum_sq / clean.len() as f64)
}

/// Histogram of `data` in `bins` equal bins spanning `[min, max]`: `(edges, counts)` with
/// `bins + 1` edges; the last bin includes `max`. A constant sample gets one unit-wide
/// range centred on its value.
pub fn histogram(data: &[f64], bins: usize) -> Result<(Vec<f64>, Vec<usize>), DiagnosticsError> {
    if bins == 0 {
        return Err(DiagnosticsError::ZeroBins);
    }
    check_samples(data, 1)?;
    let min = data.iter().copied().fold(f64::INFINITY, f64::min);
    let max = data.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let (low, high) = if max > min {
        (min, max)
    } else {
        (min - 0.5, max + 0.5)
    };
    let width = (high - low) / bins as f64;
    let edges: Vec<f64> = (0..=bins)
        .map(|k| {
            if k == bins {
                high
            } else {
                low + k as f64 * width
            }
        })
        .collect();
    let mut counts = vec![0usize; bins];
    for y in data {
        let position = ((y - low) / width).floor();
        let index = if position <= 0.0 {
            0
        } else {
            (position as usize).min(bins - 1)
        };
        counts[index] += 1;
    }
    Ok((edges, counts))
}

/// The band `(ȳ − 2s, ȳ + 2s)` drawn over the histogram (≈ 95 % of a Gaussian sample).
pub fn two_sigma_band(data: &[f64]) -> Result<(f64, f64), DiagnosticsError> {
    let m = mean(data)?;
    let s = std_dev(data)?;
    Ok((m - 2.0 * s, m + 2.0 * s))
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::PI;

    #[test]
    fn student_t_quantiles_match_published_values() {
        // Published values (qt(0.975, 10), qt(0.995, 5)) and closed forms for ν = 1
        // (tan(π(p − ½))) and ν = 2 ((2p − 1)/√(2p(1 − p)))).
        let cases = [
            (0.975, 10.0, 2.228_138_851_986),
            (0.995, 5.0, 4.032_142_983_557),
            (0.95, 1.0, 6.313_751_514_675),
            (0.9, 2.0, 1.885_618_083_164),
        ];
        for (p, dof, want) in cases {
            let got = student_t_quantile(p, dof).unwrap();
            assert!(
                (got - want).abs() < 1e-10,
                "t({p}, {dof}) = {got} vs {want}"
            );
            let lower = student_t_quantile(1.0 - p, dof).unwrap();
            assert!((lower + want).abs() < 1e-9);
        }
    }

    #[test]
    fn student_t_cdf_matches_closed_forms() {
        for t in [-30.0, -2.5, -0.3, 0.0, 0.7, 4.0, 100.0] {
            let cauchy = 0.5 + f64::atan(t) / PI;
            assert!(
                (student_t_cdf(t, 1.0).unwrap() - cauchy).abs() < 1e-14,
                "ν=1, t={t}"
            );
            let two = 0.5 + t / (2.0 * (2.0 + t * t).sqrt());
            assert!(
                (student_t_cdf(t, 2.0).unwrap() - two).abs() < 1e-14,
                "ν=2, t={t}"
            );
        }
        assert_eq!(student_t_cdf(f64::INFINITY, 3.0).unwrap(), 1.0);
        assert!(student_t_cdf(f64::NAN, 3.0).is_err());
        assert!(student_t_cdf(1.0, 0.0).is_err());
        assert!(student_t_quantile(1.0, 3.0).is_err());
    }

    #[test]
    fn grubbs_critical_values_match_the_spec() {
        // docs/reference-values.md §6 / paper 000 Table 2: 4.0400 (N = 1000) and 2.2900 (N = 10), α = 0.05.
        let g1000 = grubbs_critical_value(1000, 0.05).unwrap();
        let g10 = grubbs_critical_value(10, 0.05).unwrap();
        eprintln!("Grubbs critical values: N=1000 {g1000:.6}, N=10 {g10:.6}");
        assert!((g1000 - 4.0400).abs() < 5e-5, "{g1000}");
        assert!((g10 - 2.2900).abs() < 5e-5, "{g10}");
        assert!(grubbs_critical_value(2, 0.05).is_err());
        assert!(grubbs_critical_value(10, 1.5).is_err());
    }

    #[test]
    fn grubbs_finds_a_planted_outlier_and_the_iteration_finds_all() {
        // A smooth deterministic sample with two planted outliers.
        let mut data: Vec<f64> = (0..50).map(|k| (k as f64 * 0.7).sin()).collect();
        data[7] = 9.0;
        data[31] = -6.0;
        let outcome = grubbs_test(&data, 0.05).unwrap();
        assert!(outcome.is_outlier);
        assert_eq!(outcome.suspect_index, 7);
        assert_eq!(outcome.suspect_value, 9.0);
        assert_eq!(grubbs_iterative(&data, 0.05).unwrap(), vec![7, 31]);
        let clean: Vec<f64> = (0..50).map(|k| (k as f64 * 0.7).sin()).collect();
        assert!(grubbs_iterative(&clean, 0.05).unwrap().is_empty());
        // Constant data: nothing to reject, no NaN.
        let constant = grubbs_test(&[1.0; 5], 0.05).unwrap();
        assert_eq!(constant.statistic, 0.0);
        assert!(!constant.is_outlier);
        assert_eq!(
            grubbs_test(&[1.0, f64::NAN, 2.0], 0.05).unwrap_err(),
            DiagnosticsError::NonFinite { index: 1 }
        );
    }

    #[test]
    fn grubbs_statistic_of_a_small_sample_by_hand() {
        // Data 1, 2, 3, 4, 10: ȳ = 4, s = √(50/4) = 3.5355, G = 6/s = 1.697.
        let outcome = grubbs_test(&[1.0, 2.0, 3.0, 4.0, 10.0], 0.05).unwrap();
        assert!((outcome.mean - 4.0).abs() < 1e-15);
        assert!((outcome.std_dev - 12.5f64.sqrt()).abs() < 1e-15);
        assert!((outcome.statistic - 6.0 / 12.5f64.sqrt()).abs() < 1e-15);
    }

    #[test]
    fn moments_of_known_sequences() {
        // 1..5: m₂ = 2, m₄ = 6.8 → κ = 6.8/4 − 3 = −1.3, γ = 0.
        let m = sample_moments(&[1.0, 2.0, 3.0, 4.0, 5.0]).unwrap();
        assert!((m.excess_kurtosis + 1.3).abs() < 1e-14);
        assert!(m.skewness.abs() < 1e-15);
        assert!((m.mean - 3.0).abs() < 1e-15);
        assert!((m.std_dev - 2.5f64.sqrt()).abs() < 1e-15);
        // Bernoulli(1/4) pattern: κ = (1 − 6pq)/(pq) = −2/3, γ = (1 − 2p)/√(pq) = 2/√3.
        let b = [0.0, 0.0, 0.0, 1.0];
        assert!((excess_kurtosis(&b).unwrap() + 2.0 / 3.0).abs() < 1e-14);
        assert!((skewness(&b).unwrap() - 2.0 / 3f64.sqrt()).abs() < 1e-14);
        // Dense uniform grid: κ → −6/5.
        let uniform: Vec<f64> = (0..=100_000).map(|k| k as f64 / 100_000.0).collect();
        assert!((excess_kurtosis(&uniform).unwrap() + 1.2).abs() < 1e-4);
        assert_eq!(
            excess_kurtosis(&[2.0, 2.0]).unwrap_err(),
            DiagnosticsError::ZeroVariance
        );
        assert!(mean(&[]).is_err());
    }

    #[test]
    fn residual_error_is_the_mean_squared_difference() {
        let e = residual_error(&[1.0, 2.0, 3.0, 4.0], &[1.0, 2.5, 3.0, 2.0]).unwrap();
        assert!((e - (0.25 + 4.0) / 4.0).abs() < 1e-15);
        assert_eq!(
            residual_error(&[1.0], &[1.0, 2.0]).unwrap_err(),
            DiagnosticsError::LengthMismatch {
                clean: 1,
                estimate: 2
            }
        );
    }

    #[test]
    fn histogram_counts_every_sample_once() {
        let data = [0.0, 0.1, 0.5, 0.99, 1.0, 0.25];
        let (edges, counts) = histogram(&data, 4).unwrap();
        assert_eq!(edges, vec![0.0, 0.25, 0.5, 0.75, 1.0]);
        assert_eq!(counts, vec![2, 1, 1, 2]);
        let (edges, counts) = histogram(&[3.0, 3.0], 2).unwrap();
        assert_eq!(edges, vec![2.5, 3.0, 3.5]);
        assert_eq!(counts.iter().sum::<usize>(), 2);
        assert_eq!(histogram(&data, 0).unwrap_err(), DiagnosticsError::ZeroBins);
        let (low, high) = two_sigma_band(&[1.0, 2.0, 3.0, 4.0, 5.0]).unwrap();
        assert!((low - (3.0 - 2.0 * 2.5f64.sqrt())).abs() < 1e-15);
        assert!((high - (3.0 + 2.0 * 2.5f64.sqrt())).abs() < 1e-15);
    }
}
