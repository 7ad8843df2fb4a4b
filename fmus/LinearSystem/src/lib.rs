//! `LinearSystem.fmu`: a discrete or continuous linear state-space plant with seeded process
//! and measurement noise (docs/models.md §2.4), dimensions chosen when the FMU is packaged;
//! paper 004's three-state system (§5, docs/estimators.md §2.12) is the bundled variant
//! `DistributedObserverPlant`.
//!
//! ```text
//! discrete   (continuous = false):  x_{k+1} = A x_k + B u_k + w_k,   w_k ~ N(0, Q)
//! continuous (continuous = true):   x(t+h) = e^{Ah} x(t) + ∫₀^h e^{Aτ}dτ B u + w_h,
//!                                   w_h ~ N(0, ∫₀^h e^{Aτ} Q e^{Aᵀτ} dτ)   (exact, u held)
//! both:                             y_k = C x_k + D u_k + v_k,          v_k ~ N(0, R)
//! ```
//!
//! In discrete time the FMU samples on its own clock ([`spurio_fmu_common::clock`], rule
//! `Step`): at the instants `t_k = t_0 + k·T` of the parameter `sample_period` `T` (0, the
//! default: the size of the first step), the step from `t` to `t + h` takes the samples whose
//! instants lie in `[t, t + h)` (relative tolerance 10⁻⁹), `x_{k+1}` from `x_k` and the input
//! set before the step, shown at `t + h`; a step holding no instant (shorter than `T`, or a
//! master's rounding step of 10⁻¹⁵ s) holds the state and the measurement noise, a step
//! holding several takes them all with the same input (at most 10 000). With a fixed-step
//! master and the default, every step is one sample. In continuous time the step
//! is exact for any length and `sample_period` is not used. Outputs: the
//! measured `y[j]`, the noise-free `y_clean[j] = C x + D u` and the true state `x[i]` (for
//! scoring). `y` and `y_clean` depend directly on `u` (through `D`); the measurement noise of a
//! communication point is drawn once, when the point is reached, so setting `u` again at the
//! same point recomputes `y` with the same `v_k`. The mathematics (exact discretisation by the
//! matrix exponential, Van Loan's method for `Q_h`, eigen-factor sampling of PSD covariances)
//! is [`spurio::plants::linear_system`].
//!
//! Model Exchange (every variant declares it): the outputs `x[i]` are the continuous states,
//! `der(x[i])` their derivatives. In continuous time, of the noise-free `dx/dt = A x + B u`
//! with `y = y_clean = C x + D u`, no events. In discrete time a sampled system: `der(x) = 0`
//! and a time event at each instant `t_k = t_0 + k·T` (`sample_period`, or the default
//! experiment's step when it is 0) applies the sample of `t_{k−1}` (its input, the process
//! noise drawn as Co-Simulation draws it) and draws the measurement noise of `t_k`: each
//! event shows what the Co-Simulation step ending at `t_k` shows, bit for bit. The
//! directional derivatives are `A` (0 in discrete time), `B` (0), `C`, `D` exactly, on both
//! interfaces.
//!
//! Configuration keys: `n` (states, default 2), `m` (inputs, default 1, may be 0: then the
//! FMU has no input), `p` (outputs, default 1), and `preset = paper004` for paper 004's
//! matrices as defaults (which needs `n = 3`, `m = 0`, `p = 2`).

use nalgebra::{DMatrix, DVector};
use spurio::plants::linear_system::{Input, LinearSystem, LinearSystemParameters, TimeDomain};
use spurio::state_space::StateSpace;
use spurio_export::{
    Cause, Config, Context, DefaultExperiment, EventUpdate, Failure, FmuModel, ModelExchange,
    ModelInfo, Values, Variable, VariableTable,
};
use spurio_fmu_common::clock::{self, Rule, SampleClock};
use spurio_fmu_common::structured::{add_matrix, add_vector, Block};

/// Largest dimension a variant may have.
pub const MAX_DIMENSION: usize = 100;

/// Dimensions and preset of a configuration.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Dimensions {
    pub n: usize,
    pub m: usize,
    pub p: usize,
    /// Paper 004's matrices as defaults.
    pub paper004: bool,
}

