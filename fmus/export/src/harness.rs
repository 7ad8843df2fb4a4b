//! An in-process driver of an FMU's C entry points, for Rust tests and benchmarks.
//!
//! It calls the same generic functions of [`crate::fmi2::ffi`] that the exported `fmi2*` symbols
//! call, with real pointers, so a test or benchmark measures the C ABI path (pointer checks,
//! `catch_unwind`, state masks, dispatch) without loading a shared library. Log messages are
//! collected in memory (a C variadic logger cannot be written in stable Rust).

use crate::description::Config;
use crate::fmi2::ffi;
use crate::fmi2::values::{get, set, Boolean, Integer, Real};
use crate::instance::{Instance, LogSink, Logger};
use crate::model::{FmuModel, Hooks};
use crate::types::*;
use std::cell::RefCell;
use std::marker::PhantomData;
use std::rc::Rc;

/// One logged message: (status, category, text).
pub type Logged = (Status, String, String);

#[derive(Clone, Default)]
struct MemorySink(Rc<RefCell<Vec<Logged>>>);

impl LogSink for MemorySink {
    fn deliver(&self, _instance: &str, status: Status, category: &str, text: &str) {
        self.0
            .borrow_mut()
            .push((status, category.to_string(), text.to_string()));
    }
}

/// An instance of `M` driven through the C entry points.
pub struct Harness<M: FmuModel> {
    component: fmi2Component,
    log: MemorySink,
    model: PhantomData<M>,
}

#[allow(non_upper_case_globals)]
fn status(code: fmi2Status) -> Result<Status, Status> {
    match code {
        fmi2OK => Ok(Status::Ok),
        fmi2Warning => Ok(Status::Warning),
        fmi2Discard => Err(Status::Discard),
        fmi2Error => Err(Status::Error),
        _ => Err(Status::Fatal),
    }
}

impl<M: FmuModel> Harness<M> {
    /// Instantiates `M` for `config` with debug logging on.
    pub fn new(config: &Config) -> Result<Self, crate::model::Cause> {
        Self::with(config, |instance| instance)
    }

    /// Instantiates `M` for `config` with its unpacked `resources/` folder at `resources`
    /// ([`FmuModel::create_with_resources`]), debug logging on.
    pub fn with_resources(
        config: &Config,
        resources: &std::path::Path,
    ) -> Result<Self, crate::model::Cause> {
        Self::with_located(config, Some(resources.to_path_buf()), |instance| instance)
    }

    /// Instantiates `M` for Model Exchange, with its Model Exchange functions `hooks`.
    pub fn model_exchange(config: &Config, hooks: Hooks<M>) -> Result<Self, crate::model::Cause> {
        Self::with(config, |instance| instance.into_model_exchange(hooks))
    }

    /// The component, for the calls the harness does not wrap (Model Exchange, directional
    /// derivatives: `crate::abi::model_exchange`, `crate::fmi2::model_exchange`).
    pub fn component(&self) -> fmi2Component {
        self.component
    }

    /// Instantiates `M` for `config`, the new instance set up by `setup`.
    fn with(
        config: &Config,
        setup: impl FnOnce(Instance<M>) -> Instance<M>,
    ) -> Result<Self, crate::model::Cause> {
        Self::with_located(config, None, setup)
    }

    /// Instantiates `M` for `config` and `resources`, the new instance set up by `setup`.
    fn with_located(
        config: &Config,
        resources: Option<std::path::PathBuf>,
        setup: impl FnOnce(Instance<M>) -> Instance<M>,
    ) -> Result<Self, crate::model::Cause> {
        let info = M::describe(config)?;
        let log = MemorySink::default();
        let logger = Logger::new("harness", Box::new(log.clone()), true);
        let interface = std::sync::Arc::new(crate::instance::Interface::new(info));
        let mut instance = setup(Instance::<M>::with_resources(interface, logger, resources)?);
        // every model call of a test checks that the model writes only what it computes
        instance.audit_model_writes();
        let component = ffi::into_component(instance);
        Ok(Self {
            component,
            log,
            model: PhantomData,
        })
    }

