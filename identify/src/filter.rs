//! What the online filters on an FMU share (docs/estimators.md, "Identifying an FMU"):
//! their settings, their robust correction, their errors and the trajectory they write.
//!
//! **State.** z = [x; θ_a]: the FMU's continuous states x (n) and the parameters estimated
//! online θ_a (q, possibly none), each a random walk θ_{k+1} = θ_k + w_k, w_k ~ N(0, Q_θ)
//! (joint estimation). Parameters not in z are held at given values. The unscented filter
//! ([`crate::ukf`]) and the extended one ([`crate::ekf`]) differ only in how they predict
//! ẑ⁻, P⁻, ŷ and the covariances S = cov(y) (with R) and C = cov(z, y); the correction is
//! this module's.
//!
//! **Robust correction** (the papers' rsKF, as `spurio`'s robust Kalman filter): over the
//! present channels (a NaN is a missing sample, left out; none present: no correction) the
//! innovation e = y − ŷ is standardised by its covariance, rⱼ = eⱼ/√Sⱼⱼ, weighted
//! wⱼ = ψ(rⱼ)/rⱼ (Huber or Tukey, clamped to [`MIN_WEIGHT`]) and the measurement variance
//! inflated, R̃ⱼⱼ = Rⱼⱼ / wⱼ: S̃ = S + R̃ − R, K = C S̃⁻¹ (by the Cholesky factor of S̃),
//! ẑ = ẑ⁻ + K e, and
//! - without a measurement Jacobian (UKF): P = P⁻ − K S̃ Kᵀ;
//! - with one, H (EKF, C = P⁻ Hᵀ): the Joseph form P = (I − K H) P⁻ (I − K H)ᵀ + K R̃ Kᵀ,
//!   a sum of positive semidefinite terms whatever the rounding of K.
//!
//! **Declared ranges.** A parameter of z is held to the `min`/`max` its FMU declares: the
//! model the filter propagates is f(x, Π(θ)) with Π the projection onto the ranges (a sigma
//! point beyond a bound sees the plant at the bound, [`crate::prediction::Step`]), and the
//! corrected θ̂ is projected onto them (estimate projection; P is kept), so the plant is never
//! handed a value it may refuse and θ̂ never leaves what the model admits.
//!
//! P is symmetrised, ½(P + Pᵀ), after every prediction and correction. An innovation
//! covariance S̃ (which holds R > 0) whose Cholesky factorisation fails stops the step with an
//! error naming the sample ([`FilterError::NotPositive`]).
//!
//! **Trajectory.** The filter's outputs over time are one matrix, a column per sample (the
//! columns allocated once for the record), rows [ẑ (L); √diag P (L); e (p); √Sⱼⱼ (p);
//! w (p)], L = n + q: [`Trajectory`].

use crate::ekf::ExtendedWork;
use crate::plant::FmuPlant;
pub use crate::prediction::FilterError;
use crate::prediction::{symmetrise, Prediction, Sizes, Step};
use crate::ukf::{SigmaPoints, UnscentedWork};
use nalgebra::{Cholesky, DMatrix, DVector};
use spurio::estimation::{InfluenceFunction, MIN_WEIGHT};
use std::cell::RefCell;
use std::rc::Rc;

/// The noise of the filter's model, per sample, as diagonals: Q over z = [x; θ_a] (Q_x, the
/// variance added to each state, then Q_θ, the random-walk variance of each parameter of
/// z) and R (the variance of each measured variable).
#[derive(Debug, Clone, PartialEq)]
pub struct Noise {
    pub process: Vec<f64>,
    pub measurement: Vec<f64>,
}

impl Noise {
    /// Q_x = `state` on n states, Q_θ = `parameter` on q parameters, R = `measurement`.
    pub fn new(state: f64, n: usize, parameter: f64, q: usize, measurement: &[f64]) -> Self {
        let mut process = vec![state; n];
        process.resize(n + q, parameter);
        Self {
            process,
            measurement: measurement.to_vec(),
        }
    }
}

