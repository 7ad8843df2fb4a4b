//! One agent of the two-agent distributed observer of paper 004 (del Nozal, Orihuela,
//! Millán, Ierardi & Tapia, "Diseño LQ e implementación distribuida para la estimación de
//! estado", Jornadas de Automática 2017), docs/estimators.md §2.12.
//!
//! Plant x⁺ = A x + w, agent i measures y_i = C_i x + n_i (Cov w = Q, Cov n_i = R_i).
//!
//! **Split (004 §2).** An orthogonal T_i = [V̄_i V_i]ᵀ: V_i (n×n_o) an orthonormal basis of
//! the subspace agent i observes — the row space of its observability matrix
//! O_i = [C_i; C_i A; …; C_i A^{n−1}], rank taken from the SVD with a relative tolerance —
//! and V̄_i (n×n_ō) one of its orthogonal complement (the unobservable subspace). Each basis
//! is made canonical (pivoted Gram–Schmidt on the orthogonal projector, so a coordinate
//! subspace gets unit vectors, in decreasing index order as Matlab's `obsvf` staircase
//! form gives them). The gains L_i, N_ij are expressed in these bases; the observer only
//! uses V L and V̄ N V̄ᵀ, which do not depend on the choice. In these coordinates A_i^o = V_iᵀ A V_i,
//! A_i^ō = V̄_iᵀ A V̄_i, C̃_i = C_i V_i.
//!
//! **Observer (004 eq. 6).**
//! x̂_i⁺ = A x̂_i + V_i L_i (y_i − C_i x̂_i) + V̄_i N_ij V̄_iᵀ (x̂_j − x̂_i).
//!
//! **LQ design (004 §4.1–4.2, eqs 7–17).** The observable error ε^o⁺ = A^o ε^o + u_L with
//! u_L = −L C̃ ε^o and the unobservable error ε^ō⁺ = A^ō ε^ō + u_N with u_N = −N ε^ō are two
//! LQ problems with input matrix I:
//!
//! ```text
//! P_L = A^oᵀ P_L A^o − A^oᵀ P_L (S + P_L)⁻¹ P_L A^o + V ᵀU V,   K_L = (S + P_L)⁻¹ P_L A^o
//! P_N = A^ōᵀ P_N A^ō − A^ōᵀ P_N (T + P_N)⁻¹ P_N A^ō + V̄ᵀU V̄,   N_ij = (T + P_N)⁻¹ P_N A^ō
//! U = ρ Q,  S = λ C̃ᵀ R_i C̃,  T = λ (V̄ᵀ C_iᵀ R_i C_i V̄ + D_i)
//! ```
//!
//! and L_i solves L_i C̃_i = K_L — in the least-squares sense, L = K_L C̃ᵀ(C̃ C̃ᵀ)⁻¹, since
//! K_L (n_o×n_o) need not factor through C̃ (p×n_o). When S is singular (agent 2 of the
//! example: one output, two observable states) L C̃ cannot reproduce K_L and the local error
//! dynamics A^o − L C̃ keep a slow mode (0.9935 in the example, docs/experiments.md §4). With S positive
//! definite the Riccati equations are solved by [`crate::linalg::Dare::regulator`] (B = I); with S only
//! semidefinite by the value iteration P ← A^oᵀ P (S + P)⁻¹ S A^o + VᵀUV from P = VᵀUV
//! (P − P(S+P)⁻¹P = P(S+P)⁻¹S), which converges to the stabilising solution.
//!
//! **Local Kalman design** ([`ObserverDesign::LocalKalman`]): L_i = A^o K_f, the one-step
//! predictor gain of the steady-state Kalman filter of (A^o, C̃, VᵀQV, R_i), from
//! [`crate::linalg::kalman_gain_steady`]; N_ij from the LQ problem as above. It does far
//! better than the literal LQ design when S is singular.
//!
//! The agents together must observe the whole state: (A, [C_i; C_j]) observable, else the
//! constructor returns an error saying so.

use super::{
    parameter_error, require_input_length, require_length, require_psd, require_shape, require_spd,
    EstimationError, StateReader,
};
use crate::linalg::{cholesky_solve, is_positive_definite, kalman_gain_steady, symmetrize, Dare};
use crate::state_space::StateSpace;
use crate::ParameterError;
use nalgebra::{DMatrix, DVector, SVD};

