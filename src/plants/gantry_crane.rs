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
//!
//! **One right-hand side, two interfaces.** [`GantryCraneParameters::rhs`] is the equation in
//! a contact mode ([`RailContact`]: free, or held against one stop, where the cart stands still
//! and the load swings about a fixed pivot). The Co-Simulation side integrates
//! [`GantryCraneParameters::derivative`], which reads the mode from the state at every
//! evaluation ([`GantryCraneParameters::contact`]) and clamps the cart onto the stop after each
//! RK4 substep ([`GantryCrane::advance`]); the Model Exchange side keeps the mode as a discrete
//! state, gives the solver [`GantryCraneParameters::event_indicators`] (stop reached, release
//! when the net force turns inwards, force limit) and makes the change in event mode with
//! [`GantryCraneParameters::at_event`]. [`GantryCraneParameters::jacobian`] is the exact
//! Jacobian of the right-hand side for implicit solvers.

use crate::ode;
use crate::ParameterError;
use nalgebra::{Matrix4, SVector, Vector4};

/// State `[x, θ, ẋ, θ̇]` in m, rad, m/s, rad/s.
pub type CraneState = SVector<f64, 4>;

/// Number of event indicators of the Model Exchange interface ([`GantryCraneParameters::event_indicators`]).
pub const EVENT_INDICATORS: usize = 3;

/// How close (relative to `x_limit`) a cart must be to a stop for [`GantryCraneParameters::at_event`]
/// to put it there: a solver locates the crossing to about its root tolerance, not exactly.
pub const STOP_TOLERANCE: f64 = 1e-9;

