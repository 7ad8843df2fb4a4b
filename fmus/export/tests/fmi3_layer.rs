//! The FMI 3.0 front driven through its C entry points with a toy model that has arrays:
//! instantiation (token, resources, the interfaces it refuses), the Co-Simulation state
//! machine, arrays with `nValues`, argument checks, FMU states, panics, many instances, and
//! the messages through a real `fmi3LogMessageCallback`.
#![allow(unsafe_code)]

mod common;

use common::toy::*;
use spurio_export::abi::kinds::Fmi3;
use spurio_export::abi::model_exchange::{self as me, Array};
use spurio_export::fmi3::ffi;
use spurio_export::fmi3::types::*;
use spurio_export::fmi3::values::{self, Boolean, Float64, Int32};
use spurio_export::fmi3::{functions, model_exchange as me3};
use spurio_export::{Config, FmuModel};
use std::cell::RefCell;
use std::ffi::{c_void, CStr, CString};

macro_rules! value_references {
    (@ $n:expr;) => {};
    (@ $n:expr; $name:ident $(, $rest:ident)*) => {
        #[allow(dead_code)]
        const $name: u32 = $n;
        value_references!(@ $name + 1; $($rest),*);
    };
    ($($name:ident),*) => { value_references!(@ 0; $($name),*); };
}
// FMI 3.0 value references of the toy: 0 time, then its variables (arrays as one).
value_references! { VR_TIME, VR_U, VR_Y, VR_Z, VR_P, VR_N, VR_POSITIVE, VR_Y0, VR_DER_Y, VR_TO_WRAP }

thread_local! {
    static LOG: RefCell<Vec<(fmi3Status, String, String)>> = const { RefCell::new(Vec::new()) };
}

unsafe extern "C" fn log_message(
    _env: fmi3InstanceEnvironment,
    status: fmi3Status,
    category: fmi3String,
    message: fmi3String,
) {
    let text = |p: fmi3String| unsafe { CStr::from_ptr(p) }.to_string_lossy().into_owned();
    LOG.with(|l| l.borrow_mut().push((status, text(category), text(message))));
}

fn last_error() -> String {
    LOG.with(|l| {
        l.borrow()
            .iter()
            .rev()
            .find(|(s, _, _)| *s >= fmi3Error)
            .map(|(_, _, t)| t.clone())
            .unwrap_or_default()
    })
}

/// The arguments every instantiation function has: no logging, the test's log callback.
fn args(
    name: *const std::os::raw::c_char,
    token: *const std::os::raw::c_char,
    resources: *const std::os::raw::c_char,
) -> ffi::Instantiation {
    ffi::Instantiation(
        name,
        token,
        resources,
        fmi3False,
        std::ptr::null_mut::<c_void>(),
        Some(log_message),
    )
}

fn token() -> CString {
    CString::new(Toy::describe(&Config::new()).unwrap().guid).unwrap()
}

fn instantiate_with(name: &str, token: &CString) -> fmi3Instance {
    let name = CString::new(name).unwrap();
    unsafe {
        ffi::instantiate_co_simulation::<Toy>(
            args(name.as_ptr(), token.as_ptr(), std::ptr::null()),
            0,
            0,
            0,
            Some(spurio_export::model::hooks::<Toy>()),
        )
    }
}

/// `fmi3InstantiateCoSimulation` of the Toy with the right token but without its Model
/// Exchange functions: `eventModeUsed = event_mode`, the resource folder `resources` if any.
fn co_simulation_only(
    name: &str,
    resources: Option<&CStr>,
    event_mode: fmi3Boolean,
) -> fmi3Instance {
    let name = CString::new(name).unwrap();
    let resources = resources.map_or(std::ptr::null(), CStr::as_ptr);
    unsafe {
        ffi::instantiate_co_simulation::<Toy>(
            args(name.as_ptr(), token().as_ptr(), resources),
            event_mode,
            0,
            0,
            None,
        )
    }
}

/// Asserts that an instantiation was refused (NULL) and logged an error containing `reason`.
#[track_caller]
fn assert_refused(instance: fmi3Instance, reason: &str) {
    assert!(instance.is_null());
    let e = last_error();
    assert!(e.contains(reason), "{e}");
}

struct Instance(fmi3Instance);

impl Drop for Instance {
    fn drop(&mut self) {
        unsafe { ffi::free_instance::<Toy>(self.0) }
    }
}

