//! The FMI 3.0 typed get/set entry points (`fmi3GetFloat64` … `fmi3SetString`). Value
//! references are those of the shared [`Layout`](crate::description::arrays::Layout) of the
//! instance's interface: arrays are expanded to the instance's scalars here, without a
//! buffer, and `nValues` must equal the number of elements they name.

use super::types::*;
use crate::abi::kinds::{Fmi3, Kind};
use crate::abi::pointers::{slice, slice_mut};
use crate::abi::slot::{string_values, with_slot, Slot};
use crate::description::arrays::{Target, TIME};
use crate::description::fmi3::type_name;
use crate::instance::state::fmi3 as functions;
use crate::instance::{Access, Function, Instance, Interface};
use crate::model::FmuModel;
use crate::types::Status;
use crate::variables::{Value, VariableType};
use std::sync::Arc;

/// Why FMI 3.0 value reference `vr` names nothing.
pub(super) fn unknown_reference(interface: &Interface, vr: u32) -> String {
    format!(
        "unknown value reference {vr} ({} has value references 0 to {})",
        interface.info.model_identifier,
        interface.layout.max_value_reference()
    )
}

/// Checks the value references of a call: every one known and naming variables of type
/// `expected`, and `n_values` the number of values they name (arrays row-major); `Err` with
/// the message. Allocates nothing unless it fails.
fn check_references<M: FmuModel>(
    slot: &Slot<M, Fmi3>,
    vrs: &[u32],
    expected: VariableType,
    n_values: usize,
) -> Result<(), String> {
    let interface = slot.instance.interface();
    let mut count = 0;
    for &vr in vrs {
        let (name, actual, len) = match interface.layout.target(vr) {
            None => return Err(unknown_reference(interface, vr)),
            Some(Target::Time) => ("time", VariableType::Real, 1),
            Some(Target::Variable(v)) => (
                v.name.as_str(),
                interface.access[v.first].variable_type,
                v.len(),
            ),
        };
        if actual != expected {
            return Err(format!(
                "variable `{name}` (value reference {vr}) is of type {}, not {}",
                type_name(actual),
                type_name(expected)
            ));
        }
        count += len;
    }
    if count != n_values {
        return Err(format!(
            "nValues = {n_values}, but the {} value references name {count} values",
            vrs.len()
        ));
    }
    Ok(())
}

/// The FMI 3.0 types exchanged through `fmi3Get*`/`fmi3Set*` (the shared value kinds of
/// [`crate::abi::kinds`]): `fmi3Float64`, `fmi3Int32`, `fmi3Boolean`.
pub use crate::abi::kinds::{Boolean, Integer as Int32, Real as Float64};

