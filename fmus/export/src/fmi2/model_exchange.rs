//! The FMI 2.0 Model Exchange entry points FMI 3.0 has not in the same form
//! (`fmi2NewDiscreteStates` and its `fmi2EventInfo`, `fmi2GetDirectionalDerivative` on
//! scalars); the others are those of [`crate::abi::model_exchange`].

use super::ffi::{with_instance, Slot};
use crate::abi::model_exchange::update_discrete_states;
use crate::abi::pointers::{slice, slice_mut};
use crate::instance::state::fmi2 as functions;
use crate::model::{EventUpdate, FmuModel};
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
        with_instance::<M>(c, f, |s: &mut Slot<M>| {
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

/// Emits, inside [`export_fmu!`](crate::export_fmu), the FMI 2.0 Model Exchange symbols and
/// `fmi2GetDirectionalDerivative` (which serves Co-Simulation too).
#[doc(hidden)]
#[macro_export]
macro_rules! fmi2_model_exchange_entries {
    () => {
        #[no_mangle]
        pub unsafe extern "C" fn fmi2GetDirectionalDerivative(
            c: fmi2Component,
            unknowns: *const fmi2ValueReference,
            n_unknowns: usize,
            knowns: *const fmi2ValueReference,
            n_knowns: usize,
            seed: *const fmi2Real,
            out: *mut fmi2Real,
        ) -> fmi2Status {
            let (u, k) = ((unknowns, n_unknowns), (knowns, n_knowns));
            unsafe { me::get_directional_derivative::<M>(c, u, k, seed, out) }
        }
        $crate::model_exchange_entries!(fmi2Component, (), fmi2Boolean, functions;
            fmi2SetTime, fmi2SetContinuousStates, fmi2EnterEventMode, fmi2EnterContinuousTimeMode,
            fmi2CompletedIntegratorStep, fmi2GetContinuousStates, fmi2GetDerivatives,
            fmi2GetEventIndicators, fmi2GetNominalsOfContinuousStates);
        #[no_mangle]
        pub unsafe extern "C" fn fmi2NewDiscreteStates(
            c: fmi2Component,
            event_info: *mut me::fmi2EventInfo,
        ) -> fmi2Status {
            unsafe { me::new_discrete_states::<M>(c, event_info) }
        }
    };
}
