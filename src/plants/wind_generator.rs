//! The wind-generator laboratory set of paper 001 (§4 "Base de datos de un generador
//! eólico", Fig. 1, appendices A–D; docs/models.md §2.2): an induction motor fed by a variable
//! frequency drive (the "wind"), coupled to a wound-field synchronous generator feeding a
//! resistive load, its field fed by an SCR module, its speed read by a tachogenerator.
//!
//! Inputs: the drive reference `u_drive` and the field (SCR) reference `u_field`, both
//! 0–10 V; values outside are clipped to [0, 10] V (NaN counts as 0 V). Outputs: the shaft
//! speed as read by the tachogenerator [rpm] and the terminal voltage (RMS, line to line)
//! [V].
//!
//! # State (8, the paper's order)
//!
//! `x = [i_d, i_q, i_f, ω_m, θ_e, ω_s, v_f, ω_t]`: stator d/q currents [A] and field
//! current [A] of the generator, shaft speed [rad/s], electrical rotor angle [rad] (kept in
//! [0, 2π)), the drive's synchronous speed [rad/s, mechanical], the field voltage [V] and the
//! tachometer reading [rad/s].
//!
//! # Equations
//!
//! **Synchronous generator** (Krause's dq model in the rotor frame, amplitude-invariant Park
//! transform, generator convention: stator currents leave the machine; no damper windings).
//! Pole pairs `p`, electrical speed `ω_e = p ω_m`, flux linkages
//! `ψ_d = −L_d i_d + M_f i_f`, `ψ_q = −L_q i_q`, `ψ_f = L_f i_f − (3/2) M_f i_d`;
//! `v_d = −R_s i_d + dψ_d/dt − ω_e ψ_q`, `v_q = −R_s i_q + dψ_q/dt + ω_e ψ_d`,
//! `v_f = R_f i_f + dψ_f/dt`. A balanced star-connected resistive load `R_L` per phase gives
//! `v_d = R_L i_d`, `v_q = R_L i_q`, so with `R = R_s + R_L`:
//!
//! ```text
//! L_d di_d/dt − M_f di_f/dt        = −R i_d + ω_e L_q i_q
//! L_q di_q/dt                      = −R i_q − ω_e L_d i_d + ω_e M_f i_f
//! −(3/2) M_f di_d/dt + L_f di_f/dt = v_f − R_f i_f
//! T_e = (3/2) p (ψ_d i_q − ψ_q i_d) = (3/2) p (M_f i_f + (L_q − L_d) i_d) i_q
//! V_LL = √3 · (phase peak)/√2 = √(3/2) · R_L √(i_d² + i_q²)
//! ```
//!
//! (The d/f pair is solved in closed form; `L_d L_f − (3/2) M_f² > 0` is required.) These
//! are the paper's eqs (1)–(4) with their typos fixed: the q-axis equation has `i_q` and
//! `u_q`, and the mechanical equation below has friction and the load torque with its sign.
//!
//! **Shaft** (motor and generator rigidly coupled): `J dω_m/dt = T_m − T_e − B ω_m`,
//! `dθ_e/dt = p ω_m`.
//!
//! **Drive + induction motor.** The drive (Varispeed-606PC3, appendix C) turns `u_drive`
//! into a speed reference `ω_ref = (u_drive/10) · 2π f_rated / p` (10 V ↔ 60 Hz ↔ 1800 rpm).
//! The motor works on the linear part of its torque–slip curve,
//! `T_m = clamp(k_s (ω_s − ω_m), −T_max, T_max)` with `k_s` = rated torque / rated slip
//! speed and `T_max` the breakdown torque. The drive's slip compensation raises its output
//! frequency by the slip it estimates from the motor current (`T_m / k_s`), through a
//! first-order filter: `τ_drive dω_s/dt = ω_ref + T_m/k_s − ω_s`. Without clamping this is
//! `τ_drive dω_s/dt = ω_ref − ω_m`, an integral speed loop, so in steady state the shaft
//! turns at exactly `ω_ref` whatever the load; when the torque clamps, the same equation
//! keeps `ω_s` from winding up.
//!
//! **SCR field supply** (appendix D, 0–125 V DC for 0–10 V): `τ_scr dv_f/dt = 12.5 u_field
//! − v_f` (the firing delay of about half a mains cycle as a first-order lag).
//!
//! **Tachogenerator**: `τ_tach dω_t/dt = ω_m − ω_t`; the output is `ω_t · 60/(2π)` rpm.
//!
//! # Parameters (defaults)
//!
//! Generator (Hampden IM-100-3: 4 poles, 240 V, 1.5 A, 60 Hz, 0.33 hp, 1800 rpm; the values
//! are plausible for a machine of that size, not measured): `p = 2`, `R_s = 6 Ω`,
//! `L_d = 0.25 H` (X_d = 94 Ω ≈ 1.0 pu of the 92.4 Ω base), `L_q = 0.20 H`, `R_f = 200 Ω`,
//! `L_f = 40 H` (open-circuit field time constant 0.2 s), `M_f = 1.13844 H` (chosen so that
//! the rated operating point below gives exactly 240 V), load `R_L = 240 Ω` per phase (star).
//! Motor (Hampden IM-100, 1725 rpm at 60 Hz) and shaft: rated torque 0.33 hp / 1725 rpm =
//! 1.362 N·m, rated slip 75 rpm, so `k_s = 0.1734 N·m·s/rad`, `T_max = 3.4 N·m` (2.5 ×
//! rated); `J = 0.008 kg·m²` (both rotors), `B = 5·10⁻⁴ N·m·s/rad`. Time constants
//! `τ_drive = 0.5 s`, `τ_scr = 0.01 s`, `τ_tach = 0.02 s`; `f_rated = 60 Hz`.
//!
//! **Rated operating point** (`u_drive = 10 V`, `u_field = 8 V` = [`RATED_FIELD_REFERENCE`],
//! i.e. 100 V and 0.5 A on the field): 1800 rpm, 240 V line to line, 0.577 A per phase, 240 W
//! in the load (246 W = 0.33 hp through the air gap), `T_e = 1.305 N·m`, `T_m = 1.399 N·m`.
//! See [`WindGeneratorParameters::operating_point`].
//!
//! **Measured responses** (unit tests, from the rated point; the 63 % time of each output,
//! measured on the simulation, test `step_responses_have_the_documented_time_constants`):
//! drive step 8 → 10 V: speed (tachometer) 0.542 s; the same step moves the voltage too
//! (proportional to speed at a fixed field), 63 % in 0.503 s; field step 6 → 8 V at
//! 1800 rpm: voltage 0.221 s, no overshoot. From rest, the rated references reach 1800 rpm
//! and 240 V within 0.1 % after 3.3 s, without speed overshoot (test
//! `rated_references_give_1800_rpm_and_240_volts_from_rest`). The eigenvalues of the
//! Jacobian at the rated point are −1226 ± 377j (stator), −100 (SCR), −50 (tachometer),
//! −20.4 and −2.15 (shaft loop), −5.06 (field) and 0 (the angle) s⁻¹.
//!
//! # Integration
//!
//! The stator modes are fast (≈ −R/L ± jω_e, |λ| ≈ 1.3·10³ s⁻¹ all along a start-up, test
//! `stiffness_along_a_start_up`), far faster than the 0.1 s sampling of the paper and than
//! the slowest modes (2.15 s⁻¹): a stiffness ratio of about 600. They are kept as states, as
//! the paper's order-8 model has them. Three integrators:
//!
//! - [`WindGenerator::advance_adaptive`] with [`Adaptive::Dop853`] (the FMU's default): the
//!   eighth-order Dormand–Prince pair of [`crate::ode::dop853`] with error control
//!   ([`WindGenerator::tolerance`], relative tolerance
//!   [`WindGenerator::DEFAULT_RELATIVE_TOLERANCE`] = 7·10⁻¹²), its step carried from one
//!   communication step to the next, on [`HeldRightHandSide`]. At that tolerance the step
//!   is set by accuracy, where an eighth-order method takes long steps; where the solution is
//!   quiet the error control holds the step at the stability limit (≈ 4–5 ms, `h |λ|max ≈ 6`).
//!   Over a start-up from rest with reference steps (test
//!   `default_integrator_reaches_the_former_defaults_accuracy_in_a_sixth_of_its_work`),
//!   speed and voltage stay within 7.5·10⁻¹² (relative to 1800 rpm, 240 V) of RK4 on a
//!   2·10⁻⁵ s grid — the former default, RK4 at 10⁻⁴ s: 1.9·10⁻¹¹ — with about 615
//!   right-hand sides per 0.1 s where RK4 takes 4 000. Its error is 1–3 times `rtol` and
//!   moves with the last bits of the step sequence, so the tolerance is chosen on the worst of
//!   several scenarios (test `the_default_tolerance_keeps_the_former_defaults_accuracy_over_five_start_ups`):
//!   7·10⁻¹² keeps it within 1.2·10⁻¹¹ in all (1.6× below 1.9·10⁻¹¹), for 5 % less work
//!   than 5·10⁻¹² (whose worst was 1.5·10⁻¹¹); 6·10⁻¹² and 8·10⁻¹² reached 1.7 and
//!   1.9·10⁻¹¹, 10⁻¹¹ 2.8·10⁻¹¹ in the bench's scenario.
//!   What sets the step there is the stator currents' error in the second after a reference
//!   change (three quarters of the steps; the slow states, the lags and the first
//!   milliseconds of a communication step do not limit it: tests in [`crate::ode::dop853`],
//!   figures on the FMU page).
//! - [`WindGenerator::advance_adaptive`] with [`Adaptive::Rodas3`]: the L-stable Rosenbrock
//!   method RODAS3 of [`crate::ode::rosenbrock`] on the analytic Jacobian
//!   [`WindGeneratorParameters::jacobian_state`]. Stability never bounds its step, so it is
//!   the cheapest at loose tolerances (1.4·10⁻⁷ at rtol 10⁻⁷, 1 599 steps for the 10 s), but
//!   as a third-order method it needs ever more steps below (57 513 at rtol 10⁻¹¹).
//! - [`WindGenerator::advance`]: classical RK4 on fixed substeps. RK4 is stable for substeps
//!   below ≈ 2 ms; [`WindGenerator::RECOMMENDED_MAX_SUBSTEP`] = 10⁻⁴ s keeps the outputs
//!   within 10⁻⁶ relative of a twice finer grid (unit test; 1.9·10⁻¹¹ from the reference
//!   above).

