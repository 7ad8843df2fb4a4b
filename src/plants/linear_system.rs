//! A generic linear state-space plant (docs/models.md §2.4), used for paper 004's three-state
//! system (§5 of that paper, docs/estimators.md §2.12) and by users.
//!
//! ```text
//! discrete:    x_{k+1} = A x_k + B u_k + w_k,          w_k ~ N(0, Q)
//! continuous:  dx/dt   = A x + B u + w(t),             w white with spectral density Q
//! both:        y_k     = C x_k + D u_k + v_k,          v_k ~ N(0, R)
//! ```
//!
//! Dimensions are dynamic: `n` states, `m` inputs (may be 0), `p` outputs.
//!
//! * **Discrete**: one [`LinearSystem::advance`] is one sample, whatever `h` is (the FMU
//!   steps it at its sample time).
//! * **Continuous**: over a communication step `h` with `u` held (zero-order hold) the
//!   solution is exact: `x⁺ = Φ x + Γ u + w_h` with `Φ = e^{A h}`, `Γ = ∫₀^h e^{Aτ} dτ B`
//!   (both from the exponential of the augmented matrix `[[A, B], [0, 0]] h`,
//!   [`crate::linalg::try_zoh`]), and `w_h ~ N(0, Q_h)` with the discrete-equivalent
//!   covariance `Q_h = ∫₀^h e^{Aτ} Q e^{Aᵀτ} dτ` by Van Loan's method: with
//!   `E = exp([[−A, Q], [0, Aᵀ]] h) = [[E₁₁, E₁₂], [0, E₂₂]]`, `Q_h = E₂₂ᵀ E₁₂`. `Φ`, `Γ` and
//!   the factor of `Q_h` are cached for the last `h` used (recomputed when `h` changes).
//!
//! **Noise.** `Q` and `R` must be symmetric positive *semi*-definite (zeros allowed: `Q = 0`
//! or `R = 0` switches that noise off, singular covariances are fine). They are sampled as
//! `w = L z`, `z ~ N(0, I)`, with the symmetric eigen-factor `L = V diag(√max(λᵢ, 0))`
//! (`Q = V Λ Vᵀ`), which exists for any PSD matrix, unlike a Cholesky factor. Eigenvalues
//! down to `−10⁻¹² · max(1, ‖Q‖_F)` are accepted as round-off zeros; a more negative one is
//! a negative variance and is rejected. The process noise uses the stream
//! `RandomGenerator::for_stream(seed, 0)`, the measurement noise `for_stream(seed, 1)`.
//!
//! **Sampling.** The measurement noise `v_k` belongs to the time point: it is drawn when the
//! state reaches `x_k` (at construction and at the end of every step), so
//! [`LinearSystem::output`] is a pure function of `u` at a given point and may be called any
//! number of times. Each sample draws `n` process deviates (stream 0) and `p` measurement
//! deviates (stream 1); the streams are independent, so the points of both are drawn first
//! and transformed together ([`crate::signals::rng::deviates_into`]), bit for bit the
//! deviates drawn one after another. The complete state for save/restore is
//! [`LinearSystem::saved_state`] (`x`, the pending `v_k`, the two generator states).
//!
//! **Speed.** The matrices of a sample are packed row by row (`Kernel`) and the step and
//! the outputs are compiled with constant dimensions for the packaged variants (`sized`),
//! so a step is straight-line arithmetic; a `u` is checked once ([`LinearSystem::input`])
//! for the step and the outputs of one call, and the outputs are handed out as computed
//! ([`LinearSystem::for_each_output`]). Sums keep nalgebra's order, so the results are
//! bit-identical to the matrix expressions.

use crate::linalg;
use crate::signals::rng::{deviates_into, PolarPoint, RandomGenerator};
use crate::state::PlainState;
use crate::state_space::StateSpace;
use crate::ParameterError;
use nalgebra::{DMatrix, DVector, SymmetricEigen};

/// Whether the model is a difference or a differential equation.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TimeDomain {
    /// `x_{k+1} = A x_k + B u_k + w_k`, one sample per step.
    Discrete,
    /// `dx/dt = A x + B u + w`, integrated exactly over each step with u held.
    Continuous,
}

/// The model, its noise and its start (parameter names as the FMU uses them).
#[derive(Debug, Clone, PartialEq)]
pub struct LinearSystemParameters {
    /// `A`, `B`, `C`, `D` and the noise covariances: `Q` (n × n, PSD) per sample (discrete)
    /// or spectral density per second (continuous), `R` (p × p, PSD).
    pub system: StateSpace,
    /// Discrete or continuous.
    pub time_domain: TimeDomain,
    /// Initial state `x0` (n).
    pub initial_state: DVector<f64>,
    /// Seed of the noise streams (parameter `seed`).
    pub seed: u64,
}

impl LinearSystemParameters {
    /// A noise-free model (`Q = 0`, `R = 0`) starting at `x0 = 0`, seed 1.
    pub fn noise_free(
        a: DMatrix<f64>,
        b: DMatrix<f64>,
        c: DMatrix<f64>,
        d: DMatrix<f64>,
        time_domain: TimeDomain,
    ) -> Self {
        let n = a.nrows();
        let p = c.nrows();
        Self {
            system: StateSpace {
                a,
                b,
                c,
                d,
                q: DMatrix::zeros(n, n),
                r: DMatrix::zeros(p, p),
            },
            time_domain,
            initial_state: DVector::zeros(n),
            seed: 1,
        }
    }

    /// Paper 004 §5 (docs/estimators.md §2.12): `A = [[1.005, 0, 0], [0, 0.9954, −0.08757],
    /// [0, 0.1248, 0.9945]]`, no input, both agents' outputs `C = [[1, 0, 0], [0, 1, 0]]`,
    /// `Q = 0.2 I₃`, `R = 0.1 I₂` (covariances), discrete, `x0 = [1, 1, 1]` (docs/experiments.md §4).
    pub fn distributed_observer_example(seed: u64) -> Self {
        let a = DMatrix::from_row_slice(
            3,
            3,
            &[1.005, 0.0, 0.0, 0.0, 0.9954, -0.08757, 0.0, 0.1248, 0.9945],
        );
        let c = DMatrix::from_row_slice(2, 3, &[1.0, 0.0, 0.0, 0.0, 1.0, 0.0]);
        Self {
            system: StateSpace::without_input(
                a,
                c,
                DMatrix::identity(3, 3) * 0.2,
                DMatrix::identity(2, 2) * 0.1,
            ),
            time_domain: TimeDomain::Discrete,
            initial_state: DVector::from_element(3, 1.0),
            seed,
        }
    }

