//! `spurio run --progress`: a progress bar on standard error, drawn by an observer attached
//! around the run's own observer (the engine draws nothing; it sends every recorded
//! communication point to its observer, whose time says how far the run is).

use indicatif::{ProgressBar, ProgressStyle};
use spurio_master::Observer;

/// Passes every call on to `inner` and moves a bar of `steps` base steps to the step each
/// sample's time t_k = start + k·h belongs to; clears the bar when the run finishes.
pub struct Progress<'a> {
    inner: &'a mut dyn Observer,
    bar: ProgressBar,
    start_time: f64,
    step_size: f64,
}

impl<'a> Progress<'a> {
    /// A bar over `steps` base steps of size `step_size` from `start_time`, around `inner`.
    pub fn new(inner: &'a mut dyn Observer, steps: u64, start_time: f64, step_size: f64) -> Self {
        let bar = ProgressBar::new(steps);
        bar.set_style(
            ProgressStyle::with_template(
                "{bar:40} {pos}/{len} steps {elapsed_precise} (eta {eta})",
            )
            .unwrap_or_else(|_| ProgressStyle::default_bar()),
        );
        Self {
            inner,
            bar,
            start_time,
            step_size,
        }
    }

    /// The base step of communication point `time`.
    fn step_of(&self, time: f64) -> u64 {
        ((time - self.start_time) / self.step_size).round().max(0.0) as u64
    }
}

impl Observer for Progress<'_> {
    fn start(&mut self, names: &[String]) -> std::io::Result<()> {
        self.inner.start(names)
    }

    fn sample(&mut self, time: f64, values: &[f64]) -> std::io::Result<()> {
        self.bar.set_position(self.step_of(time));
        self.inner.sample(time, values)
    }

    fn finish(&mut self) -> std::io::Result<()> {
        self.bar.finish_and_clear();
        self.inner.finish()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use spurio_master::TimeSeries;

    #[test]
    fn the_bar_follows_the_samples_and_the_rows_pass_through() {
        let mut series = TimeSeries::default();
        let mut progress = Progress::new(&mut series, 40, 1.0, 0.25);
        progress.start(&["a.x".to_string()]).unwrap();
        progress.sample(1.0, &[3.0]).unwrap();
        assert_eq!(progress.bar.position(), 0);
        progress.sample(3.5, &[4.0]).unwrap();
        assert_eq!(progress.bar.position(), 10);
        assert_eq!(progress.step_of(1.0 + 0.25 * 37.0), 37);
        progress.finish().unwrap();
        assert_eq!(series.time, [1.0, 3.5]);
        assert_eq!(series.rows, [[3.0], [4.0]]);
    }
}
