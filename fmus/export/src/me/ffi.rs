//! The Model Exchange C entry points of both versions: pointer and count checks, then the
//! version-neutral calls of [`crate::me::instance`], each inside the same `catch_unwind` and
//! state-mask check as every other entry point ([`crate::front::with_slot`]). Each function is
//! generic over the model `M` and the front's slot data `X` and takes the calling
//! [`Function`] (`fmi2SetTime` or `fmi3SetTime`, …), so the `fmi2*` and `fmi3*` symbols that
//! [`export_fmu!`](crate::export_fmu) emits are one call each. Also
//! `fmi2GetDirectionalDerivative` (FMI 3.0's, over arrays, is in [`crate::fmi3::me`]).

use crate::ffi::{slice, slice_mut, with_instance};
use crate::front::{with_slot, Slot};
use crate::instance::{functions, Function, Instance};
use crate::model::{EventUpdate, FmuModel};
use crate::types::*;
use std::ffi::c_void;
use std::os::raw::c_int;

/// `fmi2EventInfo` of `fmi2FunctionTypes.h`.
#[repr(C)]
#[derive(Debug, Clone, Copy, Default)]
#[allow(non_snake_case)]
pub struct fmi2EventInfo {
    pub newDiscreteStatesNeeded: fmi2Boolean,
    pub terminateSimulation: fmi2Boolean,
    pub nominalsOfContinuousStatesChanged: fmi2Boolean,
    pub valuesOfContinuousStatesChanged: fmi2Boolean,
    pub nextEventTimeDefined: fmi2Boolean,
    pub nextEventTime: fmi2Real,
}

impl From<EventUpdate> for fmi2EventInfo {
    fn from(update: EventUpdate) -> Self {
        Self {
            newDiscreteStatesNeeded: update.discrete_states_need_update.into(),
            terminateSimulation: update.terminate_simulation.into(),
            nominalsOfContinuousStatesChanged: update.nominals_changed.into(),
            valuesOfContinuousStatesChanged: update.states_changed.into(),
            nextEventTimeDefined: update.next_event_time.is_some().into(),
            nextEventTime: update.next_event_time.unwrap_or(0.0),
        }
    }
}

/// Refuses an array count other than the model's (`nx` states, `ni` event indicators) before
/// the caller's pointer becomes a slice: a wrong count must never size one (it may exceed the
/// caller's memory, or `isize::MAX` bytes).
fn check_array_count<M: FmuModel>(
    instance: &Instance<M>,
    f: &Function,
    which: Array,
    n: usize,
) -> Status {
    match which {
        Array::EventIndicators => {
            instance.check_count(f, "ni", n, instance.event_indicator_count())
        }
        _ => instance.check_count(f, "nx", n, instance.state_count()),
    }
}

/// `fmi*SetTime`.
///
/// # Safety
/// FMI pointer contract.
pub unsafe fn set_time<M: FmuModel, X>(c: *mut c_void, f: &Function, time: f64) -> c_int {
    unsafe { with_slot::<M, X>(c, f, |s| s.instance.set_time(f, time)) }
}

/// `fmi*SetContinuousStates`.
///
/// # Safety
/// FMI pointer contract.
pub unsafe fn set_continuous_states<M: FmuModel, X>(
    c: *mut c_void,
    f: &Function,
    x: *const f64,
    n: usize,
) -> c_int {
    unsafe {
        with_slot::<M, X>(c, f, |s| {
            let status = check_array_count(&s.instance, f, Array::ContinuousStates, n);
            if status > Status::Warning {
                return status;
            }
            match slice(x, n) {
                Some(x) => s.instance.set_continuous_states(f, x),
                None => s.instance.reject(f, "the states argument is NULL"),
            }
        })
    }
}

/// The Real arrays of the Model Exchange interface.
#[derive(Debug, Clone, Copy)]
pub enum Array {
    /// `fmi*GetContinuousStates`.
    ContinuousStates,
    /// `fmi2GetDerivatives`, `fmi3GetContinuousStateDerivatives`.
    Derivatives,
    /// `fmi*GetEventIndicators`.
    EventIndicators,
    /// `fmi*GetNominalsOfContinuousStates`.
    Nominals,
}

