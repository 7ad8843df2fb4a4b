//! The step-size loop shared by the methods, and [`Solver`], the method chosen at run time.

use crate::{
    error_norm, first_non_finite, min_step, step_factor, Dopri5, OdeSystem, Rosenbrock, Settings,
    SolverError, SolverErrorKind, Statistics,
};

/// A point of the solution: a time, the state there and the derivative `f(t, x)`.
#[derive(Debug, Clone)]
pub(crate) struct Point {
    pub t: f64,
    pub x: Vec<f64>,
    pub dx: Vec<f64>,
}

impl Point {
    /// `t = 0`, `x = 0`, `dx = 0` for `n` states.
    fn new(n: usize) -> Self {
        Self {
            t: 0.0,
            x: vec![0.0; n],
            dx: vec![0.0; n],
        }
    }
}

/// The states' nominals and absolute tolerances `atolᵢ = atol · nominalᵢ`.
#[derive(Debug, Clone)]
pub(crate) struct Tolerance {
    pub nominal: Vec<f64>,
    pub atol: Vec<f64>,
}

impl Tolerance {
    /// Takes `|nominalᵢ|` as the nominals (one that is zero or not finite counts as 1) and
    /// `absolute · nominalᵢ` as the absolute tolerances.
    fn set(&mut self, absolute: f64, nominal: &[f64]) {
        for (i, &given) in nominal.iter().enumerate() {
            let given = given.abs();
            self.nominal[i] = if given > 0.0 && given.is_finite() {
                given
            } else {
                1.0
            };
            self.atol[i] = absolute * self.nominal[i];
        }
    }
}

/// Where a solver is: the last accepted step's end point and its start point (for the dense
/// output), the step to try next, the absolute tolerances.
#[derive(Debug, Clone)]
pub(crate) struct Trajectory {
    /// The number of states.
    pub n: usize,
    /// The last accepted step's end: its derivative is `f(t, x)` when `dx_valid`.
    pub current: Point,
    pub dx_valid: bool,
    /// The last accepted step's start (for the dense output).
    pub previous: Point,
    /// The step to try next (≤ 0: to be estimated).
    pub h: f64,
    /// The error norm of the last accepted step (at least 10⁻⁴), for the PI step control.
    pub error_old: f64,
    pub tolerance: Tolerance,
    pub settings: Settings,
    pub statistics: Statistics,
    /// Scratch of the first-step estimate.
    scratch: (Vec<f64>, Vec<f64>),
}

impl Trajectory {
    pub fn new(n: usize, settings: Settings) -> Self {
        Self {
            n,
            current: Point::new(n),
            dx_valid: false,
            previous: Point::new(n),
            h: settings.initial_step.unwrap_or(0.0),
            error_old: 1e-4,
            tolerance: Tolerance {
                nominal: vec![1.0; n],
                atol: vec![settings.absolute; n],
            },
            settings,
            statistics: Statistics::default(),
            scratch: (vec![0.0; n], vec![0.0; n]),
        }
    }

    /// Evaluates `f` at `(t, x)` into `out`, counted, failing on a model error or a value
    /// that is not finite.
    pub fn evaluate<S: OdeSystem>(
        statistics: &mut Statistics,
        system: &mut S,
        t: f64,
        x: &[f64],
        out: &mut [f64],
    ) -> Result<(), SolverError<S::Error>> {
        statistics.rhs += 1;
        system
            .rhs(t, x, out)
            .map_err(|source| SolverError::at(t, SolverErrorKind::Model(source)))
    }

    /// Takes `x_new` at `t_new` as the current point, the current one becoming the previous
    /// (for the dense output; the two are swapped, nothing allocated); the caller sets `dx`.
    pub fn advance(&mut self, x_new: &[f64], t_new: f64) {
        std::mem::swap(&mut self.previous, &mut self.current);
        self.current.x.copy_from_slice(x_new);
        self.current.t = t_new;
    }

