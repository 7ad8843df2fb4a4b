//! `GantryCrane.fmu`: the nonlinear crane of paper 000 (docs/models.md §2.1) as one FMU with
//! both interfaces, Co-Simulation and Model Exchange.
//!
//! Input `U` [N] (saturated at ±`U_max`), outputs `x`, `theta`, `v`, `omega` and the applied
//! force `U_applied`; the physical parameters of Annex A, the initial state, the RK4 substep
//! bound `h_max` and the adaptive integrator's `tolerance` (0: RK4). Model Exchange: the
//! outputs `x`…`omega` are the continuous states, `der(x)`…`der(omega)` their derivatives, the
//! rail contact (free, held left, held right) the discrete state, with three event indicators
//! (each stop, the force limit); exact directional derivatives on both interfaces. The
//! mathematics, one right-hand side for both, is [`spurio::plants::gantry_crane`].
//!
//! Bounded work: every parameter has a declared range (a laboratory crane up to 10⁴ kg and
//! 100 m, |ω₀| ≤ 10³ rad/s, 10⁻⁹ s ≤ `h_max` ≤ 1 s), checked when it is set, and a step that
//! would need more than [`spurio::ode::MAX_SUBSTEPS`] RK4 substeps is refused (`fmi2Error`,
//! nothing changed).

use nalgebra::{Matrix4, Vector4};
use spurio::plants::gantry_crane::{
    CraneState, GantryCrane, GantryCraneParameters, Integrator, RailContact,
};
use spurio_export::rows::{derivative, event_indicator, input, output, parameter};
use spurio_export::{
    Cause, Config, Context, DefaultExperiment, EventUpdate, Failure, FmuModel, ModelExchange,
    ModelInfo,
};

spurio_export::declare_variables! {
    /// The variable table, in value-reference order.
    pub fn variables() {
        let p = GantryCraneParameters::default();
        table: [
            U = input("U", 0.0, "N", "Force on the cart requested by the controller (saturated at ±U_max)"),
            X = output("x", "m", "Cart position on the rail (a continuous state)")
                .state().nominal(0.1).depends_on(&[vr::X]),
            THETA = output("theta", "rad", "Load angle, 0 hanging straight down (a continuous state)")
                .state().nominal(0.1).depends_on(&[vr::THETA]),
            V = output("v", "m/s", "Cart velocity (a continuous state)")
                .state().nominal(0.1).depends_on(&[vr::V]),
            OMEGA = output("omega", "rad/s", "Load angular velocity (a continuous state)")
                .state().depends_on(&[vr::OMEGA]),
            U_APPLIED = output("U_applied", "N",
                "Force actually applied during the last step (U saturated)").depends_on(&[vr::U]),
            M_CART = parameter("M", p.cart_mass, "kg",
                "Cart mass: cart 619.25 g + lid 90.55 g + positioners 134.05 g (paper 000, Annex A)").min(0.0).max(1e4),
            M_LOAD = parameter("m", p.load_mass, "kg", "Load mass").min(0.0).max(1e4),
            L = parameter("l", p.rod_length, "m",
                "Distance from the pivot to the load's centre of mass").min(0.0).max(100.0),
            J = parameter("J", p.inertia, "kg.m2", "Moment of inertia of the load about the pivot").min(0.0).max(1e4),
            F_C = parameter("f_c", p.cart_friction, "N.s/m",
                "Viscous friction of the cart on the rail").min(0.0).max(1e4),
            F_P = parameter("f_p", p.pivot_friction, "kg.m2/(rad.s)",
                "Viscous friction at the pivot").min(0.0).max(1e4),
            G = parameter("g", p.gravity, "m/s2", "Gravitational acceleration").min(0.0).max(100.0),
            U_MAX = parameter("U_max", p.max_force, "N",
                "Actuator limit: the applied force is U clipped to ±U_max").min(0.0).max(1e6),
            X_LIMIT = parameter("x_limit", p.rail_limit, "m",
                "Rail end stops at ±x_limit (perfectly inelastic)").min(0.0).max(1e3),
            X0 = parameter("x0", 0.0, "m", "Initial cart position").min(-1e3).max(1e3),
            THETA0 = parameter("theta0", 0.0, "rad", "Initial load angle").min(-100.0).max(100.0),
            V0 = parameter("v0", 0.0, "m/s", "Initial cart velocity").min(-1e3).max(1e3),
            OMEGA0 = parameter("omega0", 0.0, "rad/s", "Initial load angular velocity").min(-1e3).max(1e3),
            H_MAX = parameter("h_max", 1e-3, "s",
                "Longest RK4 substep inside fmi2DoStep; steps are cut into equal substeps no longer than this (at most 100000 per step)").min(1e-9).max(1.0),
            TOLERANCE = parameter("tolerance", 0.0, "1",
                "Integrator of fmi2DoStep: 0, RK4 substeps of h_max (the default); > 0, the adaptive Dormand-Prince 5(4) with this error tolerance (1e-11: as accurate as RK4 at 1 ms, a third of the work)").min(0.0).max(1e-2),
            DER_X = derivative("der(x)", vr::X, "m/s", "Cart velocity; 0 while held against a stop")
                .depends_on(&[vr::V]),
            DER_THETA = derivative("der(theta)", vr::THETA, "rad/s", "Load angular velocity")
                .depends_on(&[vr::OMEGA]),
            DER_V = derivative("der(v)", vr::V, "m/s2", "Cart acceleration; 0 while held against a stop")
                .depends_on(&[vr::THETA, vr::V, vr::OMEGA, vr::U]),
            DER_OMEGA = derivative("der(omega)", vr::OMEGA, "rad/s2", "Load angular acceleration")
                .depends_on(&[vr::THETA, vr::V, vr::OMEGA, vr::U]),
            Z_RIGHT = event_indicator("stop_right", "1",
                "Model Exchange event indicator: free, x_limit - x (the cart reaches the right stop); held there, the free cart acceleration (release when the net force turns inwards)"),
            Z_LEFT = event_indicator("stop_left", "1",
                "Model Exchange event indicator: free, x + x_limit (the cart reaches the left stop); held there, minus the free cart acceleration"),
            Z_FORCE = event_indicator("force_limit", "N",
                "Model Exchange event indicator: U_max - |U| (the requested force crosses the actuator limit)"),
        ]
    }
}