/// The agent's name of a plant matrix: its output matrix and measurement noise are its own.
fn agent_parameter(name: &str) -> &str {
    match name {
        "C" => "C_own",
        "R" => "R_own",
        other => other,
    }
}

/// How L_i is designed (N_ij always comes from the paper's LQ problem).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum ObserverDesign {
    /// The paper's LQ design with L_i the least-squares solution of L_i C̃_i = K_L.
    #[default]
    LqDesign,
    /// L_i = A^o K_f, the steady-state Kalman predictor gain of the observable part.
    LocalKalman,
}

/// Everything one agent needs; [`DistributedObserverConfig::new`] sets ρ = λ = 1, D = I,
/// the LQ design, x̂₀ = 0 and a rank tolerance of 1e-9.
#[derive(Debug, Clone)]
pub struct DistributedObserverConfig {
    /// The plant as this agent sees it: A (n×n), its own output matrix C_i (p_i×n), the
    /// process noise covariance Q (n×n, symmetric PSD) and its own measurement noise
    /// covariance R_i (p_i×p_i, SPD); no input (B n×0, D p_i×0).
    pub plant: StateSpace,
    /// The neighbour's output matrix C_j (p_j×n), used to check joint observability.
    pub c_neighbour: DMatrix<f64>,
    /// ρ in U = ρ Q (> 0).
    pub rho: f64,
    /// λ in S = λ C̃ᵀRC̃ and T = λ(…) (> 0).
    pub lambda: f64,
    /// Diagonal of D_i (distance to the neighbour per unobservable direction, > 0); `None`
    /// means all ones. Its length must be n_ō, known after the split.
    pub distance: Option<DVector<f64>>,
    /// How L_i is designed.
    pub design: ObserverDesign,
    /// Initial estimate x̂_i,0.
    pub x0: DVector<f64>,
    /// Relative singular-value tolerance for the rank of the observability matrices.
    pub rank_tolerance: f64,
}

impl DistributedObserverConfig {
    /// A configuration with the paper's defaults (ρ = λ = 1, D = I, LQ design, x̂₀ = 0).
    pub fn new(
        a: DMatrix<f64>,
        c_own: DMatrix<f64>,
        c_neighbour: DMatrix<f64>,
        q: DMatrix<f64>,
        r_own: DMatrix<f64>,
    ) -> Self {
        let n = a.nrows();
        Self {
            plant: StateSpace::without_input(a, c_own, q, r_own),
            c_neighbour,
            rho: 1.0,
            lambda: 1.0,
            distance: None,
            design: ObserverDesign::LqDesign,
            x0: DVector::zeros(n),
            rank_tolerance: 1e-9,
        }
    }
}

/// One agent of the two-agent distributed observer (see the module documentation).
#[derive(Debug, Clone)]
pub struct DistributedObserver {
    a: DMatrix<f64>,
    c: DMatrix<f64>,
    observable_basis: DMatrix<f64>,
    unobservable_basis: DMatrix<f64>,
    local_gain: DMatrix<f64>,
    consensus_gain: DMatrix<f64>,
    lq_local_gain: DMatrix<f64>,
    /// V L (n×p).
    injection: DMatrix<f64>,
    /// V̄ N V̄ᵀ (n×n).
    consensus: DMatrix<f64>,
    x: DVector<f64>,
    next: DVector<f64>,
    innovation: DVector<f64>,
    difference: DVector<f64>,
    design: ObserverDesign,
    steps: u64,
}

const LQ_WHAT: &str = "distributed observer gains";

fn design_error(reason: impl Into<String>) -> EstimationError {
    EstimationError::Design {
        what: LQ_WHAT,
        reason: reason.into(),
    }
}

/// Observability matrix [C; C A; …; C A^{n−1}].
fn observability_matrix(a: &DMatrix<f64>, c: &DMatrix<f64>) -> DMatrix<f64> {
    let n = a.nrows();
    let p = c.nrows();
    let mut o = DMatrix::zeros(n * p, n);
    let mut block = c.clone();
    for k in 0..n {
        o.view_mut((k * p, 0), (p, n)).copy_from(&block);
        block = &block * a;
    }
    o
}

/// The most steps of the Riccati value iteration of [`lq_identity_input`].
const VALUE_ITERATION_MAX: usize = 10_000;

/// The most sweeps of the SVD iteration (nalgebra's default is unbounded): an SVD of these
/// sizes converges in tens; one that does not is reported, not waited for.
const SVD_MAX_ITERATIONS: usize = 10_000;