/// How a filter carries the mean and covariance through the FMU.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Linearisation {
    /// Sigma points through the FMU (scaled unscented transform, [`crate::ukf`]): α, β and
    /// κ (None: max(0, 3 − L)).
    Unscented {
        alpha: f64,
        beta: f64,
        kappa: Option<f64>,
    },
    /// The FMU linearised about the estimate ([`crate::ekf`]): the state-transition matrix
    /// and the measurement Jacobian, the state block from the FMU's directional derivatives
    /// when it gives them.
    Extended,
}

impl Linearisation {
    /// The unscented transform with α = 1, β = 2 and κ = max(0, 3 − L): every covariance
    /// weight ≥ 0.
    pub const UNSCENTED: Self = Self::Unscented {
        alpha: 1.0,
        beta: 2.0,
        kappa: None,
    };
}

/// The tuning of a filter on an FMU, shared by the online filters and the likelihood of the
/// offline fit ([`crate::fmu_model`]).
#[derive(Debug, Clone, PartialEq)]
pub struct FilterSettings {
    pub noise: Noise,
    /// The robust weights (None: the plain filter).
    pub robust: Option<InfluenceFunction>,
    pub linearisation: Linearisation,
}

impl FilterSettings {
    /// Checks the lengths against L = n + q filter states and p measured variables, and the
    /// variances (finite, ≥ 0 for Q, > 0 for R).
    pub fn check(&self, l: usize, p: usize) -> Result<(), FilterError> {
        let noise = &self.noise;
        if noise.process.len() != l || noise.measurement.len() != p {
            return Err(FilterError::Settings(format!(
                "{} process noises and {} measurement variances given; {l} (states and parameters of z) and {p} needed",
                noise.process.len(),
                noise.measurement.len(),
            )));
        }
        let nonnegative = noise.process.iter().all(|v| v.is_finite() && *v >= 0.0);
        if !nonnegative || !noise.measurement.iter().all(|v| v.is_finite() && *v > 0.0) {
            return Err(FilterError::Settings(
                "the noise variances must be finite, ≥ 0 (Q) and > 0 (R)".into(),
            ));
        }
        Ok(())
    }
}

/// The prediction errors of the present channels and their covariance S (before the robust
/// inflation), for the innovations likelihood.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct PredictionErrors {
    pub v: DVector<f64>,
    pub f: DMatrix<f64>,
}

/// `m` as a `rows` × `cols` matrix of zeros in its own storage: nothing allocated while
/// rows · cols is at most the size it was made with.
fn reshape(m: &mut DMatrix<f64>, rows: usize, cols: usize) {
    let mut data: Vec<f64> = std::mem::take(m).data.into();
    data.clear();
    data.resize(rows * cols, 0.0);
    *m = DMatrix::from_vec(rows, cols, data);
}

/// [`reshape`] of a vector.
fn resize(v: &mut DVector<f64>, rows: usize) {
    let mut data: Vec<f64> = std::mem::take(v).data.into();
    data.clear();
    data.resize(rows, 0.0);
    *v = DVector::from_vec(data);
}

/// The robust correction's work (module documentation): its matrices made once for L states
/// and p measured variables, those of the k present channels reshaped in their storage, so
/// that a correction allocates nothing.
#[derive(Debug, Clone)]
struct Correction {
    /// The present channels.
    present: Vec<usize>,
    /// C of the present channels, transposed (k × L), solved in place into Kᵀ = S̃⁻¹ Cᵀ.
    gain_t: DMatrix<f64>,
    /// K (L × k).
    gain: DMatrix<f64>,
    /// S̃ (k × k) and its Cholesky factor.
    inflated: DMatrix<f64>,
    factor: DMatrix<f64>,
    /// R̃ (k), and as a diagonal matrix.
    r_inflated: DVector<f64>,
    r_diagonal: DMatrix<f64>,
    /// H of the present channels (k × L).
    h_present: DMatrix<f64>,
    /// K S̃ or K R̃ (L × k).
    gain_product: DMatrix<f64>,
    /// K e (L).
    step: DVector<f64>,
    /// L × L: K S̃ Kᵀ, or K H, I − K H, its transpose and products.
    square: [DMatrix<f64>; 4],
}

