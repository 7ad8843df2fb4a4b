//! `KalmanFilter.fmu` (sKF, docs/estimators.md §2.7; paper 000 §IV, 001 §2) and
//! `RobustKalmanFilter.fmu` (rsKF, docs/estimators.md §2.8; Cipra & Romera 1997, papers 000 §V, 001 §2).
//!
//! Model x_{k+1} = A x_k + B u_k + w_k, y_k = C x_k + D u_k + v_k, Cov w = Q, Cov v = R. One
//! `fmi2DoStep` with inputs u_k, y_k:
//!
//! ```text
//! x⁻ = A x̂_{k−1} + B u_{k−1},  P⁻ = A P Aᵀ + Q
//! e  = y_k − C x⁻ − D u_k                          (output `innovation`)
//! sKF:  K = P⁻Cᵀ(C P⁻ Cᵀ + R)⁻¹
//! rsKF: r = R^{-1/2} e, w_j = ψ(r_j)/r_j,  K = P⁻Cᵀ(C P⁻ Cᵀ + R^{1/2} W⁻¹ R^{1/2ᵀ})⁻¹
//! x̂_k = x⁻ + K e,  P = (I − K C) P⁻ (Joseph form)
//! ŷ_k = C x̂_k + D u_k                              (output `y_hat`)
//! ```
//!
//! Missing samples (docs/estimators.md, "Missing samples"): `y_valid[j]` = false hands the
//! filter y_j = NaN: the correction with the present channels only, e_j = 0 (rsKF: w_j = 0),
//! `y[j]` ignored.
//!
//! Configuration: `n` (states, ≥ 1, default 1), `m` (inputs, may be 0, default 0), `p`
//! (outputs, ≥ 1, default 1). The defaults of the parameters (A = I, C = [I 0], Q = R = 1e-4 I,
//! x̂₀ = 0, P₀ = 0) are the cosine experiment of docs/experiments.md §4 for n = p = 1.

use crate::filtered::{FilterFamily, Filtered, SignalBlocks, Signals};
use crate::model::{
    add_estimates, add_influence, add_inputs, model_info, read_influence, Defaults, Dimensions,
    ModelBlocks,
};
use nalgebra::DVector;
use spurio::estimation::{
    EstimationError, GaussianModel, InfluenceFunction, KalmanFilter, RobustKalmanFilter,
    ScalarKalmanFilter, ScalarRobustKalmanFilter, StateEstimator,
};
use spurio_export::{Cause, Config, Context, Failure, ModelInfo, Values, Variable, VariableTable};
use spurio_fmu_common::estimator::{
    add_validity, error, non_finite_input, DynamicState, Estimator, EstimatorFmu,
};
use spurio_fmu_common::structured::{add_vector, Block};

/// Value references of a `KalmanFilter` / `RobustKalmanFilter` variant.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct LinearLayout {
    pub signals: SignalBlocks,
    pub innovation: Block,
    /// rsKF only: the weights w_j.
    pub w: Option<Block>,
    pub model: ModelBlocks,
    /// rsKF only: value references of `psi` (Integer) and `c` (Real).
    pub psi: Option<(usize, usize)>,
}

impl Signals for LinearLayout {
    fn signals(&self) -> &SignalBlocks {
        &self.signals
    }
}

