//! The C types of the FMI 2.0 API (`fmi2TypesPlatform.h`, `fmi2FunctionTypes.h`).
//!
//! Enumerations that cross the ABI are plain integers here, so that a value outside the
//! enumeration coming from a master is an error we report, not undefined behaviour.
#![allow(non_camel_case_types, non_upper_case_globals, non_snake_case)]

use std::os::raw::{c_char, c_int, c_uint, c_void};

/// `c_types! { name = type, … }`: the type aliases of a C header.
macro_rules! c_types {
    ($($name:ident = $t:ty),* $(,)?) => { $(pub type $name = $t;)* };
}
/// `c_enum! { name: repr { CONSTANT = value, … } }`: a C enumeration as an integer type and
/// its named values (plain integers: see the module documentation).
macro_rules! c_enum {
    ($(#[$m:meta])* $name:ident: $repr:ty { $($item:ident = $value:expr),* $(,)? }) => {
        $(#[$m])* pub type $name = $repr;
        $(pub const $item: $name = $value;)*
    };
}
pub(crate) use {c_enum, c_types};

c_types! {
    fmi2Component = *mut c_void, fmi2ComponentEnvironment = *mut c_void,
    fmi2FMUstate = *mut c_void, fmi2ValueReference = c_uint, fmi2Real = f64,
    fmi2Integer = c_int, fmi2Char = c_char, fmi2String = *const fmi2Char, fmi2Byte = c_char,
}
c_enum! { /** `fmi2Boolean`. */ fmi2Boolean: c_int { fmi2True = 1, fmi2False = 0 } }
c_enum! {
    /// `fmi2Status`.
    fmi2Status: c_int {
        fmi2OK = 0, fmi2Warning = 1, fmi2Discard = 2, fmi2Error = 3, fmi2Fatal = 4,
        fmi2Pending = 5,
    }
}
c_enum! { /** `fmi2Type`. */ fmi2Type: c_int { fmi2ModelExchange = 0, fmi2CoSimulation = 1 } }
c_enum! {
    /// `fmi2StatusKind`.
    fmi2StatusKind: c_int {
        fmi2DoStepStatus = 0, fmi2PendingStatus = 1, fmi2LastSuccessfulTime = 2,
        fmi2Terminated = 3,
    }
}

/// The logger is a C variadic function. We always call it with the format `"%s"` and the
/// message as its one argument, so a `%` in a message is printed, not interpreted.
pub type fmi2CallbackLogger = Option<
    unsafe extern "C" fn(
        fmi2ComponentEnvironment,
        fmi2String,
        fmi2Status,
        fmi2String,
        fmi2String,
        ...
    ),
>;
pub type fmi2CallbackAllocateMemory = Option<unsafe extern "C" fn(usize, usize) -> *mut c_void>;
pub type fmi2CallbackFreeMemory = Option<unsafe extern "C" fn(*mut c_void)>;
pub type fmi2StepFinished = Option<unsafe extern "C" fn(fmi2ComponentEnvironment, fmi2Status)>;

/// `fmi2CallbackFunctions`.
#[repr(C)]
pub struct fmi2CallbackFunctions {
    pub logger: fmi2CallbackLogger,
    pub allocateMemory: fmi2CallbackAllocateMemory,
    pub freeMemory: fmi2CallbackFreeMemory,
    pub stepFinished: fmi2StepFinished,
    pub componentEnvironment: fmi2ComponentEnvironment,
}

/// The status a call ends with, as a Rust enum (ordered by severity).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum Status {
    Ok,
    Warning,
    Discard,
    Error,
    Fatal,
}

impl Status {
    /// The `fmi2Status` integer.
    pub fn code(self) -> fmi2Status {
        match self {
            Status::Ok => fmi2OK,
            Status::Warning => fmi2Warning,
            Status::Discard => fmi2Discard,
            Status::Error => fmi2Error,
            Status::Fatal => fmi2Fatal,
        }
    }

    /// The log category a message of this status goes to.
    pub fn category(self) -> &'static str {
        match self {
            Status::Ok => "logEvents",
            Status::Warning => "logStatusWarning",
            Status::Discard => "logStatusDiscard",
            Status::Error => "logStatusError",
            Status::Fatal => "logStatusFatal",
        }
    }
}
