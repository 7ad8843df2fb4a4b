//! `WindGenerator.fmu`: the wind-generator laboratory set of paper 001 (§4, Fig. 1,
//! appendices A–D; docs/models.md §2.2) as an FMU (FMI 2.0 and 3.0) with both interfaces, Co-Simulation
//! and Model Exchange: a drive-fed induction motor turning a
//! wound-field synchronous generator on a resistive load, field fed by an SCR module, speed
//! read by a tachogenerator.
//!
//! Inputs `u_drive`, `u_field` [V] (0–10 V references, clipped to [0, 10] V); outputs the
//! tachometer `speed` [rpm] and the terminal `voltage` [V] (RMS, line to line), plus the
//! electrical frequency, true shaft speed, field current and voltage, both torques and the
//! stator d/q currents. Eight states `[i_d, i_q, i_f, ω_m, θ_e, ω_s, v_f, ω_t]`; equations,
//! parameters and measured responses in [`spurio::plants::wind_generator`]:
//!
//! ```text
//! L_d di_d/dt − M_f di_f/dt        = −R i_d + ω_e L_q i_q             R = R_s + R_load
//! L_q di_q/dt                      = −R i_q − ω_e L_d i_d + ω_e M_f i_f
//! −(3/2) M_f di_d/dt + L_f di_f/dt = v_f − R_f i_f
//! J dω_m/dt = T_m − T_e − B ω_m,   T_e = (3/2) p (M_f i_f + (L_q − L_d) i_d) i_q,  dθ_e/dt = p ω_m
//! T_m = clamp(k_s (ω_s − ω_m), ±T_max),  τ_drive dω_s/dt = ω_ref + T_m/k_s − ω_s,
//! ω_ref = (u_drive/10) 2π f_rated / p
//! τ_scr dv_f/dt = 12.5 u_field − v_f,   τ_tach dω_t/dt = ω_m − ω_t
//! speed = 60 ω_t/(2π),   voltage = √(3/2) R_load √(i_d² + i_q²)
//! ```
//!
//! Integrated inside `fmi2DoStep` by the eighth-order Dormand–Prince pair with error control
//! (relative tolerance `rtol`, default 7·10⁻¹²: the accuracy of the former default, RK4 on
//! 10⁻⁴ s substeps, at a sixth of its right-hand sides; [`WindGenerator::advance_adaptive`]), its
//! step carried from one `fmi2DoStep` to the next; or, with `fixed_step_rk4 = true`, by RK4 on
//! substeps no longer than `h_max` (default 10⁻⁴ s). The stator modes are fast
//! (|λ| ≈ 1.3·10³ s⁻¹); an `h_max` for which RK4 would be unstable (`h_max · |λ|max > 2.5`,
//! with the bound of [`fastest_mode`]) is refused with an error naming `h_max`. Initial condition: at rest (all states 0, the default), or, with
//! `start_at_operating_point = true`, in the steady state of the references `u_drive_0`,
//! `u_field_0` (closed form, [`WindGeneratorParameters::operating_point`]).
//!
//! **Model Exchange**: the eight states are the variables `i_d`, `i_q`, `field_current`,
//! `field_voltage` (outputs) and `omega_m`, `theta_e`, `omega_s`, `omega_tach` (locals), each
//! with its `der(…)`; the right-hand side is the CS integrator's
//! [`WindGeneratorParameters::derivative_on`], with the motor torque's limit held between
//! events. Three event indicators: `T_max − k_s (ω_s − ω_m)` and `k_s (ω_s − ω_m) + T_max`
//! (the motor torque reaches or leaves its breakdown limit; in event mode the limit is switched,
//! no state jumps) and `2π − θ_e` (the angle completes a turn; in event mode `θ_e` is wrapped
//! back to [0, 2π), a state change). Directional derivatives (on both interfaces) are the
//! analytic Jacobians of the math crate.

use spurio::ode::rosenbrock::Tolerance;
use spurio::plants::wind_generator::{
    wrap_angle, Adaptive, GeneratorState, InputMatrix, OutputMatrix, StateMatrix, TorqueLimit,
    WindGenerator, WindGeneratorParameters, OUTPUTS, RATED_DRIVE_REFERENCE, RATED_FIELD_REFERENCE,
};
use spurio_export::rows::{derivative, event_indicator, input, output, parameter};
use spurio_export::{
    Causality, Cause, Config, Context, DefaultExperiment, EventUpdate, Failure, FmuModel, Initial,
    ModelExchange, ModelInfo, Variable,
};
use std::f64::consts::PI;

pub use spurio_fmu_common::RK4_STABILITY_MARGIN;
use spurio_fmu_common::{advance_finite, rk4_substep};

/// One physical parameter of the FMU: its variable's name, unit and description, its declared
/// range (min, max), and the field of [`WindGeneratorParameters`] it sets (its start value is
/// that field's default).
#[derive(Debug, Clone, Copy)]
pub struct PhysicalParameter {
    pub name: &'static str,
    pub unit: &'static str,
    pub description: &'static str,
    pub range: (f64, f64),
    pub field: fn(&mut WindGeneratorParameters) -> &mut f64,
}

