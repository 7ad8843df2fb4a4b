//! The one generic adapter of the estimator FMUs (docs/estimators.md §2.7–§2.12): dimension-generic
//! Co-Simulation wrappers (FMI 2.0 and 3.0) of [`spurio::estimation`].
//!
//! One compiled binary per algorithm; the dimensions come from the packaging configuration
//! (`resources/variant.cfg`, keys such as `n`, `m`, `p`), so `spurio package-variant
//! KalmanFilter --set n=3 --set m=1 --set p=2` writes an FMU for another plant without
//! recompiling. Every estimator FMU is an [`EstimatorFmu`] over one [`Estimator`]:
//!
//! | FMU | estimator | where |
//! |---|---|---|
//! | `KalmanFilter` | sKF | `spurio-fmu-kalman` (`fmus/kalman/`): `LinearEstimator`, the filter on plain numbers for n = p = 1, else `Filtered` over its `LinearLayout` |
//! | `RobustKalmanFilter` | rsKF (Cipra & Romera 1997) | the same |
//! | `DualKalmanFilter` | DKF (Haykin ch. 5) | `spurio-fmu-kalman`: `Filtered` over its `DualLayout` |
//! | `DkfRsKf` | rsKF cleaning → DKF (paper 001 Fig. 2) | the same |
//! | `RecursiveLeastSquares` | ARX RLS with forgetting (paper 002) | its own crate |
//! | `DistributedObserver` | one agent of paper 004's observer | its own crate |
//!
//! **Sampling convention.** The estimators are discrete-time and sample on the one clock of
//! [`crate::clock`] (parameter `sample_period`, appended to every estimator's variables,
//! [`crate::clock::Rule::Step`]): the step from t to t + h processes the samples whose
//! instants t_k = t_0 + k·T lie in [t, t + h) (relative tolerance 10⁻⁹), each with the inputs
//! set before the step (u_k, y_k), and leaves the estimates of the last in the outputs
//! (x̂_{k|k}, ŷ_k = C x̂_{k|k} + D u_k), readable at t + h. A step holding no instant (shorter
//! than T, or a master's rounding step of 10⁻¹⁵ s) holds the outputs. With the default
//! `sample_period` = 0 (T = the first step's size) a fixed-step master gets one sample per
//! step, processed from the inputs set at its start. The step size does not enter the filters (only the RLS readout uses T as the
//! sampling period when `Ts` = 0).
//!
//! **Errors.** Parameters are read and checked in initialization; a bad one gives
//! `fmi2Error` with the estimator's message, which names the matrix and the reason. A
//! non-finite input gives `fmi2Error` naming the input (`y[2]`), before the filter is touched.
//!
//! **FMU state.** The parameters read at initialization, the estimator's dynamic state and
//! the sample clock are serialized; deserialization rebuilds the estimator from the
//! parameters and restores the dynamic state and the clock, so a restored instance continues
//! bit for bit.

use crate::clock::{self, Rule, SampleClock};
use crate::structured::add_vector;
use crate::structured::Block;
use nalgebra::{DMatrix, DVector};
use spurio::estimation::EstimationError;
use spurio_export::{
    ByteReader, ByteWriter, Causality, Cause, Config, Context, Failure, FmuModel, ModelInfo,
    Values, Variability, Variable, VariableTable,
};

/// The largest dimension a variant may ask for (keeps the variable table and the matrices
/// of a mistyped configuration reasonable).
pub const MAX_DIMENSION: usize = 200;

/// Reads configuration key `key` as a count in `min..=MAX_DIMENSION` (`default` when absent).
pub fn count(config: &Config, key: &str, default: usize, min: usize) -> Result<usize, Cause> {
    let value = match config.get(key) {
        None => default,
        Some(text) => text
            .trim()
            .parse::<usize>()
            .map_err(|_| format!("variant.cfg: `{key}` must be a whole number, got `{text}`"))?,
    };
    if value < min || value > MAX_DIMENSION {
        return Err(format!(
            "variant.cfg: `{key}` must lie in {min}..={MAX_DIMENSION}, got {value}"
        )
        .into());
    }
    Ok(value)
}

