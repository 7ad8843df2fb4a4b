//! `PlantEstimator.fmu`: the robust online filter of `spurio identify --method ukf|ekf` on a
//! plant FMU that the estimator FMU carries unpacked in `resources/plant/`, for any FMI tool
//! (docs/estimators.md, "An estimator FMU for any plant FMU"). `spurio package-estimator
//! plant.fmu --free M,l,f_c --input U --output x --output theta --noise x=1e-6,theta=1e-5
//! --name GantryCraneEstimator` writes one; its names, units, starts, variances, method and
//! robust weights are the configuration `resources/variant.cfg`
//! ([`spurio_identify::packaged`]). The library bundles no variant (there is no plant to
//! carry without one).
//!
//! **The filter.** z = [x; θ], the plant's continuous states and the free parameters (random
//! walks); ẑ₀ = [x₀(θ₀); θ₀] with x₀ the plant's initial states at θ₀ and the parameters
//! `set.*`, P₀ and Q as [`spurio_identify::online::joint_filter`] sets them (the same code
//! as `spurio identify`), R = diag(`noise.*`); between samples the plant is integrated with
//! the inputs of the earlier sample held, at the relative tolerance of the configuration.
//!
//! **Sampling** ([`spurio_fmu_common::clock`], [`Rule::Step`]): the step from t to t + h
//! processes the samples whose instants t_k = t₀ + k·T lie in [t, t + h), each with the
//! inputs `u.*`, `y.*` set before the step (`y.<name>.valid` false: a missing sample, not
//! corrected on), and shows the outputs of the last at t + h:
//!
//! ```text
//! x_hat.<state>, theta_hat.<parameter>   ẑ_{k|k}
//! sd.<state>, sd.<parameter>             √diag P_{k|k}
//! innovation.<y>, innovation_sd.<y>      e_k = y_k − ŷ_k, √S_jj (0 at a missing sample)
//! weight.<y>                             the robust weight w_j (0 at a missing sample)
//! ```
//!
//! Sample k is processed at t_k with u(t_k), y(t_k): on a record sampled every T from t₀
//! the FMU gives `spurio identify`'s trajectory row by row.
//!
//! **Errors.** A missing or garbled plant, or a plant whose names do not match the
//! configuration, fails instantiation with a message naming the file; a non-finite input
//! or a filter failure is `fmi2Error` naming what. A call the plant refuses is an error that
//! quotes what the plant logged (its messages are kept, not printed:
//! [`spurio_identify::plant::keep_plant_messages`]).
//!
//! **FMU state.** `fmi2GetFMUstate`/`fmi2SetFMUstate` take and restore the filter (its
//! clone shares the plant instance, which every propagation places at the states and
//! parameters it is given). A serialized state holds the start time and the parameters the
//! filter was built from (`theta0.*`, `noise.*`, `set.*`), the filter's
//! [`FilterState`] (ẑ, P, the time and held inputs of its last sample, the samples taken),
//! the outputs of the last sample and the sample clock; deserialization builds the filter
//! again from the parameters (on the instance's plant, or one opened afresh) and restores
//! the rest, so the restored instance, this one or a fresh one, continues bit for bit. A
//! state of another configuration (its parameter count) or truncated is refused naming why.

use spurio_export::{
    ByteReader, ByteWriter, Causality, Cause, Config, Context, Failure, FmuModel, ModelInfo,
    Variability, Variable,
};
use spurio_fmu_common::clock::{self, Rule, SampleClock};
use spurio_identify::estimator::Estimator;
use spurio_identify::filter::FilterState;
use spurio_identify::online::joint_filter;
use spurio_identify::packaged::{EstimatorDeclaration, Free, Measured, Named};
use spurio_identify::plant::{integration, FmuPlant};
use std::cell::RefCell;
use std::ops::Range;
use std::path::{Path, PathBuf};
use std::rc::Rc;

/// The model identifier.
pub const MODEL_IDENTIFIER: &str = "PlantEstimator";

/// The folder of the unpacked plant inside `resources/`.
pub const PLANT_FOLDER: &str = "plant";

/// The declaration of `config`; an empty configuration (the library itself) has none.
pub fn declaration(config: &Config) -> Result<EstimatorDeclaration, Cause> {
    if config.is_empty() {
        return Err(format!(
            "{MODEL_IDENTIFIER} has no plant of its own: package one with `spurio package-estimator plant.fmu …`"
        )
        .into());
    }
    EstimatorDeclaration::from_entries(|key| config.get(key))
        .map_err(|e| format!("variant.cfg: {e}").into())
}