impl PhysicalParameter {
    /// Its value in `parameters`.
    pub fn value(&self, mut parameters: WindGeneratorParameters) -> f64 {
        *(self.field)(&mut parameters)
    }
}

/// A [`PhysicalParameter`], declared on one line.
const fn physical(
    name: &'static str,
    field: fn(&mut WindGeneratorParameters) -> &mut f64,
    unit: &'static str,
    range: (f64, f64),
    description: &'static str,
) -> PhysicalParameter {
    PhysicalParameter {
        name,
        unit,
        description,
        range,
        field,
    }
}

/// The 16 physical parameters, in value-reference order, each declared once. The ranges: a
/// laboratory machine set with room to spare, and no value that makes the model divide by
/// zero or overflow in a step.
#[rustfmt::skip]
pub const PHYSICAL_PARAMETERS: [PhysicalParameter; 16] = [
    physical("pole_pairs", |p| &mut p.pole_pairs, "1", (1.0, 32.0), "Pole pairs p (4 poles)"),
    physical("R_s", |p| &mut p.stator_resistance, "Ohm", (0.0, 1e4), "Stator resistance per phase"),
    physical("L_d", |p| &mut p.d_inductance, "H", (1e-6, 1e3), "d-axis synchronous inductance"),
    physical("L_q", |p| &mut p.q_inductance, "H", (1e-6, 1e3), "q-axis synchronous inductance"),
    physical("R_f", |p| &mut p.field_resistance, "Ohm", (0.0, 1e5), "Field winding resistance"),
    physical("L_f", |p| &mut p.field_inductance, "H", (1e-6, 1e4), "Field winding self-inductance"),
    physical("M_f", |p| &mut p.mutual_inductance, "H", (0.0, 1e3), "Stator-field mutual inductance"),
    physical("R_load", |p| &mut p.load_resistance, "Ohm", (0.0, 1e6), "Load resistance per phase, star-connected"),
    physical("J", |p| &mut p.inertia, "kg.m2", (1e-6, 1e4), "Inertia of both rotors"),
    physical("B", |p| &mut p.friction, "N.m.s/rad", (0.0, 1e3), "Viscous friction of the shaft"),
    physical("k_s", |p| &mut p.slip_stiffness, "N.m.s/rad", (0.0, 1e4), "Motor torque per rad/s of slip"),
    physical("T_max", |p| &mut p.max_motor_torque, "N.m", (0.0, 1e5), "Motor breakdown torque"),
    physical("tau_drive", |p| &mut p.drive_time_constant, "s", (1e-6, 1e3), "Drive slip-compensation lag"),
    physical("tau_scr", |p| &mut p.scr_time_constant, "s", (1e-6, 1e3), "SCR field supply lag"),
    physical("tau_tach", |p| &mut p.tachometer_time_constant, "s", (1e-6, 1e3), "Tachogenerator lag"),
    physical("f_rated", |p| &mut p.rated_frequency, "Hz", (0.0, 1e3), "Supply frequency at u_drive = 10 V"),
];

