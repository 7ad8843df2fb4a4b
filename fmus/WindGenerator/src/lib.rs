//! `WindGenerator.fmu`: the wind-generator laboratory set of paper 001 (§4, Fig. 1,
//! appendices A–D; docs/models.md §2.2) as an FMI 2.0 CS FMU: a drive-fed induction motor turning a
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
//! Integrated inside `fmi2DoStep` by RK4 on substeps no longer than `h_max` (default 10⁻⁴ s).
//! The stator modes are fast (|λ| ≈ 1.3·10³ s⁻¹); an `h_max` for which RK4 would be unstable
//! (`h_max · |λ|max > 2.5`, with the bound of [`fastest_mode`]) is refused with an error
//! naming `h_max`. Initial condition: at rest (all states 0, the default), or, with
//! `start_at_operating_point = true`, in the steady state of the references `u_drive_0`,
//! `u_field_0` (closed form, [`WindGeneratorParameters::operating_point`]).

use spurio::plants::wind_generator::{
    GeneratorState, WindGenerator, WindGeneratorParameters, RATED_DRIVE_REFERENCE,
    RATED_FIELD_REFERENCE,
};
use spurio_export::rows::{input, output, parameter};
use spurio_export::{
    Cause, Config, Context, DefaultExperiment, Failure, FmuModel, ModelInfo, Variable,
};
use std::f64::consts::PI;

pub use spurio_fmu_common::RK4_STABILITY_MARGIN;
use spurio_fmu_common::{advance_finite, rk4_substep};

/// The declared range (min, max) of each physical parameter, in [`PARAMETER_NAMES`] order:
/// a laboratory machine set with room to spare, and no value that makes the model divide by
/// zero or overflow in a step.
pub const PARAMETER_RANGES: [(f64, f64); 16] = [
    (1.0, 32.0), // pole_pairs
    (0.0, 1e4),  // R_s
    (1e-6, 1e3), // L_d
    (1e-6, 1e3), // L_q
    (0.0, 1e5),  // R_f
    (1e-6, 1e4), // L_f
    (0.0, 1e3),  // M_f
    (0.0, 1e6),  // R_load
    (1e-6, 1e4), // J
    (0.0, 1e3),  // B
    (0.0, 1e4),  // k_s
    (0.0, 1e5),  // T_max
    (1e-6, 1e3), // tau_drive
    (1e-6, 1e3), // tau_scr
    (1e-6, 1e3), // tau_tach
    (0.0, 1e3),  // f_rated
];

/// The physical parameters: (name, unit, description), in value-reference order.
pub const PARAMETER_NAMES: [(&str, &str, &str); 16] = [
    ("pole_pairs", "1", "Pole pairs p (4 poles)"),
    ("R_s", "Ohm", "Stator resistance per phase"),
    ("L_d", "H", "d-axis synchronous inductance"),
    ("L_q", "H", "q-axis synchronous inductance"),
    ("R_f", "Ohm", "Field winding resistance"),
    ("L_f", "H", "Field winding self-inductance"),
    (
        "M_f",
        "H",
        "Stator-field mutual inductance (sets 240 V at the rated point)",
    ),
    ("R_load", "Ohm", "Load resistance per phase, star-connected"),
    ("J", "kg.m2", "Inertia of both rotors"),
    ("B", "N.m.s/rad", "Viscous friction of the shaft"),
    (
        "k_s",
        "N.m.s/rad",
        "Induction motor torque per rad/s of slip (rated torque / rated slip)",
    ),
    ("T_max", "N.m", "Motor breakdown torque"),
    (
        "tau_drive",
        "s",
        "Drive slip-compensation / frequency filter time constant",
    ),
    ("tau_scr", "s", "SCR field supply lag"),
    ("tau_tach", "s", "Tachogenerator lag"),
    ("f_rated", "Hz", "Supply frequency at u_drive = 10 V"),
];