/// The blocks of variables, in the order of the table: `u.<input>`, `y.<output>`,
/// `y.<output>.valid`, `theta0.<parameter>`, `noise.<output>`, `set.<name>`, the outputs (in
/// the estimator's order [ẑ; √diag P; e; √S; w]); `sample_period` last.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Block {
    Inputs,
    Measured,
    Valid,
    Starts,
    Noise,
    Set,
    Outputs,
}

/// The value references of one variant: the size of each [`Block`], in table order.
#[derive(Debug, Clone, PartialEq)]
pub struct Layout {
    sizes: [usize; 7],
}

impl Layout {
    /// The layout of a declaration: m inputs, p measurements, q free parameters, L = n + q.
    pub fn of(d: &EstimatorDeclaration) -> Self {
        let (m, p, q) = (d.inputs.len(), d.outputs.len(), d.free.len());
        let l = d.states.len() + q;
        Self {
            sizes: [m, p, p, q, p, d.set.len(), 2 * l + 3 * p],
        }
    }

    /// The value references of `block`.
    pub fn block(&self, block: Block) -> Range<usize> {
        let i = block as usize;
        let first: usize = self.sizes[..i].iter().sum();
        first..first + self.sizes[i]
    }

    /// The value reference of `sample_period`, after every block.
    pub fn sample_period(&self) -> usize {
        self.sizes.iter().sum()
    }
}

/// A variable's unit when the plant declares one.
fn with_unit(variable: Variable, unit: &Option<String>) -> Variable {
    match unit {
        Some(unit) => variable.unit(unit),
        None => variable,
    }
}

/// A Real input, discrete (sampled).
fn sampled_input(name: &str, unit: &Option<String>, description: &str) -> Variable {
    with_unit(
        Variable {
            variability: Variability::Discrete,
            ..Variable::input(name, 0.0)
        },
        unit,
    )
    .describe(description)
}

/// The variables of a declaration, in the order of its [`Layout`] (module documentation).
pub fn variables(d: &EstimatorDeclaration) -> Vec<Variable> {
    let plant = &d.plant;
    let measured: Vec<&Named> = d.outputs.iter().map(|m| &m.variable).collect();
    let mut v: Vec<Variable> = Vec::new();
    for n in &d.inputs {
        let what = format!(
            "Input `{}` of the plant {plant}, sampled at each instant",
            n.name
        );
        v.push(sampled_input(&format!("u.{}", n.name), &n.unit, &what));
    }
    for n in &measured {
        let what = format!("Measurement of `{}` of the plant {plant}", n.name);
        v.push(sampled_input(&format!("y.{}", n.name), &n.unit, &what));
    }
    v.extend(measured.iter().map(|n| Variable {
        causality: Causality::Input,
        variability: Variability::Discrete,
        initial: None,
        ..Variable::boolean_parameter(&format!("y.{}.valid", n.name), true).describe(&format!(
            "Whether the sample of y.{} is present (false: a missing sample, not corrected on)",
            n.name
        ))
    }));
    v.extend(d.free.iter().map(
        |Free {
             parameter: n,
             start,
         }| {
            with_unit(
                Variable::parameter(&format!("theta0.{}", n.name), *start),
                &n.unit,
            )
            .describe(&format!(
                "Start value θ₀ of the estimated parameter `{}` (prior σ = 20 % of |θ₀|)",
                n.name
            ))
        },
    ));
    v.extend(d.outputs.iter().map(|Measured { variable: n, noise }| {
        Variable::parameter(&format!("noise.{}", n.name), *noise)
            .min(0.0)
            .describe(&format!(
                "Measurement noise variance R of y.{} (> 0)",
                n.name
            ))
    }));
    v.extend(d.set.iter().map(|(name, value)| {
        Variable::parameter(&format!("set.{name}"), *value).describe(&format!(
            "Parameter `{name}` of the plant, set for the experiment (not estimated)"
        ))
    }));
    // The outputs: ẑ and √diag P over z = [x; θ], then e, √S and w per measurement.
    let estimated: Vec<(&Named, &str, &str)> = (d.states.iter().map(|n| (n, "x_hat", "state")))
        .chain(
            d.free
                .iter()
                .map(|f| (&f.parameter, "theta_hat", "parameter")),
        )
        .collect();
    let output = |name: String, unit: &Option<String>, description: String| {
        with_unit(Variable::discrete_output(&name), unit).describe(&description)
    };
    for (n, prefix, kind) in &estimated {
        let what = format!(
            "Estimate of the {kind} `{}` of the plant after the last sample",
            n.name
        );
        v.push(output(format!("{prefix}.{}", n.name), &n.unit, what));
    }
    for (n, _, kind) in &estimated {
        let what = format!(
            "Standard deviation of the estimate of the {kind} `{}`",
            n.name
        );
        v.push(output(format!("sd.{}", n.name), &n.unit, what));
    }
    let per_measurement = [
        (
            "innovation",
            true,
            "Innovation y − ŷ of `{}` at the last sample (0 when missing)",
        ),
        (
            "innovation_sd",
            true,
            "Standard deviation √S of the innovation of `{}` (0 when missing)",
        ),
        (
            "weight",
            false,
            "Robust weight of the measurement of `{}` (0 when missing)",
        ),
    ];
    for (prefix, has_unit, what) in per_measurement {
        for n in &measured {
            let unit = if has_unit { n.unit.clone() } else { None };
            v.push(output(
                format!("{prefix}.{}", n.name),
                &unit,
                what.replace("{}", &n.name),
            ));
        }
    }
    v.push(clock::parameter());
    v
}

