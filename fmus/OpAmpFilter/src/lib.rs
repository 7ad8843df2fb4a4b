//! `OpAmpFilter.fmu`: the unity-gain Sallen–Key low-pass of paper 002 (§III, eq. 9; docs/models.md
//! §2.3) as an FMI 2.0 CS FMU.
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
//! Bounded work: every parameter has a declared range (1 Ω to 1 GΩ, 1 fF to 1 F, rails and
//! initial voltages within ±1 kV, 10⁻⁹ s ≤ `h_max` ≤ 1 s), checked when it is set, and a step
//! that would need more than [`spurio::ode::MAX_SUBSTEPS`] RK4 substeps is refused
//! (`fmi2Error`, nothing changed).

use spurio::plants::opamp_filter::{OpAmpFilter, OpAmpFilterParameters};
use spurio_export::rows::{input, output, parameter};
use spurio_export::{
    Cause, Config, Context, DefaultExperiment, Failure, FmuModel, ModelInfo, Variable,
};

pub use spurio_fmu_common::RK4_STABILITY_MARGIN;
use spurio_fmu_common::{advance_finite, rk4_substep};

spurio_export::declare_variables! {
    /// The variable table, in value-reference order.
    pub fn variables() {
        let p = OpAmpFilterParameters::default();
        table: [
            U = input("u", 0.0, "V", "Input voltage"),
            Y = output("y", "V", "Output voltage of the op-amp (within the supply rails)"),
            V_C1 = output("v_C1", "V", "Voltage across C1 (node A minus output)"),
            V_C2 = output("v_C2", "V", "Voltage across C2 (node B to ground, the op-amp's + input)"),
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

/// The OpAmpFilter FMU.
#[derive(Debug, Clone)]
pub struct OpAmpFilterFmu {
    filter: OpAmpFilter,
    h_max: f64,
}

impl OpAmpFilterFmu {
    fn write_outputs(&self, ctx: &mut Context) {
        let y = self.filter.output();
        ctx.values.set_real(vr::Y, y);
        ctx.values.set_real(vr::V_C1, self.filter.state[0]);
        ctx.values.set_real(vr::V_C2, self.filter.state[1]);
        ctx.values
            .set_boolean(vr::SATURATED, y != self.filter.state[1]);
    }
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
        ))
    }

    fn create(_info: &ModelInfo) -> Result<Self, Cause> {
        Ok(Self {
            filter: OpAmpFilter {
                parameters: OpAmpFilterParameters::default(),
                state: Default::default(),
            },
            h_max: 1e-3,
        })
    }

    fn initialize(&mut self, ctx: &mut Context) -> Result<(), Failure> {
        let r = |i| ctx.values.real(i);
        let parameters = OpAmpFilterParameters {
            r1: r(vr::R1),
            r2: r(vr::R2),
            c1: r(vr::C1),
            c2: r(vr::C2),
            v_sat_high: r(vr::V_SAT_HIGH),
            v_sat_low: r(vr::V_SAT_LOW),
        };
        let state = [r(vr::V_C1_0), r(vr::V_C2_0)].into();
        let filter = OpAmpFilter::with_state(parameters, state).map_err(Failure::error)?;
        let fastest = fastest_mode(&parameters);
        let mode = format!("the circuit's fastest mode ({fastest:.4} 1/s)");
        let h_max = rk4_substep(r(vr::H_MAX), fastest, &mode)?;
        self.filter = filter;
        self.h_max = h_max;
        self.write_outputs(ctx);
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
        self.write_outputs(ctx);
        Ok(())
    }

    spurio_fmu_common::fmu_state!(filter, h_max; check = |m: &Self| {
        OpAmpFilter::with_state(m.filter.parameters, m.filter.state)?;
        spurio::require_positive("h_max", m.h_max)?;
        Ok(())
    });
}

spurio_export::export_fmu!(OpAmpFilterFmu);

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

    #[test]
    fn a_step_needing_too_many_substeps_is_refused_at_once() {
        use spurio_export::harness::Harness;
        use spurio_export::types::Status;
        let mut h = Harness::<OpAmpFilterFmu>::new(&Config::new()).unwrap();
        assert_eq!(
            h.set_real(&[vr::H_MAX as u32], &[1e-300]),
            Err(Status::Error)
        );
        assert!(
            h.logged(&["`h_max`", "below its minimum 0.000000001"]),
            "{:?}",
            h.log()
        );
        h.set_real(&[vr::H_MAX as u32], &[1e-9]).unwrap();
        h.initialize(0.0).unwrap();
        h.set_real(&[vr::U as u32], &[1.0]).unwrap();
        spurio_fmu_common::refuses_too_many_substeps(&mut h, 1.0).unwrap();
        // nothing changed: a step within the bound is taken from t = 0
        h.do_step(0.0, 1e-5).unwrap();
        assert_eq!(h.last_successful_time().unwrap(), 1e-5);
    }
}