    /// Number of states `n`.
    pub fn states(&self) -> usize {
        self.system.states()
    }

    /// Number of inputs `m`.
    pub fn inputs(&self) -> usize {
        self.system.inputs()
    }

    /// Number of outputs `p`.
    pub fn outputs(&self) -> usize {
        self.system.outputs()
    }

    /// Checks shapes, finiteness and the covariances, naming the first bad matrix.
    pub fn validate(&self) -> Result<(), ParameterError> {
        self.system.check_dimensions()?;
        let n = self.states();
        if self.initial_state.len() != n {
            return Err(ParameterError::new(
                "x0",
                format!("must have {n} entries, got {}", self.initial_state.len()),
            ));
        }
        if self.initial_state.iter().any(|v| !v.is_finite()) {
            return Err(ParameterError::new("x0", "contains NaN or infinity"));
        }
        covariance_factor("Q", &self.system.q)?;
        covariance_factor("R", &self.system.r)?;
        Ok(())
    }
}

/// The state needed to continue a [`LinearSystem`] bit-for-bit.
#[derive(Debug, Clone, PartialEq)]
pub struct LinearSystemState {
    /// The state `x_k`.
    pub state: Vec<f64>,
    /// The measurement noise `v_k` of the current time point.
    pub measurement_noise: Vec<f64>,
    /// Process-noise generator state, then measurement-noise generator state.
    pub random_streams: [u64; 8],
}
/// `Φ`, `Γ` and the factor of `Q_h` for one step length `h` (continuous time).
#[derive(Debug, Clone, PartialEq)]
struct Discretisation {
    step: f64,
    transition: DMatrix<f64>,
    input: DMatrix<f64>,
    noise_factor: DMatrix<f64>,
}

/// An input `u` checked against a system (its `m` entries, all finite), from
/// [`LinearSystem::input`]: what the step and the outputs take, so one call of the FMU
/// checks its input once.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Input<'a>(&'a [f64]);

impl<'a> Input<'a> {
    /// The entries of `u`.
    pub fn values(&self) -> &'a [f64] {
        self.0
    }
}

/// The matrices of a sample packed row by row, in the order the step reads them: row `i`
/// of `[Φ | Γ | L_Q]` (`A`, `B` in discrete time; `2n + m` entries), row `j` of `[C | D]`
/// (`n + m`) and of `L_R` (`p`), and row `i` of `[A | B]` (`n + m`). Built from the
/// matrices when the system is made (and when the discretisation changes), so a step walks
/// contiguous memory and no shape.
#[derive(Debug, Clone, PartialEq, Default)]
struct Kernel {
    n: usize,
    m: usize,
    p: usize,
    process: Vec<f64>,
    output: Vec<f64>,
    measurement: Vec<f64>,
    /// Row `i` of `[A | B]`: the continuous right-hand side.
    dynamics: Vec<f64>,
}

/// The dimensions `(n, m, p)`.
type Dims = (usize, usize, usize);

impl Kernel {
    fn dims(&self) -> Dims {
        (self.n, self.m, self.p)
    }
}

/// `body(dims)`, with the dimensions as constants when they are a packaged variant's
/// (LinearSystem (2, 1, 1), LinearSystem2 (2, 2, 2), DistributedObserverPlant (3, 0, 2)) or
/// the scalar plant's (1, 1, 1): `body` is inlined into each case, so its loops have known
/// lengths and unroll into straight-line code; other dimensions run the same code with
/// run-time lengths.
#[inline(always)]
fn sized<R>(dims: Dims, body: impl FnOnce(Dims) -> R) -> R {
    match dims {
        (1, 1, 1) => body((1, 1, 1)),
        (2, 1, 1) => body((2, 1, 1)),
        (2, 2, 2) => body((2, 2, 2)),
        (3, 0, 2) => body((3, 0, 2)),
        dims => body(dims),
    }
}

/// The rows of the blocks side by side, row after row (the blocks have the same rows).
fn packed_rows(blocks: &[&DMatrix<f64>]) -> Vec<f64> {
    let rows = blocks.first().map_or(0, |b| b.nrows());
    let mut packed = Vec::new();
    for i in 0..rows {
        for block in blocks {
            packed.extend(block.row(i).iter());
        }
    }
    packed
}

/// Preallocated buffers of one step, so [`LinearSystem::advance`] allocates nothing: the
/// accepted points of the polar method; the deviates `z` of the next sample (process then
/// measurement), drawn ahead at the end of the sample before (or when the streams are set),
/// with the two streams past them; the next state; and the state and measurement noise of
/// the last time point, restored when a step fails. Derived from the streams, so not saved.
#[derive(Debug, Clone, PartialEq)]
struct Workspace {
    points: Vec<PolarPoint>,
    deviates: Vec<f64>,
    process_ahead: RandomGenerator,
    measurement_ahead: RandomGenerator,
    next: Vec<f64>,
    saved_state: Vec<f64>,
    saved_measurement_noise: Vec<f64>,
}

impl Workspace {
    /// The buffers; [`LinearSystem::draw_ahead`] fills the deviates and the streams.
    fn new(n: usize, p: usize, process: &RandomGenerator, measurement: &RandomGenerator) -> Self {
        Self {
            points: vec![PolarPoint::default(); n + p],
            deviates: vec![0.0; n + p],
            process_ahead: process.clone(),
            measurement_ahead: measurement.clone(),
            next: vec![0.0; n],
            saved_state: vec![0.0; n],
            saved_measurement_noise: vec![0.0; p],
        }
    }
}

/// The plant with its state, noise streams and discretisation cache.
#[derive(Debug, Clone, PartialEq)]
pub struct LinearSystem {
    parameters: LinearSystemParameters,
    state: DVector<f64>,
    measurement_noise: DVector<f64>,
    process_factor: DMatrix<f64>,
    measurement_factor: DMatrix<f64>,
    process_stream: RandomGenerator,
    measurement_stream: RandomGenerator,
    cache: Option<Discretisation>,
    kernel: Kernel,
    work: Workspace,
}

/// The message of a state become non-finite.
const NON_FINITE_STATE: &str =
    "the state became non-finite (A has eigenvalues far outside the stable region?)";