/// The cart's contact with the rail stops: the discrete state of the Model Exchange interface
/// (the Co-Simulation interface reads it from the state at every evaluation, [`GantryCraneParameters::contact`]).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub enum RailContact {
    /// On the rail between the stops (or at a stop and moving or pushed away from it).
    #[default]
    Free,
    /// Held against the stop at `−x_limit`.
    HeldLeft,
    /// Held against the stop at `+x_limit`.
    HeldRight,
}

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
    #[inline]
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

    /// Angular acceleration `θ̈` of the load while the cart is held against a stop (a pendulum
    /// about a fixed pivot): `(J + m l²) θ̈ = −f_p θ̇ − m g l sin θ`.
    pub fn held_angular_acceleration(&self, s: &CraneState) -> f64 {
        let a22 = self.inertia + self.load_mass * self.rod_length * self.rod_length;
        (-self.pivot_friction * s[3] - self.load_mass * self.rod_length * self.gravity * s[1].sin())
            / a22
    }

    /// The contact a state is in, given the free cart acceleration `xdd` there: held against
    /// the stop at ±`x_limit` when the cart is at it (`|x| ≥ x_limit`), not moving away from
    /// it and pushed into it (`side·ẋ ≥ 0`, `side·ẍ_free ≥ 0`); free otherwise.
    #[inline]
    pub fn contact(&self, s: &CraneState, xdd: f64) -> RailContact {
        let side = s[0].signum();
        if s[0].abs() >= self.rail_limit && side * s[2] >= 0.0 && side * xdd >= 0.0 {
            if side > 0.0 {
                RailContact::HeldRight
            } else {
                RailContact::HeldLeft
            }
        } else {
            RailContact::Free
        }
    }

    /// The right-hand side `ṡ = f(s, u)` in a given contact mode, `u` the applied force; the
    /// one both interfaces integrate. Free: `[ẋ, θ̇, ẍ, θ̈]` of the free cart. Held: the cart
    /// stands still (`ẋ = ẍ = 0` in the derivative) and the load swings about the fixed pivot.
    pub fn rhs(&self, s: &CraneState, u: f64, contact: RailContact) -> CraneState {
        match contact {
            RailContact::Free => {
                let (xdd, thdd) = self.free_accelerations(s, u);
                Vector4::new(s[2], s[3], xdd, thdd)
            }
            RailContact::HeldLeft | RailContact::HeldRight => {
                Vector4::new(0.0, s[3], 0.0, self.held_angular_acceleration(s))
            }
        }
    }

    /// Right-hand side `ṡ = f(s, u)` including the rail stops, the contact read from the state
    /// ([`Self::contact`]); `u` is the applied force. This is what the RK4 substeps of the
    /// Co-Simulation interface integrate.
    #[inline]
    pub fn derivative(&self, s: &CraneState, u: f64) -> CraneState {
        let (xdd, thdd) = self.free_accelerations(s, u);
        match self.contact(s, xdd) {
            RailContact::Free => Vector4::new(s[2], s[3], xdd, thdd),
            held => self.rhs(s, u, held),
        }
    }

    /// Slope of the saturation `dU_applied/dU`: 1 inside ±`U_max`, 0 on and beyond the limits.
    pub fn saturation_slope(&self, u: f64) -> f64 {
        if u.abs() < self.max_force {
            1.0
        } else {
            0.0
        }
    }

    /// The analytic Jacobians of [`Self::rhs`] in a contact mode: `(∂f/∂s, ∂f/∂u)`, `u` the
    /// applied force (chain with [`Self::saturation_slope`] for the requested force).
    ///
    /// With the mass matrix `[[a₁₁, a₁₂], [a₁₂, a₂₂]]`, `a₁₂ = −m l cos θ`, determinant
    /// `Δ = a₁₁ a₂₂ − a₁₂²`, right-hand sides `b₁`, `b₂` and numerators `N₁ = b₁ a₂₂ − a₁₂ b₂`,
    /// `N₂ = a₁₁ b₂ − a₁₂ b₁`: `∂ẍ/∂q = (∂N₁/∂q − ẍ ∂Δ/∂q)/Δ`, `∂θ̈/∂q = (∂N₂/∂q − θ̈ ∂Δ/∂q)/Δ`,
    /// with `∂a₁₂/∂θ = m l sin θ`, `∂Δ/∂θ = −2 a₁₂ m l sin θ`, `∂b₁/∂θ = −m l θ̇² cos θ`,
    /// `∂b₁/∂ẋ = −f_c`, `∂b₁/∂θ̇ = −2 m l θ̇ sin θ`, `∂b₁/∂u = 1`, `∂b₂/∂θ = −m g l cos θ`,
    /// `∂b₂/∂θ̇ = −f_p`.
    pub fn jacobian(
        &self,
        s: &CraneState,
        u: f64,
        contact: RailContact,
    ) -> (Matrix4<f64>, Vector4<f64>) {
        let (theta, v, omega) = (s[1], s[2], s[3]);
        let (sin, cos) = theta.sin_cos();
        let ml = self.load_mass * self.rod_length;
        let mgl = ml * self.gravity;
        let a11 = self.cart_mass + self.load_mass;
        let a22 = self.inertia + self.load_mass * self.rod_length * self.rod_length;
        let mut dfds = Matrix4::zeros();
        let mut dfdu = Vector4::zeros();
        dfds[(1, 3)] = 1.0;
        if contact != RailContact::Free {
            dfds[(3, 1)] = -mgl * cos / a22;
            dfds[(3, 3)] = -self.pivot_friction / a22;
            return (dfds, dfdu);
        }
        dfds[(0, 2)] = 1.0;
        let a12 = -ml * cos;
        let b1 = u - self.cart_friction * v - ml * omega * omega * sin;
        let b2 = -self.pivot_friction * omega - mgl * sin;
        let det = a11 * a22 - a12 * a12;
        let xdd = (b1 * a22 - a12 * b2) / det;
        let thdd = (a11 * b2 - a12 * b1) / det;
        // Partial derivatives of the pieces with respect to θ, ẋ, θ̇ and u.
        let a12_th = ml * sin;
        let det_th = -2.0 * a12 * a12_th;
        let (b1_th, b1_v, b1_om, b1_u) = (
            -ml * omega * omega * cos,
            -self.cart_friction,
            -2.0 * ml * omega * sin,
            1.0,
        );
        let (b2_th, b2_om) = (-mgl * cos, -self.pivot_friction);
        let n1 = [
            b1_th * a22 - a12_th * b2 - a12 * b2_th,
            b1_v * a22,
            b1_om * a22 - a12 * b2_om,
            b1_u * a22,
        ];
        let n2 = [
            a11 * b2_th - a12_th * b1 - a12 * b1_th,
            -a12 * b1_v,
            a11 * b2_om - a12 * b1_om,
            -a12 * b1_u,
        ];
        let det_q = [det_th, 0.0, 0.0, 0.0];
        // Columns θ, ẋ, θ̇ of ∂f/∂s (1, 2, 3) and u.
        for (k, (col, det_k)) in [1usize, 2, 3, 4].iter().zip(det_q).enumerate() {
            let dx = (n1[k] - xdd * det_k) / det;
            let dth = (n2[k] - thdd * det_k) / det;
            if *col == 4 {
                dfdu[2] = dx;
                dfdu[3] = dth;
            } else {
                dfds[(2, *col)] = dx;
                dfds[(3, *col)] = dth;
            }
        }
        (dfds, dfdu)
    }

    /// Event indicators of the Model Exchange interface for state `s`, requested force `u`
    /// (before saturation) and contact mode; each is positive inside the mode and changes
    /// sign where the physics switches:
    ///
    /// * `z₀`, right stop: free, `x_limit − x` (the cart reaches the stop); held at the right
    ///   stop, `ẍ_free` (the net force turns inwards: release).
    /// * `z₁`, left stop: free, `x + x_limit`; held at the left stop, `−ẍ_free`.
    /// * `z₂`, force limit: `U_max − |U|` (the requested force crosses ±`U_max`).
    pub fn event_indicators(&self, s: &CraneState, u: f64, contact: RailContact) -> [f64; 3] {
        let free_xdd = || self.free_accelerations(s, self.saturate(u)).0;
        let right = match contact {
            RailContact::HeldRight => free_xdd(),
            _ => self.rail_limit - s[0],
        };
        let left = match contact {
            RailContact::HeldLeft => -free_xdd(),
            _ => s[0] + self.rail_limit,
        };
        [right, left, self.max_force - u.abs()]
    }

    /// The discrete change at an event for state `s` under the applied force `u`: a cart
    /// beyond a stop, or at it (within [`STOP_TOLERANCE`] relative, where a solver locates
    /// the crossing) and not moving away from it, is put on it, its velocity into the stop
    /// set to zero (perfectly inelastic); the contact is chosen by [`Self::contact`]: held
    /// while the net force pushes outwards, released (free) once it turns inwards. A cart
    /// leaving the stop keeps its place: put back, its indicator `x_limit − |x|` would be 0
    /// again after every step, each an event (docs/models.md §2.1). Returns the new state
    /// and contact.
    pub fn at_event(&self, s: &CraneState, u: f64) -> (CraneState, RailContact) {
        let mut next = *s;
        let side = next[0].signum();
        let beyond = next[0].abs() > self.rail_limit;
        let at_stop = next[0].abs() >= self.rail_limit * (1.0 - STOP_TOLERANCE);
        if beyond || (at_stop && side * next[2] >= 0.0) {
            next[0] = side * self.rail_limit;
            if side * next[2] > 0.0 {
                next[2] = 0.0;
            }
        }
        let (xdd, _) = self.free_accelerations(&next, u);
        (next, self.contact(&next, xdd))
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
        // RK4 cannot fail: its bound on substeps is checked by the caller (`check_substeps`)
        self.advance_with(t, u, h, Integrator::Rk4 { h_max }, &mut 0.0)
            .unwrap_or_default()
    }

    /// Advances the state from time `t` over `h` seconds under the requested force `u`
    /// (saturated here) with `integrator`; `step_guess` carries the adaptive integrator's step
    /// size from call to call ([`ode::integrate_adaptive`]). After every (sub)step a cart past
    /// a stop is put back on it. Nothing changes on an error.
    pub fn advance_with(
        &mut self,
        t: f64,
        u: f64,
        h: f64,
        integrator: Integrator,
        step_guess: &mut f64,
    ) -> Result<StepReport, ParameterError> {
        let p = self.parameters;
        let force = p.saturate(u);
        let mut report = StepReport::default();
        self.state = match integrator {
            Integrator::Rk4 { h_max } => {
                p.rk4_substeps(force, (t, h), h_max, &self.state, &mut report)
            }
            Integrator::DormandPrince { tolerance } => {
                let f = |_t: f64, s: &CraneState| p.derivative(s, force);
                let keep_on_rail =
                    |time: f64, s: &mut CraneState| p.keep_on_rail(time, s, &mut report);
                let mut control = ode::StepControl {
                    tolerance,
                    next_step: *step_guess,
                };
                let state =
                    ode::integrate_adaptive(f, keep_on_rail, &mut control, (t, h), &self.state)?;
                *step_guess = control.next_step;
                state
            }
        };
        Ok(report)
    }
}