/// A get call on the slot: checks the pointers and the references, lets the instance compute
/// what it must, then hands the `n_values` values `vr` names (arrays row-major) to `write`:
/// their positions and values (`time` for value reference 0). No buffer.
///
/// # Safety
/// FMI pointer contract.
#[allow(clippy::too_many_arguments)]
unsafe fn read<M: FmuModel>(
    s: &mut Slot<M, Fmi3>,
    f: &Function,
    vr: *const fmi3ValueReference,
    nvr: usize,
    out_is_null: bool,
    n_values: usize,
    expected: VariableType,
    mut write: impl FnMut(usize, Element<'_>),
) -> Status {
    // SAFETY: forwarded from the caller.
    let Some(vrs) = (unsafe { slice(vr, nvr) }) else {
        return s.instance.reject(f, "valueReferences is NULL");
    };
    if n_values > 0 && out_is_null {
        return s.instance.reject(f, "values is NULL");
    }
    if let Err(message) = check_references(s, vrs, expected, n_values) {
        return s.instance.reject(f, &message);
    }
    let interface = Arc::clone(s.instance.interface());
    let status = s.instance.refresh_for(f, interface.layout.indices_of(vrs));
    if status > Status::Warning {
        return status;
    }
    let (interface, values) = (s.instance.interface(), s.instance.values());
    let (numbers, time) = (values.numbers(), s.instance.time());
    let texts = expected == VariableType::String;
    let mut k = 0;
    for &vr in vrs {
        match interface.layout.target(vr) {
            Some(Target::Time) => {
                write(k, Element::Number(time));
                k += 1;
            }
            Some(Target::Variable(v)) if texts => {
                for index in v.indices() {
                    write(k, Element::Text(values.string(index)));
                    k += 1;
                }
            }
            Some(Target::Variable(v)) => {
                for &x in numbers.get(v.indices()).unwrap_or_default() {
                    write(k, Element::Number(x));
                    k += 1;
                }
            }
            None => {}
        }
    }
    status
}

/// The get call's fast path: when nothing must be computed first and every reference names
/// variables of type `expected` whose values fill `out` exactly, the values (arrays
/// row-major, `time` for value reference 0) into `out`, each through `to_c`; `None`
/// otherwise, and [`read`] checks again and says why (the values written are then undefined,
/// as FMI 3.0 allows for a failed get). A span lookup and a slice copy per reference; for the
/// common call, scalars only (`nValues = nvr`), a span lookup and a load, and a call that
/// names an array goes on from it, not from the start.
#[inline(always)]
fn read_fast<M: FmuModel, C>(
    s: &Slot<M, Fmi3>,
    expected: VariableType,
    vrs: &[u32],
    out: &mut [C],
    to_c: impl Fn(f64) -> C,
) -> Option<Status> {
    let instance = &s.instance;
    if instance.needs_refresh() || instance.reads_pending_indicator(vrs, true) {
        return None;
    }
    let (spans, numbers) = (&instance.interface().spans, instance.values().numbers());
    let type_bit = Access::type_bit(expected);
    // the scalars ahead of the first other reference (all of the master's call): the value
    // at the same position as its reference
    let done = 'scalars: {
        if vrs.len() != out.len() {
            break 'scalars 0;
        }
        for (i, (o, &vr)) in out.iter_mut().zip(vrs).enumerate() {
            match spans.get(vr as usize) {
                Some(span) if span.len == 1 && span.type_bit == type_bit => {
                    *o = to_c(*numbers.get(span.first as usize)?);
                }
                _ => break 'scalars i,
            }
        }
        return Some(Status::Ok);
    };
    // the rest, from the first array, `time` or reference of another type
    let mut k = done;
    for &vr in vrs.get(done..)? {
        let span = spans.get(vr as usize)?;
        if span.type_bit != type_bit {
            return None;
        }
        let first = span.first as usize;
        k += match span.len as usize {
            0 => {
                *out.get_mut(k)? = to_c(instance.time());
                1
            }
            1 => {
                *out.get_mut(k)? = to_c(*numbers.get(first)?);
                1
            }
            len => {
                let xs = numbers.get(first..first + len)?;
                for (o, &x) in out.get_mut(k..k + len)?.iter_mut().zip(xs) {
                    *o = to_c(x);
                }
                len
            }
        };
    }
    (k == out.len()).then_some(Status::Ok)
}

/// A value a get call reads: a number ([`crate::Values::numbers`]) or a String's text.
enum Element<'a> {
    Number(f64),
    Text(&'a str),
}

/// `fmi3GetFloat64`, `fmi3GetInt32`, `fmi3GetBoolean`: the values (arrays row-major) into a C
/// array of `n_values` elements.
///
/// # Safety
/// FMI pointer contract.
pub unsafe fn get<M: FmuModel, K: Kind<Fmi3>>(
    c: fmi3Instance,
    vr: *const fmi3ValueReference,
    nvr: usize,
    out: *mut K::C,
    n_values: usize,
) -> fmi3Status {
    let (f, null) = (K::GET, out.is_null());
    unsafe {
        with_slot::<M, Fmi3>(c, f, |s| {
            // SAFETY: `vr` and `out` are NULL or hold `nvr` and `n_values` elements (FMI
            // contract).
            if let (Some(vrs), Some(to)) = (slice(vr, nvr), slice_mut(out, n_values)) {
                if let Some(status) = read_fast(s, K::TYPE, vrs, to, K::to_c) {
                    return status;
                }
            }
            read(s, f, vr, nvr, null, n_values, K::TYPE, |i, value| {
                if let Element::Number(x) = value {
                    // SAFETY: `out` holds `n_values` elements (FMI contract) and `i < n_values`
                    // (checked by `check_references`).
                    *out.add(i) = K::to_c(x)
                }
            })
        })
    }
}

/// Checks a set call's references, then hands the `(scalar index, value)` pairs they name
/// (arrays row-major; the `k`-th value is `value_at(k)`) to the instance. No buffer.
fn write_values<M: FmuModel, T>(
    slot: &mut Slot<M, Fmi3>,
    f: &Function,
    vrs: &[u32],
    expected: VariableType,
    n_values: usize,
    value_at: impl Fn(usize) -> T + Clone,
    store: impl Store<T>,
) -> Status {
    if let Err(message) = check_references(slot, vrs, expected, n_values) {
        return slot.instance.reject(f, &message);
    }
    if vrs.contains(&TIME) {
        return slot.instance.reject(
            f,
            "variable `time` (value reference 0) is the independent variable: the master sets it through fmi3EnterInitializationMode and fmi3DoStep",
        );
    }
    let interface = Arc::clone(slot.instance.interface());
    let targets = interface
        .layout
        .indices_of(vrs)
        .enumerate()
        .map(|(k, index)| (index as u32, value_at(k)));
    store.store(&mut slot.instance, f, targets)
}