fn interface(config: &Config, robust: bool) -> Result<(LinearLayout, ModelInfo), Cause> {
    let dims = Dimensions::from_config(config, 1, 0, 1)?;
    let mut t = VariableTable::new();
    let (u, y) = add_inputs(
        &mut t,
        dims,
        "Measured output y_k (sampled at the start of the step)",
    );
    let (x_hat, y_hat) = add_estimates(&mut t, dims);
    let innovation = add_vector(&mut t, "innovation", dims.p, |name, _| {
        Variable::discrete_output(name).describe("Innovation e_k = y_k − C x⁻ − D u_k")
    });
    let w = robust.then(|| {
        add_vector(&mut t, "w", dims.p, |name, _| {
            Variable::discrete_output(name).describe(
                "Robust weight w_j = ψ(r_j)/r_j of the last sample (1 = trusted, → 0 = outlier)",
            )
        })
    });
    let model = ModelBlocks::add(
        &mut t,
        dims,
        Defaults {
            q: 1e-4,
            r: 1e-4,
            p0: 0.0,
        },
        "",
    );
    let psi = robust.then(|| add_influence(&mut t));
    let (id, description) = if robust {
        (
            "RobustKalmanFilter",
            "Robust-statistics Kalman filter (rsKF, Cipra & Romera 1997): Huber/Tukey M-estimator gain, papers 000/001",
        )
    } else {
        (
            "KalmanFilter",
            "Standard Kalman filter (sKF), papers 000/001",
        )
    };
    let y_valid = add_validity(&mut t, "y", dims.p);
    let info = model_info(config, (id, description), t, 1.0, 1e-3);
    Ok((
        LinearLayout {
            signals: SignalBlocks {
                dims,
                u,
                y,
                y_valid,
                x_hat,
                y_hat,
            },
            innovation,
            w,
            model,
            psi,
        },
        info,
    ))
}

/// Writes x̂ = x0, ŷ = C x0 + D u, e = 0, w = 1 before the first step.
fn write_initial_linear(layout: &LinearLayout, ctx: &mut Context) {
    let m = layout.model.read(ctx.values);
    let u = layout.signals.u.vector(ctx.values);
    let y_hat = &m.system.c * &m.x0 + &m.system.d * &u;
    layout.signals.x_hat.write_vector(ctx.values, &m.x0);
    layout.signals.y_hat.write_vector(ctx.values, &y_hat);
    for k in layout.innovation.indices() {
        ctx.values.set_real(k, 0.0);
    }
    if let Some(w) = &layout.w {
        for k in w.indices() {
            ctx.values.set_real(k, 1.0);
        }
    }
}

/// A filter of the linear model behind a `KalmanFilter`-style FMU, built from the model
/// matrices (and, for the robust one, its influence function).
pub trait LinearFilter: StateEstimator + Clone + std::fmt::Debug + 'static {
    /// Whether the FMU is the robust one: parameters `psi`, `c_psi`, outputs `w[j]`.
    const ROBUST: bool;
    /// The same filter on plain numbers, for one state, one output and at most one input.
    type Scalar: ScalarFilter;
    /// The filter for the model `m`.
    fn from_model(m: GaussianModel, psi: InfluenceFunction) -> Result<Self, EstimationError>;
    /// The last step's weights `w_j` (robust filter only).
    fn weights(&self) -> Option<&DVector<f64>> {
        None
    }
    /// [`LinearFilter::Scalar`] when the filter has those sizes.
    fn to_scalar(&self) -> Option<Self::Scalar>;
}

impl LinearFilter for KalmanFilter {
    const ROBUST: bool = false;
    type Scalar = ScalarKalmanFilter;
    fn from_model(m: GaussianModel, _: InfluenceFunction) -> Result<Self, EstimationError> {
        KalmanFilter::new(m)
    }
    fn to_scalar(&self) -> Option<ScalarKalmanFilter> {
        KalmanFilter::to_scalar(self)
    }
}

impl LinearFilter for RobustKalmanFilter {
    const ROBUST: bool = true;
    type Scalar = ScalarRobustKalmanFilter;
    fn from_model(m: GaussianModel, psi: InfluenceFunction) -> Result<Self, EstimationError> {
        RobustKalmanFilter::new(m, psi)
    }
    fn weights(&self) -> Option<&DVector<f64>> {
        Some(RobustKalmanFilter::weights(self))
    }
    fn to_scalar(&self) -> Option<ScalarRobustKalmanFilter> {
        RobustKalmanFilter::to_scalar(self)
    }
}

