//! Linear-algebra helpers shared by the estimators and controllers (docs/estimators.md §2.7–§2.12, docs/controllers.md §2.13–§2.14).
//!
//! Everything works on dynamic `DMatrix<f64>` because the FMUs choose their dimensions at
//! packaging or instantiation time.
//!
//! * [`MatrixExponential`] (allocation-free on kept buffers), [`expm`]: the matrix
//!   exponential `e^A` by scaling and squaring with Padé approximants (Higham, "The scaling
//!   and squaring method for the matrix exponential revisited", SIAM J. Matrix Anal. Appl.
//!   26(4), 2005): `e^A = (r_m(A / 2^s))^(2^s)`, `r_m = q_m(X)⁻¹ p_m(X)`, the degree
//!   m ∈ {3, 5, 7, 9, 13} and `s` chosen from the norms of A's powers.
//! * [`zoh`]: zero-order-hold discretisation. With `M = [[A, B], [0, 0]]·Ts`,
//!   `e^M = [[A_d, B_d], [0, I]]`, i.e. `A_d = e^{A Ts}`, `B_d = ∫₀^Ts e^{A τ} dτ B`
//!   (used for the crane of paper 000 at Ts = 0.05 s).
//! * [`Dare::solve`]: the stabilising solution of the control discrete algebraic Riccati
//!   equation
//!   `P = AᵀPA − AᵀPB (R + BᵀPB)⁻¹ BᵀPA + Q`
//!   by the structured doubling algorithm (SDA; Chu, Fan, Lin & Wang, "Structure-preserving
//!   algorithms for periodic discrete-time algebraic Riccati equations", Int. J. Control
//!   77(8), 2004). With `G = B R⁻¹ Bᵀ`, `A₀ = A`, `G₀ = G`, `H₀ = Q` and `W_k = I + G_k H_k`:
//!   `A_{k+1} = A_k W_k⁻¹ A_k`, `G_{k+1} = G_k + A_k W_k⁻¹ G_k A_kᵀ`,
//!   `H_{k+1} = H_k + A_kᵀ H_k W_k⁻¹ A_k`; `H_k → P` quadratically when (A, B) is
//!   stabilisable and (A, Q^{1/2}) has no unobservable mode on the unit circle. The result
//!   is symmetrised and checked: finite, residual small, and `A − B K` Schur stable.
//! * [`Dare::regulator`]: discrete LQ regulator, `K = (R + BᵀPB)⁻¹ BᵀPA`, `u = −K x`.
//! * [`kalman_gain_steady`]: steady-state Kalman filter by duality: the predicted covariance
//!   `P⁻` solves DARE(Aᵀ, Cᵀ, Q, R), the filter gain is `K = P⁻Cᵀ (C P⁻ Cᵀ + R)⁻¹`
//!   (docs/estimators.md §2.7; scalar A = C = 1, Q = R gives K = (√5 − 1)/2, docs/reference-values.md §6).
//! * [`cholesky_solve`], [`symmetrize`], [`is_positive_definite`]: the small tools that keep
//!   covariances symmetric positive definite and avoid explicit inverses.
//!
//! Nothing here panics on bad input: the fallible functions return [`LinalgError`], which
//! names the matrix and says why.

use nalgebra::{Cholesky, DMatrix, DVector};
use std::fmt;

/// Why a linear-algebra routine could not produce a result.
#[derive(Debug, Clone, PartialEq)]
pub enum LinalgError {
    /// A matrix that must be square is not.
    NotSquare {
        /// Which matrix (e.g. `"A"`, `"R"`).
        what: String,
        /// Its rows.
        rows: usize,
        /// Its columns.
        cols: usize,
    },
    /// Two matrices do not fit together.
    DimensionMismatch {
        /// Which matrix has the wrong shape.
        what: String,
        /// The shape it must have, `(rows, cols)`.
        expected: (usize, usize),
        /// The shape it has.
        got: (usize, usize),
    },
    /// A matrix holds NaN or an infinity.
    NonFinite {
        /// Which matrix.
        what: String,
    },
    /// A matrix too large for its exponential: its 1-norm overflows `f64`, so no number of
    /// squarings `s` brings `‖A‖₁ / 2^s` into the range of the Padé approximant.
    NormOverflow {
        /// Which matrix.
        what: String,
    },
    /// A matrix that must be symmetric positive definite is not.
    NotPositiveDefinite {
        /// Which matrix (e.g. `"R"`, `"R + BᵀPB"`).
        what: String,
    },
    /// A matrix that must be invertible is (numerically) singular.
    Singular {
        /// Which matrix.
        what: String,
    },
    /// The Riccati iteration did not converge (typically (A, B) not stabilisable).
    NoConvergence {
        /// Iterations performed.
        iterations: usize,
        /// Last relative change `‖P_{k+1} − P_k‖₁ / max(1, ‖P_{k+1}‖₁)`.
        relative_change: f64,
    },
    /// The Riccati solution does not satisfy the equation to the required accuracy.
    InaccurateSolution {
        /// Relative residual `‖res‖₁ / max(1, ‖P‖₁)`.
        relative_residual: f64,
    },
    /// The Riccati solution does not stabilise the closed loop `A − B K`.
    NotStabilising {
        /// Spectral radius of `A − B K` (must be < 1).
        spectral_radius: f64,
    },
}

impl fmt::Display for LinalgError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::NotSquare { what, rows, cols } => {
                write!(f, "matrix {what} must be square, got {rows}×{cols}")
            }
            Self::DimensionMismatch {
                what,
                expected,
                got,
            } => write!(
                f,
                "matrix {what} must be {}×{}, got {}×{}",
                expected.0, expected.1, got.0, got.1
            ),
            Self::NonFinite { what } => write!(f, "matrix {what} contains NaN or infinity"),
            Self::NormOverflow { what } => write!(
                f,
                "matrix {what} is too large for its exponential: its 1-norm exceeds the \
                 largest double, {:e}",
                f64::MAX
            ),
            Self::NotPositiveDefinite { what } => {
                write!(f, "matrix {what} is not symmetric positive definite")
            }
            Self::Singular { what } => write!(f, "matrix {what} is singular"),
            Self::NoConvergence {
                iterations,
                relative_change,
            } => write!(
                f,
                "Riccati iteration did not converge after {iterations} iterations (last relative \
                 change {relative_change:e}); is (A, B) stabilisable?"
            ),
            Self::InaccurateSolution { relative_residual } => write!(
                f,
                "Riccati solution is inaccurate (relative residual {relative_residual:e})"
            ),
            Self::NotStabilising { spectral_radius } => write!(
                f,
                "no stabilising Riccati solution: closed-loop spectral radius \
                 {spectral_radius} >= 1 (is (A, B) stabilisable and (A, Q) detectable?)"
            ),
        }
    }
}

impl std::error::Error for LinalgError {}

/// Relative asymmetry accepted for a "symmetric" matrix: `|m_ij − m_ji| ≤ tol · max|m|`.
const SYMMETRY_TOLERANCE: f64 = 1e-8;
/// Maximum number of doubling steps in [`Dare::solve`] (each one squares the convergence
/// factor, so 100 is far beyond what any stabilisable problem needs).
const DARE_MAX_ITERATIONS: usize = 100;
/// Relative change below which the doubling iteration is converged.
const DARE_TOLERANCE: f64 = 1e-14;
/// Relative residual above which a Riccati solution is rejected.
const DARE_RESIDUAL_LIMIT: f64 = 1e-8;
/// Margin below 1 that the closed-loop spectral radius must keep.
const STABILITY_MARGIN: f64 = 1e-10;

fn require_square(what: &str, m: &DMatrix<f64>) -> Result<usize, LinalgError> {
    if m.is_square() {
        Ok(m.nrows())
    } else {
        Err(LinalgError::NotSquare {
            what: what.to_string(),
            rows: m.nrows(),
            cols: m.ncols(),
        })
    }
}

fn require_shape(
    what: &str,
    m: &DMatrix<f64>,
    rows: usize,
    cols: usize,
) -> Result<(), LinalgError> {
    if m.shape() == (rows, cols) {
        Ok(())
    } else {
        Err(LinalgError::DimensionMismatch {
            what: what.to_string(),
            expected: (rows, cols),
            got: m.shape(),
        })
    }
}

fn require_finite(what: &str, m: &DMatrix<f64>) -> Result<(), LinalgError> {
    if m.iter().all(|v| v.is_finite()) {
        Ok(())
    } else {
        Err(LinalgError::NonFinite {
            what: what.to_string(),
        })
    }
}

fn is_symmetric(m: &DMatrix<f64>) -> bool {
    if !m.is_square() {
        return false;
    }
    let scale = m.amax();
    let n = m.nrows();
    (0..n).all(|i| (0..i).all(|j| (m[(i, j)] - m[(j, i)]).abs() <= SYMMETRY_TOLERANCE * scale))
}

/// Induced 1-norm (maximum absolute column sum).
fn norm1(m: &DMatrix<f64>) -> f64 {
    m.column_iter()
        .map(|c| c.iter().map(|v| v.abs()).sum::<f64>())
        .fold(0.0, f64::max)
}

/// Replaces `m` by `(m + mᵀ)/2` (a non-square matrix is left unchanged).
pub fn symmetrize(m: &mut DMatrix<f64>) {
    if !m.is_square() {
        return;
    }
    let n = m.nrows();
    for i in 0..n {
        for j in 0..i {
            let mean = 0.5 * (m[(i, j)] + m[(j, i)]);
            m[(i, j)] = mean;
            m[(j, i)] = mean;
        }
    }
}

/// `true` when `m` is square, finite, symmetric (to a relative 1e-8) and its Cholesky
/// factorisation exists (all leading minors positive).
pub fn is_positive_definite(m: &DMatrix<f64>) -> bool {
    m.nrows() > 0
        && m.is_square()
        && m.iter().all(|v| v.is_finite())
        && is_symmetric(m)
        && Cholesky::new(m.clone()).is_some()
}