/// `which` array into the caller's `n` elements behind `out`.
///
/// # Safety
/// FMI pointer contract.
pub unsafe fn get_array<M: FmuModel, X>(
    c: *mut c_void,
    f: &Function,
    which: Array,
    out: *mut f64,
    n: usize,
) -> c_int {
    unsafe {
        with_slot::<M, X>(c, f, |s| {
            let status = check_array_count(&s.instance, f, which, n);
            if status > Status::Warning {
                return status;
            }
            let Some(out) = slice_mut(out, n) else {
                return s.instance.reject(f, "the array argument is NULL");
            };
            match which {
                Array::ContinuousStates => s.instance.get_continuous_states(f, out),
                Array::Derivatives => s.instance.get_derivatives(f, out),
                Array::EventIndicators => s.instance.get_event_indicators(f, out),
                Array::Nominals => s.instance.get_nominals(f, out),
            }
        })
    }
}

/// `fmi*EnterEventMode` (`event` true) or `fmi*EnterContinuousTimeMode`.
///
/// # Safety
/// FMI pointer contract.
pub unsafe fn enter_mode<M: FmuModel, X>(c: *mut c_void, f: &Function, event: bool) -> c_int {
    unsafe {
        with_slot::<M, X>(c, f, |s| {
            if event {
                s.instance.enter_event_mode(f)
            } else {
                s.instance.enter_continuous_time_mode(f)
            }
        })
    }
}

/// `fmi2NewDiscreteStates`, `fmi3UpdateDiscreteStates`: the model's discrete change, handed
/// to `write` when it succeeded; `missing` names a NULL output argument the call must refuse.
///
/// # Safety
/// FMI pointer contract.
pub unsafe fn update_discrete_states<M: FmuModel, X>(
    c: *mut c_void,
    f: &Function,
    missing: Option<&str>,
    write: impl FnOnce(EventUpdate),
) -> c_int {
    unsafe {
        with_slot::<M, X>(c, f, |s| {
            if let Some(what) = missing {
                return s.instance.reject(f, &format!("{what} is NULL"));
            }
            let (status, update) = s.instance.update_discrete_states(f);
            if status <= Status::Warning {
                write(update);
            }
            status
        })
    }
}

/// `fmi*CompletedIntegratorStep`: (enterEventMode, terminateSimulation) into the two flags,
/// each NULL or one writable value (FMI 2.0 requires both).
///
/// # Safety
/// FMI pointer contract.
pub unsafe fn completed_integrator_step<M: FmuModel, X, B: From<bool>>(
    c: *mut c_void,
    f: &Function,
    enter_event_mode: *mut B,
    terminate_simulation: *mut B,
) -> c_int {
    unsafe {
        with_slot::<M, X>(c, f, |s| {
            let (status, event, terminate) = s.instance.completed_integrator_step(f);
            for (flag, value) in [(enter_event_mode, event), (terminate_simulation, terminate)] {
                if !flag.is_null() {
                    // SAFETY: a non-NULL flag points to one writable value.
                    *flag = value.into();
                }
            }
            status
        })
    }
}

/// `fmi2NewDiscreteStates`.
///
/// # Safety
/// FMI pointer contract.
pub unsafe fn new_discrete_states<M: FmuModel>(
    c: fmi2Component,
    event_info: *mut fmi2EventInfo,
) -> fmi2Status {
    let f = &functions::NEW_DISCRETE_STATES;
    let missing = event_info.is_null().then_some("eventInfo");
    // SAFETY: written only when non-NULL; the master passes one fmi2EventInfo.
    unsafe { update_discrete_states::<M, ()>(c, f, missing, |update| *event_info = update.into()) }
}

/// The value references and seed of `fmi2GetDirectionalDerivative`: (pointer, count) pairs.
pub type References = (*const fmi2ValueReference, usize);

/// `fmi2GetDirectionalDerivative` (Model Exchange and Co-Simulation): `out` (one per
/// unknown) = J · `seed` (one per known).
///
/// # Safety
/// FMI pointer contract.
pub unsafe fn get_directional_derivative<M: FmuModel>(
    c: fmi2Component,
    (unknowns, n_unknowns): References,
    (knowns, n_knowns): References,
    seed: *const fmi2Real,
    out: *mut fmi2Real,
) -> fmi2Status {
    let f = &functions::GET_DIRECTIONAL_DERIVATIVE;
    unsafe {
        with_instance::<M>(c, f, |s: &mut Slot<M, ()>| {
            let (Some(u), Some(k), Some(seed), Some(out)) = (
                slice(unknowns, n_unknowns),
                slice(knowns, n_knowns),
                slice(seed, n_knowns),
                slice_mut(out, n_unknowns),
            ) else {
                return s
                    .instance
                    .reject(f, "vUnknown_ref, vKnown_ref, dvKnown or dvUnknown is NULL");
            };
            let u: Vec<usize> = u.iter().map(|&r| r as usize).collect();
            let k: Vec<usize> = k.iter().map(|&r| r as usize).collect();
            s.instance.directional_derivative(f, &u, &k, seed, out)
        })
    }
}