    /// The messages logged so far.
    pub fn log(&self) -> Vec<Logged> {
        self.log.0.borrow().clone()
    }

    /// Whether a message logged so far contains every one of `words`.
    pub fn logged(&self, words: &[&str]) -> bool {
        self.log
            .0
            .borrow()
            .iter()
            .any(|(_, _, text)| words.iter().all(|w| text.contains(w)))
    }

    /// Whether `call` is refused at once: it returns `fmi2Error` within `seconds` and a message
    /// logged then contains every one of `words`. What went otherwise is the error (for the
    /// tests that a call which once hung or ran for minutes now ends in an error).
    pub fn refuses_at_once(
        &mut self,
        seconds: f64,
        words: &[&str],
        call: impl FnOnce(&mut Self) -> Result<Status, Status>,
    ) -> Result<(), String> {
        let start = std::time::Instant::now();
        let status = call(self);
        let took = start.elapsed().as_secs_f64();
        if status != Err(Status::Error) {
            return Err(format!("the call gave {status:?}, not fmi2Error"));
        }
        if took >= seconds {
            return Err(format!("refusing took {took} s, not under {seconds} s"));
        }
        if !self.logged(words) {
            return Err(format!("{words:?} not all in the log {:?}", self.log()));
        }
        Ok(())
    }

    /// `fmi2SetupExperiment` + `fmi2EnterInitializationMode` + `fmi2ExitInitializationMode`.
    pub fn initialize(&mut self, start_time: f64) -> Result<Status, Status> {
        // SAFETY: `component` is a live component created by `into_component`.
        unsafe {
            status(ffi::setup_experiment::<M>(
                self.component,
                0,
                0.0,
                start_time,
                0,
                0.0,
            ))?;
            status(ffi::enter_initialization_mode::<M>(self.component))?;
            status(ffi::exit_initialization_mode::<M>(self.component))
        }
    }

    /// `fmi2SetupExperiment(start_time, stop_time)` (no tolerance).
    pub fn setup_experiment(
        &mut self,
        start_time: f64,
        stop_time: Option<f64>,
    ) -> Result<Status, Status> {
        // SAFETY: live component.
        status(unsafe {
            ffi::setup_experiment::<M>(
                self.component,
                0,
                0.0,
                start_time,
                fmi2Boolean::from(stop_time.is_some()),
                stop_time.unwrap_or(0.0),
            )
        })
    }

    /// `fmi2EnterInitializationMode`.
    pub fn enter_initialization_mode(&mut self) -> Result<Status, Status> {
        // SAFETY: live component.
        status(unsafe { ffi::enter_initialization_mode::<M>(self.component) })
    }

    /// `fmi2ExitInitializationMode`.
    pub fn exit_initialization_mode(&mut self) -> Result<Status, Status> {
        // SAFETY: live component.
        status(unsafe { ffi::exit_initialization_mode::<M>(self.component) })
    }

    /// `fmi2Reset`.
    pub fn reset(&mut self) -> Result<Status, Status> {
        // SAFETY: live component.
        status(unsafe { ffi::reset::<M>(self.component) })
    }

    /// `fmi2GetFMUstate` (a new state), `fmi2SerializedFMUstateSize`, `fmi2SerializeFMUstate`
    /// and `fmi2FreeFMUstate`: the bytes of the current state.
    pub fn serialized_state(&mut self) -> Result<Vec<u8>, Status> {
        let mut state: fmi2FMUstate = std::ptr::null_mut();
        let mut size = 0usize;
        // SAFETY: live component; `state` and `size` are valid out-pointers; the buffer holds
        // `size` bytes.
        unsafe {
            status(ffi::get_fmu_state::<M>(self.component, &mut state))?;
            let bytes = status(ffi::serialized_fmu_state_size::<M>(
                self.component,
                state,
                &mut size,
            ))
            .and_then(|_| {
                let mut bytes = vec![0u8; size];
                status(ffi::serialize_fmu_state::<M>(
                    self.component,
                    state,
                    bytes.as_mut_ptr() as *mut fmi2Byte,
                    size,
                ))
                .map(|_| bytes)
            });
            status(ffi::free_fmu_state::<M>(self.component, &mut state))?;
            bytes
        }
    }

