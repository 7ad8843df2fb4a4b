//! The pieces the two state-feedback controller FMUs (`StateFeedback`,
//! `AdaptiveStateFeedback`) share: the sampled-controller skeleton ([`SampledController`],
//! the FMU around a [`ControlLaw`]), the configuration keys and presets, the default model and
//! poles of a variant, the pole and limit parameters, the sample clock, and the design error
//! messages. Each controller FMU is its declaration and its law.
//!
//! **Sampling.** Both controllers sample on the one clock of [`crate::clock`] (parameter
//! `sample_period`, rule [`Rule::Step`]): the sample of instant t_k uses the inputs at the
//! communication point t_k (direct feedthrough: `u` is shown there as soon as the inputs are
//! set) and the step from t_k commits it; between samples (a step shorter than T, a master's
//! rounding step of 10⁻¹⁵ s) the outputs hold whatever the inputs, a step covering several
//! instants takes them all with the inputs held. With the default `sample_period` = 0 (T =
//! the first step's size) a fixed-step master gets one sample per step.

use crate::clock::{self, ClockError, Rule, SampleClock};
use crate::structured::{add_vector, Block};
use nalgebra::{Complex, DMatrix};
use spurio::control::pole_placement::check_poles;
use spurio::control::{
    ackermann_with_options, crane_reference_design, DiscreteDesign, InputLimits,
    PolePlacementError, PolePlacementOptions, CRANE_CONTINUOUS_POLES, CRANE_SAMPLE_TIME,
};
use spurio::state::{PlainState, StateError};
use spurio::ParameterError;
use spurio_export::{
    Causality, Cause, Config, Context, DefaultExperiment, Failure, FmuModel, Initial, ModelInfo,
    Values, Variability, Variable, VariableTable,
};

/// Configuration key: number of states n.
pub const CONFIG_STATES: &str = "n";
/// Configuration key: `crane` for the crane defaults, `generic` (or absent) for the chain.
pub const CONFIG_PRESET: &str = "preset";
/// Sample time of the generic chain `A = I + Ts·N` (s).
pub const GENERIC_SAMPLE_TIME: f64 = 0.05;
/// Every desired pole of the generic default (a real pole of multiplicity n).
pub const GENERIC_POLE: f64 = 0.5;
/// Default actuator limit `|u| ≤ 17` (N for the crane, paper 000 Annex A).
pub const DEFAULT_INPUT_LIMIT: f64 = 17.0;

/// Which defaults a variant carries.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Preset {
    /// The crane of paper 000: n = 4, state `[x, θ, ẋ, θ̇]`, input the force in N.
    Crane,
    /// Any n: the discretised chain of integrators.
    Generic,
}

/// The default model, poles and gain of a variant.
#[derive(Debug, Clone, PartialEq)]
pub struct VariantDefaults {
    /// Which preset.
    pub preset: Preset,
    /// Discrete `A` (n × n), `B` (n × 1), the desired poles (n) and their Ackermann gain
    /// (1 × n; zeros if the default design is not computable: a generic chain so long that
    /// its reachability matrix is ill-conditioned).
    pub design: DiscreteDesign,
}

impl VariantDefaults {
    /// Number of states.
    pub fn states(&self) -> usize {
        self.design.a.nrows()
    }
}

