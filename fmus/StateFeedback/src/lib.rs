//! `StateFeedback.fmu`: discrete pole-placement state feedback (paper 000 §IV, eqs 8–15;
//! docs/controllers.md §2.13) as an FMI 2.0 CS FMU.
//!
//! The law is
//!
//! ```text
//! u = sat_[u_min, u_max]( −L (x̂ − x_ref) ),      L = [0 … 0 1] 𝒞⁻¹ φ(A),
//! 𝒞 = [B  A B  …  A^{n−1} B],      φ(z) = Π (z − p_i)
//! ```
//!
//! with `L` computed once, at initialisation, by Ackermann's formula
//! ([`spurio::control::ackermann_with_options`]) from the parameters `A`, `B` (the discrete
//! model) and the desired discrete poles `p_i = pole_re[i] + j·pole_im[i]`. Ackermann's
//! formula is single-input, so `B` is n × 1 and there is one output, `u[1]`. `u[1]` depends
//! directly on the inputs `x_hat`, `x_ref` (direct feedthrough): it is recomputed as soon as
//! an input is set, so a master reads it at the same communication point — at the sample
//! instants of `sample_period` (see [`spurio_fmu_common::controller`]); between them it holds.
//!
//! Dimension-generic: the configuration key `n` (number of states) is chosen at packaging
//! time; `preset = crane` gives the crane defaults (n = 4, ZOH of the linearised crane at
//! Ts = 0.05 s, poles of [`spurio::control::crane_reference_design`]), any other `n` the
//! generic chain of [`variant_defaults`]. The pieces shared with the adaptive controller
//! (presets, pole parameters, error messages) live in [`spurio_fmu_common::controller`].

use spurio::control::{
    ackermann_with_options, PolePlacementOptions, StateController, StateFeedback,
};
use spurio_export::{Cause, Config, Context, Failure, Variable};
pub use spurio_fmu_common::controller::*;
use spurio_fmu_common::crane_controller_config;
use spurio_fmu_common::structured::{add_matrix, add_vector, Block};

/// Positions of the variables of one StateFeedback variant in its table.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Layout {
    /// Number of states n.
    pub states: usize,
    /// Input `x_hat[i]`: the estimated (or measured) state.
    pub x_hat: Block,
    /// Input `x_ref[i]`: the reference state.
    pub x_ref: Block,
    /// Output `u[1]`.
    pub u: usize,
    /// Calculated parameter `L[1,j]`.
    pub gain: Block,
    /// Parameter `A[i,j]`.
    pub a: Block,
    /// Parameter `B[i,1]`.
    pub b: Block,
    /// Parameters `pole_re[i]`, `pole_im[i]`, `u_min`, `u_max`.
    pub design: DesignBlocks,
    /// Boolean parameter `require_stable`.
    pub require_stable: usize,
}

/// The variable table of a variant and where each variable is.
pub fn build(config: &Config) -> Result<(Layout, Vec<Variable>), Cause> {
    let (defaults, mut t, x_hat) = start_table(config)?;
    let n = defaults.states();
    let preset = defaults.preset;
    let x_ref = add_vector(&mut t, "x_ref", n, |name, i| {
        let (meaning, unit) = state_meaning(preset, i);
        with_unit(
            Variable::input(name, 0.0).describe(&format!(
                "Reference state (an equilibrium with zero input): {meaning}; u = −L·(x_hat − x_ref)"
            )),
            unit,
        )
    });
    let feedthrough: Vec<usize> = x_hat.indices().chain(x_ref.indices()).collect();
    let u = t.add(with_unit(
        Variable::output("u[1]")
            .describe("Control input u = sat(−L·(x_hat − x_ref)) to [u_min, u_max]; never NaN")
            .depends_on(&feedthrough),
        input_unit(preset),
    ));
    let gain = add_matrix(&mut t, "L", 1, n, |name, _, j| {
        calculated_parameter(name).describe(&format!(
            "Feedback gain on state {} (Ackermann, computed at initialisation)",
            j + 1
        ))
    });
    let a = add_matrix(&mut t, "A", n, n, |name, i, j| {
        Variable::parameter(name, defaults.design.a[(i, j)])
            .describe("Discrete state matrix of the model x⁺ = A·x + B·u")
    });
    let b = add_matrix(&mut t, "B", n, 1, |name, i, _| {
        Variable::parameter(name, defaults.design.b[(i, 0)])
            .describe("Discrete input matrix (single input: one column)")
    });
    let design = DesignBlocks::add(&mut t, &defaults);
    let require_stable = t.add(
        Variable::boolean_parameter("require_stable", true).describe(
            "Reject desired poles on or outside the unit circle (|z| ≥ 1) with fmi2Error",
        ),
    );
    let layout = Layout {
        states: n,
        x_hat,
        x_ref,
        u,
        gain,
        a,
        b,
        design,
        require_stable,
    };
    Ok((layout, t.into_variables()))
}

