//! The FMI 2.0 Model Exchange C entry points (and `fmi2GetDirectionalDerivative`, which
//! serves Co-Simulation too): pointer and count checks, then the version-neutral calls of
//! [`crate::me::instance`], each inside the same `catch_unwind` and state-mask check as
//! every other entry point ([`crate::front::with_slot`]).

use crate::ffi::{slice, Slot};
use crate::front::with_slot;
use crate::instance::{functions, Function};
use crate::model::FmuModel;
use crate::types::*;

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

unsafe fn with_instance<M: FmuModel>(
    c: fmi2Component,
    f: &Function,
    body: impl FnOnce(&mut Slot<M>) -> Status,
) -> fmi2Status {
    // SAFETY: `c` is NULL or was returned by `instantiate::<M>` (the master's obligation).
    unsafe { with_slot::<M, ()>(c, f, body) }
}

/// Runs `body` on the `n` elements behind `p` as a mutable slice (NULL with `n > 0`:
/// rejected).
unsafe fn with_out<M: FmuModel>(
    c: fmi2Component,
    f: &Function,
    p: *mut f64,
    n: usize,
    body: impl FnOnce(&mut Slot<M>, &mut [f64]) -> Status,
) -> fmi2Status {
    unsafe {
        with_instance::<M>(c, f, |s| {
            if p.is_null() && n > 0 {
                return s.instance.reject(f, "the array argument is NULL");
            }
            let out: &mut [f64] = if n == 0 {
                &mut []
            } else {
                // SAFETY: the master passes `n` writable elements (FMI contract).
                std::slice::from_raw_parts_mut(p, n)
            };
            body(s, out)
        })
    }
}

/// `fmi2SetTime`.
///
/// # Safety
/// FMI pointer contract.
pub unsafe fn set_time<M: FmuModel>(c: fmi2Component, time: fmi2Real) -> fmi2Status {
    let f = &functions::SET_TIME;
    unsafe { with_instance::<M>(c, f, |s| s.instance.set_time(f, time)) }
}

/// `fmi2SetContinuousStates`.
///
/// # Safety
/// FMI pointer contract.
pub unsafe fn set_continuous_states<M: FmuModel>(
    c: fmi2Component,
    x: *const fmi2Real,
    nx: usize,
) -> fmi2Status {
    let f = &functions::SET_CONTINUOUS_STATES;
    unsafe {
        with_instance::<M>(c, f, |s| match slice(x, nx) {
            Some(x) => s.instance.set_continuous_states(f, x),
            None => s.instance.reject(f, "x is NULL"),
        })
    }
}