fn parameter_values(p: &WindGeneratorParameters) -> [f64; 16] {
    [
        p.pole_pairs,
        p.stator_resistance,
        p.d_inductance,
        p.q_inductance,
        p.field_resistance,
        p.field_inductance,
        p.mutual_inductance,
        p.load_resistance,
        p.inertia,
        p.friction,
        p.slip_stiffness,
        p.max_motor_torque,
        p.drive_time_constant,
        p.scr_time_constant,
        p.tachometer_time_constant,
        p.rated_frequency,
    ]
}

fn parameters_from(v: &[f64]) -> WindGeneratorParameters {
    let g = |i: usize| v.get(i).copied().unwrap_or(f64::NAN);
    WindGeneratorParameters {
        pole_pairs: g(0),
        stator_resistance: g(1),
        d_inductance: g(2),
        q_inductance: g(3),
        field_resistance: g(4),
        field_inductance: g(5),
        mutual_inductance: g(6),
        load_resistance: g(7),
        inertia: g(8),
        friction: g(9),
        slip_stiffness: g(10),
        max_motor_torque: g(11),
        drive_time_constant: g(12),
        scr_time_constant: g(13),
        tachometer_time_constant: g(14),
        rated_frequency: g(15),
    }
}

spurio_export::declare_variables! {
    /// The variable table, in value-reference order.
    pub fn variables() {
        let p = WindGeneratorParameters::default();
        table: [
            U_DRIVE = input("u_drive", RATED_DRIVE_REFERENCE, "V",
                "Drive speed reference, 0-10 V for 0-60 Hz (clipped to [0, 10] V)"),
            U_FIELD = input("u_field", RATED_FIELD_REFERENCE, "V",
                "SCR field reference, 0-10 V for 0-125 V DC (clipped to [0, 10] V)"),
            SPEED = output("speed", "rpm", "Shaft speed read by the tachogenerator"),
            VOLTAGE = output("voltage", "V", "Terminal voltage, RMS line to line"),
            FREQUENCY = output("frequency", "Hz", "Electrical frequency of the generated voltage"),
            SHAFT_SPEED = output("shaft_speed", "rpm", "True shaft speed (without the tachometer lag)"),
            FIELD_CURRENT = output("field_current", "A", "Field current i_f"),
            FIELD_VOLTAGE = output("field_voltage", "V", "Field voltage from the SCR module"),
            T_E = output("T_e", "N.m", "Electrical (braking) torque of the generator"),
            T_M = output("T_m", "N.m", "Motor torque"),
            I_D = output("i_d", "A", "Stator d-axis current (peak-phase scale, amplitude-invariant Park)"),
            I_Q = output("i_q", "A", "Stator q-axis current (peak-phase scale, amplitude-invariant Park)"),
            // The 16 physical parameters, in `PARAMETER_NAMES` order.
            FIRST_PARAMETER[16] = PARAMETER_NAMES
                .iter()
                .zip(parameter_values(&p))
                .zip(PARAMETER_RANGES)
                .map(|(((name, unit, description), value), (min, max))| {
                    parameter(name, value, unit, description).min(min).max(max)
                }),
            H_MAX = parameter("h_max", WindGenerator::RECOMMENDED_MAX_SUBSTEP, "s",
                "Longest RK4 substep inside fmi2DoStep (RK4 is unstable beyond about 2 ms; at most 100000 per step)")
                .min(1e-9)
                .max(1.0),
            START_AT_OPERATING_POINT = Variable::boolean_parameter("start_at_operating_point", false)
                .describe("Start in the steady state of u_drive_0, u_field_0 (true) or at rest (false)"),
            U_DRIVE_0 = parameter("u_drive_0", RATED_DRIVE_REFERENCE, "V",
                "Drive reference of the initial steady state").min(-1e3).max(1e3),
            U_FIELD_0 = parameter("u_field_0", RATED_FIELD_REFERENCE, "V",
                "Field reference of the initial steady state").min(-1e3).max(1e3),
        ]
    }
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

/// The WindGenerator FMU.
#[derive(Debug, Clone)]
pub struct WindGeneratorFmu {
    generator: WindGenerator,
    h_max: f64,
}

impl WindGeneratorFmu {
    fn write_outputs(&self, ctx: &mut Context) {
        let g = &self.generator;
        let p = &g.parameters;
        let s = &g.state;
        let values = [
            (vr::SPEED, g.speed_rpm()),
            (vr::VOLTAGE, g.terminal_voltage()),
            (vr::FREQUENCY, g.frequency()),
            (vr::SHAFT_SPEED, g.shaft_speed_rpm()),
            (vr::FIELD_CURRENT, s[2]),
            (vr::FIELD_VOLTAGE, s[6]),
            (vr::T_E, g.electrical_torque()),
            (vr::T_M, p.motor_torque(s[5], s[3])),
            (vr::I_D, s[0]),
            (vr::I_Q, s[1]),
        ];
        for (i, v) in values {
            ctx.values.set_real(i, v);
        }
    }
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
        ))
    }

    fn create(_info: &ModelInfo) -> Result<Self, Cause> {
        Ok(Self {
            generator: WindGenerator {
                parameters: WindGeneratorParameters::default(),
                state: GeneratorState::zeros(),
            },
            h_max: WindGenerator::RECOMMENDED_MAX_SUBSTEP,
        })
    }

    fn initialize(&mut self, ctx: &mut Context) -> Result<(), Failure> {
        let values: Vec<f64> = (0..PARAMETER_NAMES.len())
            .map(|k| ctx.values.real(vr::FIRST_PARAMETER + k))
            .collect();
        let parameters = parameters_from(&values);
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
        let fastest = fastest_mode(&parameters);
        let mode = format!("the machine's fastest mode (about {fastest:.1} 1/s)");
        let h_max = rk4_substep(ctx.values.real(vr::H_MAX), fastest, &mode)?;
        self.generator = generator;
        self.h_max = h_max;
        self.write_outputs(ctx);
        Ok(())
    }

    spurio_fmu_common::rk4_check_step!(h_max);

    fn do_step(&mut self, ctx: &mut Context, time: f64, step: f64) -> Result<(), Failure> {
        let (u_drive, u_field) = (ctx.values.real(vr::U_DRIVE), ctx.values.real(vr::U_FIELD));
        let h_max = self.h_max;
        advance_finite(
            &mut self.generator,
            |g| g.advance(time, u_drive, u_field, step, h_max),
            |g| g.state.iter().all(|v| v.is_finite()),
            || format!("the state became non-finite in the step from t = {time}"),
        )?;
        self.write_outputs(ctx);
        Ok(())
    }

    spurio_fmu_common::fmu_state!(generator, h_max; check = |m: &Self| {
        if m.generator.state.iter().any(|v| !v.is_finite()) {
            return Err("the saved generator state is not finite".into());
        }
        m.generator.parameters.validate()?;
        spurio::require_positive("h_max", m.h_max)?;
        Ok(())
    });
}

spurio_export::export_fmu!(WindGeneratorFmu);

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stability_bound_of_the_defaults_is_about_2_ms() {
        let limit = RK4_STABILITY_MARGIN / fastest_mode(&WindGeneratorParameters::default());
        assert!(limit > 1.5e-3 && limit < 2.2e-3, "{limit}");
    }

    #[test]
    fn a_step_needing_too_many_substeps_is_refused_at_once() {
        use spurio_export::harness::Harness;
        use spurio_export::types::Status;
        let mut h = Harness::<WindGeneratorFmu>::new(&Config::new()).unwrap();
        h.set_real(&[vr::H_MAX as u32], &[1e-9]).unwrap();
        h.initialize(0.0).unwrap();
        spurio_fmu_common::refuses_too_many_substeps(&mut h, 0.1).unwrap();
        h.do_step(0.0, 1e-5).unwrap();
        assert_eq!(h.last_successful_time().unwrap(), 1e-5);
        // every physical parameter has a declared range, checked when set
        let table = variables();
        for k in 0..PARAMETER_NAMES.len() {
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
