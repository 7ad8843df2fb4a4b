//! The one sample clock of the discrete-time FMUs (docs/fmus.md §"Sampling"): when an
//! `fmi2DoStep` takes a sample, whatever the master's rounding of time.
//!
//! **The rule.** The FMU samples at the instants `t_k = t_0 + k·T` (k = 0, 1, 2, …), with
//! `t_0` the start time of `fmi2SetupExperiment` and `T` the parameter `sample_period`; `k` is
//! counted as an integer, never accumulated. Sample 0 is the initialisation. A step from `t`
//! to the communication point `τ = t + h` takes every sample not yet taken whose instant it
//! reaches, `t_k ≤ τ + 10⁻⁹·T` ([`TOLERANCE`]), in order, each with the inputs held over the
//! step (those set before `fmi2DoStep`):
//!
//! - `h = T` (fmpy's `t_0 + n·h`, or a master that accumulates `t += h`): one sample per
//!   step, exactly as if every step were a sample;
//! - a step shorter than `T` that reaches no instant (`h = T/2`, or the `1.8·10⁻¹⁵ s` last step
//!   of a master whose accumulated time falls short of the stop time, as OMSimulator's
//!   `100 × 0.1 < 10`) takes no sample: the outputs hold;
//! - a step longer than `T` (`h = 2.5·T`) takes every instant it reaches (two or three) with
//!   the same held inputs; at most [`MAX_SAMPLES_PER_STEP`] per step, a longer step is refused
//!   with `fmi2Error` before anything changes.
//!
//! `sample_period = 0` (the default) takes `T` from the size of the first `fmi2DoStep`: a
//! fixed-step master's step, so every existing run (one sample per step) is unchanged; set it
//! when the master's steps are not the sampling period.
//!
//! The clock is part of the FMU state (`fmi2GetFMUstate`, serialization).

use spurio_export::{Failure, Values, Variable};
use std::fmt;
use std::ops::RangeInclusive;

/// Name of the sample-period parameter of every discrete-time FMU.
pub const SAMPLE_PERIOD: &str = "sample_period";

/// Relative tolerance of an instant: `τ` reaches `t_k` when `t_k ≤ τ + TOLERANCE·T`.
pub const TOLERANCE: f64 = 1e-9;

/// The most samples one `fmi2DoStep` may take (a longer step is an error).
pub const MAX_SAMPLES_PER_STEP: u64 = 10_000;

/// Why the clock cannot be built or advanced.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ClockError {
    /// `sample_period` negative or not finite.
    Period(f64),
    /// A step reaching more than [`MAX_SAMPLES_PER_STEP`] instants.
    TooManySamples {
        /// Start of the step [s].
        time: f64,
        /// Its size [s].
        step: f64,
        /// The sample period [s].
        period: f64,
        /// How many instants it reaches (may be infinite).
        samples: f64,
    },
}

impl fmt::Display for ClockError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Period(value) => write!(
                f,
                "parameter `{SAMPLE_PERIOD}`: must be a finite number >= 0 (0 = the size of the first step), got {value}"
            ),
            Self::TooManySamples {
                time,
                step,
                period,
                samples,
            } => write!(
                f,
                "the step of {step} s from t = {time} s reaches {samples} sample instants of `{SAMPLE_PERIOD}` = {period} s, more than the {MAX_SAMPLES_PER_STEP} a step may take (the step was not taken)"
            ),
        }
    }
}

impl std::error::Error for ClockError {}

impl From<ClockError> for Failure {
    fn from(e: ClockError) -> Self {
        Failure::error(e)
    }
}

/// The parameter `sample_period` [s], start 0 (= the size of the first step).
pub fn parameter() -> Variable {
    Variable::parameter(SAMPLE_PERIOD, 0.0)
        .unit("s")
        .min(0.0)
        .describe("Sample period T: samples at start + k·T, taken by the step whose end reaches the instant (relative tolerance 1e-9), outputs held in between; 0 = the size of the first step")
}

/// The instants `t_0 + k·T` and how many of them have been taken.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SampleClock {
    start: f64,
    /// `T`; 0 until the first step when `sample_period = 0`.
    period: f64,
    /// The index of the last sample taken (0: the initialisation).
    taken: u64,
}
spurio::plain_state!(SampleClock {
    start,
    period,
    taken
});