/// Emits the FMI 2.0 functions that fill a caller's Real array from one instance method.
macro_rules! array_getter {
    ($(#[$doc:meta])* $name:ident, $function:ident, $method:ident) => {
        $(#[$doc])*
        ///
        /// # Safety
        /// FMI pointer contract.
        pub unsafe fn $name<M: FmuModel>(c: fmi2Component, out: *mut fmi2Real, n: usize) -> fmi2Status {
            let f = &functions::$function;
            unsafe { with_out::<M>(c, f, out, n, |s, out| s.instance.$method(f, out)) }
        }
    };
}

array_getter!(
    /// `fmi2GetContinuousStates`.
    get_continuous_states, GET_CONTINUOUS_STATES, get_continuous_states);
array_getter!(
    /// `fmi2GetDerivatives`.
    get_derivatives, GET_DERIVATIVES, get_derivatives);
array_getter!(
    /// `fmi2GetEventIndicators`.
    get_event_indicators, GET_EVENT_INDICATORS, get_event_indicators);
array_getter!(
    /// `fmi2GetNominalsOfContinuousStates`.
    get_nominals_of_continuous_states, GET_NOMINALS_OF_CONTINUOUS_STATES, get_nominals);

/// `fmi2EnterEventMode`.
///
/// # Safety
/// FMI pointer contract.
pub unsafe fn enter_event_mode<M: FmuModel>(c: fmi2Component) -> fmi2Status {
    let f = &functions::ENTER_EVENT_MODE;
    unsafe { with_instance::<M>(c, f, |s| s.instance.enter_event_mode(f)) }
}

/// `fmi2EnterContinuousTimeMode`.
///
/// # Safety
/// FMI pointer contract.
pub unsafe fn enter_continuous_time_mode<M: FmuModel>(c: fmi2Component) -> fmi2Status {
    let f = &functions::ENTER_CONTINUOUS_TIME_MODE;
    unsafe { with_instance::<M>(c, f, |s| s.instance.enter_continuous_time_mode(f)) }
}

/// `fmi2NewDiscreteStates`: the model's discrete change, reported in `event_info`.
///
/// # Safety
/// FMI pointer contract.
pub unsafe fn new_discrete_states<M: FmuModel>(
    c: fmi2Component,
    event_info: *mut fmi2EventInfo,
) -> fmi2Status {
    let f = &functions::NEW_DISCRETE_STATES;
    unsafe {
        with_instance::<M>(c, f, |s| {
            if event_info.is_null() {
                return s.instance.reject(f, "eventInfo is NULL");
            }
            let (status, update) = s.instance.update_discrete_states(f);
            if status <= Status::Warning {
                // SAFETY: checked non-NULL; the master passes one fmi2EventInfo.
                *event_info = fmi2EventInfo {
                    newDiscreteStatesNeeded: update.discrete_states_need_update.into(),
                    terminateSimulation: update.terminate_simulation.into(),
                    nominalsOfContinuousStatesChanged: update.nominals_changed.into(),
                    valuesOfContinuousStatesChanged: update.states_changed.into(),
                    nextEventTimeDefined: update.next_event_time.is_some().into(),
                    nextEventTime: update.next_event_time.unwrap_or(0.0),
                };
            }
            status
        })
    }
}

/// `fmi2CompletedIntegratorStep`.
///
/// # Safety
/// FMI pointer contract.
pub unsafe fn completed_integrator_step<M: FmuModel>(
    c: fmi2Component,
    _no_set_fmu_state_prior: fmi2Boolean,
    enter_event_mode: *mut fmi2Boolean,
    terminate_simulation: *mut fmi2Boolean,
) -> fmi2Status {
    let f = &functions::COMPLETED_INTEGRATOR_STEP;
    unsafe {
        with_instance::<M>(c, f, |s| {
            if enter_event_mode.is_null() || terminate_simulation.is_null() {
                return s
                    .instance
                    .reject(f, "enterEventMode or terminateSimulation is NULL");
            }
            let (status, event, terminate) = s.instance.completed_integrator_step(f);
            // SAFETY: checked non-NULL; each points to one fmi2Boolean.
            *enter_event_mode = event.into();
            *terminate_simulation = terminate.into();
            status
        })
    }
}

/// `fmi2GetDirectionalDerivative` (Model Exchange and Co-Simulation).
///
/// # Safety
/// FMI pointer contract.
pub unsafe fn get_directional_derivative<M: FmuModel>(
    c: fmi2Component,
    unknowns: *const fmi2ValueReference,
    n_unknowns: usize,
    knowns: *const fmi2ValueReference,
    n_knowns: usize,
    seed: *const fmi2Real,
    out: *mut fmi2Real,
) -> fmi2Status {
    let f = &functions::GET_DIRECTIONAL_DERIVATIVE;
    unsafe {
        with_out::<M>(c, f, out, n_unknowns, |s, out| {
            let (Some(u), Some(k), Some(seed)) = (
                slice(unknowns, n_unknowns),
                slice(knowns, n_knowns),
                slice(seed, n_knowns),
            ) else {
                return s
                    .instance
                    .reject(f, "vUnknown_ref, vKnown_ref or dvKnown is NULL");
            };
            let u: Vec<usize> = u.iter().map(|&r| r as usize).collect();
            let k: Vec<usize> = k.iter().map(|&r| r as usize).collect();
            s.instance.directional_derivative(f, &u, &k, seed, out)
        })
    }
}
