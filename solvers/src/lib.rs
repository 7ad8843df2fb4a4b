//! spurio-solvers: integrators with error control for `ẋ = f(t, x)` whose dimension is chosen
//! at run time (the continuous states of a Model Exchange FMU), with dense output for event
//! location. It knows nothing of FMI: a model is an [`OdeSystem`] (a right-hand side and,
//! optionally, Jacobian–vector products).
//!
//! - [`Dopri5`]: the explicit Dormand–Prince 5(4) pair with its continuous extension of
//!   order 4 (six right-hand sides per accepted step, first same as last);
//! - [`Rosenbrock`]: linearly implicit, for stiff problems (RODAS4, L-stable, with its
//!   continuous extension of order 3, the stiff default; RODAS3 or Shampine's order-4
//!   method), with the Jacobian from the model's Jacobian–vector products when it gives them
//!   and from forward differences otherwise, one LU factorisation per attempt (never an
//!   inverse), and dense output from the stages (RODAS4) or a cubic Hermite (the others);
//! - [`Solver`]: either, chosen by [`Method`] at run time.
//!
//! **Error control.** A step from `x₀` to `x₁` with local error estimate `err` is accepted when
//!
//! ```text
//! ‖err‖ = √( (1/n) Σᵢ (errᵢ / (atol·nominalᵢ + rtol·max(|x₀ᵢ|, |x₁ᵢ|)))² ) ≤ 1
//! ```
//!
//! (the states' `nominal`s scale the absolute tolerance, as FMI asks of an importer), and the
//! next step is `h · clamp(0.9 ‖err‖^(−1/q), 0.2, 5)` (`q`: the order of the error estimate
//! plus one; no growth right after a rejection), never longer than [`Settings::max_step`].
//!
//! **Bounded work.** One [`Solver::step`] tries at most [`Settings::max_rejections`] steps
//! before it gives up with an error, refuses a step below round-off of the time, and
//! [`Solver::integrate_to`] takes at most a given number of steps: every call returns, with
//! a state or an error ([`SolverError`]) that says what and at which time.
//!
//! **No allocation per step:** every buffer is sized once, when the solver is made.

// The stages combine several vectors component by component: an index loop says so plainly.
#![allow(clippy::needless_range_loop)]

pub mod dopri5;
pub mod lu;
pub mod rosenbrock;
mod solver;
pub mod tableau;

pub use dopri5::Dopri5;
pub use rosenbrock::Rosenbrock;
pub use solver::{Method, Solver};

/// An ODE `ẋ = f(t, x)` of a dimension fixed when the solver is made.
pub trait OdeSystem {
    /// Why the model could not evaluate.
    type Error: std::error::Error + 'static;

    /// Writes `f(t, x)` into `dx`.
    fn rhs(&mut self, t: f64, x: &[f64], dx: &mut [f64]) -> Result<(), Self::Error>;

    /// Writes the Jacobian–vector product `∂f/∂x(t, x) · v` of `at` into `out` and returns
    /// `true`, or returns `false` (leaving `out` as it is) when the model gives none, in which
    /// case the solver differentiates by forward differences.
    fn jacobian_times(&mut self, at: Direction<'_>, out: &mut [f64]) -> Result<bool, Self::Error> {
        let _ = (at, out);
        Ok(false)
    }
}

/// Where and along what a Jacobian–vector product is asked: at time `t` and state `x`,
/// along `v`.
#[derive(Debug, Clone, Copy)]
pub struct Direction<'a> {
    pub t: f64,
    pub x: &'a [f64],
    pub v: &'a [f64],
}

/// Tolerances and limits of a solver.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Settings {
    /// Relative tolerance `rtol`.
    pub relative: f64,
    /// Absolute tolerance `atol`, multiplied by each state's nominal.
    pub absolute: f64,
    /// The longest step (infinite: none).
    pub max_step: f64,
    /// The first step; `None`: estimated from the derivatives (Hairer, Nørsett & Wanner,
    /// *Solving ODEs I*, §II.4).
    pub initial_step: Option<f64>,
    /// The most rejected attempts one step may take before the solver gives up.
    pub max_rejections: usize,
}

impl Settings {
    /// `rtol = tolerance`, `atol = tolerance` (times the nominals), no maximum step.
    pub fn with_tolerance(tolerance: f64) -> Self {
        Self {
            relative: tolerance,
            absolute: tolerance,
            ..Self::default()
        }
    }
}

impl Default for Settings {
    /// `rtol = atol = 1e-6`, no maximum step, an estimated first step, 100 rejections.
    fn default() -> Self {
        Self {
            relative: 1e-6,
            absolute: 1e-6,
            max_step: f64::INFINITY,
            initial_step: None,
            max_rejections: 100,
        }
    }
}

/// What a solver did since it was made.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Statistics {
    /// Evaluations of the right-hand side (including those of finite-difference Jacobians).
    pub rhs: usize,
    /// Jacobians formed.
    pub jacobians: usize,
    /// Jacobian–vector products asked of the model.
    pub jacobian_products: usize,
    /// LU factorisations.
    pub factorisations: usize,
    /// Accepted steps.
    pub accepted: usize,
    /// Rejected steps.
    pub rejected: usize,
}