fn count(config: &Config, key: &str, default: usize, min: usize) -> Result<usize, Cause> {
    match config.get(key) {
        None => Ok(default),
        Some(v) => match v.parse::<usize>() {
            Ok(k) if (min..=MAX_DIMENSION).contains(&k) => Ok(k),
            _ => Err(format!(
                "variant.cfg: `{key}` must be an integer from {min} to {MAX_DIMENSION}, got `{v}`"
            )
            .into()),
        },
    }
}

/// The dimensions a configuration asks for.
pub fn dimensions(config: &Config) -> Result<Dimensions, Cause> {
    let paper004 = match config.get("preset") {
        None | Some("") | Some("none") => false,
        Some("paper004") => true,
        Some(other) => {
            return Err(format!(
                "variant.cfg: `preset` must be `paper004` or absent, got `{other}`"
            )
            .into())
        }
    };
    let (dn, dm, dp) = if paper004 { (3, 0, 2) } else { (2, 1, 1) };
    let d = Dimensions {
        n: count(config, "n", dn, 1)?,
        m: count(config, "m", dm, 0)?,
        p: count(config, "p", dp, 1)?,
        paper004,
    };
    if paper004 && (d.n, d.m, d.p) != (3, 0, 2) {
        return Err(format!(
            "variant.cfg: `preset = paper004` is the system with n = 3, m = 0, p = 2, got n = {}, m = {}, p = {}",
            d.n, d.m, d.p
        ).into());
    }
    Ok(d)
}

/// The default parameters of a configuration: paper 004's system, or a stable chain
/// `x_i⁺ = 0.9 x_i + 0.1 x_{i+1}` (all poles at 0.9) with input `j` driving state `n − j`,
/// output `j` reading state `j`, `Q = 0.001 I`, `R = 0.01 I`, `x0 = 0`.
pub fn default_parameters(d: &Dimensions) -> LinearSystemParameters {
    if d.paper004 {
        return LinearSystemParameters::distributed_observer_example(1);
    }
    let (n, m, p) = (d.n, d.m, d.p);
    LinearSystemParameters {
        system: StateSpace {
            a: DMatrix::from_fn(n, n, |i, j| {
                if i == j {
                    0.9
                } else if j == i + 1 {
                    0.1
                } else {
                    0.0
                }
            }),
            b: DMatrix::from_fn(n, m, |i, j| if i + j + 1 == n { 1.0 } else { 0.0 }),
            c: DMatrix::from_fn(p, n, |i, j| if i == j { 1.0 } else { 0.0 }),
            d: DMatrix::zeros(p, m),
            q: DMatrix::identity(n, n) * 0.001,
            r: DMatrix::identity(p, p) * 0.01,
        },
        time_domain: TimeDomain::Discrete,
        initial_state: DVector::zeros(n),
        seed: 1,
    }
}

/// Where each block of variables starts.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Layout {
    pub dims: Dimensions,
    pub u: Block,
    pub y: Block,
    pub y_clean: Block,
    pub x: Block,
    pub a: Block,
    pub b: Block,
    pub c: Block,
    pub d: Block,
    pub q: Block,
    pub r: Block,
    pub x0: Block,
    pub seed: usize,
    pub continuous: usize,
    /// Parameter `sample_period` (discrete time).
    pub sample_period: usize,
    /// The derivatives `der(x)[i]` of the states `x[i]` (Model Exchange).
    pub der_x: Block,
}

