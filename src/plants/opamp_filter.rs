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
use crate::{require_finite, ParameterError};
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
        use crate::Requirement::{Finite, Positive};
        crate::check_all(&[
            ("R1", self.r1, Positive),
            ("R2", self.r2, Positive),
            ("C1", self.c1, Positive),
            ("C2", self.c2, Positive),
            ("V_sat_high", self.v_sat_high, Finite),
            ("V_sat_low", self.v_sat_low, Finite),
        ])?;
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

    /// Where the output of the C2 voltage `v2` is: on a rail or between them (a voltage
    /// exactly at a rail counts as on it, as in [`Self::output_for`]'s clamp).
    pub fn rail_of(&self, v2: f64) -> Rail {
        if v2 >= self.v_sat_high {
            Rail::High
        } else if v2 <= self.v_sat_low {
            Rail::Low
        } else {
            Rail::Inside
        }
    }

    /// The op-amp output with the rail held at `rail`: `v2` inside, the rail's voltage on it.
    /// Equal to [`Self::output_for`] when `rail == self.rail_of(v2)`.
    pub fn output_on(&self, v2: f64, rail: Rail) -> f64 {
        match rail {
            Rail::Inside => v2,
            Rail::High => self.v_sat_high,
            Rail::Low => self.v_sat_low,
        }
    }

    /// Right-hand side `[dv₁/dt, dv₂/dt]` for the capacitor voltages `v` and input `u`.
    pub fn derivative(&self, v: &Vector2<f64>, u: f64) -> Vector2<f64> {
        self.derivative_on(v, u, self.rail_of(v[1]))
    }

    /// The right-hand side with the output's rail held at `rail` (the Model Exchange side
    /// holds it between events so the solver sees a smooth function; [`Self::derivative`]
    /// takes the rail of `v₂` itself).
    pub fn derivative_on(&self, v: &Vector2<f64>, u: f64, rail: Rail) -> Vector2<f64> {
        let y = self.output_on(v[1], rail);
        let node_a = v[0] + y;
        let through_r2 = (node_a - v[1]) / self.r2;
        Vector2::new(
            ((u - node_a) / self.r1 - through_r2) / self.c1,
            through_r2 / self.c2,
        )
    }

    /// Event indicators `[V_sat_high − v₂, v₂ − V_sat_low]`: the output reaches (or leaves)
    /// the upper rail where the first changes sign, the lower rail where the second does.
    pub fn event_indicators(&self, v: &Vector2<f64>) -> [f64; 2] {
        [self.v_sat_high - v[1], v[1] - self.v_sat_low]
    }

    /// `∂f/∂v` of [`Self::derivative_on`] (constant in each rail mode): with `s = ∂y/∂v₂`
    /// (1 inside, 0 on a rail), `∂f₁/∂v₁ = −(1/R1 + 1/R2)/C1`,
    /// `∂f₁/∂v₂ = (1/R2 − s (1/R1 + 1/R2))/C1`, `∂f₂/∂v₁ = 1/(R2 C2)`,
    /// `∂f₂/∂v₂ = (s − 1)/(R2 C2)`.
    pub fn jacobian_state(&self, rail: Rail) -> Matrix2<f64> {
        let s = self.output_slope(rail);
        let g = 1.0 / self.r1 + 1.0 / self.r2;
        Matrix2::new(
            -g / self.c1,
            (1.0 / self.r2 - s * g) / self.c1,
            1.0 / (self.r2 * self.c2),
            (s - 1.0) / (self.r2 * self.c2),
        )
    }

    /// `∂f/∂u = [1/(R1 C1), 0]ᵀ`.
    pub fn jacobian_input(&self) -> Vector2<f64> {
        Vector2::new(1.0 / (self.r1 * self.c1), 0.0)
    }

    /// `∂y/∂v₂` on `rail`: 1 between the rails, 0 on one (`∂y/∂v₁ = ∂y/∂u = 0`).
    pub fn output_slope(&self, rail: Rail) -> f64 {
        match rail {
            Rail::Inside => 1.0,
            Rail::High | Rail::Low => 0.0,
        }
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

/// Where the op-amp output sits: between the supply rails (a voltage follower, `y = v₂`) or
/// on one of them (`y` = the rail's voltage, whatever `v₂`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Rail {
    /// `V_sat_low < v₂ < V_sat_high`: `y = v₂`.
    Inside,
    /// `v₂ ≥ V_sat_high`: `y = V_sat_high`.
    High,
    /// `v₂ ≤ V_sat_low`: `y = V_sat_low`.
    Low,
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
crate::plain_state!(
    enum Rail {
        Inside,
        High,
        Low,
    }
);

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
    fn jacobians_match_central_differences_at_random_states() {
        let mut rng = crate::signals::rng::RandomGenerator::new(15);
        for k in 0..300 {
            let p = OpAmpFilterParameters {
                r1: rng.uniform_range(1e3, 1e6),
                r2: rng.uniform_range(1e3, 1e6),
                c1: rng.uniform_range(1e-8, 1e-5),
                c2: rng.uniform_range(1e-8, 1e-5),
                ..Default::default()
            };
            let v = Vector2::new(
                rng.uniform_range(-20.0, 20.0),
                rng.uniform_range(-20.0, 20.0),
            );
            let u = rng.uniform_range(-30.0, 30.0);
            let rail = [Rail::Inside, Rail::High, Rail::Low][k % 3];
            let (jx, ju) = crate::plants::state_and_input_differences(
                |v, u| p.derivative_on(v, u, rail),
                &v,
                u,
                1e-4,
            );
            let analytic = p.jacobian_state(rail);
            for i in 0..2 {
                let scale = analytic.row(i).amax();
                for j in 0..2 {
                    assert!(
                        crate::plants::close_in_row(jx[(i, j)], analytic[(i, j)], scale),
                        "∂f{i}/∂v{j} on {rail:?}: {} vs {}",
                        jx[(i, j)],
                        analytic[(i, j)]
                    );
                }
                assert!(crate::plants::close_in_row(
                    ju[i],
                    p.jacobian_input()[i],
                    scale
                ));
            }
            // The output y = output_on(v₂, rail): slope by differences too.
            let d = 1e-4 * v[1].abs().max(1.0);
            let slope = (p.output_on(v[1] + d, rail) - p.output_on(v[1] - d, rail)) / (2.0 * d);
            assert!((slope - p.output_slope(rail)).abs() < 1e-9);
        }
        // Inside the rails the Jacobian is the A of the linear model.
        let p = OpAmpFilterParameters::default();
        assert_eq!(p.jacobian_state(Rail::Inside), p.state_space().0);
    }

    #[test]
    fn held_rail_gives_the_clamped_right_hand_side_and_indicators_change_sign_at_the_rails() {
        let p = OpAmpFilterParameters {
            v_sat_low: -5.0,
            ..Default::default()
        };
        for v2 in [-7.0, -5.0, -4.999, 0.0, 11.999, 12.0, 13.0] {
            let v = Vector2::new(0.3, v2);
            let rail = p.rail_of(v2);
            // Bit for bit: the CS integrator's right-hand side is derivative_on of the rail.
            assert_eq!(p.derivative(&v, 2.0), p.derivative_on(&v, 2.0, rail));
            assert_eq!(p.output_on(v2, rail), p.output_for(v2));
            let [high, low] = p.event_indicators(&v);
            assert_eq!(rail == Rail::High, high <= 0.0, "v2 = {v2}");
            assert_eq!(rail == Rail::Low, low <= 0.0, "v2 = {v2}");
        }
        assert_eq!(p.rail_of(12.0), Rail::High);
        assert_eq!(p.rail_of(-5.0), Rail::Low);
        // On a rail the output no longer follows v₂, so the loop through C1 opens: dv₂/dt
        // depends on v₂ only through R2 C2.
        let j = p.jacobian_state(Rail::High);
        assert!((j[(1, 1)] + 1.0 / (p.r2 * p.c2)).abs() < 1e-12);
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