/// Why a solver stopped, and the time at which it did (for [`SolverErrorKind::Model`] the
/// time the model was asked at; for [`SolverErrorKind::Dimension`] the time of the reset).
#[derive(Debug)]
pub struct SolverError<E: std::error::Error + 'static> {
    pub time: f64,
    pub kind: SolverErrorKind<E>,
}

/// What stopped a solver (the time is the [`SolverError`]'s).
#[derive(Debug)]
pub enum SolverErrorKind<E: std::error::Error + 'static> {
    /// The model could not evaluate its right-hand side (or Jacobian).
    Model(E),
    /// The model gave a derivative that is not finite at an accepted state.
    NonFiniteDerivative { index: usize, value: f64 },
    /// Every step tried had a stage that was not finite, down to the smallest step.
    NonFiniteStages { step: f64 },
    /// The error control shrank the step below the round-off of the time.
    StepTooSmall { step: f64 },
    /// More rejected steps in a row than [`Settings::max_rejections`].
    TooManyRejections { rejections: usize, step: f64 },
    /// More accepted steps than allowed to reach `target`.
    TooManySteps { target: f64, max_steps: usize },
    /// A target time that is not after the solver's time.
    BadTarget { target: f64 },
    /// A state or nominal vector of the wrong length.
    Dimension { expected: usize, given: usize },
}

impl<E: std::error::Error + 'static> SolverError<E> {
    /// The error `kind` at `time`.
    pub fn at(time: f64, kind: SolverErrorKind<E>) -> Self {
        Self { time, kind }
    }
}

impl<E: std::error::Error + 'static> std::fmt::Display for SolverError<E> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let time = self.time;
        match &self.kind {
            SolverErrorKind::Model(source) => {
                write!(f, "the model could not evaluate at t = {time}: {source}")
            }
            SolverErrorKind::NonFiniteDerivative { index, value } => {
                write!(f, "the derivative of state {index} is {value} at t = {time}")
            }
            SolverErrorKind::NonFiniteStages { step } => write!(
                f,
                "the derivatives were not finite in every step tried from t = {time}, down to a step of {step:e} s"
            ),
            SolverErrorKind::StepTooSmall { step } => write!(
                f,
                "the error control asked for a step of {step:e} s at t = {time}, below the round-off of the time"
            ),
            SolverErrorKind::TooManyRejections { rejections, step } => write!(
                f,
                "{rejections} rejected steps in a row at t = {time} (last step {step:e} s): the solution is not smooth there, or the tolerance is too tight"
            ),
            SolverErrorKind::TooManySteps { target, max_steps } => write!(
                f,
                "more than {max_steps} steps to reach t = {target} (stopped at t = {time})"
            ),
            SolverErrorKind::BadTarget { target } => write!(
                f,
                "the solver was asked to step to t = {target}, not after its time t = {time}"
            ),
            SolverErrorKind::Dimension { expected, given } => write!(
                f,
                "the dimension {given} given does not match the solver's {expected}"
            ),
        }
    }
}

impl<E: std::error::Error + 'static> std::error::Error for SolverError<E> {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match &self.kind {
            SolverErrorKind::Model(source) => Some(source),
            _ => None,
        }
    }
}

/// The weighted RMS norm of the module docs: `√((1/n) Σ (eᵢ/(atolᵢ + rtol·max(|aᵢ|, |bᵢ|)))²)`
/// (NaN when an entry is not finite). Zero states: zero.
pub(crate) fn error_norm(error: &[f64], a: &[f64], b: &[f64], atol: &[f64], rtol: f64) -> f64 {
    let n = error.len();
    if n == 0 {
        return 0.0;
    }
    let mut sum = 0.0;
    for i in 0..n {
        let scale = atol[i] + rtol * a[i].abs().max(b[i].abs());
        let q = error[i] / scale;
        sum += q * q;
    }
    (sum / n as f64).sqrt()
}

/// The factor on the step for an error norm `error` from an estimate of order `q − 1`:
/// `clamp(0.9 error^(−1/q), 0.2, 5)` (5 for a zero error).
pub(crate) fn step_factor(error: f64, q: f64) -> f64 {
    if error == 0.0 {
        5.0
    } else {
        (0.9 * error.powf(-1.0 / q)).clamp(0.2, 5.0)
    }
}

/// The shortest step at time `t`: below it `t + h` rounds to `t` or nearly.
pub(crate) fn min_step(t: f64) -> f64 {
    16.0 * f64::EPSILON * t.abs().max(1e-300)
}

/// The first index at which `values` is not finite, with the value.
pub(crate) fn first_non_finite(values: &[f64]) -> Option<(usize, f64)> {
    values
        .iter()
        .enumerate()
        .find(|(_, v)| !v.is_finite())
        .map(|(i, v)| (i, *v))
}