impl LinearSystem {
    /// The system at `x0` with its first measurement noise drawn, after validation.
    pub fn new(parameters: LinearSystemParameters) -> Result<Self, ParameterError> {
        parameters.validate()?;
        let process_factor = covariance_factor("Q", &parameters.system.q)?;
        let measurement_factor = covariance_factor("R", &parameters.system.r)?;
        let process_stream = RandomGenerator::for_stream(parameters.seed, 0);
        let measurement_stream = RandomGenerator::for_stream(parameters.seed, 1);
        let mut system = Self {
            work: Workspace::new(
                parameters.states(),
                parameters.outputs(),
                &process_stream,
                &measurement_stream,
            ),
            state: parameters.initial_state.clone(),
            measurement_noise: DVector::zeros(parameters.outputs()),
            process_factor,
            measurement_factor,
            process_stream,
            measurement_stream,
            cache: None,
            kernel: Kernel::default(),
            parameters,
        };
        system.pack();
        system.draw_measurement_noise();
        system.draw_ahead();
        Ok(system)
    }

    /// Draws the deviates of the next sample from the streams (the streams themselves stay
    /// where they are until the sample: see [`Workspace`]).
    fn draw_ahead(&mut self) {
        let w = &mut self.work;
        w.process_ahead.clone_from(&self.process_stream);
        w.measurement_ahead.clone_from(&self.measurement_stream);
        draw(
            &mut w.points,
            &mut w.deviates,
            self.kernel.n,
            &mut w.process_ahead,
            &mut w.measurement_ahead,
        );
    }

    /// Packs the kernel from the matrices (at construction, and when the discretisation
    /// changes).
    fn pack(&mut self) {
        let s = &self.parameters.system;
        let (transition, input, factor) = self.process_matrices();
        self.kernel = Kernel {
            n: s.states(),
            m: s.inputs(),
            p: s.outputs(),
            process: packed_rows(&[transition, input, factor]),
            output: packed_rows(&[&s.c, &s.d]),
            measurement: packed_rows(&[&self.measurement_factor]),
            dynamics: packed_rows(&[&s.a, &s.b]),
        };
    }

    /// `(Φ, Γ, L)` of a sample: the cached discretisation in continuous time, else `A`, `B`
    /// and the factor of `Q`.
    fn process_matrices(&self) -> (&DMatrix<f64>, &DMatrix<f64>, &DMatrix<f64>) {
        let p = &self.parameters;
        match (&p.time_domain, &self.cache) {
            (TimeDomain::Continuous, Some(d)) => (&d.transition, &d.input, &d.noise_factor),
            _ => (&p.system.a, &p.system.b, &self.process_factor),
        }
    }

    /// Paper 004's three-state example ([`LinearSystemParameters::distributed_observer_example`]).
    pub fn distributed_observer_example(seed: u64) -> Result<Self, ParameterError> {
        Self::new(LinearSystemParameters::distributed_observer_example(seed))
    }

    /// The parameters.
    pub fn parameters(&self) -> &LinearSystemParameters {
        &self.parameters
    }

    /// The current state `x_k`.
    pub fn state(&self) -> &DVector<f64> {
        &self.state
    }

    /// The measurement noise `v_k` of the current time point (for scoring).
    pub fn measurement_noise(&self) -> &DVector<f64> {
        &self.measurement_noise
    }

