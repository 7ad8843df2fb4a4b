//! `GantryCrane.fmu`: the nonlinear crane of paper 000 (docs/models.md §2.1) as an FMI 2.0 CS FMU.
//!
//! Input `U` [N] (saturated at ±`U_max`), outputs `x`, `theta`, `v`, `omega` and the applied
//! force `U_applied`; the physical parameters of Annex A, the initial state and the RK4
//! substep bound `h_max`. The mathematics is [`spurio::plants::gantry_crane`].

use spurio::plants::gantry_crane::{GantryCrane, GantryCraneParameters};
use spurio_export::rows::{input, output, parameter};
use spurio_export::{Cause, Config, Context, DefaultExperiment, Failure, FmuModel, ModelInfo};

spurio_export::declare_variables! {
    /// The variable table, in value-reference order.
    pub fn variables() {
        let p = GantryCraneParameters::default();
        table: [
            U = input("U", 0.0, "N", "Force on the cart requested by the controller (saturated at ±U_max)"),
            X = output("x", "m", "Cart position on the rail"),
            THETA = output("theta", "rad", "Load angle, 0 hanging straight down"),
            V = output("v", "m/s", "Cart velocity"),
            OMEGA = output("omega", "rad/s", "Load angular velocity"),
            U_APPLIED = output("U_applied", "N",
                "Force actually applied during the last step (U saturated)").depends_on(&[vr::U]),
            M_CART = parameter("M", p.cart_mass, "kg",
                "Cart mass: cart 619.25 g + lid 90.55 g + positioners 134.05 g (paper 000, Annex A)").min(0.0),
            M_LOAD = parameter("m", p.load_mass, "kg", "Load mass").min(0.0),
            L = parameter("l", p.rod_length, "m",
                "Distance from the pivot to the load's centre of mass").min(0.0),
            J = parameter("J", p.inertia, "kg.m2", "Moment of inertia of the load about the pivot").min(0.0),
            F_C = parameter("f_c", p.cart_friction, "N.s/m",
                "Viscous friction of the cart on the rail").min(0.0),
            F_P = parameter("f_p", p.pivot_friction, "kg.m2/(rad.s)",
                "Viscous friction at the pivot").min(0.0),
            G = parameter("g", p.gravity, "m/s2", "Gravitational acceleration").min(0.0),
            U_MAX = parameter("U_max", p.max_force, "N",
                "Actuator limit: the applied force is U clipped to ±U_max").min(0.0),
            X_LIMIT = parameter("x_limit", p.rail_limit, "m",
                "Rail end stops at ±x_limit (perfectly inelastic)").min(0.0),
            X0 = parameter("x0", 0.0, "m", "Initial cart position"),
            THETA0 = parameter("theta0", 0.0, "rad", "Initial load angle"),
            V0 = parameter("v0", 0.0, "m/s", "Initial cart velocity"),
            OMEGA0 = parameter("omega0", 0.0, "rad/s", "Initial load angular velocity"),
            H_MAX = parameter("h_max", 1e-3, "s",
                "Longest RK4 substep inside fmi2DoStep; steps are cut into equal substeps no longer than this").min(0.0),
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
