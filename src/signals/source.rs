//! Excitation signals for the experiments (docs/models.md §2.5; paper 001 §5 uses random steps of
//! both generator references, paper 002 §III a unit step, papers 000/001 a cosine).
//!
//! Every waveform is a deterministic function of its parameters, its `seed` and the time
//! `t` [s] (time origin 0):
//!
//! * **Step**: `offset + amplitude · [t ≥ step_time]`.
//! * **Random steps**: switching instants `t₀ = 0`, `t_{k+1} = t_k + h_k`, holds
//!   `h_k ~ U[min_hold, max_hold]`, levels `L_k ~ U[offset − amplitude, offset + amplitude]`;
//!   the value is `L_k` on `[t_k, t_{k+1})`. The seeded stream draws `L_k` then `h_k` for each
//!   segment in turn, so the signal does not depend on when it is sampled.
//! * **PRBS**: a maximum-length Fibonacci linear-feedback shift register of `order` n
//!   (2 ≤ n ≤ 24, period 2ⁿ − 1 bits). With the register `r` (n bits) and the feedback
//!   polynomial `xⁿ + x^{k₁} + … + 1` of [`PRBS_TAPS`], one shift computes
//!   `b = r_{n} ⊕ r_{k₁} ⊕ …` (bit positions counted from 1 at the least significant end),
//!   `r ← ((r << 1) | b) mod 2ⁿ` and outputs `b`. Bit `j` (the `(j+1)`-th shift) holds on
//!   `[j T_b, (j+1) T_b)` and the value is `offset + amplitude` for 1, `offset − amplitude`
//!   for 0. The register starts at `1 + seed mod (2ⁿ − 1)` (never zero), so the seed chooses
//!   the phase of the sequence.
//! * **Sine / cosine**: `offset + amplitude · sin(2π f t + phase)` (or `cos`), `f` in Hz;
//!   [`frequency_from_period`] converts a period.
//!
//! Switching instants are compared with a tolerance of 10⁻⁹ of the waveform's time scale
//! (`max(1 s, |step_time|)`, `T_b`, `max_hold`): a communication point computed as `k · h`
//! that lands a hair before an instant because of round-off counts as at the instant.
//!
//! **Sampling and time going back.** [`SignalSource::value_at`] is called at communication
//! points. The random steps and the PRBS keep a cursor (current segment or bit) so that
//! forward sampling costs O(1) per call; if `t` is earlier than the cursor, the source
//! rewinds to its initial state and replays the stream up to `t`, so `value_at` always
//! returns the same value for the same `t`. Hence the state is only a cache: an FMU saves
//! and restores it by cloning, or serialises nothing but the parameters (a fresh source
//! gives the same signal). Times before 0 give the first level / first bit.
//!
//! **Bounded work per sample.** The PRBS is periodic (2ⁿ − 1 bits), so a jump forward skips
//! whole periods and shifts the register at most 2ⁿ − 1 ≤ 16 777 215 times. The random steps
//! cannot skip (each hold is drawn): [`SignalSource::try_value_at`] draws at most
//! [`MAX_SEGMENTS_PER_SAMPLE`] segments and otherwise fails with [`TooFar`] (a sample at
//! `t = 10¹²` s with holds of seconds, say), leaving the cursor further on (it is a cache) —
//! sampling more often gets there.

use super::rng::RandomGenerator;
use crate::{require_finite, require_non_negative, require_positive, ParameterError};
use std::f64::consts::PI;

/// Relative tolerance on switching instants (module docs).
const BOUNDARY_TOLERANCE: f64 = 1e-9;

/// The most random-steps segments one sample may draw (module docs): 10⁷, well under a
/// second.
pub const MAX_SEGMENTS_PER_SAMPLE: u64 = 10_000_000;

/// A sample of the random steps too far from the cursor: more than
/// [`MAX_SEGMENTS_PER_SAMPLE`] segments to draw.
#[derive(Debug, Clone, PartialEq)]
pub struct TooFar {
    /// The time asked for [s].
    pub t: f64,
    /// Where the drawn segments reached [s].
    pub reached: f64,
}

impl std::fmt::Display for TooFar {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "random steps: the signal at t = {} s needs more than {MAX_SEGMENTS_PER_SAMPLE} holds drawn in one call (they reached t = {} s); sample more often, start nearer t = 0 or use longer holds",
            self.t, self.reached
        )
    }
}