spurio_export::declare_variables! {
    /// The variable table, in value-reference order.
    pub fn variables() {
        let p = WindGeneratorParameters::default();
        table: [
            U_DRIVE = input("u_drive", RATED_DRIVE_REFERENCE, "V",
                "Drive speed reference, 0-10 V for 0-60 Hz (clipped to [0, 10] V)"),
            U_FIELD = input("u_field", RATED_FIELD_REFERENCE, "V",
                "SCR field reference, 0-10 V for 0-125 V DC (clipped to [0, 10] V)"),
            SPEED = output("speed", "rpm", "Shaft speed read by the tachogenerator")
                .depends_on(&[vr::OMEGA_TACH]),
            VOLTAGE = output("voltage", "V", "Terminal voltage, RMS line to line")
                .depends_on(&[vr::I_D, vr::I_Q]),
            FREQUENCY = output("frequency", "Hz", "Electrical frequency of the generated voltage")
                .depends_on(&[vr::OMEGA_M]),
            SHAFT_SPEED = output("shaft_speed", "rpm", "True shaft speed (without the tachometer lag)")
                .depends_on(&[vr::OMEGA_M]),
            FIELD_CURRENT = state(output("field_current", "A", "Field current i_f"), 0.5, vr::FIELD_CURRENT),
            FIELD_VOLTAGE = state(output("field_voltage", "V", "Field voltage from the SCR module"), 100.0, vr::FIELD_VOLTAGE),
            T_E = output("T_e", "N.m", "Electrical (braking) torque of the generator")
                .depends_on(&[vr::FIELD_CURRENT, vr::I_D, vr::I_Q]),
            T_M = output("T_m", "N.m", "Motor torque")
                .depends_on(&[vr::OMEGA_M, vr::OMEGA_S]),
            I_D = state(output("i_d", "A", "Stator d-axis current (peak-phase scale, amplitude-invariant Park)"), 0.5, vr::I_D),
            I_Q = state(output("i_q", "A", "Stator q-axis current (peak-phase scale, amplitude-invariant Park)"), 0.5, vr::I_Q),
            // The 16 physical parameters, in `PHYSICAL_PARAMETERS` order.
            FIRST_PARAMETER[16] = PHYSICAL_PARAMETERS.iter().map(|q| {
                let (min, max) = q.range;
                parameter(q.name, q.value(p), q.unit, q.description).min(min).max(max)
            }),
            H_MAX = parameter("h_max", WindGenerator::RECOMMENDED_MAX_SUBSTEP, "s",
                "Longest RK4 substep inside fmi2DoStep when fixed_step_rk4 (RK4 is unstable beyond about 2 ms; at most 100000 per step)")
                .min(1e-9)
                .max(1.0),
            START_AT_OPERATING_POINT = Variable::boolean_parameter("start_at_operating_point", false)
                .describe("Start in the steady state of u_drive_0, u_field_0 (true) or at rest (false)"),
            U_DRIVE_0 = parameter("u_drive_0", RATED_DRIVE_REFERENCE, "V",
                "Drive reference of the initial steady state").min(-1e3).max(1e3),
            U_FIELD_0 = parameter("u_field_0", RATED_FIELD_REFERENCE, "V",
                "Field reference of the initial steady state").min(-1e3).max(1e3),
            FIXED_STEP_RK4 = Variable::boolean_parameter("fixed_step_rk4", false)
                .describe("Integrate with RK4 on fixed substeps of h_max (true) instead of the adaptive eighth-order Dormand-Prince pair DOP853 with relative tolerance rtol (false, the default)"),
            RTOL = parameter("rtol", WindGenerator::DEFAULT_RELATIVE_TOLERANCE, "1",
                "Relative tolerance of the adaptive integrator (absolute: rtol times 0.5 A, 100 rad/s, 100 V)")
                .min(1e-12)
                .max(1e-2),
            // The states that are no output, then the eight derivatives (math order).
            OMEGA_M = state_local("omega_m", "rad/s", "Shaft speed (state)", 100.0),
            THETA_E = state_local("theta_e", "rad", "Electrical rotor angle, in [0, 2 pi) (state)", 1.0),
            OMEGA_S = state_local("omega_s", "rad/s", "Synchronous speed of the drive, mechanical (state)", 100.0),
            OMEGA_TACH = state_local("omega_tach", "rad/s", "Tachometer reading (state)", 100.0),
            FIRST_DERIVATIVE[8] = (0..8).map(|k| {
                let state = STATE_VRS[k];
                derivative(DERIVATIVE_NAMES[k], state, DERIVATIVE_UNITS[k], "Time derivative of the state")
                    .depends_on(&derivative_dependencies(k))
            }),
            Z_TORQUE_UPPER = event_indicator("z_torque_upper", "N.m",
                "Event indicator T_max - k_s (omega_s - omega_m): the motor torque reaches or leaves +T_max where it changes sign"),
            Z_TORQUE_LOWER = event_indicator("z_torque_lower", "N.m",
                "Event indicator k_s (omega_s - omega_m) + T_max: the motor torque reaches or leaves -T_max where it changes sign"),
            Z_TURN = event_indicator("z_turn", "rad",
                "Event indicator 2 pi - theta_e: the angle completes a turn (wrapped back to [0, 2 pi) at the event)"),
        ]
    }
}

/// `variable` (a continuous Real output) as the state at `own` (its own index) with `nominal`:
/// as an output it depends on itself only.
fn state(variable: Variable, nominal: f64, own: usize) -> Variable {
    variable.state().nominal(nominal).depends_on(&[own])
}

/// A local continuous Real that is a state of the Model Exchange interface.
fn state_local(name: &str, unit: &str, description: &str, nominal: f64) -> Variable {
    Variable {
        causality: Causality::Local,
        initial: Some(Initial::Calculated),
        ..output(name, unit, description).state().nominal(nominal)
    }
}

/// The value references of the states in the math crate's order
/// `[i_d, i_q, i_f, ω_m, θ_e, ω_s, v_f, ω_t]`.
pub const STATE_VRS: [usize; 8] = [
    vr::I_D,
    vr::I_Q,
    vr::FIELD_CURRENT,
    vr::OMEGA_M,
    vr::THETA_E,
    vr::OMEGA_S,
    vr::FIELD_VOLTAGE,
    vr::OMEGA_TACH,
];

/// The value references of the outputs in the order of
/// [`WindGeneratorParameters::outputs`].
pub const OUTPUT_VRS: [usize; OUTPUTS] = [
    vr::SPEED,
    vr::VOLTAGE,
    vr::FREQUENCY,
    vr::SHAFT_SPEED,
    vr::FIELD_CURRENT,
    vr::FIELD_VOLTAGE,
    vr::T_E,
    vr::T_M,
    vr::I_D,
    vr::I_Q,
];

