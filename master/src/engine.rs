//! The run loop: a system's stepping algorithm ([`crate::algorithm`]) driven from the start
//! to the stop time, multirate, by index, with the recorded values sent to an observer.
//!
//! [`Simulation::new`] instantiates every instance on the calling thread, sets start values
//! by value reference, initialises, and follows the system's compiled plan (names were
//! turned into value references and buffer slots once, in [`crate::plan`]). The loop then
//! only moves numbers (the built-in algorithms, Gauss–Seidel and Jacobi):
//!
//! 1. at each communication point t_k, the connected inputs are set from their sources (for
//!    Gauss–Seidel in the order of the direct-feedthrough graph, re-reading feedthrough outputs
//!    as their inputs change, so values flow through sensors and estimators within the same
//!    point; for Jacobi from the values read after the previous step);
//! 2. the recorded variables are sent to the observer;
//! 3. every instance whose multiple divides k steps over `multiple · h`; its outputs are read
//!    at the communication point where that step ends (a multirate instance holds its outputs
//!    in between).
//!
//! An instance whose `fmi2DoStep` returns `fmi2Discard` with `fmi2GetBooleanStatus(
//! fmi2Terminated)` = true, or whose `fmi3DoStep` (or, with event mode, the event iteration
//! after it: [`crate::fmu::Instance::do_step`]) sets `terminateSimulation`, asks to end the
//! simulation (as the Reference FMU `Stair` does; fmpy, OMSimulator and the FMU Compliance
//! Checker stop there too): the run ends normally at that instance's last successful time
//! (FMI 3.0: the end of the step unless it says otherwise), records that point and says
//! why it ended ([`RunEnd::Terminated`]). Any other `fmi2Discard`/`fmi3Discard`, an error, an
//! FMI 3.0 `earlyReturn` (never allowed), `eventHandlingNeeded` from an FMU without event mode,
//! or an event iteration that fails or does not settle stop the run with an error naming the
//! instance, the FMU file, the call and the time, quoting what that instance logged; when
//! several instances fail in the same step (or in initialisation, or in terminate), the error
//! names every one of them.
//!
//! A simulation made with [`Simulation::with_monitor`] notes every FMI call it enters and
//! leaves in a [`CallMonitor`], so that a watchdog on another thread can name a call that
//! does not return (the instance, its FMU, the call, the time); what to do then is the
//! caller's (the CLI ends the process, keeping the results so far).

use crate::algorithm::{Algorithm, GaussSeidel, Jacobi};
use crate::error::{RunError, SystemError};
use crate::exchange::{due_at, Exchange, StepOutcome};
use crate::fmu::{FmiVersion, Interface};
use crate::monitor::CallMonitor;
use crate::record::Observer;
use crate::system::System;
use std::any::Any;
use std::sync::Arc;
use std::time::{Duration, Instant};

/// Options of a run.
#[derive(Debug, Clone, Default)]
pub struct RunOptions {
    /// Pace the simulation to wall-clock time divided by this factor (1 = real time).
    pub real_time_factor: Option<f64>,
    /// Send every `output_interval`-th communication point to the observer (0 and 1: every
    /// one); the start and the last point are always sent.
    pub output_interval: u64,
}

/// How a run ended.
#[derive(Debug, Clone, PartialEq)]
pub enum RunEnd {
    /// Every instance reached the stop time.
    StopTime { time: f64 },
    /// An instance asked to end the simulation (FMI 2.0: `fmi2DoStep` returned
    /// `fmi2Discard` and `fmi2GetBooleanStatus(fmi2Terminated)` is true; FMI 3.0:
    /// `fmi3DoStep` set `terminateSimulation`); the run ended at `time`, its last successful
    /// time, which is the last recorded point.
    Terminated {
        instance: String,
        time: f64,
        version: FmiVersion,
        /// Model Exchange: `fmi2NewDiscreteStates`/`fmi3UpdateDiscreteStates` or
        /// `CompletedIntegratorStep` set `terminateSimulation`.
        interface: Interface,
    },
}

impl std::fmt::Display for RunEnd {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::StopTime { time } => write!(f, "the run reached its stop time t = {time}"),
            Self::Terminated {
                instance,
                time,
                version,
                interface,
            } => write!(
                f,
                "instance `{instance}` asked to end the simulation at t = {time} ({})",
                match (interface, version) {
                    (Interface::ModelExchange, _) =>
                        "Model Exchange: terminateSimulation = true in an event or an integrator step",
                    (_, FmiVersion::Fmi2) =>
                        "fmi2DoStep returned fmi2Discard with fmi2Terminated = true",
                    (_, FmiVersion::Fmi3) =>
                        "fmi3DoStep, or the event iteration after it, returned \
                         terminateSimulation = true",
                }
            ),
        }
    }
}

/// A system ready to run: instances created, names resolved to indices.
pub struct Simulation {
    exchange: Exchange,
    algorithm: Arc<dyn Algorithm>,
    record_names: Vec<String>,
    record_slots: Vec<usize>,
    record_values: Vec<f64>,
    start_time: f64,
    step_size: f64,
    stop_time: f64,
    /// Where the run ended (the stop time until it has run).
    end_time: f64,
}

impl Simulation {
    /// Instantiates and initialises every instance of `system` on this thread.
    pub fn new(system: &System) -> Result<Self, RunError> {
        Self::with_monitor(system, None)
    }