use crate::ode;
use crate::ode::dop853;
use crate::ode::rosenbrock::{self, Statistics, StepError, Tolerance};
use crate::{require_finite, ParameterError};
use nalgebra::{SMatrix, SVector};
use std::f64::consts::PI;

/// State `[i_d, i_q, i_f, ω_m, θ_e, ω_s, v_f, ω_t]` (module docs for units).
pub type GeneratorState = SVector<f64, 8>;

/// Names of the state entries, in order (FMU variable names).
pub const STATE_NAMES: [&str; 8] = [
    "i_d",
    "i_q",
    "i_f",
    "omega_m",
    "theta_e",
    "omega_s",
    "v_f",
    "omega_tach",
];

/// The field reference [V] that gives 240 V at 1800 rpm with the default parameters.
pub const RATED_FIELD_REFERENCE: f64 = 8.0;

/// The drive reference [V] for 1800 rpm.
pub const RATED_DRIVE_REFERENCE: f64 = 10.0;

/// Field voltage per volt of SCR reference: 125 V / 10 V.
const SCR_GAIN: f64 = 12.5;

/// Range of both references [V].
const REFERENCE_MAX: f64 = 10.0;

/// Clips a reference voltage to [0, 10] V (NaN → 0 V).
pub fn clip_reference(u: f64) -> f64 {
    if u.is_nan() {
        0.0
    } else {
        u.clamp(0.0, REFERENCE_MAX)
    }
}

/// Number of event indicators ([`WindGeneratorParameters::event_indicators`]).
pub const EVENT_INDICATORS: usize = 3;

/// Number of outputs ([`WindGeneratorParameters::outputs`]).
pub const OUTPUTS: usize = 10;

/// Names of the outputs, in the order of [`WindGeneratorParameters::outputs`] (FMU variable
/// names).
pub const OUTPUT_NAMES: [&str; OUTPUTS] = [
    "speed",
    "voltage",
    "frequency",
    "shaft_speed",
    "field_current",
    "field_voltage",
    "T_e",
    "T_m",
    "i_d",
    "i_q",
];

/// `∂f/∂x` (8 × 8).
pub type StateMatrix = SMatrix<f64, 8, 8>;
/// `∂f/∂(u_drive, u_field)` (8 × 2).
pub type InputMatrix = SMatrix<f64, 8, 2>;
/// `∂(outputs)/∂x` (10 × 8).
pub type OutputMatrix = SMatrix<f64, OUTPUTS, 8>;

/// Where the motor torque `k_s (ω_s − ω_m)` is relative to its breakdown limit ±T_max.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TorqueLimit {
    /// `|k_s (ω_s − ω_m)| < T_max`: `T_m = k_s (ω_s − ω_m)`.
    Linear,
    /// `k_s (ω_s − ω_m) ≥ T_max`: `T_m = T_max`.
    Upper,
    /// `k_s (ω_s − ω_m) ≤ −T_max`: `T_m = −T_max`.
    Lower,
}

/// The discrete change when the angle completes a turn: `θ_e` back into [0, 2π).
pub fn wrap_angle(x: &mut GeneratorState) {
    x[4] = x[4].rem_euclid(2.0 * PI);
}

/// Physical parameters (SI units). Defaults: module docs.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WindGeneratorParameters {
    /// Pole pairs `p` (4 poles → 2).
    pub pole_pairs: f64,
    /// Stator resistance per phase `R_s` [Ω].
    pub stator_resistance: f64,
    /// d-axis synchronous inductance `L_d` [H].
    pub d_inductance: f64,
    /// q-axis synchronous inductance `L_q` [H].
    pub q_inductance: f64,
    /// Field resistance `R_f` [Ω].
    pub field_resistance: f64,
    /// Field self-inductance `L_f` [H].
    pub field_inductance: f64,
    /// Stator–field mutual inductance `M_f` [H].
    pub mutual_inductance: f64,
    /// Load resistance per phase, star-connected, `R_load` [Ω].
    pub load_resistance: f64,
    /// Total shaft inertia `J` [kg·m²].
    pub inertia: f64,
    /// Viscous friction `B` [N·m·s/rad].
    pub friction: f64,
    /// Motor torque per rad/s of slip `k_s` [N·m·s/rad].
    pub slip_stiffness: f64,
    /// Motor breakdown torque `T_max` [N·m].
    pub max_motor_torque: f64,
    /// Drive slip-compensation / frequency filter time constant `tau_drive` [s].
    pub drive_time_constant: f64,
    /// SCR module lag `tau_scr` [s].
    pub scr_time_constant: f64,
    /// Tachogenerator lag `tau_tach` [s].
    pub tachometer_time_constant: f64,
    /// Supply frequency at full drive reference `f_rated` [Hz].
    pub rated_frequency: f64,
}

impl Default for WindGeneratorParameters {
    fn default() -> Self {
        Self {
            pole_pairs: 2.0,
            stator_resistance: 6.0,
            d_inductance: 0.25,
            q_inductance: 0.20,
            field_resistance: 200.0,
            field_inductance: 40.0,
            mutual_inductance: 1.138_439_818_491_547,
            load_resistance: 240.0,
            inertia: 0.008,
            friction: 5e-4,
            slip_stiffness: 0.1734,
            max_motor_torque: 3.4,
            drive_time_constant: 0.5,
            scr_time_constant: 0.01,
            tachometer_time_constant: 0.02,
            rated_frequency: 60.0,
        }
    }
}

/// The steady state for constant references (see
/// [`WindGeneratorParameters::operating_point`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OperatingPoint {
    /// The full state.
    pub state: GeneratorState,
    /// Shaft speed [rpm].
    pub speed_rpm: f64,
    /// Terminal voltage, RMS line to line [V].
    pub terminal_voltage: f64,
    /// Electrical torque [N·m].
    pub electrical_torque: f64,
    /// Motor torque [N·m].
    pub motor_torque: f64,
    /// Whether the motor torque is within ±T_max (otherwise the shaft cannot reach the
    /// reference speed and `state` is not an equilibrium).
    pub reachable: bool,
}

impl WindGeneratorParameters {
    /// Checks every parameter, naming the first one that is not physical.
    pub fn validate(&self) -> Result<(), ParameterError> {
        use crate::Requirement::{NonNegative, Positive};
        crate::check_all(&[
            ("pole_pairs", self.pole_pairs, Positive),
            ("R_s", self.stator_resistance, Positive),
            ("L_d", self.d_inductance, Positive),
            ("L_q", self.q_inductance, Positive),
            ("R_f", self.field_resistance, Positive),
            ("L_f", self.field_inductance, Positive),
            ("M_f", self.mutual_inductance, Positive),
            ("R_load", self.load_resistance, Positive),
            ("J", self.inertia, Positive),
            ("B", self.friction, NonNegative),
            ("k_s", self.slip_stiffness, Positive),
            ("T_max", self.max_motor_torque, Positive),
            ("tau_drive", self.drive_time_constant, Positive),
            ("tau_scr", self.scr_time_constant, Positive),
            ("tau_tach", self.tachometer_time_constant, Positive),
            ("f_rated", self.rated_frequency, Positive),
        ])?;
        let determinant = self.d_field_determinant();
        if determinant <= 1e-9 * self.d_inductance * self.field_inductance {
            return Err(ParameterError::new(
                "M_f",
                format!("L_d·L_f − (3/2)·M_f² must be positive (some leakage), got {determinant}"),
            ));
        }
        Ok(())
    }

