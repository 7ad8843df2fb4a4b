//! `AdaptiveStateFeedback.fmu`: pole placement redone on the identified model (paper 000
//! §VI, Fig. 6; docs/controllers.md §2.14) as an FMI 2.0 CS FMU.
//!
//! Every communication point the FMU receives the estimated model `Â`, `B̂` (inputs `A_hat`,
//! `B_hat`, e.g. from a dual Kalman filter) and the estimated state `x̂`; every
//! `recompute_period`-th point it recomputes
//!
//! ```text
//! L = [0 … 0 1] 𝒞(Â, B̂)⁻¹ φ(Â),      u = sat_[u_min, u_max](−L x̂ + v)
//! ```
//!
//! (Ackermann, paper 000 eq. 15) for the fixed desired poles; `v` (input `v[1]`, default 0)
//! is an exogenous input, e.g. a small dither from a SignalSource that makes the closed loop
//! identifiable (docs/controllers.md §2.14). An estimate that is not
//! reachable (condition number of 𝒞 above `max_condition_number`), not finite, or whose gain
//! has a norm above `max_gain_norm` is rejected: the last good gain stays (at first `L0`),
//! the output is never NaN, and the first rejection of each episode of consecutive
//! rejections is logged as a warning (`fmi2Warning` from `fmi2DoStep`) that names the reason.
//! The mathematics is [`spurio::control::AdaptiveStateFeedback`].
//!
//! Timing: the outputs at a communication point are those of the controller *after*
//! processing the inputs held there (direct feedthrough: `u[1]` depends on `x_hat`, `A_hat`,
//! `B_hat`; `L`, `rejected_updates` and `estimate_rejected` on `A_hat`, `B_hat`), computed on
//! a copy when inputs are set; `fmi2DoStep` commits that update (and logs), so the gain
//! used for `u_k` is the one from `Â_k`, `B̂_k`, as in paper 000 Fig. 6. The points are the
//! sample instants of `sample_period` (see [`spurio_fmu_common::controller`]): between them
//! the outputs hold, and `recompute_period` counts samples.

use nalgebra::DMatrix;
use spurio::control::adaptive::Candidate;
use spurio::control::pole_placement::DEFAULT_MAX_CONDITION_NUMBER;
use spurio::control::state_feedback::feedback_term;
use spurio::control::{
    AdaptiveStateFeedback, AdaptiveStateFeedbackConfig, GainUpdate, StateController,
};
use spurio_export::{Cause, Config, Context, Failure, Value, Variable};
use spurio_fmu_common::controller::{
    check_pole_parameters, format_gain, input_unit, read_block, start_table, with_unit, ControlLaw,
    DesignBlocks, Preset, SampledController, Scratch,
};
use spurio_fmu_common::crane_controller_config;
use spurio_fmu_common::structured::{add_matrix, Block};

/// Default bound on ‖L‖₂ for the crane preset: 50 times the reference gain's norm (≈ 1.99).
pub const CRANE_MAX_GAIN_NORM: f64 = 100.0;
/// Default bound on ‖L‖₂ for generic variants.
pub const GENERIC_MAX_GAIN_NORM: f64 = 1e6;

/// Positions of the variables of one AdaptiveStateFeedback variant in its table.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Layout {
    /// Number of states n.
    pub states: usize,
    /// Input `x_hat[i]`.
    pub x_hat: Block,
    /// Input `A_hat[i,j]`.
    pub a_hat: Block,
    /// Input `B_hat[i,1]`.
    pub b_hat: Block,
    /// Input `v[1]`: added to −L x̂ before the saturation.
    pub v: usize,
    /// Output `u[1]`.
    pub u: usize,
    /// Output `L[1,j]`: the gain in use.
    pub gain: Block,
    /// Integer output `rejected_updates`.
    pub rejected_updates: usize,
    /// Boolean output `estimate_rejected`.
    pub estimate_rejected: usize,
    /// Parameters `pole_re[i]`, `pole_im[i]`, `u_min`, `u_max`.
    pub design: DesignBlocks,
    /// Integer parameter `recompute_period`.
    pub recompute_period: usize,
    /// Parameter `max_gain_norm`.
    pub max_gain_norm: usize,
    /// Parameter `max_condition_number`.
    pub max_condition_number: usize,
    /// Parameter `L0[1,j]`: the gain until the first accepted update.
    pub initial_gain: Block,
}