/// The variable table and its layout.
pub fn table(d: &Dimensions) -> (Vec<Variable>, Layout) {
    let defaults = default_parameters(d);
    let (n, m, p) = (d.n, d.m, d.p);
    let mut t = VariableTable::new();
    let u = add_vector(&mut t, "u", m, |name, _| {
        Variable::input(name, 0.0).describe("Input (held over each step)")
    });
    let inputs: Vec<usize> = u.indices().collect();
    // The states x come after y and y_clean; outputs and derivatives depend on them and u.
    let first_state = m + 2 * p;
    let states_and_inputs: Vec<usize> = (first_state..first_state + n)
        .chain(inputs.iter().copied())
        .collect();
    let y = add_vector(&mut t, "y", p, |name, _| {
        Variable::output(name)
            .describe("Measured output C x + D u + v (Model Exchange in continuous time: C x + D u, noise-free)")
            .depends_on(&states_and_inputs)
    });
    let y_clean = add_vector(&mut t, "y_clean", p, |name, _| {
        Variable::output(name)
            .describe("Noise-free output C x + D u")
            .depends_on(&states_and_inputs)
    });
    let x = add_vector(&mut t, "x", n, |name, i| {
        Variable::output(name)
            .describe("True state (for scoring); the continuous states of Model Exchange")
            .state()
            .depends_on(&[first_state + i])
    });
    let a = add_matrix(&mut t, "A", n, n, |name, i, j| {
        Variable::parameter(name, defaults.system.a[(i, j)]).describe("State matrix")
    });
    let b = add_matrix(&mut t, "B", n, m, |name, i, j| {
        Variable::parameter(name, defaults.system.b[(i, j)]).describe("Input matrix")
    });
    let c = add_matrix(&mut t, "C", p, n, |name, i, j| {
        Variable::parameter(name, defaults.system.c[(i, j)]).describe("Output matrix")
    });
    let dd = add_matrix(&mut t, "D", p, m, |name, i, j| {
        Variable::parameter(name, defaults.system.d[(i, j)]).describe("Feedthrough matrix")
    });
    let q = add_matrix(&mut t, "Q", n, n, |name, i, j| {
        Variable::parameter(name, defaults.system.q[(i, j)]).describe(
            "Process-noise covariance (symmetric PSD): per sample, or spectral density per second when continuous",
        )
    });
    let r = add_matrix(&mut t, "R", p, p, |name, i, j| {
        Variable::parameter(name, defaults.system.r[(i, j)])
            .describe("Measurement-noise covariance (symmetric PSD)")
    });
    let x0 = add_vector(&mut t, "x0", n, |name, i| {
        Variable::parameter(name, defaults.initial_state[i]).describe("Initial state")
    });
    let seed = t.add(
        Variable::integer_parameter("seed", 1)
            .min(0.0)
            .describe("Seed of the noise streams (process: stream 0, measurement: stream 1)"),
    );
    let continuous = t.add(Variable::boolean_parameter("continuous", false).describe(
        "false: x+ = A x + B u + w, one sample per sample_period; true: dx/dt = A x + B u + w, exact over each step",
    ));
    let sample_period = t.add(clock::parameter());
    let der_x = add_vector(&mut t, "der(x)", n, |_, i| {
        Variable::derivative(&format!("der(x[{}])", i + 1), x.first + i)
            .describe("Model Exchange: dx/dt = A x + B u in continuous time, 0 in discrete time (x changes at the sample events)")
            .depends_on(&states_and_inputs)
    });
    let layout = Layout {
        dims: *d,
        u,
        y,
        y_clean,
        x,
        a,
        b,
        c,
        d: dd,
        q,
        r,
        x0,
        seed,
        continuous,
        sample_period,
        der_x,
    };
    (t.into_variables(), layout)
}

/// The LinearSystem FMU.
#[derive(Debug, Clone)]
pub struct LinearSystemFmu {
    layout: Layout,
    system: Option<LinearSystem>,
    clock: SampleClock,
    /// The input `u`, preallocated so a step allocates nothing.
    input: Vec<f64>,
    /// The states set by a Model Exchange solver and their derivatives.
    states: Vec<f64>,
    derivatives: Vec<f64>,
    /// Model Exchange in discrete time: the clock of the sample events (rule `Point`: the
    /// event at `t_j` shows the result of the `j` samples before it) and the input sampled at
    /// the last sample instant, which the next sample event applies.
    me_clock: SampleClock,
    held: DVector<f64>,
    /// The default experiment's step size: the sample period of Model Exchange when
    /// `sample_period` = 0 (there is no first step to take it from).
    default_step: f64,
}

/// The system once initialised, or the error of a call before initialisation.
fn initialised<T>(system: Option<T>) -> Result<T, Failure> {
    system.ok_or_else(|| Failure::error("LinearSystem: not initialised"))
}

fn error(e: spurio::ParameterError) -> Failure {
    Failure::error(e.to_string())
}

/// The failure of an advance `at` (the step from, the sample event) `time`: a state become
/// non-finite is named as such.
fn advance_error(e: spurio::ParameterError, at: &str, time: f64) -> Failure {
    if e.parameter == "x" {
        Failure::error(format!(
            "the state became non-finite {at} t = {time} (A has eigenvalues far outside the unit circle?)"
        ))
    } else {
        error(e)
    }
}

