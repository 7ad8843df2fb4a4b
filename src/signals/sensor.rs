//! One measurement channel with noise, outliers and an ADC (docs/models.md §2.6; the outlier model
//! of papers 000 §VII-A and 001 §5, the 12-bit acquisition of paper 002 §III).
//!
//! For a clean value `y(t)` sampled at a communication point `t`, the channel returns
//!
//! ```text
//! measured = Q( y + σ n + o )
//! n ~ N(0, 1)                                  (noise stream)
//! o = s · a   with probability ε if t_start ≤ t < t_end, else 0   (outlier stream)
//! a ~ U[outlier_min, outlier_max],  s = ±1 with probability ½ each
//! ```
//!
//! * **Noise**: `σ² = variance`, or from a signal-to-noise ratio in dB relative to a declared
//!   signal power `P` (the mean square of the clean signal, e.g. `A²/2` for a sine of
//!   amplitude `A`): `σ² = P / 10^(snr_db/10)`.
//! * **Outliers** (ε-contamination, Huber's model): a fraction `epsilon` ∈ [0, 1] of the
//!   samples inside the window get an additive spike of uniform magnitude in
//!   `[outlier_min, outlier_max]` and random sign. With `outlier_min = 0`,
//!   `outlier_max = 4.8` this is exactly the `U(−4.8, 4.8)` spikes of docs/experiments.md §4; with
//!   `outlier_min = outlier_max = 5 · RMS` the ±5·RMS spikes of the crane experiment. The
//!   window defaults to all time (`[0, ∞)`); paper 001 uses only the first half.
//! * **Quantisation** (optional): an ideal `bits`-bit ADC on `[adc_min, adc_max]` with step
//!   `q = (adc_max − adc_min) / 2^bits`, code `k = round((v − adc_min)/q)` clipped to
//!   `[0, 2^bits − 1]`, reading `adc_min + k q`. Values below the range read `adc_min`,
//!   values above read `adc_max − q` (the full-scale code).
//!
//! Randomness: two independent [`RandomGenerator`] streams of the channel's `seed`
//! (`for_stream(seed, 0)` for the noise, `for_stream(seed, 1)` for the outliers). Every sample
//! consumes one Gaussian from the noise stream and exactly three uniforms from the outlier
//! stream (decision, magnitude, sign), whether or not an outlier occurs or the time is in the
//! window; so the outlier positions do not change with the noise level or the magnitude
//! range, and the same seed gives bit-identical readings. Each call to [`Sensor::measure`] is
//! one sample: the channel does not look at `t` except for the outlier window, so the FMU
//! restores a saved state (clone, or [`Sensor::state`]/[`Sensor::restore_state`]) rather
//! than calling it with an earlier time. A non-finite clean value gives a non-finite reading
//! (the FMU adapter rejects it before).

use super::rng::RandomGenerator;
use crate::{require_finite, require_non_negative, ParameterError};

/// How the noise level is given.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum NoiseLevel {
    /// Noise variance σ² (parameter `variance`), in the signal's unit squared.
    Variance(f64),
    /// Signal-to-noise ratio `snr_db` [dB] relative to the mean-square `signal_power` of the
    /// clean signal: σ² = `signal_power` / 10^(`snr_db`/10).
    SignalToNoiseRatio {
        /// SNR in dB (parameter `snr_db`).
        snr_db: f64,
        /// Mean square of the clean signal (parameter `signal_power`).
        signal_power: f64,
    },
}

/// The ε-contaminated outliers of one channel.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OutlierParameters {
    /// Fraction ε ∈ [0, 1] of the samples (inside the window) that carry an outlier.
    pub epsilon: f64,
    /// Smallest outlier magnitude `outlier_min` ≥ 0.
    pub min_magnitude: f64,
    /// Largest outlier magnitude `outlier_max` ≥ `outlier_min`.
    pub max_magnitude: f64,
    /// Outliers only for `outlier_t_start` ≤ t < `outlier_t_end` [s]; `f64::INFINITY` as the
    /// end means no end.
    pub window_start: f64,
    /// See `window_start`.
    pub window_end: f64,
}