/// The variable table of a variant and where each variable is.
pub fn build(config: &Config) -> Result<(Layout, Vec<Variable>), Cause> {
    let (defaults, mut t, x_hat) = start_table(config)?;
    let n = defaults.states();
    let preset = defaults.preset;
    let a_hat = add_matrix(&mut t, "A_hat", n, n, |name, i, j| {
        Variable::input(name, defaults.design.a[(i, j)])
            .describe("Estimated discrete state matrix Â (e.g. from the dual Kalman filter)")
    });
    let b_hat = add_matrix(&mut t, "B_hat", n, 1, |name, i, _| {
        Variable::input(name, defaults.design.b[(i, 0)])
            .describe("Estimated discrete input matrix B̂ (one column)")
    });
    let v = t.add(with_unit(
        Variable::input("v[1]", 0.0).describe(
            "Exogenous input added before the saturation, u = sat(−L·x_hat + v): e.g. a small dither that makes the closed loop identifiable (default 0)",
        ),
        input_unit(preset),
    ));
    let estimate: Vec<usize> = a_hat.indices().chain(b_hat.indices()).collect();
    let all_inputs: Vec<usize> = x_hat
        .indices()
        .chain(estimate.iter().copied())
        .chain([v])
        .collect();
    let u = t.add(with_unit(
        Variable::output("u[1]")
            .describe("Control input u = sat(−L·x_hat + v) to [u_min, u_max]; never NaN")
            .depends_on(&all_inputs),
        input_unit(preset),
    ));
    let gain = add_matrix(&mut t, "L", 1, n, |name, _, j| {
        Variable::discrete_output(name)
            .describe(&format!(
                "Gain in use on state {}: recomputed from A_hat, B_hat, or the last good one",
                j + 1
            ))
            .depends_on(&estimate)
    });
    let rejected_updates = t.add(Variable {
        start: Value::Integer(0),
        ..Variable::discrete_output("rejected_updates")
            .describe(
                "Number of gain updates rejected so far (estimate unusable or gain too large)",
            )
            .depends_on(&estimate)
    });
    let estimate_rejected = t.add(
        Variable::boolean_output("estimate_rejected")
            .describe("True while the latest recompute was rejected and the last good gain is kept")
            .depends_on(&estimate),
    );
    let design = DesignBlocks::add(&mut t, &defaults);
    let recompute_period = t.add(
        Variable::integer_parameter("recompute_period", 1)
            .min(1.0)
            .describe("Recompute the gain every N-th communication point (N ≥ 1)"),
    );
    let default_gain_bound = match preset {
        Preset::Crane => CRANE_MAX_GAIN_NORM,
        Preset::Generic => GENERIC_MAX_GAIN_NORM,
    };
    let max_gain_norm = t.add(
        Variable::parameter("max_gain_norm", default_gain_bound)
            .min(0.0)
            .describe("Recomputed gains with a larger Euclidean norm are rejected (the last good gain is kept)"),
    );
    let max_condition_number = t.add(
        Variable::parameter("max_condition_number", DEFAULT_MAX_CONDITION_NUMBER)
            .min(1.0)
            .describe("Estimates whose reachability matrix [B AB … A^(n−1)B] has a larger 2-norm condition number are rejected as not reachable"),
    );
    let initial_gain = add_matrix(&mut t, "L0", 1, n, |name, _, j| {
        Variable::parameter(name, defaults.design.gain[(0, j)]).describe(&format!(
            "Initial gain on state {} (used until the first accepted update; default: the design on the default model)",
            j + 1
        ))
    });
    let layout = Layout {
        states: n,
        x_hat,
        a_hat,
        b_hat,
        v,
        u,
        gain,
        rejected_updates,
        estimate_rejected,
        design,
        recompute_period,
        max_gain_norm,
        max_condition_number,
        initial_gain,
    };
    Ok((layout, t.into_variables()))
}