    /// The last step's length `h` and the fraction `θ = (t − t₀)/h` of it at `t`; `None` (the
    /// state copied into `out`) when no step was taken since the last reset.
    pub fn fraction(&self, t: f64, out: &mut [f64]) -> Option<(f64, f64)> {
        let h = self.current.t - self.previous.t;
        if h == 0.0 {
            out.copy_from_slice(&self.current.x);
            return None;
        }
        Some((h, (t - self.previous.t) / h))
    }

    /// The error norm of a step from the state to `next` with local error estimate `error`.
    pub fn norm(&self, error: &[f64], next: &[f64]) -> f64 {
        error_norm(
            error,
            &self.current.x,
            next,
            &self.tolerance.atol,
            self.settings.relative,
        )
    }

    /// Makes sure `dx = f(t, x)`; a derivative that is not finite at an accepted state is
    /// the model's fault: an error naming the state.
    pub fn ensure_derivative<S: OdeSystem>(
        &mut self,
        system: &mut S,
    ) -> Result<(), SolverError<S::Error>> {
        let current = &mut self.current;
        if !self.dx_valid {
            Self::evaluate(
                &mut self.statistics,
                system,
                current.t,
                &current.x,
                &mut current.dx,
            )?;
            self.dx_valid = true;
        }
        if let Some((index, value)) = first_non_finite(&current.dx) {
            self.dx_valid = false;
            return Err(SolverError::at(
                current.t,
                SolverErrorKind::NonFiniteDerivative { index, value },
            ));
        }
        Ok(())
    }

    /// The first step for a method of order `order` towards `t_limit` (Hairer, Nørsett &
    /// Wanner, *Solving ODEs I*, §II.4): `h₀ = 0.01 ‖x‖/‖f‖`, then from the change of `f` over
    /// an Euler step of `h₀`, `h₁ = (0.01 / max(‖f‖, ‖Δf‖/h₀))^(1/(order+1))`; the smaller of
    /// `100 h₀` and `h₁`. One evaluation of `f`.
    fn initial_step<S: OdeSystem>(
        &mut self,
        system: &mut S,
        order: f64,
        t_limit: f64,
    ) -> Result<f64, SolverError<S::Error>> {
        let Point { t, x, dx } = &self.current;
        let span = (t_limit - t).min(self.settings.max_step);
        let rtol = self.settings.relative;
        let zeros = &self.scratch.1;
        let d0 = error_norm(x, x, zeros, &self.tolerance.atol, rtol);
        let d1 = error_norm(dx, x, zeros, &self.tolerance.atol, rtol);
        let mut h0 = if d0 < 1e-5 || d1 < 1e-5 {
            1e-6
        } else {
            0.01 * d0 / d1
        };
        h0 = h0.min(span);
        let (y, f) = &mut self.scratch;
        for i in 0..self.n {
            y[i] = x[i] + h0 * dx[i];
        }
        Self::evaluate(&mut self.statistics, system, t + h0, y, f)?;
        for i in 0..self.n {
            f[i] -= dx[i];
        }
        let d2 = error_norm(f, x, x, &self.tolerance.atol, rtol) / h0;
        f.fill(0.0);
        let d = d1.max(d2);
        let h1 = if d <= 1e-15 || !d.is_finite() {
            (h0 * 1e-3).max(1e-6)
        } else {
            (0.01 / d).powf(1.0 / (order + 1.0))
        };
        Ok((100.0 * h0).min(h1).min(span))
    }
}

/// What a step of a method on the system `S` gives: `T`, or why it failed.
pub(crate) type Outcome<S, T = ()> = Result<T, SolverError<<S as OdeSystem>::Error>>;

/// An attempted step's weighted error norm, or why it failed.
pub(crate) type Norm<S> = Outcome<S, f64>;

/// One method as the step-size loop drives it.
pub(crate) trait Stepper {
    /// The order of the error estimate plus one (the step control's exponent is −1/this).
    fn error_order(&self) -> f64;

    /// The exponent `β` of the last error in the PI step control (Hairer, Nørsett & Wanner,
    /// *Solving ODEs I*, §IV.2; 0: the plain controller).
    fn pi_beta(&self) -> f64 {
        0.0
    }