    /// `(L_d, L_q, L_f, M_f)`.
    fn inductances(&self) -> (f64, f64, f64, f64) {
        (
            self.d_inductance,
            self.q_inductance,
            self.field_inductance,
            self.mutual_inductance,
        )
    }

    /// `L_d L_f − (3/2) M_f²`.
    fn d_field_determinant(&self) -> f64 {
        self.d_inductance * self.field_inductance
            - 1.5 * self.mutual_inductance * self.mutual_inductance
    }

    /// Speed reference of the drive [rad/s] for a (clipped) reference voltage.
    pub fn speed_reference(&self, u_drive: f64) -> f64 {
        clip_reference(u_drive) / REFERENCE_MAX * 2.0 * PI * self.rated_frequency / self.pole_pairs
    }

    /// Motor torque for synchronous speed `omega_s` and shaft speed `omega_m`.
    pub fn motor_torque(&self, omega_s: f64, omega_m: f64) -> f64 {
        (self.slip_stiffness * (omega_s - omega_m))
            .clamp(-self.max_motor_torque, self.max_motor_torque)
    }

    /// Where the motor torque `k_s (ω_s − ω_m)` is: within ±T_max or at one limit (a value
    /// exactly at a limit counts as on it, as in [`Self::motor_torque`]'s clamp).
    pub fn torque_limit_of(&self, omega_s: f64, omega_m: f64) -> TorqueLimit {
        let torque = self.slip_stiffness * (omega_s - omega_m);
        if torque >= self.max_motor_torque {
            TorqueLimit::Upper
        } else if torque <= -self.max_motor_torque {
            TorqueLimit::Lower
        } else {
            TorqueLimit::Linear
        }
    }

    /// The motor torque with the limit held at `limit`; equal to [`Self::motor_torque`] when
    /// `limit == self.torque_limit_of(omega_s, omega_m)`.
    pub fn motor_torque_on(&self, omega_s: f64, omega_m: f64, limit: TorqueLimit) -> f64 {
        match limit {
            TorqueLimit::Linear => self.slip_stiffness * (omega_s - omega_m),
            TorqueLimit::Upper => self.max_motor_torque,
            TorqueLimit::Lower => -self.max_motor_torque,
        }
    }

    /// Electrical (braking) torque `T_e` for the state `x`.
    pub fn electrical_torque(&self, x: &GeneratorState) -> f64 {
        let (i_d, i_q, i_f) = (x[0], x[1], x[2]);
        1.5 * self.pole_pairs
            * (self.mutual_inductance * i_f + (self.q_inductance - self.d_inductance) * i_d)
            * i_q
    }

    /// Terminal voltage, RMS line to line [V], for the state `x`.
    pub fn terminal_voltage(&self, x: &GeneratorState) -> f64 {
        (1.5f64).sqrt() * self.load_resistance * (x[0] * x[0] + x[1] * x[1]).sqrt()
    }

    /// Right-hand side `ẋ = f(x, u)` for references `u_drive`, `u_field` (clipped here).
    pub fn derivative(&self, x: &GeneratorState, u_drive: f64, u_field: f64) -> GeneratorState {
        self.derivative_on(x, u_drive, u_field, self.torque_limit_of(x[5], x[3]))
    }

    /// The right-hand side with the motor torque's limit held at `limit` (the Model Exchange
    /// side holds it between events so the solver sees a smooth function;
    /// [`Self::derivative`] takes the limit of the state itself).
    pub fn derivative_on(
        &self,
        x: &GeneratorState,
        u_drive: f64,
        u_field: f64,
        limit: TorqueLimit,
    ) -> GeneratorState {
        let (i_d, i_q, i_f, omega_m) = (x[0], x[1], x[2], x[3]);
        let (omega_s, v_f, omega_t) = (x[5], x[6], x[7]);
        let omega_e = self.pole_pairs * omega_m;
        let resistance = self.stator_resistance + self.load_resistance;
        let (l_d, l_q, l_f, m_f) = self.inductances();
        // [L_d, −M_f; −1.5 M_f, L_f] [di_d; di_f] = [r_d; r_f]
        let r_d = -resistance * i_d + omega_e * l_q * i_q;
        let r_f = v_f - self.field_resistance * i_f;
        let det = self.d_field_determinant();
        let di_d = (l_f * r_d + m_f * r_f) / det;
        let di_f = (l_d * r_f + 1.5 * m_f * r_d) / det;
        let di_q = (-resistance * i_q - omega_e * l_d * i_d + omega_e * m_f * i_f) / l_q;
        let motor_torque = self.motor_torque_on(omega_s, omega_m, limit);
        let domega_m =
            (motor_torque - self.electrical_torque(x) - self.friction * omega_m) / self.inertia;
        let omega_ref = self.speed_reference(u_drive);
        let domega_s =
            (omega_ref + motor_torque / self.slip_stiffness - omega_s) / self.drive_time_constant;
        let dv_f = (SCR_GAIN * clip_reference(u_field) - v_f) / self.scr_time_constant;
        let domega_t = (omega_m - omega_t) / self.tachometer_time_constant;
        GeneratorState::from_column_slice(&[
            di_d, di_q, di_f, domega_m, omega_e, domega_s, dv_f, domega_t,
        ])
    }

    /// Event indicators `[T_max − k_s (ω_s − ω_m), k_s (ω_s − ω_m) + T_max, 2π − θ_e]`: the
    /// motor torque reaches (or leaves) its upper or lower limit where the first or second
    /// changes sign; the third reaches zero when the angle completes a turn (it is then
    /// wrapped back to 0, [`wrap_angle`]).
    pub fn event_indicators(&self, x: &GeneratorState) -> [f64; EVENT_INDICATORS] {
        let torque = self.slip_stiffness * (x[5] - x[3]);
        [
            self.max_motor_torque - torque,
            torque + self.max_motor_torque,
            2.0 * PI - x[4],
        ]
    }

    /// `∂f/∂x` of [`Self::derivative_on`] at `x` with the torque limit held at `limit`
    /// (exact; rows and columns in the state's order).
    pub fn jacobian_state(&self, x: &GeneratorState, limit: TorqueLimit) -> StateMatrix {
        let (i_d, i_q, i_f, omega_m) = (x[0], x[1], x[2], x[3]);
        let p = self.pole_pairs;
        let omega_e = p * omega_m;
        let r = self.stator_resistance + self.load_resistance;
        let (l_d, l_q, l_f, m_f) = self.inductances();
        let det = self.d_field_determinant();
        // ∂r_d/∂(i_d, i_q, ω_m) and ∂r_f/∂(i_f, v_f).
        let (rd_id, rd_iq, rd_wm) = (-r, omega_e * l_q, p * l_q * i_q);
        let (rf_if, rf_vf) = (-self.field_resistance, 1.0);
        // ∂T_e/∂(i_d, i_q, i_f) and ∂T_m/∂(ω_m, ω_s).
        let te_id = 1.5 * p * (l_q - l_d) * i_q;
        let te_iq = 1.5 * p * (m_f * i_f + (l_q - l_d) * i_d);
        let te_if = 1.5 * p * m_f * i_q;
        let k = match limit {
            TorqueLimit::Linear => self.slip_stiffness,
            TorqueLimit::Upper | TorqueLimit::Lower => 0.0,
        };
        let (tm_wm, tm_ws) = (-k, k);
        let mut j = StateMatrix::zeros();
        // di_d = (L_f r_d + M_f r_f)/det, di_f = (L_d r_f + 1.5 M_f r_d)/det
        j[(0, 0)] = l_f * rd_id / det;
        j[(0, 1)] = l_f * rd_iq / det;
        j[(0, 2)] = m_f * rf_if / det;
        j[(0, 3)] = l_f * rd_wm / det;
        j[(0, 6)] = m_f * rf_vf / det;
        j[(2, 0)] = 1.5 * m_f * rd_id / det;
        j[(2, 1)] = 1.5 * m_f * rd_iq / det;
        j[(2, 2)] = l_d * rf_if / det;
        j[(2, 3)] = 1.5 * m_f * rd_wm / det;
        j[(2, 6)] = l_d * rf_vf / det;
        // di_q = (−R i_q − ω_e L_d i_d + ω_e M_f i_f)/L_q
        j[(1, 0)] = -omega_e * l_d / l_q;
        j[(1, 1)] = -r / l_q;
        j[(1, 2)] = omega_e * m_f / l_q;
        j[(1, 3)] = p * (m_f * i_f - l_d * i_d) / l_q;
        // dω_m = (T_m − T_e − B ω_m)/J
        let inertia = self.inertia;
        j[(3, 0)] = -te_id / inertia;
        j[(3, 1)] = -te_iq / inertia;
        j[(3, 2)] = -te_if / inertia;
        j[(3, 3)] = (tm_wm - self.friction) / inertia;
        j[(3, 5)] = tm_ws / inertia;
        // dθ_e = p ω_m
        j[(4, 3)] = p;
        // dω_s = (ω_ref + T_m/k_s − ω_s)/τ_drive
        let tau = self.drive_time_constant;
        j[(5, 3)] = tm_wm / self.slip_stiffness / tau;
        j[(5, 5)] = (tm_ws / self.slip_stiffness - 1.0) / tau;
        // dv_f = (12.5 u_field − v_f)/τ_scr, dω_t = (ω_m − ω_t)/τ_tach
        j[(6, 6)] = -1.0 / self.scr_time_constant;
        j[(7, 3)] = 1.0 / self.tachometer_time_constant;
        j[(7, 7)] = -1.0 / self.tachometer_time_constant;
        j
    }

