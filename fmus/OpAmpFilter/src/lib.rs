//! `OpAmpFilter.fmu`: the unity-gain Sallen–Key low-pass of paper 002 (§III, eq. 9; docs/models.md
//! §2.3) as an FMI 2.0 FMU with both interfaces, Co-Simulation and Model Exchange.
//!
//! Input `u` [V], output `y` [V] (the op-amp output, clipped to `[V_sat_low, V_sat_high]`),
//! plus the capacitor voltages. Component values are parameters; the defaults give
//! `H(s) = 27/(s² + 5.19 s + 27)`:
//!
//! ```text
//! C1 dv₁/dt = (u − V_A)/R1 − (V_A − v₂)/R2,   V_A = v₁ + y
//! C2 dv₂/dt = (V_A − v₂)/R2,                  y = clamp(v₂, V_sat_low, V_sat_high)
//! H(s) = 1/(R1 R2 C1 C2 s² + C2 (R1 + R2) s + 1)
//! ```
//!
//! The mathematics is [`spurio::plants::opamp_filter`]; RK4 on substeps no longer than
//! `h_max` inside `fmi2DoStep`. A substep too long for RK4 to be stable on the circuit's
//! fastest mode (`h_max · |λ|max > 2.5`, |λ|max over the linear poles and the saturated
//! modes `(1/R1 + 1/R2)/C1`, `1/(R2 C2)`) is refused with an error naming `h_max`.
//!
//! **Model Exchange**: the states are the capacitor voltages `v_C1`, `v_C2` (derivatives
//! `der(v_C1)`, `der(v_C2)`), the right-hand side is the same
//! [`OpAmpFilterParameters::derivative_on`] the CS integrator uses, with the output's rail held
//! between events. Two event indicators, `V_sat_high − v_C2` and `v_C2 − V_sat_low`: when one
//! changes sign the output reaches or leaves a rail, and in event mode the rail is switched
//! (`saturated` changes; no state jumps). Directional derivatives (on both interfaces) are the
//! analytic Jacobians of the math crate.
//!
//! Bounded work: every parameter has a declared range (1 Ω to 1 GΩ, 1 fF to 1 F, rails and
//! initial voltages within ±1 kV, 10⁻⁹ s ≤ `h_max` ≤ 1 s), checked when it is set, and a step
//! that would need more than [`spurio::ode::MAX_SUBSTEPS`] RK4 substeps is refused
//! (`fmi2Error`, nothing changed).

use nalgebra::Vector2;
use spurio::plants::opamp_filter::{OpAmpFilter, OpAmpFilterParameters, Rail};
use spurio_export::rows::{derivative, event_indicator, input, output, parameter};
use spurio_export::{
    Cause, Config, Context, DefaultExperiment, EventUpdate, Failure, FmuModel, ModelExchange,
    ModelInfo, Variable,
};

pub use spurio_fmu_common::RK4_STABILITY_MARGIN;
use spurio_fmu_common::{advance_finite, rk4_substep};

