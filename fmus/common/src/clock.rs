//! The one sample clock of the discrete-time FMUs (docs/README.md, "Sampling"): which samples
//! an `fmi2DoStep` takes, whatever the master's rounding of time.
//!
//! **The instants.** The FMU samples at `t_k = t_0 + k·T` (k = 0, 1, 2, …), with `t_0` the
//! start time of `fmi2SetupExperiment` and `T` the parameter `sample_period`; `k` is counted as
//! an integer, never accumulated, and an instant is compared with a communication point
//! within [`tolerance`] · T (10⁻⁹ T at the start, growing with the
//! drift of a time accumulated by addition, at most 10⁻³ T). `sample_period = 0` (the default) takes `T` from the
//! size of the first `fmi2DoStep`: a fixed-step master's step, so that every run of a
//! fixed-step master is one sample per step, as before; set it when the master's steps are
//! not the sampling period.
//!
//! **Which step takes a sample.** Every sample uses the inputs at its instant: those set at
//! the communication point `t_k` (held over a step that starts before `t_k`).
//! - [`Rule::Step`] (estimators, controllers, discrete plants: the sample's result is the
//!   next state): the step from `t` to `t + h` takes the instants in `[t, t + h)`, i.e.
//!   `t_k < t + h − tol`, with the inputs set before the step, and shows the result of the
//!   last at `t + h`.
//! - [`Rule::Point`] (the sensor: its output at `t_k` is the sample of `t_k`, direct
//!   feedthrough): sample 0 at initialisation, then the step takes the instants its end
//!   reaches, `t_k ≤ t + h + tol`, and the output at `t + h` is the last.
//!
//! So a step of `T` (fmpy's `t_0 + n·h`, or a master that accumulates `t += h`) takes one
//! sample; a shorter step that reaches no new instant (`h = T/2`, or the `1.8·10⁻¹⁵ s` last
//! step of a master whose accumulated time falls short of the stop time, as OMSimulator's
//! `100 × 0.1 < 10`) takes none and the outputs hold; a longer step (`h = 2.5 T`) takes every
//! instant it covers, in order, with the same held inputs, at most [`MAX_SAMPLES_PER_STEP`]:
//! a step covering more is refused with `fmi2Error` before anything changes.
//!
//! The clock is part of the FMU state (`fmi2GetFMUstate`, serialization).

use spurio_export::{ByteReader, ByteWriter, Cause, Failure, Values, Variable};
use std::fmt;
use std::ops::Range;

/// Name of the sample-period parameter of every discrete-time FMU.
pub const SAMPLE_PERIOD: &str = "sample_period";

/// When a communication point τ and an instant t_0 + k·T are the same:
/// `|τ − t_k| ≤ tolerance(k)·T`, `tolerance(k) = min(10⁻⁹ + k²·ε, 10⁻³)` periods, the one rule
/// of the sample clock, the master's data source and the `TimeTable` FMU
/// ([`spurio_table::instant`], where the bound of a master's accumulated drift is derived).
pub use spurio_table::instant::{tolerance, MAX_TOLERANCE, TOLERANCE};

/// The most samples one `fmi2DoStep` may take (a longer step is an error).
pub const MAX_SAMPLES_PER_STEP: u64 = 10_000;