    /// `fmi2DeSerializeFMUstate` of `bytes`, then `fmi2SetFMUstate` and `fmi2FreeFMUstate`.
    pub fn restore_state(&mut self, bytes: &[u8]) -> Result<Status, Status> {
        let mut state: fmi2FMUstate = std::ptr::null_mut();
        // SAFETY: live component; `bytes` holds `bytes.len()` bytes; `state` is a valid
        // out-pointer.
        unsafe {
            status(ffi::deserialize_fmu_state::<M>(
                self.component,
                bytes.as_ptr() as *const fmi2Byte,
                bytes.len(),
                &mut state,
            ))?;
            let set = status(ffi::set_fmu_state::<M>(self.component, state));
            status(ffi::free_fmu_state::<M>(self.component, &mut state))?;
            set
        }
    }

    /// `fmi2GetRealStatus(fmi2LastSuccessfulTime)`.
    pub fn last_successful_time(&mut self) -> Result<f64, Status> {
        let mut t = f64::NAN;
        // SAFETY: live component; `t` is a valid out-pointer.
        status(unsafe {
            ffi::get_real_status::<M>(self.component, fmi2LastSuccessfulTime, &mut t)
        })?;
        Ok(t)
    }

    /// `fmi2SetReal`.
    pub fn set_real(&mut self, vr: &[u32], values: &[f64]) -> Result<Status, Status> {
        if vr.len() != values.len() {
            return Err(Status::Error);
        }
        // SAFETY: both slices hold `vr.len()` elements.
        status(unsafe { set::<M, Real>(self.component, vr.as_ptr(), vr.len(), values.as_ptr()) })
    }

    /// `fmi2SetInteger`.
    pub fn set_integer(&mut self, vr: &[u32], values: &[i32]) -> Result<Status, Status> {
        if vr.len() != values.len() {
            return Err(Status::Error);
        }
        // SAFETY: both slices hold `vr.len()` elements.
        status(unsafe { set::<M, Integer>(self.component, vr.as_ptr(), vr.len(), values.as_ptr()) })
    }

    /// `fmi2SetBoolean` (`true` → fmi2True).
    pub fn set_boolean(&mut self, vr: &[u32], values: &[bool]) -> Result<Status, Status> {
        if vr.len() != values.len() {
            return Err(Status::Error);
        }
        let values: Vec<i32> = values.iter().map(|v| i32::from(*v)).collect();
        // SAFETY: both slices hold `vr.len()` elements.
        status(unsafe { set::<M, Boolean>(self.component, vr.as_ptr(), vr.len(), values.as_ptr()) })
    }

    /// `fmi2GetReal` into `out`.
    pub fn get_real(&mut self, vr: &[u32], out: &mut [f64]) -> Result<Status, Status> {
        if vr.len() != out.len() {
            return Err(Status::Error);
        }
        // SAFETY: both slices hold `vr.len()` elements.
        status(unsafe { get::<M, Real>(self.component, vr.as_ptr(), vr.len(), out.as_mut_ptr()) })
    }
    /// `fmi2GetInteger` into `out`.
    pub fn get_integer(&mut self, vr: &[u32], out: &mut [i32]) -> Result<Status, Status> {
        if vr.len() != out.len() {
            return Err(Status::Error);
        }
        // SAFETY: both slices hold `vr.len()` elements.
        status(unsafe {
            get::<M, Integer>(self.component, vr.as_ptr(), vr.len(), out.as_mut_ptr())
        })
    }
    /// `fmi2GetReal` of one variable.
    pub fn real(&mut self, vr: u32) -> Result<f64, Status> {
        let mut out = [f64::NAN];
        self.get_real(&[vr], &mut out)?;
        Ok(out[0])
    }