    /// `u` checked in one pass: `m` entries (named `u` when not), all finite.
    #[inline]
    pub fn input<'a>(&self, u: &'a [f64]) -> Result<Input<'a>, ParameterError> {
        let m = self.kernel.m;
        if u.len() != m {
            return Err(ParameterError::new(
                "u",
                format!("must have {m} entries, got {}", u.len()),
            ));
        }
        if u.iter().any(|v| !v.is_finite()) {
            return Err(ParameterError::new("u", "contains NaN or infinity"));
        }
        Ok(Input(u))
    }

    /// The outputs of the current time point, in order, each passed to `each(j, clean, v)`:
    /// the noise-free `(C x + D u)ⱼ` (summed as `&C * &x + &D * u` sums it) and the
    /// measurement noise `vⱼ`; the measured output is `yⱼ = (C x + D u)ⱼ + vⱼ`. Computed as
    /// passed, into nothing, with the packaged variants' dimensions as constants (`sized`).
    #[inline]
    pub fn for_each_output(&self, u: Input, mut each: impl FnMut(usize, f64, f64)) {
        let k = &self.kernel;
        sized(
            k.dims(),
            #[inline(always)]
            |(n, m, p)| {
                let (Some(x), Some(v), Some(u), Some(rows)) = (
                    self.state.as_slice().get(..n),
                    self.measurement_noise.as_slice().get(..p),
                    u.0.get(..m),
                    k.output.get(..p * (n + m)),
                ) else {
                    return;
                };
                let width = n + m;
                for j in 0..p {
                    let row = &rows[j * width..(j + 1) * width];
                    each(j, dot(&row[..n], x) + dot(&row[n..], u), v[j]);
                }
            },
        )
    }

    /// The noise-free output `C x + D u`.
    pub fn clean_output(&self, u: Input) -> DVector<f64> {
        let mut y = DVector::zeros(self.kernel.p);
        self.for_each_output(u, |j, clean, _| y[j] = clean);
        y
    }

    /// The measured output `y_k = C x_k + D u + v_k`.
    pub fn output(&self, u: Input) -> DVector<f64> {
        let mut y = DVector::zeros(self.kernel.p);
        self.for_each_output(u, |j, clean, v| y[j] = clean + v);
        y
    }

    /// The right-hand side `dx/dt = A x + B u` of the noise-free continuous model (the
    /// derivative a Model Exchange importer integrates), written into `dx`; its Jacobians
    /// are `∂f/∂x = A`, `∂f/∂u = B`, and those of the output `C x + D u` are `C`, `D`.
    pub fn derivative_into(
        &self,
        x: &[f64],
        u: Input,
        dx: &mut [f64],
    ) -> Result<(), ParameterError> {
        let k = &self.kernel;
        let (n, width) = (k.n, k.n + k.m);
        if x.len() != n || dx.len() != n {
            return Err(ParameterError::new("x", format!("must have {n} entries")));
        }
        for (dx, row) in dx.iter_mut().zip(k.dynamics.chunks_exact(width)) {
            *dx = dot(&row[..n], x) + dot(&row[n..], u.0);
        }
        Ok(())
    }

    /// Sets the state (the continuous states a Model Exchange importer integrates), checked
    /// against the dimension and for finiteness (named `x`).
    pub fn set_state(&mut self, x: &[f64]) -> Result<(), ParameterError> {
        if x.len() != self.kernel.n || x.iter().any(|v| !v.is_finite()) {
            return Err(ParameterError::new(
                "x",
                format!("must hold {} finite values", self.kernel.n),
            ));
        }
        self.state.copy_from_slice(x);
        Ok(())
    }

    /// Advances one sample (discrete) or `h` seconds with `u` held (continuous), adds the
    /// process noise and draws the measurement noise of the new time point. A non-positive
    /// `h` in continuous time (named `h`), or a state that would become non-finite (named
    /// `x`) is an error and leaves the system unchanged. Allocates nothing once the
    /// discretisation for `h` is cached.
    pub fn advance(&mut self, u: Input, h: f64) -> Result<(), ParameterError> {
        self.advance_samples(u, h, 1)
    }

    /// [`Self::advance`] `count` times with the same `u` and `h`, all or nothing: on an error
    /// at any sample the system is as before the call.
    pub fn advance_samples(&mut self, u: Input, h: f64, count: u64) -> Result<(), ParameterError> {
        if count == 0 {
            return Ok(());
        }
        if self.parameters.time_domain == TimeDomain::Continuous
            && !matches!(&self.cache, Some(d) if d.step == h)
        {
            self.cache = Some(self.discretisation(h)?);
            self.pack();
        }
        sized(
            self.kernel.dims(),
            #[inline(always)]
            |dims| self.samples(dims, u.0, count),
        )
    }

    /// `count` samples in place, each `x⁺ = (Φ x + Γ u) + L z` (the order `&Φ * &x + &Γ * u
    /// + w` adds in) then the measurement noise of the new point `v = L_R z`, with the
    /// deviates of the process (`n`) and the measurement (`p`) streams drawn first and
    /// transformed together. On a state that is not finite, an error and the system as
    /// before. Inlined for each of [`sized`]'s dimensions.
    #[inline(always)]
    fn samples(&mut self, (n, m, p): Dims, u: &[f64], count: u64) -> Result<(), ParameterError> {
        let Self {
            kernel: k,
            work: w,
            state,
            measurement_noise,
            process_stream,
            measurement_stream,
            ..
        } = self;
        let width = 2 * n + m;
        let (
            Some(x),
            Some(v),
            Some(u),
            Some(rows),
            Some(factor),
            Some(points),
            Some(z),
            Some(next),
            Some(saved_x),
            Some(saved_v),
        ) = (
            state.as_mut_slice().get_mut(..n),
            measurement_noise.as_mut_slice().get_mut(..p),
            u.get(..m),
            k.process.get(..n * width),
            k.measurement.get(..p * p),
            w.points.get_mut(..n + p),
            w.deviates.get_mut(..n + p),
            w.next.get_mut(..n),
            w.saved_state.get_mut(..n),
            w.saved_measurement_noise.get_mut(..p),
        )
        else {
            return Err(ParameterError::new("x", "does not match the dimensions"));
        };
        // What a failed sample after the first restores (the first fails before any change).
        let streams = (count > 1).then(|| {
            saved_x.copy_from_slice(x);
            saved_v.copy_from_slice(v);
            (process_stream.clone(), measurement_stream.clone())
        });
        for _ in 0..count {
            // The deviates z of this sample were drawn ahead.
            for i in 0..n {
                let row = &rows[i * width..(i + 1) * width];
                next[i] = dot(&row[..n], x) + dot(&row[n..n + m], u) + dot(&row[n + m..], &z[..n]);
            }
            if next.iter().any(|x| !x.is_finite()) {
                if let Some((process, measurement)) = streams {
                    x.copy_from_slice(saved_x);
                    v.copy_from_slice(saved_v);
                    (*process_stream, *measurement_stream) = (process, measurement);
                    self.draw_ahead();
                }
                return Err(ParameterError::new("x", NON_FINITE_STATE));
            }
            x.copy_from_slice(next);
            for j in 0..p {
                v[j] = dot(&factor[j * p..(j + 1) * p], &z[n..]);
            }
            process_stream.clone_from(&w.process_ahead);
            measurement_stream.clone_from(&w.measurement_ahead);
            // The next sample's, drawn now: their transforms run beside what follows.
            draw(points, z, n, &mut w.process_ahead, &mut w.measurement_ahead);
        }
        Ok(())
    }

    /// `(Φ, Γ)` for a step `h` in continuous time, or `(A, B)` in discrete time.
    pub fn discrete_matrices(
        &self,
        h: f64,
    ) -> Result<(DMatrix<f64>, DMatrix<f64>), ParameterError> {
        match self.parameters.time_domain {
            TimeDomain::Discrete => Ok((
                self.parameters.system.a.clone(),
                self.parameters.system.b.clone(),
            )),
            TimeDomain::Continuous => {
                let d = self.discretisation(h)?;
                Ok((d.transition, d.input))
            }
        }
    }

    /// The complete state, for saving.
    pub fn saved_state(&self) -> LinearSystemState {
        let p = self.process_stream.state();
        let m = self.measurement_stream.state();
        LinearSystemState {
            state: self.state.iter().copied().collect(),
            measurement_noise: self.measurement_noise.iter().copied().collect(),
            random_streams: [p[0], p[1], p[2], p[3], m[0], m[1], m[2], m[3]],
        }
    }

    /// Restores a [`Self::saved_state`] (checked against the dimensions).
    pub fn restore(&mut self, saved: &LinearSystemState) -> Result<(), ParameterError> {
        let (n, p) = (self.kernel.n, self.kernel.p);
        if saved.state.len() != n || saved.state.iter().any(|v| !v.is_finite()) {
            return Err(ParameterError::new(
                "x",
                format!("a saved state must hold {n} finite values"),
            ));
        }
        if saved.measurement_noise.len() != p
            || saved.measurement_noise.iter().any(|v| !v.is_finite())
        {
            return Err(ParameterError::new(
                "v",
                format!("a saved measurement noise must hold {p} finite values"),
            ));
        }
        let s = &saved.random_streams;
        let process = RandomGenerator::from_state([s[0], s[1], s[2], s[3]])?;
        let measurement = RandomGenerator::from_state([s[4], s[5], s[6], s[7]])?;
        // The lengths were checked above.
        self.state.as_mut_slice().copy_from_slice(&saved.state);
        self.measurement_noise
            .as_mut_slice()
            .copy_from_slice(&saved.measurement_noise);
        self.process_stream = process;
        self.measurement_stream = measurement;
        self.draw_ahead();
        Ok(())
    }

    /// Draws the measurement noise of the current time point, `v = L_R z`, in place.
    fn draw_measurement_noise(&mut self) {
        let k = &self.kernel;
        let w = &mut self.work;
        for z in w.deviates.iter_mut().take(k.p) {
            *z = self.measurement_stream.gaussian();
        }
        for (v, row) in self
            .measurement_noise
            .iter_mut()
            .zip(k.measurement.chunks_exact(k.p.max(1)))
        {
            *v = dot(row, &w.deviates[..]);
        }
    }

    /// The cached discretisation for `h`, or a fresh one.
    fn discretisation(&self, h: f64) -> Result<Discretisation, ParameterError> {
        if let Some(d) = &self.cache {
            if d.step == h {
                return Ok(d.clone());
            }
        }
        if !(h.is_finite() && h > 0.0) {
            return Err(ParameterError::new(
                "h",
                format!("the step must be finite and > 0, got {h}"),
            ));
        }
        let p = &self.parameters;
        let (transition, input) = linalg::try_zoh(&p.system.a, &p.system.b, h)
            .map_err(|e| ParameterError::new("A", format!("cannot discretise: {e}")))?;
        let n = p.states();
        let noise_factor = if p.system.q.iter().all(|v| *v == 0.0) {
            DMatrix::zeros(n, n)
        } else {
            // Van Loan: exp([[−A, Q], [0, Aᵀ]] h) = [[E11, E12], [0, E22]], Q_h = E22ᵀ E12.
            let mut van_loan = DMatrix::<f64>::zeros(2 * n, 2 * n);
            van_loan
                .view_mut((0, 0), (n, n))
                .copy_from(&(-&p.system.a * h));
            van_loan
                .view_mut((0, n), (n, n))
                .copy_from(&(&p.system.q * h));
            van_loan
                .view_mut((n, n), (n, n))
                .copy_from(&(p.system.a.transpose() * h));
            let e = linalg::try_expm(&van_loan)
                .map_err(|e| ParameterError::new("Q", format!("cannot discretise: {e}")))?;
            let e12 = e.view((0, n), (n, n)).into_owned();
            let e22 = e.view((n, n), (n, n)).into_owned();
            let mut q_h = e22.transpose() * e12;
            linalg::symmetrize(&mut q_h);
            covariance_factor("Q", &q_h)?
        };
        Ok(Discretisation {
            step: h,
            transition,
            input,
            noise_factor,
        })
    }
}