impl Correction {
    fn new(l: usize, p: usize) -> Self {
        Self {
            present: Vec::with_capacity(p),
            gain_t: DMatrix::zeros(p, l),
            gain: DMatrix::zeros(l, p),
            inflated: DMatrix::zeros(p, p),
            factor: DMatrix::zeros(p, p),
            r_inflated: DVector::zeros(p),
            r_diagonal: DMatrix::zeros(p, p),
            h_present: DMatrix::zeros(p, l),
            gain_product: DMatrix::zeros(l, p),
            step: DVector::zeros(l),
            square: std::array::from_fn(|_| DMatrix::zeros(l, l)),
        }
    }

    /// The robust correction (module documentation) of `prediction` by `y` (NaN: missing),
    /// R the measurement variances: (ẑ, P) into the prediction's ẑ⁻ and P⁻, the prediction
    /// errors into `errors`, and into `record` (e, √Sⱼⱼ, w: 3p values) the sample's rows of
    /// the trajectory.
    fn correct(
        &mut self,
        prediction: &mut Prediction,
        y: &[f64],
        (r, robust): (&[f64], Option<InfluenceFunction>),
        at: (usize, f64),
        record: &mut [f64],
        errors: &mut PredictionErrors,
    ) -> Result<(), FilterError> {
        let p_out = r.len();
        let Prediction {
            z,
            p,
            y: y_hat,
            s,
            cross,
            jacobian,
        } = prediction;
        let (innovation, rest) = record.split_at_mut(p_out);
        let (innovation_sd, weight) = rest.split_at_mut(p_out);
        for j in 0..p_out {
            innovation_sd[j] = s[(j, j)].sqrt();
            innovation[j] = f64::NAN;
            weight[j] = f64::NAN;
        }
        let present = &mut self.present;
        present.clear();
        present.extend((0..p_out).filter(|&j| !y[j].is_nan()));
        let k = present.len();
        resize(&mut errors.v, k);
        reshape(&mut errors.f, k, k);
        if k == 0 {
            return Ok(());
        }
        let l = z.len();
        reshape(&mut self.gain_t, k, l);
        for (a, &ja) in present.iter().enumerate() {
            errors.v[a] = y[ja] - y_hat[ja];
            innovation[ja] = errors.v[a];
            for (b, &jb) in present.iter().enumerate() {
                errors.f[(a, b)] = s[(ja, jb)];
            }
            for i in 0..l {
                self.gain_t[(a, i)] = cross[(i, ja)];
            }
        }
        reshape(&mut self.inflated, k, k);
        self.inflated.copy_from(&errors.f);
        resize(&mut self.r_inflated, k);
        for (a, &ja) in present.iter().enumerate() {
            let w = match robust {
                Some(psi) => psi
                    .weight(errors.v[a] / errors.f[(a, a)].sqrt())
                    .max(MIN_WEIGHT),
                None => 1.0,
            };
            weight[ja] = w;
            self.r_inflated[a] = r[ja] / w;
            self.inflated[(a, a)] += r[ja] * (1.0 / w - 1.0);
        }
        let (sample, time) = at;
        let mut factor = std::mem::take(&mut self.factor);
        reshape(&mut factor, k, k);
        factor.copy_from(&self.inflated);
        // In place (a failed factorisation gives its storage up: the step fails anyway).
        let chol = Cholesky::new(factor).ok_or(FilterError::NotPositive {
            what: "innovation covariance S",
            sample,
            time,
        })?;
        // K = C S̃⁻¹ = (S̃⁻¹ Cᵀ)ᵀ (S̃ symmetric).
        chol.solve_mut(&mut self.gain_t);
        self.factor = chol.unpack_dirty();
        reshape(&mut self.gain, l, k);
        self.gain_t.transpose_to(&mut self.gain);
        self.gain.mul_to(&errors.v, &mut self.step);
        *z += &self.step;
        reshape(&mut self.gain_product, l, k);
        let [first, second, third, fourth] = &mut self.square;
        match jacobian {
            None => {
                // P = P⁻ − K S̃ Kᵀ.
                self.gain.mul_to(&self.inflated, &mut self.gain_product);
                self.gain_product.mul_to(&self.gain_t, first);
                *p -= &*first;
            }
            Some(h) => {
                // P = (I − K H) P⁻ (I − K H)ᵀ + K R̃ Kᵀ.
                reshape(&mut self.h_present, k, l);
                for (a, &ja) in present.iter().enumerate() {
                    self.h_present.set_row(a, &h.row(ja));
                }
                self.gain.mul_to(&self.h_present, first);
                second.fill_with_identity();
                *second -= &*first;
                second.mul_to(p, first);
                second.transpose_to(third);
                first.mul_to(third, fourth);
                reshape(&mut self.r_diagonal, k, k);
                self.r_diagonal.set_diagonal(&self.r_inflated);
                self.gain.mul_to(&self.r_diagonal, &mut self.gain_product);
                self.gain_product.mul_to(&self.gain_t, first);
                fourth.add_to(first, p);
            }
        }
        symmetrise(p);
        Ok(())
    }
}