/// The derivatives' names, in the math crate's state order.
const DERIVATIVE_NAMES: [&str; 8] = [
    "der(i_d)",
    "der(i_q)",
    "der(field_current)",
    "der(omega_m)",
    "der(theta_e)",
    "der(omega_s)",
    "der(field_voltage)",
    "der(omega_tach)",
];

/// Their units.
const DERIVATIVE_UNITS: [&str; 8] = [
    "A/s", "A/s", "A/s", "rad/s2", "rad/s", "rad/s2", "V/s", "rad/s2",
];

/// The states (math order) and inputs each derivative depends on: the nonzero pattern of
/// [`WindGeneratorParameters::jacobian_state`] and [`WindGeneratorParameters::jacobian_input`]
/// (test `declared_dependencies_are_the_jacobians_pattern`).
fn derivative_dependencies(k: usize) -> Vec<usize> {
    let states: &[usize] = match k {
        0 | 2 => &[0, 1, 2, 3, 6],
        1 => &[0, 1, 2, 3],
        3 => &[0, 1, 2, 3, 5],
        4 => &[3],
        5 => &[3, 5],
        6 => &[6],
        _ => &[3, 7],
    };
    let mut references: Vec<usize> = states.iter().map(|&i| STATE_VRS[i]).collect();
    match k {
        5 => references.push(vr::U_DRIVE),
        6 => references.push(vr::U_FIELD),
        _ => {}
    }
    references.sort_unstable();
    references
}

/// Where a value reference sits among the Jacobians' rows or columns.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Slot {
    /// A state (math index).
    State(usize),
    /// An input (0: `u_drive`, 1: `u_field`).
    Input(usize),
    /// A derivative (math index of its state).
    Derivative(usize),
    /// An output (index in [`OUTPUT_VRS`]).
    Output(usize),
}

/// The slot of a known (state or input) of a directional derivative.
fn known_slot(reference: usize) -> Option<Slot> {
    match reference {
        vr::U_DRIVE => Some(Slot::Input(0)),
        vr::U_FIELD => Some(Slot::Input(1)),
        _ => STATE_VRS
            .iter()
            .position(|&s| s == reference)
            .map(Slot::State),
    }
}

/// The slot of an unknown (derivative or output) of a directional derivative.
fn unknown_slot(reference: usize) -> Option<Slot> {
    if (vr::FIRST_DERIVATIVE..vr::FIRST_DERIVATIVE + 8).contains(&reference) {
        return Some(Slot::Derivative(reference - vr::FIRST_DERIVATIVE));
    }
    OUTPUT_VRS
        .iter()
        .position(|&o| o == reference)
        .map(Slot::Output)
}

/// An upper bound on the |eigenvalue| the integrator meets: the stator modes
/// `hypot(R/L_min, 1.2 ω_e,max)` with `L_min = min(L_q, L_d − (3/2) M_f²/L_f)`, the d–field
/// block's trace `(R L_f + R_f L_d)/(L_d L_f − (3/2) M_f²)`, and the first-order lags.
pub fn fastest_mode(p: &WindGeneratorParameters) -> f64 {
    let r = p.stator_resistance + p.load_resistance;
    let det = p.d_inductance * p.field_inductance - 1.5 * p.mutual_inductance * p.mutual_inductance;
    let transient = det / p.field_inductance;
    let l_min = p.q_inductance.min(transient);
    let omega_e = 1.2 * 2.0 * PI * p.rated_frequency;
    let stator = (r / l_min).hypot(omega_e);
    let d_field = (r * p.field_inductance + p.field_resistance * p.d_inductance) / det;
    [
        stator,
        d_field.hypot(omega_e),
        1.0 / p.scr_time_constant,
        1.0 / p.tachometer_time_constant,
        1.0 / p.drive_time_constant,
        p.slip_stiffness / p.inertia,
    ]
    .into_iter()
    .fold(0.0, f64::max)
}

/// The adaptive integrator's first step after initialisation [s].
const INITIAL_STEP: f64 = 1e-3;

/// The WindGenerator FMU.
#[derive(Debug, Clone)]
pub struct WindGeneratorFmu {
    generator: WindGenerator,
    h_max: f64,
    /// RK4 on fixed substeps of `h_max` (`fixed_step_rk4`) instead of the adaptive DOP853.
    fixed_step: bool,
    /// The adaptive integrator's tolerances (`rtol`).
    tolerance: Tolerance<8>,
    /// The adaptive integrator's next step, carried from one `fmi2DoStep` to the next.
    step: f64,
    /// The motor torque's limit: on Model Exchange held between events (switched in event
    /// mode), on Co-Simulation the limit of the state the last step left.
    limit: TorqueLimit,
}

impl WindGeneratorFmu {
    /// Writes the state variables and the outputs of the state `x` on the limit held.
    fn write_outputs(&self, ctx: &mut Context, x: &GeneratorState) {
        let outputs = self.generator.parameters.outputs(x, self.limit);
        for (&reference, value) in OUTPUT_VRS.iter().zip(outputs) {
            ctx.values.set_real(reference, value);
        }
        for (&reference, &value) in STATE_VRS.iter().zip(x.iter()) {
            ctx.values.set_real(reference, value);
        }
    }

