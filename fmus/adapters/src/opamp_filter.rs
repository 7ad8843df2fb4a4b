//! `OpAmpFilter.fmu`: the unity-gain Sallen–Key low-pass of paper 002 (§III, eq. 9; SPEC §2
//! item 3) as an FMI 2.0 CS FMU.
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

use spurio::plants::opamp_filter::{OpAmpFilter, OpAmpFilterParameters};
use spurio_fmi2::{
    ByteReader, ByteWriter, Config, Context, DefaultExperiment, Failure, FmuModel, ModelInfo,
    Variable,
};

/// `h_max · |λ|max` above which RK4 is refused (its real-axis stability limit is 2.785).
pub const RK4_STABILITY_MARGIN: f64 = 2.5;

/// Value references (= positions in the variable table).
pub mod vr {
    pub const U: usize = 0;
    pub const Y: usize = 1;
    pub const V_C1: usize = 2;
    pub const V_C2: usize = 3;
    pub const SATURATED: usize = 4;
    pub const R1: usize = 5;
    pub const R2: usize = 6;
    pub const C1: usize = 7;
    pub const C2: usize = 8;
    pub const V_SAT_HIGH: usize = 9;
    pub const V_SAT_LOW: usize = 10;
    pub const V_C1_0: usize = 11;
    pub const V_C2_0: usize = 12;
    pub const H_MAX: usize = 13;
}

/// The variable table, in value-reference order.
pub fn variables() -> Vec<Variable> {
    let p = OpAmpFilterParameters::default();
    vec![
        Variable::input("u", 0.0)
            .unit("V")
            .describe("Input voltage"),
        Variable::output("y")
            .unit("V")
            .describe("Output voltage of the op-amp (within the supply rails)"),
        Variable::output("v_C1")
            .unit("V")
            .describe("Voltage across C1 (node A minus output)"),
        Variable::output("v_C2")
            .unit("V")
            .describe("Voltage across C2 (node B to ground, the op-amp's + input)"),
        Variable::boolean_output("saturated")
            .describe("Whether the output sits on a rail at this communication point"),
        Variable::parameter("R1", p.r1).unit("Ohm").describe(
            "Input resistor (default: with R2, C1, C2 gives H(s) = 27/(s^2 + 5.19 s + 27))",
        ),
        Variable::parameter("R2", p.r2)
            .unit("Ohm")
            .describe("Resistor between node A and node B"),
        Variable::parameter("C1", p.c1)
            .unit("F")
            .describe("Feedback capacitor from node A to the output (4.7 uF)"),
        Variable::parameter("C2", p.c2)
            .unit("F")
            .describe("Capacitor from node B to ground (1 uF)"),
        Variable::parameter("V_sat_high", p.v_sat_high)
            .unit("V")
            .describe("Upper output saturation (positive rail less headroom)"),
        Variable::parameter("V_sat_low", p.v_sat_low)
            .unit("V")
            .describe("Lower output saturation (negative rail less headroom)"),
        Variable::parameter("v_C1_0", 0.0)
            .unit("V")
            .describe("Initial voltage across C1"),
        Variable::parameter("v_C2_0", 0.0)
            .unit("V")
            .describe("Initial voltage across C2"),
        Variable::parameter("h_max", 1e-3)
            .unit("s")
            .describe("Longest RK4 substep inside fmi2DoStep"),
    ]
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
    fn describe(_config: &Config) -> Result<ModelInfo, String> {
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

    fn create(_info: &ModelInfo) -> Result<Self, String> {
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
        let filter = OpAmpFilter::with_state(parameters, state).map_err(|e| e.to_string())?;
        let h_max = spurio::require_positive("h_max", r(vr::H_MAX)).map_err(|e| e.to_string())?;
        let fastest = fastest_mode(&parameters);
        let product = h_max * fastest;
        if product.is_nan() || product > RK4_STABILITY_MARGIN {
            return Err(Failure::Error(format!(
                "parameter `h_max`: {h_max} s would make RK4 unstable on the circuit's fastest mode ({fastest:.4} 1/s); use at most {:.3e} s",
                RK4_STABILITY_MARGIN / fastest
            )));
        }
        self.filter = filter;
        self.h_max = h_max;
        self.write_outputs(ctx);
        Ok(())
    }

    fn do_step(&mut self, ctx: &mut Context, time: f64, step: f64) -> Result<(), Failure> {
        let u = ctx.values.real(vr::U);
        let mut next = self.filter.clone();
        next.advance(time, u, step, self.h_max);
        if next.state.iter().any(|v| !v.is_finite()) {
            return Err(Failure::Error(format!(
                "the capacitor voltages became non-finite in the step from t = {time} (input u = {u})"
            )));
        }
        self.filter = next;
        self.write_outputs(ctx);
        Ok(())
    }

    fn save_state(&self, out: &mut ByteWriter) {
        let p = &self.filter.parameters;
        out.put_f64_slice(&[p.r1, p.r2, p.c1, p.c2, p.v_sat_high, p.v_sat_low]);
        out.put_f64_slice(self.filter.state.as_slice());
        out.put_f64(self.h_max);
    }

    fn load_state(&mut self, input: &mut ByteReader) -> Result<(), String> {
        let p = input.f64_vec()?;
        let s = input.f64_vec()?;
        if p.len() != 6 || s.len() != 2 {
            return Err("OpAmpFilter state: wrong number of parameters or states".into());
        }
        self.filter.parameters = OpAmpFilterParameters {
            r1: p[0],
            r2: p[1],
            c1: p[2],
            c2: p[3],
            v_sat_high: p[4],
            v_sat_low: p[5],
        };
        self.filter.state = nalgebra::Vector2::new(s[0], s[1]);
        self.h_max = input.f64()?;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn value_reference_constants_match_the_table() {
        let v = variables();
        let expect = [
            (vr::U, "u"),
            (vr::Y, "y"),
            (vr::V_C1, "v_C1"),
            (vr::V_C2, "v_C2"),
            (vr::SATURATED, "saturated"),
            (vr::R1, "R1"),
            (vr::R2, "R2"),
            (vr::C1, "C1"),
            (vr::C2, "C2"),
            (vr::V_SAT_HIGH, "V_sat_high"),
            (vr::V_SAT_LOW, "V_sat_low"),
            (vr::V_C1_0, "v_C1_0"),
            (vr::V_C2_0, "v_C2_0"),
            (vr::H_MAX, "h_max"),
        ];
        assert_eq!(v.len(), expect.len());
        crate::assert_value_references(&v, &expect);
    }

    #[test]
    fn fastest_mode_of_the_defaults_is_the_saturated_c2_mode() {
        let p = OpAmpFilterParameters::default();
        // Linear poles |λ| = √27; saturated modes (1/R1 + 1/R2)/C1 ≈ 5.19, 1/(R2 C2) ≈ 16.9.
        let f = fastest_mode(&p);
        assert!((f - 1.0 / (p.r2 * p.c2)).abs() < 1e-9, "{f}");
    }
}