fn config_from_parameters(
    layout: &Layout,
    values: &spurio_export::Values,
) -> Result<AdaptiveStateFeedbackConfig, Cause> {
    let poles = layout.design.poles(values);
    check_pole_parameters(&poles, true)?;
    let limits = layout.design.limits(values)?;
    let period = values.integer(layout.recompute_period);
    let recompute_period = usize::try_from(period)
        .ok()
        .filter(|p| *p >= 1)
        .ok_or_else(|| {
            format!("parameter `recompute_period`: must be at least 1 (recompute every N-th step), got {period}")
        })?;
    let max_gain_norm = values.real(layout.max_gain_norm);
    if max_gain_norm.is_nan() || max_gain_norm <= 0.0 {
        return Err(format!(
            "parameter `max_gain_norm`: must be a positive number, got {max_gain_norm}"
        )
        .into());
    }
    let max_condition_number = values.real(layout.max_condition_number);
    if max_condition_number.is_nan() || max_condition_number < 1.0 {
        return Err(format!(
            "parameter `max_condition_number`: must be at least 1 (a condition number is ≥ 1), got {max_condition_number}"
        ).into());
    }
    let initial_gain = layout.initial_gain.matrix(values);
    if !initial_gain.iter().all(|v| v.is_finite()) {
        return Err("parameter `L0`: must be finite".into());
    }
    let mut config = AdaptiveStateFeedbackConfig::new(poles, limits);
    config.recompute_period = recompute_period;
    config.max_gain_norm = max_gain_norm;
    config.max_condition_number = max_condition_number;
    config.initial_gain = Some(initial_gain);
    Ok(config)
}

/// The law of the AdaptiveStateFeedback FMU: the controller, the number of rejections when
/// the current episode began (for the recovery message), and the working memory.
#[derive(Debug, Clone)]
pub struct AdaptiveLaw {
    controller: AdaptiveStateFeedback,
    rejections_before_episode: u64,
    work: Scratch<Work>,
}
spurio::plain_state!(AdaptiveLaw {
    controller,
    rejections_before_episode,
    work
});

/// The estimate last read and its assessment, so that the preview after the inputs are set,
/// the commit of the step and the preview after it recompute the gain once per estimate.
#[derive(Debug, Clone, Default)]
struct Work {
    x_hat: Vec<f64>,
    a_hat: Option<(DMatrix<f64>, DMatrix<f64>)>,
    /// The assessment of `a_hat` (`None`: not assessed yet) and the candidate row it wrote.
    assessed: Option<Candidate>,
    candidate: Vec<f64>,
}

/// Copies `block` into `m` (reshaped if needed); whether anything changed, to the bit.
fn refresh(block: &Block, values: &spurio_export::Values, m: &mut DMatrix<f64>) -> bool {
    if m.shape() != (block.rows, block.cols) {
        *m = DMatrix::from_element(block.rows, block.cols, f64::NAN);
    }
    let mut changed = false;
    for i in 0..block.rows {
        for j in 0..block.cols {
            let v = values.real(block.index(i, j));
            if m[(i, j)].to_bits() != v.to_bits() {
                m[(i, j)] = v;
                changed = true;
            }
        }
    }
    changed
}

impl AdaptiveLaw {
    /// The controller in use.
    pub fn controller(&self) -> &AdaptiveStateFeedback {
        &self.controller
    }

    /// What the update from the estimate held would do: `None` when no recompute is due,
    /// else the assessment, the candidate row in `self.work`. An unchanged estimate is not
    /// assessed again.
    fn assess(&mut self, layout: &Layout, values: &spurio_export::Values) -> Option<Candidate> {
        let work = &mut self.work.0;
        let (a_hat, b_hat) = work.a_hat.get_or_insert_with(Default::default);
        let changed = refresh(&layout.a_hat, values, a_hat) | refresh(&layout.b_hat, values, b_hat);
        if changed {
            work.assessed = None;
        }
        if !self.controller.is_due() {
            return None;
        }
        let assessed = work.assessed.get_or_insert_with(|| {
            work.candidate.resize(layout.states, 0.0);
            self.controller
                .candidate_gain_into(a_hat, b_hat, &mut work.candidate)
        });
        Some(assessed.clone())
    }
}