    /// The state from the state variables.
    fn states(ctx: &Context) -> GeneratorState {
        GeneratorState::from_fn(|i, _| ctx.values.real(STATE_VRS[i]))
    }

    /// The inputs `(u_drive, u_field)`.
    fn inputs(ctx: &Context) -> (f64, f64) {
        (ctx.values.real(vr::U_DRIVE), ctx.values.real(vr::U_FIELD))
    }
}

/// The error for a value reference that is not one the call accepts.
fn not_a(reference: usize, what: &str) -> Failure {
    Failure::error(format!(
        "fmi2GetDirectionalDerivative: value reference {reference} is not a {what}"
    ))
}

impl FmuModel for WindGeneratorFmu {
    fn describe(_config: &Config) -> Result<ModelInfo, Cause> {
        Ok(ModelInfo::new(
            "WindGenerator",
            "Wind-generator lab set of paper 001: drive-fed induction motor and wound-field synchronous generator on a resistive load (8 states)",
            variables(),
            Some(DefaultExperiment {
                start_time: 0.0,
                stop_time: 10.0,
                step_size: 0.1,
            }),
            Config::new(),
        )
        .with_model_exchange()
        .map_err(|e| e.to_string())?)
    }

    fn create(_info: &ModelInfo) -> Result<Self, Cause> {
        Ok(Self {
            generator: WindGenerator {
                parameters: WindGeneratorParameters::default(),
                state: GeneratorState::zeros(),
            },
            h_max: WindGenerator::RECOMMENDED_MAX_SUBSTEP,
            limit: TorqueLimit::Linear,
            fixed_step: false,
            tolerance: WindGenerator::tolerance(WindGenerator::DEFAULT_RELATIVE_TOLERANCE),
            step: INITIAL_STEP,
        })
    }

    fn initialize(&mut self, ctx: &mut Context) -> Result<(), Failure> {
        let mut parameters = WindGeneratorParameters::default();
        for (k, q) in PHYSICAL_PARAMETERS.iter().enumerate() {
            *(q.field)(&mut parameters) = ctx.values.real(vr::FIRST_PARAMETER + k);
        }
        let generator = if ctx.values.boolean(vr::START_AT_OPERATING_POINT) {
            let (u_drive, u_field) = (
                ctx.values.real(vr::U_DRIVE_0),
                ctx.values.real(vr::U_FIELD_0),
            );
            let g = WindGenerator::at_operating_point(parameters, u_drive, u_field)
                .map_err(Failure::error)?;
            let op = parameters.operating_point(u_drive, u_field);
            if !op.reachable {
                return Err(Failure::error(format!(
                    "parameters `u_drive_0`, `u_field_0`: the steady state needs a motor torque of {:.4} N.m, beyond T_max = {} N.m",
                    op.motor_torque, parameters.max_motor_torque
                )));
            }
            g
        } else {
            WindGenerator::new(parameters).map_err(Failure::error)?
        };
        self.fixed_step = ctx.values.boolean(vr::FIXED_STEP_RK4);
        let h_max = if self.fixed_step {
            let fastest = fastest_mode(&parameters);
            let mode = format!("the machine's fastest mode (about {fastest:.1} 1/s)");
            rk4_substep(ctx.values.real(vr::H_MAX), fastest, &mode)?
        } else {
            ctx.values.real(vr::H_MAX)
        };
        self.tolerance = WindGenerator::tolerance(ctx.values.real(vr::RTOL));
        self.step = INITIAL_STEP;
        let state = generator.state;
        self.limit = parameters.torque_limit_of(state[5], state[3]);
        self.generator = generator;
        self.h_max = h_max;
        self.write_outputs(ctx, &state);
        Ok(())
    }

    fn check_step(&self, _ctx: &Context, _time: f64, step: f64) -> Result<(), Cause> {
        if self.fixed_step {
            spurio::ode::check_substeps(step, self.h_max)?;
        }
        Ok(())
    }

    fn do_step(&mut self, ctx: &mut Context, time: f64, step: f64) -> Result<(), Failure> {
        let (u_drive, u_field) = (ctx.values.real(vr::U_DRIVE), ctx.values.real(vr::U_FIELD));
        if self.fixed_step {
            let h_max = self.h_max;
            advance_finite(
                &mut self.generator,
                |g| g.advance(time, u_drive, u_field, step, h_max),
                |g| g.state.iter().all(|v| v.is_finite()),
                || format!("the state became non-finite in the step from t = {time}"),
            )?;
        } else {
            // On an error the generator keeps its state (advance_adaptive's contract).
            self.generator
                .advance_adaptive(
                    Adaptive::Dop853,
                    (u_drive, u_field),
                    step,
                    &self.tolerance,
                    &mut self.step,
                )
                .map_err(|e| Failure::error(format!("the step from t = {time}: {e}")))?;
        }
        let state = self.generator.state;
        self.limit = self
            .generator
            .parameters
            .torque_limit_of(state[5], state[3]);
        self.write_outputs(ctx, &state);
        Ok(())
    }

