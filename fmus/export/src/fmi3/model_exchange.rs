//! The FMI 3.0 Model Exchange C entry points that FMI 2.0 has not (the others are those of
//! [`crate::abi::model_exchange`]): the counts, `fmi3UpdateDiscreteStates`' flags, and the directional
//! and adjoint derivatives (which serve Co-Simulation too) with FMI 3.0 value references
//! (arrays) expanded to the table's scalars.

use super::ffi::{with_instance, Slot};
use super::types::*;
use super::values::unknown_reference;
use crate::abi::kinds::Fmi3;
use crate::abi::model_exchange::update_discrete_states as update;
use crate::abi::pointers::{slice, slice_mut};
use crate::abi::slot::write_out;
use crate::description::arrays::Target;
use crate::instance::state::fmi3 as functions;
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
        update::<M, Fmi3>(c, f, None, |update| {
            put(out.need_update, update.discrete_states_need_update.into());
            put(out.terminate, update.terminate_simulation.into());
            put(out.nominals_changed, update.nominals_changed.into());
            put(out.values_changed, update.states_changed.into());
            put(out.next_defined, update.next_event_time.is_some().into());
            put(out.next_time, update.next_event_time.unwrap_or(0.0));
        })
    }
}

/// What `fmi3GetNumberOf…` counts.
#[derive(Debug, Clone, Copy)]
pub enum Count {
    /// `fmi3GetNumberOfEventIndicators`.
    EventIndicators,
    /// `fmi3GetNumberOfContinuousStates`.
    ContinuousStates,
}

/// `fmi3GetNumberOfEventIndicators`, `fmi3GetNumberOfContinuousStates`.
///
/// # Safety
/// FMI pointer contract.
pub unsafe fn number_of<M: FmuModel>(c: fmi3Instance, what: Count, n: *mut usize) -> fmi3Status {
    let f = match what {
        Count::EventIndicators => &functions::GET_NUMBER_OF_EVENT_INDICATORS,
        Count::ContinuousStates => &functions::GET_NUMBER_OF_CONTINUOUS_STATES,
    };
    unsafe {
        write_out::<M, Fmi3, usize>(c, f, (n, "the size argument"), |s| match what {
            Count::EventIndicators => s.instance.event_indicator_count(),
            Count::ContinuousStates => s.instance.state_count(),
        })
    }
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

/// The table indices of the Real scalars FMI 3.0 value references `vrs` name (arrays
/// row-major); `Err` with the message for `time`, an unknown reference or another type.
fn scalars_of<M: FmuModel>(s: &Slot<M>, vrs: &[u32]) -> Result<Vec<usize>, String> {
    let interface = s.instance.interface();
    let mut indices = Vec::new();
    for &vr in vrs {
        match interface.layout.target(vr) {
            Some(Target::Variable(v)) => {
                let first = &interface.info.variables[v.first];
                if first.variable_type() != VariableType::Real {
                    return Err(format!(
                        "variable `{}` (value reference {vr}) is not a Float64",
                        v.name
                    ));
                }
                indices.extend(v.indices());
            }
            Some(Target::Time) => {
                return Err(
                    "`time` (value reference 0) is neither a known nor an unknown".to_string(),
                )
            }
            None => return Err(unknown_reference(interface, vr)),
        }
    }
    Ok(indices)
}

/// `fmi3GetDirectionalDerivative`, `fmi3GetAdjointDerivative`. The adjoint is the transpose:
/// one directional derivative per known with a unit seed, each column dotted with the seed
/// (checked like the directional one's: every seed value finite, every result finite or the
/// call is `Error` naming the known, nothing published).
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
            let Some(sensitivity) = slice_mut(call.sensitivity, call.n_sensitivity) else {
                return s.instance.reject(f, "sensitivity is NULL");
            };
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
                    if let Some(x) = seed.iter().find(|x| !x.is_finite()) {
                        return s.instance.reject(
                            f,
                            &format!("seed value {x} rejected, values must be finite"),
                        );
                    }
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
                        if !out[j].is_finite() {
                            let name = &s.instance.info().variables[*known].name;
                            let message = format!(
                                "the adjoint derivative with respect to `{name}` came out as {}: not published",
                                out[j]
                            );
                            return s.instance.reject(f, &message);
                        }
                    }
                    status
                }
            };
            if status <= Status::Warning {
                sensitivity.copy_from_slice(&out);
            }
            status
        })
    }
}

/// Emits, inside [`export_fmu!`](crate::export_fmu), the FMI 3.0 Model Exchange functions and the directional
/// and adjoint derivatives (which serve Co-Simulation too) over [`me`].
#[doc(hidden)]
#[macro_export]
macro_rules! fmi3_model_exchange_entries {
    () => {
        $crate::model_exchange_entries!(fmi3Instance, Fmi3, fmi3Boolean, functions;
            fmi3SetTime, fmi3SetContinuousStates, fmi3EnterEventMode, fmi3EnterContinuousTimeMode,
            fmi3CompletedIntegratorStep, fmi3GetContinuousStates, fmi3GetContinuousStateDerivatives,
            fmi3GetEventIndicators, fmi3GetNominalsOfContinuousStates);
        #[no_mangle]
        pub unsafe extern "C" fn fmi3UpdateDiscreteStates(
            c: fmi3Instance,
            need_update: *mut fmi3Boolean,
            terminate: *mut fmi3Boolean,
            nominals_changed: *mut fmi3Boolean,
            values_changed: *mut fmi3Boolean,
            next_defined: *mut fmi3Boolean,
            next_time: *mut fmi3Float64,
        ) -> fmi3Status {
            let flags = me::EventFlags {
                need_update,
                terminate,
                nominals_changed,
                values_changed,
                next_defined,
                next_time,
            };
            unsafe { me::update_discrete_states::<M>(c, flags) }
        }
        #[no_mangle]
        pub unsafe extern "C" fn fmi3GetNumberOfEventIndicators(
            c: fmi3Instance,
            n: *mut usize,
        ) -> fmi3Status {
            unsafe { me::number_of::<M>(c, me::Count::EventIndicators, n) }
        }
        #[no_mangle]
        pub unsafe extern "C" fn fmi3GetNumberOfContinuousStates(
            c: fmi3Instance,
            n: *mut usize,
        ) -> fmi3Status {
            unsafe { me::number_of::<M>(c, me::Count::ContinuousStates, n) }
        }
        $crate::fmi3_derivative!(fmi3GetDirectionalDerivative, me::Derivative::Directional);
        $crate::fmi3_derivative!(fmi3GetAdjointDerivative, me::Derivative::Adjoint);
    };
}

/// Emits, inside [`export_fmu!`](crate::export_fmu), `fmi3GetDirectionalDerivative` or
/// `fmi3GetAdjointDerivative`.
#[doc(hidden)]
#[macro_export]
macro_rules! fmi3_derivative {
    ($name:ident, $kind:expr) => {
        #[no_mangle]
        pub unsafe extern "C" fn $name(
            c: fmi3Instance,
            unknowns: *const fmi3ValueReference,
            n_unknowns: usize,
            knowns: *const fmi3ValueReference,
            n_knowns: usize,
            seed: *const fmi3Float64,
            n_seed: usize,
            sensitivity: *mut fmi3Float64,
            n_sensitivity: usize,
        ) -> fmi3Status {
            let call = me::DerivativeCall {
                unknowns,
                n_unknowns,
                knowns,
                n_knowns,
                seed,
                n_seed,
                sensitivity,
                n_sensitivity,
            };
            unsafe { me::derivative::<M>(c, call, $kind) }
        }
    };
}