/// The online filters' outputs over a record (module documentation): one column per sample.
#[derive(Debug, Clone, PartialEq)]
pub struct Trajectory {
    /// t_k of column k.
    pub time: Vec<f64>,
    /// Rows [ẑ (L); √diag P (L); e (p); √Sⱼⱼ (p); w (p)], a column per sample.
    pub values: DMatrix<f64>,
    /// L = n + q.
    pub filter_states: usize,
}

impl Trajectory {
    /// Room for `samples` samples of a filter of L = `filter_states` and p = `outputs`.
    pub fn new(filter_states: usize, outputs: usize, samples: usize) -> Self {
        Self {
            time: Vec::with_capacity(samples),
            values: DMatrix::from_element(2 * filter_states + 3 * outputs, samples, f64::NAN),
            filter_states,
        }
    }

    /// p.
    pub fn outputs(&self) -> usize {
        (self.values.nrows() - 2 * self.filter_states) / 3
    }

    /// Samples recorded so far.
    pub fn len(&self) -> usize {
        self.time.len()
    }

    /// Whether no sample is recorded.
    pub fn is_empty(&self) -> bool {
        self.time.is_empty()
    }

    /// Sample k's column, to be written by a filter step (recorded at `time`).
    pub(crate) fn next_column(&mut self, time: f64) -> Result<&mut [f64], FilterError> {
        let k = self.time.len();
        if k >= self.values.ncols() {
            return Err(FilterError::Settings(format!(
                "the trajectory has room for {k} samples"
            )));
        }
        self.time.push(time);
        let rows = self.values.nrows();
        Ok(&mut self.values.as_mut_slice()[k * rows..(k + 1) * rows])
    }

    fn block(&self, from: usize, rows: usize, k: usize, i: usize) -> f64 {
        debug_assert!(i < rows);
        self.values[(from + i, k)]
    }

    /// ẑ_i at sample k.
    pub fn estimate(&self, k: usize, i: usize) -> f64 {
        self.block(0, self.filter_states, k, i)
    }

    /// √P_ii at sample k.
    pub fn standard_deviation(&self, k: usize, i: usize) -> f64 {
        self.block(self.filter_states, self.filter_states, k, i)
    }

    /// e_j = y_j − ŷ_j at sample k (NaN where missing).
    pub fn innovation(&self, k: usize, j: usize) -> f64 {
        self.block(2 * self.filter_states, self.outputs(), k, j)
    }

    /// √S_jj at sample k (before the robust inflation).
    pub fn innovation_sd(&self, k: usize, j: usize) -> f64 {
        self.block(
            2 * self.filter_states + self.outputs(),
            self.outputs(),
            k,
            j,
        )
    }

