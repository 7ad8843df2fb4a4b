//! The interleaving of measurements (medians: the experiments' [`median`]).

pub use spurio_experiments::runner::median;

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
