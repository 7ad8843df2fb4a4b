//! `SignalSource.fmu`: the excitation signals of the experiments (docs/models.md §2.5; paper 001 §5
//! random steps, paper 002 §III the unit step, papers 000/001 the cosine) as an FMI 2.0 CS FMU.
//!
//! Integer parameter `waveform` (an enumeration, Integer because fmpy's SSP runner has no
//! String variables):
//!
//! ```text
//! 1 step          y = offset + amplitude · [t ≥ step_time]
//! 2 random steps  y = L_k on [t_k, t_k+1), L_k ~ U[offset − amplitude, offset + amplitude],
//!                 t_k+1 − t_k ~ U[min_hold, max_hold]            (seeded)
//! 3 PRBS          y = offset ± amplitude, one bit of a maximum-length LFSR of order
//!                 prbs_order per bit_period; the seed sets the register's start
//! 4 sine          y = offset + amplitude · sin(2π t/period + phase)
//! 5 cosine        y = offset + amplitude · cos(2π t/period + phase)
//! ```
//!
//! (definitions in [`spurio::signals::source`]; time origin t = 0 whatever the start time).
//! Only the parameters of the chosen waveform are checked. The output `y` at a communication
//! point `t` is the signal at `t`: at the start time after initialisation and at `t + h`
//! after each step, so a master that connects `y` to another FMU's input at each
//! communication point feeds it the signal sampled there.
//!
//! Bounded work: the times and levels have declared ranges (periods and holds of 10⁻⁹ s or
//! 10⁻⁶ s to 10¹² s, levels within ±10¹⁵), a PRBS sample skips whole periods of the register,
//! and a random-steps sample that would draw more than
//! [`spurio::signals::source::MAX_SEGMENTS_PER_SAMPLE`] holds (a start time of 10¹² s with
//! holds of seconds) is an error naming the time, not a hang.

use spurio::signals::source::{
    frequency_from_period, Prbs, RandomSteps, SignalSource, Sinusoid, Step, Trig, Waveform,
};
use spurio::ParameterError;
use spurio_export::rows::parameter;
use spurio_export::{
    Cause, Config, Context, DefaultExperiment, Failure, FmuModel, ModelInfo, Variable,
};

/// `waveform` codes.
pub mod waveform {
    pub const STEP: i32 = 1;
    pub const RANDOM_STEPS: i32 = 2;
    pub const PRBS: i32 = 3;
    pub const SINE: i32 = 4;
    pub const COSINE: i32 = 5;
}

/// The largest |amplitude| and |offset| (declared range).
const LEVEL: f64 = 1e15;

spurio_export::declare_variables! {
    /// The variable table, in value-reference order.
    pub fn variables() {
        table: [
            Y = Variable::discrete_output("y").describe("The signal at the current communication point"),
            WAVEFORM = Variable::integer_parameter("waveform", waveform::STEP)
                .min(1.0)
                .max(5.0)
                .describe("1 step, 2 random steps, 3 PRBS, 4 sine, 5 cosine"),
            AMPLITUDE = Variable::parameter("amplitude", 1.0).min(-LEVEL).max(LEVEL).describe(
                "Step height; half-width of the random levels (>= 0); PRBS half swing; sine/cosine amplitude",
                ),
            OFFSET = Variable::parameter("offset", 0.0)
                .min(-LEVEL)
                .max(LEVEL)
                .describe("Level before the step; centre of the random levels, PRBS and sine/cosine"),
            PERIOD = parameter("period", 1.0, "s", "Period of the sine/cosine (> 0)").min(1e-9).max(1e12),
            PHASE = parameter("phase", 0.0, "rad", "Phase of the sine/cosine").min(-1e6).max(1e6),
            STEP_TIME = parameter("step_time", 1.0, "s", "Time of the step").min(-1e15).max(1e15),
            MIN_HOLD = parameter("min_hold", 1.0, "s", "Shortest hold of a random step (> 0)").min(1e-6).max(1e12),
            MAX_HOLD = parameter("max_hold", 5.0, "s", "Longest hold of a random step (>= min_hold)").min(1e-6).max(1e12),
            PRBS_ORDER = Variable::integer_parameter("prbs_order", 7)
                .min(2.0)
                .max(24.0)
                .describe("PRBS register length n, 2 to 24 (period 2^n - 1 bits)"),
            BIT_PERIOD = parameter("bit_period", 0.1, "s", "Duration of one PRBS bit (> 0)").min(1e-9).max(1e12),
            SEED = Variable::integer_parameter("seed", 1)
                .min(0.0)
                .describe("Seed of the random steps and of the PRBS start register"),
        ]
    }
}

/// The SignalSource FMU.
#[derive(Debug, Clone)]
pub struct SignalSourceFmu {
    source: Option<SignalSource>,
}

fn named(e: ParameterError) -> Failure {
    let parameter = match e.parameter.as_str() {
        "order" => "prbs_order",
        other => other,
    };
    Failure::error(format!("parameter `{parameter}`: {}", e.reason))
}