impl Instance {
    fn new(name: &str) -> Self {
        let c = instantiate_with(name, &token());
        assert!(!c.is_null(), "{}", last_error());
        Self(c)
    }
    fn initialize(&self) -> fmi3Status {
        let s = unsafe { ffi::enter_initialization_mode::<Toy>(self.0, 0.0, fmi3True, 10.0) };
        if s != fmi3OK {
            return s;
        }
        unsafe { ffi::exit_initialization_mode::<Toy>(self.0) }
    }
    fn set_f64(&self, vr: &[u32], values: &[f64]) -> fmi3Status {
        unsafe {
            values::set::<Toy, Float64>(
                self.0,
                vr.as_ptr(),
                vr.len(),
                values.as_ptr(),
                values.len(),
            )
        }
    }
    fn get_f64(&self, vr: &[u32], n: usize) -> Result<Vec<f64>, fmi3Status> {
        let mut out = vec![f64::NAN; n];
        let s = unsafe {
            values::get::<Toy, Float64>(self.0, vr.as_ptr(), vr.len(), out.as_mut_ptr(), n)
        };
        if s == fmi3OK {
            Ok(out)
        } else {
            Err(s)
        }
    }
    fn step(&self, t: f64, h: f64) -> (fmi3Status, [u8; 3], f64) {
        let mut flags = [9u8; 3];
        let mut last = f64::NAN;
        let [a, b, c] = &mut flags;
        let s = unsafe { ffi::do_step::<Toy>(self.0, t, h, a, b, c, &mut last) };
        (s, flags, last)
    }
}

