//! The C types of the FMI 3.0 API (`fmi3PlatformTypes.h`, `fmi3FunctionTypes.h`).
//!
//! `fmi3Boolean` is C99 `bool`; it crosses the ABI here as a `u8` (same size and passing
//! convention), so a byte other than 0 or 1 from a master is read as true instead of being
//! undefined behaviour. Enumerations are plain integers for the same reason.
#![allow(non_camel_case_types, non_upper_case_globals)]

use crate::types::{c_enum, c_types};
use std::os::raw::{c_char, c_int, c_void};

c_types! {
    fmi3Instance = *mut c_void, fmi3InstanceEnvironment = *mut c_void,
    fmi3FMUState = *mut c_void, fmi3ValueReference = u32,
    fmi3Float32 = f32, fmi3Float64 = f64, fmi3Int8 = i8, fmi3UInt8 = u8, fmi3Int16 = i16,
    fmi3UInt16 = u16, fmi3Int32 = i32, fmi3UInt32 = u32, fmi3Int64 = i64, fmi3UInt64 = u64,
    fmi3Char = c_char, fmi3String = *const fmi3Char, fmi3Byte = u8,
    fmi3Binary = *const fmi3Byte,
}
c_enum! { /** C99 `bool`, as a byte. */ fmi3Boolean: u8 { fmi3True = 1, fmi3False = 0 } }
c_enum! { /** C99 `bool`, as a byte. */ fmi3Clock: u8 {} }
c_enum! {
    /// `fmi3Status`.
    fmi3Status: c_int {
        fmi3OK = 0, fmi3Warning = 1, fmi3Discard = 2, fmi3Error = 3, fmi3Fatal = 4,
    }
}
c_enum! { /** `fmi3DependencyKind`. */ fmi3DependencyKind: c_int {} }
c_enum! { /** `fmi3IntervalQualifier`. */ fmi3IntervalQualifier: c_int {} }

/// `fmi3LogMessageCallback`: not variadic; the message is passed as it is.
pub type fmi3LogMessageCallback =
    Option<unsafe extern "C" fn(fmi3InstanceEnvironment, fmi3Status, fmi3String, fmi3String)>;
/// `fmi3IntermediateUpdateCallback` (never called: `providesIntermediateUpdate="false"`).
pub type fmi3IntermediateUpdateCallback = Option<
    unsafe extern "C" fn(
        fmi3InstanceEnvironment,
        fmi3Float64,
        fmi3Boolean,
        fmi3Boolean,
        fmi3Boolean,
        fmi3Boolean,
        *mut fmi3Boolean,
        *mut fmi3Float64,
    ),
>;
/// `fmi3ClockUpdateCallback` (Scheduled Execution, not supported).
pub type fmi3ClockUpdateCallback = Option<unsafe extern "C" fn(fmi3InstanceEnvironment)>;
/// `fmi3LockPreemptionCallback` / `fmi3UnlockPreemptionCallback`.
pub type fmi3PreemptionCallback = Option<unsafe extern "C" fn()>;

// The FMI 3.0 status codes are those of FMI 2.0, so one mapping ([`Status::code`]) and one
// guarded call (`crate::front::with_slot`) serve both fronts.
const _: () = assert!(
    fmi3OK == crate::types::fmi2OK
        && fmi3Warning == crate::types::fmi2Warning
        && fmi3Discard == crate::types::fmi2Discard
        && fmi3Error == crate::types::fmi2Error
        && fmi3Fatal == crate::types::fmi2Fatal
);