spurio_export::declare_variables! {
    /// The variable table, in value-reference order.
    pub fn variables() {
        let p = OpAmpFilterParameters::default();
        table: [
            U = input("u", 0.0, "V", "Input voltage"),
            Y = output("y", "V", "Output voltage of the op-amp (within the supply rails)")
                .depends_on(&[vr::V_C2]),
            V_C1 = output("v_C1", "V", "Voltage across C1 (node A minus output)")
                .state()
                .depends_on(&[vr::V_C1]),
            V_C2 = output("v_C2", "V", "Voltage across C2 (node B to ground, the op-amp's + input)")
                .state()
                .depends_on(&[vr::V_C2]),
            SATURATED = Variable::boolean_output("saturated")
                .describe("Whether the output sits on a rail at this communication point"),
            R1 = parameter("R1", p.r1, "Ohm",
                "Input resistor (default: with R2, C1, C2 gives H(s) = 27/(s^2 + 5.19 s + 27))").min(1.0).max(1e9),
            R2 = parameter("R2", p.r2, "Ohm", "Resistor between node A and node B").min(1.0).max(1e9),
            C1 = parameter("C1", p.c1, "F", "Feedback capacitor from node A to the output (4.7 uF)").min(1e-15).max(1.0),
            C2 = parameter("C2", p.c2, "F", "Capacitor from node B to ground (1 uF)").min(1e-15).max(1.0),
            V_SAT_HIGH = parameter("V_sat_high", p.v_sat_high, "V",
                "Upper output saturation (positive rail less headroom)").min(-1e3).max(1e3),
            V_SAT_LOW = parameter("V_sat_low", p.v_sat_low, "V",
                "Lower output saturation (negative rail less headroom)").min(-1e3).max(1e3),
            V_C1_0 = parameter("v_C1_0", 0.0, "V", "Initial voltage across C1").min(-1e3).max(1e3),
            V_C2_0 = parameter("v_C2_0", 0.0, "V", "Initial voltage across C2").min(-1e3).max(1e3),
            H_MAX = parameter("h_max", 1e-3, "s", "Longest RK4 substep inside fmi2DoStep (at most 100000 per step)")
                .min(1e-9)
                .max(1.0),
            DER_V_C1 = derivative("der(v_C1)", vr::V_C1, "V/s", "Time derivative of v_C1")
                .depends_on(&[vr::U, vr::V_C1, vr::V_C2]),
            DER_V_C2 = derivative("der(v_C2)", vr::V_C2, "V/s", "Time derivative of v_C2")
                .depends_on(&[vr::V_C1, vr::V_C2]),
            Z_RAIL_HIGH = event_indicator("z_rail_high", "V",
                "Event indicator V_sat_high - v_C2: the output reaches or leaves the upper rail where it changes sign"),
            Z_RAIL_LOW = event_indicator("z_rail_low", "V",
                "Event indicator v_C2 - V_sat_low: the output reaches or leaves the lower rail where it changes sign"),
        ]
    }
}

/// Largest |eigenvalue| the integrator meets: the linear poles and the saturated modes.
pub fn fastest_mode(p: &OpAmpFilterParameters) -> f64 {
    let (a, _, _) = p.state_space();
    // Poles of s² − tr(A) s + det(A).
    let (tr, det) = (a.trace(), a.determinant());
    let disc = tr * tr - 4.0 * det;
    let linear = if disc >= 0.0 {
        0.5 * (tr.abs() + disc.sqrt())
    } else {
        det.sqrt()
    };
    let saturated = ((1.0 / p.r1 + 1.0 / p.r2) / p.c1).max(1.0 / (p.r2 * p.c2));
    linear.max(saturated)
}

/// Number of event indicators (`z_rail_high`, `z_rail_low`).
pub const EVENT_INDICATORS: usize = 2;

/// The OpAmpFilter FMU.
#[derive(Debug, Clone)]
pub struct OpAmpFilterFmu {
    filter: OpAmpFilter,
    h_max: f64,
    /// The output's rail: on Model Exchange held between events (switched in event mode), on
    /// Co-Simulation the rail of the state the last step left.
    rail: Rail,
}

impl OpAmpFilterFmu {
    /// Writes the states and outputs of the capacitor voltages `v` on the rail held.
    fn write_outputs(&self, ctx: &mut Context, v: &Vector2<f64>) {
        let p = &self.filter.parameters;
        ctx.values.set_real(vr::Y, p.output_on(v[1], self.rail));
        ctx.values.set_real(vr::V_C1, v[0]);
        ctx.values.set_real(vr::V_C2, v[1]);
        ctx.values
            .set_boolean(vr::SATURATED, self.rail != Rail::Inside);
    }

    /// The capacitor voltages in the state variables.
    fn states(ctx: &Context) -> Vector2<f64> {
        Vector2::new(ctx.values.real(vr::V_C1), ctx.values.real(vr::V_C2))
    }
}

/// The error for a value reference that is not one the call accepts.
fn not_a(reference: usize, what: &str) -> Failure {
    Failure::error(format!(
        "fmi2GetDirectionalDerivative: value reference {reference} is not a {what}"
    ))
}