    /// `∂f/∂(u_drive, u_field)`: nonzero in `dω_s/dt` and `dv_f/dt` only, and zero where a
    /// reference is clipped (outside (0, 10) V).
    pub fn jacobian_input(&self, u_drive: f64, u_field: f64) -> InputMatrix {
        let slope = |u: f64| {
            if u > 0.0 && u < REFERENCE_MAX {
                1.0
            } else {
                0.0
            }
        };
        let mut j = InputMatrix::zeros();
        j[(5, 0)] = slope(u_drive) * 2.0 * PI * self.rated_frequency
            / (REFERENCE_MAX * self.pole_pairs)
            / self.drive_time_constant;
        j[(6, 1)] = slope(u_field) * SCR_GAIN / self.scr_time_constant;
        j
    }

    /// The outputs `[speed, voltage, frequency, shaft_speed, i_f, v_f, T_e, T_m, i_d, i_q]`
    /// ([`OUTPUT_NAMES`]) of the state `x` with the torque limit held at `limit`.
    pub fn outputs(&self, x: &GeneratorState, limit: TorqueLimit) -> [f64; OUTPUTS] {
        let rpm = 60.0 / (2.0 * PI);
        [
            x[7] * rpm,
            self.terminal_voltage(x),
            self.pole_pairs * x[3] / (2.0 * PI),
            x[3] * rpm,
            x[2],
            x[6],
            self.electrical_torque(x),
            self.motor_torque_on(x[5], x[3], limit),
            x[0],
            x[1],
        ]
    }

    /// `∂(outputs)/∂x` of [`Self::outputs`] (the outputs do not depend on the inputs). The
    /// voltage's gradient is taken as 0 at zero stator current, where it has none.
    pub fn output_jacobian(&self, x: &GeneratorState, limit: TorqueLimit) -> OutputMatrix {
        let rpm = 60.0 / (2.0 * PI);
        let p = self.pole_pairs;
        let (i_d, i_q, i_f) = (x[0], x[1], x[2]);
        let mut j = OutputMatrix::zeros();
        j[(0, 7)] = rpm;
        let current = i_d.hypot(i_q);
        if current > 0.0 {
            let gain = (1.5f64).sqrt() * self.load_resistance / current;
            j[(1, 0)] = gain * i_d;
            j[(1, 1)] = gain * i_q;
        }
        j[(2, 3)] = p / (2.0 * PI);
        j[(3, 3)] = rpm;
        j[(4, 2)] = 1.0;
        j[(5, 6)] = 1.0;
        let lq_ld = self.q_inductance - self.d_inductance;
        j[(6, 0)] = 1.5 * p * lq_ld * i_q;
        j[(6, 1)] = 1.5 * p * (self.mutual_inductance * i_f + lq_ld * i_d);
        j[(6, 2)] = 1.5 * p * self.mutual_inductance * i_q;
        if limit == TorqueLimit::Linear {
            j[(7, 3)] = -self.slip_stiffness;
            j[(7, 5)] = self.slip_stiffness;
        }
        j[(8, 0)] = 1.0;
        j[(9, 1)] = 1.0;
        j
    }

    /// The steady state for constant references (clipped), in closed form: `ω_m = ω_ref`,
    /// `v_f = 12.5 u_field`, `i_f = v_f/R_f`, and with `E = ω_e M_f i_f`,
    /// `X_{d,q} = ω_e L_{d,q}`: `i_q = E R/(R² + X_d X_q)`, `i_d = E X_q/(R² + X_d X_q)`;
    /// `ω_s = ω_m + T_m/k_s` with `T_m = T_e + B ω_m`; `θ_e = 0`.
    pub fn operating_point(&self, u_drive: f64, u_field: f64) -> OperatingPoint {
        let omega_m = self.speed_reference(u_drive);
        let omega_e = self.pole_pairs * omega_m;
        let v_f = SCR_GAIN * clip_reference(u_field);
        let i_f = v_f / self.field_resistance;
        let resistance = self.stator_resistance + self.load_resistance;
        let emf = omega_e * self.mutual_inductance * i_f;
        let (x_d, x_q) = (omega_e * self.d_inductance, omega_e * self.q_inductance);
        let denominator = resistance * resistance + x_d * x_q;
        let i_q = emf * resistance / denominator;
        let i_d = emf * x_q / denominator;
        let mut state =
            GeneratorState::from_column_slice(&[i_d, i_q, i_f, omega_m, 0.0, 0.0, v_f, omega_m]);
        let electrical_torque = self.electrical_torque(&state);
        let motor_torque = electrical_torque + self.friction * omega_m;
        state[5] = omega_m + motor_torque / self.slip_stiffness;
        OperatingPoint {
            state,
            speed_rpm: omega_m * 60.0 / (2.0 * PI),
            terminal_voltage: self.terminal_voltage(&state),
            electrical_torque,
            motor_torque,
            reachable: motor_torque.abs() <= self.max_motor_torque,
        }
    }
}

/// The generator set with its state.
#[derive(Debug, Clone, PartialEq)]
pub struct WindGenerator {
    /// Physical parameters.
    pub parameters: WindGeneratorParameters,
    /// Current state (module docs).
    pub state: GeneratorState,
}

impl WindGenerator {
    /// Substep that keeps the stiff stator modes accurate (module docs).
    pub const RECOMMENDED_MAX_SUBSTEP: f64 = 1e-4;

    /// Relative tolerance of the default integrator ([`Self::advance_adaptive`] with
    /// [`Adaptive::Dop853`]): speed and voltage within 1.2·10⁻¹¹ of their rated values from a
    /// tight reference over start-ups with reference steps (7.5·10⁻¹² in the first), the
    /// accuracy of the former default RK4 at 10⁻⁴ s, 1.9·10⁻¹¹ (module docs, *Integration*).
    pub const DEFAULT_RELATIVE_TOLERANCE: f64 = 7e-12;

    /// The set at rest (all states zero), after checking the parameters.
    pub fn new(parameters: WindGeneratorParameters) -> Result<Self, ParameterError> {
        Self::with_state(parameters, GeneratorState::zeros())
    }

    /// The set in steady state for the references `u_drive`, `u_field` [V].
    pub fn at_operating_point(
        parameters: WindGeneratorParameters,
        u_drive: f64,
        u_field: f64,
    ) -> Result<Self, ParameterError> {
        parameters.validate()?;
        let state = parameters.operating_point(u_drive, u_field).state;
        Self::with_state(parameters, state)
    }

    /// The set at a given state (e.g. restored), after checking parameters and state.
    pub fn with_state(
        parameters: WindGeneratorParameters,
        state: GeneratorState,
    ) -> Result<Self, ParameterError> {
        parameters.validate()?;
        for (name, value) in STATE_NAMES.iter().zip(state.iter()) {
            require_finite(name, *value)?;
        }
        Ok(Self { parameters, state })
    }

    /// Tachometer reading [rpm] (output `speed`).
    pub fn speed_rpm(&self) -> f64 {
        self.state[7] * 60.0 / (2.0 * PI)
    }

    /// Terminal voltage, RMS line to line [V] (output `voltage`).
    pub fn terminal_voltage(&self) -> f64 {
        self.parameters.terminal_voltage(&self.state)
    }

    /// True shaft speed [rpm] (without the tachometer lag).
    pub fn shaft_speed_rpm(&self) -> f64 {
        self.state[3] * 60.0 / (2.0 * PI)
    }