/// The defaults for a configuration.
///
/// * `preset = crane` (requires n = 4 or no n): `A`, `B` = ZOH at Ts = 0.05 s of the crane
///   linearisation (paper 000 eqs 4–5, Annex A), poles `z = e^{s Ts}` for
///   `s = −1 ± 0.5j, −1.5 ± 5.2j`, gain ≈ [0.982, 1.132, 1.027, 0.774] (docs/reference-values.md §6).
/// * otherwise (n default 4): the chain of n integrators discretised with Euler at
///   Ts = 0.05 s, `A = I + Ts·N` (N the ones on the superdiagonal), `B = e_n`, all poles at
///   0.5 (a repeated real pole is fine for a single input). Its reachability matrix has a
///   condition number ≈ Ts^{−(n−1)}, so for n ≳ 9 the default design is rejected as not
///   reachable: give your own `A`, `B` then.
pub fn variant_defaults(config: &Config) -> Result<VariantDefaults, Cause> {
    let preset = match config.get(CONFIG_PRESET) {
        None | Some("generic") => Preset::Generic,
        Some("crane") => Preset::Crane,
        Some(other) => {
            return Err(format!(
                "configuration `{CONFIG_PRESET}` must be `crane` or `generic`, got `{other}`"
            )
            .into())
        }
    };
    let n = config.dimension(CONFIG_STATES, 4)?;
    match preset {
        Preset::Crane => {
            if n != 4 {
                return Err(format!(
                    "configuration `{CONFIG_PRESET} = crane` has 4 states, but `{CONFIG_STATES} = {n}`"
                ).into());
            }
            let design = crane_reference_design().map_err(|e| format!("crane design: {e}"))?;
            Ok(VariantDefaults { preset, design })
        }
        Preset::Generic => {
            let a = DMatrix::from_fn(n, n, |i, j| {
                if i == j {
                    1.0
                } else if j == i + 1 {
                    GENERIC_SAMPLE_TIME
                } else {
                    0.0
                }
            });
            let mut b = DMatrix::zeros(n, 1);
            b[(n - 1, 0)] = 1.0;
            let poles = vec![Complex::new(GENERIC_POLE, 0.0); n];
            let gain = ackermann_with_options(&a, &b, &poles, &PolePlacementOptions::default())
                .unwrap_or_else(|_| DMatrix::zeros(1, n));
            let design = DiscreteDesign {
                a,
                b,
                poles,
                gain,
                sample_time: GENERIC_SAMPLE_TIME,
            };
            Ok(VariantDefaults { preset, design })
        }
    }
}

/// What state i is, and its unit, for the descriptions of the variables.
pub fn state_meaning(preset: Preset, i: usize) -> (String, Option<&'static str>) {
    const CRANE: [(&str, &str); 4] = [
        ("cart position x", "m"),
        ("load angle θ", "rad"),
        ("cart velocity ẋ", "m/s"),
        ("load angular velocity θ̇", "rad/s"),
    ];
    match (preset, CRANE.get(i)) {
        (Preset::Crane, Some((meaning, unit))) => (meaning.to_string(), Some(*unit)),
        _ => (format!("state {}", i + 1), None),
    }
}

/// Unit of the control input.
pub fn input_unit(preset: Preset) -> Option<&'static str> {
    match preset {
        Preset::Crane => Some("N"),
        Preset::Generic => None,
    }
}

/// Adds the unit when there is one.
pub fn with_unit(variable: Variable, unit: Option<&str>) -> Variable {
    match unit {
        Some(u) => variable.unit(u),
        None => variable,
    }
}

/// A calculated parameter (`fixed`, `initial="calculated"`), computed at initialisation.
pub fn calculated_parameter(name: &str) -> Variable {
    Variable {
        causality: Causality::CalculatedParameter,
        variability: Variability::Fixed,
        initial: Some(Initial::Calculated),
        ..Variable::parameter(name, 0.0)
    }
}

/// Adds the controller's state-estimate inputs `x_hat[i]`, described and with units by the
/// preset; returns their block.
pub fn add_estimated_state(table: &mut VariableTable, preset: Preset, n: usize) -> Block {
    add_vector(table, "x_hat", n, |name, i| {
        let (meaning, unit) = state_meaning(preset, i);
        with_unit(
            Variable::input(name, 0.0).describe(&format!("Estimated state: {meaning}")),
            unit,
        )
    })
}

/// The start of a controller's variable table: the variant's defaults and the table with
/// the state-estimate inputs `x_hat[i]` (the first variables of every controller).
pub fn start_table(config: &Config) -> Result<(VariantDefaults, VariableTable, Block), Cause> {
    let defaults = variant_defaults(config)?;
    let mut table = VariableTable::new();
    let x_hat = add_estimated_state(&mut table, defaults.preset, defaults.states());
    Ok((defaults, table, x_hat))
}