    /// A step of `h` from the trajectory's state: the candidate into the method's buffer and
    /// its error norm (NaN when a stage was not finite).
    fn attempt<S: OdeSystem>(&mut self, tr: &mut Trajectory, sys: &mut S, h: f64) -> Norm<S>;

    /// Takes the candidate as the new state at `t_new` (shifting the old one back) with
    /// `f(t_new, x_new)` in `trajectory.current.dx`.
    fn accept<S: OdeSystem>(&mut self, tr: &mut Trajectory, sys: &mut S, t_new: f64) -> Outcome<S>;

    /// The dense output at `t` within the last accepted step, into `out`.
    fn interpolate(&self, trajectory: &Trajectory, t: f64, out: &mut [f64]);

    /// Forgets what depends on the state (after a reset).
    fn forget(&mut self);
}

/// One accepted step of `method` not beyond `t_limit` (see [`Solver::step`]).
pub(crate) fn step<M: Stepper, S: OdeSystem>(
    method: &mut M,
    trajectory: &mut Trajectory,
    system: &mut S,
    t_limit: f64,
) -> Result<f64, SolverError<S::Error>> {
    let t = trajectory.current.t;
    if t_limit.is_nan() || t_limit <= t {
        return Err(SolverError::at(
            t,
            SolverErrorKind::BadTarget { target: t_limit },
        ));
    }
    trajectory.ensure_derivative(system)?;
    if !(trajectory.h > 0.0 && trajectory.h.is_finite()) {
        trajectory.h = trajectory.initial_step(system, method.error_order() - 1.0, t_limit)?;
    }
    let mut just_rejected = false;
    let mut rejections = 0;
    let mut non_finite = false;
    loop {
        let proposal = trajectory.h.min(trajectory.settings.max_step);
        let remaining = t_limit - t;
        // A step that would end within round-off of the limit ends on it.
        let last = proposal >= remaining || remaining - proposal < min_step(t_limit);
        let h = if last { remaining } else { proposal };
        if h < min_step(t) || h.is_nan() {
            if non_finite {
                return Err(SolverError::at(
                    t,
                    SolverErrorKind::NonFiniteStages { step: h },
                ));
            }
            return Err(SolverError::at(
                t,
                SolverErrorKind::StepTooSmall { step: h },
            ));
        }
        let error = method.attempt(trajectory, system, h)?;
        if error.is_finite() && error <= 1.0 {
            let t_new = if last { t_limit } else { t + h };
            method.accept(trajectory, system, t_new)?;
            trajectory.statistics.accepted += 1;
            // PI control: 0.9 err^(−1/q + 0.75β) err_old^β, within [0.2, 5].
            let beta = method.pi_beta();
            let factor = if error == 0.0 {
                5.0
            } else {
                (0.9 * error.powf(-1.0 / method.error_order() + 0.75 * beta)
                    * trajectory.error_old.powf(beta))
                .clamp(0.2, 5.0)
            };
            trajectory.error_old = error.max(1e-4);
            let next = h * if just_rejected {
                factor.min(1.0)
            } else {
                factor
            };
            // A step cut to end on the limit does not shrink the next proposal.
            if !last || h >= proposal {
                trajectory.h = next;
            }
            return Ok(t_new);
        }
        trajectory.statistics.rejected += 1;
        rejections += 1;
        non_finite = !error.is_finite();
        if rejections > trajectory.settings.max_rejections {
            if non_finite {
                return Err(SolverError::at(
                    t,
                    SolverErrorKind::NonFiniteStages { step: h },
                ));
            }
            return Err(SolverError::at(
                t,
                SolverErrorKind::TooManyRejections {
                    rejections,
                    step: h,
                },
            ));
        }
        trajectory.h = if error.is_finite() {
            h * step_factor(error, method.error_order()).min(1.0)
        } else {
            0.1 * h
        };
        just_rejected = true;
    }
}

