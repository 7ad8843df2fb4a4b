//! The stepping algorithm: how the instances of a system exchange values and advance in time.
//!
//! An [`Algorithm`] is consulted once when a system is compiled (which order the connected
//! inputs are set and the direct-feedthrough outputs re-read in at a communication point) and
//! then drives a running [`Exchange`] through initialisation, every base step and the end of
//! the run. The plan compiler ([`crate::plan`]) sees only the first half ([`Propagation`],
//! which [`Algorithm`] extends) and the run loop ([`crate::Simulation`]) only the trait: a new algorithm (an identification loop that repeats steps) is a new implementation given to [`crate::System::set_algorithm`], with no
//! edit to either.
//!
//! The built-in algorithms are the two fixed-step co-simulation schemes (docs/engine.md):
//! [`GaussSeidel`] (values flow through the direct-feedthrough graph within a communication
//! point) and [`Jacobi`] (every input gets the value its source had after the previous step).

use crate::coupling::propagation_order;
use crate::coupling::{Connection, Propagation, PropagationStep, ResolvedInstance};
use crate::description::AlgorithmName;
use crate::error::{RunError, SystemError};
use crate::exchange::{Exchange, StepOutcome};
use std::any::Any;
use std::sync::Arc;

/// A stepping algorithm.
///
/// # Call order
///
/// The engine calls these methods in a fixed order, as libcosim's `algorithm` interface
/// guarantees its own:
///
/// 1. [`Propagation::propagation`] and [`Propagation::refreshes_records`] (the half of an
///    algorithm the plan compiler sees): once per compilation of the system (when it is
///    loaded, edited by name, given an algorithm or told to record nothing), before any
///    instance exists. Their
///    answers are laid out in the plan's set/get batches.
/// 2. [`Algorithm::initialize`]: once per [`crate::Simulation`], after every instance has been
///    instantiated, set up, given its start values and has entered initialisation mode; it
///    must leave every instance out of initialisation mode.
/// 3. For each base step k = 0, 1, …, steps − 1 (t_k = start + k·h), while no instance asked
///    to end the run:
///    1. [`Algorithm::communicate`] at t_k: makes the inputs of the instances due at k hold
///       their values for t_k;
///    2. the observer receives the recorded values (the engine; every output interval);
///    3. [`Algorithm::step`] at t_k: advances the instances due at k to t_k + m·h (m: the
///       instance's step multiple) and says whether one asked to end the run.
/// 4. [`Algorithm::finish`]: once, with the time the run ended at; it must leave the buffer
///    holding every recorded value at that time (the engine records it as the last point).
///
/// A method that returns an error ends the run with that error (the engine then records
/// nothing more). The methods take `&self`, and one algorithm value serves every simulation
/// of a system and of its clones (a sweep runs them on several threads at once): an
/// algorithm that keeps state between calls keeps it behind a lock and tells simulations
/// apart itself. The built-in ones keep none.
pub trait Algorithm: Propagation + Any {
    /// Its name, as a system file writes it (`algorithm = "gauss-seidel"`).
    fn name(&self) -> &str;

    /// Leaves initialisation mode: by default the initial outputs are read, propagated along
    /// the connections, every instance leaves initialisation mode, and the outputs are read
    /// again.
    fn initialize(&self, exchange: &mut Exchange, time: f64) -> Result<(), RunError> {
        exchange.read_all("fmi2Get* (initial outputs)", time)?;
        exchange.propagate(0, true)?;
        exchange.exit_initialization_mode(time)?;
        exchange.read_all("fmi2Get* (initial outputs)", time)
    }

    /// The exchange at communication point t_k = `time` of base step `k`: by default the
    /// outputs of the instances whose step ends at k are read (a multirate instance holds its
    /// outputs in between; at k = 0 they were read by [`Algorithm::initialize`]), then the
    /// plan's propagation runs for the instances due at k.
    #[inline(always)]
    fn communicate(&self, exchange: &mut Exchange, k: u64, time: f64) -> Result<(), RunError> {
        if k > 0 {
            exchange.read_outputs(k, time)?;
        }
        exchange.propagate(k, false)
    }

    /// Base step `k` from `time`: by default every due instance does one co-simulation step
    /// over its multiple of the step size.
    #[inline(always)]
    fn step(&self, exchange: &mut Exchange, k: u64, time: f64) -> Result<StepOutcome, RunError> {
        exchange.step_due(k, time)
    }

    /// The end of the run at `read_time` (where the last steps ended): by default every
    /// output is read and propagated to every instance.
    fn finish(&self, exchange: &mut Exchange, read_time: f64) -> Result<(), RunError> {
        exchange.read_outputs(0, read_time)?;
        let steps = exchange.steps();
        exchange.propagate(steps, true)
    }
}

/// Fixed-step Gauss–Seidel: at a communication point, outputs flow to inputs in the order of
/// the direct-feedthrough graph ([`propagation_order`]), so values pass through sensors and
/// estimators within the same point; a loop of direct-feedthrough variables is an error.
#[derive(Debug, Clone, Copy, Default)]
pub struct GaussSeidel;

impl Algorithm for GaussSeidel {
    fn name(&self) -> &str {
        "gauss-seidel"
    }
}

impl Propagation for GaussSeidel {
    fn propagation(
        &self,
        instances: &[ResolvedInstance],
        connections: &[Connection],
    ) -> Result<Vec<PropagationStep>, SystemError> {
        propagation_order(instances, connections)
    }

    /// A record holds the values that belong to the point (e.g. a Sensor's `y_clean`, which
    /// feeds no connection, for the input just set) rather than those read after the last
    /// step.
    fn refreshes_records(&self) -> bool {
        true
    }
}

/// Fixed-step Jacobi: every input gets the value its source had after the previous step (a
/// one-step delay on direct-feedthrough paths; what fmpy's SSP runner does), set in the order
/// the connections are given.
#[derive(Debug, Clone, Copy, Default)]
pub struct Jacobi;

impl Algorithm for Jacobi {
    fn name(&self) -> &str {
        "jacobi"
    }
}

impl Propagation for Jacobi {
    fn propagation(
        &self,
        _: &[ResolvedInstance],
        connections: &[Connection],
    ) -> Result<Vec<PropagationStep>, SystemError> {
        Ok(connections
            .iter()
            .map(|c| PropagationStep::SetInput(c.to))
            .collect())
    }

    /// A record keeps the values read after the step, as fmpy's SSP runner does.
    fn refreshes_records(&self) -> bool {
        false
    }
}

/// The built-in algorithm a system file names.
pub fn named(name: AlgorithmName) -> Arc<dyn Algorithm> {
    match name {
        AlgorithmName::GaussSeidel => Arc::new(GaussSeidel),
        AlgorithmName::Jacobi => Arc::new(Jacobi),
    }
}