/// The design parameters every controller has: the desired poles
/// `pole_re[i] + j·pole_im[i]` and the input limits `u_min`, `u_max`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct DesignBlocks {
    /// Parameter `pole_re[i]`.
    pub pole_re: Block,
    /// Parameter `pole_im[i]`.
    pub pole_im: Block,
    /// Parameter `u_min`.
    pub u_min: usize,
    /// Parameter `u_max`.
    pub u_max: usize,
    /// Parameter `sample_period`.
    pub sample_period: usize,
}

impl DesignBlocks {
    /// Adds `pole_re[i]`, `pole_im[i]` (with the variant's default poles), then `u_min`,
    /// `u_max`, `sample_period`.
    pub fn add(table: &mut VariableTable, defaults: &VariantDefaults) -> Self {
        let (pole_re, pole_im) = add_pole_parameters(table, defaults);
        let (u_min, u_max) = add_limit_parameters(table, defaults.preset);
        let sample_period = table.add(clock::parameter());
        Self {
            pole_re,
            pole_im,
            u_min,
            u_max,
            sample_period,
        }
    }

    /// The controller's sample clock ([`Rule::Step`]) from `sample_period`, starting at
    /// `start`.
    pub fn clock(&self, values: &Values, start: f64) -> Result<SampleClock, ClockError> {
        SampleClock::from_parameter(Rule::Step, values, self.sample_period, start)
    }

    /// The desired poles `pole_re[i] + j·pole_im[i]`.
    pub fn poles(&self, values: &Values) -> Vec<Complex<f64>> {
        self.pole_re
            .indices()
            .zip(self.pole_im.indices())
            .map(|(r, i)| Complex::new(values.real(r), values.real(i)))
            .collect()
    }

    /// The input limits `[u_min, u_max]`, checked.
    pub fn limits(&self, values: &Values) -> Result<InputLimits, ParameterError> {
        InputLimits::new(values.real(self.u_min), values.real(self.u_max))
    }
}

/// Adds `pole_re[i]`, `pole_im[i]` with the defaults; returns their blocks.
fn add_pole_parameters(table: &mut VariableTable, defaults: &VariantDefaults) -> (Block, Block) {
    let origin = |i: usize| match defaults.preset {
        Preset::Crane => CRANE_CONTINUOUS_POLES.get(i).map_or(String::new(), |s| {
            format!(
                " (default: z = e^(s·Ts), s = {} {:+}j 1/s, Ts = {CRANE_SAMPLE_TIME} s)",
                s.re, s.im
            )
        }),
        Preset::Generic => String::new(),
    };
    let re = add_vector(table, "pole_re", defaults.states(), |name, i| {
        Variable::parameter(name, defaults.design.poles.get(i).map_or(0.0, |p| p.re)).describe(
            &format!(
                "Real part of desired closed-loop pole {} of A − B·L (discrete time, z-plane){}",
                i + 1,
                origin(i)
            ),
        )
    });
    let im = add_vector(table, "pole_im", defaults.states(), |name, i| {
        Variable::parameter(name, defaults.design.poles.get(i).map_or(0.0, |p| p.im)).describe(
            &format!(
                "Imaginary part of desired closed-loop pole {}: complex poles must come in conjugate pairs",
                i + 1
            ),
        )
    });
    (re, im)
}

/// Adds `u_min`, `u_max`; returns their indices.
fn add_limit_parameters(table: &mut VariableTable, preset: Preset) -> (usize, usize) {
    let unit = input_unit(preset);
    let u_min = table.add(with_unit(
        Variable::parameter("u_min", -DEFAULT_INPUT_LIMIT)
            .describe("Lower actuator limit: u is clipped to [u_min, u_max]"),
        unit,
    ));
    let u_max = table.add(with_unit(
        Variable::parameter("u_max", DEFAULT_INPUT_LIMIT)
            .describe("Upper actuator limit (must be greater than u_min)"),
        unit,
    ));
    (u_min, u_max)
}

