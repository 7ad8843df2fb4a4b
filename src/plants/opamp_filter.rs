//! The op-amp second-order low-pass filter of paper 002 (§III, eq. 9 and Fig. 6; docs/models.md
//! §2.3), modelled as a unity-gain Sallen–Key circuit.
//!
//! ```text
//!  u ──R1──●──R2──●──(+)▷──●── y
//!          │      │   (−)──┘        op-amp as a voltage follower
//!          C1     C2                C1 from node A back to the output y
//!          │      │                 C2 from node B to ground
//!          y     GND
//!        (node A) (node B)
//! ```
//!
//! States: the capacitor voltages `v₁ = V_A − y` (C1) and `v₂ = V_B` (C2). The op-amp follows
//! its non-inverting input but cannot leave its supply rails, so the output is
//! `y = clamp(v₂, V_sat_low, V_sat_high)`, and this saturated output is what drives C1's
//! feedback terminal: `V_A = v₁ + y`. Kirchhoff's current law at nodes A and B:
//!
//! ```text
//! C1 dv₁/dt = (u − V_A)/R1 − (V_A − v₂)/R2
//! C2 dv₂/dt = (V_A − v₂)/R2
//! ```
//!
//! Inside the rails (`y = v₂`) this is linear, `A = [[−(1/R1 + 1/R2)/C1, −1/(R1 C1)],
//! [1/(R2 C2), 0]]`, `B = [1/(R1 C1), 0]ᵀ`, `C = [0, 1]`, with the transfer function
//!
//! ```text
//! H(s) = 1 / (R1 R2 C1 C2 s² + C2 (R1 + R2) s + 1)
//!      = ω_n² / (s² + 2ζω_n s + ω_n²),  ω_n² = 1/(R1 R2 C1 C2),  2ζω_n = (R1 + R2)/(R1 R2 C1).
//! ```
//!
//! Defaults: standard capacitors C1 = 4.7 µF, C2 = 1 µF and the resistors that make
//! `H(s) = 27/(s² + 5.19 s + 27)` exactly (paper 002 eq. 9): R1 ≈ 132.95 kΩ,
//! R2 ≈ 59.272 kΩ (in the lab, a 130 kΩ + 2.94 kΩ and a 59 kΩ + 270 Ω series pair, or
//! trimmers); ω_n = 5.1962 rad/s, ζ = 0.4994. Rails ±12 V (a ±15 V supply less the output
//! stage's headroom). Measured from the simulated unit step (test
//! `unit_step_matches_the_reference_figures`): peak at 0.6979 s, overshoot 16.350 %, 2 %
//! settling time 1.5554 s, hence ω_n = 5.1962 rad/s and ζ = 0.49941 (docs/reference-values.md §6: 16.35 %,
//! 1.555 s, 0.698 s).

use crate::ode;
use crate::{require_finite, require_positive, ParameterError};
use nalgebra::{Matrix2, RowVector2, Vector2};

/// Component values and supply rails (SI units: Ω, F, V).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OpAmpFilterParameters {
    /// Input resistor `R1` [Ω].
    pub r1: f64,
    /// Resistor between the two nodes `R2` [Ω].
    pub r2: f64,
    /// Feedback capacitor `C1` [F] (node A to the output).
    pub c1: f64,
    /// Capacitor to ground `C2` [F] (node B).
    pub c2: f64,
    /// Upper output saturation `V_sat_high` [V].
    pub v_sat_high: f64,
    /// Lower output saturation `V_sat_low` [V].
    pub v_sat_low: f64,
}

impl Default for OpAmpFilterParameters {
    /// H(s) = 27/(s² + 5.19 s + 27) with C1 = 4.7 µF, C2 = 1 µF; rails ±12 V.
    fn default() -> Self {
        Self {
            r1: 132_950.289_072_002_9,
            r2: 59_271.933_150_219_34,
            c1: 4.7e-6,
            c2: 1e-6,
            v_sat_high: 12.0,
            v_sat_low: -12.0,
        }
    }
}

impl OpAmpFilterParameters {
    /// Checks every parameter, naming the first one that is not physical.
    pub fn validate(&self) -> Result<(), ParameterError> {
        require_positive("R1", self.r1)?;
        require_positive("R2", self.r2)?;
        require_positive("C1", self.c1)?;
        require_positive("C2", self.c2)?;
        require_finite("V_sat_high", self.v_sat_high)?;
        require_finite("V_sat_low", self.v_sat_low)?;
        if self.v_sat_low >= self.v_sat_high {
            return Err(ParameterError::new(
                "V_sat_low",
                format!(
                    "must be below V_sat_high = {}, got {}",
                    self.v_sat_high, self.v_sat_low
                ),
            ));
        }
        Ok(())
    }

    /// Undamped natural frequency ω_n = 1/√(R1 R2 C1 C2) [rad/s].
    pub fn natural_frequency(&self) -> f64 {
        1.0 / (self.r1 * self.r2 * self.c1 * self.c2).sqrt()
    }

    /// Damping ratio ζ = (R1 + R2)/(2 ω_n R1 R2 C1).
    pub fn damping_ratio(&self) -> f64 {
        (self.r1 + self.r2) / (2.0 * self.natural_frequency() * self.r1 * self.r2 * self.c1)
    }