impl Default for OutlierParameters {
    /// ε = 0.05 (docs/models.md §2.6) with the `U(−4.8, 4.8)` spikes of docs/experiments.md §4, at all times.
    fn default() -> Self {
        Self {
            epsilon: 0.05,
            min_magnitude: 0.0,
            max_magnitude: 4.8,
            window_start: 0.0,
            window_end: f64::INFINITY,
        }
    }
}

/// An ideal analogue-to-digital converter.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Quantiser {
    /// Resolution `bits`, 1 to 32.
    pub bits: u32,
    /// Lower end of the input range `adc_min`.
    pub min: f64,
    /// Upper end of the input range `adc_max` > `adc_min`.
    pub max: f64,
}

impl Quantiser {
    /// Checks `bits` ∈ [1, 32] and a finite, non-empty range.
    pub fn validate(&self) -> Result<(), ParameterError> {
        crate::require_between("bits", self.bits, 1..=32)?;
        require_finite("adc_min", self.min)?;
        require_finite("adc_max", self.max)?;
        if self.max <= self.min {
            return Err(ParameterError::new(
                "adc_max",
                format!("must exceed adc_min = {}, got {}", self.min, self.max),
            ));
        }
        Ok(())
    }

    /// The quantisation step `(max − min) / 2^bits`.
    pub fn step(&self) -> f64 {
        (self.max - self.min) / 2f64.powi(self.bits as i32)
    }

    /// The ADC reading of `value` (module docs): rounded to the nearest code, clipped.
    pub fn quantise(&self, value: f64) -> f64 {
        let step = self.step();
        let top_code = 2f64.powi(self.bits as i32) - 1.0;
        let code = ((value - self.min) / step).round().clamp(0.0, top_code);
        self.min + code * step
    }
}

/// All parameters of one channel.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SensorParameters {
    /// Additive Gaussian noise level.
    pub noise: NoiseLevel,
    /// Outliers (set `epsilon = 0` for none).
    pub outliers: OutlierParameters,
    /// Optional ADC; `None` leaves the value continuous.
    pub quantiser: Option<Quantiser>,
    /// Seed of the channel's random streams (parameter `seed`).
    pub seed: u64,
}

impl Default for SensorParameters {
    /// Noise variance 0.01 (docs/experiments.md §4), default outliers, no ADC, seed 1.
    fn default() -> Self {
        Self {
            noise: NoiseLevel::Variance(0.01),
            outliers: OutlierParameters::default(),
            quantiser: None,
            seed: 1,
        }
    }
}

impl SensorParameters {
    /// Checks every parameter, naming the first one that is not acceptable.
    pub fn validate(&self) -> Result<(), ParameterError> {
        match self.noise {
            NoiseLevel::Variance(v) => {
                require_non_negative("variance", v)?;
            }
            NoiseLevel::SignalToNoiseRatio {
                snr_db,
                signal_power,
            } => {
                require_finite("snr_db", snr_db)?;
                require_non_negative("signal_power", signal_power)?;
            }
        }
        let o = &self.outliers;
        if !(o.epsilon.is_finite() && (0.0..=1.0).contains(&o.epsilon)) {
            return Err(ParameterError::new(
                "epsilon",
                format!("must be in [0, 1], got {}", o.epsilon),
            ));
        }
        require_non_negative("outlier_min", o.min_magnitude)?;
        require_non_negative("outlier_max", o.max_magnitude)?;
        if o.max_magnitude < o.min_magnitude {
            return Err(ParameterError::new(
                "outlier_max",
                format!(
                    "must be >= outlier_min = {}, got {}",
                    o.min_magnitude, o.max_magnitude
                ),
            ));
        }
        require_finite("outlier_t_start", o.window_start)?;
        if o.window_end.is_nan() || o.window_end < o.window_start {
            return Err(ParameterError::new(
                "outlier_t_end",
                format!(
                    "must be >= outlier_t_start = {} (or +inf), got {}",
                    o.window_start, o.window_end
                ),
            ));
        }
        if let Some(q) = &self.quantiser {
            q.validate()?;
        }
        let variance = self.noise_variance();
        if !variance.is_finite() {
            return Err(ParameterError::new(
                "snr_db",
                format!("gives a non-finite noise variance {variance}"),
            ));
        }
        Ok(())
    }