impl std::error::Error for TooFar {}

/// Feedback taps of the maximum-length LFSR for orders 2 to 24: `PRBS_TAPS[n − 2]` lists
/// the exponents of the primitive polynomial `xⁿ + … + 1` (without the constant term).
/// The unit tests check that every order has period 2ⁿ − 1.
pub const PRBS_TAPS: [&[u32]; 23] = [
    &[2, 1],
    &[3, 2],
    &[4, 3],
    &[5, 3],
    &[6, 5],
    &[7, 6],
    &[8, 6, 5, 4],
    &[9, 5],
    &[10, 7],
    &[11, 9],
    &[12, 11, 10, 4],
    &[13, 12, 11, 8],
    &[14, 13, 12, 2],
    &[15, 14],
    &[16, 15, 13, 4],
    &[17, 14],
    &[18, 11],
    &[19, 18, 17, 14],
    &[20, 17],
    &[21, 19],
    &[22, 21],
    &[23, 18],
    &[24, 23, 22, 17],
];

/// The frequency [Hz] of a signal of period `period` [s] (parameter `period`, > 0).
pub fn frequency_from_period(period: f64) -> Result<f64, ParameterError> {
    Ok(1.0 / require_positive("period", period)?)
}

/// The periodic function of a [`Waveform::Sinusoid`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Trig {
    /// `sin`.
    Sine,
    /// `cos`.
    Cosine,
}

impl Trig {
    /// The function at `x` [rad].
    pub fn apply(self, x: f64) -> f64 {
        match self {
            Trig::Sine => x.sin(),
            Trig::Cosine => x.cos(),
        }
    }
}

/// `offset + amplitude · [t ≥ step_time]`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Step {
    /// Height of the step (parameter `amplitude`).
    pub amplitude: f64,
    /// Value before the step (parameter `offset`).
    pub offset: f64,
    /// When the step happens [s] (parameter `step_time`).
    pub step_time: f64,
}

/// Levels uniform in `[offset − amplitude, offset + amplitude]` held for random times.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RandomSteps {
    /// Half-width of the level range (parameter `amplitude`, ≥ 0).
    pub amplitude: f64,
    /// Centre of the level range (parameter `offset`).
    pub offset: f64,
    /// Shortest hold [s] (parameter `min_hold`, > 0).
    pub min_hold: f64,
    /// Longest hold [s] (parameter `max_hold`, ≥ `min_hold`).
    pub max_hold: f64,
}

/// Pseudo-random binary sequence `offset ± amplitude`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Prbs {
    /// Register length n, 2 to 24 (parameter `order`).
    pub order: u32,
    /// Duration of one bit `T_b` [s] (parameter `bit_period`, > 0).
    pub bit_period: f64,
    /// Half the peak-to-peak swing (parameter `amplitude`).
    pub amplitude: f64,
    /// Mean level (parameter `offset`).
    pub offset: f64,
}

/// `offset + amplitude · sin(2π f t + phase)` or the same with `cos`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sinusoid {
    /// Sine or cosine.
    pub function: Trig,
    /// Parameter `amplitude`.
    pub amplitude: f64,
    /// Parameter `offset`.
    pub offset: f64,
    /// Frequency f [Hz] (parameter `frequency`, ≥ 0).
    pub frequency: f64,
    /// Phase [rad] (parameter `phase`).
    pub phase: f64,
}

/// What the source generates, with its parameters (module docs for the definitions).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Waveform {
    /// A step.
    Step(Step),
    /// Random steps.
    RandomSteps(RandomSteps),
    /// A PRBS.
    Prbs(Prbs),
    /// A sine or cosine.
    Sinusoid(Sinusoid),
}

/// Checks the `amplitude` and `offset` of a waveform whose amplitude may have either sign.
fn require_levels(amplitude: f64, offset: f64) -> Result<(), ParameterError> {
    require_finite("amplitude", amplitude)?;
    require_finite("offset", offset)?;
    Ok(())
}