/// Why the clock cannot be built or advanced.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ClockError {
    /// `sample_period` negative or not finite.
    Period(f64),
    /// A step reaching more than [`MAX_SAMPLES_PER_STEP`] instants.
    TooManySamples {
        /// Start of the step (s).
        time: f64,
        /// Its size (s).
        step: f64,
        /// The sample period (s).
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

/// Writes `clock` into an FMU state (an estimator's part of `fmi2SerializeFMUstate`).
pub fn save(clock: &SampleClock, out: &mut ByteWriter) {
    out.put_bytes(&spurio::state::to_bytes(clock));
}

/// Reads a clock written by [`save`]; malformed bytes are an error saying so.
pub fn load(input: &mut ByteReader) -> Result<SampleClock, Cause> {
    let bytes = input.byte_vec()?;
    spurio::state::from_bytes(&bytes)
        .map_err(|e| format!("serialized FMU state: the sample clock: {e}").into())
}

/// The parameter `sample_period` (s), start 0 (= the size of the first step).
pub fn parameter() -> Variable {
    Variable::parameter(SAMPLE_PERIOD, 0.0)
        .unit("s")
        .min(0.0)
        .describe("Sample period T: one sample at each instant start + k·T (k an integer; relative tolerance 1e-9, growing to 1e-3 with the drift of accumulated time), outputs held between samples, every instant a longer step covers taken with the inputs held; 0 = the size of the first step")
}

/// Which step takes the sample of an instant (see the module documentation). A word wide,
/// so that a [`SampleClock`] has no padding: copied whole (taken over after a step), it
/// moves as four words rather than the rule's byte and the bytes around it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u64)]
pub enum Rule {
    /// The step from `t` to `t + h` takes the instants in `[t, t + h)`.
    Step,
    /// Sample 0 at initialisation; the step takes the instants in `(t, t + h]`.
    Point,
}
spurio::plain_state!(
    enum Rule {
        Step,
        Point,
    }
);

/// The instants `t_0 + k·T` and which of them have been taken.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SampleClock {
    rule: Rule,
    start: f64,
    /// `T`; 0 until the first step when `sample_period = 0`.
    period: f64,
    /// The index of the next sample to take.
    next: u64,
}
spurio::plain_state!(SampleClock {
    rule,
    start,
    period,
    next
});

impl SampleClock {
    /// A clock of `rule` starting at `start` with period `period` (0: the first step's size);
    /// under [`Rule::Point`] sample 0 counts as taken (at initialisation).
    pub fn new(rule: Rule, start: f64, period: f64) -> Result<Self, ClockError> {
        if !(period.is_finite() && period >= 0.0) {
            return Err(ClockError::Period(period));
        }
        Ok(Self {
            rule,
            start,
            period,
            next: match rule {
                Rule::Step => 0,
                Rule::Point => 1,
            },
        })
    }

    /// The clock of parameter `index` (`sample_period`) starting at `start`.
    pub fn from_parameter(
        rule: Rule,
        values: &Values,
        index: usize,
        start: f64,
    ) -> Result<Self, ClockError> {
        Self::new(rule, start, values.real(index))
    }

    /// The sample period `T` (0 before the first step when it is taken from that step).
    pub fn period(&self) -> f64 {
        self.period
    }

    /// How many samples have been taken (under [`Rule::Point`], with sample 0).
    pub fn taken(&self) -> u64 {
        self.next
    }

    /// The instant `t_0 + k·T` of sample `k`.
    pub fn instant(&self, k: u64) -> f64 {
        self.start + k as f64 * self.period
    }

    /// Under [`Rule::Point`]: the index of the last sample taken, when `time` is its instant
    /// (within the tolerance), i.e. when `time` is a communication point where a sample was
    /// taken and not one between samples.
    pub fn sample_at(&self, time: f64) -> Option<u64> {
        let last = self.next.checked_sub(1)?;
        let within = tolerance(last as f64) * self.period;
        ((time - self.instant(last)).abs() <= within).then_some(last)
    }

    /// Under [`Rule::Step`]: whether `time` is (within the tolerance) the instant of the next
    /// sample, i.e. a communication point whose inputs the next step will sample (a
    /// direct-feedthrough output shows that sample there).
    pub fn due_at(&self, time: f64) -> bool {
        (time - self.instant(self.next)).abs() <= tolerance(self.next as f64) * self.period
    }

    /// The clock after the step from `time` of size `step`, and the samples (their indices
    /// `k`, in order, possibly none) that step takes; `self` is not changed, so a step that
    /// fails leaves the clock as it was.
    #[inline]
    pub fn after(&self, time: f64, step: f64) -> Result<(SampleClock, Range<u64>), ClockError> {
        let mut next = *self;
        if next.period == 0.0 {
            if !(step.is_finite() && step > 0.0) {
                return Ok((next, next.next..next.next));
            }
            next.period = step;
        }
        let x = (time + step - next.start) / next.period;
        let first = next.next;
        // The number of instants t_k, k >= 0, the step's end has passed (Step) or reached (Point).
        let end = match next.rule {
            Rule::Step => {
                let passed = x - tolerance(x);
                // The common step, one sample: ⌈passed⌉ = first + 1 (the test below, exact
                // for counts below 2⁵³), without the rounding and the checks.
                // (through i64: one conversion instruction; a count is below 2⁶³)
                let before = first as i64 as f64;
                if passed > before && passed <= before + 1.0 {
                    next.next = first + 1;
                    return Ok((next, first..next.next));
                }
                ceil(passed)
            }
            Rule::Point => (x + tolerance(x)).floor() + 1.0,
        };
        if end.is_nan() || end <= first as f64 {
            return Ok((next, first..first));
        }
        if end - first as f64 > MAX_SAMPLES_PER_STEP as f64 {
            return Err(ClockError::TooManySamples {
                time,
                step,
                period: next.period,
                samples: end - first as f64,
            });
        }
        // `end` is finite, > first and at most first + MAX_SAMPLES_PER_STEP here.
        next.next = end as u64;
        Ok((next, first..next.next))
    }
}

