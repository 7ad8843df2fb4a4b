//! Recursive least squares for ARX models with forgetting, docs/estimators.md §2.11; paper 002 §3.
//!
//! ARX(na, nb): y(t) = −a₁ y(t−1) − … − a_na y(t−na) + b₁ u(t−1) + … + b_nb u(t−nb) + e(t),
//! i.e. y(t) = φ(t)ᵀθ + e(t) with φ(t) = [−y(t−1) … −y(t−na), u(t−1) … u(t−nb)]ᵀ and
//! θ = [a₁ … a_na, b₁ … b_nb]ᵀ. With forgetting factor λ ∈ (0, 1] (paper 002: 0.98):
//!
//! ```text
//! ε(t) = y(t) − φᵀ θ(t−1)
//! L(t) = P φ / (λ + φᵀ P φ)
//! θ(t) = θ(t−1) + L(t) ε(t)
//! P(t) = (P − P φ φᵀ P / (λ + φᵀ P φ)) / λ
//! ```
//!
//! P is updated in the symmetric form P − L sᵀ − s Lᵀ + d L Lᵀ (s = Pφ, d = λ + φᵀPφ; equal
//! to P − s sᵀ/d) and symmetrised. Samples before the first call are taken as zero.
//!
//! **Missing samples** (docs/estimators.md, "Missing samples"). A missing y(t) has no
//! equation: θ and P stay, and y(t) is replaced in the regressors by its prediction φ(t)ᵀθ so
//! that the predictions go on. The na equations after it hold that imputed value in φ; they
//! are not data either, so θ and P stay through them too (the prediction ŷ and the error ε are
//! still formed): the recursion uses exactly the equations that batch least squares keeps when
//! it drops every equation touching a missing sample. With every sample present nothing
//! changes, bit for bit.
//!
//! **Continuous-time readout** (second order, na = 2, nb ∈ {1, 2}): the discrete poles are
//! the roots of z² + a₁ z + a₂; s = ln(z)/Ts gives ω_n = |s| and ζ = −Re(s)/|s| (for two
//! real positive roots ω_n = √(s₁s₂), ζ = −(s₁+s₂)/(2ω_n)); the DC gain is
//! Σb / (1 + a₁ + a₂) (a ZOH model keeps the DC gain). Overshoot, peak time and the 2 %
//! settling time are those of the step response of K ω_n²/(s² + 2ζω_n s + ω_n²), the
//! settling time found numerically on that response (bisection on the last exit from the
//! ±2 % band), not with the 4/(ζω_n) rule.
//!
//! **Bias.** Least squares on an ARX model whose output carries white measurement noise is
//! biased (towards too much damping: paper 002's error, docs/experiments.md §4). [`RecursiveLeastSquares::
//! with_prefilter`] runs the Steiglitz–McBride variant: u and y are filtered through 1/Â(q)
//! with the current estimate Â (refreshed every `refresh` samples) before entering φ, which
//! makes the equation error white when Â is right and removes most of the bias.
//!
//! **Steiglitz–McBride iterations.** Refreshing Â from the running estimate needs long,
//! rich records: with a single step of the op-amp filter (paper 002) the early estimates
//! are so biased that the refreshed prefilter spoils the regressors. The classical batch form
//! is sound there: run the estimator over the record with Â *fixed* (`refresh` = 0), set Â
//! to the θ it ends with ([`RecursiveLeastSquares::set_prefilter_denominator`]) and run the
//! same record again, until Â stops changing. With λ = 1 each run is the least-squares
//! solution on the prefiltered record (up to the P₀ prior), i.e. one Steiglitz–McBride
//! iteration (Steiglitz & McBride 1965; Ljung, *System Identification*, §10.4).

use super::{parameter_error, EstimationError, StateReader};
use std::f64::consts::PI;

/// Recursive least squares on an ARX(na, nb) model (see the module documentation).
#[derive(Debug, Clone)]
pub struct RecursiveLeastSquares {
    na: usize,
    nb: usize,
    lambda: f64,
    theta: Vec<f64>,
    p: Vec<f64>,
    phi: Vec<f64>,
    work_s: Vec<f64>,
    work_l: Vec<f64>,
    /// y(t−1) … y(t−na) of the signals entering φ (filtered when prefiltering).
    past_y: Vec<f64>,
    /// u(t−1) … u(t−nb).
    past_u: Vec<f64>,
    prefilter: Option<Prefilter>,
    /// How many of the next steps still have an imputed (predicted) y in their regressor φ:
    /// na after a missing sample, counting down with each present one (module doc).
    imputed_regressors: usize,
    last_error: f64,
    steps: u64,
}

/// Steiglitz–McBride prefilter state: 1/Â(q) applied to u and y.
#[derive(Debug, Clone)]
struct Prefilter {
    refresh: u64,
    since_refresh: u64,
    denominator: Vec<f64>,
    filtered_past_u: Vec<f64>,
    filtered_past_y: Vec<f64>,
    /// Work space of the stability test (na + 1 coefficients).
    work: Vec<f64>,
}

