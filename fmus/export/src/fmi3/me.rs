//! The FMI 3.0 Model Exchange C entry points (and the directional and adjoint derivatives,
//! which serve Co-Simulation too): pointer and count checks, FMI 3.0 value references (arrays)
//! expanded to the table's scalars, then the version-neutral calls of
//! [`crate::me::instance`] that the FMI 2.0 front makes too.

use super::ffi::{expand, with_instance, Element, Slot};
use super::functions;
use super::types::*;
use crate::ffi::slice;
use crate::instance::Function;
use crate::model::FmuModel;
use crate::types::Status;
use crate::variables::VariableType;

/// Writes `value` behind `p` unless it is NULL.
///
/// # Safety
/// `p` is NULL or points to one writable `T`.
unsafe fn put<T>(p: *mut T, value: T) {
    if !p.is_null() {
        // SAFETY: the caller's obligation.
        unsafe { *p = value };
    }
}

/// `fmi3EnterEventMode`.
///
/// # Safety
/// FMI pointer contract.
pub unsafe fn enter_event_mode<M: FmuModel>(c: fmi3Instance) -> fmi3Status {
    let f = &functions::ENTER_EVENT_MODE;
    unsafe { with_instance::<M>(c, f, |s| s.instance.enter_event_mode(f)) }
}

/// `fmi3EnterContinuousTimeMode`.
///
/// # Safety
/// FMI pointer contract.
pub unsafe fn enter_continuous_time_mode<M: FmuModel>(c: fmi3Instance) -> fmi3Status {
    let f = &functions::ENTER_CONTINUOUS_TIME_MODE;
    unsafe { with_instance::<M>(c, f, |s| s.instance.enter_continuous_time_mode(f)) }
}

/// The output arguments of `fmi3UpdateDiscreteStates` (each may be NULL).
pub struct EventFlags {
    pub need_update: *mut fmi3Boolean,
    pub terminate: *mut fmi3Boolean,
    pub nominals_changed: *mut fmi3Boolean,
    pub values_changed: *mut fmi3Boolean,
    pub next_defined: *mut fmi3Boolean,
    pub next_time: *mut fmi3Float64,
}

/// `fmi3UpdateDiscreteStates`.
///
/// # Safety
/// FMI pointer contract; each flag is NULL or points to one writable value.
pub unsafe fn update_discrete_states<M: FmuModel>(c: fmi3Instance, out: EventFlags) -> fmi3Status {
    let f = &functions::UPDATE_DISCRETE_STATES;
    unsafe {
        with_instance::<M>(c, f, |s| {
            let (status, update) = s.instance.update_discrete_states(f);
            if status <= Status::Warning {
                put(out.need_update, update.discrete_states_need_update.into());
                put(out.terminate, update.terminate_simulation.into());
                put(out.nominals_changed, update.nominals_changed.into());
                put(out.values_changed, update.states_changed.into());
                put(out.next_defined, update.next_event_time.is_some().into());
                put(out.next_time, update.next_event_time.unwrap_or(0.0));
            }
            status
        })
    }
}

/// `fmi3CompletedIntegratorStep`.
///
/// # Safety
/// FMI pointer contract.
pub unsafe fn completed_integrator_step<M: FmuModel>(
    c: fmi3Instance,
    enter_event_mode: *mut fmi3Boolean,
    terminate: *mut fmi3Boolean,
) -> fmi3Status {
    let f = &functions::COMPLETED_INTEGRATOR_STEP;
    unsafe {
        with_instance::<M>(c, f, |s| {
            let (status, event, stop) = s.instance.completed_integrator_step(f);
            put(enter_event_mode, event.into());
            put(terminate, stop.into());
            status
        })
    }
}

/// `fmi3SetTime`.
///
/// # Safety
/// FMI pointer contract.
pub unsafe fn set_time<M: FmuModel>(c: fmi3Instance, time: fmi3Float64) -> fmi3Status {
    let f = &functions::SET_TIME;
    unsafe { with_instance::<M>(c, f, |s| s.instance.set_time(f, time)) }
}

