//! Dual Kalman filter (DKF), docs/estimators.md §2.9–§2.10; papers 000 §VI (eqs 25–28) and 001 §2,
//! after Haykin, *Kalman Filtering and Neural Networks*, ch. 5.
//!
//! Two Kalman filters run in sequence each sample: a **state filter** that uses the current
//! model estimate, and a **parameter filter** on Θ = [A B; C D] ((n+p)×(n+m)) with the
//! random-walk model
//!
//! ```text
//! Θ_k = Θ_{k−1} + r_k,   r ~ N(0, Q_θ) (Q_θ diagonal: one variance per entry of Θ)
//! Y_k = Θ_k Φ_k + V_k,   V ~ N(0, R_θ) (R_θ diagonal, default 0.5 I)
//! Y_k = [x_{k+1}; y_k],  Φ_k = [x_k; u_k]
//! ```
//!
//! Exact sequence of one call `step(u_k, y_k)` (x̂ are the state filter's estimates):
//!
//! 1. State filter with the model Θ̂_{k−1}: x⁻ = Â x̂_{k−1} + B̂ u_{k−1}, P⁻ = Â P Âᵀ + Q,
//!    correction with y_k through Ĉ, D̂ (as [`KalmanFilter`](super::KalmanFilter)) → x̂_k.
//!    Outputs: ŷ_k = Ĉ x̂_k + D̂ u_k (filtered) and the one-step prediction Ĉ x⁻ + D̂ u_k.
//! 2. Parameter filter on the *previous* sample, the first one for which x_{k+1} is known:
//!    Φ = [x̂_{k−1}; u_{k−1}], Y = [x̂_k; y_{k−1}] (x_{k+1} ↦ x̂_k, y_k ↦ y_{k−1}). Skipped
//!    on the first call. For every row θᵢ of Θ (a scalar measurement Yᵢ = θᵢᵀΦ + Vᵢ):
//!    Σ⁻ = Σ + diag(Q_θ,i), s = Σ⁻Φ, d = Φᵀs + R_θ,i, g = s/d,
//!    θᵢ ← θᵢ + g (Yᵢ − θᵢᵀΦ), Σ = Σ⁻ − (g sᵀ + s gᵀ) + d g gᵀ (the Joseph form for a scalar
//!    measurement, = Σ⁻ − s sᵀ/d), each entry computed symmetric in i and j, so Σ stays
//!    exactly symmetric.
//!
//! Every row shares the regressor Φ and, with R_θ diagonal, the rows are independent: the
//! (rows·cols)² covariance is block diagonal, and rows with the same Q_θ row, Σ₀ row and R_θ
//! entry have the *same* (n+m)×(n+m) block. Rows are grouped at construction and each group
//! keeps one Σ, so a step costs O(groups·(n+m)² + rows·(n+m)).
//!
//! **Bounded adaptation** (docs/estimators.md §2.9, "Bounded adaptation"). Without
//! excitation the random walk only accumulates: Σ grows by Q_θ every sample in every direction
//! the data do not inform, and Θ̂ follows the noise projected on them (in the adaptive crane at
//! rest B̂[1,1] went from 0.0012 to 1.03 in 5·10⁶ samples). Two optional bounds, both off by
//! default (the papers' filter bit for bit):
//!
//! * **Excitation gate.** The windowed regressor moment
//!   M_k = λ M_{k−1} + (1 − λ) Φ Φᵀ, λ = 1 − 1/N_w (N_w: `excitation_window` samples),
//!   and its smallest eigenvalue ε_k = λ_min(M_k), the mean power of Φ in its least excited
//!   direction, measure persistent excitation. While ε_k < ε_min (`excitation_min`) the
//!   parameter filter is frozen: no Q_θ is added, Θ̂ and Σ stay those of the last excited
//!   sample. Under pure state feedback u = −L x̂ the regressor lies in a subspace (u follows
//!   x̂), ε ≈ 0 and A, B are not identifiable anyway (only A − B L is); a dither on u lifts ε.
//! * **Bounded covariance.** The random walk adds to the i-th diagonal entry of Σ at most up
//!   to σ²_max (`max_variance`): Σ⁻ = Σ + diag(q̃), q̃ᵢ = min(q_θ,i, max(0, σ²_max − Σᵢᵢ)).
//!   A non-negative diagonal keeps Σ⁻ positive semidefinite; Σ's diagonal never exceeds
//!   max(Σ₀, σ²_max) (the measurement update only shrinks it).
//!
//! **Identifying A and B** (docs/estimators.md §2.9, "Identifying A and B"; both off by
//! default). In the papers' filter the prediction error of the rows of A and B,
//! x̂_k − Â x̂_{k−1} − B̂ u_{k−1}, is the state filter's correction K e_k: the filtered states
//! follow the model they are filtered with, and regressing them on themselves returns that
//! model (the adaptive crane with a dither keeps its rows 3–4 error at 0.124). Two options:
//!
//! * **Known rows** ([`DualKalmanConfig::fix_state_rows`]): rows of [A B] fixed at their
//!   initial values. With C = [I 0] known the model is unique only up to x ↦ T x with
//!   T = [I 0; T₂₁ T₂₂]; known rows [A₁₁ A₁₂] with A₁₂ invertible leave T = I.
//! * **Output-error parameter filter** ([`ParameterMeasurement::OutputError`], the dual EKF
//!   of Haykin ch. 5): on the free entries ϑ of [A B] (C, D must be known), with the
//!   sensitivity S_k = ∂x̂_k/∂ϑ (S₀ = 0) and J(Φ) = ∂(Â x + B̂ u)/∂ϑ at Φ = [x̂_{k−1}; u_{k−1}]
//!   (column of entry (i, j): Φ_j in row i), after the state filter's correction:
//!
//!   ```text
//!   S⁻ = Â S_{k−1} + J(Φ),   H = Ĉ S⁻                        (p × nϑ)
//!   Σ⁻ = Σ + diag(q̃),  Γ = H Σ⁻ Hᵀ + Ĉ P⁻ Ĉᵀ + R,  G = Σ⁻ Hᵀ Γ⁻¹
//!   ϑ ← ϑ + G e_k   (e_k = y_k − Ĉ x⁻ − D̂ u_k, the state filter's innovation)
//!   Σ = Σ⁻ − G H Σ⁻,   S_k = (I − K Ĉ) S⁻   (K: the state filter's gain; dK/dϑ neglected)
//!   ```
//!
//!   The gate and the variance bound act as above (a frozen step still propagates S).
//!   Σ₀ and Q_θ of the free entries come from `parameter_p0`, `parameter_q`; R_θ is unused.
//!
//! Identifiability: (A, B, C, D) from output data alone is defined only up to a similarity
//! transform x ↦ T x. Fix C and D (zero Q_θ and Σ₀ on their rows, see
//! [`DualKalmanConfig::fix_output_matrices`]) or measure the states (C = I) so the truth is
//! unique; paper 000's crane measures x and θ.
//!
//! **Missing samples** (docs/estimators.md, "Missing samples"). A NaN y_j is a
//! missing sample. The state filter corrects with the present channels only (as the
//! [`KalmanFilter`](super::KalmanFilter): x̂ = x⁻, P = Â P Âᵀ + Q when every channel is
//! missing), and the predicted output Ĉ x⁻ + D̂ u_k is reported for every channel. The
//! parameter filter has no measurement when a channel of y_k (x̂_k is then, in part, the
//! model's own prediction Θ̂Φ) or of y_{k−1} (a row of Y) is missing: Θ̂ stays and Σ grows
//! by its random walk diag(q̃) only (bounded by σ²_max; the excitation gate still freezes
//! it). The output-error filter likewise skips its update when a channel of y_k is missing.
//!
//! [`DkfRsKf`] is the papers' combination (001 Fig. 2): an rsKF cleans the measured outputs
//! and the DKF identifies from the cleaned outputs and the inputs.

use super::kalman::{FilterCore, GaussianModel};
use super::missing::MissingMask;
use super::robust::RobustKalmanFilter;
use super::{
    parameter_error, require_finite_matrix, require_input_length, require_length, require_psd,
    require_shape, require_spd, symmetrize_in_place, EstimationError, Saved, StateReader,
};
use crate::linalg::dense::{self, View};
use nalgebra::{DMatrix, DVector, SMatrix};

/// Everything a [`DualKalmanFilter`] needs. Build it with [`DualKalmanConfig::new`] (which
/// sets the paper's defaults for the parameter filter) and adjust the public fields.
#[derive(Debug, Clone)]
pub struct DualKalmanConfig {
    /// The initial model Â, B̂, Ĉ, D̂ (parameters "A0", "B0", "C0", "D0"), the state filter's
    /// noise covariances Q (symmetric PSD) and R (SPD), and its initial state x0 with
    /// covariance P0 (symmetric PSD).
    pub initial: GaussianModel,
    /// Q_θ: random-walk variance of every entry of Θ ((n+p)×(n+m), ≥ 0). Default 1e-6.
    pub parameter_q: DMatrix<f64>,
    /// Σ₀: initial variance of every entry of Θ ((n+p)×(n+m), ≥ 0). Default 1.
    /// A row with zero Q_θ and zero Σ₀ is known and never changes.
    pub parameter_p0: DMatrix<f64>,
    /// R_θ: measurement variance of every row of Y ((n+p), > 0). Default 0.5 (papers).
    pub parameter_r: DVector<f64>,
    /// The bounds on the parameter filter's adaptation (module documentation). Default: none.
    pub bounds: AdaptationBounds,
    /// The parameter filter's measurement (module documentation, "Output-error parameter
    /// filter"). Default [`ParameterMeasurement::FilteredState`] (papers).
    pub measurement: ParameterMeasurement,
}

/// What the parameter filter takes as its measurement.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum ParameterMeasurement {
    /// The papers' filter: Y = [x̂_k; y_{k−1}] against Φ = [x̂_{k−1}; u_{k−1}], row by row.
    #[default]
    FilteredState,
    /// The dual EKF's output error (Haykin ch. 5): the state filter's innovation
    /// e_k = y_k − Ĉ x⁻_k against its recurrent sensitivity to the free entries of [A B].
    OutputError,
}

