//! The one adapter of the Kalman family's filters behind an [`EstimatorFmu`]
//! (docs/estimators.md §2.7–§2.10): a [`FilterFamily`] says how its filter is built from the
//! parameters and what it writes; [`Filtered`] reads the inputs `u[i]`, `y[j]` of a sample
//! into buffers of fixed size (a non-finite one is an error naming it, before the filter is
//! touched), marks `y[j]` missing (NaN) where `y_valid[j]` is false, steps the filter and
//! writes its outputs.
//!
//! [`EstimatorFmu`]: spurio_fmu_common::estimator::EstimatorFmu

use crate::model::Dimensions;
use nalgebra::DVector;
use spurio::estimation::{EstimationError, StateEstimator};
use spurio_export::{Cause, Config, Context, Failure, ModelInfo, Values};
use spurio_fmu_common::estimator::{
    copy_inputs, error, mark_missing, read_inputs, DynamicState, Estimator,
};
use spurio_fmu_common::structured::Block;
use std::marker::PhantomData;

/// The value references every variant of the family has, whatever its filter: its
/// dimensions, the inputs `u[i]`, `y[j]` and `y_valid[j]`, and the estimates `x_hat[i]`,
/// `y_hat[j]`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SignalBlocks {
    pub dims: Dimensions,
    pub u: Block,
    pub y: Block,
    /// The Boolean inputs `y_valid[j]` ([`add_validity`], last in the table).
    ///
    /// [`add_validity`]: spurio_fmu_common::estimator::add_validity
    pub y_valid: Block,
    pub x_hat: Block,
    pub y_hat: Block,
}

/// A variant's layout holds its [`SignalBlocks`]: where the adapter reads the inputs.
pub trait Signals {
    /// The blocks of the inputs and estimates.
    fn signals(&self) -> &SignalBlocks;
}

/// A family of filters behind the one [`Filtered`] adapter, implemented by the family's
/// variable layout for each filter `F` it holds (the linear-model filters' [`LinearLayout`],
/// the dual filters' [`DualLayout`]): its variables, where its inputs are, how its filter is
/// built from the parameters, and what the filter writes.
///
/// [`LinearLayout`]: crate::linear::LinearLayout
/// [`DualLayout`]: crate::dual::DualLayout
pub trait FilterFamily<F>: Signals + Sized + Clone + std::fmt::Debug + 'static {
    /// The layout (value references of one variant's variables) and model description for a
    /// configuration.
    fn interface(config: &Config) -> Result<(Self, ModelInfo), Cause>;
    /// Reads and checks the parameters, builds the filter.
    fn build(&self, values: &Values) -> Result<F, Failure>;
    /// Reads the filter's inputs other than `u[i]`, `y[j]` before a step (none by default).
    fn read_inputs(&self, filter: &mut F, values: &Values) -> Result<(), Failure> {
        let _ = (filter, values);
        Ok(())
    }
    /// Writes the outputs before the first step.
    fn write_initial(&self, filter: &F, ctx: &mut Context);
    /// Writes the outputs after a step.
    fn write_outputs(&self, filter: &F, values: &mut Values);
}

/// The one adapter of the filter families: the filter `F` of the family `L` and its input
/// buffers.
#[derive(Debug, Clone)]
pub struct Filtered<L, F> {
    filter: F,
    u: DVector<f64>,
    y: DVector<f64>,
    family: PhantomData<L>,
}

impl<L, F> Filtered<L, F> {
    /// The filter.
    pub fn filter(&self) -> &F {
        &self.filter
    }
}

impl<L, F> Estimator for Filtered<L, F>
where
    L: FilterFamily<F>,
    F: StateEstimator + Clone + std::fmt::Debug + 'static,
{
    type Layout = L;
    fn interface(config: &Config) -> Result<(L, ModelInfo), Cause> {
        L::interface(config)
    }

    fn build(layout: &L, values: &Values) -> Result<Self, Failure> {
        let SignalBlocks { u, y, .. } = layout.signals();
        Ok(Self {
            filter: layout.build(values)?,
            u: DVector::zeros(u.indices().len()),
            y: DVector::zeros(y.indices().len()),
            family: PhantomData,
        })
    }

    fn write_initial(&self, layout: &L, ctx: &mut Context) {
        layout.write_initial(&self.filter, ctx);
    }

    fn step(&mut self, l: &L, ctx: &mut Context, _: f64, _: f64) -> Result<(), Failure> {
        let SignalBlocks { u, y, y_valid, .. } = l.signals();
        if !(copy_inputs(ctx.values, u, &mut self.u) && copy_inputs(ctx.values, y, &mut self.y)) {
            // A non-finite input (or buffers of another size): the message names it.
            read_inputs(ctx.values, u, "u", &mut self.u)?;
            read_inputs(ctx.values, y, "y", &mut self.y)?;
        }
        mark_missing(ctx.values, y_valid, &mut self.y);
        l.read_inputs(&mut self.filter, ctx.values)?;
        self.filter.step(&self.u, &self.y).map_err(error)?;
        l.write_outputs(&self.filter, ctx.values);
        Ok(())
    }
}

impl<L, F: StateEstimator> DynamicState for Filtered<L, F> {
    fn dynamic_state(&self) -> Vec<f64> {
        StateEstimator::dynamic_state(&self.filter)
    }
    fn set_dynamic_state(&mut self, state: &[f64]) -> Result<(), EstimationError> {
        StateEstimator::set_dynamic_state(&mut self.filter, state)
    }
}