    /// [`Simulation::new`], noting every FMI call (from `fmi2Instantiate` on) in `monitor`.
    pub fn with_monitor(
        system: &System,
        monitor: Option<Arc<CallMonitor>>,
    ) -> Result<Self, RunError> {
        let plan = system.plan();
        let t0 = system.start_time();
        let mut exchange = Exchange::instantiate(
            system.instances(),
            plan,
            (t0, system.stop_time(), system.step_size()),
            monitor,
        )?;
        let algorithm = system.algorithm().clone();
        // Initial values flow through the connections in initialization mode, then every
        // instance leaves it.
        algorithm.initialize(&mut exchange, t0)?;
        Ok(Self {
            exchange,
            algorithm,
            record_names: plan.recorded.names.clone(),
            record_slots: plan.recorded.slots.clone(),
            record_values: vec![0.0; plan.recorded.vars.len()],
            start_time: t0,
            step_size: system.step_size(),
            stop_time: system.stop_time(),
            end_time: system.stop_time(),
        })
    }

    /// The names of the recorded variables.
    pub fn recorded_names(&self) -> &[String] {
        &self.record_names
    }

    /// Number of base steps the run takes.
    pub fn step_count(&self) -> u64 {
        self.exchange.steps()
    }

    fn record(&mut self, observer: &mut dyn Observer, time: f64) -> Result<(), RunError> {
        let buffer = self.exchange.buffer();
        for (v, s) in self.record_values.iter_mut().zip(&self.record_slots) {
            *v = buffer[*s];
        }
        observer.sample(time, &self.record_values)?;
        Ok(())
    }

    /// Runs to the stop time (or until an instance asks to end the simulation), sending the
    /// recorded variables to `observer` at every communication point (every
    /// [`RunOptions::output_interval`]-th one; start time and last point included), and says
    /// how the run ended. The algorithm's methods are called in the order its trait documents
    /// ([`Algorithm`]); the loop is compiled for each built-in algorithm, so that they cost no
    /// virtual call per step.
    pub fn run(
        &mut self,
        observer: &mut dyn Observer,
        options: &RunOptions,
    ) -> Result<RunEnd, RunError> {
        let algorithm = self.algorithm.clone();
        let any: &dyn Any = algorithm.as_ref();
        if let Some(a) = any.downcast_ref::<GaussSeidel>() {
            self.run_with(a, observer, options)
        } else if let Some(a) = any.downcast_ref::<Jacobi>() {
            self.run_with(a, observer, options)
        } else {
            self.run_with(algorithm.as_ref(), observer, options)
        }
    }

    /// [`Simulation::run`] with `algorithm`.
    fn run_with<A: Algorithm + ?Sized>(
        &mut self,
        algorithm: &A,
        observer: &mut dyn Observer,
        options: &RunOptions,
    ) -> Result<RunEnd, RunError> {
        if let Some(factor) = options.real_time_factor {
            if !(factor.is_finite() && factor > 0.0) {
                return Err(SystemError::Invalid(format!(
                    "the real-time factor must be a positive number, got {factor}"
                ))
                .into());
            }
        }
        observer.start(&self.record_names)?;
        let wall_start = Instant::now();
        let every = options.output_interval.max(1);
        let steps = self.exchange.steps();
        for k in 0..steps {
            let time = self.start_time + k as f64 * self.step_size;
            algorithm.communicate(&mut self.exchange, k, time)?;
            if due_at(k, every) {
                self.record(observer, time)?;
            }
            if let StepOutcome::Terminated(asked) = algorithm.step(&mut self.exchange, k, time)? {
                // The run ends where the earliest of them stopped: every output is read
                // there and recorded as the last point.
                let (instance, end, version, interface) = asked
                    .into_iter()
                    .reduce(|first, other| if first.1 <= other.1 { first } else { other })
                    .unwrap_or((
                        String::new(),
                        time,
                        FmiVersion::Fmi2,
                        Interface::CoSimulation,
                    ));
                self.finish(algorithm, observer, end, end)?;
                return Ok(RunEnd::Terminated {
                    instance,
                    time: end,
                    version,
                    interface,
                });
            }
            if let Some(factor) = options.real_time_factor {
                // A due time beyond Duration's range (a tiny factor) is never reached.
                let due =
                    Duration::try_from_secs_f64((time + self.step_size - self.start_time) / factor)
                        .unwrap_or(Duration::MAX);
                if let Some(wait) = due.checked_sub(wall_start.elapsed()) {
                    std::thread::sleep(wait);
                }
            }
        }
        let last = self.start_time + steps as f64 * self.step_size;
        // Every instance's last step ends at the stop time.
        let end = last.min(self.stop_time);
        self.finish(algorithm, observer, last, end)?;
        Ok(RunEnd::StopTime { time: end })
    }

    /// Ends a run: the algorithm's finish at `read_time`, the buffer recorded as the last
    /// point at `end`, the observer finished.
    fn finish<A: Algorithm + ?Sized>(
        &mut self,
        algorithm: &A,
        observer: &mut dyn Observer,
        read_time: f64,
        end: f64,
    ) -> Result<(), RunError> {
        algorithm.finish(&mut self.exchange, read_time)?;
        self.record(observer, end)?;
        observer.finish()?;
        self.end_time = end;
        Ok(())
    }

    /// Terminates every instance (they are freed when the simulation is dropped); reports
    /// every instance that fails to.
    pub fn terminate(&mut self) -> Result<(), RunError> {
        self.exchange.terminate(self.end_time)
    }
}
