//! The FMI 2.0 typed get/set entry points (`fmi2GetReal` … `fmi2SetString`) and their
//! symbols ([`fmi2_value_entries!`](crate::fmi2_value_entries)): the pointer checks, then the
//! instance's checked get/set ([`crate::instance::get_set`]).

use crate::abi::kinds::{Fmi2, Kind};
use crate::abi::pointers::{slice, slice_mut};
use crate::abi::slot::{string_values, with_slot, Slot};
use crate::instance::state::{fmi2 as functions, Function};
use crate::model::FmuModel;
use crate::types::*;
use crate::variables::VariableType;

/// The numeric FMI 2.0 types exchanged through `fmi2Get*`/`fmi2Set*` (the shared value
/// kinds of [`crate::abi::kinds`]).
pub use crate::abi::kinds::{Boolean, Integer, Real};

/// The value references of a get call, after its pointer checks (`Err`: the rejection's
/// status).
///
/// # Safety
/// FMI pointer contract.
unsafe fn get_references<'a, M: FmuModel>(
    s: &Slot<M>,
    f: &Function,
    vr: *const fmi2ValueReference,
    n: usize,
    out_is_null: bool,
) -> Result<&'a [fmi2ValueReference], Status> {
    // SAFETY: forwarded from the caller.
    let Some(vrs) = (unsafe { slice(vr, n) }) else {
        return Err(s.instance.reject(f, "vr is NULL"));
    };
    if n > 0 && out_is_null {
        return Err(s.instance.reject(f, "value is NULL"));
    }
    Ok(vrs)
}

/// `fmi2GetReal`, `fmi2GetInteger`, `fmi2GetBoolean`: the values into a C array.
///
/// # Safety
/// FMI pointer contract.
pub unsafe fn get<M: FmuModel, T: Kind<Fmi2>>(
    c: fmi2Component,
    vr: *const fmi2ValueReference,
    n: usize,
    out: *mut T::C,
) -> fmi2Status {
    let f = T::GET;
    unsafe {
        with_slot::<M, ()>(c, f, |s| {
            // SAFETY: `vr` and `out` are NULL or hold `n` elements (FMI contract).
            match (slice(vr, n), slice_mut(out, n)) {
                (Some(vrs), Some(out)) => s.instance.get_array(f, T::TYPE, vrs, out, T::to_c),
                _ => match get_references(s, f, vr, n, out.is_null()) {
                    Err(status) => status,
                    Ok(_) => Status::Error,
                },
            }
        })
    }
}

/// `fmi2GetString`.
///
/// # Safety
/// FMI pointer contract.
pub unsafe fn get_string<M: FmuModel>(
    c: fmi2Component,
    vr: *const fmi2ValueReference,
    n: usize,
    value: *mut fmi2String,
) -> fmi2Status {
    let f = &functions::GET_STRING;
    unsafe {
        with_slot::<M, ()>(c, f, |s| {
            let vrs = match get_references(s, f, vr, n, value.is_null()) {
                Ok(vrs) => vrs,
                Err(status) => return status,
            };
            let mut values = Vec::with_capacity(n);
            let status = s
                .instance
                .get_values(f, vrs, VariableType::String, |_, all, index| {
                    values.push(all.string(index).to_string())
                });
            // SAFETY: `value` points to `n` slots and `values` has at most `n` elements.
            s.return_strings(&values, value);
            status
        })
    }
}

/// `fmi2SetReal`, `fmi2SetInteger`, `fmi2SetBoolean`: the values from a C array.
///
/// # Safety
/// FMI pointer contract.
pub unsafe fn set<M: FmuModel, T: Kind<Fmi2>>(
    c: fmi2Component,
    vr: *const fmi2ValueReference,
    n: usize,
    value: *const T::C,
) -> fmi2Status {
    let f = T::SET;
    unsafe {
        with_slot::<M, ()>(c, f, |s| {
            let (Some(vrs), Some(values)) = (slice(vr, n), slice(value, n)) else {
                return s.instance.reject(f, "vr or value is NULL");
            };
            s.instance
                .set_array(f, T::TYPE, (vrs, values), T::to_number)
        })
    }
}

/// `fmi2SetString`.
///
/// # Safety
/// FMI pointer contract.
pub unsafe fn set_string<M: FmuModel>(
    c: fmi2Component,
    vr: *const fmi2ValueReference,
    n: usize,
    value: *const fmi2String,
) -> fmi2Status {
    let f = &functions::SET_STRING;
    unsafe {
        with_slot::<M, ()>(c, f, |s| {
            match string_values(s, f, (vr, n), (value, n), "vr or value is NULL") {
                Ok((vrs, values)) => s.instance.set_values(f, vrs.iter().copied().zip(values)),
                Err(status) => status,
            }
        })
    }
}

/// Emits, inside [`export_fmu!`](crate::export_fmu), the `fmi2Get*`/`fmi2Set*` symbols, each
/// pair with its C value type and the two functions of this module it calls.
#[doc(hidden)]
#[macro_export]
macro_rules! fmi2_value_entries {
    () => {
        use $crate::fmi2::values as v;
        $crate::get_set_entries!(fmi2Component, fmi2ValueReference, fmi2Status, ();
            fmi2GetReal, fmi2SetReal, fmi2Real => v::get::<M, v::Real>, v::set::<M, v::Real>;
            fmi2GetInteger, fmi2SetInteger, fmi2Integer => v::get::<M, v::Integer>, v::set::<M, v::Integer>;
            fmi2GetBoolean, fmi2SetBoolean, fmi2Boolean => v::get::<M, v::Boolean>, v::set::<M, v::Boolean>;
            fmi2GetString, fmi2SetString, fmi2String => v::get_string::<M>, v::set_string::<M>;
        );
    };
}