/// Solves `m X = rhs` for symmetric positive definite `m` by a Cholesky factorisation.
///
/// `what` names `m` in the error (e.g. `"C P Cᵀ + R"`). `m` may be asymmetric by round-off
/// (relative 1e-8): its symmetric part is factorised.
pub fn cholesky_solve(
    m: &DMatrix<f64>,
    rhs: &DMatrix<f64>,
    what: &str,
) -> Result<DMatrix<f64>, LinalgError> {
    let n = require_square(what, m)?;
    require_shape("right-hand side", rhs, n, rhs.ncols())?;
    require_finite(what, m)?;
    require_finite("right-hand side", rhs)?;
    let not_spd = || LinalgError::NotPositiveDefinite {
        what: what.to_string(),
    };
    if n == 0 || !is_symmetric(m) {
        return Err(not_spd());
    }
    let mut symmetric = m.clone();
    symmetrize(&mut symmetric);
    let factor = Cholesky::new(symmetric).ok_or_else(not_spd)?;
    let solution = factor.solve(rhs);
    require_finite(&format!("solution of ({what}) X = rhs"), &solution)?;
    Ok(solution)
}

/// Solves `m X = rhs` for a general square `m` by LU with partial pivoting.
fn lu_solve(m: &DMatrix<f64>, rhs: &DMatrix<f64>, what: &str) -> Result<DMatrix<f64>, LinalgError> {
    let solution = m
        .clone()
        .lu()
        .solve(rhs)
        .ok_or_else(|| LinalgError::Singular {
            what: what.to_string(),
        })?;
    if solution.iter().all(|v| v.is_finite()) {
        Ok(solution)
    } else {
        Err(LinalgError::Singular {
            what: what.to_string(),
        })
    }
}

/// Padé(13) coefficients b₀…b₁₃ (Higham 2005, Table 10.4 / expm.m).
const PADE13: [f64; 14] = [
    64_764_752_532_480_000.0,
    32_382_376_266_240_000.0,
    7_771_770_303_897_600.0,
    1_187_353_796_428_800.0,
    129_060_195_264_000.0,
    10_559_470_521_600.0,
    670_442_572_800.0,
    33_522_128_640.0,
    1_323_241_920.0,
    40_840_800.0,
    960_960.0,
    16_380.0,
    182.0,
    1.0,
];
/// Padé(3), (5), (7), (9) coefficients b₀…b_m of r_m = q_m⁻¹ p_m (Higham 2005, Table 10.4 /
/// expm.m).
const PADE3: [f64; 4] = [120.0, 60.0, 12.0, 1.0];
const PADE5: [f64; 6] = [30_240.0, 15_120.0, 3_360.0, 420.0, 30.0, 1.0];
const PADE7: [f64; 8] = [
    17_297_280.0,
    8_648_640.0,
    1_995_840.0,
    277_200.0,
    25_200.0,
    1_512.0,
    56.0,
    1.0,
];
const PADE9: [f64; 10] = [
    17_643_225_600.0,
    8_821_612_800.0,
    2_075_673_600.0,
    302_702_400.0,
    30_270_240.0,
    2_162_160.0,
    110_880.0,
    3_960.0,
    90.0,
    1.0,
];
/// θ₃, θ₅, θ₇, θ₉: the largest norm for which r_m reaches double precision (Higham 2005,
/// Table 2.3), compared with the norm estimates η.
const THETA3: f64 = 1.495_585_217_958_292e-2;
const THETA5: f64 = 2.539_398_330_063_23e-1;
const THETA7: f64 = 9.504_178_996_162_932e-1;
const THETA9: f64 = 2.097_847_961_257_068;
/// The η₅ that r₁₃ takes before ℓ adds squarings (Al-Mohy & Higham 2009, Algorithm 5.1).
const THETA13_SCALED: f64 = 4.25;

/// What [`try_expm`] names when `e^A` overflows.
const EXPM_OVERFLOW: &str = "e^A (overflow)";

/// `n!` (exact in `u128` up to 34!).
fn factorial(n: u32) -> u128 {
    (1..=u128::from(n)).product()
}

/// The matrix exponential `e^A` of `n × n` matrices on buffers made once: [`Self::exp_into`]
/// allocates nothing (the EKF's state-transition matrix Φ_xx = e^{½h(A₀+A₁)} every sample,
/// docs/estimators.md; [`try_expm`] and [`try_zoh`] make one per call).
///
/// Scaling and squaring with the diagonal Padé approximants `r_m = q_m⁻¹ p_m`, m ∈ {3, 5, 7,
/// 9, 13} (Higham, "The scaling and squaring method for the matrix exponential revisited",
/// SIAM J. Matrix Anal. Appl. 26(4), 2005), the degree and the squarings chosen as in
/// Al-Mohy & Higham, "A new scaling and squaring algorithm for the matrix exponential",
/// SIAM J. Matrix Anal. Appl. 31(3), 2009, Algorithm 5.1: the algorithm of scipy's and
/// nalgebra 0.35's `expm`, operation for operation, so the result is `DMatrix::exp`'s bit
/// for bit.
///
/// * `p_m(X) = V + U`, `q_m(X) = V − U`, with the odd part `U = X Σ_k b_{2k+1} X^{2k}` and
///   the even part `V = Σ_k b_{2k} X^{2k}` (b from the tables above);
/// * with `d_p = ‖A^p‖₁^{1/p}` (≤ ‖A‖₁, ≥ the spectral radius), `η₁ = max(d₄, d₆)`,
///   `η₃ = max(d₆, d₈)`: m = 3 if `η₁ < θ₃`, m = 5 if `η₁ < θ₅`, m = 7 if `η₃ < θ₇`,
///   m = 9 if `η₃ < θ₉`, each only where the backward-error correction
///   `ℓ(A, m) = max(0, ⌈log₂(α / u) / 2m⌉)` is 0, `α = ‖|A|^{2m+1}‖₁ / (‖A‖₁ C(2m, m)
///   (2m+1)!)`, `u = 2⁻⁵³`;
/// * otherwise `e^A = r₁₃(A / 2^s)^{2^s}` by `s` squarings,
///   `s = max(0, ⌈log₂(η₅ / 4.25)⌉) + ℓ(A / 2^s, 13)`, `η₅ = min(η₃, max(d₈, d₁₀))` (‖A‖₁
///   where a power overflows).
///
/// `q_m X = p_m` is solved by LU with partial pivoting in place (nalgebra's Gauss steps; the
/// row interchanges kept in a vector of capacity n).
#[derive(Debug, Clone)]
pub struct MatrixExponential {
    /// A, then A / 2^s.
    a: DMatrix<f64>,
    /// A², A⁴, A⁶, A⁸, A¹⁰: the first `powers_known`, then (degree 13) scaled by 2^{−2ks}.
    powers: [DMatrix<f64>; 5],
    powers_known: usize,
    /// The work of ℓ.
    backward_error: BackwardErrorWork,
    /// A sum of powers, a product of matrices, U, and V (then q_m and its LU factors).
    sum: DMatrix<f64>,
    product: DMatrix<f64>,
    odd: DMatrix<f64>,
    even: DMatrix<f64>,
    /// The LU's row interchanges (i, pivot row), in order.
    interchanges: Vec<(usize, usize)>,
    /// The degree m and the squarings s of the last exponential (0, 0 for n ≤ 1).
    degree_and_squarings: (usize, u64),
}

/// The buffers of `ℓ(B, m)`: |B|ᵀ and the two vectors of the power iteration
/// `v ← |B|ᵀ v` from `v = 1`, whose largest entry is ‖|B|^p‖₁.
#[derive(Debug, Clone)]
struct BackwardErrorWork {
    absolute: DMatrix<f64>,
    absolute_t: DMatrix<f64>,
    vectors: (DVector<f64>, DVector<f64>),
}

impl BackwardErrorWork {
    /// `ℓ(b, m)` (see [`MatrixExponential`]).
    fn ell(&mut self, b: &DMatrix<f64>, m: u32) -> u64 {
        self.absolute.zip_apply(b, |x, y| *x = y.abs());
        self.absolute.transpose_to(&mut self.absolute_t);
        let (v, next) = &mut self.vectors;
        v.fill(1.0);
        for _ in 0..2 * m + 1 {
            self.absolute_t.mul_to(v, next);
            std::mem::swap(v, next);
        }
        let power_norm = v.max();
        if power_norm == 0.0 {
            return 0;
        }
        let m_factorial = factorial(m);
        let choose_2m_m = factorial(2 * m) / (m_factorial * m_factorial);
        let coefficient_reciprocal = choose_2m_m * factorial(2 * m + 1);
        let alpha = power_norm / b.one_norm() / coefficient_reciprocal as f64;
        let unit_roundoff = 2_f64.powf(-53.0);
        let value = ((alpha / unit_roundoff).log2() / (2.0 * f64::from(m))).ceil();
        if value > 0.0 {
            value as u64
        } else {
            0
        }
    }
}

/// `out = start + Σ (X c) [+ c_I I]`, entry by entry in this order (nalgebra's
/// `X * c + …`); without `start` the sum begins with the first term.
fn combine(
    out: &mut DMatrix<f64>,
    start: Option<&DMatrix<f64>>,
    terms: &[(&DMatrix<f64>, f64)],
    identity: Option<f64>,
) {
    let n = out.nrows();
    for (index, entry) in out.as_mut_slice().iter_mut().enumerate() {
        let mut rest = terms.iter();
        let mut value = match (start, rest.next()) {
            (Some(start), Some((x, c))) => start.as_slice()[index] + x.as_slice()[index] * c,
            (Some(start), None) => start.as_slice()[index],
            (None, Some((x, c))) => x.as_slice()[index] * c,
            (None, None) => 0.0,
        };
        for (x, c) in rest {
            value += x.as_slice()[index] * c;
        }
        if let Some(identity) = identity {
            value += if index % (n + 1) == 0 { identity } else { 0.0 };
        }
        *entry = value;
    }
}