    /// Electrical frequency of the generated voltage [Hz].
    pub fn frequency(&self) -> f64 {
        self.parameters.pole_pairs * self.state[3] / (2.0 * PI)
    }

    /// Electrical torque [N·m].
    pub fn electrical_torque(&self) -> f64 {
        self.parameters.electrical_torque(&self.state)
    }

    /// Advances from time `t` over `h` seconds with the references held (clipped to
    /// [0, 10] V), with RK4 substeps no longer than `h_max`
    /// (use [`Self::RECOMMENDED_MAX_SUBSTEP`]).
    pub fn advance(&mut self, t: f64, u_drive: f64, u_field: f64, h: f64, h_max: f64) {
        let p = self.parameters;
        let (u_drive, u_field) = (clip_reference(u_drive), clip_reference(u_field));
        self.state = ode::integrate(
            |_t, x| p.derivative(x, u_drive, u_field),
            |_, x| wrap_angle(x),
            t,
            &self.state,
            h,
            h_max,
        );
    }

    /// The adaptive integrator's tolerances for a relative tolerance `rtol`: absolute ones of
    /// `rtol` times each state's scale ([`STATE_SCALES`]: 0.5 A for the currents, 100 rad/s
    /// for the speeds, 100 V for the field voltage; the angle is not controlled).
    pub fn tolerance(rtol: f64) -> Tolerance<8> {
        Tolerance {
            relative: rtol,
            absolute: GeneratorState::from_column_slice(&STATE_SCALES) * rtol,
        }
    }

    /// Advances over `h` seconds with the references held (clipped to [0, 10] V), with an
    /// adaptive integrator (module docs, *Integration*): [`Adaptive::Dop853`], the
    /// eighth-order Dormand–Prince pair of [`crate::ode::dop853`] on [`HeldRightHandSide`]
    /// (the default), or [`Adaptive::Rodas3`], the Rosenbrock method of
    /// [`crate::ode::rosenbrock`] on the analytic Jacobian. The angle is wrapped into [0, 2π)
    /// at the end (it feeds nothing back). `step` is the step to try first and, on return, the
    /// next one proposed (keep it from one call to the next, so that a call does not restart
    /// from a short step). On an error the state is unchanged.
    pub fn advance_adaptive(
        &mut self,
        integrator: Adaptive,
        (u_drive, u_field): (f64, f64),
        h: f64,
        tolerance: &Tolerance<8>,
        step: &mut f64,
    ) -> Result<Statistics, StepError> {
        let p = self.parameters;
        let mut statistics = Statistics::default();
        let mut proposal = *step;
        let (x, counts) = (&self.state, &mut statistics);
        let mut state = match integrator {
            Adaptive::Dop853 => {
                let rhs = HeldRightHandSide::new(&p, u_drive, u_field);
                // Inlined into every stage: the right-hand side is a few dozen flops, and a call
                // would put the state and its derivative through memory twelve times a step.
                dop853::integrate(
                    #[inline(always)]
                    |x: &GeneratorState| rhs.derivative(x),
                    (x, h),
                    tolerance,
                    (&mut proposal, counts),
                )?
            }
            Adaptive::Rodas3 => rosenbrock::integrate(
                &rosenbrock::RODAS3,
                |x| p.derivative(x, u_drive, u_field),
                |x| p.jacobian_state(x, p.torque_limit_of(x[5], x[3])),
                x,
                h,
                tolerance,
                &mut proposal,
                counts,
            )?,
        };
        wrap_angle(&mut state);
        self.state = state;
        *step = proposal;
        Ok(statistics)
    }
}

/// The adaptive integrators of [`WindGenerator::advance_adaptive`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Adaptive {
    /// DOP853 (the FMU's default): eighth order, explicit, stable for `h |λ|max ≲ 6`.
    Dop853,
    /// RODAS3: third order, L-stable, one Jacobian and LU per step.
    Rodas3,
}

/// [`WindGeneratorParameters::derivative`] for references held over a communication step, with
/// every constant of the equations (module docs) formed once: the right-hand side is then
/// products and sums only, no division (the Co-Simulation integrator evaluates it twelve times
/// a step). The same equations, with the quotients distributed over the sums:
///
/// ```text
/// ρ_d = (−R i_d + p ω_m L_q i_q)/det,  ρ_f = (v_f − R_f i_f)/det,   det = L_d L_f − (3/2) M_f²
/// di_d = L_f ρ_d + M_f ρ_f,   di_f = L_d ρ_f + (3/2) M_f ρ_d
/// di_q = −(R/L_q) i_q + ω_m (−(p L_d/L_q) i_d + (p M_f/L_q) i_f)
/// dω_m = T_m/J − ((3/2) p M_f/J · i_f + (3/2) p (L_q − L_d)/J · i_d) i_q − (B/J) ω_m
/// dω_s = (ω_ref − ω_s)/τ_drive + T_m/(k_s τ_drive),   T_m = clamp(k_s (ω_s − ω_m), ±T_max)
/// ```
///
/// It agrees with [`WindGeneratorParameters::derivative`] to a few units in the last place
/// (test `jacobians_and_the_held_right_hand_side_match_at_random_states`), not bit for bit: the Model Exchange
/// interface and `fixed_step_rk4` keep `derivative`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HeldRightHandSide {
    /// `−R/det`, `p L_q/det`, `1/det`, `R_f/det`.
    rho: [f64; 4],
    /// `L_f`, `M_f`, `L_d`, `(3/2) M_f`.
    currents: [f64; 4],
    /// `−R/L_q`, `−p L_d/L_q`, `p M_f/L_q`.
    quadrature: [f64; 3],
    /// `1/J`, `(3/2) p M_f/J`, `(3/2) p (L_q − L_d)/J`, `B/J`.
    shaft: [f64; 4],
    /// `k_s`, `T_max`, `ω_ref/τ_drive`, `1/τ_drive`, `1/(k_s τ_drive)`.
    drive: [f64; 5],
    /// `p`, `12.5 u_field/τ_scr`, `1/τ_scr`, `1/τ_tach`.
    lags: [f64; 4],
}

impl HeldRightHandSide {
    /// The constants for the parameters `p` and the references `u_drive`, `u_field` (clipped).
    pub fn new(p: &WindGeneratorParameters, u_drive: f64, u_field: f64) -> Self {
        let det = p.d_field_determinant();
        let resistance = p.stator_resistance + p.load_resistance;
        let (l_d, l_q, l_f, m_f) = p.inductances();
        let pp = p.pole_pairs;
        let tau = p.drive_time_constant;
        Self {
            rho: [
                -resistance / det,
                pp * l_q / det,
                1.0 / det,
                p.field_resistance / det,
            ],
            currents: [l_f, m_f, l_d, 1.5 * m_f],
            quadrature: [-resistance / l_q, -pp * l_d / l_q, pp * m_f / l_q],
            shaft: [
                1.0 / p.inertia,
                1.5 * pp * m_f / p.inertia,
                1.5 * pp * (l_q - l_d) / p.inertia,
                p.friction / p.inertia,
            ],
            drive: [
                p.slip_stiffness,
                p.max_motor_torque,
                p.speed_reference(u_drive) / tau,
                1.0 / tau,
                1.0 / (p.slip_stiffness * tau),
            ],
            lags: [
                pp,
                SCR_GAIN * clip_reference(u_field) / p.scr_time_constant,
                1.0 / p.scr_time_constant,
                1.0 / p.tachometer_time_constant,
            ],
        }
    }

    /// `ẋ = f(x)` at the held references (the motor torque's limit taken from `x`).
    #[inline(always)]
    pub fn derivative(&self, x: &GeneratorState) -> GeneratorState {
        let (i_d, i_q, i_f, omega_m) = (x[0], x[1], x[2], x[3]);
        let (omega_s, v_f, omega_t) = (x[5], x[6], x[7]);
        let [rd_i, rd_w, inv_det, rf_i] = self.rho;
        let [l_f, m_f, l_d, m_f15] = self.currents;
        let rho_d = rd_i * i_d + rd_w * omega_m * i_q;
        let rho_f = inv_det * v_f - rf_i * i_f;
        let [q_q, q_d, q_f] = self.quadrature;
        let [inv_j, te_f, te_d, b_j] = self.shaft;
        let [k_s, t_max, ref_tau, inv_tau, tm_tau] = self.drive;
        let [pp, v_target, inv_scr, inv_tach] = self.lags;
        let motor_torque = (k_s * (omega_s - omega_m)).clamp(-t_max, t_max);
        GeneratorState::from([
            l_f * rho_d + m_f * rho_f,
            q_q * i_q + omega_m * (q_d * i_d + q_f * i_f),
            l_d * rho_f + m_f15 * rho_d,
            inv_j * motor_torque - (te_f * i_f + te_d * i_d) * i_q - b_j * omega_m,
            pp * omega_m,
            ref_tau - inv_tau * omega_s + tm_tau * motor_torque,
            v_target - inv_scr * v_f,
            inv_tach * (omega_m - omega_t),
        ])
    }
}

