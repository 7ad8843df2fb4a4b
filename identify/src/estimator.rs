//! The robust online filter one sample at a time, as an estimator FMU runs it in each
//! `DoStep`: the joint filter of [`crate::online`] (the same set-up as `spurio identify
//! --method ukf|ekf`, so both give the same θ̂ on the same record) on a plant FMU opened from
//! its folder (as the estimator FMU carries it) or archive, inputs u and measurements y in,
//! one output vector out
//! (docs/estimators.md, "Identifying an FMU"):
//!
//! ```text
//! [ ẑ = [x̂; θ̂] (L) ; √diag P (L) ; e = y − ŷ (p) ; √S_jj (p) ; w (p) ],   L = n + q
//! ```
//!
//! A missing measurement (NaN) is not corrected on: its innovation, innovation deviation and
//! weight are given as 0 (an FMU output is finite). Any other value that is not finite is an
//! error naming the output and the time, never an output.

use crate::filter::{Filter, FilterError, FilterState};

/// Why a sample failed.
#[derive(Debug, thiserror::Error)]
pub enum EstimatorError {
    #[error("the filter: {0}")]
    Filter(#[from] FilterError),
    #[error("{given} inputs and {measured} measurements given at t = {time}; the estimator has {inputs} inputs and {outputs} measured outputs")]
    Sample {
        given: usize,
        measured: usize,
        inputs: usize,
        outputs: usize,
        time: f64,
    },
    #[error("output {index} of the estimator is not finite at t = {time}")]
    NotFinite { index: usize, time: f64 },
}

/// The online filter on a plant FMU, one sample per call (module documentation). A clone
/// (an estimator FMU's FMU state) shares the plant ([`Filter`]).
#[derive(Debug, Clone)]
pub struct Estimator {
    filter: Filter,
    /// The outputs of the last sample.
    column: Vec<f64>,
    inputs: usize,
    outputs: usize,
}

impl Estimator {
    /// The estimator running `filter` (set up by [`crate::online::joint_filter`], as
    /// `spurio identify` sets it up) on a plant with `inputs` inputs.
    pub fn new(filter: Filter, inputs: usize) -> Self {
        let outputs = filter.measured();
        let column = vec![0.0; 2 * filter.filter_states() + 3 * outputs];
        Self {
            filter,
            column,
            inputs,
            outputs,
        }
    }

    /// L = n + q: the rows of ẑ (the states, then the free parameters).
    pub fn filter_states(&self) -> usize {
        self.filter.filter_states()
    }

    /// The filter: ẑ and P before the next sample.
    pub fn filter(&self) -> &Filter {
        &self.filter
    }

    /// The length of the output vector, 2L + 3p.
    pub fn outputs(&self) -> usize {
        self.column.len()
    }

    /// The output vector of the last sample (zeros before the first).
    pub fn last_outputs(&self) -> &[f64] {
        &self.column
    }

    /// Restores the filter's `state` ([`Filter::restore`]) and the output vector of its last
    /// sample, `outputs`, into an estimator set up alike: it then continues bit for bit.
    pub fn restore(&mut self, state: &FilterState, outputs: &[f64]) -> Result<(), EstimatorError> {
        if outputs.len() != self.column.len() {
            return Err(FilterError::Settings(format!(
                "a restored state has {} outputs of its last sample; the estimator has {}",
                outputs.len(),
                self.column.len()
            ))
            .into());
        }
        self.filter.restore(state)?;
        self.column.copy_from_slice(outputs);
        Ok(())
    }

    /// Processes the sample at `time` (inputs `u`, measurements `y`, NaN where missing) and
    /// gives the output vector (module documentation), every value finite.
    pub fn step(&mut self, time: f64, u: &[f64], y: &[f64]) -> Result<&[f64], EstimatorError> {
        if u.len() != self.inputs || y.len() != self.outputs {
            return Err(EstimatorError::Sample {
                given: u.len(),
                measured: y.len(),
                inputs: self.inputs,
                outputs: self.outputs,
                time,
            });
        }
        self.filter.process(time, u, y, &mut self.column)?;
        let l = self.filter.filter_states();
        let p = self.outputs;
        for (j, yj) in y.iter().enumerate() {
            if yj.is_nan() {
                for block in 0..3 {
                    self.column[2 * l + block * p + j] = 0.0;
                }
            }
        }
        if let Some(index) = self.column.iter().position(|v| !v.is_finite()) {
            return Err(EstimatorError::NotFinite { index, time });
        }
        Ok(&self.column)
    }
}