/// The methods a [`Solver`] can be.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Method {
    /// Dormand–Prince 5(4), explicit ([`Dopri5`]).
    #[default]
    Dopri5,
    /// RODAS4, linearly implicit, L-stable, order 4 with a continuous extension of order 3
    /// ([`Rosenbrock`] with [`crate::tableau::RODAS4`]): the stiff default.
    Rodas4,
    /// RODAS3, linearly implicit, L-stable ([`Rosenbrock`] with [`crate::tableau::RODAS3`]).
    Rodas3,
    /// Shampine's order-4 Rosenbrock method ([`crate::tableau::SHAMPINE4`]).
    Shampine4,
}

impl Method {
    /// The name a user writes: `dopri5`, `rodas4`, `rodas3`, `shampine4`.
    pub fn name(self) -> &'static str {
        match self {
            Self::Dopri5 => "dopri5",
            Self::Rodas4 => "rodas4",
            Self::Rodas3 => "rodas3",
            Self::Shampine4 => "shampine4",
        }
    }

    /// Whether the method is for stiff problems.
    pub fn is_stiff(self) -> bool {
        !matches!(self, Self::Dopri5)
    }
}

impl std::str::FromStr for Method {
    type Err = String;

    /// `dopri5` (also `explicit`), `rodas4` (also `stiff`, `rosenbrock`), `rodas3`,
    /// `shampine4`.
    fn from_str(s: &str) -> Result<Self, String> {
        match s.to_ascii_lowercase().as_str() {
            "dopri5" | "explicit" | "dormand-prince" => Ok(Self::Dopri5),
            "rodas4" | "stiff" | "rosenbrock" => Ok(Self::Rodas4),
            "rodas3" => Ok(Self::Rodas3),
            "shampine4" => Ok(Self::Shampine4),
            other => Err(format!(
                "unknown solver `{other}`: expected dopri5 (explicit), rodas4 (stiff), rodas3 \
                 or shampine4"
            )),
        }
    }
}

impl std::fmt::Display for Method {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// The method's own part of a solver.
#[derive(Debug, Clone)]
enum Inner {
    Dopri5(Box<Dopri5>),
    Rosenbrock(Box<Rosenbrock>),
}

/// A solver of the method chosen at run time, for `n` states.
#[derive(Debug, Clone)]
pub struct Solver {
    method: Method,
    trajectory: Trajectory,
    inner: Inner,
}

impl Solver {
    /// A solver of `method` for `n` states, at `t = 0`, `x = 0` until [`Solver::reset`].
    pub fn new(method: Method, n: usize, settings: Settings) -> Self {
        let inner = match method {
            Method::Dopri5 => Inner::Dopri5(Box::new(Dopri5::new(n))),
            Method::Rodas4 => {
                Inner::Rosenbrock(Box::new(Rosenbrock::new(crate::tableau::RODAS4, n)))
            }
            Method::Rodas3 => {
                Inner::Rosenbrock(Box::new(Rosenbrock::new(crate::tableau::RODAS3, n)))
            }
            Method::Shampine4 => {
                Inner::Rosenbrock(Box::new(Rosenbrock::new(crate::tableau::SHAMPINE4, n)))
            }
        };
        Self {
            method,
            trajectory: Trajectory::new(n, settings),
            inner,
        }
    }

    /// The method.
    pub fn method(&self) -> Method {
        self.method
    }

    /// The number of states.
    pub fn dimension(&self) -> usize {
        self.trajectory.n
    }

    /// Starts again from `(t, x)` with the states' `nominal`s (absolute tolerance
    /// `atol · |nominalᵢ|`; a nominal that is zero or not finite counts as 1): after an
    /// event, or at the start. The step size proposed so far is kept (the first step after
    /// an event is estimated again when it was never set).
    pub fn reset<E: std::error::Error + 'static>(
        &mut self,
        t: f64,
        x: &[f64],
        nominal: &[f64],
    ) -> Result<(), SolverError<E>> {
        let n = self.trajectory.n;
        for given in [x.len(), nominal.len()] {
            if given != n {
                return Err(SolverError::at(
                    t,
                    SolverErrorKind::Dimension { expected: n, given },
                ));
            }
        }
        let tr = &mut self.trajectory;
        for point in [&mut tr.current, &mut tr.previous] {
            point.t = t;
            point.x.copy_from_slice(x);
        }
        tr.dx_valid = false;
        tr.tolerance.set(tr.settings.absolute, nominal);
        match &mut self.inner {
            Inner::Dopri5(m) => m.forget(),
            Inner::Rosenbrock(m) => m.forget(),
        }
        Ok(())
    }

