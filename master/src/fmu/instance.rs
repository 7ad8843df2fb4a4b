//! One Co-Simulation instance, FMI 2.0 or FMI 3.0, behind one set of calls: the engine
//! moves values as f64 and steps without knowing the version. The FMI 3.0 typed getters
//! and setters (`Float32`, `Int8` … `UInt64`, `Boolean`, Enumerations as `Int64`) convert at
//! this boundary; an FMI 3.0 array is moved whole (`nValues` = its element count).

use super::{CsInstance, FmiVersion, VarType};
use crate::logging::LogKey;
use fmi::fmi2::instance::{CoSimulation as _, Common as _};
use fmi::fmi2::Fmi2Error;
use fmi::fmi3::{CoSimulation as _, Fmi3Error, GetSet as _};

/// A failed FMI call: the status it returned, named as its version names it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct CallError(pub String);

impl From<Fmi2Error> for CallError {
    fn from(e: Fmi2Error) -> Self {
        Self(match e {
            Fmi2Error::Discard => "fmi2Discard".into(),
            Fmi2Error::Error => "fmi2Error".into(),
            Fmi2Error::Fatal => "fmi2Fatal".into(),
            other => other.to_string(),
        })
    }
}

impl From<Fmi3Error> for CallError {
    fn from(e: Fmi3Error) -> Self {
        Self(
            match e {
                Fmi3Error::Discard => "fmi3Discard",
                Fmi3Error::Error => "fmi3Error",
                Fmi3Error::Fatal => "fmi3Fatal",
            }
            .into(),
        )
    }
}

/// How a step ended.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum StepEnd {
    /// The step reached its end.
    Completed,
    /// The instance asked to end the simulation (FMI 2.0: `fmi2Discard` with
    /// `fmi2Terminated`; FMI 3.0: `terminateSimulation`), its last successful time if it
    /// said one.
    Terminate(Option<f64>),
}

/// Why a step that returned OK cannot be taken as done.
#[derive(Debug, Clone, PartialEq)]
pub enum StepProblem {
    Failed(CallError),
    /// `earlyReturn` = true although early return was not allowed (the master instantiates
    /// without it).
    EarlyReturn {
        last_successful_time: f64,
    },
    /// `eventHandlingNeeded` = true from an instance instantiated without event mode (its
    /// `<CoSimulation>` does not declare `hasEventMode="true"`).
    EventHandlingNeeded,
    /// The event handling after the step, at `time`, failed: `call` (`fmi3EnterEventMode`,
    /// `fmi3UpdateDiscreteStates`, `fmi3EnterStepMode`) did not succeed, or the event
    /// iteration did not settle within [`EVENT_ITERATION_LIMIT`].
    Event {
        call: &'static str,
        error: CallError,
        time: f64,
    },
}

/// The most `fmi3UpdateDiscreteStates` calls of one event iteration (one super-dense time
/// instant, FMI 3.0 §3.2 and §4.2): an iteration still asking for another update after as
/// many is an error, as the Model Exchange driver's default bound.
pub const EVENT_ITERATION_LIMIT: usize = 1000;

impl From<CallError> for StepProblem {
    fn from(e: CallError) -> Self {
        Self::Failed(e)
    }
}

/// A Co-Simulation instance of either version, with the key its messages are kept under.
pub struct Instance {
    inner: CsInstance,
    log: LogKey,
    /// Scratch space of the calls whose values are not f64 (no allocation per call).
    scratch: Scratch,
    /// FMI 3.0, instantiated with `eventModeUsed = true`: the master runs the event
    /// iterations (after initialisation and after every step that needs one).
    event_mode: bool,
}

impl std::fmt::Debug for Instance {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "Instance(FMI {}, {})",
            self.version().number(),
            self.log.instance_name()
        )
    }
}

/// The experiment an instance is initialized for: FMI 2.0 takes it in
/// `fmi2SetupExperiment`, FMI 3.0 in `fmi3EnterInitializationMode`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Experiment {
    /// The tolerance, if one is asked for.
    pub tolerance: Option<f64>,
    /// The start time.
    pub start: f64,
    /// The stop time, if one is defined.
    pub stop: Option<f64>,
}

/// FMI 3.0 getters into f64: `$get` for the element type `$t`, through the scratch buffer
/// of that type.
macro_rules! get3 {
    ($inst:expr, $vrs:expr, $out:expr, $scratch:expr, $get:ident, $set:ident, $t:ident) => {{
        let v = scratch(&mut $scratch.$t, $out.len());
        $inst.$get($vrs, v)?;
        for (o, x) in $out.iter_mut().zip(v.iter()) {
            *o = *x as f64;
        }
    }};
}