/// Bounds on the parameter filter (see the module documentation, "Bounded adaptation").
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AdaptationBounds {
    /// N_w: effective length (samples) of the exponential window of the excitation measure,
    /// ≥ 1 (parameter "excitation_window"). Default 200.
    pub excitation_window: f64,
    /// ε_min: the parameter filter runs only while λ_min(M_k) ≥ ε_min, in the regressor's
    /// units squared, ≥ 0 (parameter "excitation_min"). Default 0: always (papers).
    pub excitation_min: f64,
    /// σ²_max: the random walk raises a diagonal entry of Σ at most up to this, > 0 or +∞
    /// (parameter "max_variance"). Default +∞: unbounded (papers).
    pub max_variance: f64,
}

impl Default for AdaptationBounds {
    /// No bound: the papers' parameter filter.
    fn default() -> Self {
        Self {
            excitation_window: 200.0,
            excitation_min: 0.0,
            max_variance: f64::INFINITY,
        }
    }
}

impl AdaptationBounds {
    fn validate(&self) -> Result<(), EstimationError> {
        let w = self.excitation_window;
        if !(w.is_finite() && w >= 1.0) {
            return Err(parameter_error(
                "excitation_window",
                format!("must be a finite number of samples >= 1, got {w}"),
            ));
        }
        let e = self.excitation_min;
        if !(e.is_finite() && e >= 0.0) {
            return Err(parameter_error(
                "excitation_min",
                format!("must be finite and >= 0, got {e}"),
            ));
        }
        let v = self.max_variance;
        if v.is_nan() || v <= 0.0 {
            return Err(parameter_error(
                "max_variance",
                format!("must be > 0 (or +inf), got {v}"),
            ));
        }
        Ok(())
    }

    /// Whether the excitation gate is on.
    fn gated(&self) -> bool {
        self.excitation_min > 0.0
    }
}

impl DualKalmanConfig {
    /// A configuration with the papers' parameter-filter defaults: Q_θ = 1e-6, Σ₀ = 1,
    /// R_θ = 0.5 for every entry / row.
    pub fn new(initial: GaussianModel) -> Self {
        let rows = initial.system.a.nrows() + initial.system.c.nrows();
        let cols = initial.system.a.ncols() + initial.system.b.ncols();
        Self {
            initial,
            parameter_q: DMatrix::from_element(rows, cols, 1e-6),
            parameter_p0: DMatrix::from_element(rows, cols, 1.0),
            parameter_r: DVector::from_element(rows, 0.5),
            bounds: AdaptationBounds::default(),
            measurement: ParameterMeasurement::default(),
        }
    }

    /// Marks rows of [A B] as known (structural knowledge, docs/estimators.md §2.9, "Known
    /// rows"): zero Q_θ and Σ₀ on row i of Θ for every i in `rows` (< n), so
    /// [Â B̂]ᵢ = [A₀ B₀]ᵢ forever. Rows out of range are ignored.
    ///
    /// With C known the model is defined only up to x ↦ T x with C T = C; fixing rows of A
    /// removes that freedom when the fixed rows and C together pin T. For the crane
    /// (C = [I 0], x = [x, θ, v, ω]) fixing the kinematic rows 1–2 of A, whose velocity block
    /// A₁₂ is invertible (≈ Ts I), leaves T = I only: from [A₁₁ A₁₂] T⁻¹ = [A₁₁ A₁₂] follow
    /// T₂₁ = 0 and T₂₂ = I. The velocity rows 3–4 are then unique.
    pub fn fix_state_rows(mut self, rows: &[usize]) -> Self {
        let n = self.initial.system.a.nrows();
        for &row in rows.iter().filter(|r| **r < n) {
            self.parameter_q.row_mut(row).fill(0.0);
            self.parameter_p0.row_mut(row).fill(0.0);
        }
        self
    }

    /// Marks C and D as known: zero Q_θ and Σ₀ on their rows, so Ĉ = C₀ and D̂ = D₀ forever.
    pub fn fix_output_matrices(mut self) -> Self {
        let n = self.initial.system.a.nrows();
        let rows = self.parameter_q.nrows();
        if rows > n {
            self.parameter_q.rows_mut(n, rows - n).fill(0.0);
            self.parameter_p0.rows_mut(n, rows - n).fill(0.0);
        }
        self
    }
}

/// Rows of Θ that share one parameter covariance.
#[derive(Debug, Clone)]
struct ParameterGroup {
    rows: Vec<usize>,
    /// The same rows as runs `start..end` of consecutive rows (Θ is stored by columns, so a
    /// run is a contiguous piece of every column).
    runs: Vec<(usize, usize)>,
    q_diag: DVector<f64>,
    r: f64,
    sigma: DMatrix<f64>,
    /// Zero Q_θ and zero Σ: the rows are known and the update would leave them (and Σ) as
    /// they are, so it is skipped.
    fixed: bool,
}

impl ParameterGroup {
    /// The runs of consecutive rows in `rows` (ascending).
    fn runs_of(rows: &[usize]) -> Vec<(usize, usize)> {
        let mut runs: Vec<(usize, usize)> = Vec::new();
        for &row in rows {
            match runs.last_mut() {
                Some((_, end)) if *end == row => *end = row + 1,
                _ => runs.push((row, row + 1)),
            }
        }
        runs
    }

    fn is_fixed(q_diag: &DVector<f64>, sigma: &DMatrix<f64>) -> bool {
        q_diag.iter().all(|v| *v == 0.0) && sigma.iter().all(|v| *v == 0.0)
    }
}

/// Views of Â, B̂, Ĉ, D̂ in Θ̂ = [Â B̂; Ĉ D̂].
fn theta_blocks(theta: &DMatrix<f64>, n: usize, m: usize, p: usize) -> [View<'_>; 4] {
    [
        View::block(theta, (0, 0), (n, n)),
        View::block(theta, (0, n), (n, m)),
        View::block(theta, (n, 0), (p, n)),
        View::block(theta, (n, n), (p, m)),
    ]
}

/// Dual Kalman filter: states and Θ = [A B; C D]. See the module documentation.
#[derive(Debug, Clone)]
pub struct DualKalmanFilter {
    n: usize,
    m: usize,
    p: usize,
    theta: DMatrix<f64>,
    q: DMatrix<f64>,
    r: DMatrix<f64>,
    core: FilterCore,
    groups: Vec<ParameterGroup>,
    predicted_output: DVector<f64>,
    y_prev: DVector<f64>,
    /// C_M, R_M of a sample with missing channels.
    missing: MissingMask,
    regressor: DVector<f64>,
    target: DVector<f64>,
    work_s: DVector<f64>,
    work_g: DVector<f64>,
    /// The parameter filter's errors Yᵢ − θᵢᵀΦ, one per row of Θ.
    work_e: DVector<f64>,
    bounds: AdaptationBounds,
    /// M_k, the windowed regressor moment of the excitation gate ((n+m)×(n+m)).
    moment: DMatrix<f64>,
    /// ε_k = λ_min(M_k) of the last parameter step (0 before the first).
    excitation: f64,
    /// Parameter steps skipped by the excitation gate.
    frozen_steps: u64,
    /// The output-error parameter filter, when configured.
    output_error: Option<OutputErrorFilter>,
}

/// The most free entries of [A B] the output-error parameter filter takes: its Σ and work
/// matrices hold nϑ² values each (2000: 32 MB apiece), so a large model with every entry free
/// is refused up front instead of asking for tens of gigabytes.
pub const MAX_OUTPUT_ERROR_PARAMETERS: usize = 2000;

/// The output-error parameter filter (module documentation, "Output-error parameter
/// filter") on the free entries ϑ of [A B].
#[derive(Debug, Clone)]
struct OutputErrorFilter {
    /// (row, column) in Θ of every free entry.
    entries: Vec<(usize, usize)>,
    q_diag: DVector<f64>,
    /// Σ (nϑ×nϑ).
    sigma: DMatrix<f64>,
    /// S_{k−1} = ∂x̂_{k−1}/∂ϑ (n×nϑ).
    sensitivity: DMatrix<f64>,
    /// S⁻_k (n×nϑ).
    sensitivity_prior: DMatrix<f64>,
    /// Work space of one step, allocated once.
    work: OutputErrorWork,
}

/// The output-error filter's work space: K Ĉ (n×n), H (p×nϑ), Σ⁻Hᵀ (nϑ×p), its transpose
/// twice (p×nϑ: one becomes Gᵀ), Ĉ P⁻ (p×n), the innovation covariance and H Σ⁻ Hᵀ (p×p),
/// G H Σ⁻ (nϑ×nϑ) and the step of ϑ.
#[derive(Debug, Clone)]
struct OutputErrorWork {
    kc: DMatrix<f64>,
    h: DMatrix<f64>,
    sigma_ht: DMatrix<f64>,
    h_sigma: DMatrix<f64>,
    gain_t: DMatrix<f64>,
    cp: DMatrix<f64>,
    s: DMatrix<f64>,
    hsh: DMatrix<f64>,
    gh_sigma: DMatrix<f64>,
    delta: DVector<f64>,
}

impl OutputErrorWork {
    fn new(n: usize, p: usize, count: usize) -> Self {
        Self {
            kc: DMatrix::zeros(n, n),
            h: DMatrix::zeros(p, count),
            sigma_ht: DMatrix::zeros(count, p),
            h_sigma: DMatrix::zeros(p, count),
            gain_t: DMatrix::zeros(p, count),
            cp: DMatrix::zeros(p, n),
            s: DMatrix::zeros(p, p),
            hsh: DMatrix::zeros(p, p),
            gh_sigma: DMatrix::zeros(count, count),
            delta: DVector::zeros(count),
        }
    }
}