/// The FMU parameters a pole-placement error is about, and why.
pub fn design_error_message(error: &PolePlacementError, poles: &[Complex<f64>]) -> String {
    let pole_parameters = |pole: &Complex<f64>| match poles.iter().position(|p| p == pole) {
        Some(i) => format!("parameters `pole_re[{0}]`, `pole_im[{0}]`", i + 1),
        None => "parameters `pole_re`, `pole_im`".to_string(),
    };
    let what = match error {
        PolePlacementError::NotConjugate { pole }
        | PolePlacementError::UnstablePole { pole, .. } => pole_parameters(pole),
        PolePlacementError::NonFinite { what: "poles" }
        | PolePlacementError::WrongPoleCount { .. } => {
            "parameters `pole_re`, `pole_im`".to_string()
        }
        PolePlacementError::NonFinite { what } => format!("parameter `{what}`"),
        PolePlacementError::NotReachable { .. } | PolePlacementError::NonFiniteGain => {
            "parameters `A`, `B`".to_string()
        }
        PolePlacementError::NotSquare { .. }
        | PolePlacementError::DimensionMismatch { .. }
        | PolePlacementError::NotSingleInput { .. } => "parameters `A`, `B`".to_string(),
    };
    format!("pole placement (Ackermann) failed: {what}: {error}")
}

/// Checks the desired poles alone (self-conjugate, finite, inside the unit circle when
/// `require_stable`), naming the offending `pole_re[i]`, `pole_im[i]`.
pub fn check_pole_parameters(poles: &[Complex<f64>], require_stable: bool) -> Result<(), Cause> {
    check_poles(poles, require_stable).map_err(|e| design_error_message(&e, poles).into())
}

/// `[l₁, l₂, …]` with every digit (for log messages).
pub fn format_gain(gain: &DMatrix<f64>) -> String {
    let entries: Vec<String> = gain.iter().map(|v| v.to_string()).collect();
    format!("[{}]", entries.join(", "))
}

/// Rebuilds the layout of an instance's model description (and checks it fits).
pub fn layout_for<L>(
    info: &ModelInfo,
    build: impl Fn(&Config) -> Result<(L, Vec<Variable>), Cause>,
) -> Result<L, Cause> {
    let (layout, variables) = build(&info.config)?;
    if variables.len() != info.variables.len() {
        return Err(format!(
            "{}: the model description has {} variables, the configuration gives {}",
            info.model_identifier,
            info.variables.len(),
            variables.len()
        )
        .into());
    }
    Ok(layout)
}

/// The model description of a controller variant: its variables from `build`, the crane's
/// sample time as the default step.
pub fn describe_controller<L>(
    model_identifier: &str,
    description: &str,
    config: &Config,
    build: impl Fn(&Config) -> Result<(L, Vec<Variable>), Cause>,
) -> Result<ModelInfo, Cause> {
    let (_, variables) = build(config)?;
    Ok(ModelInfo::new(
        model_identifier,
        description,
        variables,
        Some(DefaultExperiment {
            start_time: 0.0,
            stop_time: 10.0,
            step_size: CRANE_SAMPLE_TIME,
        }),
        config.clone(),
    ))
}

/// A controller law behind the sampled-controller FMU skeleton [`SampledController`]: its
/// variables, its design at initialisation, what a sample commits and the outputs it shows.
pub trait ControlLaw: Sized + Clone + std::fmt::Debug + PlainState + 'static {
    /// Where the law's variables are in the table.
    type Layout: Copy + std::fmt::Debug;
    /// The FMU's model identifier.
    const MODEL_IDENTIFIER: &'static str;
    /// The FMU's one-line description.
    const DESCRIPTION: &'static str;
    /// The variable table of a configuration and where each variable is.
    fn build(config: &Config) -> Result<(Self::Layout, Vec<Variable>), Cause>;
    /// The pole, limit and `sample_period` parameters of the layout.
    fn design(layout: &Self::Layout) -> &DesignBlocks;
    /// The law designed from the parameters (at initialisation).
    fn initialize(layout: &Self::Layout, ctx: &mut Context) -> Result<Self, Failure>;
    /// Commits the sample at `time` from the inputs held (and logs what is worth it).
    fn commit(
        &mut self,
        layout: &Self::Layout,
        ctx: &mut Context,
        time: f64,
    ) -> Result<(), Failure>;
    /// Writes the outputs the law shows for the inputs held, without committing anything:
    /// called any number of times, it gives the same outputs.
    fn write_outputs(&mut self, layout: &Self::Layout, ctx: &mut Context);
}