/// The waveform the parameters describe.
fn read_waveform(ctx: &Context) -> Result<(Waveform, u64), Failure> {
    let v = &ctx.values;
    let amplitude = v.real(vr::AMPLITUDE);
    let offset = v.real(vr::OFFSET);
    let seed = v.integer(vr::SEED);
    if seed < 0 {
        return Err(Failure::error(format!(
            "parameter `seed`: must be >= 0, got {seed}"
        )));
    }
    let periodic = |function: Trig| -> Result<Waveform, Failure> {
        Ok(Waveform::Sinusoid(Sinusoid {
            function,
            amplitude,
            offset,
            frequency: frequency_from_period(v.real(vr::PERIOD)).map_err(named)?,
            phase: v.real(vr::PHASE),
        }))
    };
    let w = match v.integer(vr::WAVEFORM) {
        waveform::STEP => Waveform::Step(Step {
            amplitude,
            offset,
            step_time: v.real(vr::STEP_TIME),
        }),
        waveform::RANDOM_STEPS => Waveform::RandomSteps(RandomSteps {
            amplitude,
            offset,
            min_hold: v.real(vr::MIN_HOLD),
            max_hold: v.real(vr::MAX_HOLD),
        }),
        waveform::PRBS => {
            let order = v.integer(vr::PRBS_ORDER);
            if !(2..=24).contains(&order) {
                return Err(Failure::error(format!(
                    "parameter `prbs_order`: must be between 2 and 24, got {order}"
                )));
            }
            Waveform::Prbs(Prbs {
                order: order as u32,
                bit_period: v.real(vr::BIT_PERIOD),
                amplitude,
                offset,
            })
        }
        waveform::SINE => periodic(Trig::Sine)?,
        waveform::COSINE => periodic(Trig::Cosine)?,
        other => {
            return Err(Failure::error(format!(
                "parameter `waveform`: must be 1 (step), 2 (random steps), 3 (PRBS), 4 (sine) or 5 (cosine), got {other}"
            )))
        }
    };
    Ok((w, seed as u64))
}

impl FmuModel for SignalSourceFmu {
    fn describe(_config: &Config) -> Result<ModelInfo, Cause> {
        Ok(ModelInfo::new(
            "SignalSource",
            "Excitation signals: step, random steps, PRBS, sine, cosine (seeded)",
            variables(),
            Some(DefaultExperiment {
                start_time: 0.0,
                stop_time: 10.0,
                step_size: 0.01,
            }),
            Config::new(),
        ))
    }

    fn create(_info: &ModelInfo) -> Result<Self, Cause> {
        Ok(Self { source: None })
    }

    fn initialize(&mut self, ctx: &mut Context) -> Result<(), Failure> {
        let (w, seed) = read_waveform(ctx)?;
        let mut source = SignalSource::new(w, seed).map_err(named)?;
        let y = source.try_value_at(ctx.time()).map_err(Failure::error)?;
        ctx.values.set_real(vr::Y, y);
        self.source = Some(source);
        Ok(())
    }

    fn do_step(&mut self, ctx: &mut Context, time: f64, step: f64) -> Result<(), Failure> {
        let source = self
            .source
            .as_mut()
            .ok_or_else(|| Failure::error("SignalSource: not initialised"))?;
        let mut next = source.clone();
        let y = next.try_value_at(time + step).map_err(Failure::error)?;
        *source = next;
        ctx.values.set_real(vr::Y, y);
        Ok(())
    }

    spurio_fmu_common::fmu_state!(source; check = |m: &Self| {
        if let Some(source) = &m.source {
            source.waveform().validate()?;
        }
        Ok(())
    });
}

spurio_export::export_fmu!(SignalSourceFmu);

#[cfg(test)]
mod tests {
    use super::*;
    use spurio_export::harness::Harness;
    use spurio_export::types::Status;
    use std::time::Instant;

    fn source(waveform: i32) -> Harness<SignalSourceFmu> {
        let mut h = Harness::<SignalSourceFmu>::new(&Config::new()).unwrap();
        h.set_integer(&[vr::WAVEFORM as u32], &[waveform]).unwrap();
        h
    }

    #[test]
    fn a_start_far_in_the_future_is_an_error_not_a_hang() {
        let mut h = source(waveform::RANDOM_STEPS);
        h.setup_experiment(1e12, None).unwrap();
        h.enter_initialization_mode().unwrap();
        let words = ["fmi2ExitInitializationMode", "t = 1000000000000 s", "holds"];
        let refused = h.refuses_at_once(5.0, &words, |h| h.exit_initialization_mode());
        assert_eq!(refused, Ok(()));
    }

    #[test]
    fn a_prbs_at_a_far_time_and_tiny_periods_returns() {
        let mut h = source(waveform::PRBS);
        // A bit period below the declared minimum is refused, naming the parameter.
        let refused = h.set_real(&[vr::BIT_PERIOD as u32], &[1e-300]);
        let named = h.logged(&["`bit_period`", "below its minimum"]);
        assert!(
            refused == Err(Status::Error) && named,
            "{refused:?} {:?}",
            h.log()
        );
        h.set_real(&[vr::BIT_PERIOD as u32], &[1e-9]).unwrap();
        h.set_integer(&[vr::PRBS_ORDER as u32], &[24]).unwrap();
        let start = Instant::now();
        h.initialize(1e12).unwrap();
        h.do_step(1e12, 1e11).unwrap();
        assert!(start.elapsed().as_secs_f64() < 5.0);
        assert_eq!(h.real(vr::Y as u32).unwrap().abs(), 1.0);
    }
}