    /// w_j at sample k (1 without robust weighting, NaN where missing).
    pub fn weight(&self, k: usize, j: usize) -> f64 {
        self.block(
            2 * self.filter_states + 2 * self.outputs(),
            self.outputs(),
            k,
            j,
        )
    }
}

/// Writes ẑ and √diag P into the first 2L entries of a trajectory column.
pub(crate) fn record_state(z: &DVector<f64>, p: &DMatrix<f64>, column: &mut [f64]) {
    let l = z.len();
    column[..l].copy_from_slice(z.as_slice());
    for i in 0..l {
        column[l + i] = p[(i, i)].max(0.0).sqrt();
    }
}

/// What a filter carries from one sample to the next, besides its settings and the plant:
/// ẑ, P (column-major, L × L), the time and held inputs of the last sample (None before the
/// first: the next sample is then the first, with no prediction) and the samples taken. An
/// estimator FMU serializes it ([`Filter::state`]) and restores it into a filter set up
/// alike ([`Filter::restore`]), which then continues bit for bit.
#[derive(Debug, Clone, PartialEq)]
pub struct FilterState {
    pub estimate: Vec<f64>,
    pub covariance: Vec<f64>,
    pub last: Option<(f64, Vec<f64>)>,
    pub samples: usize,
}

/// A filter's own way of predicting, with its work buffers.
#[derive(Debug, Clone)]
enum Predictor {
    Unscented(SigmaPoints, Box<UnscentedWork>),
    Extended(Box<ExtendedWork>),
}

/// An online filter on an FMU (module documentation): the unscented or the extended one by
/// its [`FilterSettings::linearisation`]. A clone shares the plant: every propagation places
/// the plant's instance at the states and parameters it is given, so clones are independent.
#[derive(Debug, Clone)]
pub struct Filter {
    plant: Rc<RefCell<FmuPlant>>,
    n: usize,
    augmented: Vec<usize>,
    theta: Vec<f64>,
    z: DVector<f64>,
    p: DMatrix<f64>,
    q: DVector<f64>,
    settings: FilterSettings,
    predictor: Predictor,
    /// Time of the last sample (None before the first) and its inputs.
    last: Option<f64>,
    last_inputs: Vec<f64>,
    sample: usize,
    /// The prediction, the correction's work and the last prediction errors (written by every
    /// sample: a sample allocates nothing once the first has sized them).
    prediction: Prediction,
    correction: Correction,
    errors: PredictionErrors,
}

impl Filter {
    /// A filter on `plant` with every free parameter at `theta`, those of `augmented`
    /// (indices into θ) estimated in z, started at ẑ₀ = [x0; θ_a], P₀ = `p0` ((n+q)×(n+q)).
    pub fn new(
        plant: Rc<RefCell<FmuPlant>>,
        theta: &[f64],
        augmented: &[usize],
        x0: &[f64],
        p0: DMatrix<f64>,
        settings: &FilterSettings,
    ) -> Result<Self, FilterError> {
        let (n, free, outputs) = {
            let pl = plant.borrow();
            (pl.states(), pl.parameters().len(), pl.output_names().len())
        };
        let l = n + augmented.len();
        if theta.len() != free || x0.len() != n || p0.shape() != (l, l) {
            return Err(FilterError::Settings(format!(
                "{} parameters, {} states and a {}×{} P₀ given; the model has {free} parameters, {n} states and {l} filter states",
                theta.len(),
                x0.len(),
                p0.nrows(),
                p0.ncols()
            )));
        }
        if augmented.iter().any(|&i| i >= free) {
            return Err(FilterError::Settings(
                "an estimated parameter's index is out of range".into(),
            ));
        }
        settings.check(l, outputs)?;
        let (inputs, indicators) = {
            let pl = plant.borrow();
            (pl.input_names().len(), pl.event_indicators().len())
        };
        let sizes = Sizes {
            states: n,
            filter_states: l,
            measured: outputs,
            parameters: free,
            indicators,
        };
        let predictor = match settings.linearisation {
            Linearisation::Unscented { alpha, beta, kappa } => Predictor::Unscented(
                SigmaPoints::new(l, alpha, beta, kappa)?,
                Box::new(UnscentedWork::new(&sizes)),
            ),
            Linearisation::Extended => Predictor::Extended(Box::new(ExtendedWork::new(&sizes))),
        };
        let extended = matches!(predictor, Predictor::Extended(_));
        let mut z = DVector::zeros(l);
        z.rows_mut(0, n).copy_from_slice(x0);
        for (k, &i) in augmented.iter().enumerate() {
            z[n + k] = theta[i];
        }
        Ok(Self {
            plant,
            n,
            augmented: augmented.to_vec(),
            theta: theta.to_vec(),
            z,
            p: p0,
            q: DVector::from_column_slice(&settings.noise.process),
            settings: settings.clone(),
            predictor,
            last: None,
            last_inputs: Vec::with_capacity(inputs),
            sample: 0,
            prediction: Prediction::new(l, outputs, extended),
            correction: Correction::new(l, outputs),
            errors: PredictionErrors {
                v: DVector::zeros(outputs),
                f: DMatrix::zeros(outputs, outputs),
            },
        })
    }