/// The law of the StateFeedback FMU: the controller designed at initialisation (no state
/// that evolves: a sample only shows `u` for the inputs held).
#[derive(Debug, Clone)]
pub struct FeedbackLaw {
    controller: StateFeedback,
    /// `x_hat`, `x_ref` as last read.
    work: Scratch<(Vec<f64>, Vec<f64>)>,
}
spurio::plain_state!(FeedbackLaw { controller, work });

/// The StateFeedback FMU.
pub type StateFeedbackFmu = SampledController<FeedbackLaw>;

spurio_export::export_fmu! { StateFeedbackFmu, variants = [("StateFeedback", crane_controller_config())] }

impl FeedbackLaw {
    /// The controller in use.
    pub fn controller(&self) -> &StateFeedback {
        &self.controller
    }
}

impl ControlLaw for FeedbackLaw {
    type Layout = Layout;
    const MODEL_IDENTIFIER: &'static str = "StateFeedback";
    const DESCRIPTION: &'static str = "Discrete state feedback u = sat(−L·(x_hat − x_ref)), L by Ackermann's pole placement at initialisation (paper 000 §IV); single input";

    fn build(config: &Config) -> Result<(Layout, Vec<Variable>), Cause> {
        build(config)
    }

    fn design(layout: &Layout) -> &DesignBlocks {
        &layout.design
    }

    fn initialize(layout: &Layout, ctx: &mut Context) -> Result<Self, Failure> {
        let values = &*ctx.values;
        let limits = layout.design.limits(values).map_err(Failure::error)?;
        let a = layout.a.matrix(values);
        let b = layout.b.matrix(values);
        let poles = layout.design.poles(values);
        let options = PolePlacementOptions {
            require_stable: values.boolean(layout.require_stable),
            ..PolePlacementOptions::default()
        };
        let gain = ackermann_with_options(&a, &b, &poles, &options)
            .map_err(|e| design_error_message(&e, &poles))?;
        let controller = StateFeedback::from_gain(gain, limits).map_err(Failure::error)?;
        layout.gain.write(ctx.values, controller.gain());
        let n = layout.states;
        let work = (Vec::with_capacity(n), Vec::with_capacity(n));
        Ok(Self {
            controller,
            work: Scratch(work),
        })
    }

    /// No internal state: the output of a sample is shown by `write_outputs`.
    fn commit(&mut self, _: &Layout, _: &mut Context, _: f64) -> Result<(), Failure> {
        Ok(())
    }