/// The estimator FMU: its declaration, the plant opened from `resources/plant/`, the filter
/// once initialised, its clock and the buffers of one sample.
#[derive(Debug, Clone)]
pub struct PlantEstimatorFmu {
    declared: Rc<EstimatorDeclaration>,
    layout: Layout,
    /// `resources/plant/`.
    plant_dir: PathBuf,
    /// The plant opened at instantiation (start time 0), used by the first initialisation.
    opened: Option<Rc<RefCell<FmuPlant>>>,
    estimator: Option<Estimator>,
    clock: SampleClock,
    /// The start time and the parameters ([`PlantEstimatorFmu::parameters`]) the estimator
    /// was built from, saved with an FMU state to build it again.
    start: f64,
    parameters: Vec<f64>,
    u: Vec<f64>,
    y: Vec<f64>,
}

/// The plant of `declared` in `dir`, opened for integrations from `start`, checked against
/// the declaration (its state count).
fn open_plant(dir: &Path, declared: &EstimatorDeclaration, start: f64) -> Result<FmuPlant, Cause> {
    let spec = declared.plant_spec();
    let plant =
        FmuPlant::open(dir, &spec, integration(start, declared.tolerance)).map_err(|e| {
            format!(
                "the plant resources/{PLANT_FOLDER} ({}): {e}",
                declared.plant
            )
        })?;
    if plant.states() != declared.states.len() {
        return Err(format!(
            "the plant resources/{PLANT_FOLDER} ({}) has {} continuous states, the configuration declares {}: it was packaged from another plant",
            declared.plant,
            plant.states(),
            declared.states.len()
        )
        .into());
    }
    Ok(plant)
}

/// An error of the model as `fmi2Error`.
fn failed(e: impl std::fmt::Display) -> Failure {
    Failure::error(e.to_string())
}

impl PlantEstimatorFmu {
    /// The number of filter states L = n + q.
    fn filter_states(&self) -> usize {
        self.declared.states.len() + self.declared.free.len()
    }

    /// The value references of the parameters the filter is built from, in table order: θ₀
    /// (`theta0.*`), R (`noise.*`), then the plant's `set.*`.
    fn parameters(&self) -> Range<usize> {
        self.layout.block(Block::Starts).start..self.layout.block(Block::Set).end
    }

    /// The estimator from `start` with `parameters` ([`Self::parameters`]): the plant set and
    /// the joint filter at ẑ₀, P₀ as `spurio identify` sets them up. The plant is the one
    /// opened at instantiation for the first build from t = 0, the estimator's own when the
    /// build restores a `state` of it at the same start and parameters (an FMU state of this
    /// instance: the plant is already set), else one opened afresh.
    fn build(
        &mut self,
        start: f64,
        parameters: &[f64],
        restoring: Option<&FilterState>,
    ) -> Result<Estimator, Failure> {
        let d = Rc::clone(&self.declared);
        let same = restoring.is_some() && start == self.start && parameters == self.parameters;
        let plant = match (self.opened.take(), &self.estimator) {
            (_, Some(estimator)) if same => estimator.filter().plant(),
            (Some(plant), _) if start == 0.0 => plant,
            _ => Rc::new(RefCell::new(
                open_plant(&self.plant_dir, &d, start).map_err(Failure::Error)?,
            )),
        };
        let (q, p) = (d.free.len(), d.outputs.len());
        let (starts, rest) = parameters.split_at(q);
        let (noise, set) = rest.split_at(p);
        if let Some(j) = noise.iter().position(|r| !(r.is_finite() && *r > 0.0)) {
            return Err(Failure::error(format!(
                "parameter `noise.{}` = {}: a measurement variance must be finite and > 0",
                d.outputs[j].variable.name, noise[j]
            )));
        }
        let set: Vec<(String, f64)> = (d.set.iter().zip(set))
            .map(|((name, _), value)| (name.clone(), *value))
            .collect();
        let x0 = {
            let mut p = plant.borrow_mut();
            p.set_values(&set).map_err(failed)?;
            p.initial_states(starts).map_err(failed)?
        };
        let filter = joint_filter(
            &plant,
            starts,
            &x0,
            noise,
            d.robust.influence(),
            d.method.linearisation(),
        )
        .map_err(failed)?;
        Ok(Estimator::new(filter, d.inputs.len()))
    }

