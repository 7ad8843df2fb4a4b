//! The nonlinear gantry crane of paper 000 (docs/models.md §2.1, paper 000 §III and Annex A).
//!
//! A cart of mass `M` runs on a rail; a load of mass `m` hangs from it on a rod whose centre
//! of mass is at distance `l` from the pivot, with moment of inertia `J` about the pivot. The
//! state is `[x, θ, ẋ, θ̇]` (θ = 0 hanging down). With cart friction `f_c`, pivot friction `f_p`
//! and the force `U` on the cart (saturated at ±`U_max`):
//!
//! ```text
//! (M + m) ẍ − m l (θ̈ cos θ − θ̇² sin θ) = U − f_c ẋ
//! (J + m l²) θ̈ − m l ẍ cos θ + m g l sin θ = − f_p θ̇
//! ```
//!
//! i.e. the mass matrix `[[M+m, −m l cos θ], [−m l cos θ, J + m l²]]` times `[ẍ, θ̈]` equals
//! `[U − f_c ẋ − m l θ̇² sin θ, −f_p θ̇ − m g l sin θ]`; its determinant
//! `(M+m)(J+m l²) − m² l² cos² θ` is positive for any θ, so the 2×2 system is solved in closed
//! form. Linearised about the rest point this gives the paper's eqs (4)–(5).
//!
//! The rail ends at ±`x_limit` are perfectly inelastic stops: a cart that reaches one loses
//! its velocity into the stop and stays there while the net force pushes it outwards.

use crate::ode;
use crate::ParameterError;
use nalgebra::{Matrix4, SVector, Vector4};

/// State `[x, θ, ẋ, θ̇]` in m, rad, m/s, rad/s.
pub type CraneState = SVector<f64, 4>;

/// Physical parameters of the crane. Defaults: paper 000, Annex A.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GantryCraneParameters {
    /// Cart mass `M` (kg): cart 619.25 g + lid 90.55 g + positioners 134.05 g.
    pub cart_mass: f64,
    /// Load mass `m` (kg).
    pub load_mass: f64,
    /// Pivot to the load's centre of mass, `l` (m).
    pub rod_length: f64,
    /// Moment of inertia of the load about the pivot, `J` (kg·m²).
    pub inertia: f64,
    /// Viscous cart friction `f_c` (N·s/m).
    pub cart_friction: f64,
    /// Viscous pivot friction `f_p` (kg·m²/(rad·s)).
    pub pivot_friction: f64,
    /// Gravity `g` (m/s²).
    pub gravity: f64,
    /// Actuator limit `U_max` (N): the force is saturated at ±`U_max`.
    pub max_force: f64,
    /// Rail end stops at ±`x_limit` (m).
    pub rail_limit: f64,
}

impl Default for GantryCraneParameters {
    fn default() -> Self {
        Self {
            cart_mass: 0.84385,
            load_mass: 0.013,
            rod_length: 0.3434,
            inertia: 1e-5,
            cart_friction: 0.67,
            pivot_friction: 9.3e-6,
            gravity: 9.8,
            max_force: 17.0,
            rail_limit: 0.5,
        }
    }
}

impl GantryCraneParameters {
    /// Checks every parameter, naming the first one that is not physical.
    pub fn validate(&self) -> Result<(), ParameterError> {
        use crate::Requirement::{NonNegative, Positive};
        crate::check_all(&[
            ("M", self.cart_mass, Positive),
            ("m", self.load_mass, Positive),
            ("l", self.rod_length, Positive),
            ("J", self.inertia, NonNegative),
            ("f_c", self.cart_friction, NonNegative),
            ("f_p", self.pivot_friction, NonNegative),
            ("g", self.gravity, Positive),
            ("U_max", self.max_force, Positive),
            ("x_limit", self.rail_limit, Positive),
        ])
    }

    /// The force actually applied for a requested force `u`: `u` clipped to ±`U_max`.
    pub fn saturate(&self, u: f64) -> f64 {
        u.clamp(-self.max_force, self.max_force)
    }

    /// Accelerations `[ẍ, θ̈]` of the free (unconstrained) cart for state `s` and force `u`.
    pub fn free_accelerations(&self, s: &CraneState, u: f64) -> (f64, f64) {
        let (theta, v, omega) = (s[1], s[2], s[3]);
        let (sin, cos) = theta.sin_cos();
        let ml = self.load_mass * self.rod_length;
        let a11 = self.cart_mass + self.load_mass;
        let a22 = self.inertia + self.load_mass * self.rod_length * self.rod_length;
        let a12 = -ml * cos;
        let b1 = u - self.cart_friction * v - ml * omega * omega * sin;
        let b2 = -self.pivot_friction * omega - ml * self.gravity * sin;
        let det = a11 * a22 - a12 * a12;
        ((b1 * a22 - a12 * b2) / det, (a11 * b2 - a12 * b1) / det)
    }