/// The GantryCrane FMU: the crane, the substep bound, whether the rail stop was logged, the
/// adaptive integrator's tolerance (0: RK4) and next step size, and the contact with the rail
/// stops (the Model Exchange interface's discrete state; after a Co-Simulation step, the
/// contact read from the state).
#[derive(Debug, Clone)]
pub struct GantryCraneFmu {
    crane: GantryCrane,
    h_max: f64,
    stop_logged: bool,
    tolerance: f64,
    step_guess: f64,
    contact: RailContact,
}

/// The state variables in state order.
const STATES: [usize; 4] = [vr::X, vr::THETA, vr::V, vr::OMEGA];
/// Their derivatives, in the same order.
const DERIVATIVES: [usize; 4] = [vr::DER_X, vr::DER_THETA, vr::DER_V, vr::DER_OMEGA];

impl GantryCraneFmu {
    /// The state `[x, θ, ẋ, θ̇]` from the state variables (set by the solver in Model Exchange).
    fn state_values(ctx: &Context) -> CraneState {
        STATES.map(|k| ctx.values.real(k)).into()
    }

    /// The contact the current state is in (the Co-Simulation rule, also the start of Model
    /// Exchange before the first event iteration).
    fn contact_of_state(&self, u: f64) -> RailContact {
        let p = &self.crane.parameters;
        let s = &self.crane.state;
        p.contact(s, p.free_accelerations(s, p.saturate(u)).0)
    }

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
        )
        .with_model_exchange()?)
    }

    fn create(_info: &ModelInfo) -> Result<Self, Cause> {
        Ok(Self {
            crane: GantryCrane {
                parameters: GantryCraneParameters::default(),
                state: Default::default(),
            },
            h_max: 1e-3,
            stop_logged: false,
            tolerance: 0.0,
            step_guess: 0.0,
            contact: RailContact::Free,
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
        self.tolerance =
            spurio::require_non_negative("tolerance", r(vr::TOLERANCE)).map_err(Failure::error)?;
        self.step_guess = 0.0;
        let u = r(vr::U);
        self.contact = self.contact_of_state(u);
        self.write_outputs(ctx, parameters.saturate(u));
        Ok(())
    }

    fn check_step(&self, _ctx: &Context, _time: f64, step: f64) -> Result<(), Cause> {
        if self.tolerance == 0.0 {
            spurio::ode::check_substeps(step, self.h_max)?;
        }
        Ok(())
    }

    fn do_step(&mut self, ctx: &mut Context, time: f64, step: f64) -> Result<(), Failure> {
        let u = ctx.values.real(vr::U);
        let integrator = if self.tolerance > 0.0 {
            Integrator::DormandPrince {
                tolerance: self.tolerance,
            }
        } else {
            Integrator::Rk4 { h_max: self.h_max }
        };
        let report = self
            .crane
            .advance_with(time, u, step, integrator, &mut self.step_guess)
            .map_err(Failure::error)?;
        if let (Some((t, x)), false) = (report.hit_stop, self.stop_logged) {
            self.stop_logged = true;
            ctx.log_event(|| format!(
                "the cart reached the rail end x = {x:+} m at t = {t:.4} s: its velocity into the stop was set to zero (logged once)"
            ));
        }
        self.contact = self.contact_of_state(u);
        self.write_outputs(ctx, self.crane.parameters.saturate(u));
        Ok(())
    }

    spurio_fmu_common::fmu_state!(crane, h_max, stop_logged, tolerance, step_guess, contact; check = |m: &Self| {
        GantryCrane::new(m.crane.parameters, m.crane.state)?;
        spurio::require_positive("h_max", m.h_max)?;
        spurio::require_non_negative("tolerance", m.tolerance)?;
        spurio::require_finite("step_guess", m.step_guess)?;
        Ok(())
    });
}

impl ModelExchange for GantryCraneFmu {
    fn evaluate(&mut self, ctx: &mut Context) -> Result<(), Failure> {
        let p = self.crane.parameters;
        let s = Self::state_values(ctx);
        let applied = p.saturate(ctx.values.real(vr::U));
        let derivative = p.rhs(&s, applied, self.contact);
        for (k, d) in DERIVATIVES.iter().zip(derivative.iter()) {
            ctx.values.set_real(*k, *d);
        }
        ctx.values.set_real(vr::U_APPLIED, applied);
        Ok(())
    }

    fn event_indicators(&mut self, ctx: &mut Context, z: &mut [f64]) -> Result<(), Failure> {
        let s = Self::state_values(ctx);
        let u = ctx.values.real(vr::U);
        let indicators = self.crane.parameters.event_indicators(&s, u, self.contact);
        for (z, value) in z.iter_mut().zip(indicators) {
            *z = value;
        }
        Ok(())
    }

    fn update_discrete_states(&mut self, ctx: &mut Context) -> Result<EventUpdate, Failure> {
        let p = self.crane.parameters;
        let s = Self::state_values(ctx);
        let (next, contact) = p.at_event(&s, p.saturate(ctx.values.real(vr::U)));
        let mut update = EventUpdate::default();
        if next != s {
            for (k, value) in STATES.iter().zip(next.iter()) {
                ctx.values.set_real(*k, *value);
            }
            update.states_changed = true;
        }
        if update.states_changed || contact != self.contact {
            let what = match contact {
                RailContact::Free if update.states_changed => {
                    "the cart is free on the rail after its velocity into the stop was set to zero"
                }
                RailContact::Free => "the cart is free on the rail",
                RailContact::HeldLeft => "the cart is held against the left stop",
                RailContact::HeldRight => "the cart is held against the right stop",
            };
            let time = ctx.time();
            ctx.log_event(|| {
                format!(
                    "t = {} s: {what} (x = {:+} m, v = {} m/s)",
                    time, next[0], next[2]
                )
            });
            self.contact = contact;
        }
        self.crane.state = next;
        Ok(update)
    }

    /// `∂f/∂s` and `∂f/∂u` at the current state, with the saturation's slope at the force.
    type Jacobian = (Matrix4<f64>, Vector4<f64>, f64);

    fn jacobian(&mut self, ctx: &Context) -> Result<Self::Jacobian, Failure> {
        let p = self.crane.parameters;
        let u = ctx.values.real(vr::U);
        let (dfds, dfdu) = p.jacobian(&Self::state_values(ctx), p.saturate(u), self.contact);
        Ok((dfds, dfdu, p.saturation_slope(u)))
    }

    fn partial(&self, at: &Self::Jacobian, unknown: usize, known: usize) -> Result<f64, Failure> {
        let (dfds, dfdu, slope) = at;
        // column of a known: the state's position, or 4 for the force
        let j = match known {
            vr::U => 4,
            k => STATES.iter().position(|&x| x == k).ok_or_else(|| {
                Failure::error(format!(
                    "directional derivative: value reference {k} is not a state or the input U"
                ))
            })?,
        };
        Ok(
            if let Some(i) = DERIVATIVES.iter().position(|&d| d == unknown) {
                if j == 4 {
                    dfdu[i] * slope
                } else {
                    dfds[(i, j)]
                }
            } else if let Some(i) = STATES.iter().position(|&x| x == unknown) {
                f64::from(u8::from(i == j))
            } else if unknown == vr::U_APPLIED {
                if j == 4 {
                    *slope
                } else {
                    0.0
                }
            } else {
                return Err(Failure::error(format!(
                "directional derivative: value reference {unknown} is not a derivative or an output"
            )));
            },
        )
    }
}

spurio_export::export_fmu!(GantryCraneFmu, model_exchange);

#[cfg(test)]
mod tests {
    use super::*;
    use spurio_export::harness::Harness;
    use spurio_export::types::Status;
    use std::time::Instant;

    fn crane() -> Harness<GantryCraneFmu> {
        Harness::new(&Config::new()).unwrap()
    }

    #[test]
    fn a_step_needing_too_many_substeps_is_refused_at_once() {
        let mut h = crane();
        h.set_real(&[vr::H_MAX as u32, vr::THETA0 as u32], &[1e-9, 0.1])
            .unwrap();
        h.initialize(0.0).unwrap();
        spurio_fmu_common::refuses_too_many_substeps(&mut h, 1.0).unwrap();
        // nothing changed: the next step within the bound is taken from t = 0, theta = 0.1
        assert_eq!(h.real(vr::THETA as u32).unwrap(), 0.1);
        h.do_step(0.0, 1e-5).unwrap();
        assert!((h.real(vr::THETA as u32).unwrap() - 0.1).abs() < 1e-6);
        assert_eq!(h.last_successful_time().unwrap(), 1e-5);
    }

    #[test]
    fn the_largest_step_allowed_returns_quickly() {
        let mut h = crane();
        h.initialize(0.0).unwrap();
        let start = Instant::now();
        // 100 s at h_max = 1 ms: 10⁵ substeps, the bound
        h.do_step(0.0, 100.0).unwrap();
        assert!(start.elapsed().as_secs_f64() < 1.0);
        assert!(h.real(vr::X as u32).unwrap().is_finite());
    }

    #[test]
    fn parameters_outside_their_declared_range_are_refused() {
        let mut h = crane();
        for (vr, value, words) in [
            (
                vr::OMEGA0,
                1e6,
                "`omega0` = 1000000 is above its maximum 1000",
            ),
            (vr::H_MAX, 1e-300, "`h_max` = 0.000"),
            (vr::M_CART, -1e308, "`M` = -1"),
        ] {
            assert_eq!(h.set_real(&[vr as u32], &[value]), Err(Status::Error));
            assert!(h.logged(&[words]), "{words}: {:?}", h.log());
        }
    }

    #[test]
    fn a_loaded_state_with_impossible_parameters_is_refused() {
        let mut h = crane();
        h.initialize(0.0).unwrap();
        let good = h.serialized_state().unwrap();
        // the model's part ends with the plain bytes of crane (9 parameters, 4 states),
        // h_max, stop_logged, tolerance, step_guess and contact: make the cart mass (first
        // parameter) negative
        let model_part = good.len() - (9 + 4 + 1) * 8 - 1 - 2 * 8 - 1;
        let mut bad = good.clone();
        bad[model_part..model_part + 8].copy_from_slice(&(-1.0f64).to_le_bytes());
        assert_eq!(h.restore_state(&bad), Err(Status::Error));
        assert!(
            h.logged(&["fmi2DeSerializeFMUstate", "parameter `M`"]),
            "{:?}",
            h.log()
        );
        h.restore_state(&good).unwrap();
    }

    #[test]
    fn an_unstable_configuration_ends_in_an_error_never_in_a_nan_output() {
        // RK4 with 1 s substeps on a pendulum spinning at 10³ rad/s blows up within steps
        let mut h = crane();
        h.set_real(
            &[vr::H_MAX as u32, vr::OMEGA0 as u32, vr::V0 as u32],
            &[1.0, 1e3, 1e3],
        )
        .unwrap();
        h.initialize(0.0).unwrap();
        let outputs = [vr::X, vr::THETA, vr::V, vr::OMEGA].map(|v| v as u32);
        let mut out = [0.0; 4];
        let mut k = 0;
        while h.do_step(k as f64, 1.0).is_ok() {
            h.get_real(&outputs, &mut out).unwrap();
            assert!(out.iter().all(|v| v.is_finite()), "{out:?} with fmi2OK");
            k += 1;
            assert!(k < 100, "the configuration was expected to overflow");
        }
        assert!(
            h.logged(&["fmi2DoStep: variable `", "came out as", "not published"]),
            "{:?}",
            h.log()
        );
        // the values stay those of the last communication point, all finite
        h.get_real(&outputs, &mut out).unwrap();
        assert!(out.iter().all(|v| v.is_finite()), "{out:?}");
        assert!(k >= 1);
    }
}