    /// The op-amp output for the C2 voltage `v2`: `v2` clipped to the rails.
    pub fn output_for(&self, v2: f64) -> f64 {
        v2.clamp(self.v_sat_low, self.v_sat_high)
    }

    /// Right-hand side `[dv₁/dt, dv₂/dt]` for the capacitor voltages `v` and input `u`.
    pub fn derivative(&self, v: &Vector2<f64>, u: f64) -> Vector2<f64> {
        let y = self.output_for(v[1]);
        let node_a = v[0] + y;
        let through_r2 = (node_a - v[1]) / self.r2;
        Vector2::new(
            ((u - node_a) / self.r1 - through_r2) / self.c1,
            through_r2 / self.c2,
        )
    }

    /// The linear model inside the rails: `(A, B, C)` of the module docs (D = 0).
    pub fn state_space(&self) -> (Matrix2<f64>, Vector2<f64>, RowVector2<f64>) {
        let a = Matrix2::new(
            -(1.0 / self.r1 + 1.0 / self.r2) / self.c1,
            -1.0 / (self.r1 * self.c1),
            1.0 / (self.r2 * self.c2),
            0.0,
        );
        let b = Vector2::new(1.0 / (self.r1 * self.c1), 0.0);
        (a, b, RowVector2::new(0.0, 1.0))
    }
}

/// The filter circuit with its state (capacitor voltages `[v₁, v₂]` in V).
#[derive(Debug, Clone, PartialEq)]
pub struct OpAmpFilter {
    /// Components and rails.
    pub parameters: OpAmpFilterParameters,
    /// Capacitor voltages `[v_C1, v_C2]` [V].
    pub state: Vector2<f64>,
}

impl OpAmpFilter {
    /// A discharged filter (both capacitors at 0 V), after checking the parameters.
    pub fn new(parameters: OpAmpFilterParameters) -> Result<Self, ParameterError> {
        Self::with_state(parameters, Vector2::zeros())
    }

    /// A filter with capacitor voltages `[v_C1, v_C2]` (parameters `v_C1_0`, `v_C2_0`).
    pub fn with_state(
        parameters: OpAmpFilterParameters,
        state: Vector2<f64>,
    ) -> Result<Self, ParameterError> {
        parameters.validate()?;
        require_finite("v_C1_0", state[0])?;
        require_finite("v_C2_0", state[1])?;
        Ok(Self { parameters, state })
    }

    /// The output voltage `y` [V] (op-amp output, within the rails).
    pub fn output(&self) -> f64 {
        self.parameters.output_for(self.state[1])
    }

    /// Advances from time `t` over `h` seconds with the input voltage `u` held, with RK4
    /// substeps no longer than `h_max` (the poles are at −2.60 ± 4.50j rad/s: 10⁻³ s is
    /// plenty). A saturated output is handled by the model itself (the clamp in
    /// [`OpAmpFilterParameters::derivative`]).
    pub fn advance(&mut self, t: f64, u: f64, h: f64, h_max: f64) {
        let p = self.parameters;
        self.state = ode::integrate(
            |_t, v| p.derivative(v, u),
            |_, _| {},
            t,
            &self.state,
            h,
            h_max,
        );
    }
}

// FMU-state snapshots (plain bytes) of the types above: every field, in order.
crate::plain_state!(OpAmpFilterParameters {
    r1,
    r2,
    c1,
    c2,
    v_sat_high,
    v_sat_low
});
crate::plain_state!(OpAmpFilter { parameters, state });

#[cfg(test)]
mod tests {
    use super::*;

    /// Figures of a unit step response measured from the simulation.
    struct StepFigures {
        peak_time: f64,
        overshoot: f64,
        settling_time: f64,
    }

    fn measure_unit_step(parameters: OpAmpFilterParameters) -> StepFigures {
        let mut f = OpAmpFilter::new(parameters).unwrap();
        let h = 1e-4;
        let n = 60_000;
        let mut y = vec![0.0];
        for k in 0..n {
            f.advance(k as f64 * h, 1.0, h, h);
            y.push(f.output());
        }
        // Peak, refined by a parabola through the three samples around the maximum.
        let (k, _) = y.iter().enumerate().fold(
            (0, f64::MIN),
            |m, (k, v)| if *v > m.1 { (k, *v) } else { m },
        );
        let (a, b, c) = (y[k - 1], y[k], y[k + 1]);
        let shift = 0.5 * (a - c) / (a - 2.0 * b + c);
        let peak_time = (k as f64 + shift) * h;
        let peak = b - 0.25 * (a - c) * shift;
        // Settling: last crossing into the ±2 % band, interpolated.
        let last_out = (0..y.len())
            .rev()
            .find(|&k| (y[k] - 1.0).abs() > 0.02)
            .unwrap();
        let (e0, e1) = ((y[last_out] - 1.0).abs(), (y[last_out + 1] - 1.0).abs());
        let settling_time = (last_out as f64 + (e0 - 0.02) / (e0 - e1)) * h;
        StepFigures {
            peak_time,
            overshoot: peak - 1.0,
            settling_time,
        }
    }