/// How the Co-Simulation side integrates a communication step.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Integrator {
    /// Classical RK4 on equal substeps no longer than `h_max` ([`ode::integrate`]).
    Rk4 {
        /// Longest substep (s).
        h_max: f64,
    },
    /// Dormand–Prince 5(4) with error control at `tolerance` ([`ode::integrate_adaptive`]).
    DormandPrince {
        /// Mixed absolute/relative error tolerance per step.
        tolerance: f64,
    },
}

impl GantryCraneParameters {
    /// RK4 substeps no longer than `h_max` over the span `(t, h)` from `state` under the
    /// applied force, the cart kept on the rail after each ([`ode::integrate`]).
    ///
    /// Out of line on purpose: compiled as a function of its own, with the right-hand side
    /// inlined into its loop, it runs a GantryCrane step 8–10 % faster than the same loop
    /// inlined into [`GantryCrane::advance_with`] beside the adaptive integrator (the same
    /// instructions, measured with `scripts/bench --baseline`).
    #[inline(never)]
    fn rk4_substeps(
        self,
        force: f64,
        (t, h): (f64, f64),
        h_max: f64,
        state: &CraneState,
        report: &mut StepReport,
    ) -> CraneState {
        let f = |_t: f64, s: &CraneState| self.derivative(s, force);
        let keep_on_rail = |time: f64, s: &mut CraneState| self.keep_on_rail(time, s, report);
        ode::integrate(f, keep_on_rail, t, state, h, h_max)
    }

