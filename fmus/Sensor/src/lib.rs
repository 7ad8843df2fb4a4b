//! `Sensor.fmu`: measurement channels with Gaussian noise, ε-contaminated outliers and an
//! optional ADC (docs/models.md §2.6; the outlier model of papers 000 §VII-A and 001 §5, the
//! 12-bit acquisition of paper 002 §III) as an FMI 2.0 CS FMU.
//!
//! Configuration key `channels` (default 1) sets the number of channels `N`. Channel `i`
//! (1-based) has the input `u[i]` (the clean signal) and the outputs
//!
//! ```text
//! y[i]       = Q( u[i] + σᵢ nᵢ + oᵢ )     measured value        (depends directly on u[i])
//! y_clean[i] = u[i]                        clean value, for scoring
//! outlier[i] = (oᵢ ≠ 0)                    whether this sample carries an outlier
//! ```
//!
//! with the noise, outlier and quantiser of [`spurio::signals::sensor`]: `nᵢ ~ N(0, 1)`,
//! `σᵢ² = variance[i]` or, when `use_snr[i]`, `σᵢ² = signal_power[i] / 10^(snr_db[i]/10)`;
//! `oᵢ = ±U[outlier_min[i], outlier_max[i]]` with probability `epsilon[i]` (only inside
//! `[outlier_t_start[i], outlier_t_end[i])` when `outlier_window[i]`); `Q` an ideal
//! `adc_bits[i]`-bit ADC on `[adc_min[i], adc_max[i]]` (no quantisation when `adc_bits[i] = 0`).
//!
//! **Sampling.** The sensor samples on its own clock ([`spurio_fmu_common::clock`], rule
//! `Point`): at the
//! instants `t_k = t_0 + k·T` (`T` = the parameter `sample_period`; 0, the default, takes the
//! size of the first step), sample 0 at initialisation, sample `k` when a step's end reaches
//! `t_k` within a relative tolerance of 10⁻⁹ (with the input held over the step; the outlier
//! window is tested at `t_k`). A step that reaches no instant (shorter than `T`, or a
//! master's rounding step of 10⁻¹⁵ s) holds `y`, `y_clean` and `outlier`; a step reaching
//! several instants draws each of them (at most 10 000) and shows the last. With a fixed-step
//! master and the default, every communication point is one sample. The noise and outlier
//! draw of a sample is made once; if the master sets `u` again at the point of the last
//! sample (direct feedthrough), `y` is recomputed with the same draw (the channel's random
//! streams are rewound to the state before the draw), so reading the outputs any number of
//! times gives one sample; between samples the outputs hold whatever `u` is set to.
//!
//! **Seeds.** One Integer parameter `seed` ≥ 0; channel `i` uses the 64-bit seed
//! `seed + (i − 1)·2³²`, so every (seed, channel) pair has its own independent streams and the
//! one-channel FMU is exactly [`Sensor`] with seed `seed`.

use spurio::signals::sensor::{
    NoiseLevel, OutlierParameters, Quantiser, Sensor, SensorParameters, SensorReading,
};
use spurio_export::{
    Cause, Config, Context, DefaultExperiment, Failure, FmuModel, ModelInfo, Variable,
    VariableTable,
};
use spurio_fmu_common::clock::{self, Rule, SampleClock};
use spurio_fmu_common::param_failure;
use spurio_fmu_common::structured::{add_vector, Block};

/// Largest number of channels a variant may have.
pub const MAX_CHANNELS: usize = 256;

/// Where each per-channel variable block starts (value references).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Layout {
    /// Number of channels.
    pub channels: usize,
    pub u: Block,
    pub y: Block,
    pub y_clean: Block,
    pub outlier: Block,
    pub variance: Block,
    pub use_snr: Block,
    pub snr_db: Block,
    pub signal_power: Block,
    pub epsilon: Block,
    pub outlier_min: Block,
    pub outlier_max: Block,
    pub outlier_window: Block,
    pub outlier_t_start: Block,
    pub outlier_t_end: Block,
    pub adc_bits: Block,
    pub adc_min: Block,
    pub adc_max: Block,
    /// Value reference of `seed`.
    pub seed: usize,
    /// Value reference of `sample_period`.
    pub sample_period: usize,
}