impl RecursiveLeastSquares {
    /// ARX(na, nb) estimator with forgetting factor `lambda` ∈ (0, 1] and initial
    /// covariance `p0_scale`·I (large, e.g. 1e4, means "no prior knowledge"); θ starts at 0.
    /// Errors name "na", "nb", "lambda" or "P0".
    pub fn new(na: usize, nb: usize, lambda: f64, p0_scale: f64) -> Result<Self, EstimationError> {
        if na + nb == 0 {
            return Err(parameter_error(
                "na",
                "na + nb must be at least 1 (no parameter to estimate)",
            ));
        }
        if !(lambda.is_finite() && lambda > 0.0 && lambda <= 1.0) {
            return Err(parameter_error(
                "lambda",
                format!("the forgetting factor λ must lie in (0, 1], got {lambda}"),
            ));
        }
        if !(p0_scale.is_finite() && p0_scale > 0.0) {
            return Err(parameter_error(
                "P0",
                format!("the initial covariance scale must be finite and > 0, got {p0_scale}"),
            ));
        }
        let dim = na + nb;
        let mut p = vec![0.0; dim * dim];
        for i in 0..dim {
            p[i * dim + i] = p0_scale;
        }
        Ok(Self {
            na,
            nb,
            lambda,
            theta: vec![0.0; dim],
            p,
            phi: vec![0.0; dim],
            work_s: vec![0.0; dim],
            work_l: vec![0.0; dim],
            past_y: vec![0.0; na],
            past_u: vec![0.0; nb],
            prefilter: None,
            imputed_regressors: 0,
            last_error: 0.0,
            steps: 0,
        })
    }

    /// As [`new`](Self::new), with Steiglitz–McBride prefiltering through 1/Â(q); Â starts
    /// at 1 (no filtering; see [`set_prefilter_denominator`](Self::set_prefilter_denominator))
    /// and is refreshed from θ every `refresh` samples when it is stable (roots inside the
    /// unit circle), otherwise the previous Â is kept; `refresh` = 0 keeps Â fixed (one
    /// Steiglitz–McBride iteration per pass over the data, module doc). Errors as `new`.
    pub fn with_prefilter(
        na: usize,
        nb: usize,
        lambda: f64,
        p0_scale: f64,
        refresh: u64,
    ) -> Result<Self, EstimationError> {
        let mut rls = Self::new(na, nb, lambda, p0_scale)?;
        rls.prefilter = Some(Prefilter {
            refresh,
            since_refresh: 0,
            denominator: vec![0.0; na],
            filtered_past_u: vec![0.0; na],
            filtered_past_y: vec![0.0; na],
            work: Vec::with_capacity(na + 1),
        });
        Ok(rls)
    }

    /// Sets the prefilter's denominator Â = [â₁ … â_na] (before the first sample: the
    /// filter's past is zero). Errors: no prefilter, a length other than na, a non-finite
    /// or unstable Â (roots on or outside the unit circle) — named "prefilter_a".
    pub fn set_prefilter_denominator(&mut self, a: &[f64]) -> Result<(), EstimationError> {
        let na = self.na;
        let filter = self.prefilter.as_mut().ok_or_else(|| {
            parameter_error("prefilter_a", "the estimator has no prefilter to set")
        })?;
        if a.len() != na {
            return Err(parameter_error(
                "prefilter_a",
                format!("needs na = {na} coefficients, got {}", a.len()),
            ));
        }
        if a.iter().any(|v| !v.is_finite()) || !polynomial_is_stable(a) {
            return Err(parameter_error(
                "prefilter_a",
                format!("1/Â(q) must be a stable filter (all roots of z^na + â₁ z^(na−1) + … inside the unit circle), got Â = {a:?}"),
            ));
        }
        filter.denominator.copy_from_slice(a);
        Ok(())
    }

    /// The prefilter's current denominator Â (None without a prefilter).
    pub fn prefilter_denominator(&self) -> Option<&[f64]> {
        self.prefilter.as_ref().map(|f| f.denominator.as_slice())
    }

    /// Processes one sample u(t), y(t); returns the prior prediction error ε(t). A NaN y(t)
    /// is a missing sample ([`RecursiveLeastSquares::step_missing`]); a non-finite u or a
    /// y = ±∞ is an error. While φ(t) holds an imputed y (the na samples after a missing
    /// one) the step predicts and gives ε(t) but does not update θ and P (module doc).
    pub fn step(&mut self, u: f64, y: f64) -> Result<f64, EstimationError> {
        if y.is_nan() && u.is_finite() {
            self.step_missing(u)?;
            return Ok(0.0);
        }
        if !(u.is_finite() && y.is_finite()) {
            return Err(EstimationError::NonFinite {
                what: "RLS sample (u, y)",
                step: self.steps + 1,
            });
        }
        self.steps += 1;
        let (u_used, y_used) = match &mut self.prefilter {
            None => (u, y),
            Some(filter) => filter.apply(u, y),
        };
        let dim = self.na + self.nb;
        for i in 0..self.na {
            self.phi[i] = -self.past_y[i];
        }
        for j in 0..self.nb {
            self.phi[self.na + j] = self.past_u[j];
        }
        let prediction: f64 = self.phi.iter().zip(&self.theta).map(|(f, t)| f * t).sum();
        let error = y_used - prediction;
        if self.imputed_regressors > 0 {
            // φ(t) holds a prediction of a missing y: no equation, as batch least squares
            // drops it (θ, P and the prefilter's refresh counter stay).
            self.imputed_regressors -= 1;
            shift_in(&mut self.past_y, y_used);
            shift_in(&mut self.past_u, u_used);
            self.last_error = error;
            return Ok(error);
        }
        // s = P φ, d = λ + φᵀ s.
        for i in 0..dim {
            self.work_s[i] = (0..dim).map(|j| self.p[i * dim + j] * self.phi[j]).sum();
        }
        let denominator = self.lambda
            + self
                .phi
                .iter()
                .zip(&self.work_s)
                .map(|(f, s)| f * s)
                .sum::<f64>();
        if !(denominator.is_finite() && denominator > 0.0) {
            return Err(EstimationError::NonFinite {
                what: "RLS denominator λ + φᵀPφ",
                step: self.steps,
            });
        }
        for i in 0..dim {
            self.work_l[i] = self.work_s[i] / denominator;
            self.theta[i] += self.work_l[i] * error;
        }
        let inv_lambda = 1.0 / self.lambda;
        for i in 0..dim {
            for j in 0..=i {
                let l = &self.work_l;
                let s = &self.work_s;
                let value = (self.p[i * dim + j] - l[i] * s[j] - s[i] * l[j]
                    + denominator * l[i] * l[j])
                    * inv_lambda;
                self.p[i * dim + j] = value;
                self.p[j * dim + i] = value;
            }
        }
        if self.theta.iter().any(|v| !v.is_finite()) || self.p.iter().any(|v| !v.is_finite()) {
            return Err(EstimationError::NonFinite {
                what: "RLS estimate θ or covariance P",
                step: self.steps,
            });
        }
        shift_in(&mut self.past_y, y_used);
        shift_in(&mut self.past_u, u_used);
        self.last_error = error;
        if let Some(filter) = self.prefilter.as_mut().filter(|f| f.refresh > 0) {
            filter.since_refresh += 1;
            if filter.since_refresh >= filter.refresh {
                filter.since_refresh = 0;
                filter.refresh_denominator(&self.theta[..self.na]);
            }
        }
        Ok(error)
    }