    /// ẑ now.
    pub fn estimate(&self) -> &DVector<f64> {
        &self.z
    }

    /// The plant it propagates through (shared with its clones).
    pub fn plant(&self) -> Rc<RefCell<FmuPlant>> {
        Rc::clone(&self.plant)
    }

    /// P now.
    pub fn covariance(&self) -> &DMatrix<f64> {
        &self.p
    }

    /// L = n + q, the rows of ẑ.
    pub fn filter_states(&self) -> usize {
        self.z.len()
    }

    /// p, the measured variables.
    pub fn measured(&self) -> usize {
        self.settings.noise.measurement.len()
    }

    /// What the next sample reads of this filter ([`FilterState`]).
    pub fn state(&self) -> FilterState {
        FilterState {
            estimate: self.z.as_slice().to_vec(),
            covariance: self.p.as_slice().to_vec(),
            last: self.last.map(|t| (t, self.last_inputs.clone())),
            samples: self.sample,
        }
    }

    /// Restores `state` (of a filter with the same settings on the same plant): ẑ, P, the
    /// parameters θ_a of ẑ, the last sample and the count. Lengths that do not fit this
    /// filter (L, L², the plant's inputs) or a value that is not finite are an error naming
    /// them, the filter unchanged.
    pub fn restore(&mut self, state: &FilterState) -> Result<(), FilterError> {
        let l = self.z.len();
        let inputs = self.plant.borrow().input_names().len();
        let held = state.last.as_ref().map_or(inputs, |(_, u)| u.len());
        if state.estimate.len() != l || state.covariance.len() != l * l || held != inputs {
            return Err(FilterError::Settings(format!(
                "a filter state of {} estimates, {} covariances and {held} held inputs given; this filter has {l} filter states and {inputs} inputs",
                state.estimate.len(),
                state.covariance.len()
            )));
        }
        let last = state.last.as_ref();
        let finite = (state.estimate.iter().chain(&state.covariance))
            .chain(
                last.into_iter()
                    .flat_map(|(t, u)| std::iter::once(t).chain(u)),
            )
            .all(|v| v.is_finite());
        if !finite {
            return Err(FilterError::Settings(
                "a filter state with a value that is not finite".into(),
            ));
        }
        self.z.copy_from_slice(&state.estimate);
        self.p.copy_from_slice(&state.covariance);
        for (k, &i) in self.augmented.iter().enumerate() {
            self.theta[i] = self.z[self.n + k];
        }
        self.last = last.map(|(t, _)| *t);
        self.last_inputs.clear();
        if let Some((_, u)) = last {
            self.last_inputs.extend_from_slice(u);
        }
        self.sample = state.samples;
        Ok(())
    }