    /// The estimator of a serialized state (its part after the flag "initialised"): built
    /// from `start` and `parameters` ([`Self::build`]), its [`FilterState`] and last outputs
    /// restored.
    fn restored(
        &mut self,
        input: &mut ByteReader,
        start: f64,
        parameters: &[f64],
    ) -> Result<Estimator, Cause> {
        let estimate = input.f64_vec()?;
        let covariance = input.f64_vec()?;
        let has_last = input.bool()?;
        let (last, held) = (input.f64()?, input.f64_vec()?);
        let state = FilterState {
            estimate,
            covariance,
            last: has_last.then_some((last, held)),
            samples: usize::try_from(input.u64()?)?,
        };
        let outputs = input.f64_vec()?;
        let name = self.declared.name.clone();
        let mut estimator = (self.build(start, parameters, Some(&state)))
            .map_err(|f| format!("{name}: serialized state: {}", f.cause()))?;
        estimator
            .restore(&state, &outputs)
            .map_err(|e| format!("{name}: serialized state: {e}"))?;
        Ok(estimator)
    }

    /// Reads the sample's inputs into the buffers: u, and y with NaN where not valid; a
    /// non-finite input is an error naming it.
    fn read_sample(&mut self, ctx: &Context) -> Result<(), Failure> {
        let values = &ctx.values;
        for (k, vr) in self.layout.block(Block::Inputs).enumerate() {
            let v = values.real(vr);
            if !v.is_finite() {
                return Err(non_finite(&self.declared.inputs[k].name, "u", v));
            }
            self.u[k] = v;
        }
        let valid = self.layout.block(Block::Valid);
        for (j, vr) in self.layout.block(Block::Measured).enumerate() {
            let present = values.boolean(valid.start + j);
            let v = values.real(vr);
            if present && !v.is_finite() {
                return Err(non_finite(&self.declared.outputs[j].variable.name, "y", v));
            }
            self.y[j] = if present { v } else { f64::NAN };
        }
        Ok(())
    }
}

/// The failure of a non-finite input `{prefix}.{name}`.
#[cold]
fn non_finite(name: &str, prefix: &str, v: f64) -> Failure {
    Failure::error(format!(
        "input `{prefix}.{name}` = {v} is not finite (a missing measurement is `y.<name>.valid` = false); the step was not taken"
    ))
}

impl FmuModel for PlantEstimatorFmu {
    fn describe(config: &Config) -> Result<ModelInfo, Cause> {
        let d = declaration(config)?;
        let variables = variables(&d);
        let description = format!(
            "Robust {} ({} weights) of the states and the parameters {} of the plant {} (carried in resources/{PLANT_FOLDER}), as `spurio identify --method {}`",
            match d.method {
                spurio_identify::online::Method::Ekf => "extended Kalman filter",
                _ => "unscented Kalman filter",
            },
            d.robust.name(),
            (d.free.iter())
                .map(|f| f.parameter.name.as_str())
                .collect::<Vec<_>>()
                .join(", "),
            d.plant,
            d.method.name()
        );
        Ok(ModelInfo::new(
            MODEL_IDENTIFIER,
            &description,
            variables,
            None,
            config.clone(),
        )
        .with_model_name(&d.name))
    }

    fn create(info: &ModelInfo) -> Result<Self, Cause> {
        Self::create_with_resources(info, None)
    }