/// A filter with one state, one output and at most one input on plain numbers
/// ([`LinearFilter::Scalar`]): one step, its outputs written.
pub trait ScalarFilter: Clone + std::fmt::Debug + 'static {
    /// One sample (u_k, y_k) (u_k unused without input).
    fn step(&mut self, u: f64, y: f64) -> Result<(), EstimationError>;
    /// How many outputs [`ScalarFilter::write_outputs`] writes.
    const OUTPUTS: usize;
    /// Writes `x_hat[1]`, `y_hat[1]`, `innovation[1]` (and the robust filter's `w[1]`), the
    /// Reals declared one after the other from `first` (checked when the estimator was
    /// built: [`Values::are_reals`]).
    fn write_outputs(&self, values: &mut Values, first: usize);
    /// [`StateEstimator::dynamic_state`] of the filter.
    fn dynamic_state(&self) -> Vec<f64>;
    /// Restores [`ScalarFilter::dynamic_state`].
    fn set_dynamic_state(&mut self, state: &[f64]) -> Result<(), EstimationError>;
}

/// Implements [`ScalarFilter`] for a scalar filter of the math crate (its own `step`,
/// `dynamic_state`, `set_dynamic_state`), whose outputs, in declaration order, are
/// `$outputs` of the filter `$f`.
macro_rules! scalar_filter {
    ($filter:ty, $n:literal, |$f:ident| $outputs:expr) => {
        impl ScalarFilter for $filter {
            const OUTPUTS: usize = $n;
            #[inline(always)]
            fn step(&mut self, u: f64, y: f64) -> Result<(), EstimationError> {
                <$filter>::step(self, u, y)
            }
            #[inline(always)]
            fn write_outputs(&self, values: &mut Values, first: usize) {
                let $f = self;
                values.put_reals::<$n>(first, $outputs);
            }
            fn dynamic_state(&self) -> Vec<f64> {
                <$filter>::dynamic_state(self)
            }
            fn set_dynamic_state(&mut self, state: &[f64]) -> Result<(), EstimationError> {
                <$filter>::set_dynamic_state(self, state)
            }
        }
    };
}

scalar_filter!(ScalarKalmanFilter, 3, |f| [
    f.state(),
    f.output(),
    f.innovation()
]);
scalar_filter!(ScalarRobustKalmanFilter, 4, |r| {
    let f = r.filter();
    [f.state(), f.output(), f.innovation(), r.weight()]
});

/// The scalar variant's filter and where its values are: the inputs `u[1]` (if any) and
/// `y[1]`, the first of its outputs.
#[derive(Debug, Clone)]
pub struct Scalar<S: ScalarFilter> {
    filter: S,
    u: Option<usize>,
    y: usize,
    /// `y_valid[1]`.
    valid: usize,
    outputs: usize,
}

impl<S: ScalarFilter> Scalar<S> {
    /// The step: the inputs read (Reals, checked when the estimator was built; a non-finite
    /// one is an error naming it, the filter untouched), the filter stepped, the outputs
    /// written. `y_valid[1]` false makes y a NaN (a select, no branch): the filter's one
    /// check of its innovation finds it and predicts only, out of line.
    #[inline(always)]
    fn step(&mut self, values: &mut Values) -> Result<(), Failure> {
        let numbers = values.numbers();
        let y = numbers.get(self.y).copied().unwrap_or(f64::NAN);
        let u = self
            .u
            .map_or(0.0, |u| numbers.get(u).copied().unwrap_or(f64::NAN));
        // one compare for both: x·0 is ±0 for a finite x and NaN otherwise
        if y * 0.0 + u * 0.0 != 0.0 {
            let (name, v) = if u.is_finite() { ("y", y) } else { ("u", u) };
            return Err(non_finite_input(name, 1, v));
        }
        // `y_valid[1]` false: a missing sample (NaN), the filter predicts only.
        let y = match numbers.get(self.valid) {
            Some(0.0) => f64::NAN,
            _ => y,
        };
        self.filter.step(u, y).map_err(error)?;
        self.filter.write_outputs(values, self.outputs);
        Ok(())
    }
}

/// The estimator of the `KalmanFilter`-style FMUs: the filter on plain numbers for the
/// scalar variants (one state, one output, at most one input: the packaged `KalmanFilter`
/// and `RobustKalmanFilter`), the general one otherwise. Both give the same numbers bit for
/// bit and the same FMU state.
#[derive(Debug, Clone)]
pub enum LinearEstimator<F: LinearFilter> {
    /// One state, one output, at most one input.
    Scalar(Scalar<F::Scalar>),
    /// Any sizes.
    General(Filtered<LinearLayout, F>),
}