/// `fmi3SetContinuousStates`.
///
/// # Safety
/// FMI pointer contract.
pub unsafe fn set_continuous_states<M: FmuModel>(
    c: fmi3Instance,
    x: *const fmi3Float64,
    n: usize,
) -> fmi3Status {
    let f = &functions::SET_CONTINUOUS_STATES;
    unsafe {
        with_instance::<M>(c, f, |s| match slice(x, n) {
            Some(x) => s.instance.set_continuous_states(f, x),
            None => s.instance.reject(f, "continuousStates is NULL"),
        })
    }
}

/// The Float64 arrays of the Model Exchange interface.
#[allow(non_camel_case_types)]
pub enum Array {
    get_continuous_states,
    get_derivatives,
    get_event_indicators,
    get_nominals,
}

/// `fmi3GetContinuousStates`, `fmi3GetContinuousStateDerivatives`, `fmi3GetEventIndicators`,
/// `fmi3GetNominalsOfContinuousStates`: the array into the caller's `n` elements.
///
/// # Safety
/// FMI pointer contract.
pub unsafe fn array<M: FmuModel>(
    c: fmi3Instance,
    out: *mut fmi3Float64,
    n: usize,
    which: Array,
) -> fmi3Status {
    let f = match which {
        Array::get_continuous_states => &functions::GET_CONTINUOUS_STATES,
        Array::get_derivatives => &functions::GET_CONTINUOUS_STATE_DERIVATIVES,
        Array::get_event_indicators => &functions::GET_EVENT_INDICATORS,
        Array::get_nominals => &functions::GET_NOMINALS_OF_CONTINUOUS_STATES,
    };
    unsafe {
        with_instance::<M>(c, f, |s| {
            if out.is_null() && n > 0 {
                return s.instance.reject(f, "the array argument is NULL");
            }
            let out: &mut [f64] = if n == 0 {
                &mut []
            } else {
                // SAFETY: the master passes `n` writable elements (FMI contract).
                std::slice::from_raw_parts_mut(out, n)
            };
            match which {
                Array::get_continuous_states => s.instance.get_continuous_states(f, out),
                Array::get_derivatives => s.instance.get_derivatives(f, out),
                Array::get_event_indicators => s.instance.get_event_indicators(f, out),
                Array::get_nominals => s.instance.get_nominals(f, out),
            }
        })
    }
}

/// Writes a count of the instance behind `c` into `n`.
unsafe fn count<M: FmuModel>(
    c: fmi3Instance,
    f: &Function,
    n: *mut usize,
    of: impl FnOnce(&Slot<M>) -> usize,
) -> fmi3Status {
    unsafe {
        with_instance::<M>(c, f, |s| {
            if n.is_null() {
                return s.instance.reject(f, "the size argument is NULL");
            }
            // SAFETY: checked non-NULL; one writable size_t.
            *n = of(s);
            Status::Ok
        })
    }
}

/// `fmi3GetNumberOfEventIndicators`.
///
/// # Safety
/// FMI pointer contract.
pub unsafe fn number_of_event_indicators<M: FmuModel>(
    c: fmi3Instance,
    n: *mut usize,
) -> fmi3Status {
    let f = &functions::GET_NUMBER_OF_EVENT_INDICATORS;
    unsafe { count::<M>(c, f, n, |s| s.instance.event_indicator_count()) }
}

/// `fmi3GetNumberOfContinuousStates`.
///
/// # Safety
/// FMI pointer contract.
pub unsafe fn number_of_continuous_states<M: FmuModel>(
    c: fmi3Instance,
    n: *mut usize,
) -> fmi3Status {
    let f = &functions::GET_NUMBER_OF_CONTINUOUS_STATES;
    unsafe { count::<M>(c, f, n, |s| s.instance.state_count()) }
}

/// Which derivative a call asks for.
pub enum Derivative {
    /// `fmi3GetDirectionalDerivative`: sensitivity = J · seed (seed over the knowns).
    Directional,
    /// `fmi3GetAdjointDerivative`: sensitivity = Jᵀ · seed (seed over the unknowns).
    Adjoint,
}