/// The outputs of the current point straight into the values: the measured
/// `y = (C x + D u) + v`, the noise-free `y_clean = C x + D u` and the state `x`.
#[inline]
fn write_outputs(l: &Layout, system: &LinearSystem, u: Input, values: &mut Values) {
    system.for_each_output(u, |j, clean, v| {
        values.set_real(l.y.first + j, clean + v);
        values.set_real(l.y_clean.first + j, clean);
    });
    for (i, x) in system.state().as_slice().iter().enumerate() {
        values.set_real(l.x.first + i, *x);
    }
}

impl LinearSystemFmu {
    /// Reads the inputs into the preallocated `u`.
    fn read_input(&mut self, ctx: &Context) {
        for (u, k) in self.input.iter_mut().zip(self.layout.u.indices()) {
            *u = ctx.values.real(k);
        }
    }

    /// Model Exchange: the input read last becomes the one the next sample event applies.
    fn hold_input(&mut self) {
        for (held, u) in self.held.iter_mut().zip(&self.input) {
            *held = *u;
        }
    }

    /// Reads and checks `u`, then writes the outputs of the current point.
    fn write_outputs(&mut self, ctx: &mut Context) -> Result<(), Failure> {
        self.read_input(ctx);
        let system = initialised(self.system.as_ref())?;
        let u = system.input(&self.input).map_err(error)?;
        write_outputs(&self.layout, system, u, ctx.values);
        Ok(())
    }

    /// Model Exchange: the states the solver set become the system's state.
    fn take_solver_states(&mut self, ctx: &Context) -> Result<(), Failure> {
        for (x, k) in self.states.iter_mut().zip(self.layout.x.indices()) {
            *x = ctx.values.real(k);
        }
        initialised(self.system.as_mut())?
            .set_state(&self.states)
            .map_err(error)
    }

    fn read_parameters(&self, ctx: &Context) -> Result<LinearSystemParameters, Failure> {
        let l = &self.layout;
        let v = &*ctx.values;
        let seed = v.integer(l.seed);
        if seed < 0 {
            return Err(Failure::error(format!(
                "parameter `seed`: must be >= 0, got {seed}"
            )));
        }
        Ok(LinearSystemParameters {
            system: StateSpace {
                a: l.a.matrix(v),
                b: l.b.matrix(v),
                c: l.c.matrix(v),
                d: l.d.matrix(v),
                q: l.q.matrix(v),
                r: l.r.matrix(v),
            },
            time_domain: if v.boolean(l.continuous) {
                TimeDomain::Continuous
            } else {
                TimeDomain::Discrete
            },
            initial_state: l.x0.vector(v),
            seed: seed as u64,
        })
    }
}

impl FmuModel for LinearSystemFmu {
    fn describe(config: &Config) -> Result<ModelInfo, Cause> {
        let d = dimensions(config)?;
        let (variables, _) = table(&d);
        let description = if d.paper004 {
            "Linear state-space plant with seeded noise: paper 004's three-state system (A, C, Q = 0.2 I, R = 0.1 I)"
        } else {
            "Discrete or continuous linear state-space plant with seeded process and measurement noise"
        };
        Ok(ModelInfo::new(
            "LinearSystem",
            description,
            variables,
            Some(DefaultExperiment {
                start_time: 0.0,
                stop_time: if d.paper004 { 100.0 } else { 10.0 },
                step_size: if d.paper004 { 1.0 } else { 0.1 },
            }),
            config.clone(),
        )
        .with_model_exchange()?)
    }

    fn create(info: &ModelInfo) -> Result<Self, Cause> {
        let d = dimensions(&info.config)?;
        let (_, layout) = table(&d);
        Ok(Self {
            layout,
            system: None,
            clock: SampleClock::new(Rule::Step, 0.0, 0.0)?,
            input: vec![0.0; d.m],
            states: vec![0.0; d.n],
            derivatives: vec![0.0; d.n],
            me_clock: SampleClock::new(Rule::Point, 0.0, 0.0)?,
            held: DVector::zeros(d.m),
            default_step: info
                .default_experiment
                .as_ref()
                .map_or(0.0, |e| e.step_size),
        })
    }

    fn initialize(&mut self, ctx: &mut Context) -> Result<(), Failure> {
        let parameters = self.read_parameters(ctx)?;
        let start = ctx.time();
        let clock =
            SampleClock::from_parameter(Rule::Step, ctx.values, self.layout.sample_period, start)?;
        let period = match clock.period() {
            0.0 => self.default_step,
            period => period,
        };
        let me_clock = SampleClock::new(Rule::Point, start, period)?;
        self.system = Some(LinearSystem::new(parameters).map_err(error)?);
        self.clock = clock;
        self.me_clock = me_clock;
        self.read_input(ctx);
        self.hold_input();
        self.write_outputs(ctx)
    }