/// `Σⱼ rowⱼ vⱼ` over the common length, summed in order from the first product, as
/// nalgebra's `&M * &v` sums a row (column by column), so `(C x)ᵢ + (D u)ᵢ` is bit-identical
/// to `&C * &x + &D * u`; 0 for an empty row. Index loops, so that a length known where it
/// is inlined unrolls into straight-line code.
#[inline(always)]
fn dot(row: &[f64], v: &[f64]) -> f64 {
    let length = row.len().min(v.len());
    if length == 0 {
        return 0.0;
    }
    let mut sum = row[0] * v[0];
    for j in 1..length {
        sum += row[j] * v[j];
    }
    sum
}

/// The deviates of one sample into `z`: `n` from the process stream, then the rest from the
/// measurement stream, their points drawn first and transformed together.
#[inline(always)]
fn draw(
    points: &mut [PolarPoint],
    z: &mut [f64],
    n: usize,
    process: &mut RandomGenerator,
    measurement: &mut RandomGenerator,
) {
    for point in points.iter_mut().take(n) {
        *point = process.polar_point();
    }
    for point in points.iter_mut().skip(n) {
        *point = measurement.polar_point();
    }
    deviates_into(points, z);
}

/// The eigen-factor `L = V diag(√max(λ, 0))` of a symmetric PSD covariance (module docs),
/// or an error naming it if it is not symmetric or has a negative variance.
fn covariance_factor(
    name: &str,
    covariance: &DMatrix<f64>,
) -> Result<DMatrix<f64>, ParameterError> {
    let n = covariance.nrows();
    if n == 0 {
        return Ok(DMatrix::zeros(0, 0));
    }
    let scale = covariance.norm().max(1.0);
    let asymmetry = (covariance - covariance.transpose()).amax();
    if asymmetry > 1e-12 * scale {
        return Err(ParameterError::new(
            name,
            format!("must be symmetric (largest |{name} − {name}ᵀ| entry {asymmetry:e})"),
        ));
    }
    if covariance.iter().all(|v| *v == 0.0) {
        return Ok(DMatrix::zeros(n, n));
    }
    let diagonal = (0..n).all(|i| (0..n).all(|j| i == j || covariance[(i, j)] == 0.0));
    if diagonal {
        let mut factor = DMatrix::zeros(n, n);
        for i in 0..n {
            let variance = covariance[(i, i)];
            if variance < 0.0 {
                return Err(ParameterError::new(
                    name,
                    format!("negative variance {variance} on the diagonal (entry {i})"),
                ));
            }
            factor[(i, i)] = variance.sqrt();
        }
        return Ok(factor);
    }
    let eigen = SymmetricEigen::new(covariance.clone());
    let smallest = eigen.eigenvalues.min();
    if smallest < -1e-12 * scale {
        return Err(ParameterError::new(
            name,
            format!("must be positive semi-definite, has eigenvalue {smallest:e}"),
        ));
    }
    let mut factor = eigen.eigenvectors;
    for (j, lambda) in eigen.eigenvalues.iter().enumerate() {
        let root = lambda.max(0.0).sqrt();
        factor.column_mut(j).scale_mut(root);
    }
    Ok(factor)
}

// FMU-state snapshots (plain bytes) of the types above: every field, in order.
crate::plain_state!(
    enum TimeDomain {
        Discrete,
        Continuous,
    }
);
crate::plain_state!(StateSpace { a, b, c, d, q, r });
crate::plain_state!(LinearSystemParameters {
    system,
    time_domain,
    initial_state,
    seed
});
crate::plain_state!(Discretisation {
    step,
    transition,
    input,
    noise_factor
});

/// Every field but the kernel and the workspace, which are rebuilt from the saved matrices and
/// dimensions.
impl PlainState for LinearSystem {
    fn save(&self, out: &mut Vec<u8>) {
        self.parameters.save(out);
        self.state.save(out);
        self.measurement_noise.save(out);
        self.process_factor.save(out);
        self.measurement_factor.save(out);
        self.process_stream.save(out);
        self.measurement_stream.save(out);
        self.cache.save(out);
    }

