//! The Model Exchange C entry points both versions have alike: pointer and count checks,
//! then the version-neutral calls of [`crate::instance::model_exchange`], each inside the
//! same guarded call as every other entry point ([`with_slot`]). Each function is generic
//! over the model `M` and the front's slot data `X` and takes the calling [`Function`]
//! (`fmi2SetTime` or `fmi3SetTime`, …), so the `fmi2*` and `fmi3*` symbols
//! ([`crate::model_exchange_entries!`]) are one call each.

use super::pointers::{slice, slice_mut};
use super::slot::with_slot;
use crate::instance::{Function, Instance};
use crate::model::{EventUpdate, FmuModel};
use crate::types::Status;
use std::ffi::c_void;
use std::os::raw::c_int;

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

/// Emits, inside a front's export macro, the Model Exchange functions both versions have
/// alike (`fmi2SetTime`/`fmi3SetTime`, …, and those that fill the caller's Real array:
/// `fmi2GetDerivatives`, `fmi3GetContinuousStateDerivatives`, …) for the front's handle type,
/// slot data, Boolean type and `functions` module; the names in the standard's order.
#[doc(hidden)]
#[macro_export]
macro_rules! model_exchange_entries {
    (
        $handle:ty, $extra:ty, $boolean:ty, $functions:ident;
        $set_time:ident, $set_states:ident, $event_mode:ident, $continuous_mode:ident,
        $completed:ident, $states:ident, $derivatives:ident, $indicators:ident, $nominals:ident
    ) => {
        #[no_mangle]
        pub unsafe extern "C" fn $set_time(c: $handle, time: f64) -> ::std::os::raw::c_int {
            let f = &$functions::SET_TIME;
            unsafe { $crate::abi::model_exchange::set_time::<M, $extra>(c, f, time) }
        }
        #[no_mangle]
        pub unsafe extern "C" fn $set_states(
            c: $handle,
            x: *const f64,
            n: usize,
        ) -> ::std::os::raw::c_int {
            let f = &$functions::SET_CONTINUOUS_STATES;
            unsafe { $crate::abi::model_exchange::set_continuous_states::<M, $extra>(c, f, x, n) }
        }
        #[no_mangle]
        pub unsafe extern "C" fn $event_mode(c: $handle) -> ::std::os::raw::c_int {
            let f = &$functions::ENTER_EVENT_MODE;
            unsafe { $crate::abi::model_exchange::enter_mode::<M, $extra>(c, f, true) }
        }
        #[no_mangle]
        pub unsafe extern "C" fn $continuous_mode(c: $handle) -> ::std::os::raw::c_int {
            let f = &$functions::ENTER_CONTINUOUS_TIME_MODE;
            unsafe { $crate::abi::model_exchange::enter_mode::<M, $extra>(c, f, false) }
        }
        #[no_mangle]
        pub unsafe extern "C" fn $completed(
            c: $handle,
            no_set_prior: $boolean,
            enter_event_mode: *mut $boolean,
            terminate_simulation: *mut $boolean,
        ) -> ::std::os::raw::c_int {
            let _ = no_set_prior;
            let f = &$functions::COMPLETED_INTEGRATOR_STEP;
            let (event, stop) = (enter_event_mode, terminate_simulation);
            unsafe { $crate::abi::model_exchange::completed_integrator_step::<M, $extra, _>(c, f, event, stop) }
        }
        $crate::model_exchange_entries!(@array $handle, $extra, $functions;
            $states = GET_CONTINUOUS_STATES, ContinuousStates;
            $derivatives = GET_DERIVATIVES, Derivatives;
            $indicators = GET_EVENT_INDICATORS, EventIndicators;
            $nominals = GET_NOMINALS_OF_CONTINUOUS_STATES, Nominals;
        );
    };
    (@array $handle:ty, $extra:ty, $functions:ident; $($name:ident = $function:ident, $array:ident;)+) => {
        $(
            #[no_mangle]
            pub unsafe extern "C" fn $name(c: $handle, out: *mut f64, n: usize) -> ::std::os::raw::c_int {
                let (f, which) = (&$functions::$function, $crate::abi::model_exchange::Array::$array);
                unsafe { $crate::abi::model_exchange::get_array::<M, $extra>(c, f, which, out, n) }
            }
        )+
    };
}