    fn do_step(&mut self, ctx: &mut Context, time: f64, step: f64) -> Result<(), Failure> {
        self.read_input(ctx);
        let system = initialised(self.system.as_mut())?;
        // u checked once for the step and the outputs.
        let u = system.input(&self.input).map_err(error)?;
        // In place and all or nothing: a failed step leaves the system as it was.
        let (clock, advanced) = match system.parameters().time_domain {
            TimeDomain::Continuous => (self.clock, system.advance(u, step)),
            TimeDomain::Discrete => {
                // The samples whose instants lie in this step, with the input set before it.
                let (clock, samples) = self.clock.after(time, step)?;
                let count = samples.end - samples.start;
                (clock, system.advance_samples(u, clock.period(), count))
            }
        };
        advanced.map_err(|e| advance_error(e, "in the step from", time))?;
        self.clock = clock;
        write_outputs(&self.layout, system, u, ctx.values);
        Ok(())
    }

    fn update_outputs(&mut self, ctx: &mut Context) -> Result<(), Failure> {
        self.write_outputs(ctx)
    }

    spurio_fmu_common::fmu_state!(system, clock, me_clock, held; check = |m: &Self| {
        if let Some(system) = &m.system {
            let p = system.parameters();
            p.validate()?;
            if system.state().len() != p.states() || system.state().iter().any(|v| !v.is_finite()) {
                return Err("the saved state x is not a finite vector of n entries".into());
            }
            if m.held.len() != p.inputs() || m.held.iter().any(|v| !v.is_finite()) {
                return Err("the saved sampled input is not a finite vector of m entries".into());
            }
        }
        Ok(())
    });
}

impl ModelExchange for LinearSystemFmu {
    fn evaluate(&mut self, ctx: &mut Context) -> Result<(), Failure> {
        let l = self.layout;
        if !ctx.values.boolean(l.continuous) {
            // Piecewise constant states: der(x) = 0, the measured output with the noise of
            // the last sample.
            self.take_solver_states(ctx)?;
            for k in l.der_x.indices() {
                ctx.values.set_real(k, 0.0);
            }
            return self.write_outputs(ctx);
        }
        for (x, k) in self.states.iter_mut().zip(l.x.indices()) {
            *x = ctx.values.real(k);
        }
        self.read_input(ctx);
        let system = initialised(self.system.as_mut())?;
        let u = system.input(&self.input).map_err(error)?;
        system
            .derivative_into(&self.states, u, &mut self.derivatives)
            .map_err(error)?;
        for (dx, k) in self.derivatives.iter().zip(l.der_x.indices()) {
            ctx.values.set_real(k, *dx);
        }
        // The outputs of the states the solver set, noise-free.
        system.set_state(&self.states).map_err(error)?;
        system.for_each_output(u, |j, clean, _| {
            ctx.values.set_real(l.y.first + j, clean);
            ctx.values.set_real(l.y_clean.first + j, clean);
        });
        Ok(())
    }

    fn event_indicators(&mut self, _ctx: &mut Context, _z: &mut [f64]) -> Result<(), Failure> {
        Ok(())
    }

    fn update_discrete_states(&mut self, ctx: &mut Context) -> Result<EventUpdate, Failure> {
        if ctx.values.boolean(self.layout.continuous) {
            return Ok(EventUpdate::default());
        }
        let time = ctx.time();
        self.take_solver_states(ctx)?;
        // The samples whose results are due by now (one at each sample instant), with the
        // input sampled at the instant before.
        let (clock, samples) = self.me_clock.after(time, 0.0)?;
        let count = samples.end - samples.start;
        let system = initialised(self.system.as_mut())?;
        let held = system.input(self.held.as_slice()).map_err(error)?;
        system
            .advance_samples(held, clock.period(), count)
            .map_err(|e| advance_error(e, "at the sample event", time))?;
        self.me_clock = clock;
        // At a sample instant: the input the next sample takes.
        if clock.sample_at(time).is_some() {
            self.read_input(ctx);
            self.hold_input();
        }
        self.write_outputs(ctx)?;
        Ok(EventUpdate {
            states_changed: count > 0,
            next_event_time: Some(clock.instant(clock.taken())),
            ..EventUpdate::default()
        })
    }