impl FmuModel for OpAmpFilterFmu {
    fn describe(_config: &Config) -> Result<ModelInfo, Cause> {
        Ok(ModelInfo::new(
            "OpAmpFilter",
            "Sallen-Key op-amp low-pass of paper 002, H(s) = 27/(s^2 + 5.19 s + 27) by default, output saturated at the rails",
            variables(),
            Some(DefaultExperiment {
                start_time: 0.0,
                stop_time: 5.0,
                step_size: 0.01,
            }),
            Config::new(),
        )
        .with_model_exchange()
        .map_err(|e| e.to_string())?)
    }

    fn create(_info: &ModelInfo) -> Result<Self, Cause> {
        Ok(Self {
            filter: OpAmpFilter {
                parameters: OpAmpFilterParameters::default(),
                state: Default::default(),
            },
            h_max: 1e-3,
            rail: Rail::Inside,
        })
    }

    fn initialize(&mut self, ctx: &mut Context) -> Result<(), Failure> {
        let r = |i| ctx.values.real(i);
        let [r1, r2, c1, c2, v_sat_high, v_sat_low] = [
            vr::R1,
            vr::R2,
            vr::C1,
            vr::C2,
            vr::V_SAT_HIGH,
            vr::V_SAT_LOW,
        ]
        .map(r);
        let parameters = OpAmpFilterParameters {
            r1,
            r2,
            c1,
            c2,
            v_sat_high,
            v_sat_low,
        };
        let state = [r(vr::V_C1_0), r(vr::V_C2_0)].into();
        let filter = OpAmpFilter::with_state(parameters, state).map_err(Failure::error)?;
        let fastest = fastest_mode(&parameters);
        let mode = format!("the circuit's fastest mode ({fastest:.4} 1/s)");
        let h_max = rk4_substep(r(vr::H_MAX), fastest, &mode)?;
        self.rail = parameters.rail_of(filter.state[1]);
        self.filter = filter;
        self.h_max = h_max;
        self.write_outputs(ctx, &state);
        Ok(())
    }

    spurio_fmu_common::rk4_check_step!(h_max);

    fn do_step(&mut self, ctx: &mut Context, time: f64, step: f64) -> Result<(), Failure> {
        let u = ctx.values.real(vr::U);
        let h_max = self.h_max;
        advance_finite(
            &mut self.filter,
            |f| f.advance(time, u, step, h_max),
            |f| f.state.iter().all(|v| v.is_finite()),
            || {
                format!("the capacitor voltages became non-finite in the step from t = {time} (input u = {u})")
            },
        )?;
        let state = self.filter.state;
        self.rail = self.filter.parameters.rail_of(state[1]);
        self.write_outputs(ctx, &state);
        Ok(())
    }

    spurio_fmu_common::fmu_state!(filter, h_max, rail; check = |m: &Self| {
        OpAmpFilter::with_state(m.filter.parameters, m.filter.state)?;
        spurio::require_positive("h_max", m.h_max)?;
        Ok(())
    });
}

impl ModelExchange for OpAmpFilterFmu {
    fn evaluate(&mut self, ctx: &mut Context) -> Result<(), Failure> {
        let v = Self::states(ctx);
        let u = ctx.values.real(vr::U);
        let dv = self.filter.parameters.derivative_on(&v, u, self.rail);
        ctx.values.set_real(vr::DER_V_C1, dv[0]);
        ctx.values.set_real(vr::DER_V_C2, dv[1]);
        self.write_outputs(ctx, &v);
        Ok(())
    }

    fn event_indicators(&mut self, ctx: &mut Context, z: &mut [f64]) -> Result<(), Failure> {
        let indicators = self.filter.parameters.event_indicators(&Self::states(ctx));
        for (z, value) in z.iter_mut().zip(indicators) {
            *z = value;
        }
        Ok(())
    }

    fn update_discrete_states(&mut self, ctx: &mut Context) -> Result<EventUpdate, Failure> {
        let v = Self::states(ctx);
        let rail = self.filter.parameters.rail_of(v[1]);
        if rail != self.rail {
            let time = ctx.time();
            ctx.log_event(|| {
                format!(
                    "t = {}: the output {} (v_C2 = {} V)",
                    time,
                    match rail {
                        Rail::Inside => "leaves its rail",
                        Rail::High => "reaches the upper rail",
                        Rail::Low => "reaches the lower rail",
                    },
                    v[1]
                )
            });
            self.rail = rail;
            self.write_outputs(ctx, &v);
        }
        Ok(EventUpdate::default())
    }