    /// A trajectory with room for `samples` samples of this filter.
    pub fn trajectory(&self, samples: usize) -> Trajectory {
        Trajectory::new(self.z.len(), self.measured(), samples)
    }

    /// Processes the sample at `time` with inputs `u` and measurements `y` (NaN: missing):
    /// prediction from the last sample, robust correction (module documentation); the
    /// sample's column (2L + 3p values) into `column`. Gives the prediction errors of the
    /// present channels and their covariance, for the likelihood.
    pub fn step(
        &mut self,
        time: f64,
        u: &[f64],
        y: &[f64],
        column: &mut [f64],
    ) -> Result<PredictionErrors, FilterError> {
        self.process(time, u, y, column).cloned()
    }

    /// [`Filter::step`], the prediction errors borrowed: after the first sample (which sizes
    /// the work buffers) nothing is allocated, but for the message of an error.
    pub fn process(
        &mut self,
        time: f64,
        u: &[f64],
        y: &[f64],
        column: &mut [f64],
    ) -> Result<&PredictionErrors, FilterError> {
        let l = self.z.len();
        let p_out = self.settings.noise.measurement.len();
        if y.len() != p_out || column.len() != 2 * l + 3 * p_out {
            return Err(FilterError::Settings(format!(
                "{} measurements and a column of {} given at sample {}; the filter has {p_out} measured variables and columns of {}",
                y.len(),
                column.len(),
                self.sample,
                2 * l + 3 * p_out
            )));
        }
        let (t0, u_held) = match self.last {
            Some(t0) => (t0, &self.last_inputs[..]),
            None => (time, u),
        };
        {
            let mut plant = self.plant.borrow_mut();
            let mut step = Step {
                plant: &mut plant,
                states: self.n,
                augmented: &self.augmented,
                theta: &self.theta,
                z: &self.z,
                p: &self.p,
                r: &self.settings.noise.measurement,
                q: self.last.is_some().then_some(&self.q),
                t0,
                t1: time,
                u: u_held,
                sample: self.sample,
            };
            let prediction = &mut self.prediction;
            match &mut self.predictor {
                Predictor::Unscented(sigma, work) => sigma.predict(&mut step, work, prediction)?,
                Predictor::Extended(work) => crate::ekf::predict(&mut step, work, prediction)?,
            }
        }
        self.correction.correct(
            &mut self.prediction,
            y,
            (&self.settings.noise.measurement, self.settings.robust),
            (self.sample, time),
            &mut column[2 * l..],
            &mut self.errors,
        )?;
        if let Some(i) = self.prediction.z.iter().position(|v| !v.is_finite()) {
            return Err(FilterError::Settings(format!(
                "the estimate of filter state {i} is not finite at sample {} (t = {time})",
                self.sample
            )));
        }
        std::mem::swap(&mut self.z, &mut self.prediction.z);
        std::mem::swap(&mut self.p, &mut self.prediction.p);
        {
            // θ̂ projected onto its declared range (module documentation), P kept.
            let plant = self.plant.borrow();
            let declared = plant.parameters();
            for (k, &i) in self.augmented.iter().enumerate() {
                let projected = declared[i].range.clamp(self.z[self.n + k]);
                self.z[self.n + k] = projected;
                self.theta[i] = projected;
            }
        }
        record_state(&self.z, &self.p, column);
        self.last = Some(time);
        self.last_inputs.clear();
        self.last_inputs.extend_from_slice(u);
        self.sample += 1;
        Ok(&self.errors)
    }

    /// Steps through every sample of a record (times, inputs, measurements) into a new
    /// trajectory.
    pub fn run(
        &mut self,
        time: &[f64],
        inputs: &[Vec<f64>],
        outputs: &[Vec<f64>],
    ) -> Result<Trajectory, FilterError> {
        let mut trajectory = self.trajectory(time.len());
        for ((t, u), y) in time.iter().zip(inputs).zip(outputs) {
            let column = trajectory.next_column(*t)?;
            self.step(*t, u, y, column)?;
        }
        Ok(trajectory)
    }
}