/// The scale of each state for the adaptive integrator's absolute tolerances.
/// The angle `θ_e` feeds nothing back and is no output, so it is left out of the error norm
/// (an infinite scale): its error is that of integrating `p ω_m`.
pub const STATE_SCALES: [f64; 8] = [0.5, 0.5, 0.5, 100.0, f64::INFINITY, 100.0, 100.0, 100.0];

// FMU-state snapshots (plain bytes) of the types above: every field, in order.
crate::plain_state!(WindGeneratorParameters {
    pole_pairs,
    stator_resistance,
    d_inductance,
    q_inductance,
    field_resistance,
    field_inductance,
    mutual_inductance,
    load_resistance,
    inertia,
    friction,
    slip_stiffness,
    max_motor_torque,
    drive_time_constant,
    scr_time_constant,
    tachometer_time_constant,
    rated_frequency
});
crate::plain_state!(WindGenerator { parameters, state });
crate::plain_state!(
    enum TorqueLimit {
        Linear,
        Upper,
        Lower,
    }
);

#[cfg(test)]
mod tests {
    use super::*;

    const H_MAX: f64 = WindGenerator::RECOMMENDED_MAX_SUBSTEP;

    /// Runs `seconds` at the references, sampling every 0.01 s; returns (t, rpm, volts).
    fn run(
        g: &mut WindGenerator,
        u_drive: f64,
        u_field: f64,
        seconds: f64,
    ) -> Vec<(f64, f64, f64)> {
        let h = 0.01;
        let n = (seconds / h).round() as usize;
        let mut out = Vec::with_capacity(n);
        for k in 0..n {
            g.advance(k as f64 * h, u_drive, u_field, h, H_MAX);
            out.push(((k + 1) as f64 * h, g.speed_rpm(), g.terminal_voltage()));
        }
        out
    }

    /// Time for `signal` to cover 63.2 % of its change from `initial` to `last`.
    fn time_constant(samples: &[(f64, f64)], initial: f64) -> f64 {
        let last = samples[samples.len() - 1].1;
        let target = initial + (1.0 - (-1f64).exp()) * (last - initial);
        let rising = last > initial;
        let mut previous = (0.0, initial);
        for &(t, v) in samples {
            if (rising && v >= target) || (!rising && v <= target) {
                return previous.0 + (target - previous.1) / (v - previous.1) * (t - previous.0);
            }
            previous = (t, v);
        }
        f64::NAN
    }

    #[test]
    fn rated_references_give_1800_rpm_and_240_volts_from_rest() {
        let mut g = WindGenerator::new(WindGeneratorParameters::default()).unwrap();
        let out = run(&mut g, RATED_DRIVE_REFERENCE, RATED_FIELD_REFERENCE, 12.0);
        let (_, rpm, volts) = out[out.len() - 1];
        let peak_rpm = out.iter().map(|s| s.1).fold(f64::MIN, f64::max);
        let settled = out
            .iter()
            .rev()
            .find(|s| (s.1 - rpm).abs() > 1.8 || (s.2 - volts).abs() > 0.24)
            .map_or(0.0, |s| s.0);
        eprintln!(
            "rated steady state: {rpm:.3} rpm, {volts:.3} V; peak {peak_rpm:.1} rpm; \
             within 0.1 % after {settled:.2} s"
        );
        assert!((rpm - 1800.0).abs() < 18.0, "speed {rpm}");
        assert!((volts - 240.0).abs() < 4.8, "voltage {volts}");
        // And it is the closed-form operating point.
        let op = g.parameters.operating_point(10.0, 8.0);
        assert!(op.reachable);
        assert!((op.speed_rpm - 1800.0).abs() < 1e-9);
        assert!((op.terminal_voltage - 240.0).abs() < 1e-9);
        assert!((rpm - op.speed_rpm).abs() < 1e-3 * 1800.0);
        assert!((volts - op.terminal_voltage).abs() < 1e-3 * 240.0);
        assert!((g.frequency() - 60.0).abs() < 0.1);
    }

    #[test]
    fn operating_point_is_an_equilibrium() {
        let p = WindGeneratorParameters::default();
        for (u_drive, u_field) in [(10.0, 8.0), (7.0, 5.0), (3.0, 9.5)] {
            let op = p.operating_point(u_drive, u_field);
            let dx = p.derivative(&op.state, u_drive, u_field);
            for i in [0, 1, 2, 3, 5, 6, 7] {
                assert!(
                    dx[i].abs() < 1e-9,
                    "state {} derivative {}",
                    STATE_NAMES[i],
                    dx[i]
                );
            }
            assert!((dx[4] - p.pole_pairs * op.state[3]).abs() < 1e-12);
        }
    }

    #[test]
    fn step_responses_have_the_documented_time_constants() {
        let p = WindGeneratorParameters::default();
        // Drive step 8 → 10 V at rated field.
        let mut g = WindGenerator::at_operating_point(p, 8.0, 8.0).unwrap();
        let (rpm0, volts0) = (g.speed_rpm(), g.terminal_voltage());
        let out = run(&mut g, 10.0, 8.0, 6.0);
        let speed: Vec<(f64, f64)> = out.iter().map(|s| (s.0, s.1)).collect();
        let voltage: Vec<(f64, f64)> = out.iter().map(|s| (s.0, s.2)).collect();
        let tau_speed = time_constant(&speed, rpm0);
        let tau_voltage_drive = time_constant(&voltage, volts0);
        // Field step 6 → 8 V at rated speed.
        let mut g = WindGenerator::at_operating_point(p, 10.0, 6.0).unwrap();
        let volts0 = g.terminal_voltage();
        let out = run(&mut g, 10.0, 8.0, 3.0);
        let voltage: Vec<(f64, f64)> = out.iter().map(|s| (s.0, s.2)).collect();
        let tau_field = time_constant(&voltage, volts0);
        let overshoot = out.iter().map(|s| s.2).fold(f64::MIN, f64::max) - 240.0;
        eprintln!(
            "time constants: speed {tau_speed:.4} s, voltage after drive step \
             {tau_voltage_drive:.4} s, voltage after field step {tau_field:.4} s \
             (overshoot {overshoot:.3} V)"
        );
        assert!((tau_speed - 0.542).abs() < 0.005, "speed {tau_speed}");
        assert!(
            (tau_voltage_drive - 0.503).abs() < 0.005,
            "{tau_voltage_drive}"
        );
        assert!((tau_field - 0.221).abs() < 0.005, "field {tau_field}");
    }

    #[test]
    fn references_are_clipped_to_0_10_volts() {
        assert_eq!(clip_reference(12.0), 10.0);
        assert_eq!(clip_reference(-3.0), 0.0);
        assert_eq!(clip_reference(f64::NAN), 0.0);
        let p = WindGeneratorParameters::default();
        let mut over = WindGenerator::at_operating_point(p, 10.0, 8.0).unwrap();
        let mut rated = over.clone();
        run(&mut over, 15.0, 8.0, 1.0);
        run(&mut rated, 10.0, 8.0, 1.0);
        assert_eq!(over.state, rated.state);
        assert_eq!(
            p.operating_point(15.0, 20.0).state,
            p.operating_point(10.0, 10.0).state
        );
    }

    #[test]
    fn substep_of_1e_4_is_converged() {
        let p = WindGeneratorParameters::default();
        let simulate = |h_max: f64| {
            let mut g = WindGenerator::at_operating_point(p, 6.0, 5.0).unwrap();
            for k in 0..10 {
                g.advance(k as f64 * 0.1, 10.0, 8.0, 0.1, h_max);
            }
            (g.speed_rpm(), g.terminal_voltage())
        };
        let (rpm, volts) = simulate(H_MAX);
        let (rpm_fine, volts_fine) = simulate(H_MAX / 2.0);
        assert!(((rpm - rpm_fine) / rpm_fine).abs() < 1e-6);
        assert!(((volts - volts_fine) / volts_fine).abs() < 1e-6);
    }

    #[test]
    fn energy_balance_at_the_operating_point() {
        // Air-gap power = load power + stator copper losses.
        let p = WindGeneratorParameters::default();
        let op = p.operating_point(10.0, 8.0);
        let (i_d, i_q) = (op.state[0], op.state[1]);
        let current2 = i_d * i_d + i_q * i_q;
        let load = 1.5 * p.load_resistance * current2;
        let copper = 1.5 * p.stator_resistance * current2;
        let air_gap = op.electrical_torque * op.state[3];
        assert!((air_gap - load - copper).abs() < 1e-9 * air_gap);
        assert!((load - 240.0).abs() < 1e-6);
        assert!((op.terminal_voltage.powi(2) / p.load_resistance - load).abs() < 1e-6);
    }