/// Orthogonal projector onto the row space of `m` and its rank (relative tolerance), for the
/// observability matrix of `what`. Errors when `m` is not finite (A^k overflowed: the
/// parameters are too large) or its SVD does not converge within [`SVD_MAX_ITERATIONS`].
fn row_space_projector(
    m: &DMatrix<f64>,
    tolerance: f64,
    what: &str,
) -> Result<(DMatrix<f64>, usize), EstimationError> {
    let n = m.ncols();
    let mut projector = DMatrix::zeros(n, n);
    if !m.iter().all(|v| v.is_finite()) {
        return Err(design_error(format!(
            "the observability matrix of {what} overflows (entries of A or C too large: A^k is not finite)"
        )));
    }
    if m.nrows() == 0 || m.amax() == 0.0 {
        return Ok((projector, 0));
    }
    let svd = SVD::try_new(m.clone(), false, true, f64::EPSILON, SVD_MAX_ITERATIONS)
        .filter(|svd| svd.singular_values.iter().all(|s| s.is_finite()))
        .ok_or_else(|| {
            design_error(format!(
                "the SVD of the observability matrix of {what} did not converge in {SVD_MAX_ITERATIONS} iterations (badly scaled A or C?)"
            ))
        })?;
    let largest = svd.singular_values.max();
    let mut rank = 0;
    if let Some(v_t) = &svd.v_t {
        for (i, sigma) in svd.singular_values.iter().enumerate() {
            if *sigma > tolerance * largest {
                let v = v_t.row(i).transpose();
                projector.ger(1.0, &v, &v, 1.0);
                rank += 1;
            }
        }
    }
    Ok((projector, rank))
}

/// An orthonormal basis (n×dim) of the range of the orthogonal projector `projector`,
/// canonical: the unit vectors e_j chosen by pivoting (largest projection first), then
/// Gram–Schmidt on P e_j in *decreasing* j. A coordinate subspace gets its unit vectors,
/// last coordinate first — the order of the staircase form of Matlab's `obsvf`, which the
/// paper's numbers use (docs/reference-values.md §6: N₁₂ with V̄₁ = [e₃ e₂]).
fn canonical_basis(projector: &DMatrix<f64>, dim: usize) -> DMatrix<f64> {
    let n = projector.nrows();
    let mut residual = projector.clone();
    let mut chosen = Vec::with_capacity(dim);
    for _ in 0..dim {
        let norms: Vec<f64> = (0..n).map(|j| residual.column(j).norm()).collect();
        let largest = norms.iter().copied().fold(0.0, f64::max);
        let Some(pick) =
            (0..n).find(|&j| !chosen.contains(&j) && norms[j] >= largest * (1.0 - 1e-9))
        else {
            break;
        };
        chosen.push(pick);
        let q = residual.column(pick) / norms[pick];
        let projections = q.transpose() * &residual;
        residual.ger(-1.0, &q, &projections.transpose(), 1.0);
    }
    chosen.sort_unstable_by(|a, b| b.cmp(a));
    let mut basis = DMatrix::zeros(n, chosen.len());
    for (k, &j) in chosen.iter().enumerate() {
        let mut v = projector.column(j).into_owned();
        for _ in 0..2 {
            for previous in 0..k {
                let b = basis.column(previous).into_owned();
                let dot = b.dot(&v);
                v.axpy(-dot, &b, 1.0);
            }
        }
        let norm = v.norm();
        basis.set_column(k, &(v / norm));
    }
    basis
}

