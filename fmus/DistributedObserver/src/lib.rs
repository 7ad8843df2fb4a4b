//! `DistributedObserver.fmu`: one agent of the two-agent distributed observer of paper 004
//! (del Nozal et al., Jornadas de Automática 2017), docs/estimators.md §2.12.
//!
//! Plant x⁺ = A x + w, agent i measures y_i = C_i x + n_i. Each sample (a step reaching a
//! sample instant of `sample_period`, [`spurio_fmu_common::clock`]) with inputs
//! y_own = y_i(k) and x_neighbour = x̂_j(k) (the other agent's output, connected by the
//! master) computes
//!
//! ```text
//! x̂_i⁺ = A x̂_i + V_i L_i (y_i − C_i x̂_i) + V̄_i N_ij V̄_iᵀ (x̂_j − x̂_i)
//! ```
//!
//! A missing sample (`y_own_valid[j]` = false, docs/estimators.md, "Missing samples") has
//! innovation 0: no injection from that channel, `y_own[j]` ignored.
//!
//! with T_i = [V̄_i V_i]ᵀ splitting the state into the part agent i cannot observe (V̄_i,
//! n_ō columns) and the part it can (V_i, n_o columns), and the gains of two discrete
//! Riccati (LQ) problems with U = ρ Q, S = λ V_iᵀC_iᵀR_iC_iV_i, T = λ(V̄_iᵀC_iᵀR_iC_iV̄_i + D_i)
//! solved once in initialization ([`spurio::estimation::DistributedObserver`]). `design` = 2
//! replaces L_i by the local steady-state Kalman predictor gain (far better when S is
//! singular, docs/experiments.md §4).
//!
//! Configuration: `n` (states, default 3), `p_own` and `p_neighbour` (outputs of this agent
//! and of the other, default 1), `agent` (1 or 2; only the defaults depend on it: agent 1
//! measures the first `p_own` states and its neighbour the next `p_neighbour`, agent 2 the
//! other way round). For n = 3 the default A is paper 004's example.
//!
//! The gains are calculated parameters `L[i,j]` (n_o×p_own, rows beyond n_o are 0) and
//! `N[i,j]` (n_ō×n_ō, padded to n×n with zeros), in the bases V_i, V̄_i, with `n_observable`
//! = n_o. Only the first n_ō entries of the distance `D[i]` are used.

use nalgebra::{DMatrix, DVector};
use spurio::estimation::{
    DistributedObserver, DistributedObserverConfig, EstimationError, ObserverDesign,
};
use spurio_export::{
    Causality, Cause, Config, Context, DefaultExperiment, Failure, ModelInfo, Value, Values,
    Variability, Variable, VariableTable,
};
use spurio_fmu_common::estimator::{
    add_choice, add_tuning, add_validity, choice, count, error, leading_identity, mark_missing,
    read_inputs, DynamicState, Estimator,
};
use spurio_fmu_common::structured::{add_matrix, add_vector, Block};

/// Paper 004's example A.
pub const PAPER_A: [[f64; 3]; 3] = [
    [1.005, 0.0, 0.0],
    [0.0, 0.9954, -0.08757],
    [0.0, 0.1248, 0.9945],
];

/// Value references of a `DistributedObserver` variant.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ObserverLayout {
    pub n: usize,
    pub p_own: usize,
    pub p_neighbour: usize,
    pub y_own: Block,
    /// The Boolean inputs `y_own_valid[j]` (last in the table).
    pub y_own_valid: Block,
    pub x_neighbour: Block,
    pub x_hat: Block,
    pub l: Block,
    pub n_gain: Block,
    pub n_observable: usize,
    pub a: Block,
    pub c_own: Block,
    pub c_neighbour: Block,
    pub q: Block,
    pub r_own: Block,
    pub rho: usize,
    pub lambda: usize,
    pub distance: Block,
    pub design: usize,
    pub x0: Block,
}

fn calculated(mut v: Variable) -> Variable {
    v.causality = Causality::CalculatedParameter;
    v.variability = Variability::Fixed;
    v
}

/// Unit rows e_{first}, e_{first+1}, … (indices modulo n).
fn selector(rows: usize, n: usize, first: usize) -> DMatrix<f64> {
    DMatrix::from_fn(rows, n, |i, j| if (first + i) % n == j { 1.0 } else { 0.0 })
}