impl DualKalmanFilter {
    /// Validates the configuration (parameter names "A0", "B0", "C0", "D0", "Q", "R", "x0",
    /// "P0", "Q_theta", "P0_theta", "R_theta") and builds the filter.
    pub fn new(config: DualKalmanConfig) -> Result<Self, EstimationError> {
        let DualKalmanConfig {
            initial,
            parameter_q,
            parameter_p0,
            parameter_r,
            bounds,
            measurement,
        } = config;
        bounds.validate()?;
        let n = initial.system.a.nrows();
        if n == 0 {
            return Err(parameter_error("A0", "must have at least one state"));
        }
        require_shape("A0", &initial.system.a, n, n, "square: n×n")?;
        let m = initial.system.b.ncols();
        require_shape("B0", &initial.system.b, n, m, "n rows, like A0")?;
        let p = initial.system.c.nrows();
        require_shape("C0", &initial.system.c, p, n, "n columns, like A0")?;
        require_shape("D0", &initial.system.d, p, m, "rows of C0 × columns of B0")?;
        require_psd("Q", &initial.system.q, n)?;
        require_spd("R", &initial.system.r, p)?;
        require_length("x0", &initial.x0, n, "one entry per state")?;
        require_psd("P0", &initial.p0, n)?;
        let rows = n + p;
        let cols = n + m;
        let theta_shape = "the shape of Θ = [A B; C D]: (n+p)×(n+m)";
        require_shape("Q_theta", &parameter_q, rows, cols, theta_shape)?;
        require_shape("P0_theta", &parameter_p0, rows, cols, theta_shape)?;
        require_length("R_theta", &parameter_r, rows, "one entry per row of Θ")?;
        if let Some(v) = parameter_q.iter().find(|v| **v < 0.0) {
            return Err(parameter_error(
                "Q_theta",
                format!("variances must be >= 0, got {v}"),
            ));
        }
        if let Some(v) = parameter_p0.iter().find(|v| **v < 0.0) {
            return Err(parameter_error(
                "P0_theta",
                format!("variances must be >= 0, got {v}"),
            ));
        }
        if let Some(v) = parameter_r.iter().find(|v| **v <= 0.0) {
            return Err(parameter_error(
                "R_theta",
                format!("variances must be > 0, got {v}"),
            ));
        }

        let mut theta = DMatrix::zeros(rows, cols);
        theta.view_mut((0, 0), (n, n)).copy_from(&initial.system.a);
        theta.view_mut((0, n), (n, m)).copy_from(&initial.system.b);
        theta.view_mut((n, 0), (p, n)).copy_from(&initial.system.c);
        theta.view_mut((n, n), (p, m)).copy_from(&initial.system.d);
        require_finite_matrix("Theta0", &theta)?;

        let output_error = match measurement {
            ParameterMeasurement::FilteredState => None,
            ParameterMeasurement::OutputError => {
                let fixed =
                    |r: usize, c: usize| parameter_q[(r, c)] == 0.0 && parameter_p0[(r, c)] == 0.0;
                if (n..rows).any(|r| (0..cols).any(|c| !fixed(r, c))) {
                    return Err(parameter_error(
                        "Q_theta",
                        "the output-error parameter filter needs C and D known (zero Q_theta and P0_theta on their rows)",
                    ));
                }
                let entries: Vec<(usize, usize)> = (0..n)
                    .flat_map(|r| (0..cols).map(move |c| (r, c)))
                    .filter(|&(r, c)| !fixed(r, c))
                    .collect();
                let count = entries.len();
                if count > MAX_OUTPUT_ERROR_PARAMETERS {
                    return Err(parameter_error(
                        "Q_theta",
                        format!(
                            "the output-error parameter filter carries an nϑ × nϑ covariance: at most {MAX_OUTPUT_ERROR_PARAMETERS} free entries of [A B], got {count} (fix entries by zero Q_theta and P0_theta)"
                        ),
                    ));
                }
                Some(OutputErrorFilter {
                    q_diag: DVector::from_iterator(
                        count,
                        entries.iter().map(|&(r, c)| parameter_q[(r, c)]),
                    ),
                    sigma: DMatrix::from_diagonal(&DVector::from_iterator(
                        count,
                        entries.iter().map(|&(r, c)| parameter_p0[(r, c)]),
                    )),
                    sensitivity: DMatrix::zeros(n, count),
                    sensitivity_prior: DMatrix::zeros(n, count),
                    work: OutputErrorWork::new(n, p, count),
                    entries,
                })
            }
        };

        let mut groups: Vec<ParameterGroup> = Vec::new();
        for row in 0..rows {
            let q_row = parameter_q.row(row).transpose();
            let p0_row = parameter_p0.row(row).transpose();
            let sigma0 = DMatrix::from_diagonal(&p0_row);
            let r_row = parameter_r[row];
            match groups
                .iter_mut()
                .find(|g| g.q_diag == q_row && g.sigma == sigma0 && g.r == r_row)
            {
                Some(group) => group.rows.push(row),
                None => groups.push(ParameterGroup {
                    rows: vec![row],
                    runs: Vec::new(),
                    fixed: ParameterGroup::is_fixed(&q_row, &sigma0),
                    q_diag: q_row,
                    r: r_row,
                    sigma: sigma0,
                }),
            }
        }
        for group in &mut groups {
            group.runs = ParameterGroup::runs_of(&group.rows);
        }

        Ok(Self {
            n,
            m,
            p,
            theta,
            q: initial.system.q,
            r: initial.system.r,
            core: FilterCore::new(initial.x0, initial.p0, m, p),
            groups,
            predicted_output: DVector::zeros(p),
            y_prev: DVector::zeros(p),
            missing: MissingMask::new(p, n),
            regressor: DVector::zeros(cols),
            target: DVector::zeros(rows),
            work_s: DVector::zeros(cols),
            work_g: DVector::zeros(cols),
            work_e: DVector::zeros(rows),
            bounds,
            moment: DMatrix::zeros(cols, cols),
            excitation: 0.0,
            frozen_steps: 0,
            output_error,
        })
    }

    /// Processes one sample (see the module documentation for the exact sequence).
    pub fn step(&mut self, u: &DVector<f64>, y: &DVector<f64>) -> Result<(), EstimationError> {
        require_input_length("u", u, self.m)?;
        require_input_length("y", y, self.p)?;
        let (n, m, p) = (self.n, self.m, self.p);
        // Φ = [x̂_{k−1}; u_{k−1}] before the state filter overwrites them.
        concatenate(&mut self.regressor, &self.core.x, &self.core.u_prev);

        // 1. State filter with Θ̂_{k−1}.
        let missing = {
            let [a, b, c, d] = theta_blocks(&self.theta, n, m, p);
            self.core.predict(a, b, &self.q);
            let missing = self.core.compute_innovation(c, d, u, y)?;
            let predicted = self.predicted_output.as_mut_slice();
            if missing {
                // Ĉ x⁻ + D̂ u for every channel (y − e is not a number for a missing one).
                dense::gemv_inline(predicted, 1.0, c, self.core.x_prior.as_slice(), 0.0);
                dense::gemv_inline(predicted, 1.0, d, u.as_slice(), 1.0);
            }
            let innovation = self.core.innovation.as_slice();
            for ((predicted, y), e) in predicted.iter_mut().zip(y.as_slice()).zip(innovation) {
                if !y.is_nan() {
                    *predicted = y - e;
                }
            }
            if missing {
                self.core
                    .correct_present(&mut self.missing, c, &self.r, y)?;
            } else {
                self.core.correct(c, &self.r)?;
            }
            self.core.finish(c, d, u);
            if missing {
                self.core.check_output()?;
            }
            missing
        };

        if self.output_error.is_some() {
            // 2'. Output-error parameter filter on the innovation of this sample.
            let excited = self.core.steps > 1 && self.excited();
            if self.core.steps > 1 && !excited {
                self.frozen_steps += 1;
            }
            if excited && missing {
                self.random_walk();
            }
            self.update_output_error(excited && !missing)?;
            self.y_prev.copy_from(y);
            return Ok(());
        }

        // 2. Parameter filter on (Φ = [x̂_{k−1}; u_{k−1}], Y = [x̂_k; y_{k−1}]): with a
        // channel of y_k or y_{k−1} missing, the random walk of Θ only.
        if self.core.steps > 1 {
            concatenate(&mut self.target, &self.core.x, &self.y_prev);
            if !self.excited() {
                self.frozen_steps += 1;
            } else if missing || MissingMask::any(&self.y_prev) {
                self.random_walk();
            } else {
                self.update_parameters()?;
            }
        }
        self.y_prev.copy_from(y);
        Ok(())
    }

    /// The parameter filter's step without a measurement (module documentation, "Missing
    /// samples"): Θ̂ unchanged, Σ = Σ + diag(q̃) with the bounded random walk q̃ of every group
    /// that is not fixed (and of the output-error filter).
    fn random_walk(&mut self) {
        let cap = self.bounds.max_variance;
        let walk = |sigma: &mut DMatrix<f64>, q: &DVector<f64>| {
            for (i, q) in q.iter().enumerate() {
                let diagonal = &mut sigma[(i, i)];
                let room = (cap - *diagonal).max(0.0);
                *diagonal += q.min(room);
            }
        };
        match self.output_error.as_mut() {
            Some(oe) => walk(&mut oe.sigma, &oe.q_diag),
            None => {
                for group in self.groups.iter_mut().filter(|g| !g.fixed) {
                    walk(&mut group.sigma, &group.q_diag);
                }
            }
        }
    }

    /// Everything that evolves from step to step (see
    /// [`KalmanFilter::dynamic_state`](super::KalmanFilter::dynamic_state)): the state filter,
    /// Θ̂, every parameter covariance, the previous output and the predicted output.
    pub fn dynamic_state(&self) -> Vec<f64> {
        self.saved()
    }

    /// Restores what [`DualKalmanFilter::dynamic_state`] returned.
    pub fn set_dynamic_state(&mut self, state: &[f64]) -> Result<(), EstimationError> {
        self.restore_saved(state)
    }

    /// Updates M_k and ε_k with the regressor Φ (when the gate is on) and says whether the
    /// parameter filter may run: ε_k ≥ ε_min.
    fn excited(&mut self) -> bool {
        if !self.bounds.gated() {
            return true;
        }
        let forget = 1.0 - 1.0 / self.bounds.excitation_window;
        self.moment
            .ger(1.0 - forget, &self.regressor, &self.regressor, forget);
        symmetrize_in_place(&mut self.moment);
        let smallest = smallest_eigenvalue(&self.moment);
        // A non-finite regressor is caught by the state filter; keep ε finite regardless.
        self.excitation = if smallest.is_finite() {
            smallest.max(0.0)
        } else {
            0.0
        };
        self.excitation >= self.bounds.excitation_min
    }

