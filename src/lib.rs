//! spurio: the mathematics behind the spurio FMUs, as plain Rust.
//!
//! Nothing in this crate knows about FMI. Each FMU of the product (see `fmus/`) is a thin
//! adapter around one of the types here: the plants of the papers, the signal chain, the
//! estimators and the controllers. Every module cites the paper section it implements; the
//! equations are in `docs/README.md` §2 and in the doc comments.

#![forbid(unsafe_code)]

pub mod control;
pub mod estimation;
pub mod linalg;
pub mod ode;
pub mod plants;
pub mod signals;
pub mod state;
pub mod state_space;

use std::fmt;

/// A parameter (or a configuration value) that a model or algorithm cannot accept.
///
/// Every constructor in this crate validates its inputs and returns this error instead of
/// producing NaN later; the FMU adapters pass the message on through the FMI logger, so it
/// names the parameter and says why.
#[derive(Debug, Clone, PartialEq)]
pub struct ParameterError {
    /// The parameter's name as the user sees it (the FMU variable name where there is one).
    pub parameter: String,
    /// Why the value is not acceptable.
    pub reason: String,
}

impl ParameterError {
    /// An error for `parameter`, saying `reason`.
    pub fn new(parameter: impl Into<String>, reason: impl Into<String>) -> Self {
        Self {
            parameter: parameter.into(),
            reason: reason.into(),
        }
    }
}

impl fmt::Display for ParameterError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "parameter `{}`: {}", self.parameter, self.reason)
    }
}

impl std::error::Error for ParameterError {}

/// Checks that `value` is finite and strictly positive.
pub fn require_positive(parameter: &str, value: f64) -> Result<f64, ParameterError> {
    if value.is_finite() && value > 0.0 {
        Ok(value)
    } else {
        Err(ParameterError::new(
            parameter,
            format!("must be a finite positive number, got {value}"),
        ))
    }
}

/// Checks that `value` is finite and not negative.
pub fn require_non_negative(parameter: &str, value: f64) -> Result<f64, ParameterError> {
    if value.is_finite() && value >= 0.0 {
        Ok(value)
    } else {
        Err(ParameterError::new(
            parameter,
            format!("must be a finite number >= 0, got {value}"),
        ))
    }
}

/// Checks that the whole number `value` lies in `range` (both ends included).
pub fn require_between(
    parameter: &str,
    value: u32,
    range: std::ops::RangeInclusive<u32>,
) -> Result<u32, ParameterError> {
    if range.contains(&value) {
        Ok(value)
    } else {
        Err(ParameterError::new(
            parameter,
            format!(
                "must be between {} and {}, got {value}",
                range.start(),
                range.end()
            ),
        ))
    }
}

/// Checks that `value` is finite.
pub fn require_finite(parameter: &str, value: f64) -> Result<f64, ParameterError> {
    if value.is_finite() {
        Ok(value)
    } else {
        Err(ParameterError::new(
            parameter,
            format!("must be finite, got {value}"),
        ))
    }
}

/// What one parameter of a [`check_all`] table must be.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Requirement {
    /// Finite and strictly positive ([`require_positive`]).
    Positive,
    /// Finite and not negative ([`require_non_negative`]).
    NonNegative,
    /// Finite ([`require_finite`]).
    Finite,
}

/// Checks a table of `(name, value, requirement)` rows in order, naming the first parameter
/// that fails its requirement (the validate functions of the plants).
pub fn check_all(rows: &[(&str, f64, Requirement)]) -> Result<(), ParameterError> {
    for &(name, value, requirement) in rows {
        match requirement {
            Requirement::Positive => require_positive(name, value)?,
            Requirement::NonNegative => require_non_negative(name, value)?,
            Requirement::Finite => require_finite(name, value)?,
        };
    }
    Ok(())
}