impl Waveform {
    /// Checks every parameter, naming the first one that is not acceptable.
    pub fn validate(&self) -> Result<(), ParameterError> {
        match self {
            Waveform::Step(w) => {
                require_levels(w.amplitude, w.offset)?;
                require_finite("step_time", w.step_time)?;
            }
            Waveform::RandomSteps(w) => {
                require_non_negative("amplitude", w.amplitude)?;
                require_finite("offset", w.offset)?;
                require_positive("min_hold", w.min_hold)?;
                require_positive("max_hold", w.max_hold)?;
                if w.max_hold < w.min_hold {
                    return Err(ParameterError::new(
                        "max_hold",
                        format!("must be >= min_hold = {}, got {}", w.min_hold, w.max_hold),
                    ));
                }
            }
            Waveform::Prbs(w) => {
                crate::require_between("order", w.order, 2..=24)?;
                require_positive("bit_period", w.bit_period)?;
                require_levels(w.amplitude, w.offset)?;
            }
            Waveform::Sinusoid(w) => {
                require_levels(w.amplitude, w.offset)?;
                require_non_negative("frequency", w.frequency)?;
                require_finite("phase", w.phase)?;
            }
        }
        Ok(())
    }
}

/// Cursor of the random-steps stream: the current segment `[start, end)` and its level.
#[derive(Debug, Clone, PartialEq)]
struct RandomStepsCursor {
    stream: RandomGenerator,
    start: f64,
    end: f64,
    level: f64,
}

impl RandomStepsCursor {
    /// Moves on to the next segment, which starts where the current one ends: its level, then
    /// its hold, drawn in turn from the stream.
    fn draw_segment(&mut self, w: &RandomSteps) {
        self.start = self.end;
        self.level = self
            .stream
            .uniform_range(w.offset - w.amplitude, w.offset + w.amplitude);
        self.end += self.stream.uniform_range(w.min_hold, w.max_hold);
    }
}

/// Cursor of the PRBS: the register after producing bit `index`, and that bit.
#[derive(Debug, Clone, PartialEq)]
struct PrbsCursor {
    register: u32,
    index: i64,
    bit: bool,
}

/// A signal source: a [`Waveform`], its seed, and a cursor that makes forward sampling cheap.
#[derive(Debug, Clone, PartialEq)]
pub struct SignalSource {
    waveform: Waveform,
    seed: u64,
    random_steps: Option<RandomStepsCursor>,
    prbs: Option<PrbsCursor>,
}

impl SignalSource {
    /// A source after checking the waveform's parameters; `seed` matters only for the random
    /// steps and the PRBS.
    pub fn new(waveform: Waveform, seed: u64) -> Result<Self, ParameterError> {
        waveform.validate()?;
        let mut source = Self {
            waveform,
            seed,
            random_steps: None,
            prbs: None,
        };
        source.rewind();
        Ok(source)
    }

    /// The waveform and its parameters.
    pub fn waveform(&self) -> &Waveform {
        &self.waveform
    }

    /// The seed.
    pub fn seed(&self) -> u64 {
        self.seed
    }

    /// Puts the cursor back at the start of the stream (what `value_at` does when time goes
    /// back).
    pub fn rewind(&mut self) {
        match self.waveform {
            Waveform::RandomSteps(w) => {
                let mut cursor = RandomStepsCursor {
                    stream: RandomGenerator::new(self.seed),
                    start: 0.0,
                    end: 0.0,
                    level: f64::NAN,
                };
                cursor.draw_segment(&w);
                self.random_steps = Some(cursor);
            }
            Waveform::Prbs(Prbs { order, .. }) => {
                let period = (1u64 << order) - 1;
                let register = (1 + self.seed % period) as u32;
                let mut cursor = PrbsCursor {
                    register,
                    index: -1,
                    bit: false,
                };
                prbs_shift(&mut cursor, order);
                self.prbs = Some(cursor);
            }
            _ => {}
        }
    }

    /// The signal at time `t` [s] (module docs; a non-finite `t`, or a sample
    /// [`SignalSource::try_value_at`] refuses, gives NaN).
    pub fn value_at(&mut self, t: f64) -> f64 {
        self.try_value_at(t).unwrap_or(f64::NAN)
    }