    /// The step of a sample whose y(t) is missing: the prediction only. θ and P stay (no
    /// data, so no update and no forgetting: P is not divided by λ); the regressor φ(t) is
    /// formed as usual and y(t) is replaced in the history of the regressors by its one-step
    /// prediction φ(t)ᵀθ (in the prefiltered signals when prefiltering; u still passes
    /// through the prefilter), which is what the ARX model expects there; the na steps that
    /// follow hold it in φ and do not update θ and P either (module doc). The prediction
    /// error ε(t) is not defined and is 0 ([`RecursiveLeastSquares::last_error`]); the
    /// prefilter's refresh counter counts updates and does not advance. Gives the
    /// prediction ŷ(t) of the unfiltered y (φᵀθ + Σ âᵢ y_f(t−i) when prefiltering: the
    /// prefilter's inverse). Errors when u is not finite. Allocation-free.
    pub fn step_missing(&mut self, u: f64) -> Result<f64, EstimationError> {
        if !u.is_finite() {
            return Err(EstimationError::NonFinite {
                what: "RLS input u",
                step: self.steps + 1,
            });
        }
        self.steps += 1;
        for i in 0..self.na {
            self.phi[i] = -self.past_y[i];
        }
        for j in 0..self.nb {
            self.phi[self.na + j] = self.past_u[j];
        }
        let prediction: f64 = self.phi.iter().zip(&self.theta).map(|(f, t)| f * t).sum();
        let (u_used, y_hat) = match &mut self.prefilter {
            None => (u, prediction),
            Some(filter) => filter.apply_missing(u, prediction),
        };
        shift_in(&mut self.past_y, prediction);
        shift_in(&mut self.past_u, u_used);
        self.imputed_regressors = self.na;
        self.last_error = 0.0;
        if !y_hat.is_finite() {
            return Err(EstimationError::NonFinite {
                what: "RLS prediction φᵀθ",
                step: self.steps,
            });
        }
        Ok(y_hat)
    }

    /// Everything that evolves from step to step, as a flat list of numbers (for FMU state
    /// serialization): θ, P, the past samples, the prefilter's state, the count of regressors
    /// still holding an imputed sample, the last error and the step count. Restoring it with [`RecursiveLeastSquares::set_dynamic_state`] into an
    /// estimator built with the same arguments continues bit for bit.
    pub fn dynamic_state(&self) -> Vec<f64> {
        let mut out = Vec::new();
        for block in [&self.theta, &self.p, &self.phi, &self.past_y, &self.past_u] {
            out.extend_from_slice(block);
        }
        if let Some(filter) = &self.prefilter {
            out.push(filter.since_refresh as f64);
            out.extend_from_slice(&filter.denominator);
            out.extend_from_slice(&filter.filtered_past_u);
            out.extend_from_slice(&filter.filtered_past_y);
        }
        out.push(self.imputed_regressors as f64);
        out.push(self.last_error);
        out.push(self.steps as f64);
        out
    }

    /// Restores what [`RecursiveLeastSquares::dynamic_state`] returned.
    pub fn set_dynamic_state(&mut self, state: &[f64]) -> Result<(), EstimationError> {
        let mut input = StateReader::new(state);
        input.fill(&mut self.theta)?;
        input.fill(&mut self.p)?;
        input.fill(&mut self.phi)?;
        input.fill(&mut self.past_y)?;
        input.fill(&mut self.past_u)?;
        if let Some(filter) = &mut self.prefilter {
            filter.since_refresh = input.counter()?;
            input.fill(&mut filter.denominator)?;
            input.fill(&mut filter.filtered_past_u)?;
            input.fill(&mut filter.filtered_past_y)?;
        }
        // At most na: a regressor holds na past outputs.
        self.imputed_regressors = input.counter()?.min(self.na as u64) as usize;
        self.last_error = input.scalar()?;
        self.steps = input.counter()?;
        input.finish()
    }