/// One estimator algorithm behind an [`EstimatorFmu`].
pub trait Estimator: DynamicState + Clone + std::fmt::Debug + 'static {
    /// Value references of the variables of one variant.
    type Layout: Clone + std::fmt::Debug + 'static;
    /// The variable layout and model description for a configuration.
    fn interface(config: &Config) -> Result<(Self::Layout, ModelInfo), Cause>;
    /// Reads and checks the parameters, builds the estimator.
    fn build(layout: &Self::Layout, values: &Values) -> Result<Self, Failure>;
    /// Writes the outputs (and calculated parameters) before the first step.
    fn write_initial(&self, layout: &Self::Layout, ctx: &mut Context);
    /// One sample at instant `time` of period `step`: reads the inputs, steps, writes the
    /// outputs.
    fn step(
        &mut self,
        layout: &Self::Layout,
        ctx: &mut Context,
        time: f64,
        step: f64,
    ) -> Result<(), Failure>;
}

/// An FMU over an [`Estimator`]: the layout, the parameters the estimator was built from
/// (kept for FMU state serialization), the estimator once initialized and its sample clock.
#[derive(Debug, Clone)]
pub struct EstimatorFmu<E: Estimator> {
    layout: E::Layout,
    /// Value reference of `sample_period` (the last variable).
    sample_period: usize,
    parameters: Values,
    estimator: Option<E>,
    clock: SampleClock,
}

impl<E: Estimator> EstimatorFmu<E> {
    /// The layout, the parameters read at initialization and the estimator, for tests that
    /// swap in another estimator built from the same parameters.
    #[doc(hidden)]
    pub fn parts_mut(&mut self) -> (&E::Layout, &Values, Option<&mut E>) {
        (&self.layout, &self.parameters, self.estimator.as_mut())
    }
}

/// A step before the estimator was built.
#[cold]
#[inline(never)]
fn not_initialized() -> Failure {
    Failure::Error("the estimator was not initialized (fmi2ExitInitializationMode failed?)".into())
}

/// The estimator's interface with the parameter `sample_period` appended (value reference:
/// the number of the estimator's own variables).
fn with_sample_period(info: ModelInfo) -> ModelInfo {
    let mut variables = info.variables;
    variables.push(clock::parameter());
    ModelInfo::new(
        &info.model_identifier,
        &info.description,
        variables,
        info.default_experiment,
        info.config,
    )
}

impl<E: Estimator> FmuModel for EstimatorFmu<E> {
    fn describe(config: &Config) -> Result<ModelInfo, Cause> {
        E::interface(config).map(|(_, info)| with_sample_period(info))
    }

    fn create(info: &ModelInfo) -> Result<Self, Cause> {
        let (layout, own) = E::interface(&info.config)?;
        Ok(Self {
            layout,
            sample_period: own.variables.len(),
            parameters: Values::from_start(&info.variables),
            estimator: None,
            clock: SampleClock::new(Rule::Step, 0.0, 0.0)?,
        })
    }

    fn initialize(&mut self, ctx: &mut Context) -> Result<(), Failure> {
        let start = ctx.time();
        let clock = SampleClock::from_parameter(Rule::Step, ctx.values, self.sample_period, start)?;
        let estimator = E::build(&self.layout, ctx.values)?;
        estimator.write_initial(&self.layout, ctx);
        self.parameters = ctx.values.clone();
        self.estimator = Some(estimator);
        self.clock = clock;
        Ok(())
    }

