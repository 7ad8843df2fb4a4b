//! The instance handle both fronts hand out (`fmi2Component`, `fmi3Instance`: a boxed
//! [`Slot`]) and the guarded call every entry point makes on it: the NULL check, the panic
//! guard ([`crate::guard`]; a panic makes the instance `Fatal`) and the allowed-state mask.
//!
//! Both versions' status codes are the same integers (`fmi2OK` = `fmi3OK` = 0 … `Fatal` =
//! 4: [`Status::code`]), and their instance and FMU-state handles are both `void*`, so one
//! path serves them.

use super::pointers::{slice, string_arg};
use crate::guard::{guarded, guarded_call, install_panic_hook, panic_text, CallMarker, Payload};
use crate::instance::{Core, Function, Instance};
use crate::model::FmuModel;
use crate::types::Status;
use crate::variables::Value;
use std::ffi::CString;
use std::os::raw::{c_char, c_void};
use std::sync::Arc;

/// What an instance handle (`fmi2Component`, `fmi3Instance`) points to: the instance, the
/// front's own data `X` (the FMI 3.0 array layout), the FMU states it created and the
/// strings it last returned.
pub struct Slot<M: FmuModel, X = ()> {
    pub(crate) instance: Instance<M>,
    pub(crate) extra: X,
    /// FMU states created by this instance and not freed yet.
    pub(crate) states: Vec<*mut Core<M>>,
    /// Keeps the strings returned by `fmi*GetString` alive until the next call.
    strings: Vec<CString>,
    /// Which thread runs a call on the slot, for the panic hook ([`crate::guard`]).
    marker: Arc<CallMarker>,
}

impl<M: FmuModel, X> Slot<M, X> {
    /// A slot for `instance` with the front's data.
    pub fn new(instance: Instance<M>, extra: X) -> Self {
        Self {
            instance,
            extra,
            states: Vec::new(),
            strings: Vec::new(),
            marker: CallMarker::registered(),
        }
    }

    /// The front's own data.
    pub fn extra(&self) -> &X {
        &self.extra
    }

    /// The instance.
    pub fn instance(&self) -> &Instance<M> {
        &self.instance
    }

    /// Boxes the slot as an instance handle (and installs the panic hook the calls on it
    /// rely on: [`crate::guard`]).
    pub fn into_handle(self) -> *mut c_void {
        install_panic_hook();
        Box::into_raw(Box::new(self)) as *mut c_void
    }

    /// Keeps `texts` as C strings until the next call and writes pointers to them into
    /// `out`.
    ///
    /// # Safety
    /// `out` points to at least `texts.len()` writable slots.
    pub(crate) unsafe fn return_strings(&mut self, texts: &[String], out: *mut *const c_char) {
        self.strings = texts
            .iter()
            .map(|text| CString::new(text.replace('\0', " ")).unwrap_or_default())
            .collect();
        for (i, cs) in self.strings.iter().enumerate() {
            // SAFETY: `out` holds the slots (caller); the strings live in the slot until the
            // next get-string call.
            unsafe { *out.add(i) = cs.as_ptr() };
        }
    }
}

impl<M: FmuModel, X> Drop for Slot<M, X> {
    fn drop(&mut self) {
        CallMarker::unregister(&self.marker);
        for p in self.states.drain(..) {
            // SAFETY: every pointer in `states` came from `Box::into_raw` and is removed from the
            // list when freed, so each is freed exactly once.
            drop(unsafe { Box::from_raw(p) });
        }
    }
}

/// Frees a slot boxed by [`Slot::into_handle`] (`fmi*FreeInstance`).
///
/// # Safety
/// `c` must be NULL or a handle of a `Slot<M, X>` not freed yet.
pub unsafe fn free_slot<M: FmuModel, X>(c: *mut c_void) {
    if c.is_null() {
        return;
    }
    let _ = guarded(|| {
        // SAFETY: `c` came from `Box::into_raw` in `Slot::into_handle`.
        drop(unsafe { Box::from_raw(c as *mut Slot<M, X>) });
    });
}

/// Runs `body` on the slot behind `c` after the null and state checks, catching panics (the
/// instance is then `Fatal`); the status as its C code. Inlined into every entry point: the
/// fixed cost of a call is the null check, the call marker (two stores), the state mask test.
///
/// # Safety
/// `c` must be NULL or a live handle of a `Slot<M, X>` (the master's obligation).
#[inline(always)]
pub unsafe fn with_slot<M: FmuModel, X>(
    c: *mut c_void,
    f: &Function,
    body: impl FnOnce(&mut Slot<M, X>) -> Status,
) -> std::os::raw::c_int {
    if c.is_null() {
        return Status::Error.code();
    }
    let slot = c as *mut Slot<M, X>;
    // SAFETY: `c` is non-null and a live slot (the caller's obligation); the marker lives in
    // its own allocation (the slot's `Arc`), outside the memory the call borrows mutably, as
    // long as the slot, which outlives the call.
    let marker: &CallMarker = unsafe { &*Arc::as_ptr(&(*slot).marker) };
    let result = guarded_call(marker, || {
        // SAFETY: `c` is non-null and a live slot (the caller's obligation); no other reference
        // to the slot is alive during the call.
        let slot = unsafe { &mut *slot };
        if !slot.instance.allows(f) {
            return Status::Error;
        }
        body(slot)
    });
    match result {
        Ok(status) => status.code(),
        // SAFETY: as above; the closure that panicked no longer borrows the slot.
        Err(payload) => unsafe { fatal(slot, f, payload) },
    }
}