impl SampleClock {
    /// A clock starting at `start` with period `period` (0: the first step's size), with
    /// sample 0 taken.
    pub fn new(start: f64, period: f64) -> Result<Self, ClockError> {
        if !(period.is_finite() && period >= 0.0) {
            return Err(ClockError::Period(period));
        }
        Ok(Self {
            start,
            period,
            taken: 0,
        })
    }

    /// The clock of parameter `index` (`sample_period`) starting at `start`.
    pub fn from_parameter(values: &Values, index: usize, start: f64) -> Result<Self, ClockError> {
        Self::new(start, values.real(index))
    }

    /// The sample period `T` (0 before the first step when it is taken from that step).
    pub fn period(&self) -> f64 {
        self.period
    }

    /// The index of the last sample taken (0 at initialisation).
    pub fn taken(&self) -> u64 {
        self.taken
    }

    /// The instant `t_0 + k·T` of sample `k`.
    pub fn instant(&self, k: u64) -> f64 {
        self.start + k as f64 * self.period
    }

    /// Whether `time` is the instant of the last sample taken (within the tolerance): a
    /// communication point where a sample was taken, not one between samples.
    pub fn at_last_sample(&self, time: f64) -> bool {
        (time - self.instant(self.taken)).abs() <= TOLERANCE * self.period
    }