    /// Whether the system runs in continuous time (der(x) = 0 in discrete time: the states
    /// change only at the sample events); the entries are those of the system's matrices.
    type Jacobian = bool;

    fn jacobian(&mut self, ctx: &Context) -> Result<bool, Failure> {
        initialised(self.system.as_ref())?;
        Ok(ctx.values.boolean(self.layout.continuous))
    }

    fn partial(&self, &continuous: &bool, unknown: usize, known: usize) -> Result<f64, Failure> {
        let p = initialised(self.system.as_ref())?.parameters();
        let l = &self.layout;
        let position = |block: &Block, k: usize| block.indices().position(|i| i == k);
        let (state, input) = (position(&l.x, known), position(&l.u, known));
        if state.is_none() && input.is_none() {
            return Err(Failure::error(format!(
                "directional derivative: value reference {known} is not a state x or an input u"
            )));
        }
        // the rows of [A B], [C D] and [I 0] for der(x), y and y_clean, and x
        let (over_state, over_input) = if let Some(i) = position(&l.der_x, unknown) {
            if continuous {
                (
                    state.map(|j| p.system.a[(i, j)]),
                    input.map(|j| p.system.b[(i, j)]),
                )
            } else {
                (state.map(|_| 0.0), input.map(|_| 0.0))
            }
        } else if let Some(i) = position(&l.y, unknown).or_else(|| position(&l.y_clean, unknown)) {
            (
                state.map(|j| p.system.c[(i, j)]),
                input.map(|j| p.system.d[(i, j)]),
            )
        } else if let Some(i) = position(&l.x, unknown) {
            (
                state.map(|j| f64::from(u8::from(i == j))),
                input.map(|_| 0.0),
            )
        } else {
            return Err(Failure::error(format!(
                "directional derivative: value reference {unknown} is not der(x), x, y or y_clean"
            )));
        };
        Ok(over_state.or(over_input).unwrap_or(0.0))
    }
}