/// The FMU of a sampled [`ControlLaw`] (see the module doc for the sampling): the law is
/// designed at initialisation; each sample instant a step covers is committed in turn, then
/// the outputs are shown for the inputs held; at a sample instant the outputs follow the
/// inputs as they are set (direct feedthrough), between instants they hold.
#[derive(Debug, Clone)]
pub struct SampledController<L: ControlLaw> {
    layout: L::Layout,
    law: Option<L>,
    clock: SampleClock,
}

impl<L: ControlLaw> SampledController<L> {
    /// Where the variables are.
    pub fn layout(&self) -> &L::Layout {
        &self.layout
    }

    /// The law in use (after initialisation).
    pub fn law(&self) -> Option<&L> {
        self.law.as_ref()
    }

    /// Writes the outputs for the inputs held (nothing before initialisation).
    pub fn write_outputs(&mut self, ctx: &mut Context) {
        if let Some(law) = &mut self.law {
            law.write_outputs(&self.layout, ctx);
        }
    }
}

impl<L: ControlLaw> FmuModel for SampledController<L> {
    fn describe(config: &Config) -> Result<ModelInfo, Cause> {
        describe_controller(L::MODEL_IDENTIFIER, L::DESCRIPTION, config, L::build)
    }

    fn create(info: &ModelInfo) -> Result<Self, Cause> {
        Ok(Self {
            layout: layout_for(info, L::build)?,
            law: None,
            clock: SampleClock::new(Rule::Step, 0.0, 0.0)?,
        })
    }

    fn initialize(&mut self, ctx: &mut Context) -> Result<(), Failure> {
        let law = L::initialize(&self.layout, ctx)?;
        self.clock = L::design(&self.layout).clock(ctx.values, ctx.time())?;
        self.law = Some(law);
        self.write_outputs(ctx);
        Ok(())
    }

    fn do_step(&mut self, ctx: &mut Context, time: f64, step: f64) -> Result<(), Failure> {
        let (clock, samples) = self.clock.after(time, step)?;
        if samples.is_empty() {
            // Between samples: nothing is committed and the outputs hold.
            self.clock = clock;
            return Ok(());
        }
        let Some(law) = &mut self.law else {
            return Err(Failure::error("the controller was not initialised"));
        };
        for k in samples {
            law.commit(&self.layout, ctx, clock.instant(k))?;
        }
        self.clock = clock;
        // Outputs at the new communication point, for the inputs still held.
        law.write_outputs(&self.layout, ctx);
        Ok(())
    }

    /// At a sample instant the outputs follow the inputs just set; between samples they hold.
    fn update_outputs(&mut self, ctx: &mut Context) -> Result<(), Failure> {
        if self.clock.due_at(ctx.time()) {
            self.write_outputs(ctx);
        }
        Ok(())
    }

    crate::fmu_state!(law, clock);
}

/// Working memory of a law (buffers filled from the inputs, cached results): not part of the
/// FMU state. It is saved as nothing and read back as `T::default()`, so whatever it cached
/// is recomputed, and its buffers are sized again at their first use.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Scratch<T>(pub T);

impl<T: Default> PlainState for Scratch<T> {
    fn save(&self, _out: &mut Vec<u8>) {}
    fn read(_input: &mut &[u8]) -> Result<Self, StateError> {
        Ok(Self(T::default()))
    }
}

/// Reads a block of Real variables into `out` (row-major), reusing its memory.
pub fn read_block(block: &Block, values: &Values, out: &mut Vec<f64>) {
    out.clear();
    out.extend(block.indices().map(|k| values.real(k)));
}

/// Writes `row` into a block of Real variables (row-major), as far as both go.
pub fn write_block(block: &Block, values: &mut Values, row: &[f64]) {
    for (k, v) in block.indices().zip(row) {
        values.set_real(k, *v);
    }
}