    /// Right-hand side `ṡ = f(s, u)` including the rail stops; `u` is the applied force.
    pub fn derivative(&self, s: &CraneState, u: f64) -> CraneState {
        let (mut xdd, mut thdd) = self.free_accelerations(s, u);
        let mut xd = s[2];
        let side = s[0].signum();
        if s[0].abs() >= self.rail_limit && side * s[2] >= 0.0 && side * xdd >= 0.0 {
            // Held against the stop: the cart does not move, the load swings about a fixed pivot.
            xd = 0.0;
            xdd = 0.0;
            let a22 = self.inertia + self.load_mass * self.rod_length * self.rod_length;
            thdd = (-self.pivot_friction * s[3]
                - self.load_mass * self.rod_length * self.gravity * s[1].sin())
                / a22;
        }
        Vector4::new(xd, s[3], xdd, thdd)
    }

    /// Continuous linearisation about the rest point: `ṡ = A s + B U` (paper 000 eqs 4–5).
    pub fn linearised(&self) -> (Matrix4<f64>, Vector4<f64>) {
        let ml = self.load_mass * self.rod_length;
        let a11 = self.cart_mass + self.load_mass;
        let a22 = self.inertia + self.load_mass * self.rod_length * self.rod_length;
        let det = a11 * a22 - ml * ml;
        let mgl = ml * self.gravity;
        // [ẍ; θ̈] = (1/det) [[a22, ml], [ml, a11]] [U − f_c ẋ; −f_p θ̇ − m g l θ]
        let a = Matrix4::new(
            0.0,
            0.0,
            1.0,
            0.0, //
            0.0,
            0.0,
            0.0,
            1.0, //
            0.0,
            -ml * mgl / det,
            -a22 * self.cart_friction / det,
            -ml * self.pivot_friction / det,
            0.0,
            -a11 * mgl / det,
            -ml * self.cart_friction / det,
            -a11 * self.pivot_friction / det,
        );
        let b = Vector4::new(0.0, 0.0, a22 / det, ml / det);
        (a, b)
    }
}

/// What happened during one [`GantryCrane::advance`].
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct StepReport {
    /// The cart hit a rail end during the step: `Some((time, position))` of the first hit.
    pub hit_stop: Option<(f64, f64)>,
}

/// The crane with its state: parameters + `[x, θ, ẋ, θ̇]`.
#[derive(Debug, Clone, PartialEq)]
pub struct GantryCrane {
    /// Physical parameters.
    pub parameters: GantryCraneParameters,
    /// Current state `[x, θ, ẋ, θ̇]`.
    pub state: CraneState,
}

impl GantryCrane {
    /// A crane at `initial_state`, after checking the parameters and that the cart starts on
    /// the rail.
    pub fn new(
        parameters: GantryCraneParameters,
        initial_state: CraneState,
    ) -> Result<Self, ParameterError> {
        parameters.validate()?;
        let names = ["x0", "theta0", "v0", "omega0"];
        for (name, value) in names.iter().zip(initial_state.iter()) {
            crate::require_finite(name, *value)?;
        }
        if initial_state[0].abs() > parameters.rail_limit {
            return Err(ParameterError::new(
                "x0",
                format!(
                    "the cart must start on the rail, |x0| <= x_limit = {}, got {}",
                    parameters.rail_limit, initial_state[0]
                ),
            ));
        }
        Ok(Self {
            parameters,
            state: initial_state,
        })
    }

    /// Advances the state from time `t` over `h` seconds under the requested force `u`
    /// (saturated here), with RK4 substeps no longer than `h_max`.
    pub fn advance(&mut self, t: f64, u: f64, h: f64, h_max: f64) -> StepReport {
        let p = self.parameters;
        let force = p.saturate(u);
        let mut report = StepReport::default();
        self.state = ode::integrate(
            |_t, s| p.derivative(s, force),
            |time, s| {
                if s[0].abs() > p.rail_limit {
                    let side = s[0].signum();
                    s[0] = side * p.rail_limit;
                    if side * s[2] > 0.0 {
                        s[2] = 0.0;
                    }
                    if report.hit_stop.is_none() {
                        report.hit_stop = Some((time, s[0]));
                    }
                }
            },
            t,
            &self.state,
            h,
            h_max,
        );
        report
    }
}

// FMU-state snapshots (plain bytes) of the types above: every field, in order.
crate::plain_state!(GantryCraneParameters {
    cart_mass,
    load_mass,
    rod_length,
    inertia,
    cart_friction,
    pivot_friction,
    gravity,
    max_force,
    rail_limit
});
crate::plain_state!(GantryCrane { parameters, state });

#[cfg(test)]
mod tests {
    use super::*;

    fn crane(theta0: f64) -> GantryCrane {
        GantryCrane::new(
            GantryCraneParameters::default(),
            Vector4::new(0.0, theta0, 0.0, 0.0),
        )
        .unwrap()
    }