    fn create_with_resources(info: &ModelInfo, resources: Option<&Path>) -> Result<Self, Cause> {
        let declared = declaration(&info.config)?;
        let layout = Layout::of(&declared);
        let Some(resources) = resources else {
            return Err(format!(
                "the plant resources/{PLANT_FOLDER} cannot be opened: no resource location is given"
            )
            .into());
        };
        // A plant's refusal (its fmi2Error and the message it logs) reaches this FMU's log.
        spurio_identify::plant::keep_plant_messages();
        let plant_dir = resources.join(PLANT_FOLDER);
        let plant = open_plant(&plant_dir, &declared, 0.0)?;
        Ok(Self {
            u: vec![0.0; declared.inputs.len()],
            y: vec![0.0; declared.outputs.len()],
            declared: Rc::new(declared),
            layout,
            plant_dir,
            opened: Some(Rc::new(RefCell::new(plant))),
            estimator: None,
            clock: SampleClock::new(Rule::Step, 0.0, 0.0)?,
            start: 0.0,
            parameters: Vec::new(),
        })
    }

    fn initialize(&mut self, ctx: &mut Context) -> Result<(), Failure> {
        let start = ctx.time();
        let clock = SampleClock::from_parameter(
            Rule::Step,
            ctx.values,
            self.layout.sample_period(),
            start,
        )?;
        let values = &ctx.values;
        let parameters: Vec<f64> = self.parameters().map(|vr| values.real(vr)).collect();
        let estimator = self.build(start, &parameters, None)?;
        // Before the first sample: ẑ₀, √diag P₀; no innovation yet.
        let l = self.filter_states();
        let outputs = self.layout.block(Block::Outputs);
        let first = outputs.start;
        let (z, p) = (
            estimator.filter().estimate(),
            estimator.filter().covariance(),
        );
        for i in 0..l {
            ctx.values.set_real(first + i, z[i]);
            ctx.values
                .set_real(first + l + i, p[(i, i)].max(0.0).sqrt());
        }
        for vr in first + 2 * l..outputs.end {
            ctx.values.set_real(vr, 0.0);
        }
        self.estimator = Some(estimator);
        self.clock = clock;
        self.start = start;
        self.parameters = parameters;
        Ok(())
    }

    fn do_step(&mut self, ctx: &mut Context, time: f64, step: f64) -> Result<(), Failure> {
        let (clock, samples) = self.clock.after(time, step)?;
        // The inputs are read once, for every sample the step takes (none: outputs hold).
        if !samples.is_empty() {
            self.read_sample(ctx)?;
        }
        let outputs = self.layout.block(Block::Outputs);
        for k in samples {
            let estimator = self.estimator.as_mut().ok_or_else(|| {
                Failure::error(
                    "the estimator was not initialized (fmi2ExitInitializationMode failed?)",
                )
            })?;
            let column = estimator
                .step(clock.instant(k), &self.u, &self.y)
                .map_err(failed)?;
            let target = ctx.values.reals_mut(outputs.clone());
            let target = target.filter(|t| t.len() == column.len()).ok_or_else(|| {
                Failure::error(format!(
                    "the estimator gives {} outputs, the FMU declares {}",
                    column.len(),
                    outputs.len()
                ))
            })?;
            target.copy_from_slice(column);
        }
        self.clock = clock;
        Ok(())
    }

    fn save_state(&self, out: &mut ByteWriter) {
        out.put_f64(self.start);
        out.put_f64_slice(&self.parameters);
        match &self.estimator {
            Some(estimator) => {
                let state = estimator.filter().state();
                out.put_bool(true);
                out.put_f64_slice(&state.estimate);
                out.put_f64_slice(&state.covariance);
                out.put_bool(state.last.is_some());
                let (last, held) = state.last.unwrap_or_default();
                out.put_f64(last);
                out.put_f64_slice(&held);
                out.put_u64(state.samples as u64);
                out.put_f64_slice(estimator.last_outputs());
            }
            None => out.put_bool(false),
        }
        clock::save(&self.clock, out);
    }

    fn load_state(&mut self, input: &mut ByteReader) -> Result<(), Cause> {
        let start = input.f64()?;
        let parameters = input.f64_vec()?;
        let expected = self.parameters().len();
        if parameters.len() != expected || !start.is_finite() {
            return Err(format!(
                "{}: a serialized state of {} parameters from t = {start}; this estimator has {expected} (θ₀, noise, set): it is another configuration's",
                self.declared.name,
                parameters.len()
            )
            .into());
        }
        let estimator = match input.bool()? {
            true => Some(self.restored(input, start, &parameters)?),
            false => None,
        };
        (self.estimator, self.clock) = (estimator, clock::load(input)?);
        (self.start, self.parameters) = (start, parameters);
        Ok(())
    }
}

spurio_export::export_fmu!(PlantEstimatorFmu);

#[cfg(test)]
mod tests;