/// LQ problem with input matrix I: ε⁺ = A ε + u, cost Σ εᵀUε + uᵀWu, W symmetric PSD.
/// Returns (K, P) with K = (W + P)⁻¹ P A.
fn lq_identity_input(
    a: &DMatrix<f64>,
    u: &DMatrix<f64>,
    w: &DMatrix<f64>,
    what: &str,
) -> Result<(DMatrix<f64>, DMatrix<f64>), EstimationError> {
    let n = a.nrows();
    if n == 0 {
        return Ok((DMatrix::zeros(0, 0), DMatrix::zeros(0, 0)));
    }
    let identity = DMatrix::identity(n, n);
    if is_positive_definite(w) {
        let dare = Dare {
            a,
            b: &identity,
            q: u,
            r: w,
        };
        return dare
            .regulator()
            .map_err(|e| design_error(format!("{what} Riccati equation: {e}")));
    }
    // Singular weight: value iteration P ← Aᵀ P (W + P)⁻¹ W A + U (the paper's example
    // converges in about a dozen iterations; the bound keeps fmi2ExitInitializationMode
    // within about 0.1 s when it does not).
    let mut p = u.clone();
    let scale = u.amax().max(1.0);
    for _ in 0..VALUE_ITERATION_MAX {
        let sum = w + &p;
        let gain_w = cholesky_solve(&sum, &(w * a), "W + P")
            .map_err(|e| design_error(format!("{what} Riccati iteration: {e}")))?;
        let mut next = a.transpose() * &p * gain_w + u;
        symmetrize(&mut next);
        let change = (&next - &p).amax();
        p = next;
        if !p.iter().all(|v| v.is_finite()) {
            return Err(design_error(format!(
                "{what} Riccati iteration diverged (is the LQ problem stabilisable?)"
            )));
        }
        if change <= 1e-14 * scale {
            let gain = cholesky_solve(&(w + &p), &(&p * a), "W + P")
                .map_err(|e| design_error(format!("{what} gain: {e}")))?;
            return Ok((gain, p));
        }
    }
    Err(design_error(format!(
        "{what} Riccati iteration did not converge in {VALUE_ITERATION_MAX} steps"
    )))
}

impl DistributedObserver {
    /// Validates the configuration (parameter names "A", "C_own", "C_neighbour", "Q", "R_own",
    /// "rho", "lambda", "distance", "x0", "rank_tolerance"), splits the state space and designs
    /// L_i and N_ij. Errors when the agents cannot observe the state jointly or a Riccati
    /// equation has no stabilising solution.
    pub fn new(config: DistributedObserverConfig) -> Result<Self, EstimationError> {
        let DistributedObserverConfig {
            plant,
            c_neighbour,
            rho,
            lambda,
            distance,
            design,
            x0,
            rank_tolerance,
        } = config;
        plant.check_dimensions().map_err(|error| {
            ParameterError::new(agent_parameter(&error.parameter), error.reason)
        })?;
        if plant.inputs() != 0 {
            return Err(parameter_error(
                "B",
                "the observer takes no input: must be n×0",
            ));
        }
        let (n, p) = (plant.states(), plant.outputs());
        require_shape(
            "C_neighbour",
            &c_neighbour,
            c_neighbour.nrows(),
            n,
            "n columns, like A",
        )?;
        require_psd("Q", &plant.q, n)?;
        require_spd("R_own", &plant.r, p)?;
        let StateSpace {
            a,
            c: c_own,
            q,
            r: r_own,
            ..
        } = plant;
        crate::require_positive("rho", rho)?;
        crate::require_positive("lambda", lambda)?;
        crate::require_positive("rank_tolerance", rank_tolerance)?;
        require_length("x0", &x0, n, "one entry per state")?;

        // Joint observability (004 Assumption 1).
        let mut stacked = DMatrix::zeros(p + c_neighbour.nrows(), n);
        stacked.rows_mut(0, p).copy_from(&c_own);
        stacked
            .rows_mut(p, c_neighbour.nrows())
            .copy_from(&c_neighbour);
        let (_, joint_rank) = row_space_projector(
            &observability_matrix(&a, &stacked),
            rank_tolerance,
            "(A, [C_own; C_neighbour])",
        )?;
        if joint_rank < n {
            return Err(design_error(format!(
                "the agents together do not observe the state: (A, [C_own; C_neighbour]) has \
                 observability rank {joint_rank} < n = {n}"
            )));
        }

        // Split T_i = [V̄ V]ᵀ.
        let (observable_projector, n_observable) = row_space_projector(
            &observability_matrix(&a, &c_own),
            rank_tolerance,
            "(A, C_own)",
        )?;
        let unobservable_projector = DMatrix::identity(n, n) - &observable_projector;
        let v = canonical_basis(&observable_projector, n_observable);
        let v_bar = canonical_basis(&unobservable_projector, n - n_observable);
        if v.ncols() != n_observable || v_bar.ncols() != n - n_observable {
            return Err(design_error(
                "could not build orthonormal bases of the observable / unobservable subspaces",
            ));
        }
        let n_unobservable = v_bar.ncols();
        let distance = match distance {
            None => DVector::from_element(n_unobservable, 1.0),
            Some(d) => {
                require_length(
                    "distance",
                    &d,
                    n_unobservable,
                    "one entry per unobservable direction (n_ō)",
                )?;
                if let Some(bad) = d.iter().find(|v| **v <= 0.0) {
                    return Err(parameter_error(
                        "distance",
                        format!("entries must be > 0, got {bad}"),
                    ));
                }
                d
            }
        };

        let u_weight = &q * rho;
        let a_obs = v.transpose() * &a * &v;
        let a_unobs = v_bar.transpose() * &a * &v_bar;
        let c_tilde = &c_own * &v;
        let mut s_weight = c_tilde.transpose() * &r_own * &c_tilde * lambda;
        symmetrize(&mut s_weight);
        let c_bar = &c_own * &v_bar;
        let mut t_weight =
            (c_bar.transpose() * &r_own * &c_bar + DMatrix::from_diagonal(&distance)) * lambda;
        symmetrize(&mut t_weight);
        let mut u_obs = v.transpose() * &u_weight * &v;
        symmetrize(&mut u_obs);
        let mut u_unobs = v_bar.transpose() * &u_weight * &v_bar;
        symmetrize(&mut u_unobs);

        // L from the LQ gain: L C̃ = K_L in least squares, Lᵀ = (C̃ C̃ᵀ)⁻¹ C̃ K_Lᵀ.
        let lq_local_gain = if n_observable == 0 {
            DMatrix::zeros(0, p)
        } else {
            let (k_local, _) = lq_identity_input(&a_obs, &u_obs, &s_weight, "local (observable)")?;
            cholesky_solve(
                &(&c_tilde * c_tilde.transpose()),
                &(&c_tilde * k_local.transpose()),
                "C̃ C̃ᵀ",
            )
            .map_err(|e| {
                design_error(format!(
                    "the local gain needs C_own V of full row rank (redundant outputs?): {e}"
                ))
            })?
            .transpose()
        };
        let local_gain = match design {
            ObserverDesign::LqDesign => lq_local_gain.clone(),
            ObserverDesign::LocalKalman if n_observable > 0 => {
                let mut q_obs = v.transpose() * &q * &v;
                symmetrize(&mut q_obs);
                let (k_filter, _) = kalman_gain_steady(&a_obs, &c_tilde, &q_obs, &r_own)
                    .map_err(|e| design_error(format!("local Kalman gain: {e}")))?;
                &a_obs * k_filter
            }
            ObserverDesign::LocalKalman => DMatrix::zeros(0, p),
        };
        let consensus_gain = if n_unobservable == 0 {
            DMatrix::zeros(0, 0)
        } else {
            lq_identity_input(&a_unobs, &u_unobs, &t_weight, "consensus (unobservable)")?.0
        };

        let injection = &v * &local_gain;
        let consensus = &v_bar * &consensus_gain * v_bar.transpose();
        Ok(Self {
            c: c_own,
            observable_basis: v,
            unobservable_basis: v_bar,
            local_gain,
            consensus_gain,
            lq_local_gain,
            injection,
            consensus,
            next: DVector::zeros(n),
            innovation: DVector::zeros(p),
            difference: DVector::zeros(n),
            x: x0,
            a,
            design,
            steps: 0,
        })
    }