    /// One step of the output-error parameter filter (after the state filter's correction
    /// with Θ̂_{k−1}): S⁻ = Â S + J(Φ), H = Ĉ S⁻, then, when `excited`, the Kalman update of ϑ
    /// with the innovation e_k and its covariance Ĉ P⁻ Ĉᵀ + R; finally S = (I − K Ĉ) S⁻.
    fn update_output_error(&mut self, excited: bool) -> Result<(), EstimationError> {
        let (n, m, p) = (self.n, self.m, self.p);
        let Some(oe) = self.output_error.as_mut() else {
            return Ok(());
        };
        let [a, _, c, _] = theta_blocks(&self.theta, n, m, p);
        let w = &mut oe.work;
        dense::gemm(
            oe.sensitivity_prior.as_mut_slice(),
            1.0,
            a,
            View::of(&oe.sensitivity),
            0.0,
        );
        // K Ĉ with Ĉ of Θ̂_{k−1}, taken before the update of ϑ below changes Θ̂.
        dense::gemm(w.kc.as_mut_slice(), 1.0, View::of(&self.core.gain), c, 0.0);
        for (e, &(row, col)) in oe.entries.iter().enumerate() {
            oe.sensitivity_prior[(row, e)] += self.regressor[col];
        }
        if excited {
            let cap = self.bounds.max_variance;
            for (i, q) in oe.q_diag.iter().enumerate() {
                let room = (cap - oe.sigma[(i, i)]).max(0.0);
                oe.sigma[(i, i)] += q.min(room);
            }
            // H = Ĉ S⁻, Σ⁻ Hᵀ, and S = Ĉ P⁻ Ĉᵀ + R + H Σ⁻ Hᵀ.
            dense::gemm(
                w.h.as_mut_slice(),
                1.0,
                c,
                View::of(&oe.sensitivity_prior),
                0.0,
            );
            dense::gemm(
                w.sigma_ht.as_mut_slice(),
                1.0,
                View::of(&oe.sigma),
                View::of(&w.h).t(),
                0.0,
            );
            dense::gemm(
                w.cp.as_mut_slice(),
                1.0,
                c,
                View::of(&self.core.p_prior),
                0.0,
            );
            dense::gemm(w.s.as_mut_slice(), 1.0, View::of(&w.cp), c.t(), 0.0);
            dense::gemm(
                w.hsh.as_mut_slice(),
                1.0,
                View::of(&w.h),
                View::of(&w.sigma_ht),
                0.0,
            );
            let (s, r, hsh) = (w.s.as_mut_slice(), self.r.as_slice(), w.hsh.as_slice());
            for ((s, r), hsh) in s.iter_mut().zip(r).zip(hsh) {
                *s = *s + r + hsh;
            }
            symmetrize_in_place(&mut w.s);
            // Gᵀ = S⁻¹ H Σ⁻.
            w.h_sigma.tr_copy_from(&w.sigma_ht);
            w.gain_t.copy_from(&w.h_sigma);
            super::cholesky_solve_in_place(
                &mut w.s,
                &mut w.gain_t,
                "output-error innovation covariance H Σ Hᵀ + C P⁻ Cᵀ + R",
                self.core.steps,
            )?;
            dense::gemv(
                w.delta.as_mut_slice(),
                1.0,
                View::of(&w.gain_t).t(),
                self.core.innovation.as_slice(),
                0.0,
            );
            for (e, &(row, col)) in oe.entries.iter().enumerate() {
                self.theta[(row, col)] += w.delta[e];
            }
            // Σ = Σ⁻ − G H Σ⁻.
            dense::gemm(
                w.gh_sigma.as_mut_slice(),
                1.0,
                View::of(&w.gain_t).t(),
                View::of(&w.h_sigma),
                0.0,
            );
            for (sigma, gh_sigma) in oe
                .sigma
                .as_mut_slice()
                .iter_mut()
                .zip(w.gh_sigma.as_slice())
            {
                *sigma -= gh_sigma;
            }
            symmetrize_in_place(&mut oe.sigma);
            let finite = |m: &DMatrix<f64>| m.as_slice().iter().all(|v| v.is_finite());
            if !finite(&self.theta) || !finite(&oe.sigma) {
                return Err(EstimationError::NonFinite {
                    what: "parameter estimate Θ or its covariance",
                    step: self.core.steps,
                });
            }
        }
        // S = (I − K C) S⁻, K = (Kᵀ)ᵀ.
        oe.sensitivity.copy_from(&oe.sensitivity_prior);
        dense::gemm(
            oe.sensitivity.as_mut_slice(),
            -1.0,
            View::of(&w.kc),
            View::of(&oe.sensitivity_prior),
            1.0,
        );
        Ok(())
    }

    /// The parameter filter on every group that is not fixed (module documentation, step 2),
    /// through [`parameter_step`] with the regressor length of the packaged variants (3, 5,
    /// 10) as a constant, so that the loops are unrolled at fixed size; any other length runs
    /// the same code with the length at run time (same arithmetic, same results).
    fn update_parameters(&mut self) -> Result<(), EstimationError> {
        let work = ParameterWork {
            phi: self.regressor.as_slice(),
            target: self.target.as_slice(),
            s: self.work_s.as_mut_slice(),
            g: self.work_g.as_mut_slice(),
            e: self.work_e.as_mut_slice(),
            cap: self.bounds.max_variance,
        };
        let (groups, theta) = (&mut self.groups, &mut self.theta);
        let outcome = match work.phi.len() {
            3 => parameter_step::<3>(groups, theta, work),
            5 => parameter_step::<5>(groups, theta, work),
            10 => parameter_step::<10>(groups, theta, work),
            _ => parameter_step::<0>(groups, theta, work),
        };
        outcome.map_err(|what| EstimationError::NonFinite {
            what,
            step: self.core.steps,
        })
    }

    /// Filtered state x̂_{k|k}.
    pub fn state(&self) -> &DVector<f64> {
        &self.core.x
    }
    /// Covariance of the filtered state.
    pub fn covariance(&self) -> &DMatrix<f64> {
        &self.core.p
    }
    /// Filtered output ŷ_k = Ĉ x̂_{k|k} + D̂ u_k (model of the start of the step).
    pub fn output(&self) -> &DVector<f64> {
        &self.core.output
    }
    /// One-step-ahead predicted output Ĉ x⁻ + D̂ u_k (before y_k was used).
    pub fn predicted_output(&self) -> &DVector<f64> {
        &self.predicted_output
    }
    /// State-filter innovation y_k − Ĉ x⁻ − D̂ u_k.
    pub fn innovation(&self) -> &DVector<f64> {
        &self.core.innovation
    }
    /// Θ̂ = [Â B̂; Ĉ D̂], (n+p)×(n+m).
    pub fn theta(&self) -> &DMatrix<f64> {
        &self.theta
    }
    /// Â (n×n).
    pub fn a(&self) -> DMatrix<f64> {
        self.theta.view((0, 0), (self.n, self.n)).into_owned()
    }
    /// B̂ (n×m).
    pub fn b(&self) -> DMatrix<f64> {
        self.theta.view((0, self.n), (self.n, self.m)).into_owned()
    }
    /// Ĉ (p×n).
    pub fn c(&self) -> DMatrix<f64> {
        self.theta.view((self.n, 0), (self.p, self.n)).into_owned()
    }
    /// D̂ (p×m).
    pub fn d(&self) -> DMatrix<f64> {
        self.theta
            .view((self.n, self.n), (self.p, self.m))
            .into_owned()
    }
    /// Number of distinct parameter covariances kept (rows of Θ sharing Q_θ, Σ₀, R_θ share one).
    pub fn parameter_covariance_count(&self) -> usize {
        self.groups.len()
    }
    /// Parameter covariance Σ of row `row` of Θ ((n+m)×(n+m)), if the row exists.
    pub fn parameter_covariance(&self, row: usize) -> Option<&DMatrix<f64>> {
        self.groups
            .iter()
            .find(|g| g.rows.contains(&row))
            .map(|g| &g.sigma)
    }
    /// Covariance Σ of the free entries of [A B] (in row-major order of Θ) of the output-error
    /// parameter filter, when configured.
    pub fn output_error_covariance(&self) -> Option<&DMatrix<f64>> {
        self.output_error.as_ref().map(|oe| &oe.sigma)
    }
    /// Number of steps processed.
    pub fn steps(&self) -> u64 {
        self.core.steps
    }
    /// The excitation measure ε_k = λ_min(M_k) of the last step (0 while the gate is off).
    pub fn excitation(&self) -> f64 {
        self.excitation
    }
    /// Whether the last step updated Θ̂ (false when the excitation gate froze it, and at the
    /// first step).
    pub fn adapting(&self) -> bool {
        self.core.steps > 1
            && (!self.bounds.gated() || self.excitation >= self.bounds.excitation_min)
    }
    /// Number of parameter steps the excitation gate skipped.
    pub fn frozen_steps(&self) -> u64 {
        self.frozen_steps
    }
    /// The bounds on the adaptation.
    pub fn bounds(&self) -> &AdaptationBounds {
        &self.bounds
    }
    /// Number of states n.
    pub fn states(&self) -> usize {
        self.n
    }
    /// Number of inputs m.
    pub fn inputs(&self) -> usize {
        self.m
    }
    /// Number of outputs p.
    pub fn outputs(&self) -> usize {
        self.p
    }
}

impl Saved for DualKalmanFilter {
    fn save(&self, out: &mut Vec<f64>) {
        self.core.save(out);
        out.extend_from_slice(self.theta.as_slice());
        for group in &self.groups {
            out.extend_from_slice(group.sigma.as_slice());
        }
        out.extend_from_slice(self.y_prev.as_slice());
        out.extend_from_slice(self.predicted_output.as_slice());
        out.extend_from_slice(self.moment.as_slice());
        out.push(self.excitation);
        out.push(self.frozen_steps as f64);
        if let Some(oe) = &self.output_error {
            out.extend_from_slice(oe.sigma.as_slice());
            out.extend_from_slice(oe.sensitivity.as_slice());
        }
    }