impl<F: LinearFilter> Estimator for LinearEstimator<F> {
    type Layout = LinearLayout;
    fn interface(config: &Config) -> Result<(LinearLayout, ModelInfo), Cause> {
        interface(config, F::ROBUST)
    }

    fn build(layout: &LinearLayout, values: &Values) -> Result<Self, Failure> {
        let general = Filtered::<LinearLayout, F>::build(layout, values)?;
        let l = layout;
        // The outputs one after the other: x_hat[1], y_hat[1], innovation[1] (, w[1]).
        let first = l.signals.x_hat.first;
        let consecutive = l.signals.y_hat.first == first + 1
            && l.innovation.first == first + 2
            && l.w.as_ref().is_none_or(|w| w.first == first + 3);
        let scalar = match (
            general.filter().to_scalar(),
            l.signals.u.indices().len(),
            consecutive,
        ) {
            (Some(filter), m @ (0 | 1), true)
                if l.signals.y.indices().len() == 1
                    && values.are_reals(l.signals.y.first, 1)
                    && (m == 0 || values.are_reals(l.signals.u.first, 1))
                    && values.are_reals(first, F::Scalar::OUTPUTS) =>
            {
                Scalar {
                    filter,
                    u: (m == 1).then_some(l.signals.u.first),
                    y: l.signals.y.first,
                    valid: l.signals.y_valid.first,
                    outputs: first,
                }
            }
            _ => return Ok(Self::General(general)),
        };
        Ok(Self::Scalar(scalar))
    }

    fn write_initial(&self, layout: &LinearLayout, ctx: &mut Context) {
        write_initial_linear(layout, ctx);
    }

    #[inline(always)]
    fn step(&mut self, l: &LinearLayout, ctx: &mut Context, t: f64, h: f64) -> Result<(), Failure> {
        match self {
            Self::Scalar(scalar) => scalar.step(ctx.values),
            Self::General(general) => general.step(l, ctx, t, h),
        }
    }
}

impl<F: LinearFilter> DynamicState for LinearEstimator<F> {
    fn dynamic_state(&self) -> Vec<f64> {
        match self {
            Self::Scalar(s) => s.filter.dynamic_state(),
            Self::General(g) => g.dynamic_state(),
        }
    }
    fn set_dynamic_state(&mut self, state: &[f64]) -> Result<(), EstimationError> {
        match self {
            Self::Scalar(s) => s.filter.set_dynamic_state(state),
            Self::General(g) => g.set_dynamic_state(state),
        }
    }
}

/// The family of the linear-model filters (sKF, rsKF) behind the one [`Filtered`] adapter.
impl<F: LinearFilter> FilterFamily<F> for LinearLayout {
    fn interface(config: &Config) -> Result<(Self, ModelInfo), Cause> {
        interface(config, F::ROBUST)
    }

    fn build(&self, values: &Values) -> Result<F, Failure> {
        let psi = match self.psi {
            Some(indices) => read_influence(values, indices)?,
            None => InfluenceFunction::default(),
        };
        F::from_model(self.model.read(values), psi).map_err(error)
    }

    fn write_initial(&self, _: &F, ctx: &mut Context) {
        write_initial_linear(self, ctx);
    }

    fn write_outputs(&self, filter: &F, values: &mut Values) {
        self.signals.x_hat.write_vector(values, filter.state());
        self.signals.y_hat.write_vector(values, filter.output());
        self.innovation.write_vector(values, filter.innovation());
        if let (Some(w), Some(weights)) = (&self.w, filter.weights()) {
            w.write_vector(values, weights);
        }
    }
}