impl ControlLaw for AdaptiveLaw {
    type Layout = Layout;
    const MODEL_IDENTIFIER: &'static str = "AdaptiveStateFeedback";
    const DESCRIPTION: &'static str = "Adaptive pole placement: L recomputed by Ackermann from the estimated A_hat, B_hat every N steps, last good gain kept when the estimate is unusable (paper 000 Fig. 6); single input";

    fn build(config: &Config) -> Result<(Layout, Vec<Variable>), Cause> {
        build(config)
    }

    fn design(layout: &Layout) -> &DesignBlocks {
        &layout.design
    }

    fn initialize(layout: &Layout, ctx: &mut Context) -> Result<Self, Failure> {
        let config = config_from_parameters(layout, ctx.values)?;
        let controller = AdaptiveStateFeedback::new(config).map_err(|e| {
            let parameter = if e.parameter == "initial_gain" {
                "L0"
            } else {
                e.parameter.as_str()
            };
            format!("parameter `{parameter}`: {}", e.reason)
        })?;
        let n = layout.states;
        let work = Work {
            x_hat: Vec::with_capacity(n),
            a_hat: Some((DMatrix::zeros(n, n), DMatrix::zeros(n, 1))),
            assessed: None,
            candidate: vec![0.0; n],
        };
        Ok(Self {
            controller,
            rejections_before_episode: 0,
            work: Scratch(work),
        })
    }

    /// Commits the gain update of the sample at `time` from the inputs held (and logs).
    fn commit(&mut self, layout: &Layout, ctx: &mut Context, time: f64) -> Result<(), Failure> {
        let outcome = self.assess(layout, ctx.values);
        let controller = &mut self.controller;
        let rejections_before = controller.rejected_updates();
        let was_rejecting = controller.in_rejection_episode();
        match controller.commit(outcome, &self.work.0.candidate) {
            GainUpdate::Kept {
                reason,
                first_in_episode: true,
            } => {
                self.rejections_before_episode = rejections_before;
                let kept = controller
                    .gain()
                    .map_or("none yet (u = 0)".to_string(), format_gain);
                ctx.warn(format!(
                    "t = {time} s: gain update rejected: {reason}; keeping the last good gain L = {kept} (warned once per episode; `rejected_updates` counts every rejection)"
                ));
            }
            GainUpdate::Updated if was_rejecting => {
                let rejected = controller.rejected_updates() - self.rejections_before_episode;
                let gain = controller.gain().map_or(String::new(), format_gain);
                ctx.log_event(|| format!(
                    "t = {time} s: the estimate is usable again after {rejected} rejected updates; new gain L = {gain}"
                ));
            }
            GainUpdate::Kept { .. } | GainUpdate::Updated | GainUpdate::NotDue => {}
        }
        Ok(())
    }

    /// The outputs of the controller after processing the inputs held, without committing:
    /// `u = sat(−L x̂ + v)` with the gain the update would leave, `L`, `rejected_updates`,
    /// `estimate_rejected`.
    fn write_outputs(&mut self, layout: &Layout, ctx: &mut Context) {
        let outcome = self.assess(layout, ctx.values);
        let work = &mut self.work.0;
        let controller = &self.controller;
        let (gain, rejected, rejecting) = match outcome {
            None => (
                controller.gain_row(),
                controller.rejected_updates(),
                controller.in_rejection_episode(),
            ),
            Some(Ok(())) => (&work.candidate[..], controller.rejected_updates(), false),
            Some(Err(_)) => (
                controller.gain_row(),
                controller.rejected_updates() + 1,
                true,
            ),
        };
        read_block(&layout.x_hat, ctx.values, &mut work.x_hat);
        let v = ctx.values.real(layout.v);
        let feedback = feedback_term(gain, &work.x_hat, None);
        let u = controller
            .input_limits()
            .saturate(feedback.unwrap_or(0.0) + v);
        ctx.values.set_real(layout.u, u);
        for (k, j) in layout.gain.indices().enumerate() {
            ctx.values.set_real(j, gain.get(k).copied().unwrap_or(0.0));
        }
        let rejected = i32::try_from(rejected).unwrap_or(i32::MAX);
        ctx.values.set_integer(layout.rejected_updates, rejected);
        ctx.values.set_boolean(layout.estimate_rejected, rejecting);
    }
}