    /// The signal at time `t` [s] in bounded time (module docs): [`TooFar`] when the random
    /// steps would draw more than [`MAX_SEGMENTS_PER_SAMPLE`] segments; NaN for a non-finite
    /// `t`.
    pub fn try_value_at(&mut self, t: f64) -> Result<f64, TooFar> {
        if !t.is_finite() {
            return Ok(f64::NAN);
        }
        self.sample(t)
    }

    fn sample(&mut self, t: f64) -> Result<f64, TooFar> {
        Ok(match self.waveform {
            Waveform::Step(Step {
                amplitude,
                offset,
                step_time,
            }) => {
                let tolerance = BOUNDARY_TOLERANCE * step_time.abs().max(1.0);
                if t >= step_time - tolerance {
                    offset + amplitude
                } else {
                    offset
                }
            }
            Waveform::RandomSteps(w) => {
                let tolerance = BOUNDARY_TOLERANCE * w.max_hold;
                let behind = |c: &RandomStepsCursor| t < c.start - tolerance && c.start > 0.0;
                if self.random_steps.as_ref().is_none_or(behind) {
                    self.rewind();
                }
                match self.random_steps.as_mut() {
                    Some(c) => {
                        let mut drawn = 0;
                        while t >= c.end - tolerance {
                            if drawn == MAX_SEGMENTS_PER_SAMPLE {
                                return Err(TooFar { t, reached: c.end });
                            }
                            drawn += 1;
                            c.draw_segment(&w);
                        }
                        c.level
                    }
                    None => f64::NAN,
                }
            }
            Waveform::Prbs(Prbs {
                order,
                bit_period,
                amplitude,
                offset,
            }) => {
                let index = ((t / bit_period + BOUNDARY_TOLERANCE).floor() as i64).max(0);
                if self.prbs.as_ref().is_none_or(|c| index < c.index) {
                    self.rewind();
                }
                match self.prbs.as_mut() {
                    Some(c) => {
                        // The register repeats every 2ⁿ − 1 bits: skip whole periods.
                        let period = (1i128 << order) - 1;
                        let ahead = i128::from(index) - i128::from(c.index);
                        if ahead > period {
                            let skip = ahead / period * period;
                            c.index = (i128::from(c.index) + skip) as i64;
                        }
                        while c.index < index {
                            prbs_shift(c, order);
                        }
                        if c.bit {
                            offset + amplitude
                        } else {
                            offset - amplitude
                        }
                    }
                    None => f64::NAN,
                }
            }
            Waveform::Sinusoid(Sinusoid {
                function,
                amplitude,
                offset,
                frequency,
                phase,
            }) => offset + amplitude * function.apply(2.0 * PI * frequency * t + phase),
        })
    }
}

/// One shift of the LFSR (module docs): computes the feedback bit, shifts it in, outputs it.
fn prbs_shift(cursor: &mut PrbsCursor, order: u32) {
    let taps = PRBS_TAPS[(order - 2) as usize];
    let mut bit = 0u32;
    for &tap in taps {
        bit ^= (cursor.register >> (tap - 1)) & 1;
    }
    let mask = (1u32 << order) - 1; // order ≤ 24 (validated)
    cursor.register = ((cursor.register << 1) | bit) & mask;
    cursor.bit = bit == 1;
    cursor.index += 1;
}

// FMU-state snapshots (plain bytes) of the types above: every field, in order.
crate::plain_state!(Step {
    amplitude,
    offset,
    step_time
});
crate::plain_state!(RandomSteps {
    amplitude,
    offset,
    min_hold,
    max_hold
});
crate::plain_state!(Prbs {
    order,
    bit_period,
    amplitude,
    offset
});
crate::plain_state!(Sinusoid {
    function,
    amplitude,
    offset,
    frequency,
    phase
});
crate::plain_state!(
    enum Waveform {
        Step(w),
        RandomSteps(w),
        Prbs(w),
        Sinusoid(w),
    }
);
crate::plain_state!(
    enum Trig {
        Sine,
        Cosine,
    }
);
crate::plain_state!(RandomStepsCursor {
    stream,
    start,
    end,
    level
});
crate::plain_state!(PrbsCursor {
    register,
    index,
    bit
});
crate::plain_state!(SignalSource {
    waveform,
    seed,
    random_steps,
    prbs
});

#[cfg(test)]
mod tests {
    use super::*;