/// Number of channels of a configuration (`channels`, default 1).
pub fn channels(config: &Config) -> Result<usize, Cause> {
    let n = config.dimension("channels", 1)?;
    if n > MAX_CHANNELS {
        return Err(format!("`channels` must be at most {MAX_CHANNELS}, got {n}").into());
    }
    Ok(n)
}

/// The variable table and its layout for `n` channels.
pub fn table(n: usize) -> (Vec<Variable>, Layout) {
    let d = SensorParameters::default();
    let o = OutlierParameters::default();
    let mut t = VariableTable::new();
    let u = add_vector(&mut t, "u", n, |name, _| {
        Variable::input(name, 0.0).describe("Clean signal to be measured")
    });
    let y = add_vector(&mut t, "y", n, |name, i| {
        Variable::discrete_output(name)
            .describe("Measured value: u + noise + outlier, quantised when adc_bits > 0")
            .depends_on(&[u.first + i])
    });
    let y_clean = add_vector(&mut t, "y_clean", n, |name, i| {
        Variable::discrete_output(name)
            .describe("Clean value (the input at the last sample instant), for scoring")
            .depends_on(&[u.first + i])
    });
    let outlier = add_vector(&mut t, "outlier", n, |name, _| {
        Variable::boolean_output(name).describe("Whether this sample carries an outlier")
    });
    let variance = add_vector(&mut t, "variance", n, |name, _| {
        Variable::parameter(name, 0.01).min(0.0).describe(
            "Noise variance σ² (signal unit squared), used when use_snr is false; 0.01 in the experiments of the papers",
        )
    });
    let use_snr = add_vector(&mut t, "use_snr", n, |name, _| {
        Variable::boolean_parameter(name, false)
            .describe("Noise level from snr_db and signal_power (true) instead of variance (false)")
    });
    let snr_db = add_vector(&mut t, "snr_db", n, |name, _| {
        Variable::parameter(name, 20.0)
            .describe("Signal-to-noise ratio [dB]: σ² = signal_power / 10^(snr_db/10)")
    });
    let signal_power = add_vector(&mut t, "signal_power", n, |name, _| {
        Variable::parameter(name, 0.5)
            .min(0.0)
            .describe("Mean square of the clean signal for the SNR (0.5 for a unit-amplitude sine)")
    });
    let epsilon = add_vector(&mut t, "epsilon", n, |name, _| {
        Variable::parameter(name, o.epsilon)
            .describe("Outlier fraction ε in [0, 1] (default 0.05: 5 % contamination)")
    });
    let outlier_min = add_vector(&mut t, "outlier_min", n, |name, _| {
        Variable::parameter(name, o.min_magnitude)
            .describe("Smallest outlier magnitude (signal unit)")
    });
    let outlier_max = add_vector(&mut t, "outlier_max", n, |name, _| {
        Variable::parameter(name, o.max_magnitude).describe(
            "Largest outlier magnitude; 0 to 4.8 gives the U(-4.8, 4.8) spikes of the cosine experiment of papers 000 and 001",
        )
    });
    let outlier_window = add_vector(&mut t, "outlier_window", n, |name, _| {
        Variable::boolean_parameter(name, false).describe(
            "Outliers only for outlier_t_start <= t < outlier_t_end (true), or at all times (false)",
        )
    });
    let outlier_t_start = add_vector(&mut t, "outlier_t_start", n, |name, _| {
        Variable::parameter(name, 0.0)
            .unit("s")
            .describe("Start of the outlier window")
    });
    let outlier_t_end = add_vector(&mut t, "outlier_t_end", n, |name, _| {
        Variable::parameter(name, 50.0)
            .unit("s")
            .describe("End of the outlier window (paper 001: the first 500 samples of 0.1 s)")
    });
    let adc_bits = add_vector(&mut t, "adc_bits", n, |name, _| {
        Variable::integer_parameter(name, 0)
            .min(0.0)
            .max(32.0)
            .describe("ADC resolution in bits, 1 to 32; 0 = no quantisation (paper 002: 12)")
    });
    let adc_min = add_vector(&mut t, "adc_min", n, |name, _| {
        Variable::parameter(name, -10.0).describe("Lower end of the ADC input range")
    });
    let adc_max = add_vector(&mut t, "adc_max", n, |name, _| {
        Variable::parameter(name, 10.0).describe("Upper end of the ADC input range")
    });
    let seed = t.add(
        Variable::integer_parameter("seed", d.seed as i32)
            .min(0.0)
            .describe("Seed of the random streams; channel i uses seed + (i-1)·2^32"),
    );
    let sample_period = t.add(clock::parameter());
    let layout = Layout {
        channels: n,
        u,
        y,
        y_clean,
        outlier,
        variance,
        use_snr,
        snr_db,
        signal_power,
        epsilon,
        outlier_min,
        outlier_max,
        outlier_window,
        outlier_t_start,
        outlier_t_end,
        adc_bits,
        adc_min,
        adc_max,
        seed,
        sample_period,
    };
    (t.into_variables(), layout)
}