impl MatrixExponential {
    /// Buffers for the exponential of `n × n` matrices.
    pub fn new(n: usize) -> Self {
        let square = || DMatrix::zeros(n, n);
        Self {
            a: square(),
            powers: [square(), square(), square(), square(), square()],
            powers_known: 0,
            backward_error: BackwardErrorWork {
                absolute: square(),
                absolute_t: square(),
                vectors: (DVector::zeros(n), DVector::zeros(n)),
            },
            sum: square(),
            product: square(),
            odd: square(),
            even: square(),
            interchanges: Vec::with_capacity(n),
            degree_and_squarings: (0, 0),
        }
    }

    /// The order `n` of the matrices these buffers are for.
    pub fn order(&self) -> usize {
        self.a.nrows()
    }

    /// The Padé degree m and the squarings s of the last [`Self::exp_into`] (0, 0 when
    /// n ≤ 1 or it failed before).
    pub fn degree_and_squarings(&self) -> (usize, u64) {
        self.degree_and_squarings
    }

    /// `out = e^a` (see the type's doc), allocating nothing but an error's text.
    ///
    /// Errors: `a` or `out` not `n × n` ([`LinalgError::DimensionMismatch`]), `a` not finite
    /// ([`LinalgError::NonFinite`]), ‖a‖₁ beyond `f64` ([`LinalgError::NormOverflow`]), a
    /// singular Padé denominator ([`LinalgError::Singular`]) or an overflowing result
    /// ([`LinalgError::NonFinite`] naming `e^A (overflow)`); `out` is then unspecified.
    pub fn exp_into(
        &mut self,
        a: &DMatrix<f64>,
        out: &mut DMatrix<f64>,
    ) -> Result<(), LinalgError> {
        let n = self.order();
        require_shape("A", a, n, n)?;
        require_shape("e^A", out, n, n)?;
        require_finite("A", a)?;
        let norm = a.one_norm();
        if !norm.is_finite() {
            // ‖A‖₁ = ∞ would ask for 2^s ≥ ∞ squarings.
            return Err(LinalgError::NormOverflow {
                what: "A".to_string(),
            });
        }
        self.degree_and_squarings = (0, 0);
        match n {
            0 => return Ok(()),
            1 => out[(0, 0)] = a[(0, 0)].exp(),
            _ => self.pade_scaled_and_squared(a, norm, out)?,
        }
        require_finite(EXPM_OVERFLOW, out)
    }

    /// `out = r_m(A / 2^s)^{2^s}` with m and s chosen from `a` (n ≥ 2, ‖a‖₁ = `norm` finite).
    fn pade_scaled_and_squared(
        &mut self,
        a: &DMatrix<f64>,
        norm: f64,
        out: &mut DMatrix<f64>,
    ) -> Result<(), LinalgError> {
        self.a.copy_from(a);
        self.powers_known = 0;
        let eta_1 = self.d(2).max(self.d(3));
        if eta_1 < THETA3 && self.backward_error.ell(&self.a, 3) == 0 {
            return self.pade(&PADE3, out);
        }
        if eta_1 < THETA5 && self.backward_error.ell(&self.a, 5) == 0 {
            return self.pade(&PADE5, out);
        }
        let eta_3 = self.d(3).max(self.d(4));
        if eta_3 < THETA7 && self.backward_error.ell(&self.a, 7) == 0 {
            return self.pade(&PADE7, out);
        }
        if eta_3 < THETA9 && self.backward_error.ell(&self.a, 9) == 0 {
            return self.pade(&PADE9, out);
        }
        let eta_4 = self.d(4).max(self.d(5));
        let eta_5 = eta_3.min(eta_4);
        let eta_5 = if eta_5.is_finite() { eta_5 } else { norm };
        let mut squarings = if eta_5 == 0.0 {
            0
        } else {
            let l2 = (eta_5 / THETA13_SCALED).log2().ceil();
            if l2 < 0.0 {
                0
            } else {
                l2 as u64
            }
        };
        let scale = 2.0_f64.powf(-(squarings as f64));
        self.sum.zip_apply(&self.a, |x, y| *x = y * scale);
        squarings += self.backward_error.ell(&self.sum, 13);
        self.degree_and_squarings = (13, squarings);
        self.pade13_scaled(squarings, out)?;
        for _ in 0..squarings {
            out.mul_to(&*out, &mut self.product);
            std::mem::swap(out, &mut self.product);
        }
        Ok(())
    }

    /// A^{2k} (k = 1…5), computing the missing ones: A² = A A, A⁴ = A² A², A⁶ = A⁴ A²,
    /// A⁸ = A⁶ A², A¹⁰ = A⁶ A⁴.
    fn even_power(&mut self, k: usize) -> &DMatrix<f64> {
        while self.powers_known < k {
            let [a2, a4, a6, a8, a10] = &mut self.powers;
            match self.powers_known {
                0 => self.a.mul_to(&self.a, a2),
                1 => a2.mul_to(a2, a4),
                2 => a4.mul_to(a2, a6),
                3 => a6.mul_to(a2, a8),
                _ => a6.mul_to(a4, a10),
            }
            self.powers_known += 1;
        }
        &self.powers[k - 1]
    }

    /// `d_{2k} = ‖A^{2k}‖₁^{1/2k}`.
    fn d(&mut self, k: usize) -> f64 {
        self.even_power(k).one_norm().powf(1.0 / (2 * k) as f64)
    }

    /// `out = r_m(A)` for m = `b.len() − 1` ∈ {3, 5, 7, 9} (A², …, A^{m−1} known).
    fn pade(&mut self, b: &[f64], out: &mut DMatrix<f64>) -> Result<(), LinalgError> {
        self.degree_and_squarings = (b.len() - 1, 0);
        let half = (b.len() - 2) / 2;
        let [a2, a4, a6, a8, _] = &self.powers;
        let powers = [a2, a4, a6, a8];
        // The highest power first: U = A (b_m A^{m−1} + … + b₃ A² + b₁ I).
        let odd_terms = [3, 2, 1, 0].map(|k| (powers[k], b[(2 * k + 3).min(b.len() - 1)]));
        let even_terms = [3, 2, 1, 0].map(|k| (powers[k], b[(2 * k + 2).min(b.len() - 1)]));
        combine(&mut self.sum, None, &odd_terms[4 - half..], Some(b[1]));
        self.a.mul_to(&self.sum, &mut self.odd);
        combine(&mut self.even, None, &even_terms[4 - half..], Some(b[0]));
        self.solve(out)
    }

    /// `out = r₁₃(A / 2^s)` (A², A⁴, A⁶ known), scaling A and its powers in place.
    fn pade13_scaled(&mut self, squarings: u64, out: &mut DMatrix<f64>) -> Result<(), LinalgError> {
        let b = &PADE13;
        let s = squarings as f64;
        self.even_power(3);
        self.a.scale_mut(2.0_f64.powf(-s));
        let [x2, x4, x6, _, _] = &mut self.powers;
        x2.scale_mut(2.0_f64.powf(-2.0 * s));
        x4.scale_mut(2.0_f64.powf(-4.0 * s));
        x6.scale_mut(2.0_f64.powf(-6.0 * s));
        let (x2, x4, x6) = (&*x2, &*x4, &*x6);
        // U = X [X⁶(b₁₃X⁶ + b₁₁X⁴ + b₉X²) + b₇X⁶ + b₅X⁴ + b₃X² + b₁I] (parity 1), then
        // V = X⁶(b₁₂X⁶ + b₁₀X⁴ + b₈X²) + b₆X⁶ + b₄X⁴ + b₂X² + b₀I (parity 0).
        for parity in [1, 0] {
            let inner = [
                (x6, b[12 + parity]),
                (x4, b[10 + parity]),
                (x2, b[8 + parity]),
            ];
            combine(&mut self.sum, None, &inner, None);
            x6.mul_to(&self.sum, &mut self.product);
            let outer = [
                (x6, b[6 + parity]),
                (x4, b[4 + parity]),
                (x2, b[2 + parity]),
            ];
            if parity == 1 {
                combine(&mut self.sum, Some(&self.product), &outer, Some(b[1]));
                self.a.mul_to(&self.sum, &mut self.odd);
            } else {
                combine(&mut self.even, Some(&self.product), &outer, Some(b[0]));
            }
        }
        self.solve(out)
    }

    /// `out = (V − U)⁻¹ (V + U)` from U = `odd`, V = `even` (`even` then holds the LU
    /// factors of V − U).
    fn solve(&mut self, out: &mut DMatrix<f64>) -> Result<(), LinalgError> {
        out.zip_zip_apply(&self.odd, &self.even, |p, u, v| *p = u + v);
        self.even.zip_apply(&self.odd, |q, u| *q -= u);
        let q = &mut self.even;
        let n = q.nrows();
        self.interchanges.clear();
        for i in 0..n {
            let pivot = q.view_range(i.., i).icamax() + i;
            let diagonal = q[(pivot, i)];
            if diagonal == 0.0 {
                continue;
            }
            if pivot != i {
                self.interchanges.push((i, pivot));
                q.columns_range_mut(..i).swap_rows(i, pivot);
                nalgebra::linalg::gauss_step_swap(q, diagonal, i, pivot);
            } else {
                nalgebra::linalg::gauss_step(q, diagonal, i);
            }
        }
        for &(i, pivot) in &self.interchanges {
            out.swap_rows(i, pivot);
        }
        // The unit diagonal is never zero: this always succeeds.
        let _ = q.solve_lower_triangular_with_diag_mut(out, 1.0);
        if q.solve_upper_triangular_mut(out) {
            Ok(())
        } else {
            Err(LinalgError::Singular {
                what: "Padé denominator q_m(A/2^s)".to_string(),
            })
        }
    }
}

/// The matrix exponential `e^a`, or an error for a non-square or non-finite matrix (one
/// [`MatrixExponential`] made for the call).
pub fn try_expm(a: &DMatrix<f64>) -> Result<DMatrix<f64>, LinalgError> {
    let n = require_square("A", a)?;
    let mut exponential = DMatrix::zeros(n, n);
    MatrixExponential::new(n).exp_into(a, &mut exponential)?;
    Ok(exponential)
}