    fn restore(&mut self, input: &mut StateReader<'_>) -> Result<(), EstimationError> {
        self.core.restore(input)?;
        input.fill(self.theta.as_mut_slice())?;
        // A step checks only the rows of Θ̂ it updates: the known rows are checked here.
        require_finite_matrix("state: parameter estimate Θ", &self.theta)?;
        for group in &mut self.groups {
            input.fill(group.sigma.as_mut_slice())?;
            group.fixed = ParameterGroup::is_fixed(&group.q_diag, &group.sigma);
        }
        input.fill(self.y_prev.as_mut_slice())?;
        input.fill(self.predicted_output.as_mut_slice())?;
        input.fill(self.moment.as_mut_slice())?;
        require_finite_matrix("state: excitation moment M", &self.moment)?;
        let excitation = input.scalar()?;
        if !(excitation.is_finite() && excitation >= 0.0) {
            return Err(parameter_error(
                "state",
                format!("the saved excitation measure must be finite and >= 0, got {excitation}"),
            ));
        }
        self.excitation = excitation;
        self.frozen_steps = input.counter()?;
        if let Some(oe) = &mut self.output_error {
            input.fill(oe.sigma.as_mut_slice())?;
            input.fill(oe.sensitivity.as_mut_slice())?;
            require_finite_matrix("state: output-error covariance", &oe.sigma)?;
            require_finite_matrix("state: output-error sensitivity", &oe.sensitivity)?;
        }
        Ok(())
    }
}

/// `to` = [`first`; `second`] (the regressor Φ, the parameter filter's measurement Y), copied
/// as slices.
fn concatenate(to: &mut DVector<f64>, first: &DVector<f64>, second: &DVector<f64>) {
    let split = first.len().min(to.len());
    let (head, tail) = to.as_mut_slice().split_at_mut(split);
    for (to, from) in head.iter_mut().zip(first.as_slice()) {
        *to = *from;
    }
    for (to, from) in tail.iter_mut().zip(second.as_slice()) {
        *to = *from;
    }
}

/// λ_min of the symmetric matrix `m` (the smallest of nalgebra's symmetric eigenvalues; +∞
/// without any), computed on a matrix of fixed size for the packaged regressor lengths 3, 5
/// and 10: the same algorithm and numbers, without the heap allocations of a dynamic matrix.
fn smallest_eigenvalue(m: &DMatrix<f64>) -> f64 {
    let smallest = |eigenvalues: &[f64]| eigenvalues.iter().copied().fold(f64::INFINITY, f64::min);
    macro_rules! fixed {
        ($d:literal) => {
            <[f64; $d * $d]>::try_from(m.as_slice()).ok().map(|data| {
                let eigenvalues =
                    SMatrix::<f64, $d, $d>::from_column_slice(&data).symmetric_eigenvalues();
                smallest(eigenvalues.as_slice())
            })
        };
    }
    let fixed = match m.nrows() {
        3 => fixed!(3),
        5 => fixed!(5),
        10 => fixed!(10),
        _ => None,
    };
    fixed.unwrap_or_else(|| smallest(m.symmetric_eigenvalues().as_slice()))
}

/// What one step of the parameter filter reads (Φ, Y, σ²_max) and its work space (s, g and
/// the errors e, one per row of Θ).
struct ParameterWork<'a> {
    phi: &'a [f64],
    target: &'a [f64],
    s: &'a mut [f64],
    g: &'a mut [f64],
    e: &'a mut [f64],
    cap: f64,
}

/// One step of the row-grouped parameter filter (module documentation, step 2) on the groups
/// that are not fixed, `cols` = n + m the length of Φ. Per group, with its Σ stored full
/// (cols×cols, by columns) and kept exactly symmetric:
///
/// ```text
/// Σ⁻ = Σ + diag(q̃)                     s = Σ⁻Φ (by columns)      d = Φᵀs + R_θ    g = s/d
/// eᵢ = Yᵢ − θᵢᵀΦ (for its rows i)        θᵢ ← θᵢ + g eᵢ
/// Σᵢⱼ = Σ⁻ᵢⱼ − (gᵢsⱼ + sᵢgⱼ) + d (gᵢgⱼ)   (Joseph form, written symmetric in i and j)
/// ```
///
/// Entries (i, j) and (j, i) of the Joseph update are the same operations on the same numbers,
/// so Σ comes out exactly symmetric with no symmetrisation pass: one triangle's worth of
/// distinct values. (Every entry is computed: whole contiguous columns vectorise, and cost
/// fewer instructions than one triangle of ragged columns and a mirroring pass.) s, d, e and
/// the update of Θ sum in the order of the former code (bit for bit); the covariance update
/// is within rounding of the former `Σ⁻ − g sᵀ − s gᵀ + d g gᵀ` followed by (Σ + Σᵀ)/2 (the
/// test `the_symmetric_joseph_update_matches_the_former_full_matrix_one`).
///
/// `COLS` > 0 is the length of Φ known at compile time (the loops then run at fixed size),
/// 0 takes it from Φ at run time: the same code and arithmetic either way. Errors say what
/// became non-finite.
fn parameter_step<const COLS: usize>(
    groups: &mut [ParameterGroup],
    theta: &mut DMatrix<f64>,
    work: ParameterWork<'_>,
) -> Result<(), &'static str> {
    let cols = if COLS == 0 { work.phi.len() } else { COLS };
    let ParameterWork {
        phi,
        target,
        s,
        g,
        e,
        cap,
    } = work;
    let ld = theta.nrows();
    let (Some(phi), Some(s), Some(g)) = (phi.get(..cols), s.get_mut(..cols), g.get_mut(..cols))
    else {
        return Ok(());
    };
    let Some(theta) = theta.as_mut_slice().get_mut(..ld * cols) else {
        return Ok(());
    };
    let mut non_finite = false;
    for group in groups.iter_mut().filter(|g| !g.fixed) {
        let (Some(sigma), Some(q)) = (
            group.sigma.as_mut_slice().get_mut(..cols * cols),
            group.q_diag.as_slice().get(..cols),
        ) else {
            continue;
        };
        let d = gain::<COLS>(sigma, q, group.r, cap, phi, s, g)
            .ok_or("parameter-filter innovation variance Φᵀ Σ⁻ Φ + R_θ")?;
        for &(start, end) in &group.runs {
            let (Some(e), Some(target)) = (e.get_mut(start..end), target.get(start..end)) else {
                continue;
            };
            // The packaged variants' free rows (n of them) as a constant too.
            non_finite |= match (COLS, e.len()) {
                (10, 8) => update_rows::<10, 8>(ld, start, theta, phi, target, g, e),
                (5, 4) => update_rows::<5, 4>(ld, start, theta, phi, target, g, e),
                _ => update_rows::<COLS, 0>(ld, start, theta, phi, target, g, e),
            };
        }
        joseph_update::<COLS>(sigma, s, g, d);
    }
    if non_finite {
        return Err("parameter estimate Θ");
    }
    Ok(())
}

/// The first half of a group's step: Σ⁻ = Σ + diag(q̃), q̃ᵢ = min(qᵢ, max(0, σ²_max − Σᵢᵢ))
/// (= qᵢ with σ²_max = +∞), s = Σ⁻Φ (column by column, term by term from the first),
/// d = Φᵀs + R_θ and g = s/d. Gives d, or None when it is not finite and positive. (The
/// kernels take their slices as arguments of a function of their own, not in a struct, so the
/// compiler knows that they do not overlap: the loops are vectorised.)
#[inline(never)]
fn gain<const COLS: usize>(
    sigma: &mut [f64],
    q: &[f64],
    r: f64,
    cap: f64,
    phi: &[f64],
    s: &mut [f64],
    g: &mut [f64],
) -> Option<f64> {
    let cols = if COLS == 0 { phi.len() } else { COLS };
    for (i, q) in q.iter().enumerate().take(cols) {
        if let Some(diagonal) = sigma.get_mut(i * cols + i) {
            let room = (cap - *diagonal).max(0.0);
            *diagonal += q.min(room);
        }
    }
    let mut columns = sigma.chunks_exact(cols).zip(phi);
    if let Some((first, f)) = columns.next() {
        for (s, sigma) in s.iter_mut().zip(first) {
            *s = sigma * f;
        }
    }
    for (column, f) in columns {
        for (s, sigma) in s.iter_mut().zip(column) {
            *s += sigma * f;
        }
    }
    let d = dense::dot(phi, s) + r;
    if !(d.is_finite() && d > 0.0) {
        return None;
    }
    for (g, s) in g.iter_mut().zip(s.iter()) {
        *g = s / d;
    }
    Some(d)
}

/// The rows `start..start + e.len()` of Θ (stored by columns, `ld` rows): eᵢ = Yᵢ − θᵢᵀΦ
/// (term by term from the first column), then θᵢ ← θᵢ + g eᵢ. Says whether an updated entry is
/// not finite. `COLS` > 0 is the length of Φ, `ROWS` > 0 the number of rows, known at compile
/// time (0: at run time).
#[inline(never)]
fn update_rows<const COLS: usize, const ROWS: usize>(
    ld: usize,
    start: usize,
    theta: &mut [f64],
    phi: &[f64],
    target: &[f64],
    g: &[f64],
    e: &mut [f64],
) -> bool {
    let cols = if COLS == 0 { phi.len() } else { COLS };
    let len = if ROWS == 0 { e.len() } else { ROWS };
    let (Some(e), Some(target)) = (e.get_mut(..len), target.get(..len)) else {
        return false;
    };
    let rows = start..start + len;
    let mut columns = theta.chunks_exact(ld).take(cols).zip(phi);
    if let Some((first, f)) = columns.next() {
        for (e, t) in e.iter_mut().zip(first.get(rows.clone()).unwrap_or(&[])) {
            *e = t * f;
        }
    }
    for (column, f) in columns {
        for (e, t) in e.iter_mut().zip(column.get(rows.clone()).unwrap_or(&[])) {
            *e += t * f;
        }
    }
    for (e, y) in e.iter_mut().zip(target) {
        *e = y - *e;
    }
    let mut non_finite = false;
    for (column, g) in theta.chunks_exact_mut(ld).take(cols).zip(g) {
        let column = column.get_mut(rows.clone()).unwrap_or(&mut []);
        for (t, e) in column.iter_mut().zip(e.iter()) {
            *t += g * e;
            non_finite |= !t.is_finite();
        }
    }
    non_finite
}

/// The second half of a group's step: Σ = Σ⁻ − (g sᵀ + s gᵀ) + d g gᵀ, column by column.
/// Entry (i, j) and entry (j, i) are the same operations on the same numbers, so Σ stays
/// exactly symmetric without a symmetrisation pass.
#[inline(never)]
fn joseph_update<const COLS: usize>(sigma: &mut [f64], s: &[f64], g: &[f64], d: f64) {
    let cols = if COLS == 0 { s.len() } else { COLS };
    for ((column, &sj), &gj) in sigma.chunks_exact_mut(cols).zip(s).zip(g) {
        for ((sigma, &si), &gi) in column.iter_mut().zip(s).zip(g) {
            *sigma = (*sigma - (gi * sj + si * gj)) + d * (gi * gj);
        }
    }
}