    /// Back to what [`Solver::new`] made, its buffers kept (nothing allocated): the first
    /// step size to be estimated again, the PI control's memory and the statistics cleared;
    /// [`Solver::reset`] then gives the start. A model run again from its start (an instance
    /// reset and initialised afresh) is integrated bit for bit as by a new solver.
    pub fn renew(&mut self) {
        let tr = &mut self.trajectory;
        tr.h = tr.settings.initial_step.unwrap_or(0.0);
        tr.error_old = 1e-4;
        tr.statistics = Statistics::default();
        tr.dx_valid = false;
        match &mut self.inner {
            Inner::Dopri5(m) => m.forget(),
            Inner::Rosenbrock(m) => m.forget(),
        }
    }

    /// The step size to try first after an event: starts the estimate again.
    pub fn forget_step_size(&mut self) {
        self.trajectory.h = self.trajectory.settings.initial_step.unwrap_or(0.0);
    }

    /// Takes one accepted step from the current time, not beyond `t_limit` (ending exactly on
    /// it when the step reaches it), and returns the new time. Between the previous time and
    /// the new one, [`Solver::interpolate`] gives the dense output.
    pub fn step<S: OdeSystem>(
        &mut self,
        system: &mut S,
        t_limit: f64,
    ) -> Result<f64, SolverError<S::Error>> {
        match &mut self.inner {
            Inner::Dopri5(m) => step(m.as_mut(), &mut self.trajectory, system, t_limit),
            Inner::Rosenbrock(m) => step(m.as_mut(), &mut self.trajectory, system, t_limit),
        }
    }

    /// Steps until `t_end`, at most `max_steps` accepted steps.
    pub fn integrate_to<S: OdeSystem>(
        &mut self,
        system: &mut S,
        t_end: f64,
        max_steps: usize,
    ) -> Result<(), SolverError<S::Error>> {
        let mut steps = 0;
        while self.trajectory.current.t < t_end {
            if steps == max_steps {
                return Err(SolverError::at(
                    self.trajectory.current.t,
                    SolverErrorKind::TooManySteps {
                        target: t_end,
                        max_steps,
                    },
                ));
            }
            self.step(system, t_end)?;
            steps += 1;
        }
        Ok(())
    }

    /// The solution at `t` in `[previous_time, time]` of the last step (the dense output),
    /// into `out`; outside, the method's polynomial extrapolated.
    pub fn interpolate(&self, t: f64, out: &mut [f64]) {
        if t == self.trajectory.current.t {
            out.copy_from_slice(&self.trajectory.current.x);
            return;
        }
        match &self.inner {
            Inner::Dopri5(m) => m.interpolate(&self.trajectory, t, out),
            Inner::Rosenbrock(m) => m.interpolate(&self.trajectory, t, out),
        }
    }

    /// The time of the last accepted step.
    pub fn time(&self) -> f64 {
        self.trajectory.current.t
    }

    /// The time before the last accepted step.
    pub fn previous_time(&self) -> f64 {
        self.trajectory.previous.t
    }

    /// The state at [`Solver::time`].
    pub fn state(&self) -> &[f64] {
        &self.trajectory.current.x
    }

    /// The step the error control proposes next.
    pub fn next_step(&self) -> f64 {
        self.trajectory.h
    }

    /// What the solver did since it was made.
    pub fn statistics(&self) -> Statistics {
        self.trajectory.statistics
    }

    /// The settings.
    pub fn settings(&self) -> &Settings {
        &self.trajectory.settings
    }
}