    /// A random state of the working range (currents of a few A, speeds up to 260 rad/s).
    fn random_state(rng: &mut crate::signals::rng::RandomGenerator) -> GeneratorState {
        let mut x = GeneratorState::zeros();
        for (i, (low, high)) in [
            (-2.0, 2.0),
            (-2.0, 2.0),
            (-0.2, 1.0),
            (-20.0, 250.0),
            (0.0, 2.0 * PI),
            (-20.0, 260.0),
            (0.0, 125.0),
            (0.0, 250.0),
        ]
        .into_iter()
        .enumerate()
        {
            x[i] = rng.uniform_range(low, high);
        }
        x
    }

    /// `|a − b| ≤ 1e-6 · max(|a|, |b|, largest analytic entry of the row)`.
    fn assert_close(what: &str, fd: f64, analytic: f64, row_scale: f64) {
        assert!(
            crate::plants::close_in_row(fd, analytic, row_scale),
            "{what}: differences {fd} vs analytic {analytic}"
        );
    }

    #[test]
    fn jacobians_and_the_held_right_hand_side_match_at_random_states() {
        let mut rng = crate::signals::rng::RandomGenerator::new(15);
        let base = WindGeneratorParameters::default();
        for k in 0..300 {
            // Vary the machine too, keeping L_d L_f − 1.5 M_f² > 0.
            let p = WindGeneratorParameters {
                d_inductance: base.d_inductance * rng.uniform_range(0.8, 1.5),
                q_inductance: base.q_inductance * rng.uniform_range(0.5, 1.5),
                load_resistance: base.load_resistance * rng.uniform_range(0.2, 2.0),
                friction: base.friction * rng.uniform_range(0.0, 4.0),
                ..base
            };
            let x = random_state(&mut rng);
            let (u_drive, u_field) = (rng.uniform_range(0.5, 9.5), rng.uniform_range(0.5, 9.5));
            let limit = [TorqueLimit::Linear, TorqueLimit::Upper, TorqueLimit::Lower][k % 3];
            let f = |x: &GeneratorState, u_drive: f64, u_field: f64| {
                p.derivative_on(x, u_drive, u_field, limit)
            };
            let jx = p.jacobian_state(&x, limit);
            let jy = p.output_jacobian(&x, limit);
            let df = crate::plants::central_differences(|x| f(x, u_drive, u_field), &x, 1e-5);
            let dy = crate::plants::central_differences(
                |x| nalgebra::SVector::from(p.outputs(x, limit)),
                &x,
                1e-5,
            );
            for j in 0..8 {
                for i in 0..8 {
                    let what = format!("∂f[{}]/∂{} ({limit:?})", STATE_NAMES[i], STATE_NAMES[j]);
                    assert_close(&what, df[(i, j)], jx[(i, j)], jx.row(i).amax());
                }
                for i in 0..OUTPUTS {
                    let what = format!("∂{}/∂{}", OUTPUT_NAMES[i], STATE_NAMES[j]);
                    assert_close(&what, dy[(i, j)], jy[(i, j)], jy.row(i).amax());
                }
            }
            let ju = p.jacobian_input(u_drive, u_field);
            for (j, (plus, minus)) in [
                ((u_drive + 1e-5, u_field), (u_drive - 1e-5, u_field)),
                ((u_drive, u_field + 1e-5), (u_drive, u_field - 1e-5)),
            ]
            .into_iter()
            .enumerate()
            {
                let df = (f(&x, plus.0, plus.1) - f(&x, minus.0, minus.1)) / 2e-5;
                for i in 0..8 {
                    assert_close(&format!("∂f[{i}]/∂u[{j}]"), df[i], ju[(i, j)], ju.amax());
                }
            }
            // The held right-hand side (the divisions distributed over the sums: only the
            // rounding differs) within 1e-13 of the size of the terms, |f| + |J x| + |f(0)| per
            // row, at 20 states and references per machine, in every torque mode.
            for _ in 0..20 {
                let mut x = random_state(&mut rng);
                x[5] = x[3] + rng.uniform_range(-40.0, 40.0);
                let u = (rng.uniform_range(-1.0, 11.0), rng.uniform_range(-1.0, 11.0));
                let exact = p.derivative(&x, u.0, u.1);
                let held = HeldRightHandSide::new(&p, u.0, u.1).derivative(&x);
                let at_rest = p.derivative(&GeneratorState::zeros(), u.0, u.1);
                let jx = p.jacobian_state(&x, p.torque_limit_of(x[5], x[3]));
                let terms = exact.abs() + jx.abs() * x.abs() + at_rest.abs();
                let worst = (held - exact)
                    .abs()
                    .zip_map(&terms, |d, t| d / t.max(f64::MIN_POSITIVE))
                    .amax();
                assert!(worst <= 1e-13, "{held} vs {exact}");
            }
        }
        // Clipped references have no effect, hence no derivative.
        assert_eq!(base.jacobian_input(12.0, -1.0), InputMatrix::zeros());
    }

    #[test]
    fn held_limit_gives_the_clamped_right_hand_side_and_indicators_change_sign_at_the_limits() {
        let p = WindGeneratorParameters::default();
        let mut rng = crate::signals::rng::RandomGenerator::new(17);
        for _ in 0..200 {
            let x = random_state(&mut rng);
            let limit = p.torque_limit_of(x[5], x[3]);
            // Bit for bit: the CS integrator's right-hand side is derivative_on of the limit.
            assert_eq!(
                p.derivative(&x, 7.0, 6.0),
                p.derivative_on(&x, 7.0, 6.0, limit)
            );
            assert_eq!(
                p.motor_torque(x[5], x[3]),
                p.motor_torque_on(x[5], x[3], limit)
            );
            let [upper, lower, turn] = p.event_indicators(&x);
            assert_eq!(limit == TorqueLimit::Upper, upper <= 0.0);
            assert_eq!(limit == TorqueLimit::Lower, lower <= 0.0);
            assert!(turn > 0.0);
            let mut wrapped = x;
            wrapped[4] += 2.0 * PI;
            assert!(p.event_indicators(&wrapped)[2] <= 0.0);
            wrap_angle(&mut wrapped);
            assert!((wrapped[4] - x[4]).abs() < 1e-12);
        }
    }

    #[test]
    fn stiffness_along_a_start_up() {
        // Eigenvalues of ∂f/∂x along the rated start-up from rest: the stator pair stays near
        // −1.2·10³ s⁻¹ while the slowest nonzero modes are a few s⁻¹, a stiffness ratio of
        // several hundred, which is what limits RK4 (and any explicit method) to ≈ 2 ms.
        let p = WindGeneratorParameters::default();
        let mut g = WindGenerator::new(p).unwrap();
        let mut fastest: f64 = 0.0;
        let mut slowest_at_rated = f64::MAX;
        for k in 0..40 {
            let x = g.state;
            let limit = p.torque_limit_of(x[5], x[3]);
            let eigenvalues = p.jacobian_state(&x, limit).complex_eigenvalues();
            let magnitudes: Vec<f64> = eigenvalues.iter().map(|l| l.norm()).collect();
            fastest = fastest.max(magnitudes.iter().cloned().fold(0.0, f64::max));
            if k == 39 {
                slowest_at_rated = magnitudes
                    .iter()
                    .cloned()
                    .filter(|m| *m > 1e-9)
                    .fold(f64::MAX, f64::min);
                let stator = eigenvalues
                    .iter()
                    .find(|l| l.re < -1000.0)
                    .copied()
                    .unwrap();
                eprintln!("rated point: stator {stator}, slowest {slowest_at_rated}");
                assert!((stator.re + 1226.0).abs() < 5.0, "{stator}");
                assert!((stator.im.abs() - 377.0).abs() < 5.0, "{stator}");
            }
            for j in 0..10 {
                g.advance((10 * k + j) as f64 * 0.01, 10.0, 8.0, 0.01, H_MAX);
            }
        }
        eprintln!("start-up: largest |λ| {fastest:.1} 1/s");
        assert!(fastest > 1100.0 && fastest < 1400.0, "{fastest}");
        assert!(fastest / slowest_at_rated > 200.0);
    }

