//! The step-size loop shared by the embedded integrators ([`super::rosenbrock`],
//! [`super::dop853`]): a method proposes a candidate step and its weighted error norm; the
//! loop accepts it when the norm is at most 1, sizes the next step from the norm (no growth
//! right after a rejection; a step shortened to end on the interval does not shrink the next
//! proposal), shrinks hard after an overflow, and bounds the work ([`MAX_ATTEMPTS`] attempts,
//! no step shorter than [`MIN_STEP_FRACTION`] of the interval).

use nalgebra::SVector;
use std::fmt;

/// The most step attempts (accepted or rejected) one call may take.
pub const MAX_ATTEMPTS: usize = 100_000;

/// The shortest step, as a fraction of the interval, before the integrator gives up.
pub const MIN_STEP_FRACTION: f64 = 1e-12;

/// Why an interval could not be integrated.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum StepError {
    /// `I/(γh) − J` was singular at time `at` (from the interval's start).
    Singular { at: f64 },
    /// The step fell below [`MIN_STEP_FRACTION`] of the interval (at `at`, step `step`).
    StepTooSmall { at: f64, step: f64 },
    /// More than [`MAX_ATTEMPTS`] attempts (stopped at `at`).
    TooManySteps { at: f64 },
    /// The state or the error estimate became non-finite at `at`.
    NonFinite { at: f64 },
}

impl fmt::Display for StepError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Singular { at } => write!(
                f,
                "the Rosenbrock iteration matrix is singular {at} s into the step"
            ),
            Self::StepTooSmall { at, step } => write!(
                f,
                "the error control asked for a step of {step} s ({at} s into the step), too small to go on"
            ),
            Self::TooManySteps { at } => write!(
                f,
                "more than {MAX_ATTEMPTS} Rosenbrock steps were needed (stopped {at} s into the step)"
            ),
            Self::NonFinite { at } => {
                write!(f, "the state became non-finite {at} s into the step")
            }
        }
    }
}

impl std::error::Error for StepError {}

/// What one call did (for benchmarks and tests).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Statistics {
    /// Accepted steps.
    pub accepted: usize,
    /// Rejected steps.
    pub rejected: usize,
}

/// A candidate step and its weighted error norm, or a failure.
pub(crate) type Attempt<const N: usize> = Result<(SVector<f64, N>, f64), StepError>;

/// One embedded method with its right-hand side, as the loop drives it.
pub(crate) trait Embedded<const N: usize> {
    /// A step of `h` from `state`, `done` into the interval (`h_done`): the candidate and its
    /// weighted error norm (non-finite when a stage overflowed), or a failure that ends the
    /// integration.
    fn attempt(&mut self, state: &SVector<f64, N>, h_done: (f64, f64)) -> Attempt<N>;

    /// Accepts the candidate `next`, reached at `at` into the interval: the state to go on
    /// from (a discrete change applied), or a failure.
    fn accept(&mut self, next: SVector<f64, N>, at: f64) -> Result<SVector<f64, N>, StepError>;

    /// The factor on the step for a finite error norm `error`.
    fn factor(&self, error: f64) -> f64;
}

/// Integrates over an interval of `length` from `x` with `method`; `step` is the step to try
/// first and, on return, the one proposed next.
pub(crate) fn drive<const N: usize>(
    method: &mut impl Embedded<N>,
    x: &SVector<f64, N>,
    length: f64,
    step: &mut f64,
    statistics: &mut Statistics,
) -> Result<SVector<f64, N>, StepError> {
    let mut state = *x;
    let mut done = 0.0;
    let mut h = if step.is_finite() && *step > 0.0 {
        *step
    } else {
        length
    };
    let mut just_rejected = false;
    for _ in 0..MAX_ATTEMPTS {
        let left = length - done;
        if left <= 1e-14 * length {
            *step = h;
            return Ok(state);
        }
        let last = h >= left;
        let h_try = if last { left } else { h };
        if h_try < MIN_STEP_FRACTION * length {
            return Err(StepError::StepTooSmall {
                at: done,
                step: h_try,
            });
        }
        let (next, error) = method.attempt(&state, (h_try, done))?;
        if !error.is_finite() || next.iter().any(|v| !v.is_finite()) {
            // A step so long that the stages overflowed: shrink hard and retry.
            if h_try < MIN_STEP_FRACTION * length * 10.0 {
                return Err(StepError::NonFinite { at: done });
            }
            h = 0.1 * h_try;
            just_rejected = true;
            statistics.rejected += 1;
            continue;
        }
        let factor = method.factor(error);
        if error <= 1.0 {
            let at = if last { length } else { done + h_try };
            state = method.accept(next, at)?;
            done = at;
            statistics.accepted += 1;
            let proposal = h_try
                * if just_rejected {
                    factor.min(1.0)
                } else {
                    factor
                };
            // The proposal from a full step; a shortened last step keeps the previous one.
            if !last || h_try >= h {
                h = proposal;
            }
            just_rejected = false;
        } else {
            h = h_try * factor.min(1.0);
            just_rejected = true;
            statistics.rejected += 1;
        }
    }
    Err(StepError::TooManySteps { at: done })
}