    /// θ = [a₁ … a_na, b₁ … b_nb].
    pub fn parameters(&self) -> &[f64] {
        &self.theta
    }
    /// a₁ … a_na.
    pub fn a(&self) -> &[f64] {
        &self.theta[..self.na]
    }
    /// b₁ … b_nb.
    pub fn b(&self) -> &[f64] {
        &self.theta[self.na..]
    }
    /// Covariance P (row-major, (na+nb)²).
    pub fn covariance(&self) -> &[f64] {
        &self.p
    }
    /// Prior prediction error ε of the last step.
    pub fn last_error(&self) -> f64 {
        self.last_error
    }
    /// Forgetting factor λ.
    pub fn forgetting_factor(&self) -> f64 {
        self.lambda
    }
    /// Number of steps processed.
    pub fn steps(&self) -> u64 {
        self.steps
    }

    /// Continuous-time readout of the current estimate (needs na = 2, nb ∈ {1, 2}); see
    /// [`ContinuousSecondOrder::from_arx`].
    pub fn continuous_second_order(
        &self,
        sample_time: f64,
    ) -> Result<ContinuousSecondOrder, EstimationError> {
        self.readout(sample_time).map_err(EstimationError::from)
    }

    /// [`RecursiveLeastSquares::continuous_second_order`] with the reason it is unavailable as a
    /// plain value: no allocation, for callers that read it every sample and report the
    /// reason rarely.
    pub fn readout(&self, sample_time: f64) -> Result<ContinuousSecondOrder, ReadoutUnavailable> {
        if self.na != 2 || !(1..=2).contains(&self.nb) {
            return Err(ReadoutUnavailable::Structure {
                na: self.na,
                nb: self.nb,
            });
        }
        ContinuousSecondOrder::readout(self.theta[0], self.theta[1], self.b(), sample_time)
    }
}

/// Why an ARX model has no continuous second-order readout
/// ([`RecursiveLeastSquares::readout`]); [`EstimationError`] carries it as a message.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ReadoutUnavailable {
    /// The model is not ARX(2, 1) or ARX(2, 2).
    Structure { na: usize, nb: usize },
    /// The sample time is not finite and > 0.
    SampleTime(f64),
    /// A pole on the negative real axis.
    NegativePole { z1: f64, z2: f64 },
    /// A pole on or outside the unit circle.
    Unstable {
        natural_frequency: f64,
        damping: f64,
        a1: f64,
        a2: f64,
    },
}

impl From<ReadoutUnavailable> for EstimationError {
    fn from(why: ReadoutUnavailable) -> Self {
        let design_error = |reason: String| EstimationError::Design {
            what: "continuous second-order readout",
            reason,
        };
        match why {
            ReadoutUnavailable::Structure { na, nb } => design_error(format!(
                "needs na = 2 and nb = 1 or 2, the model has na = {na}, nb = {nb}"
            )),
            ReadoutUnavailable::SampleTime(sample_time) => parameter_error(
                "Ts",
                format!("the sample time must be finite and > 0, got {sample_time}"),
            ),
            ReadoutUnavailable::NegativePole { z1, z2 } => design_error(format!(
                "a pole on the negative real axis (z = {z1}, {z2}) has no continuous equivalent"
            )),
            ReadoutUnavailable::Unstable {
                natural_frequency,
                damping,
                a1,
                a2,
            } => design_error(format!(
                "the model is not stable (ω_n = {natural_frequency}, ζ = {damping}): poles of \
                 z² + {a1} z + {a2} must lie inside the unit circle"
            )),
        }
    }
}

fn shift_in(history: &mut [f64], value: f64) {
    if history.is_empty() {
        return;
    }
    history.rotate_right(1);
    history[0] = value;
}

impl Prefilter {
    /// x_f(t) = x(t) − â₁ x_f(t−1) − … − â_na x_f(t−na).
    fn apply(&mut self, u: f64, y: f64) -> (f64, f64) {
        let filter = |x: f64, past: &[f64], a: &[f64]| -> f64 {
            x - a.iter().zip(past).map(|(a, p)| a * p).sum::<f64>()
        };
        let u_f = filter(u, &self.filtered_past_u, &self.denominator);
        let y_f = filter(y, &self.filtered_past_y, &self.denominator);
        shift_in(&mut self.filtered_past_u, u_f);
        shift_in(&mut self.filtered_past_y, y_f);
        (u_f, y_f)
    }

    /// [`Prefilter::apply`] for a sample whose y is missing: u is filtered, and the filtered
    /// y is the given one-step prediction `y_filtered`. Gives the filtered u and the
    /// unfiltered y that would have given `y_filtered`: y_f + Σ âᵢ y_f(t−i).
    fn apply_missing(&mut self, u: f64, y_filtered: f64) -> (f64, f64) {
        let past = |past: &[f64]| {
            let terms = self.denominator.iter().zip(past);
            terms.map(|(a, p)| a * p).sum::<f64>()
        };
        let u_f = u - past(&self.filtered_past_u);
        let y = y_filtered + past(&self.filtered_past_y);
        shift_in(&mut self.filtered_past_u, u_f);
        shift_in(&mut self.filtered_past_y, y_filtered);
        (u_f, y)
    }

    fn refresh_denominator(&mut self, a: &[f64]) {
        if polynomial_is_stable_in(a, &mut self.work) {
            self.denominator.copy_from_slice(a);
        }
    }
}