    /// One step: x̂_i ← A x̂_i + V L (y_i − C_i x̂_i) + V̄ N V̄ᵀ (x̂_j − x̂_i), with the
    /// neighbour's estimate x̂_j of the same instant. A NaN y_i,j is a missing sample: its
    /// innovation is 0, so the step is the prediction A x̂_i plus the injection of the present
    /// channels and the consensus term (the gains are fixed: there is no covariance to grow).
    /// A y_i,j = ±∞ or a non-finite x̂_j is an error.
    pub fn step(
        &mut self,
        y_own: &DVector<f64>,
        x_neighbour: &DVector<f64>,
    ) -> Result<(), EstimationError> {
        require_input_length("y_own", y_own, self.c.nrows())?;
        require_input_length("x_neighbour", x_neighbour, self.a.nrows())?;
        self.steps += 1;
        self.innovation.copy_from(y_own);
        self.innovation.gemv(-1.0, &self.c, &self.x, 1.0);
        // A missing sample (NaN) of channel j: no output injection from it, e_j = 0.
        for (e, y) in self.innovation.iter_mut().zip(y_own.iter()) {
            if y.is_nan() {
                *e = 0.0;
            }
        }
        self.difference.copy_from(x_neighbour);
        self.difference -= &self.x;
        self.next.gemv(1.0, &self.a, &self.x, 0.0);
        self.next.gemv(1.0, &self.injection, &self.innovation, 1.0);
        self.next.gemv(1.0, &self.consensus, &self.difference, 1.0);
        if self.next.iter().any(|v| !v.is_finite()) {
            return Err(EstimationError::NonFinite {
                what: "distributed observer estimate (check y_own and x_neighbour)",
                step: self.steps,
            });
        }
        std::mem::swap(&mut self.x, &mut self.next);
        Ok(())
    }