    /// `u[1] = sat(−L (x̂ − x_ref))` from the current inputs.
    fn write_outputs(&mut self, layout: &Layout, ctx: &mut Context) {
        let (x_hat, x_ref) = &mut self.work.0;
        read_block(&layout.x_hat, ctx.values, x_hat);
        read_block(&layout.x_ref, ctx.values, x_ref);
        let u = self.controller.control_towards(x_hat, x_ref);
        ctx.values.set_real(layout.u, u);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::DMatrix;
    use spurio_export::harness::Harness;
    use spurio_export::types::Status;
    use spurio_export::{FmuModel, Values};
    use spurio_fmu_common::crane_controller_config as crane_config;

    #[test]
    fn layout_matches_the_table() {
        let (l, v) = build(&crane_config()).unwrap();
        let named = [
            (l.x_hat.first, "x_hat[1]"),
            (l.x_ref.index(3, 0), "x_ref[4]"),
            (l.u, "u[1]"),
            (l.gain.index(0, 3), "L[1,4]"),
            (l.a.index(3, 3), "A[4,4]"),
            (l.b.index(3, 0), "B[4,1]"),
            (l.design.pole_re.first, "pole_re[1]"),
            (l.design.pole_im.index(3, 0), "pole_im[4]"),
            (l.design.u_min, "u_min"),
            (l.design.u_max, "u_max"),
            (l.require_stable, "require_stable"),
        ];
        for (index, name) in named {
            assert_eq!(v[index].name, name);
        }
        let layout = l;
        assert_eq!(v.len(), layout.require_stable + 1);
        assert_eq!(v[layout.u].unit.as_deref(), Some("N"));
        assert_eq!(v[layout.u].dependencies.len(), 8);
    }

    #[test]
    fn configurations_are_checked() {
        let mut c = crane_config();
        c.set(CONFIG_STATES, 3);
        assert!(build(&c).unwrap_err().to_string().contains("4 states"));
        let mut c = Config::new();
        c.set(CONFIG_PRESET, "bridge");
        assert!(build(&c).unwrap_err().to_string().contains("`preset`"));
        let mut c = Config::new();
        c.set(CONFIG_STATES, 0);
        assert!(build(&c).unwrap_err().to_string().contains("`n`"));
        let mut c = Config::new();
        c.set(CONFIG_STATES, 3);
        let d = variant_defaults(&c).unwrap();
        assert_eq!(d.preset, Preset::Generic);
        let closed = &d.design.a - &d.design.b * &d.design.gain;
        // (z − 0.5)³: the closed loop minus 0.5 I is nilpotent.
        let shifted = closed - DMatrix::identity(3, 3) * GENERIC_POLE;
        assert!((&shifted * &shifted * &shifted).amax() < 1e-12);
        // A long chain: default design not computable, the description still is.
        let mut c = Config::new();
        c.set(CONFIG_STATES, 16);
        assert!(build(&c).is_ok());
    }

    #[test]
    fn crane_defaults_give_the_reference_gain_and_survive_nan() {
        let info = StateFeedbackFmu::describe(&crane_config()).unwrap();
        let mut model = StateFeedbackFmu::create(&info).unwrap();
        let mut values = Values::from_start(&info.variables);
        let layout = *model.layout();
        let mut ctx = Context::new(&mut values);
        model.initialize(&mut ctx).unwrap();
        let gain = layout.gain.matrix(ctx.values);
        let reference = [0.982, 1.132, 1.027, 0.774];
        for (j, want) in reference.iter().enumerate() {
            assert!((gain[(0, j)] - want).abs() < 5e-4, "{gain}");
        }
        ctx.values.set_real(layout.x_hat.first, 0.2);
        model.update_outputs(&mut ctx).unwrap();
        let u = ctx.values.real(layout.u);
        assert!((u + 0.2 * gain[(0, 0)]).abs() < 1e-15);
        ctx.values.set_real(layout.x_hat.first + 1, f64::NAN);
        model.do_step(&mut ctx, 0.0, 0.05).unwrap();
        assert_eq!(ctx.values.real(layout.u), 0.0);
        // At the next sample instant (the instance's time after the step), inputs set are
        // used at once.
        let mut ctx = Context::at(ctx.values, 0.05);
        ctx.values.set_real(layout.x_hat.first + 1, 1e3);
        model.update_outputs(&mut ctx).unwrap();
        assert_eq!(ctx.values.real(layout.u), -17.0);
    }

    /// The crane variant through the C API, and the value reference of a variable name.
    fn crane_harness() -> (Harness<StateFeedbackFmu>, impl Fn(&str) -> u32) {
        let config = crane_config();
        let info = StateFeedbackFmu::describe(&config).unwrap();
        let vr = move |name: &str| info.index_of(name).unwrap() as u32;
        (Harness::new(&config).unwrap(), vr)
    }

    #[test]
    fn the_output_holds_between_sample_instants() {
        let (mut h, vr) = crane_harness();
        h.set_real(&[vr("sample_period")], &[0.1]).unwrap();
        h.initialize(0.0).unwrap();
        let l1 = h.real(vr("L[1,1]")).unwrap();
        let (x, u) = (vr("x_hat[1]"), vr("u[1]"));
        // u = −L₁·x at each instant 0, 0.1, …; steps of 0.05 hold it in between.
        let mut seen = Vec::new();
        for k in 0..4 {
            h.set_real(&[x], &[0.01 * (k + 1) as f64]).unwrap();
            seen.push(h.real(u).unwrap());
            h.do_step(k as f64 * 0.05, 0.05).unwrap();
        }
        let expected = [-0.01 * l1, -0.01 * l1, -0.03 * l1, -0.03 * l1];
        for (got, want) in seen.iter().zip(expected) {
            assert!((got - want).abs() < 1e-15, "{seen:?} vs {expected:?}");
        }
    }

    #[test]
    fn bad_poles_are_named_through_the_c_api() {
        let (mut h, vr) = crane_harness();
        h.set_real(&[vr("pole_im[2]")], &[0.3]).unwrap();
        assert_eq!(h.initialize(0.0), Err(Status::Error));
        let log = h.log();
        assert!(
            log.iter().any(|(s, _, t)| *s == Status::Error
                && t.contains("`pole_re[1]`, `pole_im[1]`")
                && t.contains("conjugate")),
            "{log:?}"
        );
        let (mut h, _) = crane_harness();
        assert_eq!(h.initialize(0.0), Ok(Status::Ok));
        h.set_real(&[vr("x_hat[2]")], &[0.01]).unwrap();
        let u = h.real(vr("u[1]")).unwrap();
        assert_eq!(u, -0.01 * h.real(vr("L[1,2]")).unwrap());
    }
}