/// How the values of a set call reach the instance: numbers of one type, or values.
trait Store<T> {
    fn store<M: FmuModel, I>(self, instance: &mut Instance<M>, f: &Function, targets: I) -> Status
    where
        I: Iterator<Item = (u32, T)> + Clone;
}

/// Numbers of one type ([`Instance::set_numbers`]).
struct AsNumbers(VariableType);
impl Store<f64> for AsNumbers {
    fn store<M: FmuModel, I>(self, instance: &mut Instance<M>, f: &Function, targets: I) -> Status
    where
        I: Iterator<Item = (u32, f64)> + Clone,
    {
        instance.set_numbers(f, self.0, targets)
    }
}

/// Values ([`Instance::set_values`]).
struct AsValues;
impl Store<Value> for AsValues {
    fn store<M: FmuModel, I>(self, instance: &mut Instance<M>, f: &Function, targets: I) -> Status
    where
        I: Iterator<Item = (u32, Value)> + Clone,
    {
        instance.set_values(f, targets)
    }
}

/// `fmi3SetFloat64`, `fmi3SetInt32`, `fmi3SetBoolean`: the values (arrays row-major) from a
/// C array of `n_values` elements.
///
/// # Safety
/// FMI pointer contract.
pub unsafe fn set<M: FmuModel, K: Kind<Fmi3>>(
    c: fmi3Instance,
    vr: *const fmi3ValueReference,
    nvr: usize,
    values: *const K::C,
    n_values: usize,
) -> fmi3Status {
    let f = K::SET;
    unsafe {
        with_slot::<M, Fmi3>(c, f, |s| {
            let (Some(vrs), Some(raw)) = (slice(vr, nvr), slice(values, n_values)) else {
                return s.instance.reject(f, "valueReferences or values is NULL");
            };
            if let Some(status) = s.instance.set_spans(f, K::TYPE, vrs, raw, K::to_number) {
                return status;
            }
            let number = |k: usize| K::to_number(raw[k]);
            write_values(s, f, vrs, K::TYPE, n_values, number, AsNumbers(K::TYPE))
        })
    }
}

/// `fmi3GetString`.
///
/// # Safety
/// FMI pointer contract.
pub unsafe fn get_string<M: FmuModel>(
    c: fmi3Instance,
    vr: *const fmi3ValueReference,
    nvr: usize,
    out: *mut fmi3String,
    n_values: usize,
) -> fmi3Status {
    let (f, null) = (&functions::GET_STRING, out.is_null());
    unsafe {
        with_slot::<M, Fmi3>(c, f, |s| {
            let mut values = Vec::with_capacity(n_values);
            let status = read(
                s,
                f,
                vr,
                nvr,
                null,
                n_values,
                VariableType::String,
                |_, value| {
                    if let Element::Text(text) = value {
                        values.push(text.to_string())
                    }
                },
            );
            if status <= Status::Warning {
                // SAFETY: `out` holds `n_values` slots, the number of `values`.
                s.return_strings(&values, out);
            }
            status
        })
    }
}

/// `fmi3SetString`.
///
/// # Safety
/// FMI pointer contract.
pub unsafe fn set_string<M: FmuModel>(
    c: fmi3Instance,
    vr: *const fmi3ValueReference,
    nvr: usize,
    values: *const fmi3String,
    n_values: usize,
) -> fmi3Status {
    let f = &functions::SET_STRING;
    let null = "valueReferences or values is NULL";
    unsafe {
        with_slot::<M, Fmi3>(c, f, |s| {
            match string_values(s, f, (vr, nvr), (values, n_values), null) {
                Ok((vrs, texts)) => {
                    let text = |k: usize| texts[k].clone();
                    write_values(s, f, vrs, VariableType::String, n_values, text, AsValues)
                }
                Err(status) => status,
            }
        })
    }
}

/// Emits, inside [`export_fmu!`](crate::export_fmu), the `fmi3Get*`/`fmi3Set*` symbols of the
/// types the FMUs declare, each pair with its C value type and the two functions of this
/// module it calls (`nValues` after the values).
#[doc(hidden)]
#[macro_export]
macro_rules! fmi3_value_entries {
    () => {
        use $crate::fmi3::values as v;
        $crate::get_set_entries!(fmi3Instance, fmi3ValueReference, fmi3Status, (n_values);
            fmi3GetFloat64, fmi3SetFloat64, fmi3Float64 => v::get::<M, v::Float64>, v::set::<M, v::Float64>;
            fmi3GetInt32, fmi3SetInt32, fmi3Int32 => v::get::<M, v::Int32>, v::set::<M, v::Int32>;
            fmi3GetBoolean, fmi3SetBoolean, fmi3Boolean => v::get::<M, v::Boolean>, v::set::<M, v::Boolean>;
            fmi3GetString, fmi3SetString, fmi3String => v::get_string::<M>, v::set_string::<M>;
        );
    };
}