fn interface(config: &Config) -> Result<(ObserverLayout, ModelInfo), Cause> {
    let n = count(config, "n", 3, 1)?;
    let p_own = count(config, "p_own", 1, 1)?;
    let p_neighbour = count(config, "p_neighbour", 1, 1)?;
    let agent = count(config, "agent", 1, 1)?;
    if agent > 2 {
        return Err(format!("variant.cfg: `agent` must be 1 or 2, got {agent}").into());
    }
    let (c_own_default, c_neighbour_default) = if agent == 1 {
        (selector(p_own, n, 0), selector(p_neighbour, n, p_own))
    } else {
        (selector(p_own, n, p_neighbour), selector(p_neighbour, n, 0))
    };
    let a_default = if n == 3 {
        DMatrix::from_fn(3, 3, |i, j| PAPER_A[i][j])
    } else {
        leading_identity(n, n)
    };
    let mut t = VariableTable::new();
    let y_own = add_vector(&mut t, "y_own", p_own, |name, _| {
        Variable::input(name, 0.0).describe("This agent's measurement y_i(k) = C_own x(k) + n_i")
    });
    let x_neighbour = add_vector(&mut t, "x_neighbour", n, |name, _| {
        Variable::input(name, 0.0)
            .describe("The neighbour's estimate x̂_j(k) (connect to its x_hat)")
    });
    let x_hat = add_vector(&mut t, "x_hat", n, |name, _| {
        Variable::discrete_output(name)
            .describe("This agent's estimate x̂_i (after the step with y(k): of x(k+1))")
    });
    let l = add_matrix(&mut t, "L", n, p_own, |name, _, _| {
        calculated(Variable::output(name))
            .describe("Local gain L_i in the basis V_i (rows beyond n_observable are 0)")
    });
    let n_gain = add_matrix(&mut t, "N", n, n, |name, _, _| {
        calculated(Variable::output(name))
            .describe("Consensus gain N_ij in the basis V̄_i (n_ō×n_ō, padded with 0)")
    });
    let mut n_observable_var = calculated(Variable::integer_parameter("n_observable", 0))
        .describe("n_o: dimension of the subspace this agent observes");
    n_observable_var.initial = Some(spurio_export::Initial::Calculated);
    let n_observable = t.add(n_observable_var);
    let a = add_matrix(&mut t, "A", n, n, |name, i, j| {
        Variable::parameter(name, a_default[(i, j)]).describe("State matrix A (x⁺ = A x + w)")
    });
    let c_own = add_matrix(&mut t, "C_own", p_own, n, |name, i, j| {
        Variable::parameter(name, c_own_default[(i, j)]).describe("This agent's output matrix C_i")
    });
    let c_neighbour = add_matrix(&mut t, "C_neighbour", p_neighbour, n, |name, i, j| {
        Variable::parameter(name, c_neighbour_default[(i, j)])
            .describe("The neighbour's output matrix C_j (checks joint observability)")
    });
    let q = add_matrix(&mut t, "Q", n, n, |name, i, j| {
        Variable::parameter(name, if i == j { 0.2 } else { 0.0 })
            .describe("Process noise covariance Q (symmetric positive semidefinite)")
    });
    let r_own = add_matrix(&mut t, "R_own", p_own, p_own, |name, i, j| {
        Variable::parameter(name, if i == j { 0.1 } else { 0.0 })
            .describe("This agent's measurement noise covariance R_i (symmetric positive definite)")
    });
    let rho = add_tuning(&mut t, "rho", 1.0, "ρ in U = ρ Q (> 0; only ρ/λ matters)");
    let lambda = add_tuning(&mut t, "lambda", 1.0, "λ in S = λ C̃ᵀRC̃ and T = λ(…) (> 0)");
    let distance = add_vector(&mut t, "D", n, |name, _| {
        Variable::parameter(name, 1.0).min(0.0).describe(
            "Distance to the neighbour (diagonal of D_i, > 0); the first n_ō entries are used",
        )
    });
    let design = add_choice(
        &mut t,
        "design",
        1,
        2,
        "Design of L_i: 1 = paper's LQ (least squares), 2 = local steady-state Kalman",
    );
    let x0 = add_vector(&mut t, "x0", n, |name, _| {
        Variable::parameter(name, 0.0).describe("Initial estimate x̂_i(0)")
    });
    let y_own_valid = add_validity(&mut t, "y_own", p_own);
    let info = ModelInfo::new(
        "DistributedObserver",
        "One agent of the two-agent LQ-designed distributed state observer of paper 004",
        t.into_variables(),
        Some(DefaultExperiment {
            start_time: 0.0,
            stop_time: 100.0,
            step_size: 1.0,
        }),
        config.clone(),
    );
    Ok((
        ObserverLayout {
            n,
            p_own,
            p_neighbour,
            y_own,
            y_own_valid,
            x_neighbour,
            x_hat,
            l,
            n_gain,
            n_observable,
            a,
            c_own,
            c_neighbour,
            q,
            r_own,
            rho,
            lambda,
            distance,
            design,
            x0,
        },
        info,
    ))
}