    /// Nothing precomputed: the entries depend on the rail the model holds.
    type Jacobian = ();

    fn jacobian(&mut self, _ctx: &Context) -> Result<(), Failure> {
        Ok(())
    }

    /// `∂unknown/∂known` on the rail held: `unknown` one of `der(v_C1)`, `der(v_C2)`, `y`,
    /// `v_C1`, `v_C2`; `known` one of `v_C1`, `v_C2`, `u`.
    fn partial(&self, _: &(), unknown: usize, known: usize) -> Result<f64, Failure> {
        let p = &self.filter.parameters;
        let column = match known {
            vr::V_C1 => 0,
            vr::V_C2 => 1,
            vr::U => 2,
            _ => return Err(not_a(known, "state or input (v_C1, v_C2, u)")),
        };
        let row = |derivatives: Vector2<f64>, input: f64| match column {
            2 => input,
            c => derivatives[c],
        };
        let identity = |state: usize| f64::from(u8::from(column == state));
        let jx = p.jacobian_state(self.rail);
        Ok(match unknown {
            vr::DER_V_C1 => row(jx.row(0).transpose(), p.jacobian_input()[0]),
            vr::DER_V_C2 => row(jx.row(1).transpose(), p.jacobian_input()[1]),
            vr::Y => identity(1) * p.output_slope(self.rail),
            vr::V_C1 => identity(0),
            vr::V_C2 => identity(1),
            _ => {
                return Err(not_a(
                    unknown,
                    "derivative or output (der(v_C1), der(v_C2), y, v_C1, v_C2)",
                ))
            }
        })
    }
}

