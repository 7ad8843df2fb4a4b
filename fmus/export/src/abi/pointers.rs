//! The pointer arguments of the C entry points as Rust values: arrays as slices (NULL with a
//! count of 0 is the empty array), C strings as owned text.

use std::ffi::CStr;
use std::os::raw::c_char;

/// Reads `n` elements behind `p` as a slice; `None` if `p` is NULL while `n > 0`.
pub(crate) unsafe fn slice<'a, T>(p: *const T, n: usize) -> Option<&'a [T]> {
    if n == 0 {
        Some(&[])
    } else if p.is_null() {
        None
    } else {
        // SAFETY: the caller guarantees `p` points to `n` valid elements (FMI contract).
        Some(unsafe { std::slice::from_raw_parts(p, n) })
    }
}

/// The `n` writable elements behind `p` (empty when `n` is 0); `None` for NULL with `n > 0`.
///
/// # Safety
/// `p` is NULL or points to `n` writable elements (FMI contract).
pub(crate) unsafe fn slice_mut<'a, T>(p: *mut T, n: usize) -> Option<&'a mut [T]> {
    if n == 0 {
        Some(&mut [])
    } else if p.is_null() {
        None
    } else {
        // SAFETY: the caller's obligation.
        Some(unsafe { std::slice::from_raw_parts_mut(p, n) })
    }
}

/// The text of the C string `s`; `None` for NULL.
///
/// # Safety
/// `s` is NULL or a NUL-terminated string.
pub(crate) unsafe fn string_arg(s: *const c_char) -> Option<String> {
    if s.is_null() {
        None
    } else {
        // SAFETY: FMI strings are NUL-terminated.
        Some(unsafe { CStr::from_ptr(s) }.to_string_lossy().into_owned())
    }
}