/// One channel: its sensor and the state of its streams before the current point's draw.
#[derive(Debug, Clone)]
struct Channel {
    sensor: Sensor,
    before: [u64; 8],
}
spurio::plain_state!(Channel { sensor, before });

/// The Sensor FMU.
#[derive(Debug, Clone)]
pub struct SensorFmu {
    layout: Layout,
    channels: Vec<Channel>,
    clock: SampleClock,
}

impl SensorFmu {
    /// The parameters of channel `i` (0-based) from the values.
    fn channel_parameters(&self, ctx: &Context, i: usize) -> Result<SensorParameters, Failure> {
        let l = &self.layout;
        let v = &ctx.values;
        let real = |b: &Block| v.real(b.first + i);
        let noise = if v.boolean(l.use_snr.first + i) {
            NoiseLevel::SignalToNoiseRatio {
                snr_db: real(&l.snr_db),
                signal_power: real(&l.signal_power),
            }
        } else {
            NoiseLevel::Variance(real(&l.variance))
        };
        let windowed = v.boolean(l.outlier_window.first + i);
        let outliers = OutlierParameters {
            epsilon: real(&l.epsilon),
            min_magnitude: real(&l.outlier_min),
            max_magnitude: real(&l.outlier_max),
            window_start: if windowed {
                real(&l.outlier_t_start)
            } else {
                f64::MIN
            },
            window_end: if windowed {
                real(&l.outlier_t_end)
            } else {
                f64::INFINITY
            },
        };
        let bits = v.integer(l.adc_bits.first + i);
        let quantiser = match bits {
            0 => None,
            b if b < 0 => {
                return Err(Failure::error(format!(
                    "parameter `adc_bits[{}]`: must be 0 (off) or 1 to 32, got {b}",
                    i + 1
                )))
            }
            b => Some(Quantiser {
                bits: b as u32,
                min: real(&l.adc_min),
                max: real(&l.adc_max),
            }),
        };
        let seed = v.integer(l.seed);
        if seed < 0 {
            return Err(Failure::error(format!(
                "parameter `seed`: must be >= 0, got {seed}"
            )));
        }
        Ok(SensorParameters {
            noise,
            outliers,
            quantiser,
            seed: seed as u64 + ((i as u64) << 32),
        })
    }

    fn write(&self, ctx: &mut Context, i: usize, r: SensorReading) {
        ctx.values.set_real(self.layout.y.first + i, r.measured);
        ctx.values.set_real(self.layout.y_clean.first + i, r.clean);
        ctx.values
            .set_boolean(self.layout.outlier.first + i, r.outlier);
    }

    /// A fresh draw for every channel at time `t` with the current inputs.
    fn sample(&mut self, ctx: &mut Context, t: f64) {
        for i in 0..self.channels.len() {
            let u = ctx.values.real(self.layout.u.first + i);
            let c = &mut self.channels[i];
            c.before = c.sensor.state();
            let r = c.sensor.measure(t, u);
            self.write(ctx, i, r);
        }
    }
}

/// The measured-value names of the parameters the `spurio` sensor reports, mapped to the
/// FMU's variables of channel `i` (0-based).
fn channel_name(parameter: &str, i: usize) -> String {
    let name = match parameter {
        "bits" => "adc_bits",
        other => other,
    };
    if name == "seed" {
        name.to_string()
    } else {
        format!("{name}[{}]", i + 1)
    }
}