/// `KalmanFilter.fmu`.
pub type KalmanFilterFmu = EstimatorFmu<LinearEstimator<KalmanFilter>>;
/// `RobustKalmanFilter.fmu`.
pub type RobustKalmanFilterFmu = EstimatorFmu<LinearEstimator<RobustKalmanFilter>>;

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::dims_config;
    use spurio_export::harness::Harness;
    use spurio_export::FmuModel;

    #[test]
    fn scalar_variant_tracks_a_constant_and_names_bad_parameters() {
        let config = dims_config(1, 0, 1);
        let info = KalmanFilterFmu::describe(&config).unwrap();
        let names: Vec<&str> = info.variables.iter().map(|v| v.name.as_str()).collect();
        assert_eq!(
            &names[..4],
            &["y[1]", "x_hat[1]", "y_hat[1]", "innovation[1]"]
        );
        let vr = |n: &str| info.index_of(n).unwrap() as u32;
        let mut h = Harness::<KalmanFilterFmu>::new(&config).unwrap();
        h.set_real(&[vr("P0[1,1]")], &[1.0]).unwrap();
        h.initialize(0.0).unwrap();
        let mut out = [0.0];
        for k in 0..50 {
            h.set_real(&[vr("y[1]")], &[2.0]).unwrap();
            h.do_step(k as f64 * 1e-3, 1e-3).unwrap();
        }
        h.get_real(&[vr("x_hat[1]")], &mut out).unwrap();
        assert!((out[0] - 2.0).abs() < 1e-3, "{out:?}");

        let robust = RobustKalmanFilterFmu::describe(&config).unwrap();
        let r = robust.index_of("R[1,1]").unwrap() as u32;
        let mut bad = Harness::<RobustKalmanFilterFmu>::new(&config).unwrap();
        bad.set_real(&[r], &[-1.0]).unwrap();
        assert!(bad.initialize(0.0).is_err());
        assert!(
            bad.log().iter().any(|(_, _, text)| text.contains("`R`")),
            "{:?}",
            bad.log()
        );
    }

    /// `x_hat[1]` of the scalar filter (P0 = 1) fed `y` (one value per step) at steps of
    /// `step` with the given `sample_period`, read after each step.
    fn filtered(sample_period: f64, step: f64, y: &[f64]) -> Vec<f64> {
        let config = dims_config(1, 0, 1);
        let info = KalmanFilterFmu::describe(&config).unwrap();
        let vr = |n: &str| info.index_of(n).unwrap() as u32;
        let mut h = Harness::<KalmanFilterFmu>::new(&config).unwrap();
        h.set_real(&[vr("P0[1,1]"), vr("sample_period")], &[1.0, sample_period])
            .unwrap();
        h.initialize(0.0).unwrap();
        y.iter()
            .enumerate()
            .map(|(k, &y)| {
                h.set_real(&[vr("y[1]")], &[y]).unwrap();
                h.do_step(k as f64 * step, step).unwrap();
                h.real(vr("x_hat[1]")).unwrap()
            })
            .collect()
    }

    #[test]
    fn the_filter_samples_on_its_clock_whatever_the_step() {
        let info = KalmanFilterFmu::describe(&dims_config(1, 0, 1)).unwrap();
        assert_eq!(
            info.index_of("sample_period"),
            Some(info.variables.len() - 1)
        );
        let at_period = filtered(0.1, 0.1, &[1.0, 3.0]);
        // K = P⁻/(P⁻ + R) = 1.0001/1.0002 on the first sample.
        assert!(
            (at_period[0] - 1.0001 / 1.0002).abs() < 1e-15,
            "{at_period:?}"
        );
        // The default (0) takes the period from the first step: the same samples.
        assert_eq!(filtered(0.0, 0.1, &[1.0, 3.0]), at_period);
        // Steps of T/2: the step from t_k takes the sample with the input set at t_k (1,
        // then 3); the step from t_k + T/2 holds the outputs (the inputs 2 and 4 are unused).
        let half = filtered(0.1, 0.05, &[1.0, 2.0, 3.0, 4.0]);
        assert_eq!(
            half,
            [at_period[0], at_period[0], at_period[1], at_period[1]]
        );
        // Steps of 2T: two samples per step with the input held (1, 1, then 2, 2).
        let double = filtered(0.1, 0.2, &[1.0, 2.0]);
        let single = filtered(0.1, 0.1, &[1.0, 1.0, 2.0, 2.0]);
        assert_eq!(double, [single[1], single[3]]);
        assert!(double[1] > 1.5 && double[1] < 2.0, "{double:?}");
    }

    #[test]
    fn the_fmu_state_carries_the_clock() {
        let config = dims_config(1, 0, 1);
        let info = KalmanFilterFmu::describe(&config).unwrap();
        let index = |n: &str| info.index_of(n).unwrap();
        let (x, y) = (index("x_hat[1]"), index("y[1]"));
        let mut values = spurio_export::Values::from_start(&info.variables);
        values.set_real(index("P0[1,1]"), 1.0);
        values.set_real(index("sample_period"), 0.1);
        let mut model = KalmanFilterFmu::create(&info).unwrap();
        let mut ctx = spurio_export::Context::new(&mut values);
        model.initialize(&mut ctx).unwrap();
        ctx.values.set_real(y, 1.0);
        model.do_step(&mut ctx, 0.0, 0.05).unwrap();
        let mut out = spurio_export::ByteWriter::new();
        model.save_state(&mut out);
        let bytes = out.into_bytes();
        // The restored instance knows that sample 0 was taken and sample 1 (t = 0.1) is the
        // next: the step from 0.05 holds, the one from 0.1 takes it.
        let mut restored = KalmanFilterFmu::create(&info).unwrap();
        restored
            .load_state(&mut spurio_export::ByteReader::new(&bytes))
            .unwrap();
        let mut estimates = Vec::new();
        for m in [&mut model, &mut restored] {
            ctx.values.set_real(x, -1.0);
            m.do_step(&mut ctx, 0.05, 0.05).unwrap();
            assert_eq!(ctx.values.real(x), -1.0, "held");
            ctx.values.set_real(y, 3.0);
            m.do_step(&mut ctx, 0.1, 0.05).unwrap();
            estimates.push(ctx.values.real(x));
        }
        assert_eq!(estimates[0], estimates[1]);
        assert_eq!(estimates[0], filtered(0.1, 0.1, &[1.0, 3.0])[1]);
        assert!(restored
            .load_state(&mut spurio_export::ByteReader::new(
                &bytes[..bytes.len() - 1]
            ))
            .is_err());
    }

    /// The outputs and FMU state of `M`'s variant `(n, m, p)` with its filter on plain numbers
    /// and with the general one, over `steps` random samples (outliers and missing samples
    /// among them).
    fn scalar_and_general<F: LinearFilter>(m: usize, steps: usize) {
        type M<F> = EstimatorFmu<LinearEstimator<F>>;
        let config = dims_config(1, m, 1);
        let info = M::<F>::describe(&config).unwrap();
        let index = |n: &str| info.index_of(n).unwrap();
        let outputs: Vec<usize> = info
            .variables
            .iter()
            .enumerate()
            .filter(|(_, v)| v.causality == spurio_export::Causality::Output)
            .map(|(k, _)| k)
            .collect();
        assert_eq!(outputs.len(), if F::ROBUST { 4 } else { 3 });
        let mut runs = Vec::new();
        for general in [false, true] {
            let mut values = spurio_export::Values::from_start(&info.variables);
            values.set_real(index("P0[1,1]"), 1.0);
            values.set_real(index("A[1,1]"), 0.9);
            if m == 1 {
                values.set_real(index("B[1,1]"), 0.5);
                values.set_real(index("D[1,1]"), -0.25);
            }
            let mut model = M::<F>::create(&info).unwrap();
            let mut ctx = spurio_export::Context::new(&mut values);
            model.initialize(&mut ctx).unwrap();
            let mut state = spurio_export::ByteWriter::new();
            model.save_state(&mut state);
            let (layout, parameters, estimator) = model.parts_mut();
            let estimator = estimator.unwrap();
            assert!(matches!(estimator, LinearEstimator::Scalar(_)));
            if general {
                let filtered = Filtered::<LinearLayout, F>::build(layout, parameters).unwrap();
                *estimator = LinearEstimator::General(filtered);
            }
            let mut rng = spurio::signals::rng::RandomGenerator::new(0x9E37_79B9_7F4A_7C15);
            let mut uniform = || rng.uniform();
            let mut seen = Vec::new();
            for k in 0..steps {
                let outlier = if uniform() < 0.1 { 1.0 } else { 0.0 };
                let y = (k as f64 * 0.01).sin() + 0.01 * (uniform() - 0.5) + outlier;
                ctx.values.set_real(index("y[1]"), y);
                // missing samples among them, runs of them too
                let missing = uniform() < 0.1 || (1000..1050).contains(&k);
                ctx.values.set_boolean(index("y_valid[1]"), !missing);
                if m == 1 {
                    ctx.values.set_real(index("u[1]"), uniform() - 0.5);
                }
                model.do_step(&mut ctx, k as f64 * 1e-3, 1e-3).unwrap();
                seen.extend(outputs.iter().map(|&o| ctx.values.real(o).to_bits()));
            }
            let mut saved = spurio_export::ByteWriter::new();
            model.save_state(&mut saved);
            runs.push((seen, state.into_bytes(), saved.into_bytes()));
        }
        assert_eq!(runs[0], runs[1], "m = {m}");
    }

    #[test]
    fn the_scalar_variants_on_numbers_give_the_general_filters_results_bit_for_bit() {
        for m in [0, 1] {
            scalar_and_general::<KalmanFilter>(m, 3000);
            scalar_and_general::<RobustKalmanFilter>(m, 3000);
        }
    }

    #[test]
    fn a_non_finite_input_of_a_scalar_variant_names_it_and_leaves_the_filter() {
        for (m, name) in [(0, "y[1]"), (1, "u[1]"), (1, "y[1]")] {
            let config = dims_config(1, m, 1);
            let info = RobustKalmanFilterFmu::describe(&config).unwrap();
            let index = |n: &str| info.index_of(n).unwrap();
            let mut values = spurio_export::Values::from_start(&info.variables);
            let mut model = RobustKalmanFilterFmu::create(&info).unwrap();
            let mut ctx = spurio_export::Context::new(&mut values);
            model.initialize(&mut ctx).unwrap();
            ctx.values.set_real(index("y[1]"), 1.0);
            model.do_step(&mut ctx, 0.0, 0.1).unwrap();
            let (_, _, estimator) = model.parts_mut();
            let before = estimator.unwrap().dynamic_state();
            ctx.values.set_real(index(name), f64::NEG_INFINITY);
            let failure = model.do_step(&mut ctx, 0.1, 0.1).unwrap_err();
            assert!(
                matches!(&failure, Failure::Error(t) if t.to_string().contains(&format!("`{name}` = -inf"))),
                "{failure:?}"
            );
            let (_, _, estimator) = model.parts_mut();
            assert_eq!(estimator.unwrap().dynamic_state(), before, "{name}");
        }
    }

    #[test]
    fn nan_input_is_an_error_naming_the_input() {
        let config = dims_config(2, 1, 1);
        let info = RobustKalmanFilterFmu::describe(&config).unwrap();
        let mut h = Harness::<RobustKalmanFilterFmu>::new(&config).unwrap();
        h.initialize(0.0).unwrap();
        let y = info.index_of("y[1]").unwrap() as u32;
        // The export layer rejects the value; the adapter would too (`read_inputs`).
        assert!(h.set_real(&[y], &[f64::NAN]).is_err());
        assert!(h.log().iter().any(|(_, _, text)| text.contains("`y[1]`")));
        let mut values = spurio_export::Values::from_start(&info.variables);
        values.set_real(y as usize, f64::INFINITY);
        let block = Block {
            first: y as usize,
            rows: 1,
            cols: 1,
        };
        let mut buffer = DVector::from_element(1, 7.0);
        assert!(!spurio_fmu_common::estimator::copy_inputs(
            &values,
            &block,
            &mut buffer
        ));
        assert_eq!(buffer[0], 7.0, "left as it was");
        values.set_real(y as usize, 2.5);
        assert!(spurio_fmu_common::estimator::copy_inputs(
            &values,
            &block,
            &mut buffer
        ));
        assert_eq!(buffer[0], 2.5);
        values.set_real(y as usize, f64::INFINITY);
        let error =
            spurio_fmu_common::estimator::read_inputs(&values, &block, "y", &mut DVector::zeros(1));
        assert!(matches!(error, Err(Failure::Error(m)) if m.to_string().contains("`y[1]`")));
    }
}