/// DKF-rsKF (paper 001, Fig. 2): the rsKF cleans the measured outputs, the DKF identifies
/// from the cleaned outputs ŷ_rsKF = C x̂ + D u of the cleaner and the inputs.
#[derive(Debug, Clone)]
pub struct DkfRsKf {
    cleaner: RobustKalmanFilter,
    dual: DualKalmanFilter,
    no_input: DVector<f64>,
    /// The cleaner's own input v_k ([`DkfRsKf::with_cleaner_input`]), set before each step.
    cleaner_input: Option<DVector<f64>>,
    /// The DKF's measurement of the step: the cleaned outputs, NaN where y is missing.
    dual_output: DVector<f64>,
}

impl DkfRsKf {
    /// Composes a cleaner and a DKF. The cleaner must have as many outputs as the DKF and
    /// either no input (e.g. [`RobustKalmanFilter::random_walk`]) or the DKF's inputs.
    pub fn new(
        cleaner: RobustKalmanFilter,
        dual: DualKalmanFilter,
    ) -> Result<Self, EstimationError> {
        if cleaner.inputs() != 0 && cleaner.inputs() != dual.inputs() {
            return Err(parameter_error(
                "cleaner",
                format!(
                    "the rsKF has {} inputs: it must have none or the DKF's {}",
                    cleaner.inputs(),
                    dual.inputs()
                ),
            ));
        }
        Self::compose(cleaner, dual, None)
    }

    /// Composes a cleaner driven by an input of its own (e.g.
    /// [`RobustKalmanFilter::first_order_from`]) and a DKF: each step the cleaner takes the
    /// input set by [`DkfRsKf::set_cleaner_input`] (v_k, one entry per cleaner input, zero
    /// until set) instead of the DKF's u_k. The cleaner must have as many outputs as the DKF.
    pub fn with_cleaner_input(
        cleaner: RobustKalmanFilter,
        dual: DualKalmanFilter,
    ) -> Result<Self, EstimationError> {
        let inputs = DVector::zeros(cleaner.inputs());
        Self::compose(cleaner, dual, Some(inputs))
    }

    fn compose(
        cleaner: RobustKalmanFilter,
        dual: DualKalmanFilter,
        cleaner_input: Option<DVector<f64>>,
    ) -> Result<Self, EstimationError> {
        if cleaner.outputs() != dual.outputs() {
            return Err(parameter_error(
                "cleaner",
                format!(
                    "the rsKF has {} outputs but the DKF has {}",
                    cleaner.outputs(),
                    dual.outputs()
                ),
            ));
        }
        Ok(Self {
            dual_output: DVector::zeros(dual.outputs()),
            cleaner,
            dual,
            no_input: DVector::zeros(0),
            cleaner_input,
        })
    }

    /// The cleaner's own input v_k for the next [`DkfRsKf::step`], to be overwritten in
    /// place (no allocation per step); `None` when the cleaner takes none or the DKF's u_k.
    pub fn cleaner_input_mut(&mut self) -> Option<&mut DVector<f64>> {
        self.cleaner_input.as_mut()
    }

    /// Sets the cleaner's own input v_k for the next [`DkfRsKf::step`].
    pub fn set_cleaner_input(&mut self, v: &DVector<f64>) -> Result<(), EstimationError> {
        let slot = self.cleaner_input.as_mut().ok_or_else(|| {
            parameter_error("v", "this DKF-rsKF's cleaner takes no input of its own")
        })?;
        require_length("v", v, slot.len(), "one entry per cleaner input")?;
        slot.copy_from(v);
        Ok(())
    }

    /// One sample: rsKF on (u, y), then the DKF on (u, cleaned y). A missing y_j (NaN)
    /// stays missing for the DKF: the cleaner's output there is its own prediction, not a
    /// measurement, so the DKF predicts its state and lets Θ walk (module documentation).
    pub fn step(&mut self, u: &DVector<f64>, y: &DVector<f64>) -> Result<(), EstimationError> {
        require_input_length("u", u, self.dual.inputs())?;
        let cleaner_input = match &self.cleaner_input {
            Some(v) => v,
            None if self.cleaner.inputs() == 0 => &self.no_input,
            None => u,
        };
        self.cleaner.step(cleaner_input, y)?;
        if !MissingMask::any(y) {
            return self.dual.step(u, self.cleaner.output());
        }
        self.dual_output.copy_from(self.cleaner.output());
        for (target, y) in self.dual_output.iter_mut().zip(y.iter()) {
            if y.is_nan() {
                *target = f64::NAN;
            }
        }
        self.dual.step(u, &self.dual_output)
    }

    /// Everything that evolves from step to step: the rsKF's and then the DKF's dynamic state
    /// (see [`KalmanFilter::dynamic_state`](super::KalmanFilter::dynamic_state)).
    pub fn dynamic_state(&self) -> Vec<f64> {
        self.saved()
    }

    /// Restores what [`DkfRsKf::dynamic_state`] returned.
    pub fn set_dynamic_state(&mut self, state: &[f64]) -> Result<(), EstimationError> {
        self.restore_saved(state)
    }

    /// The cleaned outputs of the last step.
    pub fn cleaned_output(&self) -> &DVector<f64> {
        self.cleaner.output()
    }
    /// The rsKF.
    pub fn cleaner(&self) -> &RobustKalmanFilter {
        &self.cleaner
    }
    /// The DKF (states, outputs, Â, B̂, Ĉ, D̂).
    pub fn dual(&self) -> &DualKalmanFilter {
        &self.dual
    }
}

impl Saved for DkfRsKf {
    fn save(&self, out: &mut Vec<f64>) {
        self.cleaner.save(out);
        self.dual.save(out);
    }
    fn restore(&mut self, input: &mut StateReader<'_>) -> Result<(), EstimationError> {
        self.cleaner.restore(input)?;
        self.dual.restore(input)
    }
}

#[cfg(test)]
mod tests {
    use super::super::robust::test_rng::TestRng;
    use super::super::{GaussianModel, InfluenceFunction};
    use super::*;
    use crate::state_space::StateSpace;

    struct Truth {
        a: DMatrix<f64>,
        b: DMatrix<f64>,
    }

    fn truth() -> Truth {
        Truth {
            a: DMatrix::from_row_slice(2, 2, &[0.9, 0.2, -0.1, 0.8]),
            b: DMatrix::from_row_slice(2, 1, &[0.5, 1.0]),
        }
    }

    /// Simulates the 2-state system with C = I: returns (u, clean y, measured y).
    fn simulate(
        seed: u64,
        samples: usize,
        process_std: f64,
        noise_std: f64,
        outlier_fraction: f64,
    ) -> Vec<(DVector<f64>, DVector<f64>, DVector<f64>)> {
        let t = truth();
        let mut rng = TestRng::new(seed);
        let mut x = DVector::zeros(2);
        let mut u_held = 0.0;
        let mut data = Vec::with_capacity(samples);
        for k in 0..samples {
            if k % 5 == 0 {
                u_held = rng.normal();
            }
            let u = DVector::from_element(1, u_held);
            let clean = x.clone();
            let mut measured = &clean
                + DVector::from_vec(vec![noise_std * rng.normal(), noise_std * rng.normal()]);
            for j in 0..2 {
                if rng.uniform() < outlier_fraction {
                    measured[j] += if rng.uniform() < 0.5 { -5.0 } else { 5.0 };
                }
            }
            data.push((u.clone(), clean, measured));
            x = &t.a * &x
                + &t.b * &u
                + DVector::from_vec(vec![process_std * rng.normal(), process_std * rng.normal()]);
        }
        data
    }

    fn config(noise_var: f64) -> DualKalmanConfig {
        let mut config = DualKalmanConfig::new(GaussianModel {
            system: StateSpace {
                a: DMatrix::identity(2, 2) * 0.5,
                b: DMatrix::zeros(2, 1),
                c: DMatrix::identity(2, 2),
                d: DMatrix::zeros(2, 1),
                q: DMatrix::identity(2, 2) * 1e-4,
                r: DMatrix::identity(2, 2) * noise_var,
            },
            x0: DVector::zeros(2),
            p0: DMatrix::identity(2, 2),
        })
        .fix_output_matrices();
        config.parameter_q.fill(0.0);
        config.parameter_q.rows_mut(2, 2).fill(0.0);
        config
    }

    #[test]
    fn shares_one_parameter_covariance_per_row_group() {
        let dkf = DualKalmanFilter::new(config(1e-4)).unwrap();
        // A/B rows share one Σ, the fixed C/D rows another.
        assert_eq!(dkf.parameter_covariance_count(), 2);
        assert_eq!(dkf.parameter_covariance(3).unwrap(), &DMatrix::zeros(3, 3));
    }

    #[test]
    fn recovers_a_known_two_state_system() {
        let t = truth();
        let data = simulate(11, 3000, 0.01, 0.01, 0.0);
        let mut dkf = DualKalmanFilter::new(config(1e-4)).unwrap();
        for (u, _, y) in &data {
            dkf.step(u, y).unwrap();
        }
        let a_error = (dkf.a() - &t.a).amax();
        let b_error = (dkf.b() - &t.b).amax();
        println!(
            "Â = {}B̂ = {}|ΔA| = {a_error:.2e}, |ΔB| = {b_error:.2e}",
            dkf.a(),
            dkf.b()
        );
        assert!(a_error < 0.02, "Â = {}", dkf.a());
        assert!(b_error < 0.02, "B̂ = {}", dkf.b());
        assert_eq!(dkf.c(), DMatrix::identity(2, 2));
        assert_eq!(dkf.d(), DMatrix::zeros(2, 1));
    }