    /// `offset ± amplitude`, one LFSR bit of `order` per `bit_period`.
    fn prbs(order: u32, bit_period: f64, amplitude: f64, offset: f64) -> Waveform {
        Waveform::Prbs(Prbs {
            order,
            bit_period,
            amplitude,
            offset,
        })
    }

    /// Levels in `offset ± amplitude` held for `min_hold` to `max_hold`.
    fn random_steps(amplitude: f64, offset: f64, min_hold: f64, max_hold: f64) -> Waveform {
        Waveform::RandomSteps(RandomSteps {
            amplitude,
            offset,
            min_hold,
            max_hold,
        })
    }

    #[test]
    fn every_prbs_order_has_maximal_length() {
        for order in 2..=24u32 {
            let start = 1u32;
            let mut c = PrbsCursor {
                register: start,
                index: 0,
                bit: false,
            };
            let period = (1u64 << order) - 1;
            let mut ones = 0u64;
            for k in 1..=period {
                prbs_shift(&mut c, order);
                ones += c.bit as u64;
                if k < period {
                    assert_ne!(c.register, start, "order {order} repeats after {k}");
                }
            }
            assert_eq!(c.register, start, "order {order}");
            // A maximum-length sequence has 2^(n−1) ones and 2^(n−1) − 1 zeros per period.
            assert_eq!(ones, 1u64 << (order - 1), "order {order}");
        }
    }

    #[test]
    fn prbs_levels_bits_and_replay() {
        let w = prbs(7, 0.2, 1.5, 2.0);
        let mut s = SignalSource::new(w, 11).unwrap();
        let forward: Vec<f64> = (0..2000).map(|k| s.value_at(k as f64 * 0.05)).collect();
        for v in &forward {
            assert!(*v == 3.5 || *v == 0.5);
        }
        // Constant within a bit (4 samples of 0.05 s per 0.2 s bit).
        for bit in forward.chunks(4) {
            assert!(bit.iter().all(|v| *v == bit[0]));
        }
        // Periodic with 127 bits.
        for k in 0..(2000 - 127 * 4) {
            assert_eq!(forward[k], forward[k + 127 * 4]);
        }
        // Time going back replays the same values.
        assert_eq!(s.value_at(0.35), forward[7]);
        let mut fresh = SignalSource::new(w, 11).unwrap();
        assert_eq!(fresh.value_at(60.0), s.value_at(60.0));
        // Another seed shifts the phase.
        let mut other = SignalSource::new(w, 12).unwrap();
        let shifted: Vec<f64> = (0..2000).map(|k| other.value_at(k as f64 * 0.05)).collect();
        assert_ne!(shifted, forward);
    }

    #[test]
    fn random_steps_are_held_within_range_and_independent_of_sampling() {
        let w = random_steps(2.0, 5.0, 1.0, 3.0);
        let mut fine = SignalSource::new(w, 7).unwrap();
        let mut coarse = SignalSource::new(w, 7).unwrap();
        let mut changes = Vec::new();
        let mut last = fine.value_at(0.0);
        for k in 0..=100_000 {
            let t = k as f64 * 1e-3;
            let v = fine.value_at(t);
            assert!((3.0..=7.0).contains(&v));
            if v != last {
                changes.push(t);
                last = v;
            }
            if k % 100 == 0 {
                assert_eq!(coarse.value_at(t), v);
            }
        }
        let mut previous = 0.0;
        for t in &changes {
            let hold = t - previous;
            assert!((1.0 - 2e-3..=3.0 + 2e-3).contains(&hold), "hold {hold}");
            previous = *t;
        }
        assert!(changes.len() >= 33 && changes.len() <= 100);
        // Back in time: the same value as the first pass.
        let mut again = SignalSource::new(w, 7).unwrap();
        let v50 = again.value_at(50.0);
        assert_eq!(fine.value_at(50.0), v50);
        let mut other_seed = SignalSource::new(w, 8).unwrap();
        assert_ne!(other_seed.value_at(0.0), again.value_at(0.0));
    }