/// `v.ceil()` without the library call on the hot path: for |v| < 2⁵² the truncation to an
/// integer is exact, one more when it lies below `v`; larger values (integers already), ±∞
/// and NaN go to [`f64::ceil`]. The one difference, 0 for `v` in (−1, 0) where `ceil` gives
/// −0, is the same instant count for every use in [`SampleClock::after`] (compared with and
/// subtracted from a count, converted to one).
#[inline(always)]
fn ceil(v: f64) -> f64 {
    const EXACT: f64 = 4_503_599_627_370_496.0; // 2⁵²
    if v.abs() < EXACT {
        let t = v as i64 as f64;
        if t < v {
            t + 1.0
        } else {
            t
        }
    } else {
        v.ceil()
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// Xorshift64: the tests' random bits.
    pub(crate) fn xorshift(mut state: u64) -> impl FnMut() -> u64 {
        move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            state
        }
    }

    /// The former `after` (the library `ceil`, no one-sample shortcut), as the reference.
    fn former_after(
        clock: &SampleClock,
        time: f64,
        step: f64,
    ) -> Option<(SampleClock, Range<u64>)> {
        let first = clock.next;
        let period = match clock.period {
            0.0 if !(step.is_finite() && step > 0.0) => return Some((*clock, first..first)),
            0.0 => step,
            period => period,
        };
        let x = (time + step - clock.start) / period;
        let end = if clock.rule == Rule::Step {
            (x - tolerance(x)).ceil()
        } else {
            (x + tolerance(x)).floor() + 1.0
        };
        let next = if end.is_nan() || end <= first as f64 {
            first
        } else if end - first as f64 > MAX_SAMPLES_PER_STEP as f64 {
            return None;
        } else {
            end as u64
        };
        Some((
            SampleClock {
                period,
                next,
                ..*clock
            },
            first..next,
        ))
    }

    #[test]
    fn after_takes_the_samples_of_the_former_formula() {
        let mut bits = xorshift(0x2545_F491_4F6C_DD1D);
        let mut uniform = || (bits() >> 11) as f64 / (1u64 << 53) as f64;
        let mut one_sample = 0;
        for _ in 0..200_000 {
            let period = [0.0, 1e-3, 0.1, 0.25, 1.0 / 3.0][(uniform() * 5.0) as usize];
            let start = [0.0, -1.0, 2.5][(uniform() * 3.0) as usize];
            let rule = if uniform() < 0.7 {
                Rule::Step
            } else {
                Rule::Point
            };
            let mut clock = SampleClock::new(rule, start, period).unwrap();
            let taken = (uniform() * 1e6) as u64;
            clock.next = taken;
            let t_period = if period == 0.0 { 0.1 } else { period };
            // around the next instant, and steps of about one period (and others)
            let time = start + taken as f64 * t_period + (uniform() - 0.5) * 1e-9 * t_period;
            let step = t_period
                * [1.0, 0.5, 2.5, 1.0 + 1e-10, 1.0 - 1e-10, 1e-13][(uniform() * 6.0) as usize];
            let ours = clock.after(time, step).ok();
            assert_eq!(
                ours,
                former_after(&clock, time, step),
                "{clock:?} {time} {step}"
            );
            one_sample += usize::from(ours.is_some_and(|(_, r)| r.end - r.start == 1));
        }
        assert!(one_sample > 50_000, "{one_sample}");
    }

    #[test]
    fn the_inline_ceil_is_the_library_ceil() {
        let mut next = xorshift(0x9E37_79B9_7F4A_7C15);
        let special = [
            0.0,
            -0.0,
            0.5,
            -0.5,
            1.0,
            -1.0,
            1.0 - f64::EPSILON,
            4_503_599_627_370_495.5,
            4_503_599_627_370_496.0,
            -4_503_599_627_370_495.5,
            1e300,
            -1e300,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::MIN_POSITIVE,
            -f64::MIN_POSITIVE,
        ];
        let random = (0..100_000).map(|k| {
            let bits = next();
            match k % 3 {
                // any double
                0 => f64::from_bits(bits),
                // near the counts a clock sees
                1 => (bits >> 11) as f64 / (1u64 << 40) as f64 - 1.0,
                _ => ((bits >> 11) as f64 / (1u64 << 20) as f64).copysign(f64::from_bits(bits)),
            }
        });
        for v in special.into_iter().chain(random) {
            let (ours, library) = (ceil(v), v.ceil());
            if library == 0.0 {
                assert_eq!(ours, 0.0, "{v}");
            } else if library.is_nan() {
                assert!(ours.is_nan(), "{v}");
            } else {
                assert_eq!(ours.to_bits(), library.to_bits(), "{v}");
            }
        }
        assert!(ceil(f64::NAN).is_nan());
    }

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

    fn clocks(start: f64, period: f64) -> [SampleClock; 2] {
        [Rule::Step, Rule::Point].map(|rule| SampleClock::new(rule, start, period).unwrap())
    }

    #[test]
    fn exact_multiples_take_one_sample_per_step() {
        let [mut step, mut point] = clocks(0.0, 0.25);
        let steps = [(0.0, 0.25), (0.25, 0.25), (0.5, 0.25)];
        assert_eq!(run(&mut step, &steps), vec![vec![0], vec![1], vec![2]]);
        assert_eq!(run(&mut point, &steps), vec![vec![1], vec![2], vec![3]]);
        assert_eq!(point.instant(3), 0.75);
        assert_eq!(point.sample_at(0.75), Some(3));
        assert_eq!(point.sample_at(0.625), None);
    }

    #[test]
    fn time_accumulated_by_addition_takes_exactly_one_sample_per_step() {
        // 100 × 0.1 accumulated falls short of 10 (9.99999999999998); every step still takes
        // exactly its sample, and the master's last step to 10 (~2e-14 s) takes none.
        for mut clock in clocks(0.0, 0.1) {
            let first = clock.taken();
            let mut t = 0.0_f64;
            for k in 0..100 {
                let (next, samples) = clock.after(t, 0.1).unwrap();
                assert_eq!(samples, first + k..first + k + 1, "step from t = {t}");
                clock = next;
                t += 0.1;
            }
            assert!(t < 10.0, "{t}");
            let last = 10.0 - t;
            assert!(last > 1e-15 && last < 1e-13, "{last}");
            let (next, samples) = clock.after(t, last).unwrap();
            assert!(samples.is_empty());
            assert_eq!(next, clock);
        }
    }

    #[test]
    fn a_long_run_of_accumulated_time_takes_exactly_one_sample_per_step() {
        // 2·10⁶ steps of 0.001 s accumulated by addition drift from k·T by up to ~4e-5 T, far
        // beyond 1e-9 T: the growing tolerance keeps every step at exactly one sample.
        for period in [0.001, 0.1] {
            for mut clock in clocks(0.0, period) {
                let first = clock.taken();
                let mut t = 0.0_f64;
                let mut worst = 0.0_f64;
                for k in 0..2_000_000_u64 {
                    let (next, samples) = clock.after(t, period).unwrap();
                    assert_eq!(samples, first + k..first + k + 1, "step from t = {t}");
                    clock = next;
                    t += period;
                    worst = worst.max((t - (k + 1) as f64 * period).abs() / period);
                }
                assert!(worst > 1e-6, "the drift this test is about: {worst}");
            }
        }
    }

    #[test]
    fn a_last_step_of_1_8e_15_s_holds_the_outputs() {
        // OMSimulator's timing: the point before the stop time is one ulp short of 10
        // (9.999999999999998) and its last step is 1.8e-15 s.
        let t = 10.0 - 1.8e-15;
        assert!(t < 10.0);
        for (mut clock, taken) in clocks(0.0, 0.1).into_iter().zip([0..100, 1..101]) {
            let (next, samples) = clock.after(0.0, t).unwrap();
            assert_eq!(samples, taken.clone());
            clock = next;
            let (next, samples) = clock.after(t, 1.8e-15).unwrap();
            assert!(samples.is_empty());
            // The next regular step takes the next sample.
            let (_, samples) = next.after(t + 1.8e-15, 0.1).unwrap();
            assert_eq!(samples, taken.end..taken.end + 1);
        }
    }

    #[test]
    fn a_step_of_two_and_a_half_periods_takes_the_instants_it_covers() {
        let [mut step, mut point] = clocks(1.0, 0.2);
        let steps = [(1.0, 0.5), (1.5, 0.5)];
        // [1, 1.5) holds t_0 … t_2; [1.5, 2) holds t_3, t_4.
        assert_eq!(run(&mut step, &steps), vec![vec![0, 1, 2], vec![3, 4]]);
        // (1, 1.5] reaches t_1, t_2; (1.5, 2] reaches t_3 … t_5 (t_5 = 2 is the point).
        assert_eq!(run(&mut point, &steps), vec![vec![1, 2], vec![3, 4, 5]]);
        assert_eq!(point.instant(5), 2.0);
    }

    #[test]
    fn half_period_steps_hold_every_other_step() {
        let [mut step, mut point] = clocks(0.0, 0.1);
        let steps = [(0.0, 0.05), (0.05, 0.05), (0.1, 0.05), (0.15, 0.05)];
        assert_eq!(
            run(&mut step, &steps),
            vec![vec![0], vec![], vec![1], vec![]]
        );
        assert!(step.due_at(0.2) && !step.due_at(0.15));
        assert_eq!(
            run(&mut point, &steps),
            vec![vec![], vec![1], vec![], vec![2]]
        );
        assert_eq!(point.sample_at(0.2), Some(2));
    }

    #[test]
    fn period_zero_takes_the_first_step_size() {
        let [mut step, mut point] = clocks(0.0, 0.0);
        assert_eq!(point.sample_at(0.0), Some(0));
        let steps = [(0.0, 0.3), (0.3, 0.3), (0.6, 0.15), (0.75, 0.15)];
        assert_eq!(
            run(&mut step, &steps),
            vec![vec![0], vec![1], vec![2], vec![]]
        );
        assert_eq!(
            run(&mut point, &steps),
            vec![vec![1], vec![2], vec![], vec![3]]
        );
        assert_eq!((step.period(), point.period()), (0.3, 0.3));
    }

    #[test]
    fn too_long_a_step_and_bad_periods_are_refused() {
        let [step, _] = clocks(0.0, 1e-6);
        let error = step.after(0.0, 1.0).unwrap_err();
        assert!(
            matches!(error, ClockError::TooManySamples { samples, .. } if samples == 1e6),
            "{error:?}"
        );
        assert!(
            error.to_string().contains("`sample_period` = 0.000001 s"),
            "{error}"
        );
        let (next, samples) = step.after(0.0, 0.01).unwrap();
        assert_eq!(samples, 0..MAX_SAMPLES_PER_STEP);
        assert_eq!(next.taken(), MAX_SAMPLES_PER_STEP);
        for bad in [-0.1, f64::NAN, f64::INFINITY] {
            assert!(SampleClock::new(Rule::Step, 0.0, bad).is_err(), "{bad}");
        }
        assert_eq!(
            SampleClock::new(Rule::Point, 0.0, -1.0).unwrap_err().to_string(),
            "parameter `sample_period`: must be a finite number >= 0 (0 = the size of the first step), got -1"
        );
    }

    #[test]
    fn the_clock_is_restored_bit_for_bit_from_its_snapshot() {
        for mut clock in clocks(0.5, 0.1) {
            run(&mut clock, &[(0.5, 0.3)]);
            let back: SampleClock =
                spurio::state::from_bytes(&spurio::state::to_bytes(&clock)).unwrap();
            assert_eq!(back, clock);
            assert_eq!(back.taken(), 3 + u64::from(clock.rule == Rule::Point));
        }
    }
}