#[test]
fn instantiation_checks_the_token_and_refuses_other_interfaces() {
    let wrong = CString::new("{00000000-0000-0000-0000-000000000000}").unwrap();
    assert!(instantiate_with("bad", &wrong).is_null());
    let e = last_error();
    assert!(
        e.starts_with("fmi3InstantiateCoSimulation: instantiationToken mismatch")
            && e.contains(&token().into_string().unwrap()),
        "{e}"
    );
    assert_refused(
        co_simulation_only("events", None, fmi3True),
        "eventModeUsed = true, but the FMU declares hasEventMode",
    );
    assert_refused(
        instantiate_with("", &token()),
        "instanceName must be a non-empty string",
    );
    let se = unsafe {
        ffi::refuse_instantiation::<Toy>(
            "fmi3InstantiateScheduledExecution",
            "Scheduled Execution",
            args(std::ptr::null(), std::ptr::null(), std::ptr::null()),
        )
    };
    assert_refused(se, "Toy does not implement Scheduled Execution");
    // Model Exchange needs the model's functions (`export_fmu!(Toy, model_exchange)`).
    let name = CString::new("me").unwrap();
    let me = unsafe {
        ffi::instantiate_model_exchange::<Toy>(
            args(name.as_ptr(), token().as_ptr(), std::ptr::null()),
            None,
        )
    };
    assert_refused(
        me,
        "fmi3InstantiateModelExchange: Toy is a Co-Simulation FMU only",
    );
    // A variant configuration in the resource folder is read; a broken one is reported.
    let dir = std::env::temp_dir().join(format!("fmi3_layer_{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(dir.join("variant.cfg"), "not a setting\n").unwrap();
    let resources = CString::new(format!("{}/", dir.display())).unwrap();
    assert_refused(
        co_simulation_only("cfg", Some(&resources), 0),
        "variant.cfg line 1",
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn the_co_simulation_state_machine_rejects_wrong_call_orders() {
    let i = Instance::new("order");
    assert_eq!(i.step(0.0, 0.1).0, fmi3Error);
    let e = last_error();
    assert!(
        e.contains("fmi3DoStep: illegal call sequence") && e.contains("Instantiated"),
        "{e}"
    );
    assert_eq!(
        unsafe { ffi::exit_initialization_mode::<Toy>(i.0) },
        fmi3Error
    );
    assert_eq!(unsafe { ffi::terminate::<Toy>(i.0) }, fmi3Error);
    assert_eq!(i.initialize(), fmi3OK);
    assert_eq!(
        unsafe { ffi::enter_initialization_mode::<Toy>(i.0, 0.0, 0, 0.0) },
        fmi3Error
    );
    assert!(last_error().contains("allowed in: Instantiated") && last_error().contains("StepMode"));
    let s = unsafe { ffi::unsupported::<Toy>(i.0, "fmi3EnterEventMode", "no event mode") };
    assert_eq!(s, fmi3Error);
    assert_eq!(
        last_error(),
        "fmi3EnterEventMode: not supported: no event mode"
    );
    // Nothing was lost: stepping works, with the CS outputs of fmi3DoStep.
    assert_eq!(i.set_f64(&[VR_U], &[1.0, -2.0]), fmi3OK);
    let (s, flags, last) = i.step(0.0, 0.5);
    assert_eq!((s, flags, last), (fmi3OK, [0, 0, 0], 0.5));
    assert_eq!(i.get_f64(&[VR_Y, VR_TIME], 3).unwrap(), [0.5, -1.0, 0.5]);
    // The stop time given in fmi3EnterInitializationMode is enforced.
    assert_eq!(i.step(0.5, 10.0).0, fmi3Error);
    assert!(last_error().contains("stopTime"), "{}", last_error());
    assert_eq!(unsafe { ffi::terminate::<Toy>(i.0) }, fmi3OK);
    assert_eq!(i.step(0.5, 0.5).0, fmi3Error);
    assert_eq!(unsafe { ffi::reset::<Toy>(i.0) }, fmi3OK);
    assert_eq!(i.initialize(), fmi3OK);
    assert_eq!(i.get_f64(&[VR_Y], 2).unwrap(), [0.0, 0.0]);
}

#[test]
fn arrays_are_one_value_reference_counted_in_elements() {
    let i = Instance::new("arrays");
    assert_eq!(i.initialize(), fmi3OK);
    // P is 2×2, row-major, one value reference.
    assert_eq!(i.get_f64(&[VR_P], 4).unwrap(), [11.0, 12.0, 21.0, 22.0]);
    assert_eq!(i.get_f64(&[VR_P], 3), Err(fmi3Error));
    assert!(
        last_error().contains("nValues = 3, but the 1 value references name 4 values"),
        "{}",
        last_error()
    );
    // Inputs set as a whole; the direct feedthrough output follows without a step.
    assert_eq!(i.set_f64(&[VR_U], &[2.0, 3.0]), fmi3OK);
    assert_eq!(i.get_f64(&[VR_Z, VR_U], 3).unwrap(), [5.0, 2.0, 3.0]);
    assert_eq!(i.set_f64(&[VR_U], &[2.0]), fmi3Error);
    // Int32 and Boolean.
    let mut n = [0i32; 1];
    let s = unsafe { values::get::<Toy, Int32>(i.0, [VR_N].as_ptr(), 1, n.as_mut_ptr(), 1) };
    assert_eq!((s, n), (fmi3OK, [3]));
    assert_eq!(i.step(0.0, 1.0).0, fmi3OK);
    let mut b = [7u8; 1];
    let s =
        unsafe { values::get::<Toy, Boolean>(i.0, [VR_POSITIVE].as_ptr(), 1, b.as_mut_ptr(), 1) };
    assert_eq!((s, b), (fmi3OK, [fmi3True]));
}

#[test]
fn bad_references_types_and_values_are_rejected_and_change_nothing() {
    let i = Instance::new("checks");
    // Fixed parameter bounds before initialisation, per element of the array.
    assert_eq!(i.set_f64(&[VR_P], &[1.0, 2.0, 3.0, 101.0]), fmi3Error);
    assert!(last_error().contains("`P[2,2]` = 101 is above its maximum 100"));
    assert_eq!(i.initialize(), fmi3OK);
    assert_eq!(i.get_f64(&[VR_P], 4).unwrap(), [11.0, 12.0, 21.0, 22.0]);
    assert_eq!(i.get_f64(&[99], 1), Err(fmi3Error));
    assert_eq!(
        last_error(),
        "fmi3GetFloat64: unknown value reference 99 (Toy has value references 0 to 10)"
    );
    let mut n = [0i32; 2];
    let s = unsafe { values::get::<Toy, Int32>(i.0, [VR_U].as_ptr(), 1, n.as_mut_ptr(), 2) };
    assert_eq!(s, fmi3Error);
    assert!(last_error().contains("variable `u` (value reference 1) is of type Float64, not Int32"));
    assert_eq!(i.set_f64(&[VR_U], &[1.0, f64::NAN]), fmi3Error);
    assert!(last_error().contains("`u[2]`") && last_error().contains("NaN"));
    assert_eq!(i.set_f64(&[VR_TIME], &[1.0]), fmi3Error);
    assert!(last_error().contains("independent variable"));
    assert_eq!(i.set_f64(&[VR_Y], &[1.0, 1.0]), fmi3Error);
    assert_eq!(
        last_error(),
        "fmi3SetFloat64: variable `y[1]` is an output: the FMU computes it (state StepMode)"
    );
    let p = [1.0, 2.0, 3.0, 4.0];
    assert_eq!(i.set_f64(&[VR_P], &p), fmi3Error);
    assert!(last_error().contains("it can be set only before fmi3ExitInitializationMode"));
    assert_eq!(i.get_f64(&[VR_U], 2).unwrap(), [0.0, 0.0]);
}

/// The set call's fast path (each reference looked up once, up to 16 references) and the
/// general one (more references) check every value before storing any: a call that mixes a
/// scalar and an array and refuses one element changes nothing, whichever path takes it.
#[test]
fn a_set_of_scalars_and_arrays_stores_all_or_nothing() {
    let i = Instance::new("all-or-nothing");
    assert_eq!(
        i.set_f64(&[VR_Y0, VR_P], &[1.5, 1.0, 2.0, 3.0, 4.0]),
        fmi3OK
    );
    assert_eq!(
        i.get_f64(&[VR_P, VR_Y0], 5),
        Err(fmi3Error),
        "no get in state Instantiated"
    );
    assert_eq!(
        i.set_f64(&[VR_P, VR_Y0], &[5.0, 6.0, 7.0, 101.0, 2.5]),
        fmi3Error
    );
    assert!(last_error().contains("`P[2,2]` = 101 is above its maximum 100"));
    assert_eq!(i.set_f64(&[VR_Y0, VR_P], &[2.5, 5.0, 6.0, 7.0]), fmi3Error);
    assert!(last_error().contains("nValues = 4, but the 2 value references name 5 values"));
    // 17 references: past the fast path's stack, the same rules
    let many = [VR_Y0; 17];
    let mut values = [3.0; 17];
    values[16] = 11.0;
    assert_eq!(i.set_f64(&many, &values), fmi3Error);
    assert!(last_error().contains("`y0` = 11 is above its maximum 10"));
    values[16] = -3.0;
    assert_eq!(i.set_f64(&many, &values), fmi3OK);
    assert_eq!(i.initialize(), fmi3OK);
    assert_eq!(
        i.get_f64(&[VR_P, VR_Y0, VR_Y], 7).unwrap(),
        [1.0, 2.0, 3.0, 4.0, -3.0, -3.0, 0.0]
    );
    // scalars and arrays read together, a scalar twice
    assert_eq!(i.set_f64(&[VR_U], &[0.5, 0.25]), fmi3OK);
    assert_eq!(
        i.get_f64(&[VR_Z, VR_TIME, VR_Z, VR_U], 5).unwrap(),
        [0.75, 0.0, 0.75, 0.5, 0.25]
    );
}

#[test]
fn fmu_states_replay_and_serialize() {
    let i = Instance::new("states");
    assert_eq!(i.initialize(), fmi3OK);
    assert_eq!(i.set_f64(&[VR_U], &[1.0, 2.0]), fmi3OK);
    assert_eq!(i.step(0.0, 0.5).0, fmi3OK);
    let mut state: fmi3FMUState = std::ptr::null_mut();
    assert_eq!(
        unsafe { ffi::get_fmu_state::<Toy>(i.0, &mut state) },
        fmi3OK
    );
    assert_eq!(i.step(0.5, 0.5).0, fmi3OK);
    let first = i.get_f64(&[VR_Y, VR_TIME], 3).unwrap();
    assert_eq!(unsafe { ffi::set_fmu_state::<Toy>(i.0, state) }, fmi3OK);
    assert_eq!(i.get_f64(&[VR_TIME], 1).unwrap(), [0.5]);
    assert_eq!(i.step(0.5, 0.5).0, fmi3OK);
    assert_eq!(i.get_f64(&[VR_Y, VR_TIME], 3).unwrap(), first);
    // Serialized into another instance of the same FMU.
    let mut size = 0usize;
    assert_eq!(
        unsafe { ffi::serialized_fmu_state_size::<Toy>(i.0, state, &mut size) },
        fmi3OK
    );
    let mut bytes = vec![0u8; size];
    assert_eq!(
        unsafe { ffi::serialize_fmu_state::<Toy>(i.0, state, bytes.as_mut_ptr(), size) },
        fmi3OK
    );
    let other = Instance::new("other");
    let mut copy: fmi3FMUState = std::ptr::null_mut();
    let s = unsafe { ffi::deserialize_fmu_state::<Toy>(other.0, bytes.as_ptr(), size, &mut copy) };
    assert_eq!(s, fmi3OK);
    assert_eq!(unsafe { ffi::set_fmu_state::<Toy>(other.0, copy) }, fmi3OK);
    assert_eq!(other.step(0.5, 0.5).0, fmi3OK);
    assert_eq!(other.get_f64(&[VR_Y, VR_TIME], 3).unwrap(), first);
    // A state of another instance, or garbage, is refused.
    assert_eq!(
        unsafe { ffi::set_fmu_state::<Toy>(other.0, state) },
        fmi3Error
    );
    assert!(last_error().contains("unknown FMUState"));
    let s =
        unsafe { ffi::deserialize_fmu_state::<Toy>(other.0, [1u8, 2, 3].as_ptr(), 3, &mut copy) };
    assert_eq!(s, fmi3Error);
    assert_eq!(
        unsafe { ffi::free_fmu_state::<Toy>(i.0, &mut state) },
        fmi3OK
    );
    assert!(state.is_null());
}

#[test]
fn interleaved_instances_are_independent_and_a_panic_is_fatal() {
    let a = Instance::new("a");
    let b = Instance::new("b");
    assert_eq!(a.initialize(), fmi3OK);
    assert_eq!(b.initialize(), fmi3OK);
    for k in 0..4 {
        let t = k as f64 * 0.25;
        assert_eq!(a.set_f64(&[VR_U], &[1.0, 0.0]), fmi3OK);
        assert_eq!(b.set_f64(&[VR_U], &[-1.0, 4.0]), fmi3OK);
        assert_eq!(a.step(t, 0.25).0, fmi3OK);
        assert_eq!(b.step(t, 0.25).0, fmi3OK);
    }
    assert_eq!(a.get_f64(&[VR_Y], 2).unwrap(), [1.0, 0.0]);
    assert_eq!(b.get_f64(&[VR_Y], 2).unwrap(), [-1.0, 4.0]);
    assert_eq!(a.set_f64(&[VR_U], &[13.0, 0.0]), fmi3OK);
    assert_eq!(a.step(1.0, 0.25).0, fmi3Fatal);
    assert!(last_error().contains("fmi3DoStep: internal error: unlucky input"));
    assert_eq!(a.get_f64(&[VR_Y], 2), Err(fmi3Error));
    // The other instance is untouched.
    assert_eq!(b.step(1.0, 0.25).0, fmi3OK);
}

/// Run by [`an_fmi3_panic_prints_nothing_on_stderr`] in a child process: a panicking
/// `fmi3DoStep`, whose text goes to the logger only.
#[test]
fn panicking_fmi3_step_child() {
    if std::env::var_os("SPURIO_PANIC_CHILD").is_none() {
        return;
    }
    let a = Instance::new("a");
    assert_eq!(a.initialize(), fmi3OK);
    assert_eq!(a.set_f64(&[VR_U], &[13.0, 0.0]), fmi3OK);
    assert_eq!(a.step(0.0, 0.25).0, fmi3Fatal);
    let text = last_error();
    assert!(text.contains("unlucky input (at "), "{text}");
    assert!(text.contains("toy.rs"), "{text}");
    eprintln!("child done");
}

#[test]
fn an_fmi3_panic_prints_nothing_on_stderr() {
    common::assert_child_prints_only_its_line("panicking_fmi3_step_child");
}

/// The toy instantiated for FMI 3.0 Model Exchange.
fn instantiate_model_exchange() -> Instance {
    let name = CString::new("me").unwrap();
    let c = unsafe {
        ffi::instantiate_model_exchange::<Toy>(
            args(name.as_ptr(), token().as_ptr(), std::ptr::null()),
            Some(spurio_export::model::hooks::<Toy>()),
        )
    };
    assert!(!c.is_null(), "{}", last_error());
    Instance(c)
}

/// The directional (`adjoint` false) or adjoint derivative through the C entry point.
fn derivative(
    i: &Instance,
    adjoint: bool,
    unknowns: &[u32],
    knowns: &[u32],
    seed: &[f64],
    n_out: usize,
) -> Result<Vec<f64>, fmi3Status> {
    let mut out = vec![f64::NAN; n_out];
    let call = me3::DerivativeCall {
        unknowns: unknowns.as_ptr(),
        n_unknowns: unknowns.len(),
        knowns: knowns.as_ptr(),
        n_knowns: knowns.len(),
        seed: seed.as_ptr(),
        n_seed: seed.len(),
        sensitivity: out.as_mut_ptr(),
        n_sensitivity: n_out,
    };
    let kind = if adjoint {
        me3::Derivative::Adjoint
    } else {
        me3::Derivative::Directional
    };
    match unsafe { me3::derivative::<Toy>(i.0, call, kind) } {
        0 => Ok(out),
        s => Err(s),
    }
}

#[test]
fn model_exchange_runs_through_event_and_continuous_time_mode() {
    let i = instantiate_model_exchange();
    let get = |which| {
        let mut out = [f64::NAN; 2];
        let (f, which) = which;
        let s = unsafe { me::get_array::<Toy, Fmi3>(i.0, f, which, out.as_mut_ptr(), 2) };
        (s, out)
    };
    let mut n = 0usize;
    assert_eq!(
        unsafe { me3::number_of::<Toy>(i.0, me3::Count::ContinuousStates, &mut n) },
        fmi3OK
    );
    assert_eq!(n, 2);
    assert_eq!(
        unsafe { me3::number_of::<Toy>(i.0, me3::Count::EventIndicators, &mut n) },
        fmi3OK
    );
    assert_eq!(n, 1);
    assert_eq!(i.set_f64(&[VR_U], &[1.0, -2.0]), fmi3OK);
    assert_eq!(i.initialize(), fmi3OK);
    // Event Mode after initialization: the first event iteration
    let mut flags = [9u8; 5];
    let mut next = f64::NAN;
    let [a, b, c, d, e] = &mut flags;
    let events = me3::EventFlags {
        need_update: a,
        terminate: b,
        nominals_changed: c,
        values_changed: d,
        next_defined: e,
        next_time: &mut next,
    };
    assert_eq!(
        unsafe { me3::update_discrete_states::<Toy>(i.0, events) },
        fmi3OK
    );
    assert_eq!(flags, [fmi3False; 5]);
    assert_eq!(i.step(0.0, 0.1).0, fmi3Error);
    assert!(
        last_error().contains("fmi3DoStep: illegal call sequence: not allowed in state EventMode")
    );
    assert_eq!(
        unsafe { me::enter_mode::<Toy, Fmi3>(i.0, &functions::ENTER_CONTINUOUS_TIME_MODE, false) },
        fmi3OK
    );
    assert_eq!(
        unsafe { me::set_time::<Toy, Fmi3>(i.0, &functions::SET_TIME, 0.5) },
        fmi3OK
    );
    let x = [0.5, -1.0];
    assert_eq!(
        unsafe {
            me::set_continuous_states::<Toy, Fmi3>(
                i.0,
                &functions::SET_CONTINUOUS_STATES,
                x.as_ptr(),
                2,
            )
        },
        fmi3OK
    );
    assert_eq!(
        get((&functions::GET_DERIVATIVES, Array::Derivatives)),
        (fmi3OK, [1.0, -2.0])
    );
    assert_eq!(
        get((&functions::GET_CONTINUOUS_STATES, Array::ContinuousStates)),
        (fmi3OK, x)
    );
    assert_eq!(
        get((
            &functions::GET_NOMINALS_OF_CONTINUOUS_STATES,
            Array::Nominals
        )),
        (fmi3OK, [2.0, 2.0])
    );
    assert_eq!(
        i.get_f64(&[VR_DER_Y, VR_TIME], 3).unwrap(),
        [1.0, -2.0, 0.5]
    );
    // the event indicator's variable, read through fmi3GetFloat64 alone, follows the states
    // (computed when read: y_max − y[1])
    assert_eq!(i.get_f64(&[VR_TO_WRAP], 1).unwrap(), [1e6 - 0.5]);
    let x = [2.5, -1.0];
    let f = &functions::SET_CONTINUOUS_STATES;
    let s = unsafe { me::set_continuous_states::<Toy, Fmi3>(i.0, f, x.as_ptr(), 2) };
    assert_eq!(s, fmi3OK);
    assert_eq!(
        i.get_f64(&[VR_Z, VR_TO_WRAP], 2).unwrap(),
        [-1.0, 1e6 - 2.5]
    );
    // wrong counts
    let mut z = [0.0; 2];
    let (f, which) = (&functions::GET_EVENT_INDICATORS, Array::EventIndicators);
    let s = unsafe { me::get_array::<Toy, Fmi3>(i.0, f, which, z.as_mut_ptr(), 2) };
    assert_eq!(s, fmi3Error);
    assert!(last_error().contains("fmi3GetEventIndicators: ni = 2, but Toy has 1"));
    let (mut event, mut terminate) = (9u8, 9u8);
    let f = &functions::COMPLETED_INTEGRATOR_STEP;
    let s = unsafe {
        me::completed_integrator_step::<Toy, Fmi3, _>(i.0, f, &mut event, &mut terminate)
    };
    assert_eq!((s, event, terminate), (fmi3OK, fmi3False, fmi3False));
    // directional derivatives over arrays: d der(y) = du, dz = du[1] + du[2]
    assert_eq!(
        derivative(&i, false, &[VR_DER_Y, VR_Z], &[VR_U], &[3.0, 4.0], 3).unwrap(),
        [3.0, 4.0, 7.0]
    );
    // the adjoint is the transpose: seed over der(y), z; result over u
    assert_eq!(
        derivative(&i, true, &[VR_DER_Y, VR_Z], &[VR_U], &[1.0, 2.0, 10.0], 2).unwrap(),
        [11.0, 12.0]
    );
    // the adjoint's seed and result are checked as the directional one's (found by the
    // misuse suite: a NaN seed or an overflowing sum came back with fmi3OK)
    let adjoint = |seed: &[f64]| derivative(&i, true, &[VR_DER_Y, VR_Z], &[VR_U], seed, 2);
    assert_eq!(adjoint(&[1.0, f64::NAN, 10.0]), Err(fmi3Error));
    assert!(last_error().contains("fmi3GetAdjointDerivative: seed value NaN rejected"));
    assert_eq!(adjoint(&[1e308, 1.0, 1e308]), Err(fmi3Error));
    assert!(
        last_error().contains("the adjoint derivative with respect to `u[1]` came out as inf"),
        "{}",
        last_error()
    );
    assert_eq!(adjoint(&[1.0, 2.0, 10.0]).unwrap(), [11.0, 12.0]);
    assert_eq!(
        derivative(&i, false, &[VR_Z], &[VR_TIME], &[1.0], 1),
        Err(fmi3Error)
    );
    assert!(last_error().contains("`time` (value reference 0) is neither a known nor an unknown"));
    assert_eq!(
        derivative(&i, false, &[VR_Z], &[VR_U], &[1.0], 1),
        Err(fmi3Error)
    );
    assert!(last_error()
        .contains("nSeed = 1 and nSensitivity = 1, but the references name 2 and 1 values"));
    assert_eq!(
        unsafe { me::enter_mode::<Toy, Fmi3>(i.0, &functions::ENTER_EVENT_MODE, true) },
        fmi3OK
    );
    assert_eq!(unsafe { ffi::terminate::<Toy>(i.0) }, fmi3OK);
}

#[test]
fn a_co_simulation_instance_refuses_the_model_exchange_functions() {
    let i = Instance::new("cs");
    assert_eq!(i.initialize(), fmi3OK);
    assert_eq!(
        unsafe { me::set_time::<Toy, Fmi3>(i.0, &functions::SET_TIME, 1.0) },
        fmi3Error
    );
    assert!(last_error().contains("fmi3SetTime: illegal call sequence"));
    assert_eq!(
        unsafe { me::enter_mode::<Toy, Fmi3>(i.0, &functions::ENTER_EVENT_MODE, true) },
        fmi3Error
    );
    let mut n = 9usize;
    assert_eq!(
        unsafe { me3::number_of::<Toy>(i.0, me3::Count::ContinuousStates, &mut n) },
        fmi3OK
    );
    assert_eq!(n, 2);
    // its directional derivative is there (the model has it): dy[1]/dy[1] after a step
    assert_eq!(i.set_f64(&[VR_U], &[1.0, 1.0]), fmi3OK);
    assert_eq!(i.step(0.0, 0.5).0, fmi3OK);
    assert_eq!(
        derivative(&i, false, &[VR_Y], &[VR_Y], &[1.0, 1.0], 2).unwrap(),
        [1.0, 1.0]
    );
}