    /// The noise variance σ² the parameters mean (module docs for the SNR conversion).
    pub fn noise_variance(&self) -> f64 {
        match self.noise {
            NoiseLevel::Variance(v) => v,
            NoiseLevel::SignalToNoiseRatio {
                snr_db,
                signal_power,
            } => signal_power / 10f64.powf(snr_db / 10.0),
        }
    }
}

/// One sample of the channel.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SensorReading {
    /// What the acquisition delivers: noise, outlier and quantisation applied.
    pub measured: f64,
    /// The clean value that went in (for scoring).
    pub clean: f64,
    /// Whether this sample carries an outlier.
    pub outlier: bool,
}

/// One sensor channel with its random streams (module docs).
#[derive(Debug, Clone, PartialEq)]
pub struct Sensor {
    parameters: SensorParameters,
    noise_deviation: f64,
    noise_stream: RandomGenerator,
    outlier_stream: RandomGenerator,
}

impl Sensor {
    /// A channel after checking its parameters, with its streams at the start of `seed`.
    pub fn new(parameters: SensorParameters) -> Result<Self, ParameterError> {
        parameters.validate()?;
        Ok(Self {
            noise_deviation: parameters.noise_variance().sqrt(),
            noise_stream: RandomGenerator::for_stream(parameters.seed, 0),
            outlier_stream: RandomGenerator::for_stream(parameters.seed, 1),
            parameters,
        })
    }

    /// The parameters the channel was built with.
    pub fn parameters(&self) -> &SensorParameters {
        &self.parameters
    }

    /// The noise variance in use.
    pub fn noise_variance(&self) -> f64 {
        self.noise_deviation * self.noise_deviation
    }

    /// Samples the channel at time `t` for the clean value `clean` (one draw of each stream).
    pub fn measure(&mut self, t: f64, clean: f64) -> SensorReading {
        let noise = self.noise_deviation * self.noise_stream.gaussian();
        let o = &self.parameters.outliers;
        let decision = self.outlier_stream.uniform();
        let magnitude = self
            .outlier_stream
            .uniform_range(o.min_magnitude, o.max_magnitude);
        let sign = if self.outlier_stream.uniform() < 0.5 {
            -1.0
        } else {
            1.0
        };
        let in_window = t >= o.window_start && t < o.window_end;
        let outlier = in_window && decision < o.epsilon;
        let mut measured = clean + noise;
        if outlier {
            measured += sign * magnitude;
        }
        if let Some(q) = &self.parameters.quantiser {
            measured = q.quantise(measured);
        }
        SensorReading {
            measured,
            clean,
            outlier,
        }
    }

    /// The random streams' state (noise stream, then outlier stream), for saving.
    pub fn state(&self) -> [u64; 8] {
        let n = self.noise_stream.state();
        let o = self.outlier_stream.state();
        [n[0], n[1], n[2], n[3], o[0], o[1], o[2], o[3]]
    }

    /// Restores a saved [`Self::state`]; the channel then continues bit-for-bit.
    pub fn restore_state(&mut self, state: [u64; 8]) -> Result<(), ParameterError> {
        let noise = RandomGenerator::from_state([state[0], state[1], state[2], state[3]])?;
        let outlier = RandomGenerator::from_state([state[4], state[5], state[6], state[7]])?;
        self.noise_stream = noise;
        self.outlier_stream = outlier;
        Ok(())
    }
}