/// Whether all roots of z^na + a₁ z^{na−1} + … + a_na lie strictly inside the unit circle
/// (Jury / Schur–Cohn recursion).
fn polynomial_is_stable(a: &[f64]) -> bool {
    polynomial_is_stable_in(a, &mut Vec::with_capacity(a.len() + 1))
}

/// [`polynomial_is_stable`] in the work space `coefficients` (no allocation when it holds
/// `a.len() + 1` values): each step of the recursion replaces c by cᵢ − k c_{deg−i}, in
/// place pair by pair.
fn polynomial_is_stable_in(a: &[f64], coefficients: &mut Vec<f64>) -> bool {
    coefficients.clear();
    coefficients.push(1.0);
    coefficients.extend_from_slice(a);
    while coefficients.len() > 1 {
        let degree = coefficients.len() - 1;
        let reflection = coefficients[degree] / coefficients[0];
        if !reflection.is_finite() || reflection.abs() >= 1.0 {
            return false;
        }
        for i in 0..=degree / 2 {
            let (low, high) = (coefficients[i], coefficients[degree - i]);
            coefficients[i] = low - reflection * high;
            if i > 0 && degree - i != i {
                coefficients[degree - i] = high - reflection * low;
            }
        }
        coefficients.truncate(degree);
    }
    true
}

/// The continuous second-order equivalent K ω_n² / (s² + 2ζω_n s + ω_n²) of an ARX(2, nb)
/// model and its unit-step response figures.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ContinuousSecondOrder {
    /// Natural frequency ω_n [rad/s].
    pub natural_frequency: f64,
    /// Damping ratio ζ.
    pub damping: f64,
    /// DC gain K.
    pub dc_gain: f64,
    /// Overshoot of the step response, in percent of the final value (0 when ζ ≥ 1).
    pub overshoot_percent: f64,
    /// Time of the first peak [s] (infinite when ζ ≥ 1: no peak).
    pub peak_time: f64,
    /// 2 % settling time [s], from the step response.
    pub settling_time: f64,
}

impl ContinuousSecondOrder {
    /// From y(t) = −a₁ y(t−1) − a₂ y(t−2) + Σ bᵢ u(t−i) sampled every `sample_time` seconds.
    /// Errors when the poles have no continuous equivalent (negative real pole, pole at or
    /// outside the unit circle) or the sample time is not positive.
    pub fn from_arx(
        a1: f64,
        a2: f64,
        b: &[f64],
        sample_time: f64,
    ) -> Result<Self, EstimationError> {
        Self::readout(a1, a2, b, sample_time).map_err(EstimationError::from)
    }

    /// [`ContinuousSecondOrder::from_arx`] with the reason as a plain value.
    pub fn readout(
        a1: f64,
        a2: f64,
        b: &[f64],
        sample_time: f64,
    ) -> Result<Self, ReadoutUnavailable> {
        if !(sample_time.is_finite() && sample_time > 0.0) {
            return Err(ReadoutUnavailable::SampleTime(sample_time));
        }
        let discriminant = a1 * a1 - 4.0 * a2;
        let (natural_frequency, damping) = if discriminant < 0.0 {
            // z = r e^{±iφ}: s = (ln r ± iφ)/Ts.
            let radius = a2.sqrt();
            let angle = (-a1 / (2.0 * radius)).clamp(-1.0, 1.0).acos();
            let real = radius.ln() / sample_time;
            let imaginary = angle / sample_time;
            let wn = real.hypot(imaginary);
            (wn, -real / wn)
        } else {
            let root = discriminant.sqrt();
            let z1 = (-a1 + root) / 2.0;
            let z2 = (-a1 - root) / 2.0;
            if z1 <= 0.0 || z2 <= 0.0 {
                return Err(ReadoutUnavailable::NegativePole { z1, z2 });
            }
            let s1 = z1.ln() / sample_time;
            let s2 = z2.ln() / sample_time;
            let wn = (s1 * s2).sqrt();
            (wn, -(s1 + s2) / (2.0 * wn))
        };
        if !(natural_frequency.is_finite() && natural_frequency > 0.0 && damping > 0.0) {
            return Err(ReadoutUnavailable::Unstable {
                natural_frequency,
                damping,
                a1,
                a2,
            });
        }
        let dc_gain = b.iter().sum::<f64>() / (1.0 + a1 + a2);
        let (overshoot_percent, peak_time) = if damping < 1.0 {
            let root = (1.0 - damping * damping).sqrt();
            (
                100.0 * (-PI * damping / root).exp(),
                PI / (natural_frequency * root),
            )
        } else {
            (0.0, f64::INFINITY)
        };
        let settling_time = settling_time_2_percent(natural_frequency, damping);
        Ok(Self {
            natural_frequency,
            damping,
            dc_gain,
            overshoot_percent,
            peak_time,
            settling_time,
        })
    }

    /// Normalised step response y(t)/K of ω_n²/(s² + 2ζω_n s + ω_n²).
    pub fn normalized_step_response(&self, t: f64) -> f64 {
        normalized_step(self.natural_frequency, self.damping, t)
    }
}