    /// The samples whose instants lie in the step ([`crate::clock`]), each with the inputs set
    /// before it. (Inlined into the export layer's step: the common step is one sample.)
    #[inline(always)]
    fn do_step(&mut self, ctx: &mut Context, time: f64, step: f64) -> Result<(), Failure> {
        let Some(estimator) = &mut self.estimator else {
            return Err(not_initialized());
        };
        let (clock, samples) = self.clock.after(time, step)?;
        for k in samples {
            estimator.step(&self.layout, ctx, clock.instant(k), clock.period())?;
        }
        self.clock = clock;
        Ok(())
    }

    fn save_state(&self, out: &mut ByteWriter) {
        out.put_u64(self.parameters.len() as u64);
        self.parameters.save(out);
        match &self.estimator {
            Some(estimator) => {
                out.put_bool(true);
                out.put_f64_slice(&estimator.dynamic_state());
            }
            None => out.put_bool(false),
        }
        clock::save(&self.clock, out);
    }

    fn load_state(&mut self, input: &mut ByteReader) -> Result<(), Cause> {
        let count = input.u64()?;
        if count != self.parameters.len() as u64 {
            return Err(format!(
                "estimator state: {count} saved values, the FMU has {}",
                self.parameters.len()
            )
            .into());
        }
        let mut parameters = self.parameters.clone();
        parameters.load(input)?;
        let estimator = if input.bool()? {
            let state = input.f64_vec()?;
            let mut estimator = E::build(&self.layout, &parameters).map_err(|f| match f {
                Failure::Error(m) | Failure::Discard(m) => m,
            })?;
            estimator.set_dynamic_state(&state)?;
            Some(estimator)
        } else {
            None
        };
        let clock = clock::load(input)?;
        self.estimator = estimator;
        self.parameters = parameters;
        self.clock = clock;
        Ok(())
    }
}

/// What evolves in an estimator adapter from step to step, saved in FMU states (for the
/// filters, their [`spurio::estimation::StateEstimator::dynamic_state`]).
pub trait DynamicState {
    /// Everything that evolves.
    fn dynamic_state(&self) -> Vec<f64>;
    /// Restores [`DynamicState::dynamic_state`] into an estimator built from the same
    /// parameters.
    fn set_dynamic_state(&mut self, state: &[f64]) -> Result<(), EstimationError>;
}

/// Copies the inputs of `block` (Real variables) into `buffer` when they are all finite and
/// fit it (`false`, `buffer` unchanged, otherwise): a slice copy, no allocation.
#[inline]
pub fn copy_inputs(values: &Values, block: &Block, buffer: &mut DVector<f64>) -> bool {
    let source = values.numbers().get(block.indices()).unwrap_or(&[]);
    let target = buffer.as_mut_slice();
    // The packaged sizes without the library copy: no input, one input.
    match (source, &mut *target) {
        ([], []) => return true,
        ([v], [slot]) => {
            let finite = v.is_finite();
            if finite {
                *slot = *v;
            }
            return finite;
        }
        _ => {}
    }
    let fits = source.len() == target.len() && source.iter().all(|v| v.is_finite());
    if fits {
        target.copy_from_slice(source);
    }
    fits
}

/// Copies the inputs of `block` into `buffer` (no allocation), or fails naming the first
/// non-finite one (`y[2] = NaN`).
pub fn read_inputs(
    values: &Values,
    block: &Block,
    name: &str,
    buffer: &mut DVector<f64>,
) -> Result<(), Failure> {
    let target = buffer.as_mut_slice();
    for (k, index) in block.indices().enumerate() {
        let v = values.real(index);
        if !v.is_finite() {
            return Err(non_finite_input(name, k + 1, v));
        }
        if let Some(slot) = target.get_mut(k) {
            *slot = v;
        }
    }
    Ok(())
}