spurio_export::export_fmu!(OpAmpFilterFmu, model_exchange);

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fastest_mode_of_the_defaults_is_the_saturated_c2_mode() {
        let p = OpAmpFilterParameters::default();
        // Linear poles |λ| = √27; saturated modes (1/R1 + 1/R2)/C1 ≈ 5.19, 1/(R2 C2) ≈ 16.9.
        let f = fastest_mode(&p);
        assert!((f - 1.0 / (p.r2 * p.c2)).abs() < 1e-9, "{f}");
    }

    use spurio_export::Values;

    /// A model initialised from the start values with the capacitor voltages `v`.
    fn model_at(values: &mut Values, v: [f64; 2]) -> OpAmpFilterFmu {
        let info = OpAmpFilterFmu::describe(&Config::new()).unwrap();
        let mut m = OpAmpFilterFmu::create(&info).unwrap();
        values.set_real(vr::V_C1_0, v[0]);
        values.set_real(vr::V_C2_0, v[1]);
        m.initialize(&mut Context::new(values)).unwrap();
        m
    }

    #[test]
    fn directional_derivatives_match_central_differences_of_evaluate() {
        let info = OpAmpFilterFmu::describe(&Config::new()).unwrap();
        let me = info.model_exchange.as_ref().unwrap();
        assert_eq!(me.states, [vr::V_C1, vr::V_C2]);
        assert_eq!(me.derivatives, [vr::DER_V_C1, vr::DER_V_C2]);
        let unknowns = [vr::DER_V_C1, vr::DER_V_C2, vr::Y, vr::V_C1, vr::V_C2];
        let knowns = [vr::V_C1, vr::V_C2, vr::U];
        // Inside the rails, and on each of them.
        for v in [[0.4, 3.0], [1.0, 14.0], [-2.0, -13.0]] {
            let mut values = Values::from_start(&info.variables);
            let mut m = model_at(&mut values, v);
            values.set_real(vr::U, 2.5);
            for (j, &known) in knowns.iter().enumerate() {
                let mut seed = [0.0; 3];
                seed[j] = 1.0;
                let mut analytic = [0.0; 5];
                let mut ctx = Context::new(&mut values);
                m.evaluate(&mut ctx).unwrap();
                m.directional_derivative(&mut ctx, &unknowns, &knowns, &seed, &mut analytic)
                    .unwrap();
                let base = values.real(known);
                let mut at = |value: f64| {
                    values.set_real(known, value);
                    m.evaluate(&mut Context::new(&mut values)).unwrap();
                    unknowns.map(|u| values.real(u))
                };
                let (plus, minus) = (at(base + 1e-4), at(base - 1e-4));
                values.set_real(known, base);
                for i in 0..5 {
                    let fd = (plus[i] - minus[i]) / 2e-4;
                    assert!(
                        (fd - analytic[i]).abs()
                            <= 1e-6 * fd.abs().max(analytic[i].abs()).max(1e-3),
                        "v = {v:?}: d{}/d{}: {fd} vs {}",
                        info.variables[unknowns[i]].name,
                        info.variables[known].name,
                        analytic[i]
                    );
                }
            }
        }
        // A value reference that is neither a state nor an input is refused.
        let mut values = Values::from_start(&info.variables);
        let mut m = model_at(&mut values, [0.0, 0.0]);
        let mut out = [0.0];
        let mut ctx = Context::new(&mut values);
        assert!(m
            .directional_derivative(&mut ctx, &[vr::Y], &[vr::R1], &[1.0], &mut out)
            .is_err());
    }

    #[test]
    fn events_switch_the_rail_and_the_output_follows() {
        let info = OpAmpFilterFmu::describe(&Config::new()).unwrap();
        let mut values = Values::from_start(&info.variables);
        let mut m = model_at(&mut values, [0.0, 11.0]);
        assert_eq!(m.rail, Rail::Inside);
        // The solver moved v_C2 past the upper rail: the indicator has changed sign, the output
        // still follows v_C2 (the rail is held) until the event.
        values.set_real(vr::V_C2, 12.001);
        let mut ctx = Context::new(&mut values);
        m.evaluate(&mut ctx).unwrap();
        let mut z = [0.0; EVENT_INDICATORS];
        m.event_indicators(&mut ctx, &mut z).unwrap();
        assert!(z[0] < 0.0 && z[1] > 0.0, "{z:?}");
        assert_eq!(ctx.values.real(vr::Y), 12.001);
        let update = m.update_discrete_states(&mut ctx).unwrap();
        assert!(!update.states_changed);
        assert_eq!(m.rail, Rail::High);
        m.evaluate(&mut ctx).unwrap();
        assert_eq!(ctx.values.real(vr::Y), 12.0);
        assert!(ctx.values.boolean(vr::SATURATED));
        // Back below the rail: the next event releases it.
        ctx.values.set_real(vr::V_C2, 11.5);
        m.update_discrete_states(&mut ctx).unwrap();
        assert_eq!(m.rail, Rail::Inside);
        m.evaluate(&mut ctx).unwrap();
        assert_eq!(ctx.values.real(vr::Y), 11.5);
    }

    #[test]
    fn a_step_needing_too_many_substeps_is_refused_at_once() {
        use spurio_export::harness::Harness;
        use spurio_export::types::Status;
        let mut h = Harness::<OpAmpFilterFmu>::new(&Config::new()).unwrap();
        // an h_max below its declared minimum (1 ns) is refused when set, naming it
        for below in [1e-300, 5e-10] {
            let status = h.set_real(&[vr::H_MAX as u32], &[below]);
            assert_eq!(status, Err(Status::Error), "h_max = {below}");
        }
        assert!(h.logged(&["`h_max`", "below its minimum 0.000000001"]));
        h.set_real(&[vr::H_MAX as u32], &[1e-9]).unwrap();
        h.initialize(0.0).unwrap();
        h.set_real(&[vr::U as u32], &[1.0]).unwrap();
        spurio_fmu_common::refuses_too_many_substeps(&mut h, 1.0).unwrap();
        // nothing changed: a step within the bound is taken from t = 0
        h.do_step(0.0, 1e-5).unwrap();
        assert_eq!(h.last_successful_time().unwrap(), 1e-5);
    }
}
