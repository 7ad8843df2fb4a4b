//! The C types of the FMI 2.0 API (`fmi2TypesPlatform.h`, `fmi2FunctionTypes.h`).
//!
//! Enumerations that cross the ABI are plain integers here, so that a value outside the
//! enumeration coming from a master is an error we report, not undefined behaviour.
#![allow(non_camel_case_types, non_upper_case_globals, non_snake_case)]

use std::os::raw::{c_char, c_int, c_uint, c_void};

pub type fmi2Component = *mut c_void;
pub type fmi2ComponentEnvironment = *mut c_void;
pub type fmi2FMUstate = *mut c_void;
pub type fmi2ValueReference = c_uint;
pub type fmi2Real = f64;
pub type fmi2Integer = c_int;
pub type fmi2Boolean = c_int;
pub type fmi2Char = c_char;
pub type fmi2String = *const fmi2Char;
pub type fmi2Byte = c_char;

pub const fmi2True: fmi2Boolean = 1;
pub const fmi2False: fmi2Boolean = 0;

/// `fmi2Status`.
pub type fmi2Status = c_int;
pub const fmi2OK: fmi2Status = 0;
pub const fmi2Warning: fmi2Status = 1;
pub const fmi2Discard: fmi2Status = 2;
pub const fmi2Error: fmi2Status = 3;
pub const fmi2Fatal: fmi2Status = 4;
pub const fmi2Pending: fmi2Status = 5;

/// `fmi2Type`.
pub type fmi2Type = c_int;
pub const fmi2ModelExchange: fmi2Type = 0;
pub const fmi2CoSimulation: fmi2Type = 1;

/// `fmi2StatusKind`.
pub type fmi2StatusKind = c_int;
pub const fmi2DoStepStatus: fmi2StatusKind = 0;
pub const fmi2PendingStatus: fmi2StatusKind = 1;
pub const fmi2LastSuccessfulTime: fmi2StatusKind = 2;
pub const fmi2Terminated: fmi2StatusKind = 3;

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
