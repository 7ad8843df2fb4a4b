//! The linear-Gaussian model every Kalman-family FMU is built on (docs/estimators.md §2.7–§2.10):
//! its dimensions `n`, `m`, `p` (configuration keys), the parameter blocks of
//! x⁺ = A x + B u + w, y = C x + D u + v (Cov w = Q, Cov v = R) with the initial estimate x0
//! and its covariance P0, the inputs `u[i]`, `y[j]`, the estimates `x_hat[i]`, `y_hat[j]`, and
//! the robust filters' influence function ψ (`psi`, `c`).

use spurio::estimation::{GaussianModel, InfluenceFunction};
use spurio::state_space::StateSpace;
use spurio_export::{
    Cause, Config, DefaultExperiment, Failure, ModelInfo, Values, Variable, VariableTable,
};
use spurio_fmu_common::estimator::{add_choice, add_tuning, count, leading_identity};
use spurio_fmu_common::structured::{add_matrix, add_vector, Block};

/// Dimensions of a linear-Gaussian estimator variant.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Dimensions {
    /// States.
    pub n: usize,
    /// Inputs (may be 0).
    pub m: usize,
    /// Outputs.
    pub p: usize,
}

impl Dimensions {
    /// Reads `n`, `m`, `p` from the configuration (defaults as given).
    pub fn from_config(config: &Config, n: usize, m: usize, p: usize) -> Result<Self, Cause> {
        Ok(Self {
            n: count(config, "n", n, 1)?,
            m: count(config, "m", m, 0)?,
            p: count(config, "p", p, 1)?,
        })
    }
}

/// Default diagonal values of the model parameters.
#[derive(Debug, Clone, Copy)]
pub struct Defaults {
    pub q: f64,
    pub r: f64,
    pub p0: f64,
}

/// The parameter blocks A, B, C, D, Q, R, P0, x0.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ModelBlocks {
    pub system: StateSpace<Block>,
    pub p0: Block,
    pub x0: Block,
}

impl ModelBlocks {
    /// Adds the parameters, named as in the model `x⁺ = A x + B u, y = C x + D u` (prefix
    /// `what` in the descriptions, e.g. "initial " for the DKF).
    pub fn add(
        table: &mut VariableTable,
        dims: Dimensions,
        defaults: Defaults,
        what: &str,
    ) -> Self {
        let Dimensions { n, m, p } = dims;
        let diag = |value: f64| move |i: usize, j: usize| if i == j { value } else { 0.0 };
        let a_default = diag(1.0);
        let c_default = leading_identity(p, n);
        let q_default = diag(defaults.q);
        let r_default = diag(defaults.r);
        let p0_default = diag(defaults.p0);
        let system = StateSpace {
            a: add_matrix(table, "A", n, n, |name, i, j| {
                Variable::parameter(name, a_default(i, j))
                    .describe(&format!("{what}state matrix A (x⁺ = A x + B u + w)"))
            }),
            b: add_matrix(table, "B", n, m, |name, _, _| {
                Variable::parameter(name, 0.0).describe(&format!("{what}input matrix B"))
            }),
            c: add_matrix(table, "C", p, n, |name, i, j| {
                Variable::parameter(name, c_default[(i, j)])
                    .describe(&format!("{what}output matrix C (y = C x + D u + v)"))
            }),
            d: add_matrix(table, "D", p, m, |name, _, _| {
                Variable::parameter(name, 0.0).describe(&format!("{what}feedthrough matrix D"))
            }),
            q: add_matrix(table, "Q", n, n, |name, i, j| {
                Variable::parameter(name, q_default(i, j))
                    .describe("Process noise covariance Q (symmetric positive semidefinite)")
            }),
            r: add_matrix(table, "R", p, p, |name, i, j| {
                Variable::parameter(name, r_default(i, j))
                    .describe("Measurement noise covariance R (symmetric positive definite)")
            }),
        };
        Self {
            system,
            p0: add_matrix(table, "P0", n, n, |name, i, j| {
                Variable::parameter(name, p0_default(i, j))
                    .describe("Covariance of x0 (symmetric positive semidefinite; 0 = x0 is exact)")
            }),
            x0: add_vector(table, "x0", n, |name, _| {
                Variable::parameter(name, 0.0)
                    .describe("Initial state estimate (one sample before the first step)")
            }),
        }
    }

    /// Reads the matrices.
    pub fn read(&self, values: &Values) -> GaussianModel {
        GaussianModel {
            system: self.system.map(|block| block.matrix(values)),
            p0: self.p0.matrix(values),
            x0: self.x0.vector(values),
        }
    }
}

/// Adds the inputs `u[i]`, `y[j]`.
pub fn add_inputs(table: &mut VariableTable, dims: Dimensions, y_what: &str) -> (Block, Block) {
    let u = add_vector(table, "u", dims.m, |name, _| {
        Variable::input(name, 0.0).describe("Control input u_k (sampled at the start of the step)")
    });
    let y = add_vector(table, "y", dims.p, |name, _| {
        Variable::input(name, 0.0).describe(y_what)
    });
    (u, y)
}

/// Adds `x_hat[i]` and `y_hat[j]`.
pub fn add_estimates(table: &mut VariableTable, dims: Dimensions) -> (Block, Block) {
    let x_hat = add_vector(table, "x_hat", dims.n, |name, _| {
        Variable::discrete_output(name).describe("Filtered state x̂_{k|k}")
    });
    let y_hat = add_vector(table, "y_hat", dims.p, |name, _| {
        Variable::discrete_output(name).describe("Filtered output ŷ_k = C x̂_{k|k} + D u_k")
    });
    (x_hat, y_hat)
}

/// Adds `psi` and `c` (rsKF): returns their value references.
pub fn add_influence(table: &mut VariableTable) -> (usize, usize) {
    let psi = add_choice(
        table,
        "psi",
        1,
        2,
        "Influence function ψ: 1 = Huber, 2 = Tukey bisquare",
    );
    let c = add_tuning(table, "c", 1.645, "Tuning constant of ψ in standard deviations (Huber 1.645 = 5 % contamination; Tukey usually 4.685)");
    (psi, c)
}

/// Reads ψ from the `psi` and `c` parameters.
pub fn read_influence(
    values: &Values,
    (psi, c): (usize, usize),
) -> Result<InfluenceFunction, Failure> {
    let kind = spurio_fmu_common::estimator::choice(
        values,
        psi,
        "psi",
        &[(1, "Huber"), (2, "Tukey bisquare")],
    )?;
    let c = values.real(c);
    if !(c.is_finite() && c > 0.0) {
        return Err(Failure::error(format!(
            "parameter `c`: the tuning constant of ψ must be finite and > 0, got {c}"
        )));
    }
    Ok(if kind == 1 {
        InfluenceFunction::Huber { c }
    } else {
        InfluenceFunction::Tukey { c }
    })
}

/// The model description of a variant: its identifier and description, the variables of
/// `table`, and its default experiment from 0 to `stop_time` s in communication steps of
/// `step_size` s.
pub fn model_info(
    config: &Config,
    (id, description): (&str, &str),
    table: VariableTable,
    stop_time: f64,
    step_size: f64,
) -> ModelInfo {
    ModelInfo::new(
        id,
        description,
        table.into_variables(),
        Some(DefaultExperiment {
            start_time: 0.0,
            stop_time,
            step_size,
        }),
        config.clone(),
    )
}

/// The configuration of a variant of dimensions n, m, p.
pub fn dims_config(n: usize, m: usize, p: usize) -> Config {
    let mut c = Config::new();
    c.set("n", n);
    c.set("m", m);
    c.set("p", p);
    c
}