/// Adds the Boolean inputs `{measured}_valid[j]`, j = 1…`len` (start true), at the end of
/// the table so that the value references of the variables before them do not change;
/// `{measured}_valid` without index when `len` is 0 (one scalar measurement). Whether the
/// sample of the measurement `{measured}[j]` taken at this step is present: false is a
/// missing sample (docs/estimators.md, "Missing samples"): the estimator predicts for that
/// channel only, whatever the value of `{measured}[j]`.
pub fn add_validity(table: &mut VariableTable, measured: &str, len: usize) -> Block {
    let input = |name: &str| {
        Variable {
        causality: Causality::Input,
        variability: Variability::Discrete,
        initial: None,
        ..Variable::boolean_parameter(name, true).describe(&format!(
            "Whether the sample of {measured} at this step is present (false: a missing sample, the estimator predicts only)"
        ))
    }
    };
    let name = format!("{measured}_valid");
    if len == 0 {
        let first = table.add(input(&name));
        return Block {
            first,
            rows: 1,
            cols: 1,
        };
    }
    add_vector(table, &name, len, |name, _| input(name))
}

/// Marks the missing samples of a step in the measurement buffer: `buffer[j]` = NaN where
/// the Boolean `valid[j]` ([`add_validity`]) is false — the estimators' missing sample. No
/// allocation.
#[inline]
pub fn mark_missing(values: &Values, valid: &Block, buffer: &mut DVector<f64>) {
    let flags = values.numbers().get(valid.indices()).unwrap_or(&[]);
    for (y, flag) in buffer.iter_mut().zip(flags) {
        if *flag == 0.0 {
            *y = f64::NAN;
        }
    }
}

/// The failure of a step whose input `{name}[{k}]` (1-based) is the non-finite `v`.
#[cold]
#[inline(never)]
pub fn non_finite_input(name: &str, k: usize, v: f64) -> Failure {
    Failure::error(format!(
        "input `{name}[{k}]` = {v} is not finite: the estimator cannot use it (the step was not taken)"
    ))
}

/// Writes a vector into a block.
pub fn write_vector(values: &mut Values, block: &Block, v: &DVector<f64>) {
    block.write_vector(values, v);
}

/// Adds an integer-valued choice parameter with the options 1..=`last` (read back with
/// [`choice`]); returns its value reference.
pub fn add_choice(
    table: &mut VariableTable,
    name: &str,
    start: i32,
    last: i32,
    description: &str,
) -> usize {
    table.add(
        Variable::integer_parameter(name, start)
            .min(1.0)
            .max(f64::from(last))
            .describe(description),
    )
}

/// Reads an integer-valued choice parameter, with the allowed values in the message.
pub fn choice(
    values: &Values,
    index: usize,
    name: &str,
    allowed: &[(i32, &str)],
) -> Result<i32, Failure> {
    let v = values.integer(index);
    if allowed.iter().any(|(k, _)| *k == v) {
        Ok(v)
    } else {
        let list: Vec<String> = allowed
            .iter()
            .map(|(k, what)| format!("{k} = {what}"))
            .collect();
        Err(Failure::error(format!(
            "parameter `{name}`: must be one of {}, got {v}",
            list.join(", ")
        )))
    }
}

/// Adds a real tuning parameter that may not be negative (a variance, a weight, a tuning
/// constant): `name`, start value `start`, minimum 0; returns its value reference.
pub fn add_tuning(table: &mut VariableTable, name: &str, start: f64, description: &str) -> usize {
    table.add(
        Variable::parameter(name, start)
            .min(0.0)
            .describe(description),
    )
}

/// Turns an estimation error into `fmi2Error` with its message.
#[cold]
#[inline(never)]
pub fn error(e: spurio::estimation::EstimationError) -> Failure {
    Failure::error(e.to_string())
}

/// Identity-like default for C (p×n): C[j, j] = 1 for j < min(n, p).
pub fn leading_identity(rows: usize, cols: usize) -> DMatrix<f64> {
    DMatrix::from_fn(rows, cols, |i, j| if i == j { 1.0 } else { 0.0 })
}