    /// The start-up scenario of the integrator comparison: from rest, rated references for
    /// 4 s, then drive 6 V, then field 5 V, then both back to rated (torque at its limit in
    /// the start-up), sampled every 0.1 s: (speed rpm, voltage V) at each sample. Both
    /// references are scaled, the drive by `scale` and the field by its square root (1: as
    /// given).
    fn start_up(
        scale: f64,
        mut advance: impl FnMut(&mut WindGenerator, f64, f64),
    ) -> Vec<(f64, f64)> {
        let mut g = WindGenerator::new(WindGeneratorParameters::default()).unwrap();
        (0..100)
            .map(|k| {
                let (u_drive, u_field) = match k {
                    0..40 => (10.0, 8.0),
                    40..60 => (6.0, 8.0),
                    60..80 => (6.0, 5.0),
                    _ => (10.0, 8.0),
                };
                advance(&mut g, u_drive * scale, u_field * scale.sqrt());
                (g.speed_rpm(), g.terminal_voltage())
            })
            .collect()
    }

    /// Largest error of speed and voltage relative to their rated values (1800 rpm, 240 V).
    fn largest_error(run: &[(f64, f64)], reference: &[(f64, f64)]) -> f64 {
        run.iter()
            .zip(reference)
            .map(|(a, b)| {
                ((a.0 - b.0) / 1800.0)
                    .abs()
                    .max(((a.1 - b.1) / 240.0).abs())
            })
            .fold(0.0, f64::max)
    }

    /// The start-up with RK4 substeps of `h_max` (the former default: 10⁻⁴ s).
    fn rk4_start_up(h_max: f64, scale: f64) -> Vec<(f64, f64)> {
        let mut t = 0.0;
        start_up(scale, |g, u_drive, u_field| {
            g.advance(t, u_drive, u_field, 0.1, h_max);
            t += 0.1;
        })
    }

    /// The start-up with an adaptive integrator at relative tolerance `rtol`, and its work:
    /// DOP853's right-hand sides, RODAS3's steps (each 3 right-hand sides, a Jacobian, an LU).
    fn adaptive_start_up(integrator: Adaptive, rtol: f64, scale: f64) -> (Vec<(f64, f64)>, usize) {
        let tolerance = WindGenerator::tolerance(rtol);
        let (mut step, mut work) = (1e-3, 0);
        let run = start_up(scale, |g, u_drive, u_field| {
            let s = g
                .advance_adaptive(integrator, (u_drive, u_field), 0.1, &tolerance, &mut step)
                .unwrap();
            work += match integrator {
                Adaptive::Dop853 => 12 * s.accepted + 11 * s.rejected + 1,
                Adaptive::Rodas3 => s.accepted + s.rejected,
            };
        });
        (run, work)
    }

    #[test]
    fn default_integrator_reaches_the_former_defaults_accuracy_in_a_sixth_of_its_work() {
        // The reference: RK4 on a grid five times finer than the former default (2·10⁻⁵ s),
        // independent of the methods under test (its own error: ≈ 6·10⁻¹⁴ against 10⁻⁵ s).
        let reference = rk4_start_up(2e-5, 1.0);
        let adaptive = |integrator: Adaptive, rtol: f64| {
            let (run, work) = adaptive_start_up(integrator, rtol, 1.0);
            (largest_error(&run, &reference), work)
        };
        let former = largest_error(&rk4_start_up(H_MAX, 1.0), &reference);
        let rk4_evaluations = 4 * 100 * 1000;
        let (new, evaluations) =
            adaptive(Adaptive::Dop853, WindGenerator::DEFAULT_RELATIVE_TOLERANCE);
        let (tight, _) = adaptive(Adaptive::Dop853, 1e-12);
        let (rodas, rodas_steps) = adaptive(Adaptive::Rodas3, 1e-7);
        eprintln!(
            "largest error vs RK4 at 2e-5 s over the start-up (relative to 1800 rpm / 240 V): \
             RK4 at 1e-4 s {former:.2e} ({rk4_evaluations} evaluations); DOP853 rtol {:e} \
             {new:.2e} ({evaluations} evaluations), rtol 1e-12 {tight:.2e}; RODAS3 rtol 1e-7 \
             {rodas:.2e} ({rodas_steps} steps)",
            WindGenerator::DEFAULT_RELATIVE_TOLERANCE
        );
        // The former default's accuracy (1.9·10⁻¹¹) ...
        assert!(former > 1.5e-11 && former < 2.5e-11, "RK4 {former}");
        assert!(new <= 0.5 * former, "DOP853 {new} vs RK4 {former}");
        // ... in less than a sixth of its right-hand sides (measured 61 520 against 400 000).
        assert!(6 * evaluations < rk4_evaluations, "{evaluations}");
        // The error control converges to the reference as the tolerance tightens.
        assert!(tight < 3e-12, "{tight}");
        // RODAS3 keeps its documented accuracy and cost at 10⁻⁷.
        assert!(rodas < 3e-7 && rodas_steps < 2000, "{rodas} {rodas_steps}");
    }

    #[test]
    fn the_default_tolerance_keeps_the_former_defaults_accuracy_over_five_start_ups() {
        // The start-up of `start_up` with both references scaled (drive by s, field by √s):
        // DOP853 at the default tolerance against RK4 at 2·10⁻⁵ s, in each scenario within
        // the former default's 1.9·10⁻¹¹ of rated (measured 7.5, 6.5, 6.0, 11.3, 11.3·10⁻¹²)
        // and in less than a sixth of its work.
        for scale in [1.0, 0.97, 0.9, 0.8, 0.75] {
            let reference = rk4_start_up(2e-5, scale);
            let (adaptive, work) = adaptive_start_up(
                Adaptive::Dop853,
                WindGenerator::DEFAULT_RELATIVE_TOLERANCE,
                scale,
            );
            let error = largest_error(&adaptive, &reference);
            eprintln!("scale {scale}: DOP853 {error:.2e}, {work} right-hand sides");
            assert!(error < 1.2e-11, "scale {scale}: {error:e}");
            assert!(6 * work < 4 * 100 * 1000, "scale {scale}: {work}");
        }
    }

    /// The times at which the start-up from rest at the rated references with `T_max` = 2 N·m
    /// enters and leaves the torque limit, located independently of any FMU or solver: RK4 on
    /// 1 µs steps, each sign change of the indicator refined by bisection (one RK4 step from
    /// the last grid point), and the integration restarted from the located state.
    pub(crate) fn torque_limit_event_times() -> [f64; 2] {
        let p = WindGeneratorParameters {
            max_motor_torque: 2.0,
            ..Default::default()
        };
        let mut f = |_t: f64, x: &GeneratorState| p.derivative(x, 10.0, 8.0);
        let mut x = GeneratorState::zeros();
        let mut t = 0.0;
        let h = 1e-6;
        let mut times = [0.0; 2];
        for (k, time) in times.iter_mut().enumerate() {
            // k = 0: z_upper goes ≤ 0 (entering); k = 1: back > 0 (leaving).
            let crossed = |x: &GeneratorState| (p.event_indicators(x)[0] <= 0.0) == (k == 0);
            loop {
                let next = ode::rk4_step(&mut f, t, &x, h);
                if crossed(&next) {
                    let (mut a, mut b) = (0.0, h);
                    while b - a > 1e-14 {
                        let mid = 0.5 * (a + b);
                        if crossed(&ode::rk4_step(&mut f, t, &x, mid)) {
                            b = mid;
                        } else {
                            a = mid;
                        }
                    }
                    x = ode::rk4_step(&mut f, t, &x, b);
                    t += b;
                    *time = t;
                    break;
                }
                x = next;
                t += h;
            }
        }
        times
    }

    #[test]
    fn start_up_with_a_weak_motor_enters_and_leaves_the_torque_limit_at_the_pinned_times() {
        // The times fmus/WindGenerator/me_scenarios.py asks CVode's events to match (1e-6 s).
        let [enter, leave] = torque_limit_event_times();
        eprintln!("torque limit: enters at {enter:.10} s, leaves at {leave:.10} s");
        assert!((enter - 0.051_913_134_5).abs() < 1e-9, "{enter}");
        assert!((leave - 0.929_609_803_2).abs() < 1e-9, "{leave}");
    }

    #[test]
    fn bad_parameters_are_named() {
        let base = WindGeneratorParameters::default();
        let name = |p: WindGeneratorParameters| WindGenerator::new(p).unwrap_err().parameter;
        assert_eq!(
            name(WindGeneratorParameters {
                load_resistance: 0.0,
                ..base
            }),
            "R_load"
        );
        assert_eq!(
            name(WindGeneratorParameters {
                inertia: -1.0,
                ..base
            }),
            "J"
        );
        assert_eq!(
            name(WindGeneratorParameters {
                mutual_inductance: 3.0,
                ..base
            }),
            "M_f"
        );
        assert_eq!(
            WindGenerator::with_state(base, GeneratorState::from_element(f64::NAN))
                .unwrap_err()
                .parameter,
            "i_d"
        );
    }
}