/// After a panic in a call `f` on the slot: the instance is `Fatal`, the panic logged.
///
/// # Safety
/// `slot` is a live slot no reference points into.
#[cold]
#[inline(never)]
unsafe fn fatal<M: FmuModel, X>(
    slot: *mut Slot<M, X>,
    f: &Function,
    payload: Payload,
) -> std::os::raw::c_int {
    let message = panic_text(payload.as_ref());
    let _ = guarded(|| {
        // SAFETY: the caller's obligation.
        unsafe { &mut *slot }.instance.set_fatal(f, &message)
    });
    Status::Fatal.code()
}

/// The value references and the values of a set-string call (`nvr` references behind `vr`,
/// `n_values` C strings behind `values`); `Err` with the rejection's status when a pointer
/// is NULL (`null` names the arguments) or one of the strings is.
///
/// # Safety
/// FMI pointer contract: each pointer is NULL or holds its count of elements, every string
/// NULL or NUL-terminated.
pub(crate) unsafe fn string_values<'a, M: FmuModel, X>(
    slot: &Slot<M, X>,
    f: &Function,
    (vr, nvr): (*const u32, usize),
    (values, n_values): (*const *const c_char, usize),
    null: &str,
) -> Result<(&'a [u32], Vec<Value>), Status> {
    // SAFETY: the caller's obligation.
    let (Some(vrs), Some(raw)) = (unsafe { slice(vr, nvr) }, unsafe {
        slice(values, n_values)
    }) else {
        return Err(slot.instance.reject(f, null));
    };
    let values = raw
        .iter()
        // SAFETY: the caller's obligation.
        .map(|p| match unsafe { string_arg(*p) } {
            Some(t) => Ok(Value::String(t)),
            None => Err(slot.instance.reject(f, "a string value is NULL")),
        })
        .collect::<Result<_, _>>()?;
    Ok((vrs, values))
}

/// `fmi*SetDebugLogging` (`f`): debug logging on or off for the `n` categories behind
/// `categories` (all when none).
///
/// # Safety
/// `c` as for [`with_slot`]; `categories` is NULL or holds `n` strings, each NULL or
/// NUL-terminated.
pub unsafe fn set_debug_logging<M: FmuModel, X>(
    c: *mut c_void,
    f: &Function,
    logging_on: bool,
    (categories, n): (*const *const c_char, usize),
) -> std::os::raw::c_int {
    unsafe {
        with_slot::<M, X>(c, f, |s| {
            let Some(raw) = slice(categories, n) else {
                return s.instance.reject(f, "categories is NULL");
            };
            let names: Vec<String> = raw
                .iter()
                .map(|p| string_arg(*p).unwrap_or_default())
                .collect();
            s.instance.set_debug_logging_as(f, logging_on, &names)
        })
    }
}

/// Writes what `answer` says of the instance behind `c` into the one value behind `out`
/// (rejected when NULL, naming the argument `what`): the size and status queries.
///
/// # Safety
/// `c` as for [`with_slot`]; `out` is NULL or points to one writable `T`.
pub unsafe fn write_out<M: FmuModel, X, T>(
    c: *mut c_void,
    f: &Function,
    (out, what): (*mut T, &str),
    answer: impl FnOnce(&Slot<M, X>) -> T,
) -> std::os::raw::c_int {
    unsafe {
        with_slot::<M, X>(c, f, |s| {
            if out.is_null() {
                return s.instance.reject(f, &format!("{what} is NULL"));
            }
            // SAFETY: checked non-NULL; the caller's obligation otherwise.
            *out = answer(s);
            Status::Ok
        })
    }
}

/// Emits, inside a front's export macro, the entry points that take only the instance: each
/// name with the function of the `ffi` module in scope that it calls.
#[doc(hidden)]
#[macro_export]
macro_rules! instance_entries {
    ($handle:ty; $($name:ident = $function:ident),+ $(,)?) => {
        $(
            #[no_mangle]
            pub unsafe extern "C" fn $name(c: $handle) -> ::std::os::raw::c_int {
                unsafe { ffi::$function::<M>(c) }
            }
        )+
    };
}