/// FMI 3.0 setters from f64 (rounded to the nearest integer for the integer types), through
/// the scratch buffer of the element type.
macro_rules! set3 {
    ($inst:expr, $vrs:expr, $values:expr, $scratch:expr, $get:ident, $set:ident, $t:ident) => {{
        let v = scratch(&mut $scratch.$t, $values.len());
        for (o, x) in v.iter_mut().zip($values) {
            *o = x.round() as $t;
        }
        $inst.$set($vrs, v)?;
    }};
}

/// The values of one call in the element type of an FMI 3.0 getter or setter, one buffer per
/// type, grown to the largest call and then reused: a get or set allocates nothing once the
/// first call of each size has been made.
#[derive(Debug, Default)]
pub(crate) struct Scratch {
    f32: Vec<f32>,
    bool: Vec<bool>,
    i8: Vec<i8>,
    u8: Vec<u8>,
    i16: Vec<i16>,
    u16: Vec<u16>,
    i32: Vec<i32>,
    u32: Vec<u32>,
    i64: Vec<i64>,
    u64: Vec<u64>,
}

/// The first `n` elements of `buffer`, grown if needed.
fn scratch<T: Default + Clone>(buffer: &mut Vec<T>, n: usize) -> &mut [T] {
    if buffer.len() < n {
        buffer.resize(n, T::default());
    }
    &mut buffer[..n]
}

/// The FMI 3.0 integer types (and enumerations, Int64 in FMI 3.0) with their getter, setter
/// and element type: `$apply!(args, getter, setter, type)` for the one `$t` is, `$other`
/// for every other type.
macro_rules! fmi3_integer {
    ($t:expr, $apply:ident!($($args:tt)*), $other:expr) => {
        match $t {
            VarType::Int8 => $apply!($($args)*, get_int8, set_int8, i8),
            VarType::UInt8 => $apply!($($args)*, get_uint8, set_uint8, u8),
            VarType::Int16 => $apply!($($args)*, get_int16, set_int16, i16),
            VarType::UInt16 => $apply!($($args)*, get_uint16, set_uint16, u16),
            VarType::Integer => $apply!($($args)*, get_int32, set_int32, i32),
            VarType::UInt32 => $apply!($($args)*, get_uint32, set_uint32, u32),
            VarType::Int64 | VarType::Enumeration => $apply!($($args)*, get_int64, set_int64, i64),
            VarType::UInt64 => $apply!($($args)*, get_uint64, set_uint64, u64),
            _ => $other,
        }
    };
}

impl Instance {
    pub(super) fn fmi2(instance: fmi::fmi2::instance::InstanceCS, log: LogKey) -> Self {
        Self {
            inner: CsInstance::Fmi2(Box::new(instance)),
            log,
            scratch: Scratch::default(),
            event_mode: false,
        }
    }

    /// An FMI 3.0 instance; `event_mode`: it was instantiated with `eventModeUsed = true`.
    pub(super) fn fmi3(
        instance: fmi::fmi3::instance::InstanceCS,
        log: LogKey,
        event_mode: bool,
    ) -> Self {
        Self {
            inner: CsInstance::Fmi3(Box::new(instance)),
            log,
            scratch: Scratch::default(),
            event_mode,
        }
    }

    /// The FMI version of the instance.
    pub fn version(&self) -> FmiVersion {
        match self.inner {
            CsInstance::Fmi2(_) => FmiVersion::Fmi2,
            CsInstance::Fmi3(_) => FmiVersion::Fmi3,
        }
    }

    /// The rust-fmi FMI 2.0 instance, for calls of its own (None for FMI 3.0).
    pub fn fmi2_mut(&mut self) -> Option<&mut fmi::fmi2::instance::InstanceCS> {
        match &mut self.inner {
            CsInstance::Fmi2(i) => Some(i.as_mut()),
            CsInstance::Fmi3(_) => None,
        }
    }

    /// Where this instance's log messages are kept.
    pub fn log(&self) -> &LogKey {
        &self.log
    }