/// The matrix exponential `e^a` (scaling and squaring with Padé approximants; see
/// [`MatrixExponential`]).
///
/// Accurate to about 1e-15 relative on well-scaled matrices. This never panics: a
/// non-square matrix gives a `rows × cols` matrix of NaN, and non-finite input (or overflow)
/// gives NaN entries. Use [`try_expm`] to get the reason as an error.
pub fn expm(a: &DMatrix<f64>) -> DMatrix<f64> {
    try_expm(a).unwrap_or_else(|_| DMatrix::from_element(a.nrows(), a.ncols(), f64::NAN))
}

/// Zero-order-hold discretisation of `ẋ = A x + B u` with sample time `ts`, or an error for
/// inconsistent dimensions, a non-finite matrix or a non-positive / non-finite `ts`.
pub fn try_zoh(
    a: &DMatrix<f64>,
    b: &DMatrix<f64>,
    ts: f64,
) -> Result<(DMatrix<f64>, DMatrix<f64>), LinalgError> {
    let n = require_square("A", a)?;
    require_shape("B", b, n, b.ncols())?;
    require_finite("A", a)?;
    require_finite("B", b)?;
    if !(ts.is_finite() && ts > 0.0) {
        return Err(LinalgError::NonFinite {
            what: format!("sample time Ts = {ts} (must be finite and > 0)"),
        });
    }
    let m = b.ncols();
    let mut augmented = DMatrix::<f64>::zeros(n + m, n + m);
    augmented.view_mut((0, 0), (n, n)).copy_from(&(a * ts));
    augmented.view_mut((0, n), (n, m)).copy_from(&(b * ts));
    let exponential = try_expm(&augmented).map_err(|e| match e {
        LinalgError::NormOverflow { .. } => LinalgError::NormOverflow {
            what: format!("[[A, B], [0, 0]]·Ts (Ts = {ts:e} s; a shorter Ts is needed)"),
        },
        // The norm is finite but e^{A Ts} is not: A grows too fast over Ts.
        LinalgError::NonFinite { what } if what == EXPM_OVERFLOW => LinalgError::NonFinite {
            what: format!(
                "e^([[A, B], [0, 0]]·Ts) (overflow: Ts = {ts:e} s is too long for this A; a \
                 shorter Ts is needed)"
            ),
        },
        other => other,
    })?;
    let a_d = exponential.view((0, 0), (n, n)).into_owned();
    let b_d = exponential.view((0, n), (n, m)).into_owned();
    Ok((a_d, b_d))
}

/// Zero-order-hold discretisation: `(A_d, B_d)` with `A_d = e^{A ts}`,
/// `B_d = ∫₀^ts e^{A τ} dτ B`, from the exponential of `[[A, B], [0, 0]]·ts`.
///
/// Never panics: on bad input (see [`try_zoh`]) both matrices are NaN of the shapes
/// `n × n` and `n × m` (`n` = rows of `a`, `m` = columns of `b`).
pub fn zoh(a: &DMatrix<f64>, b: &DMatrix<f64>, ts: f64) -> (DMatrix<f64>, DMatrix<f64>) {
    try_zoh(a, b, ts).unwrap_or_else(|_| {
        (
            DMatrix::from_element(a.nrows(), a.nrows(), f64::NAN),
            DMatrix::from_element(a.nrows(), b.ncols(), f64::NAN),
        )
    })
}

/// A control discrete algebraic Riccati equation
/// `P = AᵀPA − AᵀPB (R + BᵀPB)⁻¹ BᵀPA + Q`: its four matrices, `A` n×n, `B` n×m, `Q` n×n
/// symmetric positive semidefinite, `R` m×m symmetric positive definite, all finite.
#[derive(Debug, Clone, Copy)]
pub struct Dare<'a> {
    pub a: &'a DMatrix<f64>,
    pub b: &'a DMatrix<f64>,
    pub q: &'a DMatrix<f64>,
    pub r: &'a DMatrix<f64>,
}

impl Dare<'_> {
    /// Checks the requirements on the four matrices (see [`Dare`]), naming the bad one.
    fn check(&self) -> Result<(), LinalgError> {
        let Dare { a, b, q, r } = *self;
        let n = require_square("A", a)?;
        require_shape("B", b, n, b.ncols())?;
        let m = b.ncols();
        require_shape("Q", q, n, n)?;
        require_shape("R", r, m, m)?;
        for (what, mat) in [("A", a), ("B", b), ("Q", q), ("R", r)] {
            require_finite(what, mat)?;
        }
        let q_is_semidefinite = is_symmetric(q) && {
            let mut q_sym = q.clone();
            symmetrize(&mut q_sym);
            let smallest = q_sym.symmetric_eigenvalues().min();
            n == 0 || smallest >= -SYMMETRY_TOLERANCE * q.amax()
        };
        if !q_is_semidefinite {
            return Err(LinalgError::NotPositiveDefinite {
                what: "Q (must be symmetric positive semidefinite)".to_string(),
            });
        }
        if !is_positive_definite(r) {
            return Err(LinalgError::NotPositiveDefinite {
                what: "R".to_string(),
            });
        }
        Ok(())
    }

    /// Residual of the equation at `P`, `AᵀPA − AᵀPB (R + BᵀPB)⁻¹ BᵀPA + Q − P`.
    pub fn residual(&self, p: &DMatrix<f64>) -> Result<DMatrix<f64>, LinalgError> {
        self.check()?;
        Ok(self.checked_residual(p)?.0)
    }

    /// [`Dare::residual`] once [`Dare::check`] has passed (it is not repeated), with the gain
    /// `K = (R + BᵀPB)⁻¹ BᵀPA` it goes through (that of [`Dare::gain`]).
    fn checked_residual(
        &self,
        p: &DMatrix<f64>,
    ) -> Result<(DMatrix<f64>, DMatrix<f64>), LinalgError> {
        let Dare { a, b, q, r } = *self;
        require_shape("P", p, a.nrows(), a.nrows())?;
        let btpa = b.transpose() * p * a;
        let s = r + b.transpose() * p * b;
        let k = cholesky_solve(&s, &btpa, "R + BᵀPB")?;
        Ok((a.transpose() * p * a - btpa.transpose() * &k + q - p, k))
    }

    /// The regulator gain at `P`, `K = (R + BᵀPB)⁻¹ BᵀPA`.
    pub fn gain(&self, p: &DMatrix<f64>) -> Result<DMatrix<f64>, LinalgError> {
        let Dare { a, b, r, .. } = *self;
        let s = r + b.transpose() * p * b;
        cholesky_solve(&s, &(b.transpose() * p * a), "R + BᵀPB")
    }

    /// The discrete LQ regulator: `(K, P)` with `P` from [`Dare::solve`] and
    /// `K = (R + BᵀPB)⁻¹ BᵀPA`, so that `u = −K x` minimises `Σ xᵀQx + uᵀRu`.
    pub fn regulator(&self) -> Result<(DMatrix<f64>, DMatrix<f64>), LinalgError> {
        let (p, k) = self.solve_with_gain()?;
        Ok((k, p))
    }

    /// Its stabilising solution `P` (structured doubling; see the module doc). Errors when an
    /// input is malformed, when the iteration does not converge (typically (A, B) not
    /// stabilisable), when the relative residual exceeds 1e-8, or when `A − B K` is not Schur
    /// stable. The result is symmetric.
    pub fn solve(&self) -> Result<DMatrix<f64>, LinalgError> {
        Ok(self.solve_with_gain()?.0)
    }

    /// [`Dare::solve`] with the gain `K` at the solution, computed once for the residual, the
    /// stability check and [`Dare::regulator`].
    fn solve_with_gain(&self) -> Result<(DMatrix<f64>, DMatrix<f64>), LinalgError> {
        self.check()?;
        let Dare { a, b, q, r } = *self;
        let n = a.nrows();
        let identity = DMatrix::<f64>::identity(n, n);
        // G = B R⁻¹ Bᵀ
        let r_inv_bt = cholesky_solve(r, &b.transpose(), "R")?;
        let mut g = b * r_inv_bt;
        symmetrize(&mut g);
        let mut h = q.clone();
        symmetrize(&mut h);
        let mut a_k = a.clone();
        let mut relative_change = f64::INFINITY;
        let mut converged = false;
        let mut iterations = 0;
        while iterations < DARE_MAX_ITERATIONS {
            iterations += 1;
            let w = &identity + &g * &h;
            // W⁻¹ A_k and W⁻¹ G_k in one solve.
            let mut rhs = DMatrix::<f64>::zeros(n, 2 * n);
            rhs.view_mut((0, 0), (n, n)).copy_from(&a_k);
            rhs.view_mut((0, n), (n, n)).copy_from(&g);
            let solved = lu_solve(&w, &rhs, "I + G H (doubling step)")?;
            let w_inv_a = solved.view((0, 0), (n, n)).into_owned();
            let w_inv_g = solved.view((0, n), (n, n)).into_owned();
            let h_next = &h + a_k.transpose() * &h * &w_inv_a;
            let g_next = &g + &a_k * w_inv_g * a_k.transpose();
            let a_next = &a_k * &w_inv_a;
            if !(h_next.iter().all(|v| v.is_finite())
                && g_next.iter().all(|v| v.is_finite())
                && a_next.iter().all(|v| v.is_finite()))
            {
                return Err(LinalgError::NoConvergence {
                    iterations,
                    relative_change,
                });
            }
            relative_change = norm1(&(&h_next - &h)) / norm1(&h_next).max(1.0);
            h = h_next;
            g = g_next;
            a_k = a_next;
            symmetrize(&mut h);
            symmetrize(&mut g);
            if relative_change <= DARE_TOLERANCE {
                converged = true;
                break;
            }
        }
        if !converged {
            return Err(LinalgError::NoConvergence {
                iterations,
                relative_change,
            });
        }
        let p = h;
        let (residual, gain) = self.checked_residual(&p)?;
        let relative_residual = norm1(&residual) / norm1(&p).max(1.0);
        if relative_residual.is_nan() || relative_residual > DARE_RESIDUAL_LIMIT {
            return Err(LinalgError::InaccurateSolution { relative_residual });
        }
        let rho = spectral_radius(&(a - b * &gain));
        if rho.is_nan() || rho >= 1.0 - STABILITY_MARGIN {
            return Err(LinalgError::NotStabilising {
                spectral_radius: rho,
            });
        }
        Ok((p, gain))
    }
}