    /// Everything that evolves from step to step (the estimate, the last innovation and
    /// neighbour difference, the step count), as a flat list of numbers for FMU state
    /// serialization; see [`DistributedObserver::set_dynamic_state`].
    pub fn dynamic_state(&self) -> Vec<f64> {
        let mut out = Vec::new();
        out.extend_from_slice(self.x.as_slice());
        out.extend_from_slice(self.innovation.as_slice());
        out.extend_from_slice(self.difference.as_slice());
        out.push(self.steps as f64);
        out
    }

    /// Restores what [`DistributedObserver::dynamic_state`] returned, into an observer built
    /// with the same configuration.
    pub fn set_dynamic_state(&mut self, state: &[f64]) -> Result<(), EstimationError> {
        let mut input = StateReader::new(state);
        input.fill(self.x.as_mut_slice())?;
        input.fill(self.innovation.as_mut_slice())?;
        input.fill(self.difference.as_mut_slice())?;
        self.steps = input.counter()?;
        input.finish()
    }

    /// The estimate x̂_i (a one-step prediction: after the step with y_k it estimates x_{k+1}).
    pub fn estimate(&self) -> &DVector<f64> {
        &self.x
    }
    /// L_i (n_o×p_i) in use.
    pub fn local_gain(&self) -> &DMatrix<f64> {
        &self.local_gain
    }
    /// The least-squares L of the LQ design (whatever the design in use).
    pub fn lq_local_gain(&self) -> &DMatrix<f64> {
        &self.lq_local_gain
    }
    /// N_ij (n_ō×n_ō).
    pub fn consensus_gain(&self) -> &DMatrix<f64> {
        &self.consensus_gain
    }
    /// V_i: orthonormal basis of the observable subspace (n×n_o).
    pub fn observable_basis(&self) -> &DMatrix<f64> {
        &self.observable_basis
    }
    /// V̄_i: orthonormal basis of the unobservable subspace (n×n_ō).
    pub fn unobservable_basis(&self) -> &DMatrix<f64> {
        &self.unobservable_basis
    }
    /// T_i = [V̄_i V_i]ᵀ (n×n, orthogonal).
    pub fn transformation(&self) -> DMatrix<f64> {
        let n = self.a.nrows();
        let n_unobservable = self.unobservable_basis.ncols();
        let mut t_transposed = DMatrix::zeros(n, n);
        t_transposed
            .columns_mut(0, n_unobservable)
            .copy_from(&self.unobservable_basis);
        t_transposed
            .columns_mut(n_unobservable, n - n_unobservable)
            .copy_from(&self.observable_basis);
        t_transposed.transpose()
    }
    /// Local error dynamics A^o − L C̃ of the observable part.
    pub fn local_error_dynamics(&self) -> DMatrix<f64> {
        let v = &self.observable_basis;
        v.transpose() * &self.a * v - &self.local_gain * &self.c * v
    }
    /// Design in use.
    pub fn design(&self) -> ObserverDesign {
        self.design
    }
    /// Number of steps processed.
    pub fn steps(&self) -> u64 {
        self.steps
    }
}

#[cfg(test)]
mod tests {
    use super::super::robust::test_rng::{mean_std, TestRng};
    use super::super::{GaussianModel, KalmanFilter};
    use super::*;
    use crate::linalg::spectral_radius;
    use crate::state_space::StateSpace;

    fn paper_a() -> DMatrix<f64> {
        DMatrix::from_row_slice(
            3,
            3,
            &[1.005, 0.0, 0.0, 0.0, 0.9954, -0.08757, 0.0, 0.1248, 0.9945],
        )
    }
    fn c1() -> DMatrix<f64> {
        DMatrix::from_row_slice(1, 3, &[1.0, 0.0, 0.0])
    }
    fn c2() -> DMatrix<f64> {
        DMatrix::from_row_slice(1, 3, &[0.0, 1.0, 0.0])
    }
    /// The configuration of the paper's agents (Q = 0.2 I, R = 0.1) for `a`, `c_own`, `c_other`.
    fn config_of(
        a: DMatrix<f64>,
        c_own: DMatrix<f64>,
        c_other: DMatrix<f64>,
    ) -> DistributedObserverConfig {
        DistributedObserverConfig::new(
            a,
            c_own,
            c_other,
            DMatrix::identity(3, 3) * 0.2,
            DMatrix::from_element(1, 1, 0.1),
        )
    }
    fn agent(
        c_own: DMatrix<f64>,
        c_other: DMatrix<f64>,
        design: ObserverDesign,
    ) -> DistributedObserver {
        let mut config = config_of(paper_a(), c_own, c_other);
        config.design = design;
        DistributedObserver::new(config).unwrap()
    }