    spurio_fmu_common::fmu_state!(generator, h_max, limit, step; check = |m: &Self| {
        if m.generator.state.iter().any(|v| !v.is_finite()) {
            return Err("the saved generator state is not finite".into());
        }
        m.generator.parameters.validate()?;
        spurio::require_positive("h_max", m.h_max)?;
        Ok(())
    });
}

impl ModelExchange for WindGeneratorFmu {
    fn evaluate(&mut self, ctx: &mut Context) -> Result<(), Failure> {
        let x = Self::states(ctx);
        let (u_drive, u_field) = Self::inputs(ctx);
        let p = &self.generator.parameters;
        let dx = p.derivative_on(&x, u_drive, u_field, self.limit);
        for (k, value) in dx.iter().enumerate() {
            ctx.values.set_real(vr::FIRST_DERIVATIVE + k, *value);
        }
        let outputs = p.outputs(&x, self.limit);
        for (&reference, value) in OUTPUT_VRS.iter().zip(outputs) {
            ctx.values.set_real(reference, value);
        }
        Ok(())
    }

    fn event_indicators(&mut self, ctx: &mut Context, z: &mut [f64]) -> Result<(), Failure> {
        let indicators = self
            .generator
            .parameters
            .event_indicators(&Self::states(ctx));
        for (z, value) in z.iter_mut().zip(indicators) {
            *z = value;
        }
        Ok(())
    }

    fn update_discrete_states(&mut self, ctx: &mut Context) -> Result<EventUpdate, Failure> {
        let mut x = Self::states(ctx);
        let p = self.generator.parameters;
        let mut update = EventUpdate::default();
        let limit = p.torque_limit_of(x[5], x[3]);
        if limit != self.limit {
            let time = ctx.time();
            ctx.log_event(|| {
                format!(
                    "t = {}: the motor torque {} (k_s (omega_s - omega_m) = {} N.m)",
                    time,
                    match limit {
                        TorqueLimit::Linear => "leaves its limit",
                        TorqueLimit::Upper => "reaches +T_max",
                        TorqueLimit::Lower => "reaches -T_max",
                    },
                    p.slip_stiffness * (x[5] - x[3])
                )
            });
            self.limit = limit;
        }
        if p.event_indicators(&x)[2] <= 0.0 {
            wrap_angle(&mut x);
            update.states_changed = true;
        }
        self.write_outputs(ctx, &x);
        Ok(update)
    }

    /// `∂f/∂x`, `∂f/∂u` and `∂y/∂x` at the current states and inputs.
    type Jacobian = (StateMatrix, InputMatrix, OutputMatrix);

    fn jacobian(&mut self, ctx: &Context) -> Result<Self::Jacobian, Failure> {
        let x = Self::states(ctx);
        let (u_drive, u_field) = Self::inputs(ctx);
        let p = &self.generator.parameters;
        Ok((
            p.jacobian_state(&x, self.limit),
            p.jacobian_input(u_drive, u_field),
            p.output_jacobian(&x, self.limit),
        ))
    }

    fn partial(&self, at: &Self::Jacobian, unknown: usize, known: usize) -> Result<f64, Failure> {
        let (jx, ju, jy) = at;
        let row = unknown_slot(unknown).ok_or_else(|| not_a(unknown, "derivative or output"))?;
        let column = known_slot(known).ok_or_else(|| not_a(known, "state or input"))?;
        Ok(match (row, column) {
            (Slot::Derivative(i), Slot::State(j)) => jx[(i, j)],
            (Slot::Derivative(i), Slot::Input(j)) => ju[(i, j)],
            (Slot::Output(i), Slot::State(j)) => jy[(i, j)],
            _ => 0.0,
        })
    }
}

