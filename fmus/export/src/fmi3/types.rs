//! The C types of the FMI 3.0 API (`fmi3PlatformTypes.h`, `fmi3FunctionTypes.h`).
//!
//! `fmi3Boolean` is C99 `bool`; it crosses the ABI here as a `u8` (same size and passing
//! convention), so a byte other than 0 or 1 from a master is read as true instead of being
//! undefined behaviour. Enumerations are plain integers for the same reason.
#![allow(non_camel_case_types, non_upper_case_globals)]

use std::os::raw::{c_char, c_int, c_void};

pub type fmi3Instance = *mut c_void;
pub type fmi3InstanceEnvironment = *mut c_void;
pub type fmi3FMUState = *mut c_void;
pub type fmi3ValueReference = u32;
pub type fmi3Float32 = f32;
pub type fmi3Float64 = f64;
pub type fmi3Int8 = i8;
pub type fmi3UInt8 = u8;
pub type fmi3Int16 = i16;
pub type fmi3UInt16 = u16;
pub type fmi3Int32 = i32;
pub type fmi3UInt32 = u32;
pub type fmi3Int64 = i64;
pub type fmi3UInt64 = u64;
/// C99 `bool`, as a byte.
pub type fmi3Boolean = u8;
pub type fmi3Char = c_char;
pub type fmi3String = *const fmi3Char;
pub type fmi3Byte = u8;
pub type fmi3Binary = *const fmi3Byte;
/// C99 `bool`, as a byte.
pub type fmi3Clock = u8;

pub const fmi3True: fmi3Boolean = 1;
pub const fmi3False: fmi3Boolean = 0;

/// `fmi3Status`.
pub type fmi3Status = c_int;
pub const fmi3OK: fmi3Status = 0;
pub const fmi3Warning: fmi3Status = 1;
pub const fmi3Discard: fmi3Status = 2;
pub const fmi3Error: fmi3Status = 3;
pub const fmi3Fatal: fmi3Status = 4;

/// `fmi3DependencyKind`.
pub type fmi3DependencyKind = c_int;
/// `fmi3IntervalQualifier`.
pub type fmi3IntervalQualifier = c_int;

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