    #[test]
    fn paper_example_reference_gains() {
        let agent1 = agent(c1(), c2(), ObserverDesign::LqDesign);
        let agent2 = agent(c2(), c1(), ObserverDesign::LqDesign);
        println!(
            "L1 = {}N12 = {}L2 = {}N21 = {}",
            agent1.local_gain(),
            agent1.consensus_gain(),
            agent2.local_gain(),
            agent2.consensus_gain()
        );
        assert_eq!(
            agent1.observable_basis(),
            &DMatrix::from_column_slice(3, 1, &[1.0, 0.0, 0.0])
        );
        assert!((agent1.local_gain()[(0, 0)] - 0.73628).abs() < 5e-6);
        let n12 = DMatrix::from_row_slice(2, 2, &[0.35345, 0.05317, -0.02291, 0.36055]);
        let e3_e2 = DMatrix::from_row_slice(3, 2, &[0.0, 0.0, 0.0, 1.0, 1.0, 0.0]);
        assert_eq!(agent1.unobservable_basis(), &e3_e2);
        assert!(
            (agent1.consensus_gain() - n12).amax() < 5e-6,
            "{}",
            agent1.consensus_gain()
        );
        assert!((agent2.consensus_gain()[(0, 0)] - 0.36258).abs() < 5e-6);
        // Agent 2: singular S, least-squares L leaves a slow mode at 0.9935 (docs/experiments.md §4).
        let slow = spectral_radius(&agent2.local_error_dynamics());
        println!("agent 2 LQ local error spectral radius = {slow:.5}");
        assert!((slow - 0.9935).abs() < 5e-4, "{slow}");
        let t = agent1.transformation();
        assert!((&t * t.transpose() - DMatrix::identity(3, 3)).amax() < 1e-12);
    }

    #[test]
    fn local_kalman_design_is_faster_for_agent_two() {
        let lq = agent(c2(), c1(), ObserverDesign::LqDesign);
        let kalman = agent(c2(), c1(), ObserverDesign::LocalKalman);
        let slow_lq = spectral_radius(&lq.local_error_dynamics());
        let slow_kalman = spectral_radius(&kalman.local_error_dynamics());
        println!("local error spectral radius: LQ {slow_lq:.4}, local Kalman {slow_kalman:.4}");
        assert!(slow_kalman < slow_lq);
    }

    #[test]
    fn joint_unobservability_is_an_error() {
        // Nobody measures x3, and it is decoupled: (A, [C1; C2]) not observable.
        let a = DMatrix::from_diagonal(&DVector::from_vec(vec![0.9, 0.8, 0.7]));
        let config = config_of(a, c1(), c2());
        let e = DistributedObserver::new(config).unwrap_err();
        println!("{e}");
        assert!(e.to_string().contains("do not observe"), "{e}");
    }