    /// The name of a call in this instance's version, from its FMI 2.0 name
    /// ([`FmiVersion::call_name`]).
    pub fn call_name(&self, fmi2: &'static str) -> &'static str {
        self.version().call_name(fmi2)
    }

    /// Runs `call` on the instance; an FMI 3.0 instance's messages meanwhile are kept under
    /// its key (FMI 2.0 messages carry the instance name themselves).
    fn with_log<T>(&mut self, call: impl FnOnce(&mut CsInstance) -> T) -> T {
        let Self { inner, log, .. } = self;
        match inner {
            CsInstance::Fmi2(_) => call(inner),
            CsInstance::Fmi3(_) => crate::logging::speaking(log, || call(inner)),
        }
    }

    /// Makes the call `fmi2` or `fmi3`, as the instance's version is (see [`Self::with_log`]),
    /// for its success alone.
    fn call<A, B, E2: Into<CallError>, E3: Into<CallError>>(
        &mut self,
        fmi2: impl FnOnce(&mut fmi::fmi2::instance::InstanceCS) -> Result<A, E2>,
        fmi3: impl FnOnce(&mut fmi::fmi3::instance::InstanceCS) -> Result<B, E3>,
    ) -> Result<(), CallError> {
        self.with_log(|inner| match inner {
            CsInstance::Fmi2(i) => fmi2(i.as_mut()).map(|_| ()).map_err(Into::into),
            CsInstance::Fmi3(i) => fmi3(i.as_mut()).map(|_| ()).map_err(Into::into),
        })
    }

    /// FMI 2.0: `fmi2SetupExperiment` (before start values are set); FMI 3.0: nothing (its
    /// `fmi3EnterInitializationMode` takes the experiment).
    pub fn setup_experiment(&mut self, e: Experiment) -> Result<(), CallError> {
        self.call(
            |i| i.setup_experiment(e.tolerance, e.start, e.stop),
            |_| Ok::<(), Fmi3Error>(()),
        )
    }

    /// Enters initialization mode (FMI 3.0 with the experiment).
    pub fn enter_initialization_mode(&mut self, e: Experiment) -> Result<(), CallError> {
        self.call(
            fmi::fmi2::instance::Common::enter_initialization_mode,
            |i| fmi::fmi3::Common::enter_initialization_mode(i, e.tolerance, e.start, e.stop),
        )
    }

    /// Leaves initialization mode. An FMI 3.0 instance without event mode is then in Step
    /// Mode; one with event mode is in Event Mode (FMI 3.0 §4.2, the Co-Simulation state
    /// machine): the master runs the initial event iteration (`event_iteration`) and
    /// enters Step Mode. `terminateSimulation` in that iteration is an error (the run would
    /// end before its first step; fmpy refuses it too); a failed call or an iteration that
    /// does not settle is one naming that call.
    pub fn exit_initialization_mode(&mut self) -> Result<(), CallError> {
        self.call(
            fmi::fmi2::instance::Common::exit_initialization_mode,
            fmi::fmi3::Common::exit_initialization_mode,
        )?;
        if !self.event_mode {
            return Ok(());
        }
        self.with_log(|inner| {
            let CsInstance::Fmi3(i) = inner else {
                return Ok(());
            };
            let in_context = |(call, e): (&str, CallError)| {
                CallError(format!(
                    "{} ({call}, in the event iteration that follows it)",
                    e.0
                ))
            };
            if event_iteration(i).map_err(in_context)? {
                return Err(CallError(
                    "terminateSimulation = true (fmi3UpdateDiscreteStates, in the event \
                     iteration that follows it): the FMU asks to end the run before its first \
                     step"
                        .into(),
                ));
            }
            i.enter_step_mode()
                .map(|_| ())
                .map_err(|e| in_context(("fmi3EnterStepMode", e.into())))
        })
    }

    /// Terminates the instance.
    pub fn terminate(&mut self) -> Result<(), CallError> {
        self.call(
            fmi::fmi2::instance::Common::terminate,
            fmi::fmi3::Common::terminate,
        )
    }

    /// Reads the values of `vrs` (all of type `t`) into `out`: one value per FMI 2.0
    /// variable, an FMI 3.0 array's elements in a row (`out.len()` = nValues).
    pub fn get(&mut self, t: VarType, vrs: &[u32], out: &mut [f64]) -> Result<(), CallError> {
        self.exchange(
            out,
            |i, ints, out| get2(i, t, vrs, out, ints),
            |i, scratch, out| get3(i, t, vrs, out, scratch),
        )
    }

    /// Sets `vrs` (all of type `t`) from `values` (FMI 3.0: nValues = `values.len()`).
    pub fn set(&mut self, t: VarType, vrs: &[u32], values: &[f64]) -> Result<(), CallError> {
        self.exchange(
            values,
            |i, ints, values| set2(i, t, vrs, values, ints),
            |i, scratch, values| set3(i, t, vrs, values, scratch),
        )
    }

    /// Moves values between `buffer` and the instance by `fmi2` or `fmi3` with the
    /// instance's conversion buffers; an FMI 3.0 instance's log calls are heard meanwhile.
    fn exchange<T>(
        &mut self,
        buffer: T,
        fmi2: impl FnOnce(
            &mut fmi::fmi2::instance::InstanceCS,
            &mut Vec<i32>,
            T,
        ) -> Result<(), Fmi2Error>,
        fmi3: impl FnOnce(
            &mut fmi::fmi3::instance::InstanceCS,
            &mut Scratch,
            T,
        ) -> Result<(), Fmi3Error>,
    ) -> Result<(), CallError> {
        match &mut self.inner {
            CsInstance::Fmi2(i) => fmi2(i, &mut self.scratch.i32, buffer).map_err(Into::into),
            CsInstance::Fmi3(i) => {
                let scratch = &mut self.scratch;
                crate::logging::speaking(&self.log, || fmi3(i, scratch, buffer)).map_err(Into::into)
            }
        }
    }

    /// One communication step from `time` over `h`. An FMI 3.0 instance with event mode
    /// whose `fmi3DoStep` returns `eventHandlingNeeded = true` then has its event handled at
    /// the end of the step (FMI 3.0 §4.2): `fmi3EnterEventMode`, the event iteration
    /// (`event_iteration`), `fmi3EnterStepMode`; `terminateSimulation` from the iteration
    /// ends the run as from `fmi3DoStep`.
    pub fn do_step(&mut self, time: f64, h: f64) -> Result<StepEnd, StepProblem> {
        let event_mode = self.event_mode;
        self.with_log(|inner| match inner {
            CsInstance::Fmi2(i) => match i.do_step(time, h, true) {
                Ok(_) => Ok(StepEnd::Completed),
                Err(Fmi2Error::Discard) => match super::termination_requested(i) {
                    Some(last) => Ok(StepEnd::Terminate(last)),
                    None => Err(CallError::from(Fmi2Error::Discard).into()),
                },
                Err(e) => Err(CallError::from(e).into()),
            },
            CsInstance::Fmi3(i) => {
                let (mut event, mut terminate, mut early) = (false, false, false);
                let mut last = f64::NAN;
                i.do_step(
                    time,
                    h,
                    true,
                    &mut event,
                    &mut terminate,
                    &mut early,
                    &mut last,
                )
                .map_err(CallError::from)?;
                let last = Some(last).filter(|t| t.is_finite());
                if terminate {
                    return Ok(StepEnd::Terminate(last));
                }
                if early {
                    return Err(StepProblem::EarlyReturn {
                        last_successful_time: last.unwrap_or(f64::NAN),
                    });
                }
                if !event {
                    return Ok(StepEnd::Completed);
                }
                if !event_mode {
                    return Err(StepProblem::EventHandlingNeeded);
                }
                // The event is at the end of the step (early return is not allowed).
                let at = last.unwrap_or(time + h);
                let failed = |(call, error)| StepProblem::Event {
                    call,
                    error,
                    time: at,
                };
                fmi::fmi3::Common::enter_event_mode(i.as_mut())
                    .map_err(|e| failed(("fmi3EnterEventMode", e.into())))?;
                if event_iteration(i).map_err(failed)? {
                    return Ok(StepEnd::Terminate(Some(at)));
                }
                i.enter_step_mode()
                    .map_err(|e| failed(("fmi3EnterStepMode", e.into())))?;
                Ok(StepEnd::Completed)
            }
        })
    }
}

/// The event iteration of an FMI 3.0 instance in Event Mode (FMI 3.0 §4.2, as in §3.2 for
/// Model Exchange): `fmi3UpdateDiscreteStates` until `discreteStatesNeedUpdate` is false,
/// at most [`EVENT_ITERATION_LIMIT`] times. The master sets no inputs between the updates (its
/// connections are exchanged at the communication points only), so the outputs read after
/// the step are those after the iteration. Returns whether the FMU asked to end the
/// simulation (`terminateSimulation`, which ends the iteration). `nextEventTime` is not
/// used: the communication grid is fixed (t_k = start + k·h), so the master does not
/// shorten a step to reach it; an FMU with event mode handles a time event inside the step
/// that reaches it and says so by `eventHandlingNeeded` at that step's end.
fn event_iteration(
    i: &mut fmi::fmi3::instance::InstanceCS,
) -> Result<bool, (&'static str, CallError)> {
    let mut flags = fmi::EventFlags::default();
    for _ in 0..EVENT_ITERATION_LIMIT {
        flags.reset();
        fmi::fmi3::Common::update_discrete_states(i, &mut flags)
            .map_err(|e| ("fmi3UpdateDiscreteStates", e.into()))?;
        if flags.terminate_simulation {
            return Ok(true);
        }
        if !flags.discrete_states_need_update {
            return Ok(false);
        }
    }
    Err((
        "fmi3UpdateDiscreteStates",
        CallError(format!(
            "discreteStatesNeedUpdate = true {EVENT_ITERATION_LIMIT} times in a row: the event \
             iteration did not settle"
        )),
    ))
}

/// Reads FMI 2.0 values of type `t` into `out`: Integers and Booleans (`fmi2Boolean` is an
/// int) through `ints`. For instances of either interface.
pub(crate) fn get2<Tag: fmi::traits::InstanceTag>(
    i: &mut fmi::fmi2::instance::Instance<Tag>,
    t: VarType,
    vrs: &[u32],
    out: &mut [f64],
    ints: &mut Vec<i32>,
) -> Result<(), Fmi2Error> {
    use fmi::fmi2::instance::Common;
    let ints = match t {
        VarType::Real => {
            Common::get_real(i, vrs, out)?;
            return Ok(());
        }
        VarType::Boolean => {
            let ints = scratch(ints, out.len());
            Common::get_boolean(i, vrs, ints)?;
            ints.iter_mut().for_each(|x| *x = i32::from(*x != 0));
            ints
        }
        _ => {
            let ints = scratch(ints, out.len());
            Common::get_integer(i, vrs, ints)?;
            ints
        }
    };
    for (o, x) in out.iter_mut().zip(ints.iter()) {
        *o = f64::from(*x);
    }
    Ok(())
}

/// Writes FMI 2.0 values of type `t` from `values`: Integers and Booleans through `ints`.
pub(crate) fn set2<Tag: fmi::traits::InstanceTag>(
    i: &mut fmi::fmi2::instance::Instance<Tag>,
    t: VarType,
    vrs: &[u32],
    values: &[f64],
    ints: &mut Vec<i32>,
) -> Result<(), Fmi2Error> {
    use fmi::fmi2::instance::Common;
    let boolean = t == VarType::Boolean;
    if t == VarType::Real {
        Common::set_real(i, vrs, values)?;
    } else {
        let ints = scratch(ints, values.len());
        for (o, x) in ints.iter_mut().zip(values) {
            *o = if boolean {
                i32::from(*x != 0.0)
            } else {
                *x as i32
            };
        }
        if boolean {
            Common::set_boolean(i, vrs, ints)?;
        } else {
            Common::set_integer(i, vrs, ints)?;
        }
    }
    Ok(())
}

/// Reads FMI 3.0 values of type `t` into `out` through the scratch buffers.
pub(crate) fn get3<Tag>(
    i: &mut fmi::fmi3::instance::Instance<Tag>,
    t: VarType,
    vrs: &[u32],
    out: &mut [f64],
    buffers: &mut Scratch,
) -> Result<(), Fmi3Error> {
    match t {
        VarType::Real => {
            i.get_float64(vrs, out)?;
        }
        VarType::Float32 => get3!(i, vrs, out, buffers, get_float32, set_float32, f32),
        VarType::Boolean => {
            let v = scratch(&mut buffers.bool, out.len());
            i.get_boolean(vrs, v)?;
            for (o, x) in out.iter_mut().zip(v.iter()) {
                *o = f64::from(u8::from(*x));
            }
        }
        // Strings, Binaries and Clocks are never planned (the plan moves numbers and
        // Booleans only).
        _ => fmi3_integer!(t, get3!(i, vrs, out, buffers), return Err(Fmi3Error::Error)),
    }
    Ok(())
}

/// Writes FMI 3.0 values of type `t` from `values` through the scratch buffers.
pub(crate) fn set3<Tag>(
    i: &mut fmi::fmi3::instance::Instance<Tag>,
    t: VarType,
    vrs: &[u32],
    values: &[f64],
    buffers: &mut Scratch,
) -> Result<(), Fmi3Error> {
    match t {
        VarType::Real => {
            i.set_float64(vrs, values)?;
        }
        VarType::Float32 => {
            let v = scratch(&mut buffers.f32, values.len());
            for (o, x) in v.iter_mut().zip(values) {
                *o = *x as f32;
            }
            i.set_float32(vrs, v)?;
        }
        VarType::Boolean => {
            let v = scratch(&mut buffers.bool, values.len());
            for (o, x) in v.iter_mut().zip(values) {
                *o = *x != 0.0;
            }
            i.set_boolean(vrs, v)?;
        }
        _ => fmi3_integer!(
            t,
            set3!(i, vrs, values, buffers),
            return Err(Fmi3Error::Error)
        ),
    }
    Ok(())
}
