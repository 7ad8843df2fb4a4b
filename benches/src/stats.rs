//! Medians and the interleaving of measurements.

/// The median of `samples` (NaN for none).
pub fn median(mut samples: Vec<f64>) -> f64 {
    if samples.is_empty() {
        return f64::NAN;
    }
    samples.sort_by(f64::total_cmp);
    let n = samples.len();
    if n % 2 == 1 {
        samples[n / 2]
    } else {
        0.5 * (samples[n / 2 - 1] + samples[n / 2])
    }
}

/// Runs every measurement of `subjects` once per round, in turn (A, B, A, B …, so that a
/// drift of the machine hits all of them alike), and gives each one's samples.
pub fn interleaved<T>(
    rounds: usize,
    subjects: &mut [T],
    mut measure: impl FnMut(&mut T) -> anyhow::Result<f64>,
) -> anyhow::Result<Vec<Vec<f64>>> {
    let mut samples = vec![Vec::with_capacity(rounds); subjects.len()];
    for _ in 0..rounds {
        for (s, out) in subjects.iter_mut().zip(&mut samples) {
            out.push(measure(s)?);
        }
    }
    Ok(samples)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn medians_of_odd_and_even_counts() {
        assert_eq!(median(vec![3.0, 1.0, 2.0]), 2.0);
        assert_eq!(median(vec![4.0, 1.0, 3.0, 2.0]), 2.5);
        assert!(median(Vec::new()).is_nan());
    }

    #[test]
    fn rounds_alternate_between_the_subjects() {
        let mut order = Vec::new();
        let mut subjects = ['a', 'b'];
        let samples = interleaved(3, &mut subjects, |s| {
            order.push(*s);
            Ok(order.len() as f64)
        })
        .unwrap();
        assert_eq!(order, ['a', 'b', 'a', 'b', 'a', 'b']);
        assert_eq!(samples, [vec![1.0, 3.0, 5.0], vec![2.0, 4.0, 6.0]]);
    }
}