/// y(t)/K for the standard second-order system (under-, critically and overdamped).
fn normalized_step(wn: f64, zeta: f64, t: f64) -> f64 {
    if t <= 0.0 {
        return 0.0;
    }
    if zeta < 1.0 - 1e-9 {
        let root = (1.0 - zeta * zeta).sqrt();
        let wd = wn * root;
        1.0 - (-zeta * wn * t).exp() * ((wd * t).cos() + zeta / root * (wd * t).sin())
    } else if zeta <= 1.0 + 1e-9 {
        1.0 - (1.0 + wn * t) * (-wn * t).exp()
    } else {
        let root = (zeta * zeta - 1.0).sqrt();
        let p1 = -wn * (zeta - root);
        let p2 = -wn * (zeta + root);
        1.0 + (p2 * (p1 * t).exp() - p1 * (p2 * t).exp()) / (p1 - p2)
    }
}

/// Last time the normalised step response leaves the ±2 % band, by bisection on the
/// response itself. Underdamped: the extrema of the error are at t_k = kπ/ω_d with size
/// Mᵏ (M the overshoot ratio); the exit lies after the last extremum above 2 %, before the
/// following zero of the error, where |error| decreases monotonically. Otherwise the
/// response is monotone.
fn settling_time_2_percent(wn: f64, zeta: f64) -> f64 {
    const BAND: f64 = 0.02;
    let error = |t: f64| (normalized_step(wn, zeta, t) - 1.0).abs();
    let (mut low, mut high) = if zeta < 1.0 - 1e-9 {
        let root = (1.0 - zeta * zeta).sqrt();
        let wd = wn * root;
        let overshoot = (-PI * zeta / root).exp();
        // Last k with overshootᵏ > BAND (k = 0 is t = 0, error 1).
        let last = if overshoot > 0.0 {
            (BAND.ln() / overshoot.ln()).ceil() - 1.0
        } else {
            0.0
        };
        let last = last.max(0.0);
        let phase = zeta.acos();
        ((last * PI) / wd, ((last + 1.0) * PI - phase) / wd)
    } else {
        let mut high = 1.0 / wn;
        while error(high) > BAND {
            high *= 2.0;
        }
        (0.0, high)
    };
    for _ in 0..200 {
        let middle = 0.5 * (low + high);
        if error(middle) > BAND {
            low = middle;
        } else {
            high = middle;
        }
        if high - low <= 1e-12 * high {
            break;
        }
    }
    0.5 * (low + high)
}

#[cfg(test)]
mod tests {
    use super::super::robust::test_rng::TestRng;
    use super::*;
    use nalgebra::DMatrix;

    const A1: f64 = -1.946793;
    const A2: f64 = 0.949424;
    const B1: f64 = 1.32665e-3;
    const B2: f64 = 1.30389e-3;

    #[test]
    fn rejects_bad_forgetting_factor() {
        for lambda in [0.0, -0.5, 1.01, f64::NAN] {
            let e = RecursiveLeastSquares::new(2, 2, lambda, 1e4).unwrap_err();
            assert!(e.to_string().contains("lambda"), "{e}");
        }
        assert!(RecursiveLeastSquares::new(2, 2, 1.0, 1e4).is_ok());
    }

    fn simulate_arx(a: [f64; 2], b: [f64; 2], inputs: &[f64]) -> Vec<f64> {
        let (mut y1, mut y2, mut u1, mut u2) = (0.0, 0.0, 0.0, 0.0);
        inputs
            .iter()
            .map(|&u| {
                let y = -a[0] * y1 - a[1] * y2 + b[0] * u1 + b[1] * u2;
                (y2, y1, u2, u1) = (y1, y, u1, u);
                y
            })
            .collect()
    }

    #[test]
    fn recovers_exact_arx_model_from_noise_free_data() {
        let (a, b) = ([-1.5, 0.7], [1.0, 0.5]);
        let mut rng = TestRng::new(3);
        let inputs: Vec<f64> = (0..300).map(|_| rng.normal()).collect();
        let outputs = simulate_arx(a, b, &inputs);
        let mut rls = RecursiveLeastSquares::new(2, 2, 1.0, 1e8).unwrap();
        for (u, y) in inputs.iter().zip(&outputs) {
            rls.step(*u, *y).unwrap();
        }
        println!("θ = {:?}", rls.parameters());
        for (estimate, truth) in rls.parameters().iter().zip([a[0], a[1], b[0], b[1]]) {
            assert!((estimate - truth).abs() < 1e-8, "{estimate} vs {truth}");
        }
        // Forgetting does not change the answer on exact data.
        let mut forgetful = RecursiveLeastSquares::new(2, 2, 0.98, 1e8).unwrap();
        for (u, y) in inputs.iter().zip(&outputs) {
            forgetful.step(*u, *y).unwrap();
        }
        for (estimate, truth) in forgetful.parameters().iter().zip([a[0], a[1], b[0], b[1]]) {
            assert!((estimate - truth).abs() < 1e-8, "{estimate} vs {truth}");
        }
    }

    /// The exact ZOH discretisation of H(s) = 27 / (s² + 5.19 s + 27) at Ts = 0.01, as ARX
    /// coefficients (a₁, a₂, b₁, b₂).
    fn op_amp_arx() -> (f64, f64, f64, f64) {
        let a = DMatrix::from_row_slice(2, 2, &[0.0, 1.0, -27.0, -5.19]);
        let b = DMatrix::from_row_slice(2, 1, &[0.0, 27.0]);
        let c = DMatrix::from_row_slice(1, 2, &[1.0, 0.0]);
        let (ad, bd) = crate::linalg::zoh(&a, &b, 0.01);
        let trace = ad.trace();
        let b1 = (&c * &bd)[(0, 0)];
        let b2 = (&c * (&ad - DMatrix::identity(2, 2) * trace) * &bd)[(0, 0)];
        (-trace, ad.determinant(), b1, b2)
    }