    #[test]
    fn step_and_sinusoids() {
        let mut step = SignalSource::new(
            Waveform::Step(Step {
                amplitude: 2.0,
                offset: -1.0,
                step_time: 0.3,
            }),
            0,
        )
        .unwrap();
        assert_eq!(step.value_at(0.29), -1.0);
        // 0.1 + 0.2 = 0.30000000000000004, 3 · 0.1 − 1e-16 is still at the step.
        assert_eq!(step.value_at(0.3 - 1e-16), 1.0);
        assert_eq!(step.value_at(0.1 + 0.2), 1.0);
        let f = frequency_from_period(0.25).unwrap();
        let mut sine = SignalSource::new(
            Waveform::Sinusoid(Sinusoid {
                function: Trig::Sine,
                amplitude: 2.0,
                offset: 1.0,
                frequency: f,
                phase: 0.0,
            }),
            0,
        )
        .unwrap();
        let mut cosine = SignalSource::new(
            Waveform::Sinusoid(Sinusoid {
                function: Trig::Cosine,
                amplitude: 2.0,
                offset: 1.0,
                frequency: f,
                phase: -PI / 2.0,
            }),
            0,
        )
        .unwrap();
        for k in 0..100 {
            let t = k as f64 * 0.013;
            let want = 1.0 + 2.0 * (2.0 * PI * 4.0 * t).sin();
            assert!((sine.value_at(t) - want).abs() < 1e-12);
            assert!((cosine.value_at(t) - want).abs() < 1e-12);
        }
        assert!((sine.value_at(0.0625) - 3.0).abs() < 1e-12);
    }

    #[test]
    fn far_samples_take_bounded_work() {
        // PRBS: a sample 10¹² bit periods on equals the one a whole number of periods back
        let fast = prbs(24, 1e-300, 1.0, 0.0);
        let mut far = SignalSource::new(fast, 3).unwrap();
        let start = std::time::Instant::now();
        let v = far.value_at(1e300);
        assert!(v == 1.0 || v == -1.0, "{v}");
        let mut slow = SignalSource::new(prbs(7, 1.0, 1.0, 0.0), 5).unwrap();
        let mut replay = slow.clone();
        let k = 127.0 * 1e9 + 42.0;
        assert_eq!(slow.value_at(k + 0.5), replay.value_at(42.5));
        assert!(start.elapsed().as_secs_f64() < 5.0);
        // random steps: 10¹² s of holds of 1 s to 5 s is refused, not drawn
        let mut random = SignalSource::new(random_steps(1.0, 0.0, 1.0, 5.0), 1).unwrap();
        let start = std::time::Instant::now();
        let e = random.try_value_at(1e12).unwrap_err();
        assert!(start.elapsed().as_secs_f64() < 5.0);
        assert!(e.to_string().contains("more than 10000000 holds"), "{e}");
        assert!(e.reached > 1e7 && e.reached < 6e7, "{}", e.reached);
        assert!(random.value_at(1e12).is_nan());
        // and still right where it can go
        let mut fresh = random.clone();
        fresh.rewind();
        assert_eq!(random.try_value_at(100.0), fresh.try_value_at(100.0));
    }

    #[test]
    fn bad_parameters_are_named() {
        let err = |w: Waveform| SignalSource::new(w, 0).unwrap_err().parameter;
        assert_eq!(err(prbs(1, 1.0, 1.0, 0.0)), "order");
        assert_eq!(err(prbs(5, 0.0, 1.0, 0.0)), "bit_period");
        assert_eq!(err(random_steps(1.0, 0.0, -1.0, 1.0)), "min_hold");
        assert_eq!(err(random_steps(1.0, 0.0, 2.0, 1.0)), "max_hold");
        assert_eq!(
            err(Waveform::Sinusoid(Sinusoid {
                function: Trig::Sine,
                amplitude: f64::NAN,
                offset: 0.0,
                frequency: 1.0,
                phase: 0.0
            })),
            "amplitude"
        );
        assert_eq!(
            err(Waveform::Sinusoid(Sinusoid {
                function: Trig::Cosine,
                amplitude: 1.0,
                offset: 0.0,
                frequency: -1.0,
                phase: 0.0
            })),
            "frequency"
        );
        assert_eq!(
            err(Waveform::Step(Step {
                amplitude: 1.0,
                offset: 0.0,
                step_time: f64::INFINITY
            })),
            "step_time"
        );
        assert_eq!(frequency_from_period(0.0).unwrap_err().parameter, "period");
    }
}
