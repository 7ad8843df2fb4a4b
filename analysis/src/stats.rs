//! Summary statistics of Monte-Carlo runs and benchmark samples, over the finite values only
//! (a diverged run's NaN or infinity is left out rather than poisoning the summary).

/// Mean and sample standard deviation (N − 1) of the finite values (NaN if none).
pub fn mean_std(values: &[f64]) -> (f64, f64) {
    let finite: Vec<f64> = values.iter().copied().filter(|v| v.is_finite()).collect();
    let n = finite.len();
    if n == 0 {
        return (f64::NAN, f64::NAN);
    }
    let mean = finite.iter().sum::<f64>() / n as f64;
    let var = if n > 1 {
        finite.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1) as f64
    } else {
        0.0
    };
    (mean, var.sqrt())
}

/// [`mean_std`] of `pick` over `items`.
pub fn mean_std_of<T>(items: &[T], pick: impl Fn(&T) -> f64) -> (f64, f64) {
    mean_std(&items.iter().map(pick).collect::<Vec<_>>())
}

/// Median of the finite values (NaN if none).
pub fn median(values: &[f64]) -> f64 {
    let mut finite: Vec<f64> = values.iter().copied().filter(|v| v.is_finite()).collect();
    if finite.is_empty() {
        return f64::NAN;
    }
    finite.sort_by(f64::total_cmp);
    let n = finite.len();
    if n % 2 == 1 {
        finite[n / 2]
    } else {
        0.5 * (finite[n / 2 - 1] + finite[n / 2])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn statistics_skip_non_finite_values() {
        let (m, s) = mean_std(&[1.0, f64::NAN, 3.0]);
        assert_eq!(m, 2.0);
        assert!((s - 2f64.sqrt()).abs() < 1e-15);
        assert!(mean_std(&[f64::NAN]).0.is_nan());
        assert_eq!(mean_std(&[4.0]), (4.0, 0.0));
        assert_eq!(median(&[3.0, 1.0, f64::INFINITY, 2.0]), 2.0);
        assert_eq!(median(&[4.0, 1.0]), 2.5);
        assert!(median(&[]).is_nan());
        assert_eq!(mean_std_of(&[(1, 2.0), (2, 4.0)], |p| p.1).0, 3.0);
    }
}