    /// The clock after the step from `time` of size `step`, and the samples (their indices
    /// `k`, in order, possibly none) that step takes; `self` is not changed, so a step that
    /// fails leaves the clock as it was.
    pub fn after(
        &self,
        time: f64,
        step: f64,
    ) -> Result<(SampleClock, RangeInclusive<u64>), ClockError> {
        let mut next = *self;
        if next.period == 0.0 {
            if !(step.is_finite() && step > 0.0) {
                return Ok((next, 1..=0));
            }
            next.period = step;
        }
        let reached = ((time + step - next.start) / next.period + TOLERANCE).floor();
        let taken = next.taken as f64;
        if reached.is_nan() || reached <= taken {
            return Ok((next, 1..=0));
        }
        if reached - taken > MAX_SAMPLES_PER_STEP as f64 {
            return Err(ClockError::TooManySamples {
                time,
                step,
                period: next.period,
                samples: reached - taken,
            });
        }
        let first = next.taken + 1;
        // `reached` is finite, > taken and at most taken + MAX_SAMPLES_PER_STEP here.
        next.taken = reached as u64;
        Ok((next, first..=next.taken))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Runs `steps` (start, size) from a clock and returns the samples each took.
    fn run(clock: &mut SampleClock, steps: &[(f64, f64)]) -> Vec<Vec<u64>> {
        steps
            .iter()
            .map(|&(t, h)| {
                let (next, samples) = clock.after(t, h).unwrap();
                *clock = next;
                samples.collect()
            })
            .collect()
    }

    #[test]
    fn exact_multiples_take_one_sample_per_step() {
        let mut clock = SampleClock::new(0.0, 0.25).unwrap();
        let taken = run(&mut clock, &[(0.0, 0.25), (0.25, 0.25), (0.5, 0.25)]);
        assert_eq!(taken, vec![vec![1], vec![2], vec![3]]);
        assert_eq!(clock.instant(3), 0.75);
        assert!(clock.at_last_sample(0.75));
        assert!(!clock.at_last_sample(0.625));
    }

    #[test]
    fn time_accumulated_by_addition_takes_exactly_one_sample_per_step() {
        // 100 × 0.1 accumulated falls short of 10 (9.99999999999998); every step still takes
        // exactly its sample, and the master's last step to 10 (~2e-14 s) takes none.
        let mut clock = SampleClock::new(0.0, 0.1).unwrap();
        let mut t = 0.0_f64;
        for k in 1..=100 {
            let (next, samples) = clock.after(t, 0.1).unwrap();
            assert_eq!(
                samples.collect::<Vec<_>>(),
                vec![k],
                "step {k} from t = {t}"
            );
            clock = next;
            t += 0.1;
        }
        assert!(t < 10.0, "{t}");
        let last = 10.0 - t;
        assert!(last > 1e-15 && last < 1e-13, "{last}");
        let (next, samples) = clock.after(t, last).unwrap();
        assert!(samples.is_empty());
        assert_eq!(next, clock);
        assert_eq!(clock.taken(), 100);
        assert!(clock.at_last_sample(10.0));
    }

    #[test]
    fn a_last_step_of_1_8e_15_s_holds_the_outputs() {
        // OMSimulator's timing: the point before the stop time is one ulp short of 10
        // (9.999999999999998) and its last step is 1.8e-15 s.
        let t = 10.0 - 1.8e-15;
        assert!(t < 10.0);
        let mut clock = SampleClock::new(0.0, 0.1).unwrap();
        let (next, samples) = clock.after(0.0, t).unwrap();
        assert_eq!(samples, 1..=100);
        clock = next;
        let (next, samples) = clock.after(t, 1.8e-15).unwrap();
        assert!(samples.is_empty());
        assert_eq!(next.taken(), 100);
        // The next regular step takes sample 101 at 10.1.
        let (_, samples) = next.after(t + 1.8e-15, 0.1).unwrap();
        assert_eq!(samples, 101..=101);
    }

    #[test]
    fn a_step_of_two_and_a_half_periods_takes_the_instants_it_reaches() {
        let mut clock = SampleClock::new(1.0, 0.2).unwrap();
        // 1 + 2.5·0.2 = 1.5 reaches t_1 = 1.2 and t_2 = 1.4; the next 2.5 periods reach
        // t_3 … t_5 (t_5 = 2.0 is the communication point itself).
        let taken = run(&mut clock, &[(1.0, 0.5), (1.5, 0.5)]);
        assert_eq!(taken, vec![vec![1, 2], vec![3, 4, 5]]);
        assert_eq!(clock.instant(5), 2.0);
    }

    #[test]
    fn half_period_steps_hold_every_other_step() {
        let mut clock = SampleClock::new(0.0, 0.1).unwrap();
        let taken = run(
            &mut clock,
            &[(0.0, 0.05), (0.05, 0.05), (0.1, 0.05), (0.15, 0.05)],
        );
        assert_eq!(taken, vec![vec![], vec![1], vec![], vec![2]]);
        assert!(clock.at_last_sample(0.2));
    }

    #[test]
    fn period_zero_takes_the_first_step_size() {
        let mut clock = SampleClock::new(0.0, 0.0).unwrap();
        assert!(clock.at_last_sample(0.0));
        let taken = run(
            &mut clock,
            &[(0.0, 0.3), (0.3, 0.3), (0.6, 0.15), (0.75, 0.15)],
        );
        assert_eq!(taken, vec![vec![1], vec![2], vec![], vec![3]]);
        assert_eq!(clock.period(), 0.3);
    }

    #[test]
    fn too_long_a_step_and_bad_periods_are_refused() {
        let clock = SampleClock::new(0.0, 1e-6).unwrap();
        let error = clock.after(0.0, 1.0).unwrap_err();
        assert!(
            matches!(error, ClockError::TooManySamples { samples, .. } if samples == 1e6),
            "{error:?}"
        );
        assert!(
            error.to_string().contains("`sample_period` = 0.000001 s"),
            "{error}"
        );
        let (next, samples) = clock.after(0.0, 0.01).unwrap();
        assert_eq!(samples, 1..=10_000);
        assert_eq!(next.taken(), MAX_SAMPLES_PER_STEP);
        for bad in [-0.1, f64::NAN, f64::INFINITY] {
            assert!(SampleClock::new(0.0, bad).is_err(), "{bad}");
        }
        assert_eq!(
            SampleClock::new(0.0, -1.0).unwrap_err().to_string(),
            "parameter `sample_period`: must be a finite number >= 0 (0 = the size of the first step), got -1"
        );
    }

    #[test]
    fn the_clock_is_restored_bit_for_bit_from_its_snapshot() {
        let mut clock = SampleClock::new(0.5, 0.1).unwrap();
        run(&mut clock, &[(0.5, 0.3)]);
        let back: SampleClock =
            spurio::state::from_bytes(&spurio::state::to_bytes(&clock)).unwrap();
        assert_eq!(back, clock);
        assert_eq!(back.taken(), 3);
    }
}