/// The AdaptiveStateFeedback FMU.
pub type AdaptiveStateFeedbackFmu = SampledController<AdaptiveLaw>;

spurio_export::export_fmu! { AdaptiveStateFeedbackFmu, variants = [("AdaptiveStateFeedback", crane_controller_config())] }

#[cfg(test)]
mod tests {
    use super::*;
    use spurio::control::crane_reference_design;
    use spurio_export::types::Status;
    use spurio_export::{ByteReader, ByteWriter, FmuModel, ModelInfo, Values};
    use spurio_fmu_common::crane_controller_config as crane_config;

    #[test]
    fn layout_matches_the_table() {
        let (layout, v) = build(&crane_config()).unwrap();
        assert_eq!(v[layout.x_hat.index(3, 0)].name, "x_hat[4]");
        assert_eq!(v[layout.a_hat.index(1, 2)].name, "A_hat[2,3]");
        assert_eq!(v[layout.b_hat.index(3, 0)].name, "B_hat[4,1]");
        assert_eq!(v[layout.v].name, "v[1]");
        assert_eq!(v[layout.u].name, "u[1]");
        assert_eq!(v[layout.gain.index(0, 0)].name, "L[1,1]");
        assert_eq!(v[layout.rejected_updates].name, "rejected_updates");
        assert_eq!(v[layout.estimate_rejected].name, "estimate_rejected");
        assert_eq!(v[layout.design.pole_im.index(3, 0)].name, "pole_im[4]");
        assert_eq!(v[layout.recompute_period].name, "recompute_period");
        assert_eq!(v[layout.max_gain_norm].name, "max_gain_norm");
        assert_eq!(v[layout.max_condition_number].name, "max_condition_number");
        assert_eq!(v[layout.initial_gain.index(0, 3)].name, "L0[1,4]");
        assert_eq!(v.len(), layout.initial_gain.index(0, 3) + 1);
        assert_eq!(v[layout.u].dependencies.len(), 4 + 16 + 4 + 1);
    }

    /// u = sat(−L x̂ + v): the exogenous input adds before the saturation (±17 N).
    #[test]
    fn the_exogenous_input_adds_before_the_saturation() {
        let (_, mut model, mut values) = initialized_crane_variant();
        let layout = *model.layout();
        let x_hat = [0.1, 0.0, 0.0, 0.0];
        for (i, x) in x_hat.iter().enumerate() {
            values.set_real(layout.x_hat.index(i, 0), *x);
        }
        let mut u_at = |values: &mut Values, v: f64| {
            values.set_real(layout.v, v);
            let mut ctx = Context::new(values);
            model.write_outputs(&mut ctx);
            values.real(layout.u)
        };
        let feedback = u_at(&mut values, 0.0);
        let l11 = values.real(layout.gain.index(0, 0));
        assert_eq!(feedback, -l11 * 0.1);
        assert!((u_at(&mut values, 0.05) - (feedback + 0.05)).abs() < 1e-15);
        assert_eq!(u_at(&mut values, 100.0), 17.0);
    }

    /// The crane variant's description, the model created from it and initialised straight
    /// through the model, and its values; initialising logs nothing.
    fn initialized_crane_variant() -> (ModelInfo, AdaptiveStateFeedbackFmu, Values) {
        let info = AdaptiveStateFeedbackFmu::describe(&crane_config()).unwrap();
        let mut model = AdaptiveStateFeedbackFmu::create(&info).unwrap();
        let mut values = Values::from_start(&info.variables);
        let mut ctx = Context::new(&mut values);
        model.initialize(&mut ctx).unwrap();
        assert!(ctx.take_messages().is_empty());
        (info, model, values)
    }