    /// The Co-Simulation side's stop after a substep: a cart past a rail end is put back on
    /// it, its velocity into the stop set to zero, and the first hit recorded.
    fn keep_on_rail(&self, time: f64, s: &mut CraneState, report: &mut StepReport) {
        if s[0].abs() > self.rail_limit {
            let side = s[0].signum();
            s[0] = side * self.rail_limit;
            if side * s[2] > 0.0 {
                s[2] = 0.0;
            }
            if report.hit_stop.is_none() {
                report.hit_stop = Some((time, s[0]));
            }
        }
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
crate::plain_state!(
    enum RailContact {
        Free,
        HeldLeft,
        HeldRight,
    }
);

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
    fn analytic_jacobians_match_central_finite_differences_at_random_states() {
        let mut rng = crate::signals::rng::RandomGenerator::new(17);
        let mut worst: f64 = 0.0;
        for k in 0..500 {
            // random parameters around the laboratory crane, random states and forces
            let d = GantryCraneParameters::default();
            let p = GantryCraneParameters {
                cart_mass: d.cart_mass * rng.uniform_range(0.5, 2.0),
                load_mass: d.load_mass * rng.uniform_range(0.5, 50.0),
                rod_length: d.rod_length * rng.uniform_range(0.5, 2.0),
                inertia: d.inertia * rng.uniform_range(0.0, 100.0),
                cart_friction: d.cart_friction * rng.uniform_range(0.0, 2.0),
                pivot_friction: rng.uniform_range(0.0, 0.1),
                ..d
            };
            let s = Vector4::new(
                rng.uniform_range(-0.5, 0.5),
                rng.uniform_range(-3.0, 3.0),
                rng.uniform_range(-2.0, 2.0),
                rng.uniform_range(-5.0, 5.0),
            );
            let u = rng.uniform_range(-17.0, 17.0);
            let contact = [
                RailContact::Free,
                RailContact::HeldLeft,
                RailContact::HeldRight,
            ][k % 3];
            let (dfds, dfdu) = p.jacobian(&s, u, contact);
            let (fd_s, fd_u) = crate::plants::state_and_input_differences(
                |s, u| p.rhs(s, u, contact),
                &s,
                u,
                1e-6,
            );
            let scale = dfds.amax().max(dfdu.amax());
            let error = (dfds - fd_s).amax().max((dfdu - fd_u).amax()) / scale;
            worst = worst.max(error);
            assert!(
                error < 1e-6,
                "relative error {error:e} at {s:?}, u = {u}, {contact:?}"
            );
        }
        assert!(worst > 0.0);
        // the structure: ẋ = v, θ̇ = ω exactly; held, ẋ = ẍ = 0 and no force enters
        let p = GantryCraneParameters::default();
        let s = Vector4::new(0.5, 0.2, 0.0, 1.0);
        let (free, b) = p.jacobian(&s, 3.0, RailContact::Free);
        assert_eq!(
            (free[(0, 2)], free[(1, 3)], free.column(0).amax()),
            (1.0, 1.0, 0.0)
        );
        assert!((b[2] - 1.0 / (p.cart_mass + p.load_mass)).abs() < 0.05 * b[2]);
        let (held, b) = p.jacobian(&s, 3.0, RailContact::HeldRight);
        assert_eq!(
            (held.row(0).amax(), held.row(2).amax(), b.amax()),
            (0.0, 0.0, 0.0)
        );
    }

    #[test]
    fn the_co_simulation_right_hand_side_is_the_mode_right_hand_side() {
        let p = GantryCraneParameters::default();
        // free inside the rail, held at the right stop pushed outwards, released when pulled
        let inside = Vector4::new(0.1, 0.3, 0.2, -1.0);
        assert_eq!(
            p.derivative(&inside, 5.0),
            p.rhs(&inside, 5.0, RailContact::Free)
        );
        let at_stop = Vector4::new(0.5, 0.1, 0.0, 0.5);
        let (xdd, _) = p.free_accelerations(&at_stop, 5.0);
        assert_eq!(p.contact(&at_stop, xdd), RailContact::HeldRight);
        let held = p.derivative(&at_stop, 5.0);
        assert_eq!(held, p.rhs(&at_stop, 5.0, RailContact::HeldRight));
        assert_eq!((held[0], held[2]), (0.0, 0.0));
        let (xdd, _) = p.free_accelerations(&at_stop, -5.0);
        assert_eq!(p.contact(&at_stop, xdd), RailContact::Free);
        assert!(p.derivative(&at_stop, -5.0)[2] < 0.0);
        let left = Vector4::new(-0.5, 0.0, -0.1, 0.0);
        let (xdd, _) = p.free_accelerations(&left, -1.0);
        assert_eq!(p.contact(&left, xdd), RailContact::HeldLeft);
    }

    #[test]
    fn events_reset_the_velocity_hold_and_release_the_cart() {
        let p = GantryCraneParameters::default();
        // free and moving right: z₀ = x_limit − x, z₁ = x + x_limit, z₂ = U_max − |U|
        let s = Vector4::new(0.4, 0.0, 1.0, 0.0);
        assert_eq!(
            p.event_indicators(&s, 20.0, RailContact::Free),
            [0.5 - 0.4, 0.9, -3.0]
        );
        // a solver locates the crossing to ~1e-13 m: the cart is put on the stop, v = 0, held
        let hit = Vector4::new(0.5 - 1e-12, 0.05, 0.8, 0.3);
        let (next, contact) = p.at_event(&hit, 5.0);
        assert_eq!((next[0], next[1], next[2], next[3]), (0.5, 0.05, 0.0, 0.3));
        assert_eq!(contact, RailContact::HeldRight);
        // held: z₀ is the free acceleration (positive while pushed out), z₁ unchanged
        let z = p.event_indicators(&next, 5.0, contact);
        assert_eq!(z[0], p.free_accelerations(&next, 5.0).0);
        assert!(z[0] > 0.0 && z[1] == 1.0);
        // the push reverses: z₀ turns negative, the event releases the cart, which moves in
        assert!(p.event_indicators(&next, -5.0, contact)[0] < 0.0);
        let (released, contact) = p.at_event(&next, -5.0);
        assert_eq!((released, contact), (next, RailContact::Free));
        assert!(p.rhs(&released, -5.0, contact)[2] < 0.0);
        // an inelastic hit under an inward force: velocity reset, free at once
        let (next, contact) = p.at_event(&Vector4::new(-0.5, 0.0, -0.3, 0.0), 5.0);
        assert_eq!((next[0], next[2], contact), (-0.5, 0.0, RailContact::Free));
        assert_eq!(p.event_indicators(&next, 5.0, contact)[1], 0.0);
        // far from the stops an event (the force limit) changes nothing
        let s = Vector4::new(0.2, 0.1, -0.4, 0.2);
        assert_eq!(p.at_event(&s, 17.0), (s, RailContact::Free));
        assert_eq!(p.event_indicators(&s, -17.0, RailContact::Free)[2], 0.0);
    }

    #[test]
    fn a_cart_leaving_a_stop_is_not_put_back_and_one_beyond_it_is_put_on_it() {
        let p = GantryCraneParameters::default();
        // Released at the right stop a moment ago, moving in by 1e-13 m: an event there (z₀
        // left 0 for > 0) leaves it where it is, free, so z₀ stays > 0 and no event follows.
        // Put back on the stop, z₀ would be 0 again and every step another event.
        let leaving = Vector4::new(0.5 - 1e-13, 1e-6, -2e-9, 0.0);
        let (next, contact) = p.at_event(&leaving, 0.0);
        assert_eq!((next, contact), (leaving, RailContact::Free));
        assert!(p.event_indicators(&next, 0.0, contact)[0] > 0.0);
        // The same at the left stop.
        let leaving = Vector4::new(-0.5 + 1e-13, 1e-6, 2e-9, 0.0);
        assert_eq!(p.at_event(&leaving, 0.0), (leaving, RailContact::Free));
        // A state beyond a stop (a filter's sigma point, a state set by a master) is put on
        // it, its outward velocity removed: the velocity inwards is kept.
        let beyond = Vector4::new(0.52, 0.0, -0.1, 0.0);
        let (next, contact) = p.at_event(&beyond, 0.0);
        assert_eq!((next[0], next[2], contact), (0.5, -0.1, RailContact::Free));
        let (next, _) = p.at_event(&Vector4::new(-0.52, 0.0, -0.1, 0.0), 0.0);
        assert_eq!((next[0], next[2]), (-0.5, 0.0));
    }

    /// θ₀ = 0.3, a varying force, `push` added for the first 3 s (4 N drive the cart into the
    /// right stop): the start and the force of step `k` of 50 ms.
    fn swing_under(push: f64) -> (CraneState, impl Fn(usize) -> f64) {
        let force = move |k: usize| 0.5 * (k as f64 * 0.15).cos() + if k < 60 { push } else { 0.0 };
        (Vector4::new(0.0, 0.3, 0.0, 0.0), force)
    }

    /// The states after each of 200 steps of 50 ms of [`swing_under`], with RK4 substeps of
    /// 20 µs (a tight reference).
    fn tight_reference(push: f64) -> Vec<CraneState> {
        let (start, force) = swing_under(push);
        let mut reference = crane(0.0);
        reference.state = start;
        let states: Vec<CraneState> = (0..200)
            .map(|k| {
                reference.advance(k as f64 * 0.05, force(k), 0.05, 2e-5);
                reference.state
            })
            .collect();
        assert_eq!(states.iter().any(|s| s[0] == 0.5), push > 3.0);
        states
    }

    /// The largest difference of `[x, θ, ẋ, θ̇]` from `reference` over the 200 steps (RK4 at
    /// 1 ms, or the adaptive integrator at a tolerance); and the number of evaluations of f.
    fn error_against(reference: &[CraneState], adaptive: Option<f64>, push: f64) -> (f64, usize) {
        let (start, force) = swing_under(push);
        let mut c = crane(0.0);
        c.state = start;
        let mut worst: f64 = 0.0;
        let mut guess = 0.0;
        for (k, want) in reference.iter().enumerate() {
            let integrator = match adaptive {
                Some(tolerance) => Integrator::DormandPrince { tolerance },
                None => Integrator::Rk4 { h_max: 1e-3 },
            };
            c.advance_with(k as f64 * 0.05, force(k), 0.05, integrator, &mut guess)
                .unwrap();
            worst = worst.max((c.state - want).amax());
        }
        let p = c.parameters;
        let mut evaluations = 0;
        let mut probe = start;
        let mut control = ode::StepControl {
            tolerance: adaptive.unwrap_or(0.0),
            next_step: 0.0,
        };
        for k in 0..reference.len() {
            let f = |_t: f64, s: &CraneState| {
                evaluations += 1;
                p.derivative(s, p.saturate(force(k)))
            };
            probe = match adaptive {
                Some(_) => ode::integrate_adaptive(f, |_, _| {}, &mut control, (0.0, 0.05), &probe)
                    .unwrap(),
                None => ode::integrate(f, |_, _| {}, 0.0, &probe, 0.05, 1e-3),
            };
        }
        (worst, evaluations)
    }

    #[test]
    fn the_adaptive_integrator_is_as_accurate_as_rk4_with_fewer_evaluations() {
        let references = [tight_reference(0.0), tight_reference(4.0)];
        for (push, tolerance) in [(0.0, 1e-10), (0.0, 1e-11), (0.0, 1e-12), (4.0, 1e-11)] {
            let reference = &references[usize::from(push > 0.0)];
            let (rk4, rk4_evaluations) = error_against(reference, None, push);
            let (adaptive, adaptive_evaluations) = error_against(reference, Some(tolerance), push);
            println!("push {push} N: RK4 1 ms {rk4:.2e} in {rk4_evaluations} evaluations, DP5(4) at {tolerance:e}: {adaptive:.2e} in {adaptive_evaluations}");
            if push == 0.0 && tolerance == 1e-11 {
                // off the stops at 1e-11: as accurate as RK4 1 ms, a third of the evaluations
                assert!(adaptive <= rk4, "adaptive {adaptive:e} vs RK4 {rk4:e}");
                assert!(adaptive_evaluations * 2 < rk4_evaluations);
            }
            if push > 0.0 {
                // at the stop both are limited by where the stop is found; DP5 finds it closer
                assert!(adaptive <= rk4, "adaptive {adaptive:e} vs RK4 {rk4:e}");
            }
        }
    }

    #[test]
    fn the_rk4_step_is_rk4_on_the_right_hand_side_bit_for_bit() {
        // rk4_substeps is ode::integrate of derivative with the stop kept, nothing else: the
        // published figures depend on it (a swing with a 4 N push into the right stop)
        let (start, force) = swing_under(4.0);
        let mut c = crane(0.0);
        c.state = start;
        let p = c.parameters;
        let mut x = start;
        let mut at_stop = 0;
        for k in 0..200 {
            let t = k as f64 * 0.05;
            c.advance(t, force(k), 0.05, 1e-3);
            let u = p.saturate(force(k));
            let mut report = StepReport::default();
            x = ode::integrate(
                |_t, s| p.derivative(s, u),
                |time, s| p.keep_on_rail(time, s, &mut report),
                t,
                &x,
                0.05,
                1e-3,
            );
            assert_eq!(c.state, x, "step {k}");
            at_stop += usize::from(x[0] == 0.5);
        }
        assert!(at_stop > 10, "{at_stop} steps at the stop");
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