    #[test]
    fn linearisation_matches_the_reference_coefficients() {
        // docs/reference-values.md §6: k1..k8 computed independently.
        let (a, b) = GantryCraneParameters::default().linearised();
        let expect = [
            // (ours, reference, half a unit in the reference's last printed digit)
            (a[(2, 1)], -0.14998, 5e-6),
            (a[(2, 2)], -0.79390, 5e-6),
            (a[(2, 3)], -3.2e-5, 5e-7),
            (a[(3, 1)], -28.787, 5e-4),
            (a[(3, 2)], -2.2969, 5e-5),
            (a[(3, 3)], -0.00612, 5e-6),
            (b[2], 1.18493, 5e-6),
            (b[3], 3.42821, 5e-6),
        ];
        for (got, want, tol) in expect {
            assert!(
                (got - want).abs() <= tol,
                "coefficient {got} vs reference {want}"
            );
        }
    }

    #[test]
    fn linearisation_matches_finite_differences_of_the_nonlinear_model() {
        let p = GantryCraneParameters::default();
        let (a, b) = p.linearised();
        let zero = CraneState::zeros();
        let eps = 1e-7;
        for j in 0..4 {
            let mut s = zero;
            s[j] = eps;
            let col = (p.derivative(&s, 0.0) - p.derivative(&zero, 0.0)) / eps;
            for i in 0..4 {
                assert!((col[i] - a[(i, j)]).abs() < 1e-5 * (1.0 + a[(i, j)].abs()));
            }
        }
        let col = (p.derivative(&zero, eps) - p.derivative(&zero, 0.0)) / eps;
        assert!((col - b).norm() < 1e-5);
    }

    #[test]
    fn free_swing_conserves_energy_without_friction() {
        let p = GantryCraneParameters {
            cart_friction: 0.0,
            pivot_friction: 0.0,
            ..Default::default()
        };
        let mut c = GantryCrane::new(p, Vector4::new(0.0, 0.3, 0.0, 0.0)).unwrap();
        let energy = |s: &CraneState| {
            let (m, big_m, l, j, g) =
                (p.load_mass, p.cart_mass, p.rod_length, p.inertia, p.gravity);
            0.5 * (big_m + m) * s[2] * s[2] + 0.5 * (j + m * l * l) * s[3] * s[3]
                - m * l * s[2] * s[3] * s[1].cos()
                - m * g * l * s[1].cos()
        };
        let e0 = energy(&c.state);
        for k in 0..200 {
            c.advance(k as f64 * 0.05, 0.0, 0.05, 1e-3);
        }
        assert!((energy(&c.state) - e0).abs() < 1e-9 * e0.abs());
    }

    #[test]
    fn force_is_saturated() {
        let p = GantryCraneParameters::default();
        assert_eq!(p.saturate(100.0), 17.0);
        assert_eq!(p.saturate(-100.0), -17.0);
        assert_eq!(p.saturate(3.0), 3.0);
    }

    #[test]
    fn rail_stop_holds_the_cart() {
        let mut c = crane(0.0);
        let mut hits = 0;
        for k in 0..200 {
            let r = c.advance(k as f64 * 0.05, 17.0, 0.05, 1e-3);
            hits += r.hit_stop.is_some() as usize;
            assert!(c.state[0].abs() <= 0.5);
        }
        assert_eq!(c.state[0], 0.5);
        assert_eq!(c.state[2], 0.0);
        assert!(hits >= 1);
    }

    #[test]
    fn bad_parameters_are_named() {
        let p = GantryCraneParameters {
            rod_length: -1.0,
            ..Default::default()
        };
        let e = GantryCrane::new(p, CraneState::zeros()).unwrap_err();
        assert_eq!(e.parameter, "l");
        let e = GantryCrane::new(
            GantryCraneParameters::default(),
            Vector4::new(0.7, 0.0, 0.0, 0.0),
        )
        .unwrap_err();
        assert_eq!(e.parameter, "x0");
    }

    #[test]
    fn small_swing_period_matches_the_linearised_model() {
        let mut c = crane(0.05);
        let h = 1e-3;
        let mut crossings = Vec::new();
        let mut prev = c.state[1];
        for k in 0..10_000 {
            c.advance(k as f64 * h, 0.0, h, h);
            let th = c.state[1];
            if prev < 0.0 && th >= 0.0 {
                let t = k as f64 * h + h * (-prev) / (th - prev);
                crossings.push(t);
            }
            prev = th;
        }
        let period = (crossings[crossings.len() - 1] - crossings[0]) / (crossings.len() - 1) as f64;
        let (a, _) = GantryCraneParameters::default().linearised();
        let eig = a.complex_eigenvalues();
        let w = eig.iter().map(|e| e.im.abs()).fold(0.0, f64::max);
        let linear_period = 2.0 * std::f64::consts::PI / w;
        assert!(((period - linear_period) / linear_period).abs() < 5e-3);
    }
}