// FMU-state snapshots (plain bytes) of the types above: every field, in order.
crate::plain_state!(enum NoiseLevel { Variance(v0), SignalToNoiseRatio { snr_db, signal_power } });
crate::plain_state!(OutlierParameters {
    epsilon,
    min_magnitude,
    max_magnitude,
    window_start,
    window_end
});
crate::plain_state!(Quantiser { bits, min, max });
crate::plain_state!(SensorParameters {
    noise,
    outliers,
    quantiser,
    seed
});
crate::plain_state!(Sensor {
    parameters,
    noise_deviation,
    noise_stream,
    outlier_stream
});

#[cfg(test)]
mod tests {
    use super::*;

    fn sensor(noise: NoiseLevel, epsilon: f64) -> Sensor {
        Sensor::new(SensorParameters {
            noise,
            outliers: OutlierParameters {
                epsilon,
                ..Default::default()
            },
            quantiser: None,
            seed: 12345,
        })
        .unwrap()
    }

    #[test]
    fn outlier_fraction_and_noise_variance_match_the_settings() {
        let n = 100_000;
        let epsilon = 0.05;
        let variance = 0.01;
        let mut s = sensor(NoiseLevel::Variance(variance), epsilon);
        let (mut outliers, mut sum, mut sum2, mut clean_count) = (0usize, 0.0, 0.0, 0usize);
        for k in 0..n {
            let clean = (k as f64 * 0.01).cos();
            let r = s.measure(k as f64, clean);
            if r.outlier {
                outliers += 1;
                assert!((r.measured - clean).abs() > 0.0);
            } else {
                let e = r.measured - clean;
                sum += e;
                sum2 += e * e;
                clean_count += 1;
            }
        }
        let fraction = outliers as f64 / n as f64;
        let sigma = (epsilon * (1.0 - epsilon) / n as f64).sqrt();
        assert!(
            (fraction - epsilon).abs() < 3.0 * sigma,
            "outlier fraction {fraction}"
        );
        let mean = sum / clean_count as f64;
        let var = sum2 / clean_count as f64 - mean * mean;
        eprintln!(
            "outlier fraction {fraction} (3σ = {}), noise variance {var}",
            3.0 * sigma
        );
        assert!(
            ((var - variance) / variance).abs() < 0.02,
            "noise variance {var}"
        );
    }

    #[test]
    fn snr_in_db_sets_the_variance_from_the_signal_power() {
        let mut s = sensor(
            NoiseLevel::SignalToNoiseRatio {
                snr_db: 20.0,
                signal_power: 0.5,
            },
            0.0,
        );
        assert!((s.noise_variance() - 0.005).abs() < 1e-15);
        let n = 100_000;
        let mut sum2 = 0.0;
        for k in 0..n {
            let r = s.measure(k as f64, 1.0);
            assert!(!r.outlier);
            sum2 += (r.measured - 1.0).powi(2);
        }
        let var = sum2 / n as f64;
        eprintln!("SNR 20 dB noise variance {var}");
        assert!(((var - 0.005) / 0.005).abs() < 0.02, "variance {var}");
    }

    #[test]
    fn same_seed_gives_identical_readings_and_state_restores() {
        let mut a = sensor(NoiseLevel::Variance(0.1), 0.2);
        let mut b = a.clone();
        for k in 0..1000 {
            let (ra, rb) = (a.measure(k as f64, 0.3), b.measure(k as f64, 0.3));
            assert_eq!(ra.measured.to_bits(), rb.measured.to_bits());
            assert_eq!(ra.outlier, rb.outlier);
        }
        let saved = a.state();
        let first: Vec<f64> = (0..50).map(|k| a.measure(k as f64, 0.0).measured).collect();
        let mut c = sensor(NoiseLevel::Variance(0.1), 0.2);
        c.restore_state(saved).unwrap();
        let again: Vec<f64> = (0..50).map(|k| c.measure(k as f64, 0.0).measured).collect();
        assert_eq!(first, again);
        assert_eq!(c.restore_state([0; 8]).unwrap_err().parameter, "rng_state");
    }