spurio_export::export_fmu!(WindGeneratorFmu, model_exchange);

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stability_bound_of_the_defaults_is_about_2_ms() {
        let limit = RK4_STABILITY_MARGIN / fastest_mode(&WindGeneratorParameters::default());
        assert!(limit > 1.5e-3 && limit < 2.2e-3, "{limit}");
    }

    use spurio::plants::wind_generator::EVENT_INDICATORS;
    use spurio_export::Values;

    /// A model initialised from the start values, with the state `x` in its variables.
    fn model_at(values: &mut Values, x: &GeneratorState) -> WindGeneratorFmu {
        let info = WindGeneratorFmu::describe(&Config::new()).unwrap();
        let mut m = WindGeneratorFmu::create(&info).unwrap();
        m.initialize(&mut Context::new(values)).unwrap();
        m.limit = m.generator.parameters.torque_limit_of(x[5], x[3]);
        m.write_outputs(&mut Context::new(values), x);
        m
    }

    #[test]
    fn model_exchange_declares_the_eight_states_and_their_derivatives() {
        let info = WindGeneratorFmu::describe(&Config::new()).unwrap();
        let me = info.model_exchange.as_ref().unwrap();
        assert_eq!(
            me.event_indicators,
            [vr::Z_TORQUE_UPPER, vr::Z_TORQUE_LOWER, vr::Z_TURN]
        );
        assert_eq!(me.event_indicators.len(), EVENT_INDICATORS);
        let mut by_reference = STATE_VRS;
        by_reference.sort_unstable();
        assert_eq!(me.states, by_reference);
        for (state, derivative) in me.states.iter().zip(&me.derivatives) {
            let k = STATE_VRS.iter().position(|s| s == state).unwrap();
            assert_eq!(*derivative, vr::FIRST_DERIVATIVE + k);
        }
    }

    #[test]
    fn declared_dependencies_are_the_jacobians_pattern() {
        // The outputs' and derivatives' dependencies in the ModelStructure are exactly the
        // nonzero entries of the analytic Jacobians.
        let p = WindGeneratorParameters::default();
        let x = GeneratorState::from_column_slice(&[0.3, 0.4, 0.5, 150.0, 1.0, 160.0, 90.0, 140.0]);
        // The pattern over both modes of the torque (e.g. der(omega_s) depends on omega_s only
        // at a limit, der(omega_m) on omega_s only off it).
        let jx = p.jacobian_state(&x, TorqueLimit::Linear).abs()
            + p.jacobian_state(&x, TorqueLimit::Upper).abs();
        let ju = p.jacobian_input(5.0, 5.0);
        let jy = p.output_jacobian(&x, TorqueLimit::Linear);
        let table = variables();
        for k in 0..8 {
            let mut pattern: Vec<usize> = (0..8)
                .filter(|&j| jx[(k, j)] != 0.0)
                .map(|j| STATE_VRS[j])
                .chain(
                    (0..2)
                        .filter(|&j| ju[(k, j)] != 0.0)
                        .map(|j| [vr::U_DRIVE, vr::U_FIELD][j]),
                )
                .collect();
            pattern.sort_unstable();
            assert_eq!(
                table[vr::FIRST_DERIVATIVE + k].dependencies,
                pattern,
                "{}",
                DERIVATIVE_NAMES[k]
            );
        }
        for (i, &reference) in OUTPUT_VRS.iter().enumerate() {
            let mut pattern: Vec<usize> = (0..8)
                .filter(|&j| jy[(i, j)] != 0.0)
                .map(|j| STATE_VRS[j])
                .collect();
            pattern.sort_unstable();
            assert_eq!(
                table[reference].dependencies, pattern,
                "{}",
                table[reference].name
            );
        }
    }

    #[test]
    fn directional_derivatives_match_central_differences_of_evaluate() {
        let mut rng = spurio::signals::rng::RandomGenerator::new(15);
        let info = WindGeneratorFmu::describe(&Config::new()).unwrap();
        let unknowns: Vec<usize> = (vr::FIRST_DERIVATIVE..vr::FIRST_DERIVATIVE + 8)
            .chain(OUTPUT_VRS)
            .collect();
        let knowns: Vec<usize> = STATE_VRS
            .iter()
            .copied()
            .chain([vr::U_DRIVE, vr::U_FIELD])
            .collect();
        for _ in 0..50 {
            let x = GeneratorState::from_fn(|i, _| {
                let (low, high) = [
                    (-2.0, 2.0),
                    (-2.0, 2.0),
                    (0.0, 1.0),
                    (0.0, 250.0),
                    (0.0, 6.0),
                    (0.0, 260.0),
                    (0.0, 125.0),
                    (0.0, 250.0),
                ][i];
                rng.uniform_range(low, high)
            });
            let mut values = Values::from_start(&info.variables);
            let mut m = model_at(&mut values, &x);
            values.set_real(vr::U_DRIVE, rng.uniform_range(0.5, 9.5));
            values.set_real(vr::U_FIELD, rng.uniform_range(0.5, 9.5));
            for (j, &known) in knowns.iter().enumerate() {
                let mut seed = vec![0.0; knowns.len()];
                seed[j] = 1.0;
                let mut analytic = vec![0.0; unknowns.len()];
                let mut ctx = Context::new(&mut values);
                m.evaluate(&mut ctx).unwrap();
                m.directional_derivative(&mut ctx, &unknowns, &knowns, &seed, &mut analytic)
                    .unwrap();
                let base = values.real(known);
                let d = 1e-5 * base.abs().max(1.0);
                let mut at = |value: f64| {
                    values.set_real(known, value);
                    m.evaluate(&mut Context::new(&mut values)).unwrap();
                    unknowns
                        .iter()
                        .map(|&u| values.real(u))
                        .collect::<Vec<f64>>()
                };
                let (plus, minus) = (at(base + d), at(base - d));
                values.set_real(known, base);
                for (i, &unknown) in unknowns.iter().enumerate() {
                    let fd = (plus[i] - minus[i]) / (2.0 * d);
                    let scale = fd.abs().max(analytic[i].abs()).max(1e-3);
                    assert!(
                        (fd - analytic[i]).abs() <= 1e-6 * scale,
                        "d{}/d{}: {fd} vs {}",
                        info.variables[unknown].name,
                        info.variables[known].name,
                        analytic[i]
                    );
                }
            }
        }
    }

    #[test]
    fn events_switch_the_torque_limit_and_wrap_the_angle() {
        let info = WindGeneratorFmu::describe(&Config::new()).unwrap();
        let mut values = Values::from_start(&info.variables);
        // Far more slip than T_max allows: k_s · 30 rad/s = 5.2 N.m > 3.4 N.m.
        let x = GeneratorState::from_column_slice(&[
            0.1,
            0.2,
            0.3,
            100.0,
            2.0 * PI + 0.01,
            130.0,
            50.0,
            90.0,
        ]);
        let mut m = model_at(&mut values, &x);
        m.limit = TorqueLimit::Linear;
        let mut ctx = Context::new(&mut values);
        let mut z = [0.0; EVENT_INDICATORS];
        m.evaluate(&mut ctx).unwrap();
        m.event_indicators(&mut ctx, &mut z).unwrap();
        assert!(z[0] < 0.0 && z[1] > 0.0 && z[2] < 0.0, "{z:?}");
        let update = m.update_discrete_states(&mut ctx).unwrap();
        assert!(update.states_changed);
        assert_eq!(m.limit, TorqueLimit::Upper);
        assert!((values.real(vr::THETA_E) - 0.01).abs() < 1e-12);
        assert_eq!(values.real(vr::T_M), 3.4);
        // Nothing more to do at the same point.
        let mut ctx = Context::new(&mut values);
        assert_eq!(
            m.update_discrete_states(&mut ctx).unwrap(),
            EventUpdate::default()
        );
    }

    #[test]
    fn adaptive_default_agrees_with_fixed_step_rk4_and_fails_cleanly() {
        use spurio_export::harness::Harness;
        use spurio_export::types::Status;
        let run = |fixed: bool| {
            let mut h = Harness::<WindGeneratorFmu>::new(&Config::new()).unwrap();
            h.set_boolean(&[vr::FIXED_STEP_RK4 as u32], &[fixed])
                .unwrap();
            h.initialize(0.0).unwrap();
            let mut out = [0.0; 2];
            let mut samples = Vec::new();
            for k in 0..60 {
                let u = if k < 30 { [10.0, 8.0] } else { [6.0, 5.0] };
                let io = [vr::U_DRIVE as u32, vr::U_FIELD as u32];
                let read = [vr::SPEED as u32, vr::VOLTAGE as u32];
                h.exchange(&io, &u, (k as f64 * 0.1, 0.1), &read, &mut out)
                    .unwrap();
                samples.push(out);
            }
            (h, samples)
        };
        let (_, rk4) = run(true);
        let (mut h, adaptive) = run(false);
        // Both within about 2e-11 of rated from the truth (the math crate's tests).
        for (a, b) in adaptive.iter().zip(&rk4) {
            assert!((a[0] - b[0]).abs() < 1e-10 * 1800.0, "{a:?} {b:?}");
            assert!((a[1] - b[1]).abs() < 1e-10 * 240.0, "{a:?} {b:?}");
        }
        // A step the adaptive integrator cannot finish in its bounded work is refused and the
        // instance stays where it was.
        let before = h.real(vr::SPEED as u32).unwrap();
        assert_eq!(h.do_step(6.0, 1e308), Err(Status::Error));
        assert!(h.logged(&["the step from t = 6"]), "{:?}", h.log());
        assert_eq!(h.real(vr::SPEED as u32).unwrap(), before);
    }

    #[test]
    fn a_step_needing_too_many_substeps_is_refused_at_once() {
        use spurio_export::harness::Harness;
        use spurio_export::types::Status;
        let mut h = Harness::<WindGeneratorFmu>::new(&Config::new()).unwrap();
        h.set_boolean(&[vr::FIXED_STEP_RK4 as u32], &[true])
            .unwrap();
        h.set_real(&[vr::H_MAX as u32], &[1e-9]).unwrap();
        h.initialize(0.0).unwrap();
        spurio_fmu_common::refuses_too_many_substeps(&mut h, 0.1).unwrap();
        h.do_step(0.0, 1e-5).unwrap();
        assert_eq!(h.last_successful_time().unwrap(), 1e-5);
        // every physical parameter has a declared range, checked when set
        let table = variables();
        for k in 0..PHYSICAL_PARAMETERS.len() {
            let v = &table[vr::FIRST_PARAMETER + k];
            assert!(v.min.is_some() && v.max.is_some(), "{}", v.name);
        }
        assert_eq!(h.reset(), Ok(Status::Ok));
        assert_eq!(
            h.set_real(&[vr::FIRST_PARAMETER as u32 + 8], &[-1e308]),
            Err(Status::Error)
        );
        assert!(h.logged(&["`J` = -1"]), "{:?}", h.log());
    }
}