    fn read(input: &mut &[u8]) -> Result<Self, crate::state::StateError> {
        let parameters = LinearSystemParameters::read(input)?;
        let state = PlainState::read(input)?;
        let measurement_noise = PlainState::read(input)?;
        let process_factor = PlainState::read(input)?;
        let measurement_factor = PlainState::read(input)?;
        let process_stream = PlainState::read(input)?;
        let measurement_stream = PlainState::read(input)?;
        let work = Workspace::new(
            parameters.states(),
            parameters.outputs(),
            &process_stream,
            &measurement_stream,
        );
        let mut system = Self {
            parameters,
            state,
            measurement_noise,
            process_factor,
            measurement_factor,
            process_stream,
            measurement_stream,
            cache: PlainState::read(input)?,
            kernel: Kernel::default(),
            work,
        };
        system.pack();
        system.draw_ahead();
        Ok(system)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn matrix(rows: usize, cols: usize, values: &[f64]) -> DMatrix<f64> {
        DMatrix::from_row_slice(rows, cols, values)
    }

    /// The scalar system `x⁺ = a x` (or `dx/dt = a x`), `y = x`, no input, no noise.
    fn scalar(a: f64, time_domain: TimeDomain) -> LinearSystemParameters {
        LinearSystemParameters::noise_free(
            matrix(1, 1, &[a]),
            DMatrix::zeros(1, 0),
            matrix(1, 1, &[1.0]),
            DMatrix::zeros(1, 0),
            time_domain,
        )
    }

    #[test]
    fn discrete_system_matches_matrix_powers() {
        let a = matrix(2, 2, &[0.9, 0.2, -0.1, 0.7]);
        let b = matrix(2, 1, &[1.0, 0.5]);
        let c = matrix(1, 2, &[1.0, -1.0]);
        let d = matrix(1, 1, &[0.3]);
        let mut p = LinearSystemParameters::noise_free(
            a.clone(),
            b.clone(),
            c.clone(),
            d.clone(),
            TimeDomain::Discrete,
        );
        p.initial_state = DVector::from_vec(vec![1.0, -2.0]);
        let x0 = p.initial_state.clone();
        let mut s = LinearSystem::new(p).unwrap();
        let u = DVector::from_vec(vec![0.4]);
        for _ in 0..25 {
            s.advance(s.input(u.as_slice()).unwrap(), 0.1).unwrap();
        }
        // x_25 = A^25 x0 + Σ_{j<25} A^j B u.
        let mut expected = a.pow(25) * &x0;
        for j in 0..25 {
            expected += a.pow(j) * &b * &u;
        }
        assert!((s.state() - &expected).amax() < 1e-12);
        let y = s.output(s.input(u.as_slice()).unwrap());
        assert!((y - (&c * &expected + &d * &u)).amax() < 1e-12);
    }

    #[test]
    fn continuous_system_matches_the_analytic_solution() {
        // A = V Λ V⁻¹ with real eigenvalues −1, −2, −0.5.
        let v = matrix(3, 3, &[1.0, 1.0, 0.0, 0.0, 1.0, 1.0, 1.0, 0.0, 1.0]);
        let v_inv = v.clone().try_inverse().unwrap();
        let lambda = [-1.0, -2.0, -0.5];
        let a = &v * DMatrix::from_diagonal(&DVector::from_row_slice(&lambda)) * &v_inv;
        let b = matrix(3, 1, &[1.0, 0.0, 2.0]);
        let c = matrix(1, 3, &[1.0, 1.0, 1.0]);
        let mut p = LinearSystemParameters::noise_free(
            a,
            b.clone(),
            c,
            matrix(1, 1, &[0.0]),
            TimeDomain::Continuous,
        );
        let x0 = DVector::from_vec(vec![1.0, 0.5, -1.0]);
        p.initial_state = x0.clone();
        let mut s = LinearSystem::new(p).unwrap();
        let u = DVector::from_vec(vec![1.5]);
        let h = 0.1;
        for _ in 0..50 {
            s.advance(s.input(u.as_slice()).unwrap(), h).unwrap();
        }
        let t = 5.0;
        // x(t) = V e^{Λt} V⁻¹ x0 + V Λ⁻¹ (e^{Λt} − I) V⁻¹ B u.
        let exp = DMatrix::from_diagonal(&DVector::from_iterator(
            3,
            lambda.iter().map(|l| (l * t).exp()),
        ));
        let integral = DMatrix::from_diagonal(&DVector::from_iterator(
            3,
            lambda.iter().map(|l| ((l * t).exp() - 1.0) / l),
        ));
        let expected = &v * &exp * &v_inv * &x0 + &v * integral * &v_inv * &b * &u;
        let error = (s.state() - &expected).amax();
        assert!(error < 1e-12, "error {error:e}");
    }

    /// A random system of `n` states, `m` inputs and `p` outputs with full (non-diagonal)
    /// covariances, stable enough for its time domain.
    fn random_system(
        g: &mut RandomGenerator,
        (n, m, p): (usize, usize, usize),
        time_domain: TimeDomain,
    ) -> LinearSystemParameters {
        let mut random = |rows, cols, scale: f64| {
            DMatrix::from_fn(rows, cols, |_, _| g.uniform_range(-scale, scale))
        };
        let a = match time_domain {
            TimeDomain::Discrete => random(n, n, 0.4 / n as f64) + DMatrix::identity(n, n) * 0.5,
            TimeDomain::Continuous => random(n, n, 0.4 / n as f64) - DMatrix::identity(n, n),
        };
        let (b, c, d) = (random(n, m, 1.0), random(p, n, 1.0), random(p, m, 1.0));
        let (lq, lr) = (random(n, n, 0.5), random(p, p, 0.5));
        let mut parameters = LinearSystemParameters::noise_free(a, b, c, d, time_domain);
        parameters.system.q = &lq * lq.transpose();
        parameters.system.r = &lr * lr.transpose();
        linalg::symmetrize(&mut parameters.system.q);
        linalg::symmetrize(&mut parameters.system.r);
        parameters.initial_state = random(n, 1, 1.0).column(0).into_owned();
        parameters.seed = 7 + (n * 100 + m * 10 + p) as u64;
        parameters
    }

    #[test]
    fn in_place_steps_are_bit_identical_to_the_matrix_expressions() {
        // x⁺ = Φ x + Γ u + L_Q z, v = L_R z, y = C x + D u + v, the expressions as nalgebra
        // evaluates them (the former code), one deviate after another, against the packed
        // kernel with the deviates drawn first and transformed together: the specialised
        // n = 1…4, the general n, no input, one to three samples a call, both time domains.
        let mut g = RandomGenerator::new(2026);
        for time_domain in [TimeDomain::Discrete, TimeDomain::Continuous] {
            for dims in [
                (1, 1, 1),
                (2, 1, 1),
                (2, 2, 2),
                (3, 0, 2),
                (4, 2, 3),
                (6, 1, 2),
            ] {
                let p = random_system(&mut g, dims, time_domain);
                let (n, m, outputs) = dims;
                let mut s = LinearSystem::new(p.clone()).unwrap();
                let mut process = RandomGenerator::for_stream(p.seed, 0);
                let mut measurement = RandomGenerator::for_stream(p.seed, 1);
                let h = 0.05;
                let (phi, gamma, lq) = match time_domain {
                    TimeDomain::Discrete => (
                        p.system.a.clone(),
                        p.system.b.clone(),
                        covariance_factor("Q", &p.system.q).unwrap(),
                    ),
                    TimeDomain::Continuous => {
                        let d = s.discretisation(h).unwrap();
                        (d.transition, d.input, d.noise_factor)
                    }
                };
                let lr = covariance_factor("R", &p.system.r).unwrap();
                let gauss = |g: &mut RandomGenerator, k| DVector::from_fn(k, |_, _| g.gaussian());
                let mut x = p.initial_state.clone();
                assert_eq!(
                    s.measurement_noise(),
                    &(&lr * gauss(&mut measurement, outputs))
                );
                for k in 0..300 {
                    let u = DVector::from_fn(m, |i, _| (k as f64 * 0.3 + i as f64).sin());
                    let count = 1 + k % 3;
                    s.advance_samples(s.input(u.as_slice()).unwrap(), h, count as u64)
                        .unwrap();
                    let mut v = DVector::zeros(outputs);
                    for _ in 0..count {
                        x = &phi * &x + &gamma * &u + &lq * gauss(&mut process, n);
                        v = &lr * gauss(&mut measurement, outputs);
                    }
                    assert_eq!(s.state(), &x, "{dims:?} {time_domain:?} step {k}");
                    assert_eq!(s.measurement_noise(), &v);
                    let clean = &p.system.c * &x + &p.system.d * &u;
                    assert_eq!(s.clean_output(s.input(u.as_slice()).unwrap()), clean);
                    assert_eq!(s.output(s.input(u.as_slice()).unwrap()), clean + v);
                }
            }
        }
    }

    #[test]
    fn a_step_to_a_non_finite_state_is_refused_and_rolled_back() {
        let mut p = scalar(1e200, TimeDomain::Discrete);
        p.initial_state = DVector::from_element(1, 1.0);
        p.system.r = matrix(1, 1, &[1.0]);
        let mut s = LinearSystem::new(p).unwrap();
        let u = DVector::zeros(0);
        s.advance(s.input(u.as_slice()).unwrap(), 1.0).unwrap();
        assert_eq!(s.state()[0], 1e200);
        let before = s.saved_state();
        // the second of three samples overflows: all three are undone
        assert_eq!(
            s.advance_samples(s.input(u.as_slice()).unwrap(), 1.0, 3)
                .unwrap_err()
                .parameter,
            "x"
        );
        assert_eq!(s.saved_state(), before);
    }

    #[test]
    fn a_failed_step_leaves_the_noise_streams_where_they_were() {
        // x⁺ = 2 x + w: from 1e308 the first sample overflows, from 0.6e308 the second.
        let mut p = scalar(2.0, TimeDomain::Discrete);
        p.system.q = matrix(1, 1, &[1.0]);
        p.system.r = matrix(1, 1, &[1.0]);
        let mut failing = LinearSystem::new(p.clone()).unwrap();
        let mut reference = LinearSystem::new(p).unwrap();
        let u = failing.input(&[]).unwrap();
        for (start, count) in [(1e308, 1), (0.6e308, 3), (1e308, 2)] {
            failing.set_state(&[start]).unwrap();
            let error = failing.advance_samples(u, 1.0, count).unwrap_err();
            assert_eq!((error.parameter.as_str(), failing.state()[0]), ("x", start));
            failing.set_state(&[1.0]).unwrap();
            reference.set_state(&[1.0]).unwrap();
            assert_eq!(failing.saved_state(), reference.saved_state());
            for count in [1, 2, 1] {
                failing.advance_samples(u, 1.0, count).unwrap();
                reference.advance_samples(u, 1.0, count).unwrap();
                assert_eq!(failing.saved_state(), reference.saved_state());
            }
        }
    }

    #[test]
    fn the_continuous_right_hand_side_is_a_x_plus_b_u_and_its_jacobian_is_a() {
        let a = matrix(2, 2, &[-1.0, 2.0, -3.0, -0.5]);
        let b = matrix(2, 1, &[0.5, 1.5]);
        let mut s = LinearSystem::new(LinearSystemParameters::noise_free(
            a.clone(),
            b.clone(),
            matrix(1, 2, &[1.0, 0.0]),
            matrix(1, 1, &[0.0]),
            TimeDomain::Continuous,
        ))
        .unwrap();
        let x = DVector::from_vec(vec![0.3, -0.7]);
        let u = DVector::from_vec(vec![2.0]);
        let mut dx = DVector::zeros(2);
        s.derivative_into(
            x.as_slice(),
            s.input(u.as_slice()).unwrap(),
            dx.as_mut_slice(),
        )
        .unwrap();
        assert_eq!(dx, &a * &x + &b * &u);
        // central differences of f reproduce A column by column
        let (mut plus, mut minus) = (DVector::zeros(2), DVector::zeros(2));
        for j in 0..2 {
            let e = 1e-6;
            let mut xp = x.clone();
            xp[j] += e;
            let mut xm = x.clone();
            xm[j] -= e;
            s.derivative_into(
                xp.as_slice(),
                s.input(u.as_slice()).unwrap(),
                plus.as_mut_slice(),
            )
            .unwrap();
            s.derivative_into(
                xm.as_slice(),
                s.input(u.as_slice()).unwrap(),
                minus.as_mut_slice(),
            )
            .unwrap();
            let column = (&plus - &minus) / (2.0 * e);
            assert!((column - a.column(j)).amax() < 1e-9);
        }
        s.set_state(&[1.0, 2.0]).unwrap();
        assert_eq!(s.state().as_slice(), &[1.0, 2.0]);
        assert_eq!(s.set_state(&[f64::NAN, 0.0]).unwrap_err().parameter, "x");
        assert_eq!(s.set_state(&[1.0]).unwrap_err().parameter, "x");
    }

    #[test]
    fn process_and_measurement_noise_have_the_set_covariances() {
        // x⁺ = 0.5 x + w, Q = 1: stationary variance 1/(1 − 0.25) = 4/3; y = x + v, R = 0.1.
        let mut p = scalar(0.5, TimeDomain::Discrete);
        p.system.q = matrix(1, 1, &[1.0]);
        p.system.r = matrix(1, 1, &[0.1]);
        let mut s = LinearSystem::new(p).unwrap();
        let u = DVector::zeros(0);
        let n = 100_000;
        let (mut sx2, mut sv2) = (0.0, 0.0);
        for _ in 0..n {
            s.advance(s.input(u.as_slice()).unwrap(), 1.0).unwrap();
            sx2 += s.state()[0].powi(2);
            let v = s.output(s.input(u.as_slice()).unwrap())[0] - s.state()[0];
            sv2 += v * v;
        }
        let (var_x, var_v) = (sx2 / n as f64, sv2 / n as f64);
        assert!(
            (var_x - 4.0 / 3.0).abs() < 0.03 * 4.0 / 3.0,
            "state variance {var_x}"
        );
        assert!(
            (var_v - 0.1).abs() < 0.02 * 0.1,
            "measurement variance {var_v}"
        );
    }

    #[test]
    fn continuous_process_noise_uses_the_van_loan_covariance() {
        // dx/dt = −a x + w, spectral density q: Q_h = q (1 − e^{−2 a h}) / (2 a).
        let (a, q, h) = (2.0, 0.3, 0.25);
        let mut p = scalar(-a, TimeDomain::Continuous);
        p.system.q = matrix(1, 1, &[q]);
        let s = LinearSystem::new(p).unwrap();
        let d = s.discretisation(h).unwrap();
        let q_h = d.noise_factor[(0, 0)].powi(2);
        let want = q * (1.0 - (-2.0 * a * h).exp()) / (2.0 * a);
        assert!((q_h - want).abs() < 1e-14, "{q_h} vs {want}");
        assert!((d.transition[(0, 0)] - (-a * h).exp()).abs() < 1e-15);
    }

    #[test]
    fn semidefinite_covariances_are_accepted() {
        // Rank-one Q = [1 1; 1 1]: w₁ = w₂ always.
        let mut p = LinearSystemParameters::noise_free(
            DMatrix::zeros(2, 2),
            DMatrix::zeros(2, 0),
            DMatrix::identity(2, 2),
            DMatrix::zeros(2, 0),
            TimeDomain::Discrete,
        );
        p.system.q = matrix(2, 2, &[1.0, 1.0, 1.0, 1.0]);
        let mut s = LinearSystem::new(p).unwrap();
        let u = DVector::zeros(0);
        let mut sum2 = 0.0;
        for _ in 0..20_000 {
            s.advance(s.input(u.as_slice()).unwrap(), 1.0).unwrap();
            let x = s.state();
            assert!((x[0] - x[1]).abs() < 1e-12);
            sum2 += x[0] * x[0];
        }
        assert!((sum2 / 20_000.0 - 1.0).abs() < 0.05);
    }

    #[test]
    fn same_seed_same_run_and_restore_continues_bit_for_bit() {
        let mut a = LinearSystem::distributed_observer_example(5).unwrap();
        let mut b = LinearSystem::distributed_observer_example(5).unwrap();
        let u = DVector::zeros(0);
        for _ in 0..50 {
            a.advance(a.input(u.as_slice()).unwrap(), 1.0).unwrap();
            b.advance(b.input(u.as_slice()).unwrap(), 1.0).unwrap();
            assert_eq!(
                a.output(a.input(u.as_slice()).unwrap()),
                b.output(b.input(u.as_slice()).unwrap())
            );
        }
        let saved = a.saved_state();
        let run = |s: &mut LinearSystem| -> Vec<f64> {
            (0..20)
                .flat_map(|_| {
                    s.advance(s.input(u.as_slice()).unwrap(), 1.0).unwrap();
                    s.output(s.input(u.as_slice()).unwrap())
                        .iter()
                        .copied()
                        .collect::<Vec<_>>()
                })
                .collect()
        };
        let first = run(&mut a);
        let mut c = LinearSystem::distributed_observer_example(99).unwrap();
        c.restore(&saved).unwrap();
        assert_eq!(run(&mut c), first);
        let first_output = |seed| {
            let s = LinearSystem::distributed_observer_example(seed).unwrap();
            s.output(s.input(&[]).unwrap())
        };
        assert_ne!(first_output(6), first_output(5));
    }

    #[test]
    fn distributed_observer_example_has_the_papers_matrices() {
        let s = LinearSystem::distributed_observer_example(1).unwrap();
        let p = s.parameters();
        assert_eq!(p.system.a[(1, 2)], -0.08757);
        assert_eq!(p.system.a[(2, 1)], 0.1248);
        assert_eq!((p.states(), p.inputs(), p.outputs()), (3, 0, 2));
        assert_eq!(p.system.q, DMatrix::identity(3, 3) * 0.2);
        assert_eq!(p.system.r, DMatrix::identity(2, 2) * 0.1);
        assert_eq!(s.state(), &DVector::from_element(3, 1.0));
    }

    #[test]
    fn bad_inputs_are_named() {
        let base = LinearSystemParameters::noise_free(
            DMatrix::identity(2, 2),
            DMatrix::zeros(2, 1),
            DMatrix::zeros(1, 2),
            DMatrix::zeros(1, 1),
            TimeDomain::Continuous,
        );
        type Change = fn(&mut LinearSystemParameters);
        let cases: [(Change, &str); 10] = [
            (|p| p.system.a = DMatrix::zeros(2, 3), "A"),
            (|p| p.system.b = DMatrix::zeros(3, 1), "B"),
            (|p| p.system.c = DMatrix::zeros(1, 3), "C"),
            (|p| p.system.d = DMatrix::zeros(1, 2), "D"),
            (|p| p.system.q = matrix(2, 2, &[1.0, 0.0, 0.0, -0.5]), "Q"),
            // eigenvalues 3, −1
            (|p| p.system.q = matrix(2, 2, &[1.0, 2.0, 2.0, 1.0]), "Q"),
            (|p| p.system.q = matrix(2, 2, &[1.0, 0.5, 0.0, 1.0]), "Q"),
            (|p| p.system.r = matrix(1, 1, &[-0.1]), "R"),
            (|p| p.system.a[(0, 1)] = f64::NAN, "A"),
            (|p| p.initial_state = DVector::zeros(3), "x0"),
        ];
        for (change, name) in cases {
            let mut p = base.clone();
            change(&mut p);
            assert_eq!(LinearSystem::new(p).unwrap_err().parameter, name);
        }
        let mut s = LinearSystem::new(base).unwrap();
        let before = s.saved_state();
        assert_eq!(s.input(&[0.0, 0.0]).unwrap_err().parameter, "u");
        assert_eq!(s.input(&[f64::NAN]).unwrap_err().parameter, "u");
        assert_eq!(s.input(&[f64::INFINITY]).unwrap_err().parameter, "u");
        assert_eq!(
            s.advance(s.input(&[0.0]).unwrap(), 0.0)
                .unwrap_err()
                .parameter,
            "h"
        );
        assert_eq!(s.saved_state(), before);
    }
}