/// Largest modulus of the eigenvalues of the square matrix `m`.
pub(crate) fn spectral_radius(m: &DMatrix<f64>) -> f64 {
    m.complex_eigenvalues()
        .iter()
        .map(|z| z.norm())
        .fold(0.0, f64::max)
}

/// Steady-state Kalman filter for `x⁺ = A x + w`, `y = C x + v`, `cov(w) = Q`, `cov(v) = R`:
/// `(K, P⁻)` with the predicted covariance `P⁻` from DARE(Aᵀ, Cᵀ, Q, R) and the filter gain
/// `K = P⁻Cᵀ (C P⁻ Cᵀ + R)⁻¹` (update `x = x⁻ + K (y − C x⁻)`).
pub fn kalman_gain_steady(
    a: &DMatrix<f64>,
    c: &DMatrix<f64>,
    q: &DMatrix<f64>,
    r: &DMatrix<f64>,
) -> Result<(DMatrix<f64>, DMatrix<f64>), LinalgError> {
    let n = require_square("A", a)?;
    require_shape("C", c, c.nrows(), n)?;
    let (a_t, c_t) = (a.transpose(), c.transpose());
    let p = Dare {
        a: &a_t,
        b: &c_t,
        q,
        r,
    }
    .solve()?;
    let innovation_covariance = c * &p * c.transpose() + r;
    // K = P Cᵀ S⁻¹  ⇔  Kᵀ = S⁻¹ C P (S, P symmetric).
    let gain_t = cholesky_solve(&innovation_covariance, &(c * &p), "C P Cᵀ + R")?;
    Ok((gain_t.transpose(), p))
}

/// Allocation-free dense kernels on column-major storage for the estimators' steps
/// (docs/estimators.md §2.7–§2.10): `y ← α A x + β y`, `C ← α A B + β C` (A or B may be a
/// transposed view), the dot product and the symmetrisation.
///
/// They sum in the order of nalgebra's small-matrix BLAS (a product term by term from the
/// first column, `(α aᵢₖ) bₖⱼ` added to the running sum; a dot product in eight interleaved
/// partial sums), so a filter moved onto them reproduces its earlier results bit for bit
/// where nalgebra took that path. They never allocate and never go through matrixmultiply.
///
/// One code path serves every size: the rows of a product go in blocks of 8, 4, 2 and 1,
/// each block's sums held in registers (the kernel monomorphised per block size, its loops
/// unrolled and vectorised by the compiler). The Kalman filter core adds kernels whose
/// dimensions are constants for the packaged sizes (`estimation::kalman`, module `fixed`),
/// bit-identical to these and tested against them.
pub(crate) mod dense {
    use nalgebra::DMatrix;