/// The arguments of `fmi3GetDirectionalDerivative` / `fmi3GetAdjointDerivative`.
pub struct DerivativeCall {
    pub unknowns: *const fmi3ValueReference,
    pub n_unknowns: usize,
    pub knowns: *const fmi3ValueReference,
    pub n_knowns: usize,
    pub seed: *const fmi3Float64,
    pub n_seed: usize,
    pub sensitivity: *mut fmi3Float64,
    pub n_sensitivity: usize,
}

/// The table indices of the scalars FMI 3.0 value references `vrs` name (`time` refused).
fn scalars_of<M: FmuModel>(s: &Slot<M>, vrs: &[u32]) -> Result<Vec<usize>, String> {
    let mut n = 0;
    for &vr in vrs {
        n += match s.extra.target(vr) {
            Some(super::arrays::Target::Variable(v)) => v.len(),
            _ => 1,
        };
    }
    expand(s, vrs, VariableType::Real, n)?
        .into_iter()
        .map(|e| match e {
            Element::Scalar(i) => Ok(i as usize),
            Element::Time => {
                Err("`time` (value reference 0) is neither a known nor an unknown".to_string())
            }
        })
        .collect()
}

/// `fmi3GetDirectionalDerivative`, `fmi3GetAdjointDerivative`. The adjoint is the transpose:
/// one directional derivative per known with a unit seed, each column dotted with the seed.
///
/// # Safety
/// FMI pointer contract.
pub unsafe fn derivative<M: FmuModel>(
    c: fmi3Instance,
    call: DerivativeCall,
    kind: Derivative,
) -> fmi3Status {
    let f = match kind {
        Derivative::Directional => &functions::GET_DIRECTIONAL_DERIVATIVE,
        Derivative::Adjoint => &functions::GET_ADJOINT_DERIVATIVE,
    };
    unsafe {
        with_instance::<M>(c, f, |s| {
            let (Some(u), Some(k), Some(seed)) = (
                slice(call.unknowns, call.n_unknowns),
                slice(call.knowns, call.n_knowns),
                slice(call.seed, call.n_seed),
            ) else {
                return s.instance.reject(f, "unknowns, knowns or seed is NULL");
            };
            if call.sensitivity.is_null() && call.n_sensitivity > 0 {
                return s.instance.reject(f, "sensitivity is NULL");
            }
            let (unknowns, knowns) = match (scalars_of(s, u), scalars_of(s, k)) {
                (Ok(u), Ok(k)) => (u, k),
                (Err(message), _) | (_, Err(message)) => return s.instance.reject(f, &message),
            };
            let (n_seed, n_out) = match kind {
                Derivative::Directional => (knowns.len(), unknowns.len()),
                Derivative::Adjoint => (unknowns.len(), knowns.len()),
            };
            if call.n_seed != n_seed || call.n_sensitivity != n_out {
                return s.instance.reject(
                    f,
                    &format!(
                        "nSeed = {} and nSensitivity = {}, but the references name {n_seed} and {n_out} values",
                        call.n_seed, call.n_sensitivity
                    ),
                );
            }
            let mut out = vec![0.0; n_out];
            let status = match kind {
                Derivative::Directional => s
                    .instance
                    .directional_derivative(f, &unknowns, &knowns, seed, &mut out),
                Derivative::Adjoint => {
                    let mut column = vec![0.0; unknowns.len()];
                    let mut status = Status::Ok;
                    for (j, known) in knowns.iter().enumerate() {
                        status = status.max(s.instance.directional_derivative(
                            f,
                            &unknowns,
                            std::slice::from_ref(known),
                            &[1.0],
                            &mut column,
                        ));
                        if status > Status::Warning {
                            break;
                        }
                        out[j] = column.iter().zip(seed).map(|(a, b)| a * b).sum();
                    }
                    status
                }
            };
            if status <= Status::Warning && n_out > 0 {
                // SAFETY: `sensitivity` holds `n_sensitivity == n_out` elements.
                std::ptr::copy_nonoverlapping(out.as_ptr(), call.sensitivity, n_out);
            }
            status
        })
    }
}