/// One agent and its input buffers.
#[derive(Debug, Clone)]
pub struct Agent {
    observer: DistributedObserver,
    y_own: DVector<f64>,
    x_neighbour: DVector<f64>,
}

fn observer_error(e: spurio::estimation::EstimationError) -> Failure {
    Failure::error(
        e.to_string()
            .replace("parameter `distance`", "parameter `D` (distance)"),
    )
}

impl Estimator for Agent {
    type Layout = ObserverLayout;

    fn interface(config: &Config) -> Result<(ObserverLayout, ModelInfo), Cause> {
        interface(config)
    }

    fn build(l: &ObserverLayout, values: &Values) -> Result<Self, Failure> {
        let design = match choice(
            values,
            l.design,
            "design",
            &[(1, "LQ"), (2, "local Kalman")],
        )? {
            1 => ObserverDesign::LqDesign,
            _ => ObserverDesign::LocalKalman,
        };
        let mut config = DistributedObserverConfig::new(
            l.a.matrix(values),
            l.c_own.matrix(values),
            l.c_neighbour.matrix(values),
            l.q.matrix(values),
            l.r_own.matrix(values),
        );
        config.rho = values.real(l.rho);
        config.lambda = values.real(l.lambda);
        config.design = design;
        config.x0 = l.x0.vector(values);
        // n_ō is known after the split: build once to learn it, then with the distances.
        let probe = DistributedObserver::new(config.clone()).map_err(observer_error)?;
        let n_unobservable = probe.unobservable_basis().ncols();
        let distance = l.distance.vector(values);
        let used = distance
            .rows(0, n_unobservable.min(distance.len()))
            .into_owned();
        let observer = if used.iter().all(|d| *d == 1.0) {
            probe
        } else {
            config.distance = Some(used);
            DistributedObserver::new(config).map_err(observer_error)?
        };
        Ok(Self {
            observer,
            y_own: DVector::zeros(l.p_own),
            x_neighbour: DVector::zeros(l.n),
        })
    }

    fn write_initial(&self, l: &ObserverLayout, ctx: &mut Context) {
        l.x_hat.write_vector(ctx.values, self.observer.estimate());
        for k in l.l.indices().chain(l.n_gain.indices()) {
            ctx.values.set_real(k, 0.0);
        }
        l.l.write(ctx.values, self.observer.local_gain());
        l.n_gain.write(ctx.values, self.observer.consensus_gain());
        ctx.values.set(
            l.n_observable,
            Value::Integer(self.observer.observable_basis().ncols() as i32),
        );
    }

    fn step(
        &mut self,
        l: &ObserverLayout,
        ctx: &mut Context,
        _: f64,
        _: f64,
    ) -> Result<(), Failure> {
        read_inputs(ctx.values, &l.y_own, "y_own", &mut self.y_own)?;
        mark_missing(ctx.values, &l.y_own_valid, &mut self.y_own);
        read_inputs(
            ctx.values,
            &l.x_neighbour,
            "x_neighbour",
            &mut self.x_neighbour,
        )?;
        self.observer
            .step(&self.y_own, &self.x_neighbour)
            .map_err(error)?;
        l.x_hat.write_vector(ctx.values, self.observer.estimate());
        Ok(())
    }
}

/// The agent's dynamic state is its observer's.
impl DynamicState for Agent {
    fn dynamic_state(&self) -> Vec<f64> {
        self.observer.dynamic_state()
    }
    fn set_dynamic_state(&mut self, state: &[f64]) -> Result<(), EstimationError> {
        self.observer.set_dynamic_state(state)
    }
}