    #[test]
    fn op_amp_reference_readout() {
        let (a1, a2, b1, b2) = op_amp_arx();
        assert!((a1 - A1).abs() < 1e-6 && (a2 - A2).abs() < 1e-6);
        assert!((b1 - B1).abs() < 1e-8 && (b2 - B2).abs() < 1e-8);
        let readout = ContinuousSecondOrder::from_arx(a1, a2, &[b1, b2], 0.01).unwrap();
        println!("{readout:?}");
        assert!((readout.natural_frequency - 5.19615).abs() < 1e-5);
        assert!((readout.damping - 0.49941).abs() < 1e-5);
        assert!((readout.dc_gain - 1.0).abs() < 1e-9);
        assert!((readout.overshoot_percent - 16.35).abs() < 0.005);
        assert!((readout.peak_time - 0.698).abs() < 5e-4);
        assert!((readout.settling_time - 1.555).abs() < 5e-4);
        // The 6–7 digit coefficients of docs/reference-values.md §6: ω_n is sensitive to a₁ (∂ω_n/∂a₁ ≈ 1e3).
        let rounded = ContinuousSecondOrder::from_arx(A1, A2, &[B1, B2], 0.01).unwrap();
        assert!((rounded.natural_frequency - 5.19615).abs() < 1e-3);
        assert!((rounded.damping - 0.49941).abs() < 1e-4);
    }

    #[test]
    fn readout_from_rls_on_op_amp_step_data() {
        let (a1, a2, b1, b2) = op_amp_arx();
        let inputs: Vec<f64> = (0..300).map(|k| if k >= 10 { 1.0 } else { 0.0 }).collect();
        let outputs = simulate_arx([a1, a2], [b1, b2], &inputs);
        let mut rls = RecursiveLeastSquares::new(2, 2, 1.0, 1e8).unwrap();
        for (u, y) in inputs.iter().zip(&outputs) {
            rls.step(*u, *y).unwrap();
        }
        let readout = rls.continuous_second_order(0.01).unwrap();
        println!("{readout:?}");
        assert!(
            (readout.natural_frequency - 5.19615).abs() < 1e-3,
            "{readout:?}"
        );
        assert!((readout.damping - 0.49941).abs() < 1e-3, "{readout:?}");
        assert!((readout.settling_time - 1.555).abs() < 1e-2, "{readout:?}");
    }

    #[test]
    fn settling_time_of_overdamped_and_critical_systems() {
        // Critically damped, ω_n = 1: 1 − (1 + t) e^{−t} = 0.98 at t ≈ 5.8335.
        assert!((settling_time_2_percent(1.0, 1.0) - 5.8335).abs() < 1e-3);
        let t = settling_time_2_percent(2.0, 1.5);
        assert!(((normalized_step(2.0, 1.5, t) - 1.0).abs() - 0.02).abs() < 1e-9);
    }

    #[test]
    fn prefiltered_rls_removes_noise_bias() {
        // Output-error data: white noise on y. Plain RLS is biased (too much damping), the
        // Steiglitz–McBride prefilter is not.
        let mut rng = TestRng::new(5);
        let (mut y1, mut y2, mut u1, mut u2) = (0.0, 0.0, 0.0, 0.0);
        let mut plain = RecursiveLeastSquares::new(2, 2, 1.0, 1e4).unwrap();
        // λ slightly below 1 lets the estimate forget the regressors filtered with the
        // early (wrong) Â.
        let mut prefiltered = RecursiveLeastSquares::with_prefilter(2, 2, 0.999, 1e4, 50).unwrap();
        let mut u = 0.0;
        for k in 0..20_000 {
            if k % 200 == 0 {
                u = if rng.uniform() < 0.5 { 0.0 } else { 1.0 };
            }
            let y = -A1 * y1 - A2 * y2 + B1 * u1 + B2 * u2;
            let measured = y + 0.01 * rng.normal();
            plain.step(u, measured).unwrap();
            prefiltered.step(u, measured).unwrap();
            (y2, y1, u2, u1) = (y1, y, u1, u);
        }
        println!(
            "plain θ = {:?}, SM θ = {:?}",
            plain.parameters(),
            prefiltered.parameters()
        );
        // Plain RLS: so biased that the poles often have no continuous equivalent.
        let plain_biased = match plain.continuous_second_order(0.01) {
            Ok(readout) => (readout.damping / 0.49941 - 1.0).abs() > 0.1,
            Err(_) => true,
        };
        let sm_readout = prefiltered.continuous_second_order(0.01).unwrap();
        let sm_zeta_error = (sm_readout.damping / 0.49941 - 1.0).abs();
        let sm_wn_error = (sm_readout.natural_frequency / 5.19615 - 1.0).abs();
        println!(
            "Steiglitz–McBride: ω_n = {:.4} ({:.2} %), ζ = {:.4} ({:.2} %), DC gain {:.4}",
            sm_readout.natural_frequency,
            100.0 * sm_wn_error,
            sm_readout.damping,
            100.0 * sm_zeta_error,
            sm_readout.dc_gain
        );
        assert!(plain_biased);
        assert!(sm_zeta_error < 0.04, "ζ error {sm_zeta_error}");
        assert!(sm_wn_error < 0.04, "ω_n error {sm_wn_error}");
    }