impl FmuModel for SensorFmu {
    fn describe(config: &Config) -> Result<ModelInfo, Cause> {
        let n = channels(config)?;
        let (variables, _) = table(n);
        Ok(ModelInfo::new(
            "Sensor",
            "Measurement channels with Gaussian noise, epsilon-contaminated outliers and an optional ADC",
            variables,
            Some(DefaultExperiment {
                start_time: 0.0,
                stop_time: 100.0,
                step_size: 0.1,
            }),
            config.clone(),
        ))
    }

    fn create(info: &ModelInfo) -> Result<Self, Cause> {
        let n = channels(&info.config)?;
        let (_, layout) = table(n);
        Ok(Self {
            layout,
            channels: Vec::new(),
            clock: SampleClock::new(Rule::Point, 0.0, 0.0)?,
        })
    }

    fn initialize(&mut self, ctx: &mut Context) -> Result<(), Failure> {
        let mut channels = Vec::with_capacity(self.layout.channels);
        for i in 0..self.layout.channels {
            let parameters = self.channel_parameters(ctx, i)?;
            let sensor = Sensor::new(parameters).map_err(|e| {
                Failure::error(format!(
                    "parameter `{}`: {}",
                    channel_name(&e.parameter, i),
                    e.reason
                ))
            })?;
            channels.push(Channel {
                before: sensor.state(),
                sensor,
            });
        }
        let t = ctx.time();
        let period = self.layout.sample_period;
        self.clock = SampleClock::from_parameter(Rule::Point, ctx.values, period, t)?;
        self.channels = channels;
        self.sample(ctx, t);
        Ok(())
    }

    fn do_step(&mut self, ctx: &mut Context, time: f64, step: f64) -> Result<(), Failure> {
        let (clock, samples) = self.clock.after(time, step)?;
        for k in samples {
            self.sample(ctx, clock.instant(k));
        }
        self.clock = clock;
        Ok(())
    }

    /// At the point of the last sample: the same draw with the inputs just set; between
    /// samples: nothing (the outputs hold).
    fn update_outputs(&mut self, ctx: &mut Context) -> Result<(), Failure> {
        let Some(k) = self.clock.sample_at(ctx.time()) else {
            return Ok(());
        };
        let t = self.clock.instant(k);
        for i in 0..self.channels.len() {
            let u = ctx.values.real(self.layout.u.first + i);
            let c = &mut self.channels[i];
            c.sensor
                .restore_state(c.before)
                .map_err(|e| param_failure(&e))?;
            let r = c.sensor.measure(t, u);
            self.write(ctx, i, r);
        }
        Ok(())
    }

    spurio_fmu_common::fmu_state!(channels, clock);
}

spurio_export::export_fmu!(
    SensorFmu,
    variants = [
        ("Sensor", Config::new()),
        ("Sensor2", spurio_fmu_common::config(&[("channels", "2")])),
    ]
);

#[cfg(test)]
mod tests {
    use super::*;
    use spurio_export::harness::Harness;

    fn two_channels() -> Config {
        let mut c = Config::new();
        c.set("channels", 2);
        c
    }

    #[test]
    fn layout_names_match_the_table() {
        let (v, l) = table(2);
        assert_eq!(v[l.u.first + 1].name, "u[2]");
        assert_eq!(v[l.y.first].name, "y[1]");
        assert_eq!(v[l.outlier.first + 1].name, "outlier[2]");
        assert_eq!(v[l.adc_max.first + 1].name, "adc_max[2]");
        assert_eq!(v[l.seed].name, "seed");
        assert_eq!(v[l.sample_period].name, "sample_period");
        assert_eq!(v.len(), l.sample_period + 1);
    }

    /// `y[1]` of the one-channel sensor (u = 1) after each step, `sample_period` = `period`.
    fn measured(period: f64, steps: &[(f64, f64)]) -> Vec<f64> {
        let (_, l) = table(1);
        let mut h = Harness::<SensorFmu>::new(&Config::new()).unwrap();
        let (u, y) = (l.u.first as u32, l.y.first as u32);
        h.set_real(&[u, l.sample_period as u32], &[1.0, period])
            .unwrap();
        h.initialize(steps[0].0).unwrap();
        steps
            .iter()
            .map(|&(t, step)| {
                h.do_step(t, step).unwrap();
                h.real(y).unwrap()
            })
            .collect()
    }