    /// Straight through the model (no FMI layer, which refuses NaN inputs): NaN estimates,
    /// NaN states and mis-sized gains never reach the output.
    #[test]
    fn nan_estimate_keeps_the_gain_warns_once_and_never_outputs_nan() {
        let design = crane_reference_design().unwrap();
        let (_, mut model, mut values) = initialized_crane_variant();
        let layout = *model.layout();
        let mut ctx = Context::new(&mut values);
        ctx.values.set_real(layout.x_hat.first, 0.2);
        model.do_step(&mut ctx, 0.0, 0.05).unwrap();
        let good = layout.gain.matrix(ctx.values);
        assert!((&good - &design.gain).amax() < 1e-12);
        assert!(ctx.take_messages().is_empty());

        ctx.values.set_real(layout.a_hat.index(2, 1), f64::NAN);
        let mut messages = Vec::new();
        for k in 1..4 {
            // A context at the instance's time, a sample instant.
            let mut at = Context::at(&mut *ctx.values, k as f64 * 0.05);
            model.update_outputs(&mut at).unwrap();
            assert!(at.values.real(layout.u).is_finite());
            model.do_step(&mut at, k as f64 * 0.05, 0.05).unwrap();
            assert_eq!(layout.gain.matrix(at.values), good);
            messages.extend(at.take_messages());
        }
        assert_eq!(messages.len(), 1, "{messages:?}");
        assert_eq!(messages[0].status, Status::Warning);
        assert!(messages[0].text.contains("NaN or infinity"), "{messages:?}");
        assert_eq!(ctx.values.integer(layout.rejected_updates), 4); // 3 + the preview
        assert!(ctx.values.boolean(layout.estimate_rejected));

        let mut ctx = Context::at(ctx.values, 0.2);
        ctx.values.set_real(layout.x_hat.first + 2, f64::NAN);
        model.update_outputs(&mut ctx).unwrap();
        assert_eq!(ctx.values.real(layout.u), 0.0);
    }

    #[test]
    fn state_serialization_round_trips() {
        let (info, mut model, mut values) = initialized_crane_variant();
        let layout = *model.layout();
        let mut ctx = Context::new(&mut values);
        ctx.values.set_real(layout.b_hat.first + 3, 0.0);
        ctx.values.set_real(layout.b_hat.first + 2, 0.0);
        model.do_step(&mut ctx, 0.0, 0.05).unwrap();
        let mut out = ByteWriter::new();
        model.save_state(&mut out);
        let bytes = out.into_bytes();
        let mut restored = AdaptiveStateFeedbackFmu::create(&info).unwrap();
        restored.load_state(&mut ByteReader::new(&bytes)).unwrap();
        let (restored, model) = (restored.law().unwrap(), model.law().unwrap());
        assert_eq!(restored.controller, model.controller);
        assert_eq!(
            restored.rejections_before_episode,
            model.rejections_before_episode
        );
        let mut truncated = AdaptiveStateFeedbackFmu::create(&info).unwrap();
        assert!(truncated
            .load_state(&mut ByteReader::new(&bytes[..bytes.len() - 3]))
            .is_err());
    }

    #[test]
    fn bad_parameters_are_named() {
        let info = AdaptiveStateFeedbackFmu::describe(&crane_config()).unwrap();
        let mut model = AdaptiveStateFeedbackFmu::create(&info).unwrap();
        let layout = *model.layout();
        let cases: Vec<(usize, f64, &str)> = vec![
            (
                layout.design.pole_re.first,
                1.2,
                "`pole_re[1]`, `pole_im[1]`",
            ),
            (layout.design.u_min, 20.0, "`u_max`"),
            (layout.max_gain_norm, 0.0, "`max_gain_norm`"),
            (layout.max_condition_number, 0.5, "`max_condition_number`"),
        ];
        for (index, value, named) in cases {
            let mut values = Values::from_start(&info.variables);
            values.set_real(index, value);
            let mut ctx = Context::new(&mut values);
            match model.initialize(&mut ctx) {
                Err(Failure::Error(message)) => {
                    assert!(message.to_string().contains(named), "{message}")
                }
                other => panic!("expected an error naming {named}, got {other:?}"),
            }
        }
        let mut values = Values::from_start(&info.variables);
        values.set_integer(layout.recompute_period, 0);
        let mut ctx = Context::new(&mut values);
        assert!(matches!(
            model.initialize(&mut ctx),
            Err(Failure::Error(m)) if m.to_string().contains("`recompute_period`")
        ));
    }
}