    /// `fmi2GetBoolean` of one variable.
    pub fn boolean(&mut self, vr: u32) -> Result<bool, Status> {
        let mut out = [0];
        // SAFETY: one value reference, one element.
        status(unsafe { get::<M, Boolean>(self.component, [vr].as_ptr(), 1, out.as_mut_ptr()) })?;
        Ok(out[0] != 0)
    }

    /// `fmi2DoStep`.
    pub fn do_step(&mut self, time: f64, step: f64) -> Result<Status, Status> {
        // SAFETY: live component.
        status(unsafe { ffi::do_step::<M>(self.component, time, step, fmi2True) })
    }

    /// One communication step as a master takes it: `fmi2SetReal` of `values` into `inputs`,
    /// `fmi2DoStep(time, step)`, `fmi2GetReal` of `outputs` into `out`.
    pub fn exchange(
        &mut self,
        inputs: &[u32],
        values: &[f64],
        (time, step): (f64, f64),
        outputs: &[u32],
        out: &mut [f64],
    ) -> Result<Status, Status> {
        self.set_real(inputs, values)?;
        self.do_step(time, step)?;
        self.get_real(outputs, out)
    }

    /// For benchmarks: the [`Timing`] of one [`Harness::exchange`] per call, stepping by
    /// `step` from where the instance is: `input_values(k, values)` gives the k-th call's
    /// values of `inputs`; `outputs` are read into a black box. Counts as [`time_per_call`]
    /// does (`(warm_up, batches, per_batch)`); the first failed call's status is the error.
    pub fn time_exchanges(
        &mut self,
        (inputs, outputs): (&[u32], &[u32]),
        (start, step): (f64, f64),
        (warm_up, batches, per_batch): (usize, usize, usize),
        mut input_values: impl FnMut(u64, &mut [f64]),
    ) -> Result<Timing, Status> {
        let mut values = vec![0.0; inputs.len()];
        let mut out = vec![0.0; outputs.len()];
        let (mut time, mut k, mut failed) = (start, 0u64, None);
        let timing = time_per_call(warm_up, batches, per_batch, || {
            input_values(k, &mut values);
            if let Err(s) = self.exchange(inputs, &values, (time, step), outputs, &mut out) {
                failed.get_or_insert(s);
            }
            std::hint::black_box(&out);
            time += step;
            k += 1;
        });
        failed.map_or(Ok(timing), Err)
    }
}

impl<M: FmuModel> Drop for Harness<M> {
    fn drop(&mut self) {
        // SAFETY: the component is freed exactly once, here.
        unsafe { ffi::free_instance::<M>(self.component) }
    }
}

/// For benchmarks: the median, first and third quartiles of a time per call (ns).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Timing {
    pub median: f64,
    pub q1: f64,
    pub q3: f64,
}

impl Timing {
    /// `median 1.23 µs per {what} (IQR 1.20–1.30 µs)`.
    pub fn summary(&self, what: &str) -> String {
        format!(
            "median {:.2} µs per {what} (IQR {:.2}–{:.2} µs)",
            self.median / 1e3,
            self.q1 / 1e3,
            self.q3 / 1e3
        )
    }
}

/// For benchmarks: the [`Timing`] of `call` over `batches` batches of `per_batch` calls, after
/// `warm_up` calls (NaN without batches).
pub fn time_per_call(
    warm_up: usize,
    batches: usize,
    per_batch: usize,
    mut call: impl FnMut(),
) -> Timing {
    for _ in 0..warm_up {
        call();
    }
    let mut samples: Vec<f64> = (0..batches)
        .map(|_| {
            let start = std::time::Instant::now();
            for _ in 0..per_batch {
                call();
            }
            start.elapsed().as_nanos() as f64 / per_batch.max(1) as f64
        })
        .collect();
    samples.sort_by(|a, b| a.total_cmp(b));
    let q = |p: f64| {
        let last = samples.len().saturating_sub(1);
        samples
            .get((last as f64 * p) as usize)
            .copied()
            .unwrap_or(f64::NAN)
    };
    Timing {
        median: q(0.5),
        q1: q(0.25),
        q3: q(0.75),
    }
}