    #[test]
    fn outlier_positions_do_not_depend_on_the_noise_level() {
        let mut quiet = sensor(NoiseLevel::Variance(0.0), 0.05);
        let mut noisy = sensor(NoiseLevel::Variance(1.0), 0.05);
        for k in 0..5000 {
            assert_eq!(
                quiet.measure(k as f64, 0.0).outlier,
                noisy.measure(k as f64, 0.0).outlier
            );
        }
    }

    #[test]
    fn outliers_stay_in_their_window_and_magnitude_range() {
        let mut s = Sensor::new(SensorParameters {
            noise: NoiseLevel::Variance(0.0),
            outliers: OutlierParameters {
                epsilon: 0.5,
                min_magnitude: 2.0,
                max_magnitude: 3.0,
                window_start: 0.0,
                window_end: 500.0,
            },
            quantiser: None,
            seed: 9,
        })
        .unwrap();
        let mut inside = 0;
        for k in 0..1000 {
            let r = s.measure(k as f64, 1.0);
            if k >= 500 {
                assert!(!r.outlier);
                assert_eq!(r.measured, 1.0);
            } else if r.outlier {
                inside += 1;
                let m = (r.measured - 1.0).abs();
                assert!((2.0..=3.0).contains(&m), "magnitude {m}");
            }
        }
        assert!(inside > 200);
    }

    #[test]
    fn quantisation_step_is_range_over_two_to_the_bits() {
        let q = Quantiser {
            bits: 12,
            min: 0.0,
            max: 3.3,
        };
        let step = 3.3 / 4096.0;
        assert_eq!(q.step(), step);
        let mut s = Sensor::new(SensorParameters {
            noise: NoiseLevel::Variance(0.0),
            outliers: OutlierParameters {
                epsilon: 0.0,
                ..Default::default()
            },
            quantiser: Some(q),
            seed: 3,
        })
        .unwrap();
        for k in 0..1000 {
            let v = 0.2 + 2.9 * k as f64 / 1000.0;
            let y = s.measure(0.0, v).measured;
            let code = y / step;
            assert!((code - code.round()).abs() < 1e-9);
            assert!((y - v).abs() <= 0.5 * step + 1e-12);
        }
        assert_eq!(s.measure(0.0, -5.0).measured, 0.0);
        assert_eq!(s.measure(0.0, 50.0).measured, 3.3 - step);
        // A value between two codes moves by exactly one step.
        assert!((q.quantise(1.0 + step) - q.quantise(1.0) - step).abs() < 1e-12);
    }

    #[test]
    fn bad_parameters_are_named() {
        let base = SensorParameters::default();
        let check = |p: SensorParameters, name: &str| {
            assert_eq!(Sensor::new(p).unwrap_err().parameter, name);
        };
        check(
            SensorParameters {
                noise: NoiseLevel::Variance(-1.0),
                ..base
            },
            "variance",
        );
        check(
            SensorParameters {
                noise: NoiseLevel::SignalToNoiseRatio {
                    snr_db: f64::NAN,
                    signal_power: 1.0,
                },
                ..base
            },
            "snr_db",
        );
        check(
            SensorParameters {
                noise: NoiseLevel::SignalToNoiseRatio {
                    snr_db: 10.0,
                    signal_power: -1.0,
                },
                ..base
            },
            "signal_power",
        );
        let mut p = base;
        p.outliers.epsilon = 1.5;
        check(p, "epsilon");
        let mut p = base;
        p.outliers.min_magnitude = 5.0;
        check(p, "outlier_max");
        let mut p = base;
        p.outliers.window_end = -1.0;
        check(p, "outlier_t_end");
        let mut p = base;
        p.quantiser = Some(Quantiser {
            bits: 0,
            min: 0.0,
            max: 1.0,
        });
        check(p, "bits");
        p.quantiser = Some(Quantiser {
            bits: 8,
            min: 1.0,
            max: 1.0,
        });
        check(p, "adc_max");
    }
}