    /// A read-only matrix (or block of one): `rows × cols`, element (i, j) at
    /// `data[i·rs + j·cs]`.
    #[derive(Debug, Clone, Copy)]
    pub(crate) struct View<'a> {
        data: &'a [f64],
        rows: usize,
        cols: usize,
        rs: usize,
        cs: usize,
    }

    impl<'a> View<'a> {
        /// The whole matrix.
        pub(crate) fn of(m: &'a DMatrix<f64>) -> Self {
            Self {
                data: m.as_slice(),
                rows: m.nrows(),
                cols: m.ncols(),
                rs: 1,
                cs: m.nrows(),
            }
        }
        /// The `shape` block of `m` starting at `start` (an empty block when it would leave `m`).
        pub(crate) fn block(
            m: &'a DMatrix<f64>,
            start: (usize, usize),
            shape: (usize, usize),
        ) -> Self {
            let ld = m.nrows();
            let fits = start.0 + shape.0 <= m.nrows() && start.1 + shape.1 <= m.ncols();
            let (rows, cols) = if fits { shape } else { (0, 0) };
            let data = m
                .as_slice()
                .get(start.0 + start.1 * ld..)
                .filter(|_| fits)
                .unwrap_or(&[]);
            Self {
                data,
                rows,
                cols,
                rs: 1,
                cs: ld,
            }
        }
        /// The transpose (no copy).
        pub(crate) fn t(self) -> Self {
            Self {
                rows: self.cols,
                cols: self.rows,
                rs: self.cs,
                cs: self.rs,
                ..self
            }
        }
        /// Column `j` as a slice, when the view's columns are contiguous (`None` for a
        /// transposed view or outside the matrix).
        #[inline(always)]
        pub(crate) fn column(&self, j: usize) -> Option<&'a [f64]> {
            column_from(self, j, 0)
        }
        /// Element (i, j) (0 outside).
        #[inline(always)]
        pub(crate) fn at(&self, i: usize, j: usize) -> f64 {
            self.data
                .get(i * self.rs + j * self.cs)
                .copied()
                .unwrap_or(0.0)
        }
    }

    /// Rows `i0..i0 + L` of `y ← α A x + β y` for `A` with contiguous columns, the `L` sums
    /// kept in registers: term by term from the first column, `aᵢₖ (α xₖ)` added to the
    /// running sum (β = 0: `y` is not read). `aᵢₖ (α xₖ)` equals nalgebra's `(α aᵢₖ) xₖ`
    /// whenever α = ±1 or xₖ = 1, which is every use here.
    #[inline(always)]
    fn combine_block<const L: usize>(
        y: &mut [f64],
        i0: usize,
        alpha: f64,
        a: View<'_>,
        x: &impl Fn(usize) -> f64,
        beta: f64,
    ) {
        let Some(Ok(y)) = y.get_mut(i0..i0 + L).map(<&mut [f64; L]>::try_from) else {
            return;
        };
        let column = |k: usize| {
            let start = i0 + k * a.cs;
            a.data
                .get(start..start + L)
                .and_then(|c| <&[f64; L]>::try_from(c).ok())
        };
        let Some(first) = column(0) else {
            return;
        };
        let mut acc = [0.0; L];
        let s = alpha * x(0);
        if beta == 0.0 {
            for r in 0..L {
                acc[r] = first[r] * s;
            }
        } else {
            for r in 0..L {
                acc[r] = first[r] * s + beta * y[r];
            }
        }
        for k in 1..a.cols {
            let s = alpha * x(k);
            if let Some(c) = column(k) {
                for r in 0..L {
                    acc[r] += c[r] * s;
                }
            }
        }
        *y = acc;
    }

    /// `y ← α A x + β y` with `x(k)` the k-th entry of x: row blocks of 8, 4, 2, 1 when the
    /// columns of A are contiguous, element by element (same order) otherwise.
    #[inline(always)]
    fn combine(y: &mut [f64], alpha: f64, a: View<'_>, x: impl Fn(usize) -> f64, beta: f64) {
        let rows = a.rows;
        if a.cols == 0 {
            for y in y.iter_mut().take(rows) {
                *y = if beta == 0.0 { 0.0 } else { *y * beta };
            }
            return;
        }
        if a.rs != 1 {
            for (i, y) in y.iter_mut().enumerate().take(rows) {
                let t = a.at(i, 0) * (alpha * x(0));
                let mut acc = if beta == 0.0 { t } else { t + beta * *y };
                for k in 1..a.cols {
                    acc += a.at(i, k) * (alpha * x(k));
                }
                *y = acc;
            }
            return;
        }
        let mut i0 = 0;
        while rows - i0 >= 8 {
            combine_block::<8>(y, i0, alpha, a, &x, beta);
            i0 += 8;
        }
        if rows - i0 >= 4 {
            combine_block::<4>(y, i0, alpha, a, &x, beta);
            i0 += 4;
        }
        if rows - i0 >= 2 {
            combine_block::<2>(y, i0, alpha, a, &x, beta);
            i0 += 2;
        }
        if rows > i0 {
            combine_block::<1>(y, i0, alpha, a, &x, beta);
        }
    }

    /// `y ← a (α x) + β y` for 1×1 operands, in the order of the kernels' `L = 1` block.
    #[inline(always)]
    fn scalar(y: &mut f64, alpha: f64, a: f64, x: f64, beta: f64) {
        let s = alpha * x;
        *y = if beta == 0.0 {
            a * s
        } else {
            a * s + beta * *y
        };
    }

    /// `y ← α A x + β y` (β = 0: `y` is not read). A 1×1 `A` is one multiply-add here, at
    /// the call site, and an `A` without columns (no input) scales `y` by β; any other size
    /// goes to the kernels.
    #[inline]
    pub(crate) fn gemv(y: &mut [f64], alpha: f64, a: View<'_>, x: &[f64], beta: f64) {
        if let ((1, 1), Some(y0), Some(&a0), Some(&x0)) =
            ((a.rows, a.cols), y.first_mut(), a.data.first(), x.first())
        {
            return scalar(y0, alpha, a0, x0, beta);
        }
        if a.cols == 0 {
            for y in y.iter_mut().take(a.rows) {
                *y = if beta == 0.0 { 0.0 } else { *y * beta };
            }
            return;
        }
        gemv_kernels(y, alpha, a, x, beta);
    }

    /// [`gemv`] inlined at the call site, the kernel of the packaged row counts (1, 2, 3, 8)
    /// chosen there (the same arithmetic in the same order: bit-identical to [`gemv`]).
    #[inline(always)]
    pub(crate) fn gemv_inline(y: &mut [f64], alpha: f64, a: View<'_>, x: &[f64], beta: f64) {
        if a.cols == 0 && beta == 1.0 {
            // No input: y · 1 = y.
            return;
        }
        if !gemv_rows(y, alpha, a, x, beta) {
            gemv(y, alpha, a, x, beta);
        }
    }

    /// `y ← α A x + β y` by the kernel of A's row count when it is one of 1, 2, 3, 4, 8 and
    /// A's columns are contiguous (`false`, nothing done, otherwise).
    #[inline(always)]
    fn gemv_rows(y: &mut [f64], alpha: f64, a: View<'_>, x: &[f64], beta: f64) -> bool {
        if a.rs != 1 || a.cols == 0 {
            return false;
        }
        let x = |k: usize| x.get(k).copied().unwrap_or(0.0);
        match a.rows {
            1 => combine_block::<1>(y, 0, alpha, a, &x, beta),
            2 => combine_block::<2>(y, 0, alpha, a, &x, beta),
            3 => combine_block::<3>(y, 0, alpha, a, &x, beta),
            4 => combine_block::<4>(y, 0, alpha, a, &x, beta),
            8 => combine_block::<8>(y, 0, alpha, a, &x, beta),
            _ => return false,
        }
        true
    }

    pub(super) fn gemv_kernels(y: &mut [f64], alpha: f64, a: View<'_>, x: &[f64], beta: f64) {
        if !gemv_rows(y, alpha, a, x, beta) {
            let x = |k: usize| x.get(k).copied().unwrap_or(0.0);
            combine(y, alpha, a, x, beta);
        }
    }

    /// `C ← α A B + β C` for a `C` stored contiguously (`A.rows` rows; any strides, e.g. a
    /// transposed view; β = 0: `C` is not read). The common row counts (1, 2, 4, 8) take a
    /// kernel of their own, so a small product pays no more than its own block's set-up; a
    /// 1×1 by 1×1 product is one multiply-add at the call site.
    #[inline]
    pub(crate) fn gemm(c: &mut [f64], alpha: f64, a: View<'_>, b: View<'_>, beta: f64) {
        if let ((1, 1, 1), Some(c0), Some(&a0), Some(&b0)) = (
            (a.rows, a.cols, b.cols),
            c.first_mut(),
            a.data.first(),
            b.data.first(),
        ) {
            return scalar(c0, alpha, a0, b0, beta);
        }
        gemm_kernels(c, alpha, a, b, beta);
    }

    pub(super) fn gemm_kernels(c: &mut [f64], alpha: f64, a: View<'_>, b: View<'_>, beta: f64) {
        if a.rs == 1 && a.cols > 0 {
            match a.rows {
                1 => return gemm_rows::<1>(c, alpha, a, b, beta),
                2 => return gemm_rows::<2>(c, alpha, a, b, beta),
                4 => return gemm_rows::<4>(c, alpha, a, b, beta),
                8 => return gemm_rows::<8>(c, alpha, a, b, beta),
                _ => {}
            }
        }
        let rows = a.rows;
        for j in 0..b.cols {
            if let Some(column) = c.get_mut(j * rows..(j + 1) * rows) {
                combine(column, alpha, a, |k| b.at(k, j), beta);
            }
        }
    }

    /// [`gemm`] for an `A` of `L` rows with contiguous columns.
    fn gemm_rows<const L: usize>(c: &mut [f64], alpha: f64, a: View<'_>, b: View<'_>, beta: f64) {
        for (j, column) in c.chunks_exact_mut(L).take(b.cols).enumerate() {
            combine_block::<L>(column, 0, alpha, a, &|k| b.at(k, j), beta);
        }
    }

    /// `aᵀ b` in nalgebra's order: eight interleaved partial sums over blocks of eight,
    /// then the rest one by one.
    pub(crate) fn dot(a: &[f64], b: &[f64]) -> f64 {
        let len = a.len().min(b.len());
        let (a, b) = (&a[..len], &b[..len]);
        let mut res = 0.0;
        let mut chunks_a = a.chunks_exact(8);
        let mut chunks_b = b.chunks_exact(8);
        let mut acc = [0.0; 8];
        for (ca, cb) in (&mut chunks_a).zip(&mut chunks_b) {
            for r in 0..8 {
                acc[r] += ca[r] * cb[r];
            }
        }
        res += acc[0] + acc[4];
        res += acc[1] + acc[5];
        res += acc[2] + acc[6];
        res += acc[3] + acc[7];
        for (x, y) in chunks_a.remainder().iter().zip(chunks_b.remainder()) {
            res += x * y;
        }
        res
    }

    /// Column `j` of a view with contiguous columns, rows `from..rows` (`None` for a view
    /// with other strides or outside the matrix).
    #[inline(always)]
    fn column_from<'v>(a: &View<'v>, j: usize, from: usize) -> Option<&'v [f64]> {
        if a.rs != 1 {
            return None;
        }
        let start = j * a.cs + from;
        a.data.get(start..start + a.rows.checked_sub(from)?)
    }

    /// The lower triangle (diagonal included) of `C ← A B + Q` for square `n × n` operands,
    /// `C` and `Q` stored contiguously, element by element in the order of [`gemm`] with
    /// α = β = 1 (`(aᵢ₀ b₀ⱼ + qᵢⱼ) + aᵢ₁ b₁ⱼ + …`); the strict upper triangle is left as it
    /// was.
    #[inline(always)]
    pub(crate) fn gemm_lower(c: &mut [f64], a: View<'_>, b: View<'_>, q: &[f64]) {
        let n = a.rows;
        if c.len() < n * n || q.len() < n * n || a.cols != n || b.rows != n || b.cols != n {
            return;
        }
        for j in 0..n {
            let (column, add) = (&mut c[j * n + j..j * n + n], &q[j * n + j..j * n + n]);
            let b0 = b.at(0, j);
            match column_from(&a, 0, j) {
                Some(a0) => {
                    for ((c, a), q) in column.iter_mut().zip(a0).zip(add) {
                        *c = a * b0 + q;
                    }
                }
                None => {
                    for (r, (c, q)) in column.iter_mut().zip(add).enumerate() {
                        *c = a.at(j + r, 0) * b0 + q;
                    }
                }
            }
            for k in 1..n {
                let bk = b.at(k, j);
                match column_from(&a, k, j) {
                    Some(ak) => {
                        for (c, a) in column.iter_mut().zip(ak) {
                            *c += a * bk;
                        }
                    }
                    None => {
                        for (r, c) in column.iter_mut().enumerate() {
                            *c += a.at(j + r, k) * bk;
                        }
                    }
                }
            }
        }
    }

    /// Copies the strict lower triangle of the square `n × n` matrix in `m` onto its upper
    /// triangle (the matrix becomes exactly symmetric).
    #[inline(always)]
    pub(crate) fn mirror_lower(m: &mut [f64], n: usize) {
        if m.len() < n * n {
            return;
        }
        for j in 0..n {
            for i in j + 1..n {
                m[j + i * n] = m[i + j * n];
            }
        }
    }

    /// The lower Cholesky factor L (S = L Lᵀ) of the symmetric `p × p` matrix in `s`, in
    /// place (column-major; only the lower triangle is read, the strict upper triangle is
    /// left as it was). `false` when S is not positive definite (or not finite); `s` then
    /// holds a partial factor.
    ///
    /// Column by column: `lⱼⱼ = √(sⱼⱼ − Σₖ<ⱼ lⱼₖ²)`, `lᵢⱼ = (sᵢⱼ − Σₖ<ⱼ lᵢₖ lⱼₖ) / lⱼⱼ`.
    #[inline(always)]
    pub(crate) fn cholesky(s: &mut [f64], p: usize) -> bool {
        if s.len() < p * p {
            return false;
        }
        for j in 0..p {
            let mut d = s[j + j * p];
            for k in 0..j {
                d -= s[j + k * p] * s[j + k * p];
            }
            if !(d > 0.0 && d.is_finite()) {
                return false;
            }
            let l = d.sqrt();
            s[j + j * p] = l;
            for i in j + 1..p {
                let mut v = s[i + j * p];
                for k in 0..j {
                    v -= s[i + k * p] * s[j + k * p];
                }
                s[i + j * p] = v / l;
            }
        }
        true
    }

    /// Solves `L x = b` in place for the lower triangle of the `p × p` matrix in `l`
    /// (column-oriented: `xᵢ = bᵢ / lᵢᵢ`, then `bₖ −= lₖᵢ xᵢ` below, nalgebra's order).
    /// `false` on a zero diagonal.
    #[inline(always)]
    pub(crate) fn solve_lower(l: &[f64], p: usize, b: &mut [f64]) -> bool {
        if l.len() < p * p || b.len() < p {
            return false;
        }
        for i in 0..p {
            let d = l[i + i * p];
            if d == 0.0 {
                return false;
            }
            let x = b[i] / d;
            b[i] = x;
            for k in i + 1..p {
                b[k] -= x * l[k + i * p];
            }
        }
        true
    }

    /// Solves `L Lᵀ X = B` in place (`B` is `p × cols`, column-major) with the factor of
    /// [`cholesky`]: forward substitution with L, then back substitution with Lᵀ, column by
    /// column of B. For p = 1: `x = b / l / l`.
    #[inline(always)]
    pub(crate) fn cholesky_solve(l: &[f64], p: usize, b: &mut [f64]) {
        if l.len() < p * p || p == 0 {
            return;
        }
        for column in b.chunks_exact_mut(p) {
            solve_lower(l, p, column);
            for i in (0..p).rev() {
                let mut v = column[i];
                for k in i + 1..p {
                    v -= l[k + i * p] * column[k];
                }
                column[i] = v / l[i + i * p];
            }
        }
    }

    /// Whether every entry of `v` is finite, without a branch per entry: `x · 0` is ±0 for a
    /// finite x and NaN for an infinite or NaN one, and a sum of such terms is NaN as soon
    /// as one is (four running sums, so the loop vectorises).
    #[inline]
    pub(crate) fn all_finite(v: &[f64]) -> bool {
        let (chunks, rest) = v.as_chunks::<4>();
        let mut acc = [0.0; 4];
        for chunk in chunks {
            for (acc, x) in acc.iter_mut().zip(chunk) {
                *acc += x * 0.0;
            }
        }
        let mut total = (acc[0] + acc[1]) + (acc[2] + acc[3]);
        for x in rest {
            total += x * 0.0;
        }
        total == 0.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scalar_products_match_the_kernels_bit_for_bit() {
        use dense::View;
        let values = [0.1, -3.7, 1.0 / 3.0, 2.5e-8, 7.0];
        for &a in &values {
            for &b in &values {
                for &c0 in &values {
                    for (alpha, beta) in [(1.0, 0.0), (-1.0, 1.0), (1.0, 1.0), (0.3, -2.0)] {
                        let (am, bm) = (dmatrix![a], dmatrix![b]);
                        let (mut fast, mut kernel) = ([c0], [c0]);
                        dense::gemm(&mut fast, alpha, View::of(&am), View::of(&bm).t(), beta);
                        dense::gemm_kernels(&mut kernel, alpha, View::of(&am), View::of(&bm), beta);
                        assert_eq!(fast[0].to_bits(), kernel[0].to_bits(), "gemm {a} {b} {c0}");
                        let (mut fast, mut kernel) = ([c0], [c0]);
                        dense::gemv(&mut fast, alpha, View::of(&am), &[b], beta);
                        dense::gemv_kernels(&mut kernel, alpha, View::of(&am), &[b], beta);
                        assert_eq!(fast[0].to_bits(), kernel[0].to_bits(), "gemv {a} {b} {c0}");
                    }
                }
            }
        }
        // No input: y ← β y.
        let empty = DMatrix::<f64>::zeros(2, 0);
        let mut y = [3.0, -1.5];
        dense::gemv(&mut y, 1.0, View::of(&empty), &[], 0.5);
        assert_eq!(y, [1.5, -0.75]);
        dense::gemv(&mut y, 1.0, View::of(&empty), &[], 0.0);
        assert_eq!(y, [0.0, 0.0]);
    }

    #[test]
    fn all_finite_finds_any_nan_or_infinity() {
        for len in [0, 1, 3, 4, 7, 8, 64, 65] {
            let mut v: Vec<f64> = (0..len).map(|k| (k as f64 - 3.5) * 1e300).collect();
            assert!(dense::all_finite(&v), "{len}");
            for k in 0..len {
                for bad in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
                    let keep = v[k];
                    v[k] = bad;
                    assert!(!dense::all_finite(&v), "{len} {k} {bad}");
                    v[k] = keep;
                }
            }
        }
        assert!(dense::all_finite(&[
            f64::MAX,
            -f64::MAX,
            f64::MIN_POSITIVE,
            -0.0
        ]));
    }

    #[test]
    fn lower_product_and_cholesky_kernels_match_the_full_ones() {
        use dense::View;
        // A block of a larger matrix (column stride 7) and a contiguous one.
        let big = DMatrix::from_fn(7, 9, |i, j| ((3 * i + 5 * j) % 11) as f64 / 7.0 - 0.6);
        for n in [1, 2, 3, 5] {
            let contiguous = big.view((1, 2), (n, n)).clone_owned();
            let w = DMatrix::from_fn(n, n, |i, j| (i as f64 + 1.0) / (j as f64 + 2.0));
            let q = DMatrix::from_fn(n, n, |i, j| 0.1 * (i + j) as f64);
            for a in [View::block(&big, (1, 2), (n, n)), View::of(&contiguous)] {
                let mut full = q.clone();
                dense::gemm(full.as_mut_slice(), 1.0, a, View::of(&w), 1.0);
                let mut lower = DMatrix::from_element(n, n, 9.0);
                dense::gemm_lower(lower.as_mut_slice(), a, View::of(&w), q.as_slice());
                for j in 0..n {
                    for i in 0..n {
                        let expected = if i >= j { full[(i, j)] } else { 9.0 };
                        assert_eq!(
                            lower[(i, j)].to_bits(),
                            expected.to_bits(),
                            "{n}: ({i}, {j})"
                        );
                    }
                }
                dense::mirror_lower(lower.as_mut_slice(), n);
                assert_eq!(lower, lower.transpose());
            }
            // Cholesky and the triangular solve against nalgebra's.
            let spd = &w * w.transpose() + DMatrix::identity(n, n);
            let mut l = spd.clone();
            assert!(dense::cholesky(l.as_mut_slice(), n));
            let factor = Cholesky::new(spd.clone()).unwrap();
            assert!((l.lower_triangle() - factor.l()).amax() < 1e-14);
            let mut b = nalgebra::DVector::from_fn(n, |i, _| i as f64 - 0.5);
            let mut expected = b.clone();
            assert!(factor.l().solve_lower_triangular_mut(&mut expected));
            assert!(dense::solve_lower(
                factor.l().as_slice(),
                n,
                b.as_mut_slice()
            ));
            assert_eq!(b, expected, "forward substitution in nalgebra's order");
            let mut not_spd = -spd;
            assert!(!dense::cholesky(not_spd.as_mut_slice(), n));
        }
    }
    use crate::plants::gantry_crane::GantryCraneParameters;
    use nalgebra::{dmatrix, Vector4};

    fn max_abs_diff(x: &DMatrix<f64>, y: &DMatrix<f64>) -> f64 {
        (x - y).amax()
    }

    #[test]
    fn expm_of_a_rotation_generator_is_a_rotation() {
        for w in [0.3, 1.0, 7.5, 40.0] {
            let a = dmatrix![0.0, -w; w, 0.0];
            let e = expm(&a);
            let expected = dmatrix![w.cos(), -w.sin(); w.sin(), w.cos()];
            assert!(max_abs_diff(&e, &expected) < 1e-13 * w.max(1.0), "w = {w}");
        }
    }

    #[test]
    fn expm_of_a_nilpotent_matrix_is_a_finite_series() {
        // N³ = 0: e^N = I + N + N²/2.
        let a = dmatrix![0.0, 2.0, -1.0; 0.0, 0.0, 3.0; 0.0, 0.0, 0.0];
        let expected = DMatrix::identity(3, 3) + &a + &a * &a * 0.5;
        assert!(max_abs_diff(&expm(&a), &expected) < 1e-15 * 10.0);
    }

    #[test]
    fn expm_of_a_diagonal_matrix_exponentiates_the_diagonal() {
        let d = [-20.0, -1.0, 0.0, 0.5, 3.0, 12.0];
        let a = DMatrix::from_diagonal(&nalgebra::DVector::from_column_slice(&d));
        let e = expm(&a);
        for (i, di) in d.iter().enumerate() {
            let want = di.exp();
            let rel = ((e[(i, i)] - want) / want).abs();
            // Squaring amplifies the relative error of the small entries by about ‖A‖₁.
            assert!(
                rel < 1e-14 * di.abs().max(1.0),
                "e^{di}: relative error {rel:e}"
            );
        }
        assert_eq!(e[(0, 1)], 0.0);
    }

    /// exp([[a, b], [0, d]]) = [[e^a, b (e^a − e^d) / (a − d)], [0, e^d]]: ‖A‖₁ = 105 and
    /// the spectral radius 6 need degree 13 on A / 2^s with s = 1 squaring (η₅ ≈ 6 of the
    /// norms of A's powers; ‖A‖₁ / θ₁₃ alone would ask for 5).
    #[test]
    fn expm_of_a_matrix_of_large_norm_scales_and_squares() {
        let (a, b, d) = (6.0_f64, 100.0, -5.0_f64);
        let mut work = MatrixExponential::new(2);
        let mut e = DMatrix::zeros(2, 2);
        work.exp_into(&dmatrix![a, b; 0.0, d], &mut e).unwrap();
        assert_eq!(work.degree_and_squarings(), (13, 1));
        let expected = dmatrix![a.exp(), b * (a.exp() - d.exp()) / (a - d); 0.0, d.exp()];
        for (got, want) in e.iter().zip(expected.iter()) {
            assert!(
                (got - want).abs() <= 1e-13 * want.abs().max(1.0),
                "{got} against {want}"
            );
        }
    }

    /// Pseudo-random matrices (a linear congruential generator, entries in [−1, 1)) of
    /// orders 2…8 scaled to 1-norms from 10⁻⁴ to 10³ (every degree 3…13, up to 10
    /// squarings), all through one [`MatrixExponential`] per order: nalgebra's
    /// `DMatrix::exp` bit for bit.
    #[test]
    fn matrix_exponential_is_nalgebras_bit_for_bit() {
        let mut state = 0x2545_f491_4f6c_dd1d_u64;
        let mut uniform = || {
            state = state
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            (state >> 11) as f64 / (1u64 << 52) as f64 - 1.0
        };
        let mut degrees_and_squarings = std::collections::BTreeSet::new();
        for n in 2..=8 {
            let mut work = MatrixExponential::new(n);
            let mut e = DMatrix::zeros(n, n);
            for norm in [1e-4, 3e-3, 0.1, 0.5, 1.5, 3.0, 10.0, 100.0, 1e3] {
                for _ in 0..4 {
                    let mut a = DMatrix::from_fn(n, n, |_, _| uniform());
                    a *= norm / a.one_norm();
                    work.exp_into(&a, &mut e).unwrap();
                    let reference = a.exp();
                    for (got, want) in e.iter().zip(reference.iter()) {
                        assert_eq!(got.to_bits(), want.to_bits(), "n = {n}, ‖A‖₁ = {norm}");
                    }
                    degrees_and_squarings.insert(work.degree_and_squarings());
                }
            }
        }
        // Every degree was taken, and degree 13 with and without squarings.
        let degrees: std::collections::BTreeSet<_> =
            degrees_and_squarings.iter().map(|(m, _)| *m).collect();
        assert_eq!(
            degrees,
            [3, 5, 7, 9, 13].into(),
            "{degrees_and_squarings:?}"
        );
        assert!(
            degrees_and_squarings.contains(&(13, 0)),
            "{degrees_and_squarings:?}"
        );
        assert!(
            degrees_and_squarings.iter().any(|&(_, s)| s >= 8),
            "{degrees_and_squarings:?}"
        );
    }

    /// 1×1 and 0×0, and the shapes that do not fit.
    #[test]
    fn matrix_exponential_of_the_smallest_orders_and_wrong_shapes() {
        let mut e = dmatrix![0.0];
        MatrixExponential::new(1)
            .exp_into(&dmatrix![-0.7], &mut e)
            .unwrap();
        assert_eq!(e[(0, 0)], (-0.7_f64).exp());
        let mut empty = DMatrix::zeros(0, 0);
        MatrixExponential::new(0)
            .exp_into(&DMatrix::zeros(0, 0), &mut empty)
            .unwrap();
        let mut work = MatrixExponential::new(2);
        let mut out = DMatrix::zeros(2, 2);
        assert!(matches!(
            work.exp_into(&DMatrix::zeros(3, 3), &mut out),
            Err(LinalgError::DimensionMismatch {
                expected: (2, 2),
                got: (3, 3),
                ..
            })
        ));
        let mut wrong_out = DMatrix::zeros(2, 3);
        assert!(matches!(
            work.exp_into(&DMatrix::zeros(2, 2), &mut wrong_out),
            Err(LinalgError::DimensionMismatch { .. })
        ));
    }

    #[test]
    fn expm_of_non_square_or_nan_input_is_nan_not_a_panic() {
        let e = expm(&DMatrix::zeros(2, 3));
        assert!(e.iter().all(|v| v.is_nan()));
        assert!(matches!(
            try_expm(&dmatrix![f64::NAN]),
            Err(LinalgError::NonFinite { .. })
        ));
    }

    /// ‖A‖₁ = ∞ (every entry finite) once asked for 2³¹ squarings: 66 s, then a wrong `I`.
    #[test]
    fn expm_of_a_matrix_whose_norm_overflows_is_refused_at_once() {
        let a = dmatrix![0.9e308, 0.854e308; 0.0, 1e308];
        let start = std::time::Instant::now();
        let result = try_expm(&a);
        let elapsed = start.elapsed();
        assert!(
            matches!(&result, Err(LinalgError::NormOverflow { what }) if what == "A"),
            "{result:?}"
        );
        assert!(elapsed.as_secs_f64() < 0.1, "took {elapsed:?}");
        // The largest finite norm still goes through (1022 squarings), to an overflow.
        let largest = dmatrix![f64::MAX / 2.0, f64::MAX / 2.0; 0.0, 0.0];
        assert!(matches!(
            try_expm(&largest),
            Err(LinalgError::NonFinite { what }) if what == "e^A (overflow)"
        ));
        // A finite norm whose exponential overflows names the step too.
        let err = try_zoh(&dmatrix![0.9, 0.1; 0.0, 0.9], &dmatrix![0.854; 1.0], 1e300)
            .unwrap_err()
            .to_string();
        assert_eq!(
            err,
            "matrix e^([[A, B], [0, 0]]·Ts) (overflow: Ts = 1e300 s is too long for this A; a \
             shorter Ts is needed) contains NaN or infinity"
        );
        let err = try_zoh(&dmatrix![0.9, 0.1; 0.0, 0.9], &dmatrix![0.854; 1.0], 1e308)
            .unwrap_err()
            .to_string();
        assert_eq!(
            err,
            "matrix [[A, B], [0, 0]]·Ts (Ts = 1e308 s; a shorter Ts is needed) is too large \
             for its exponential: its 1-norm exceeds the largest double, 1.7976931348623157e308"
        );
    }

    #[test]
    fn zoh_of_the_crane_matches_fine_rk4_integration() {
        let (a4, b4) = GantryCraneParameters::default().linearised();
        let a = DMatrix::from_iterator(4, 4, a4.iter().copied());
        let b = DMatrix::from_iterator(4, 1, b4.iter().copied());
        let ts = 0.05;
        let (a_d, b_d) = zoh(&a, &b, ts);
        // Column j of A_d: x(ts) from x0 = e_j with u = 0; B_d: x(ts) from 0 with u = 1.
        let simulate = |x0: Vector4<f64>, u: f64| {
            let f = |_t: f64, x: &Vector4<f64>| a4 * x + b4 * u;
            crate::ode::integrate(f, |_, _| {}, 0.0, &x0, ts, 1e-4)
        };
        for j in 0..4 {
            let mut e = Vector4::zeros();
            e[j] = 1.0;
            let x = simulate(e, 0.0);
            for i in 0..4 {
                assert!((a_d[(i, j)] - x[i]).abs() < 1e-12, "A_d[{i},{j}]");
            }
        }
        let x = simulate(Vector4::zeros(), 1.0);
        for i in 0..4 {
            assert!((b_d[(i, 0)] - x[i]).abs() < 1e-12, "B_d[{i}]");
        }
    }

    #[test]
    fn scalar_kalman_gain_is_the_golden_ratio_conjugate() {
        // docs/reference-values.md §6: A = C = 1, Q = R → K = (√5 − 1)/2, P⁻ = (1 + √5)/2 · Q.
        for q in [1e-4, 1.0, 30.0] {
            let one = dmatrix![1.0];
            let (k, p) = kalman_gain_steady(&one, &one, &dmatrix![q], &dmatrix![q]).unwrap();
            assert!((k[(0, 0)] - (5f64.sqrt() - 1.0) / 2.0).abs() < 1e-12);
            assert!((p[(0, 0)] / q - (1.0 + 5f64.sqrt()) / 2.0).abs() < 1e-12);
        }
    }

    #[test]
    fn dare_of_the_crane_has_a_tiny_residual_and_a_stable_closed_loop() {
        let (a4, b4) = GantryCraneParameters::default().linearised();
        let a = DMatrix::from_iterator(4, 4, a4.iter().copied());
        let b = DMatrix::from_iterator(4, 1, b4.iter().copied());
        let (a_d, b_d) = zoh(&a, &b, 0.05);
        let q = DMatrix::from_diagonal(&nalgebra::DVector::from_vec(vec![10.0, 1.0, 0.1, 0.1]));
        let r = dmatrix![0.5];
        let dare = Dare {
            a: &a_d,
            b: &b_d,
            q: &q,
            r: &r,
        };
        let (k, p) = dare.regulator().unwrap();
        let res = dare.residual(&p).unwrap();
        let relative = res.amax() / p.amax();
        eprintln!("crane DARE relative residual {relative:e}");
        assert!(relative < 1e-10, "relative DARE residual {relative:e}");
        assert_eq!(p, p.transpose());
        assert!(is_positive_definite(&p));
        assert!(spectral_radius(&(&a_d - &b_d * k)) < 1.0);
    }

    #[test]
    fn dare_with_two_inputs_and_an_unstable_open_loop() {
        let a = dmatrix![1.2, 0.3, 0.0; 0.0, 0.9, 0.5; 0.1, 0.0, 1.05];
        let b = dmatrix![1.0, 0.0; 0.0, 0.0; 0.0, 1.0];
        let q = DMatrix::identity(3, 3);
        let r = dmatrix![2.0, 0.3; 0.3, 1.0];
        let dare = Dare {
            a: &a,
            b: &b,
            q: &q,
            r: &r,
        };
        let p = dare.solve().unwrap();
        let res = dare.residual(&p).unwrap();
        let relative = res.amax() / p.amax();
        eprintln!("two-input DARE relative residual {relative:e}");
        assert!(relative < 1e-10, "residual {relative:e}");
    }

    #[test]
    fn dare_rejects_unstabilisable_pairs_and_bad_weights() {
        fn solve(
            a: &DMatrix<f64>,
            b: &DMatrix<f64>,
            q: &DMatrix<f64>,
            r: &DMatrix<f64>,
        ) -> Result<DMatrix<f64>, LinalgError> {
            Dare { a, b, q, r }.solve()
        }
        let one = dmatrix![1.0];
        // Unstable mode that B cannot touch.
        let e = solve(&dmatrix![2.0], &dmatrix![0.0], &one, &one).unwrap_err();
        assert!(matches!(e, LinalgError::NoConvergence { .. }), "{e}");
        // Marginal mode invisible to Q: P = 0 does not stabilise.
        let e = solve(&one, &dmatrix![0.0], &dmatrix![0.0], &one).unwrap_err();
        assert!(matches!(e, LinalgError::NotStabilising { .. }), "{e}");
        let e = solve(&one, &one, &dmatrix![-1.0], &one).unwrap_err();
        assert!(e.to_string().contains("Q (must be"), "{e}");
        let e = solve(&one, &one, &one, &dmatrix![-1.0]).unwrap_err();
        assert_eq!(
            e,
            LinalgError::NotPositiveDefinite {
                what: "R".to_string()
            }
        );
        let e = solve(&one, &dmatrix![1.0, 1.0], &one, &one).unwrap_err();
        assert!(matches!(e, LinalgError::DimensionMismatch { .. }), "{e}");
        let e = solve(&dmatrix![f64::NAN], &one, &one, &one).unwrap_err();
        assert!(matches!(e, LinalgError::NonFinite { .. }), "{e}");
    }

    #[test]
    fn cholesky_solve_solves_and_names_the_failing_matrix() {
        let m = dmatrix![4.0, 1.0; 1.0, 3.0];
        let rhs = dmatrix![1.0; 2.0];
        let x = cholesky_solve(&m, &rhs, "M").unwrap();
        assert!(max_abs_diff(&(&m * &x), &rhs) < 1e-15 * 10.0);
        let e = cholesky_solve(&dmatrix![1.0, 2.0; 2.0, 1.0], &rhs, "S").unwrap_err();
        assert_eq!(e.to_string(), "matrix S is not symmetric positive definite");
        assert!(cholesky_solve(&dmatrix![1.0, 0.5; 0.0, 1.0], &rhs, "S").is_err());
    }

    #[test]
    fn positive_definiteness_and_symmetrisation() {
        assert!(is_positive_definite(&dmatrix![2.0, -1.0; -1.0, 2.0]));
        assert!(!is_positive_definite(&dmatrix![1.0, 2.0; 2.0, 1.0]));
        assert!(!is_positive_definite(&dmatrix![0.0]));
        assert!(!is_positive_definite(&DMatrix::zeros(0, 0)));
        assert!(!is_positive_definite(&dmatrix![1.0, 0.0]));
        let mut m = dmatrix![1.0, 2.0; 4.0, 1.0];
        symmetrize(&mut m);
        assert_eq!(m, dmatrix![1.0, 3.0; 3.0, 1.0]);
    }
}
