//! `GantryCrane.fmu`: the nonlinear crane of paper 000 (docs/models.md §2.1) as an FMI 2.0 CS FMU.
//!
//! Input `U` [N] (saturated at ±`U_max`), outputs `x`, `theta`, `v`, `omega` and the applied
//! force `U_applied`; the physical parameters of Annex A, the initial state and the RK4
//! substep bound `h_max`. The mathematics is [`spurio::plants::gantry_crane`].

use spurio::plants::gantry_crane::{GantryCrane, GantryCraneParameters};
use spurio_export::{
    Cause, Config, Context, DefaultExperiment, Failure, FmuModel, ModelInfo, Variable,
};

spurio_export::declare_variables! {
    /// The variable table, in value-reference order.
    pub fn variables() {
        let p = GantryCraneParameters::default();
        table: [
            U = Variable::input("U", 0.0)
                .unit("N")
                .describe("Force on the cart requested by the controller (saturated at ±U_max)"),
            X = Variable::output("x").unit("m").describe("Cart position on the rail"),
            THETA = Variable::output("theta")
                .unit("rad")
                .describe("Load angle, 0 hanging straight down"),
            V = Variable::output("v").unit("m/s").describe("Cart velocity"),
            OMEGA = Variable::output("omega").unit("rad/s").describe("Load angular velocity"),
            U_APPLIED = Variable::output("U_applied")
                .unit("N")
                .describe("Force actually applied during the last step (U saturated)")
                .depends_on(&[vr::U]),
            M_CART = Variable::parameter("M", p.cart_mass)
                .unit("kg")
                .min(0.0)
                .describe("Cart mass: cart 619.25 g + lid 90.55 g + positioners 134.05 g (paper 000, Annex A)"),
            M_LOAD = Variable::parameter("m", p.load_mass)
                .unit("kg")
                .min(0.0)
                .describe("Load mass"),
            L = Variable::parameter("l", p.rod_length)
                .unit("m")
                .min(0.0)
                .describe("Distance from the pivot to the load's centre of mass"),
            J = Variable::parameter("J", p.inertia)
                .unit("kg.m2")
                .min(0.0)
                .describe("Moment of inertia of the load about the pivot"),
            F_C = Variable::parameter("f_c", p.cart_friction)
                .unit("N.s/m")
                .min(0.0)
                .describe("Viscous friction of the cart on the rail"),
            F_P = Variable::parameter("f_p", p.pivot_friction)
                .unit("kg.m2/(rad.s)")
                .min(0.0)
                .describe("Viscous friction at the pivot"),
            G = Variable::parameter("g", p.gravity)
                .unit("m/s2")
                .min(0.0)
                .describe("Gravitational acceleration"),
            U_MAX = Variable::parameter("U_max", p.max_force)
                .unit("N")
                .min(0.0)
                .describe("Actuator limit: the applied force is U clipped to ±U_max"),
            X_LIMIT = Variable::parameter("x_limit", p.rail_limit)
                .unit("m")
                .min(0.0)
                .describe("Rail end stops at ±x_limit (perfectly inelastic)"),
            X0 = Variable::parameter("x0", 0.0)
                .unit("m")
                .describe("Initial cart position"),
            THETA0 = Variable::parameter("theta0", 0.0)
                .unit("rad")
                .describe("Initial load angle"),
            V0 = Variable::parameter("v0", 0.0)
                .unit("m/s")
                .describe("Initial cart velocity"),
            OMEGA0 = Variable::parameter("omega0", 0.0)
                .unit("rad/s")
                .describe("Initial load angular velocity"),
            H_MAX = Variable::parameter("h_max", 1e-3)
                .unit("s")
                .min(0.0)
                .describe("Longest RK4 substep inside fmi2DoStep; steps are cut into equal substeps no longer than this"),
        ]
    }
}

/// The GantryCrane FMU: the crane, the substep bound and whether the rail stop was logged.
#[derive(Debug, Clone)]
pub struct GantryCraneFmu {
    crane: GantryCrane,
    h_max: f64,
    stop_logged: bool,
}

impl GantryCraneFmu {
    fn write_outputs(&self, ctx: &mut Context, applied: f64) {
        let s = self.crane.state;
        ctx.values.set_real(vr::X, s[0]);
        ctx.values.set_real(vr::THETA, s[1]);
        ctx.values.set_real(vr::V, s[2]);
        ctx.values.set_real(vr::OMEGA, s[3]);
        ctx.values.set_real(vr::U_APPLIED, applied);
    }
}

impl FmuModel for GantryCraneFmu {
    fn describe(_config: &Config) -> Result<ModelInfo, Cause> {
        Ok(ModelInfo::new(
            "GantryCrane",
            "Nonlinear gantry crane (cart + pendulum load) of paper 000, Annex A parameters, RK4 inside fmi2DoStep",
            variables(),
            Some(DefaultExperiment {
                start_time: 0.0,
                stop_time: 10.0,
                step_size: 0.05,
            }),
            Config::new(),
        ))
    }

    fn create(_info: &ModelInfo) -> Result<Self, Cause> {
        Ok(Self {
            crane: GantryCrane {
                parameters: GantryCraneParameters::default(),
                state: Default::default(),
            },
            h_max: 1e-3,
            stop_logged: false,
        })
    }

    fn initialize(&mut self, ctx: &mut Context) -> Result<(), Failure> {
        let r = |i| ctx.values.real(i);
        let parameters = GantryCraneParameters {
            cart_mass: r(vr::M_CART),
            load_mass: r(vr::M_LOAD),
            rod_length: r(vr::L),
            inertia: r(vr::J),
            cart_friction: r(vr::F_C),
            pivot_friction: r(vr::F_P),
            gravity: r(vr::G),
            max_force: r(vr::U_MAX),
            rail_limit: r(vr::X_LIMIT),
        };
        let state = [r(vr::X0), r(vr::THETA0), r(vr::V0), r(vr::OMEGA0)].into();
        self.crane = GantryCrane::new(parameters, state).map_err(Failure::error)?;
        self.h_max = spurio::require_positive("h_max", r(vr::H_MAX)).map_err(Failure::error)?;
        self.stop_logged = false;
        let applied = parameters.saturate(r(vr::U));
        self.write_outputs(ctx, applied);
        Ok(())
    }

    fn do_step(&mut self, ctx: &mut Context, time: f64, step: f64) -> Result<(), Failure> {
        let u = ctx.values.real(vr::U);
        let report = self.crane.advance(time, u, step, self.h_max);
        if let (Some((t, x)), false) = (report.hit_stop, self.stop_logged) {
            self.stop_logged = true;
            ctx.log_event(format!(
                "the cart reached the rail end x = {x:+} m at t = {t:.4} s: its velocity into the stop was set to zero (logged once)"
            ));
        }
        self.write_outputs(ctx, self.crane.parameters.saturate(u));
        Ok(())
    }

    spurio_fmu_common::fmu_state!(crane, h_max, stop_logged);
}

spurio_export::export_fmu!(GantryCraneFmu);