/// `DistributedObserver.fmu`.
pub type DistributedObserverFmu = spurio_fmu_common::estimator::EstimatorFmu<Agent>;

/// The configuration of agent `agent` (1 or 2) of the paper's example (n = 3, one output each).
pub fn agent_config(agent: usize) -> Config {
    let mut c = Config::new();
    c.set("n", 3);
    c.set("p_own", 1);
    c.set("p_neighbour", 1);
    c.set("agent", agent);
    c
}

spurio_export::export_fmu!(
    DistributedObserverFmu,
    variants = [
        ("DistributedObserverAgent1", agent_config(1)),
        ("DistributedObserverAgent2", agent_config(2)),
    ]
);

#[cfg(test)]
mod tests {
    use super::*;
    use spurio_export::harness::Harness;
    use spurio_export::FmuModel;

    /// `y_own_valid[1]` = false: no output injection. The step with the own measurement
    /// missing equals the step given the agent's own prediction C x̂ as its measurement (an
    /// innovation of 0), whatever `y_own` holds meanwhile.
    #[test]
    fn a_missing_own_sample_drops_the_injection() {
        let config = agent_config(1);
        let info = DistributedObserverFmu::describe(&config).unwrap();
        let vr = |n: &str| info.index_of(n).unwrap() as u32;
        let x_hat = ["x_hat[1]", "x_hat[2]", "x_hat[3]"].map(vr);
        let neighbour = ["x_neighbour[1]", "x_neighbour[2]", "x_neighbour[3]"].map(vr);
        let mut estimates = Vec::new();
        for missing in [false, true] {
            let mut h = Harness::<DistributedObserverFmu>::new(&config).unwrap();
            h.initialize(0.0).unwrap();
            h.set_real(&neighbour, &[0.2, -0.1, 0.05]).unwrap();
            h.set_real(&[vr("y_own[1]")], &[1.0]).unwrap();
            h.do_step(0.0, 1.0).unwrap();
            let mut x = [0.0; 3];
            h.get_real(&x_hat, &mut x).unwrap();
            // agent 1 measures the first state (C_own = [1 0 0])
            let y = if missing { 1e6 } else { x[0] };
            h.set_real(&[vr("y_own[1]")], &[y]).unwrap();
            h.set_boolean(&[vr("y_own_valid[1]")], &[!missing]).unwrap();
            h.do_step(1.0, 1.0).unwrap();
            h.get_real(&x_hat, &mut x).unwrap();
            assert!(x.iter().all(|v| v.is_finite()));
            estimates.push(x);
        }
        assert_eq!(estimates[0], estimates[1]);
    }

    #[test]
    fn paper_gains_and_unobservable_design_error() {
        // docs/reference-values.md §6: agent 1 L₁ = 0.73628, N₁₂ = [[0.35345, 0.05317], [−0.02291, 0.36055]].
        let config = agent_config(1);
        let info = DistributedObserverFmu::describe(&config).unwrap();
        let vr = |n: &str| info.index_of(n).unwrap() as u32;
        let mut h = Harness::<DistributedObserverFmu>::new(&config).unwrap();
        h.initialize(0.0).unwrap();
        let mut g = [0.0; 5];
        h.get_real(
            &[
                vr("L[1,1]"),
                vr("N[1,1]"),
                vr("N[1,2]"),
                vr("N[2,1]"),
                vr("N[2,2]"),
            ],
            &mut g,
        )
        .unwrap();
        let expect = [0.73628, 0.35345, 0.05317, -0.02291, 0.36055];
        for (got, want) in g.iter().zip(expect) {
            assert!((got - want).abs() < 1e-4, "{g:?}");
        }

        let mut bad = Harness::<DistributedObserverFmu>::new(&config).unwrap();
        // The neighbour measures the same state: x₂, x₃ are seen by nobody.
        bad.set_real(
            &[vr("C_neighbour[1,1]"), vr("C_neighbour[1,2]")],
            &[1.0, 0.0],
        )
        .unwrap();
        assert!(bad.initialize(0.0).is_err());
        assert!(bad.logged(&["do not observe"]), "{:?}", bad.log());
    }
}