    #[test]
    fn rskf_cleaning_protects_identification_from_outliers() {
        let t = truth();
        let data = simulate(13, 3000, 0.01, 0.05, 0.05);
        // The state filter must trust the measurements more than the (still wrong) model:
        // Q = 1e-2 (model uncertainty) against R = 2.5e-3.
        let tuned = || {
            let mut cfg = config(0.0025);
            cfg.initial.system.q = DMatrix::identity(2, 2) * 1e-2;
            DualKalmanFilter::new(cfg).unwrap()
        };
        let mut plain = tuned();
        // The cleaner runs on a rough nominal model (entries 5–25 % off the truth); a
        // random-walk cleaner lags this fast signal, since r is standardised by R only.
        let cleaner = RobustKalmanFilter::new(
            GaussianModel {
                system: StateSpace {
                    a: DMatrix::from_row_slice(2, 2, &[0.85, 0.25, -0.05, 0.75]),
                    b: DMatrix::from_row_slice(2, 1, &[0.45, 1.1]),
                    c: DMatrix::identity(2, 2),
                    d: DMatrix::zeros(2, 1),
                    q: DMatrix::identity(2, 2) * 1e-2,
                    r: DMatrix::identity(2, 2) * 0.0025,
                },
                x0: DVector::zeros(2),
                p0: DMatrix::identity(2, 2),
            },
            InfluenceFunction::huber(),
        )
        .unwrap();
        let mut robust = DkfRsKf::new(cleaner, tuned()).unwrap();
        let (mut plain_error, mut robust_error, mut cleaner_error) = (0.0, 0.0, 0.0);
        for (u, clean, y) in &data {
            plain.step(u, y).unwrap();
            robust.step(u, y).unwrap();
            cleaner_error += (robust.cleaned_output() - clean).norm_squared();
            plain_error += (plain.output() - clean).norm_squared();
            robust_error += (robust.dual().output() - clean).norm_squared();
        }
        let plain_a = (plain.a() - &t.a).amax();
        let robust_a = (robust.dual().a() - &t.a).amax();
        println!("cleaner E_res = {:.4}", cleaner_error / data.len() as f64);
        println!(
            "outliers: DKF |ΔA| = {plain_a:.3}, E_res = {:.4}; DKF-rsKF |ΔA| = {robust_a:.3}, E_res = {:.4}",
            plain_error / data.len() as f64,
            robust_error / data.len() as f64
        );
        assert!(robust_a < 0.03 && robust_a < plain_a);
        assert!(robust_error < 0.5 * plain_error);
    }

    /// The first-order cleaner with a = 1, b = 0 is the random walk bit for bit, whatever its
    /// own input; with b ≠ 0 its own input v (not the DKF's u) drives it: a cleaner that knows
    /// the signal's dynamics, x_j(k) = a x_j(k−1) + b v_j(k−1), cleans it better than the
    /// random walk, which lags it.
    #[test]
    fn the_first_order_cleaner_reduces_to_the_random_walk_and_follows_its_own_input() {
        let data = simulate(17, 400, 0.01, 0.05, 0.05);
        let start = DVector::from_vec(vec![0.1, -0.2]);
        let (q, r, p0) = (1e-2, 0.0025, 1.0);
        let psi = InfluenceFunction::huber();
        let dual = || DualKalmanFilter::new(config(0.0025)).unwrap();
        // The random walk of A = C = I, no input, as RobustKalmanFilter::new takes it.
        let eye = DMatrix::<f64>::identity(2, 2);
        let system = StateSpace {
            a: eye.clone(),
            b: DMatrix::zeros(2, 0),
            c: eye.clone(),
            d: DMatrix::zeros(2, 0),
            q: &eye * q,
            r: &eye * r,
        };
        let (x0, p0_matrix) = (start.clone(), &eye * p0);
        let model = GaussianModel {
            system,
            x0,
            p0: p0_matrix,
        };
        let walk = RobustKalmanFilter::new(model, psi).unwrap();
        let ones = DVector::from_element(2, 1.0);
        let zeros = DVector::zeros(2);
        let first =
            RobustKalmanFilter::first_order_from(start.clone(), (&ones, &zeros), q, r, p0, psi)
                .unwrap();
        assert_eq!(first.inputs(), 0, "b = 0: no input");
        let mut by_walk = DkfRsKf::new(walk, dual()).unwrap();
        let mut by_first = DkfRsKf::with_cleaner_input(first, dual()).unwrap();
        assert!(by_first.cleaner_input_mut().is_some());
        for (u, _, y) in &data {
            by_walk.step(u, y).unwrap();
            by_first.step(u, y).unwrap();
        }
        assert_eq!(by_first.dynamic_state(), by_walk.dynamic_state());
        assert!(by_walk.set_cleaner_input(&zeros).is_err());

        // Each channel of the truth's output seen as first order: x_j(k) = a_j x_j(k−1) +
        // b_j v_j(k−1) with v_j(k) = (x(k+1) − a_j x(k))_j / b_j, the rest of the dynamics
        // folded into v. The driven cleaner then predicts the clean output to the noise.
        let (a, b) = (
            DVector::from_vec(vec![0.9, 0.8]),
            DVector::from_vec(vec![0.5, 1.0]),
        );
        let driven =
            RobustKalmanFilter::first_order_from(DVector::zeros(2), (&a, &b), 1e-4, r, p0, psi)
                .unwrap();
        assert_eq!(driven.inputs(), 2);
        let walk = RobustKalmanFilter::random_walk(2, q, r, p0, psi).unwrap();
        let mut by_walk = DkfRsKf::new(walk, dual()).unwrap();
        let mut by_input = DkfRsKf::with_cleaner_input(driven, dual()).unwrap();
        let (mut walk_error, mut input_error) = (0.0, 0.0);
        for k in 0..data.len() - 1 {
            let (u, clean, y) = &data[k];
            let next = &data[k + 1].1;
            let v = DVector::from_fn(2, |j, _| (next[j] - a[j] * clean[j]) / b[j]);
            by_input.set_cleaner_input(&v).unwrap();
            by_input.step(u, y).unwrap();
            by_walk.step(u, y).unwrap();
            input_error += (by_input.cleaned_output() - clean).norm_squared();
            walk_error += (by_walk.cleaned_output() - clean).norm_squared();
        }
        println!("cleaned E_res: random walk {walk_error:.4}, input-driven {input_error:.4}");
        assert!(input_error < 0.5 * walk_error);
        let e = by_input.set_cleaner_input(&DVector::zeros(3)).unwrap_err();
        assert!(e.to_string().contains("`v`"), "{e}");
    }

    #[test]
    fn rejects_bad_parameter_filter_settings() {
        let mut cfg = config(1e-4);
        cfg.parameter_r[0] = 0.0;
        let e = DualKalmanFilter::new(cfg).unwrap_err();
        assert!(e.to_string().contains("R_theta"), "{e}");
        let mut cfg = config(1e-4);
        cfg.parameter_q = DMatrix::zeros(3, 3);
        let e = DualKalmanFilter::new(cfg).unwrap_err();
        assert!(e.to_string().contains("Q_theta"), "{e}");
        for (bounds, name) in [
            (
                AdaptationBounds {
                    excitation_window: 0.5,
                    ..AdaptationBounds::default()
                },
                "excitation_window",
            ),
            (
                AdaptationBounds {
                    excitation_min: f64::NAN,
                    ..AdaptationBounds::default()
                },
                "excitation_min",
            ),
            (
                AdaptationBounds {
                    max_variance: 0.0,
                    ..AdaptationBounds::default()
                },
                "max_variance",
            ),
        ] {
            let mut cfg = config(1e-4);
            cfg.bounds = bounds;
            let e = DualKalmanFilter::new(cfg).unwrap_err();
            assert!(e.to_string().contains(name), "{e}");
        }
    }

    /// With no data (Φ = 0) Σ grows by Q_θ per step: without a bound to 1 + 1000·1e-3 = 2,
    /// with σ²_max = 1.5 to 1.5 exactly.
    #[test]
    fn the_variance_bound_caps_the_random_walk() {
        let run = |max_variance: f64| {
            let mut cfg = config(1e-4);
            cfg.parameter_q.rows_mut(0, 2).fill(1e-3);
            cfg.initial.x0 = DVector::zeros(2);
            cfg.bounds.max_variance = max_variance;
            let mut dkf = DualKalmanFilter::new(cfg).unwrap();
            let (u, y) = (DVector::zeros(1), DVector::zeros(2));
            for _ in 0..1001 {
                dkf.step(&u, &y).unwrap();
            }
            dkf.parameter_covariance(0).unwrap().diagonal()
        };
        let free = run(f64::INFINITY);
        assert!((free.amax() - 2.0).abs() < 1e-9, "Σ = {free}");
        let bounded = run(1.5);
        assert_eq!(bounded, DVector::from_element(3, 1.5));
    }

    /// The gate's moment, ε and frozen count travel with the dynamic state; a corrupt ε is
    /// refused.
    #[test]
    fn the_gate_state_round_trips_and_is_checked() {
        let mut dkf = DualKalmanFilter::new(gated_config()).unwrap();
        for (u, _, y) in &simulate(3, 50, 0.01, 0.01, 0.0) {
            dkf.step(u, y).unwrap();
        }
        assert!(dkf.excitation() > 0.0);
        let state = dkf.dynamic_state();
        let mut copy = DualKalmanFilter::new(gated_config()).unwrap();
        copy.set_dynamic_state(&state).unwrap();
        assert_eq!(copy.excitation(), dkf.excitation());
        assert_eq!(copy.frozen_steps(), dkf.frozen_steps());
        assert_eq!(copy.dynamic_state(), state);
        let mut bad = state.clone();
        let at = bad.len() - 2;
        bad[at] = f64::NAN;
        let e = copy.set_dynamic_state(&bad).unwrap_err();
        assert!(e.to_string().contains("excitation"), "{e}");
        // Θ̂ follows the state filter's part; a non-finite entry (here Ĉ[0, 0], a known row
        // no step checks) is refused.
        let mut bad = state.clone();
        let core = state.len() - dkf.theta.len() - dkf.groups.len() * 9 - 2 - 2 - 9 - 2;
        bad[core + 2] = f64::INFINITY;
        let e = copy.set_dynamic_state(&bad).unwrap_err();
        assert!(e.to_string().contains("Θ"), "{e}");
    }

