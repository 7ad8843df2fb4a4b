//! The interleaving of measurements (medians: spurio-analysis' [`median`], of the finite samples).

pub use spurio_analysis::median;

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

/// Something timed in batches of steps: nanoseconds per step over `steps` steps.
pub trait Timed {
    fn time_steps(&mut self, steps: u64) -> anyhow::Result<f64>;
}

/// A subject with its batch length: the steps it runs in about the batch time.
pub struct Batched<T> {
    pub subject: T,
    per_batch: u64,
}

impl<T: Timed> Batched<T> {
    /// After a warm-up, times `subject` for the number of steps it runs in about `batch_ms`.
    pub fn new(mut subject: T, batch_ms: f64) -> anyhow::Result<Self> {
        subject.time_steps(20)?;
        let estimate = subject.time_steps(20)?;
        let per_batch = ((batch_ms * 1e6 / estimate) as u64).clamp(1, 1_000_000);
        Ok(Self { subject, per_batch })
    }
}

/// [`interleaved`] batches of every subject: each one's ns per step, per round.
pub fn interleaved_batches<T: Timed>(
    rounds: usize,
    subjects: &mut [Batched<T>],
) -> anyhow::Result<Vec<Vec<f64>>> {
    interleaved(rounds, subjects, |s| s.subject.time_steps(s.per_batch))
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

    /// A subject that takes `ns` per step and records the batches it is asked for.
    struct Fixed {
        ns: f64,
        asked: Vec<u64>,
    }

    impl Timed for Fixed {
        fn time_steps(&mut self, steps: u64) -> anyhow::Result<f64> {
            self.asked.push(steps);
            Ok(self.ns)
        }
    }

    #[test]
    fn batches_last_about_the_batch_time_after_a_warm_up() {
        let fixed = |ns| Fixed { ns, asked: vec![] };
        let mut subjects = [
            Batched::new(fixed(100.0), 2.0).unwrap(),
            Batched::new(fixed(1e8), 2.0).unwrap(),
        ];
        let samples = interleaved_batches(2, &mut subjects).unwrap();
        assert_eq!(samples, [vec![100.0; 2], vec![1e8; 2]]);
        // Warm-up and estimate, then 2 ms / 100 ns; a step longer than the batch: one.
        assert_eq!(subjects[0].subject.asked, [20, 20, 20_000, 20_000]);
        assert_eq!(subjects[1].subject.asked, [20, 20, 1, 1]);
    }
}