    #[test]
    fn steiglitz_mcbride_iterations_identify_the_op_amp_from_one_noisy_step() {
        // Paper 002's experiment: one unit step, 10 s at Ts = 0.01, σ = 0.05 on the output.
        // Plain least squares has no continuous equivalent (a pole on the negative real
        // axis); passes with a fixed prefilter, Â taken from the previous pass, converge.
        let (a1, a2, b1, b2) = op_amp_arx();
        let inputs: Vec<f64> = (0..1000).map(|k| if k >= 50 { 1.0 } else { 0.0 }).collect();
        let clean = simulate_arx([a1, a2], [b1, b2], &inputs);
        let mut rng = TestRng::new(11);
        let measured: Vec<f64> = clean.iter().map(|y| y + 0.05 * rng.normal()).collect();
        let pass = |denominator: &[f64]| {
            let mut rls = RecursiveLeastSquares::with_prefilter(2, 2, 1.0, 1e4, 0).unwrap();
            rls.set_prefilter_denominator(denominator).unwrap();
            for (u, y) in inputs.iter().zip(&measured) {
                rls.step(*u, *y).unwrap();
            }
            assert_eq!(rls.prefilter_denominator().unwrap(), denominator);
            rls
        };
        let plain = pass(&[0.0, 0.0]);
        assert!(plain.continuous_second_order(0.01).is_err());
        let mut denominator = plain.a().to_vec();
        let mut passes = 1;
        let estimate = loop {
            let rls = pass(&denominator);
            passes += 1;
            let change = (rls.a()[0] - denominator[0]).abs() + (rls.a()[1] - denominator[1]).abs();
            denominator = rls.a().to_vec();
            if change < 1e-10 || passes == 30 {
                break rls;
            }
        };
        let readout = estimate.continuous_second_order(0.01).unwrap();
        println!("{passes} passes: {readout:?}");
        assert!(passes < 30);
        assert!(
            (readout.natural_frequency / 5.19615 - 1.0).abs() < 0.05,
            "{readout:?}"
        );
        assert!(
            (readout.damping / 0.49941 - 1.0).abs() < 0.05,
            "{readout:?}"
        );
        assert!(
            (readout.settling_time / 1.555 - 1.0).abs() < 0.1,
            "{readout:?}"
        );
        // Bad denominators are refused, naming the parameter.
        let mut rls = RecursiveLeastSquares::with_prefilter(2, 2, 1.0, 1e4, 0).unwrap();
        let unstable = rls.set_prefilter_denominator(&[-2.1, 1.1]).unwrap_err();
        assert!(unstable.to_string().contains("prefilter_a"), "{unstable}");
        assert!(rls.set_prefilter_denominator(&[0.5]).is_err());
        let mut no_prefilter = RecursiveLeastSquares::new(2, 2, 1.0, 1e4).unwrap();
        assert!(no_prefilter.set_prefilter_denominator(&[0.0, 0.0]).is_err());
    }

    /// With gaps in y, λ = 1 RLS is batch least squares over the equations that touch no
    /// missing sample (y(t) and y(t−1) … y(t−na) present; samples before the start are 0):
    /// noisy ARX(2, 2) data, 15 % of y missing, P₀ = 10⁸·I (a negligible prior).
    #[test]
    fn with_missing_samples_rls_is_least_squares_over_the_kept_equations() {
        let (a, b) = ([-1.5, 0.7], [1.0, 0.5]);
        let mut rng = TestRng::new(17);
        let inputs: Vec<f64> = (0..400).map(|_| rng.normal()).collect();
        let outputs: Vec<f64> = simulate_arx(a, b, &inputs)
            .into_iter()
            .map(|y| y + 0.3 * rng.normal())
            .collect();
        let missing: Vec<bool> = (0..400).map(|_| rng.uniform() < 0.15).collect();
        let mut rls = RecursiveLeastSquares::new(2, 2, 1.0, 1e8).unwrap();
        for k in 0..400 {
            let y = if missing[k] { f64::NAN } else { outputs[k] };
            rls.step(inputs[k], y).unwrap();
        }
        let at = |v: &[f64], k: usize, lag: usize| if k >= lag { v[k - lag] } else { 0.0 };
        let gone = |k: usize, lag: usize| k >= lag && missing[k - lag];
        let (mut normal, mut right) = (DMatrix::<f64>::zeros(4, 4), DMatrix::<f64>::zeros(4, 1));
        let mut kept = 0;
        for k in 0..400 {
            if (0..=2).any(|lag| gone(k, lag)) {
                continue;
            }
            kept += 1;
            let phi = DMatrix::from_row_slice(
                4,
                1,
                &[
                    -at(&outputs, k, 1),
                    -at(&outputs, k, 2),
                    at(&inputs, k, 1),
                    at(&inputs, k, 2),
                ],
            );
            normal += &phi * phi.transpose();
            right += &phi * outputs[k];
        }
        let batch = normal.cholesky().unwrap().solve(&right);
        println!(
            "{kept} equations kept; RLS θ = {:?}, batch θ = {batch}",
            rls.parameters()
        );
        assert!(kept < 260, "{kept}");
        for (estimate, least_squares) in rls.parameters().iter().zip(batch.iter()) {
            assert!(
                (estimate - least_squares).abs() < 1e-6,
                "{estimate} vs {least_squares}"
            );
        }
    }

    #[test]
    fn stability_test_of_polynomials() {
        assert!(polynomial_is_stable(&[A1, A2]));
        assert!(!polynomial_is_stable(&[-2.1, 1.1]));
        assert!(polynomial_is_stable(&[]));
    }
}