    /// The output-error filter with C = I: every entry of [A B] free, learnt from the
    /// innovation; its Σ and sensitivity travel with the dynamic state; free C is refused.
    #[test]
    fn the_output_error_filter_recovers_the_system_and_round_trips() {
        let t = truth();
        let oe_config = || {
            let mut cfg = config(1e-4);
            cfg.parameter_p0.rows_mut(0, 2).fill(1e-1);
            cfg.measurement = ParameterMeasurement::OutputError;
            cfg
        };
        let mut dkf = DualKalmanFilter::new(oe_config()).unwrap();
        let data = simulate(11, 3000, 0.01, 0.01, 0.0);
        for (u, _, y) in &data[..1500] {
            dkf.step(u, y).unwrap();
        }
        let state = dkf.dynamic_state();
        let mut copy = DualKalmanFilter::new(oe_config()).unwrap();
        copy.set_dynamic_state(&state).unwrap();
        for (u, _, y) in &data[1500..] {
            dkf.step(u, y).unwrap();
            copy.step(u, y).unwrap();
        }
        assert_eq!(copy.theta(), dkf.theta());
        let a_error = (dkf.a() - &t.a).amax();
        let b_error = (dkf.b() - &t.b).amax();
        assert!(a_error < 0.02, "Â = {}", dkf.a());
        assert!(b_error < 0.02, "B̂ = {}", dkf.b());
        assert_eq!(dkf.output_error_covariance().unwrap().nrows(), 6);
        let mut free_c = oe_config();
        free_c.parameter_p0.fill(1.0);
        let e = DualKalmanFilter::new(free_c).unwrap_err();
        assert!(e.to_string().contains("C and D known"), "{e}");
        // n = 40, m = 20: 2400 free entries of [A B], above the bound: refused at once
        let (n, m) = (40, 20);
        let mut large = DualKalmanConfig::new(GaussianModel {
            system: StateSpace {
                a: DMatrix::identity(n, n) * 0.5,
                b: DMatrix::zeros(n, m),
                c: DMatrix::identity(1, n),
                d: DMatrix::zeros(1, m),
                q: DMatrix::identity(n, n) * 1e-4,
                r: DMatrix::identity(1, 1),
            },
            x0: DVector::zeros(n),
            p0: DMatrix::identity(n, n),
        })
        .fix_output_matrices();
        large.parameter_p0.rows_mut(0, n).fill(1e-1);
        large.measurement = ParameterMeasurement::OutputError;
        let e = DualKalmanFilter::new(large).unwrap_err();
        assert!(
            e.to_string()
                .contains("at most 2000 free entries of [A B], got 2400"),
            "{e}"
        );
    }

    /// The former parameter-filter step (before the symmetric Joseph update), kept as the
    /// reference: per group Σ⁻ = Σ + diag(q̃), s = Σ⁻Φ, d, g, the rows of Θ one by one, then
    /// Σ = Σ⁻ − g sᵀ − s gᵀ + d g gᵀ on the full matrix and (Σ + Σᵀ)/2.
    fn former_parameter_step(
        groups: &mut [ParameterGroup],
        theta: &mut DMatrix<f64>,
        phi: &[f64],
        target: &[f64],
        cap: f64,
    ) {
        let cols = phi.len();
        let (mut s, mut g) = (vec![0.0; cols], vec![0.0; cols]);
        for group in groups.iter_mut().filter(|g| !g.fixed) {
            for (i, q) in group.q_diag.iter().enumerate() {
                let room = (cap - group.sigma[(i, i)]).max(0.0);
                group.sigma[(i, i)] += q.min(room);
            }
            dense::gemv(&mut s, 1.0, View::of(&group.sigma), phi, 0.0);
            let denominator = dense::dot(phi, &s) + group.r;
            for (g, s) in g.iter_mut().zip(s.iter()) {
                *g = s / denominator;
            }
            let ld = theta.nrows();
            let theta = theta.as_mut_slice();
            for &row in &group.rows {
                let theta_row = &mut theta[row..];
                let prediction: f64 = theta_row
                    .iter()
                    .step_by(ld)
                    .zip(phi)
                    .map(|(t, f)| t * f)
                    .sum();
                let error = target[row] - prediction;
                for (t, g) in theta_row.iter_mut().step_by(ld).zip(g.iter()) {
                    *t += g * error;
                }
            }
            for (j, column) in group
                .sigma
                .as_mut_slice()
                .chunks_exact_mut(cols)
                .enumerate()
            {
                let (minus_s, minus_g, d_g) = (-s[j], -g[j], denominator * g[j]);
                for ((sigma, gi), si) in column.iter_mut().zip(g.iter()).zip(s.iter()) {
                    *sigma = d_g * gi + (minus_g * si + (minus_s * gi + *sigma));
                }
            }
            // (Σ + Σᵀ)/2, as the former code's dense::symmetrize did it.
            let sigma = group.sigma.as_mut_slice();
            for j in 0..cols {
                for i in j + 1..cols {
                    let mean = 0.5 * (sigma[i + j * cols] + sigma[j + i * cols]);
                    sigma[i + j * cols] = mean;
                    sigma[j + i * cols] = mean;
                }
            }
        }
    }

    /// The symmetric Joseph update against the former full-matrix one, from the same
    /// state at each of 6000 random steps (n = 8, m = 2 at fixed size 10 with fixed C/D
    /// rows; n = 3, m = 1 with two known rows, three groups and a variance bound at run-time
    /// size 4): Θ bit for bit, every Σ within 1e-12 of its largest entry, exactly symmetric
    /// and positive definite; the fixed-size step equals the run-time-size one bit for bit.
    #[test]
    fn the_symmetric_joseph_update_matches_the_former_full_matrix_one() {
        let model = |n: usize, m: usize, p: usize| GaussianModel {
            system: StateSpace {
                a: DMatrix::identity(n, n) * 0.9,
                b: DMatrix::from_element(n, m, 0.1),
                c: DMatrix::identity(p, n),
                d: DMatrix::zeros(p, m),
                q: DMatrix::identity(n, n) * 1e-4,
                r: DMatrix::identity(p, p) * 1e-2,
            },
            x0: DVector::zeros(n),
            p0: DMatrix::identity(n, n),
        };
        let generator = DualKalmanConfig::new(model(8, 2, 2)).fix_output_matrices();
        let mut small = DualKalmanConfig::new(model(3, 1, 2)).fix_state_rows(&[0, 1]);
        small.parameter_q.row_mut(2).fill(1e-3);
        small.parameter_r[4] = 0.2;
        small.bounds.max_variance = 1.2;
        let mut rng = TestRng::new(17);
        let mut worst: f64 = 0.0;
        for (config, groups) in [(generator, 2), (small, 4)] {
            let mut dkf = DualKalmanFilter::new(config).unwrap();
            assert_eq!(dkf.groups.len(), groups);
            let (rows, cols) = dkf.theta.shape();
            let cap = dkf.bounds.max_variance;
            for step in 0..3000 {
                // Regressors from tiny to large, now and then one direction only.
                let scale = 10f64.powf(3.0 * rng.uniform() - 2.0);
                let lone = (step % 7 == 0).then(|| step % cols);
                for (j, f) in dkf.regressor.iter_mut().enumerate() {
                    *f = if lone.is_some_and(|l| l != j) {
                        0.0
                    } else {
                        scale * rng.normal()
                    };
                }
                for y in dkf.target.iter_mut() {
                    *y = scale * rng.normal();
                }
                let (mut groups, mut theta) = (dkf.groups.clone(), dkf.theta.clone());
                former_parameter_step(
                    &mut groups,
                    &mut theta,
                    dkf.regressor.as_slice(),
                    dkf.target.as_slice(),
                    cap,
                );
                // The same step with the sizes taken at run time.
                let (mut runtime_groups, mut runtime_theta) =
                    (dkf.groups.clone(), dkf.theta.clone());
                let (mut s, mut g, mut e) = (vec![0.0; cols], vec![0.0; cols], vec![0.0; rows]);
                let work = ParameterWork {
                    phi: dkf.regressor.as_slice(),
                    target: dkf.target.as_slice(),
                    s: &mut s,
                    g: &mut g,
                    e: &mut e,
                    cap,
                };
                parameter_step::<0>(&mut runtime_groups, &mut runtime_theta, work).unwrap();
                dkf.update_parameters().unwrap();
                assert_eq!(dkf.theta, runtime_theta, "step {step}");
                for (fixed, runtime) in dkf.groups.iter().zip(&runtime_groups) {
                    assert_eq!(fixed.sigma, runtime.sigma, "step {step}");
                }
                assert_eq!(dkf.theta, theta, "step {step}");
                assert_eq!(dkf.theta.shape(), (rows, cols));
                for (new, former) in dkf.groups.iter().zip(&groups) {
                    let size = former.sigma.amax();
                    let error = (&new.sigma - &former.sigma).amax();
                    worst = worst.max(error / size);
                    assert!(error <= 1e-12 * size, "step {step}: |ΔΣ| = {error:e}");
                    assert_eq!(new.sigma, new.sigma.transpose());
                    if !new.fixed {
                        assert!(new.sigma.clone().cholesky().is_some(), "step {step}");
                    }
                }
            }
        }
        println!("largest |ΔΣ| / max|Σ| = {worst:e}");
        assert!(worst > 0.0, "the two forms differ in rounding somewhere");
    }

    /// The fixed-size λ_min of the excitation gate equals the dynamic one bit for bit, on
    /// random moments (well and badly conditioned, rank deficient) of every packaged size.
    #[test]
    fn the_fixed_size_smallest_eigenvalue_is_the_dynamic_one() {
        let mut rng = TestRng::new(5);
        for size in [3, 5, 10, 4] {
            for trial in 0..300 {
                let rank = if trial % 3 == 0 { size - 1 } else { size };
                let factor = DMatrix::from_fn(size, rank, |_, _| rng.normal());
                let scale = 10f64.powi(trial % 7 - 3);
                let mut moment = &factor * factor.transpose() * scale;
                symmetrize_in_place(&mut moment);
                let dynamic = moment
                    .symmetric_eigenvalues()
                    .iter()
                    .copied()
                    .fold(f64::INFINITY, f64::min);
                let fixed = smallest_eigenvalue(&moment);
                assert_eq!(
                    fixed.to_bits(),
                    dynamic.to_bits(),
                    "size {size}, trial {trial}"
                );
                if rank < size {
                    assert!(fixed.abs() < 1e-12 * scale * size as f64, "λ_min = {fixed}");
                }
            }
        }
    }

    /// [`config`] with the excitation gate on (ε_min = 1e-2 over 10 samples).
    fn gated_config() -> DualKalmanConfig {
        let mut cfg = config(1e-4);
        cfg.bounds.excitation_min = 1e-2;
        cfg.bounds.excitation_window = 10.0;
        cfg
    }
}