    #[test]
    fn samples_are_taken_on_the_clock_whatever_the_steps() {
        let exact: Vec<(f64, f64)> = (0..6).map(|k| (k as f64 * 0.1, 0.1)).collect();
        let at_period = measured(0.1, &exact);
        assert!(at_period.windows(2).all(|w| w[0] != w[1]), "{at_period:?}");
        assert_eq!(measured(0.0, &exact), at_period);
        // Half periods: the same samples, each held over two points.
        let half: Vec<(f64, f64)> = (0..12).map(|k| (k as f64 * 0.05, 0.05)).collect();
        let held = measured(0.1, &half);
        for k in 0..6 {
            assert_eq!(held[2 * k + 1], at_period[k], "sample {}", k + 1);
            let before = if k == 0 { held[0] } else { at_period[k - 1] };
            assert_eq!(held[2 * k], before, "held before sample {}", k + 1);
        }
        // Three periods per step: the third sample of each step is shown.
        let long = measured(0.1, &[(0.0, 0.3), (0.3, 0.3)]);
        assert_eq!(long, [at_period[2], at_period[5]]);
        // Time accumulated by addition and a last step of ~1e-15 s: no extra draw.
        let mut steps = Vec::new();
        let mut t = 0.0;
        for _ in 0..6 {
            steps.push((t, 0.1));
            t += 0.1;
        }
        steps.push((t, 0.6 - t + 1.8e-15));
        let accumulated = measured(0.1, &steps);
        assert_eq!(accumulated[..6], at_period[..]);
        assert_eq!(accumulated[6], at_period[5]);
    }

    #[test]
    fn between_samples_the_outputs_hold_whatever_the_input() {
        let (_, l) = table(1);
        let mut h = Harness::<SensorFmu>::new(&Config::new()).unwrap();
        let (u, y, clean) = (l.u.first as u32, l.y.first as u32, l.y_clean.first as u32);
        h.set_real(&[l.sample_period as u32], &[0.1]).unwrap();
        h.initialize(0.0).unwrap();
        h.set_real(&[u], &[1.0]).unwrap();
        h.do_step(0.0, 0.05).unwrap();
        let first = h.real(y).unwrap();
        h.set_real(&[u], &[5.0]).unwrap();
        assert_eq!((h.real(y).unwrap(), h.real(clean).unwrap()), (first, 0.0));
        h.do_step(0.05, 0.05).unwrap();
        // At the sample instant the input just set is measured, and setting it again there
        // recomputes the same draw.
        let sampled = h.real(y).unwrap();
        assert_eq!(h.real(clean).unwrap(), 5.0);
        h.set_real(&[u], &[6.0]).unwrap();
        assert!((h.real(y).unwrap() - sampled - 1.0).abs() < 1e-12);
        assert_eq!(h.real(clean).unwrap(), 6.0);
    }

    #[test]
    fn outputs_are_one_sample_per_point_and_channels_differ() {
        let (_, l) = table(2);
        let mut h = Harness::<SensorFmu>::new(&two_channels()).unwrap();
        h.initialize(0.0).unwrap();
        let vr = |b: &Block, i: usize| (b.first + i) as u32;
        let inputs = [vr(&l.u, 0), vr(&l.u, 1)];
        let outputs = [
            vr(&l.y, 0),
            vr(&l.y, 1),
            vr(&l.y_clean, 0),
            vr(&l.y_clean, 1),
        ];
        // y[1], y[2], y_clean[1], y_clean[2] with both inputs at `u`.
        let read_at = |h: &mut Harness<SensorFmu>, u: f64| {
            let mut read = [0.0; 4];
            h.set_real(&inputs, &[u, u]).unwrap();
            h.get_real(&outputs, &mut read).unwrap();
            read
        };
        for k in 0..20 {
            let first = read_at(&mut h, 1.0);
            // Set the inputs again at the same point: same draw, shifted by the input change.
            let again = read_at(&mut h, 3.0);
            assert_eq!(again[2], 3.0);
            for c in 0..2 {
                let moved = again[c] - first[c];
                assert!((moved - 2.0).abs() < 1e-12, "point {k}: moved {moved}");
            }
            assert_ne!(first[0], first[1]);
            h.do_step(k as f64 * 0.1, 0.1).unwrap();
        }
    }
}