spurio_export::export_fmu!(
    LinearSystemFmu,
    model_exchange,
    variants = [
        ("LinearSystem", Config::new()),
        (
            "DistributedObserverPlant",
            spurio_fmu_common::config(&[
                ("n", "3"),
                ("m", "0"),
                ("p", "2"),
                ("preset", "paper004")
            ])
        ),
        (
            "LinearSystem2",
            spurio_fmu_common::config(&[("n", "2"), ("m", "2"), ("p", "2")])
        ),
    ]
);

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn configurations_give_the_right_dimensions() {
        let d = dimensions(&Config::new()).unwrap();
        assert_eq!((d.n, d.m, d.p, d.paper004), (2, 1, 1, false));
        let mut c = Config::new();
        c.set("preset", "paper004");
        let d = dimensions(&c).unwrap();
        assert_eq!((d.n, d.m, d.p), (3, 0, 2));
        c.set("n", 4);
        assert!(dimensions(&c).unwrap_err().to_string().contains("paper004"));
        let mut c = Config::new();
        c.set("m", 0);
        assert_eq!(dimensions(&c).unwrap().m, 0);
        c.set("n", 0);
        assert!(dimensions(&c).unwrap_err().to_string().contains("`n`"));
    }

    /// `x[1]` of the default system (x⁺ = 0.9 x + … + u, no noise) after each step of
    /// `step` with u = 1, `sample_period` = `period`.
    fn states(period: f64, steps: &[(f64, f64)]) -> Vec<f64> {
        use spurio_export::harness::Harness;
        let config = Config::new();
        let info = LinearSystemFmu::describe(&config).unwrap();
        let vr = |n: &str| info.index_of(n).unwrap() as u32;
        let mut h = Harness::<LinearSystemFmu>::new(&config).unwrap();
        h.set_real(
            &[
                vr("Q[1,1]"),
                vr("Q[2,2]"),
                vr("R[1,1]"),
                vr("sample_period"),
            ],
            &[0.0, 0.0, 0.0, period],
        )
        .unwrap();
        h.set_real(&[vr("u[1]")], &[1.0]).unwrap();
        h.initialize(steps[0].0).unwrap();
        steps
            .iter()
            .map(|&(t, step)| {
                h.do_step(t, step).unwrap();
                h.real(vr("x[2]")).unwrap()
            })
            .collect()
    }

    /// Continuous time, `B[1,1]` = 0.854: the step of 1e308 s makes ‖[[A, B], [0, 0]]·h‖₁
    /// overflow (0.854e308 + 1e308), which once asked for 2³¹ squarings (66 s, then an error
    /// from the noise's exponential, or with `Q` = 0 a wrong `Φ = I`). Refused at once now.
    #[test]
    fn a_step_too_long_to_discretise_is_refused_at_once() {
        use spurio_export::harness::Harness;
        for noise in [0.001, 0.0] {
            let config = Config::new();
            let info = LinearSystemFmu::describe(&config).unwrap();
            let vr = |n: &str| info.index_of(n).unwrap() as u32;
            let mut h = Harness::<LinearSystemFmu>::new(&config).unwrap();
            h.set_boolean(&[vr("continuous")], &[true]).unwrap();
            h.set_real(
                &[vr("B[1,1]"), vr("Q[1,1]"), vr("Q[2,2]")],
                &[0.854, noise, noise],
            )
            .unwrap();
            h.initialize(0.0).unwrap();
            h.do_step(0.0, 0.1).unwrap();
            let words = ["cannot discretise", "too large", "1e308"];
            let refused = h.refuses_at_once(0.5, &words, |h| h.do_step(0.1, 1e308));
            assert_eq!(refused, Ok(()), "Q = {noise}");
        }
    }

    #[test]
    fn discrete_time_samples_on_the_clock_and_holds_between_samples() {
        // x₂⁺ = 0.9 x₂ + u from 0: 1, 1.9, 2.71, …
        let exact = [1.0, 1.9, 2.71, 3.439];
        let at_period = states(0.1, &[(0.0, 0.1), (0.1, 0.1), (0.2, 0.1), (0.3, 0.1)]);
        assert_eq!(at_period, exact);
        // The default takes the period from the first step.
        assert_eq!(states(0.0, &[(0.0, 0.1), (0.1, 0.1)]), exact[..2]);
        // Half periods: the sample of t_k in the step from t_k, held over the next.
        let half = states(0.1, &[(0.0, 0.05), (0.05, 0.05), (0.1, 0.05), (0.15, 0.05)]);
        assert_eq!(half, [1.0, 1.0, 1.9, 1.9]);
        // Two and a half periods: the instants each step holds (0, 0.1, 0.2, then 0.3, 0.4).
        let long = states(0.1, &[(0.0, 0.25), (0.25, 0.25)]);
        assert_eq!(long[0], exact[2]);
        assert!((long[1] - 4.0951).abs() < 1e-12, "{long:?}");
        // Accumulated time and a last step of 1.8e-15 s: no extra sample.
        let mut steps = Vec::new();
        let mut t = 0.0;
        for _ in 0..4 {
            steps.push((t, 0.1));
            t += 0.1;
        }
        steps.push((0.4 - 1.8e-15, 1.8e-15));
        let accumulated = states(0.1, &steps);
        assert_eq!(accumulated[..4], exact);
        assert_eq!(accumulated[4], exact[3]);
    }

    /// Model Exchange in discrete time (the defaults: noise on, `sample_period` = 0, so the
    /// default experiment's step 0.1 s) against Co-Simulation steps of 0.1 s with the same
    /// input, bit for bit: the time event at `t_k` shows what the step ending at `t_k` shows.
    #[test]
    fn model_exchange_in_discrete_time_gives_the_co_simulation_samples() {
        use spurio_export::Values;
        let info = LinearSystemFmu::describe(&Config::new()).unwrap();
        let (_, l) = table(&dimensions(&Config::new()).unwrap());
        let input = |k: usize| if k < 12 { 1.0 } else { -0.5 };
        let read = |v: &Values| (v.real(l.x.first), v.real(l.x.first + 1), v.real(l.y.first));
        // Co-Simulation: the input of the step from t_k set at t_k.
        let mut values = Values::from_start(&info.variables);
        let mut cs = LinearSystemFmu::create(&info).unwrap();
        cs.initialize(&mut Context::at(&mut values, 0.0)).unwrap();
        let mut expected = vec![read(&values)];
        for k in 0..30 {
            values.set_real(l.u.first, input(k));
            let t = k as f64 * 0.1;
            cs.do_step(&mut Context::at(&mut values, t), t, 0.1)
                .unwrap();
            expected.push(read(&values));
        }
        // Model Exchange: the event at t_k, the input set there (and once between events,
        // which the samples must not see).
        let mut values = Values::from_start(&info.variables);
        let mut me = LinearSystemFmu::create(&info).unwrap();
        me.initialize(&mut Context::at(&mut values, 0.0)).unwrap();
        let mut got = Vec::new();
        for k in 0..=30 {
            let t = k as f64 * 0.1;
            values.set_real(l.u.first, input(k));
            let update = me
                .update_discrete_states(&mut Context::at(&mut values, t))
                .unwrap();
            assert_eq!(update.states_changed, k > 0);
            assert_eq!(update.next_event_time, Some((k + 1) as f64 * 0.1));
            me.evaluate(&mut Context::at(&mut values, t)).unwrap();
            got.push(read(&values));
            assert_eq!(values.real(l.der_x.first), 0.0);
            // Between the events: an input change and an importer's event change nothing.
            values.set_real(l.u.first, 100.0);
            let between = me
                .update_discrete_states(&mut Context::at(&mut values, t + 0.05))
                .unwrap();
            assert!(!between.states_changed);
            assert_eq!(between.next_event_time, Some((k + 1) as f64 * 0.1));
            assert_eq!((read(&values).0, read(&values).1), (got[k].0, got[k].1));
        }
        assert_eq!(got, expected);
        // The noise is on: the measured output is not the clean one.
        assert_ne!(got[5].2, got[5].0);
        // der(x) = 0 in the Jacobian, C as before
        let mut out = [1.0; 2];
        me.directional_derivative(
            &mut Context::at(&mut values, 3.0),
            &[l.der_x.first, l.y.first],
            &[l.x.first],
            &[1.0],
            &mut out,
        )
        .unwrap();
        assert_eq!(out, [0.0, 1.0]);
    }

    #[test]
    fn tables_have_no_inputs_when_m_is_zero_and_defaults_are_valid() {
        for (n, m, p) in [(2, 1, 1), (3, 0, 2), (4, 2, 3)] {
            let d = Dimensions {
                n,
                m,
                p,
                paper004: false,
            };
            let (v, l) = table(&d);
            assert_eq!(
                v.iter()
                    .filter(|x| x.causality == spurio_export::Causality::Input)
                    .count(),
                m
            );
            assert_eq!(v[l.continuous].name, "continuous");
            assert_eq!(v[l.sample_period].name, "sample_period");
            assert_eq!(l.sample_period, v.len() - 1 - n);
            assert_eq!(v[l.der_x.first].name, "der(x[1])");
            assert_eq!(v[l.der_x.first].derivative_of, Some(l.x.first));
            assert_eq!(v[l.a.index(n - 1, n - 1)].name, format!("A[{n},{n}]"));
            assert!(LinearSystem::new(default_parameters(&d)).is_ok());
        }
        let d = Dimensions {
            n: 3,
            m: 0,
            p: 2,
            paper004: true,
        };
        let (v, l) = table(&d);
        assert_eq!(
            v[l.a.index(1, 2)].start,
            spurio_export::Value::Real(-0.08757)
        );
        assert_eq!(v[l.x0.first].start, spurio_export::Value::Real(1.0));
    }

    #[test]
    fn a_loaded_state_with_a_nan_state_is_refused() {
        use spurio_export::harness::Harness;
        use spurio_export::types::Status;
        let d = dimensions(&Config::new()).unwrap();
        let (_, l) = table(&d);
        let mut h = Harness::<LinearSystemFmu>::new(&Config::new()).unwrap();
        let marker = 0.123_456_789_012_345_f64;
        h.set_real(&[l.x0.first as u32], &[marker]).unwrap();
        h.initialize(0.0).unwrap();
        let good = h.serialized_state().unwrap();
        // the last copy of x0[1] in the bytes is the model's current state x[1]
        let at = good
            .windows(8)
            .rposition(|w| w == marker.to_le_bytes())
            .unwrap();
        let mut bad = good.clone();
        bad[at..at + 8].copy_from_slice(&f64::NAN.to_le_bytes());
        assert_eq!(h.restore_state(&bad), Err(Status::Error));
        assert!(
            h.logged(&[
                "fmi2DeSerializeFMUstate",
                "the saved state x is not a finite vector"
            ]),
            "{:?}",
            h.log()
        );
        h.restore_state(&good).unwrap();
    }
}