    #[test]
    fn unit_step_matches_the_reference_figures() {
        let s = measure_unit_step(OpAmpFilterParameters::default());
        // ζ from the overshoot, ω_n from the damped period (peak time = π/ω_d).
        let log = s.overshoot.ln();
        let zeta = -log / (std::f64::consts::PI.powi(2) + log * log).sqrt();
        let omega_n = std::f64::consts::PI / s.peak_time / (1.0 - zeta * zeta).sqrt();
        eprintln!(
            "op-amp step: peak time {:.5} s, overshoot {:.4} %, settling {:.5} s, ω_n {:.5}, ζ {:.5}",
            s.peak_time,
            100.0 * s.overshoot,
            s.settling_time,
            omega_n,
            zeta
        );
        let close = |got: f64, want: f64| ((got - want) / want).abs() < 0.005;
        assert!(close(omega_n, 5.19615), "ω_n {omega_n}");
        assert!(close(zeta, 0.49941), "ζ {zeta}");
        assert!(close(s.overshoot, 0.1635), "overshoot {}", s.overshoot);
        assert!(
            close(s.settling_time, 1.555),
            "settling {}",
            s.settling_time
        );
        assert!(close(s.peak_time, 0.698), "peak time {}", s.peak_time);
    }

    #[test]
    fn default_components_give_the_papers_transfer_function() {
        let p = OpAmpFilterParameters::default();
        let wn2 = 1.0 / (p.r1 * p.r2 * p.c1 * p.c2);
        let two_zeta_wn = (p.r1 + p.r2) / (p.r1 * p.r2 * p.c1);
        assert!((wn2 - 27.0).abs() < 1e-9);
        assert!((two_zeta_wn - 5.19).abs() < 1e-9);
        let (a, b, c) = p.state_space();
        // Characteristic polynomial s² − tr(A) s + det(A) and DC gain −C A⁻¹ B = 1.
        assert!((-a.trace() - 5.19).abs() < 1e-9);
        assert!((a.determinant() - 27.0).abs() < 1e-9);
        let dc = -(c * a.try_inverse().unwrap() * b)[0];
        assert!((dc - 1.0).abs() < 1e-12);
        assert!((p.natural_frequency() - 27f64.sqrt()).abs() < 1e-12);
        assert!((p.damping_ratio() - 5.19 / (2.0 * 27f64.sqrt())).abs() < 1e-12);
    }

    #[test]
    fn large_input_clips_at_the_rails() {
        let mut f = OpAmpFilter::new(OpAmpFilterParameters::default()).unwrap();
        let mut max = f64::MIN;
        for k in 0..500 {
            f.advance(k as f64 * 0.01, 30.0, 0.01, 1e-3);
            max = max.max(f.output());
            assert!(f.output() <= 12.0);
        }
        assert_eq!(f.output(), 12.0);
        assert_eq!(max, 12.0);
        // Negative rail, asymmetric.
        let p = OpAmpFilterParameters {
            v_sat_low: -5.0,
            ..Default::default()
        };
        let mut f = OpAmpFilter::new(p).unwrap();
        for k in 0..500 {
            f.advance(k as f64 * 0.01, -30.0, 0.01, 1e-3);
            assert!(f.output() >= -5.0);
        }
        assert_eq!(f.output(), -5.0);
        // Back inside the rails it recovers to the small-signal steady state.
        for k in 500..1500 {
            f.advance(k as f64 * 0.01, 1.0, 0.01, 1e-3);
        }
        assert!((f.output() - 1.0).abs() < 1e-6);
    }

    #[test]
    fn response_does_not_depend_on_the_communication_step() {
        let run = |h: f64| {
            let mut f = OpAmpFilter::new(OpAmpFilterParameters::default()).unwrap();
            let n = (2.0 / h).round() as usize;
            for k in 0..n {
                f.advance(k as f64 * h, 1.0, h, 1e-3);
            }
            f.output()
        };
        assert!((run(0.1) - run(0.001)).abs() < 1e-9);
    }

    #[test]
    fn bad_parameters_are_named() {
        let base = OpAmpFilterParameters::default();
        let name = |p: OpAmpFilterParameters| OpAmpFilter::new(p).unwrap_err().parameter;
        assert_eq!(name(OpAmpFilterParameters { r1: 0.0, ..base }), "R1");
        assert_eq!(name(OpAmpFilterParameters { r2: -1.0, ..base }), "R2");
        assert_eq!(name(OpAmpFilterParameters { c1: 0.0, ..base }), "C1");
        assert_eq!(
            name(OpAmpFilterParameters {
                c2: f64::NAN,
                ..base
            }),
            "C2"
        );
        assert_eq!(
            name(OpAmpFilterParameters {
                v_sat_high: -12.0,
                v_sat_low: 12.0,
                ..base
            }),
            "V_sat_low"
        );
        assert_eq!(
            OpAmpFilter::with_state(base, Vector2::new(f64::NAN, 0.0))
                .unwrap_err()
                .parameter,
            "v_C1_0"
        );
    }
}