    /// e_ac = Σ_{k=1..100} Σ_i ‖x_k − x̂_{i,k}‖² for both agents, and the same score for
    /// the centralised one-step KF prediction x̂_{k|k−1} held by both agents (2 Σ_k ‖·‖²,
    /// which is how the reference 573 ± 238 of docs/experiments.md §4 compares).
    fn monte_carlo(design: ObserverDesign, seeds: u64) -> (Vec<f64>, Vec<f64>) {
        let a = paper_a();
        let mut distributed = Vec::new();
        let mut central = Vec::new();
        for seed in 0..seeds {
            let mut rng = TestRng::new(500 + seed);
            let mut agent1 = agent(c1(), c2(), design);
            let mut agent2 = agent(c2(), c1(), design);
            let c_all = DMatrix::from_row_slice(2, 3, &[1.0, 0.0, 0.0, 0.0, 1.0, 0.0]);
            // Constructed one sample before x₀ with x̂ = 0, P = I: x̂_{0|−1} = 0,
            // P_{0|−1} = A Aᵀ + Q (the initial error [1, 1, 1] has size 1 per state).
            let mut kf = KalmanFilter::new(GaussianModel {
                system: StateSpace {
                    a: a.clone(),
                    b: DMatrix::zeros(3, 0),
                    c: c_all.clone(),
                    d: DMatrix::zeros(2, 0),
                    q: DMatrix::identity(3, 3) * 0.2,
                    r: DMatrix::identity(2, 2) * 0.1,
                },
                x0: DVector::zeros(3),
                p0: DMatrix::identity(3, 3),
            })
            .unwrap();
            let none = DVector::zeros(0);
            let mut x = DVector::from_element(3, 1.0);
            let (mut e_distributed, mut e_central) = (0.0, 0.0);
            for _ in 0..100 {
                let n1 = 0.1_f64.sqrt() * rng.normal();
                let n2 = 0.1_f64.sqrt() * rng.normal();
                let y1 = DVector::from_element(1, x[0] + n1);
                let y2 = DVector::from_element(1, x[1] + n2);
                let x1 = agent1.estimate().clone();
                let x2 = agent2.estimate().clone();
                agent1.step(&y1, &x2).unwrap();
                agent2.step(&y2, &x1).unwrap();
                kf.step(&none, &DVector::from_vec(vec![y1[0], y2[0]]))
                    .unwrap();
                let central_prediction = &a * kf.state();
                let w = DVector::from_fn(3, |_, _| 0.2_f64.sqrt() * rng.normal());
                x = &a * &x + w;
                e_distributed += (&x - agent1.estimate()).norm_squared()
                    + (&x - agent2.estimate()).norm_squared();
                e_central += 2.0 * (&x - central_prediction).norm_squared();
            }
            distributed.push(e_distributed);
            central.push(e_central);
        }
        (distributed, central)
    }

    #[test]
    fn monte_carlo_accumulated_error_against_centralised_kalman() {
        let (lq, central) = monte_carlo(ObserverDesign::LqDesign, 100);
        let (local_kalman, _) = monte_carlo(ObserverDesign::LocalKalman, 100);
        let (lq_mean, lq_std) = mean_std(&lq);
        let (lk_mean, lk_std) = mean_std(&local_kalman);
        let (c_mean, c_std) = mean_std(&central);
        println!("e_ac LQ design      = {lq_mean:.0} ± {lq_std:.0} (reference 1507 ± 1287)");
        println!("e_ac local Kalman   = {lk_mean:.0} ± {lk_std:.0} (reference 695 ± 272)");
        println!("central KF predict  = {c_mean:.0} ± {c_std:.0} (reference 573 ± 238)");
        assert!(lk_mean <= 1.3 * c_mean, "{lk_mean} vs {c_mean}");
        assert!(lk_mean < lq_mean);
    }

    #[test]
    fn rejects_bad_parameters() {
        let mut config = config_of(paper_a(), c1(), c2());
        config.rho = -1.0;
        let e = DistributedObserver::new(config.clone()).unwrap_err();
        assert!(e.to_string().contains("rho"), "{e}");
        config.rho = 1.0;
        config.distance = Some(DVector::from_element(3, 1.0));
        let e = DistributedObserver::new(config).unwrap_err();
        assert!(e.to_string().contains("distance"), "{e}");
    }

    #[test]
    fn extreme_finite_parameters_fail_in_bounded_time() {
        // A[1,1] = -1e308 made the SVD of [C; C A; C A²] (with an infinite entry) loop forever
        for (i, j, v) in [(0, 0, -1e308), (1, 2, -1e308), (2, 1, 1e200), (0, 0, 1e150)] {
            let mut a = paper_a();
            a[(i, j)] = v;
            let config = config_of(a, c1(), c2());
            let start = std::time::Instant::now();
            let result = DistributedObserver::new(config);
            assert!(start.elapsed().as_secs_f64() < 1.0, "A[{i},{j}] = {v}");
            if let Err(e) = result {
                assert!(e.to_string().contains("distributed observer gains"), "{e}");
            }
        }
        let mut a = paper_a();
        a[(0, 0)] = -1e308;
        let config = config_of(a, c1(), c2());
        let e = DistributedObserver::new(config).unwrap_err();
        assert!(e.to_string().contains("observability matrix"), "{e}");
        assert!(e.to_string().contains("overflows"), "{e}");
    }
}
