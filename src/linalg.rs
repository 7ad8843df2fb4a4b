//! Linear-algebra helpers shared by the estimators and controllers (docs/estimators.md §2.7–§2.12, docs/controllers.md §2.13–§2.14).
//!
//! Everything works on dynamic `DMatrix<f64>` because the FMUs choose their dimensions at
//! packaging or instantiation time.
//!
//! * [`expm`]: the matrix exponential `e^A` by scaling and squaring with the degree-13 Padé
//!   approximant (Higham, "The scaling and squaring method for the matrix exponential
//!   revisited", SIAM J. Matrix Anal. Appl. 26(4), 2005):
//!   `e^A = (r₁₃(A / 2^s))^(2^s)`, `r₁₃ = q₁₃(X)⁻¹ p₁₃(X)`, with `s` chosen so that
//!   `‖A / 2^s‖₁ ≤ θ₁₃ = 5.37`.
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

use nalgebra::{Cholesky, DMatrix};
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
/// Largest 1-norm for which r₁₃ reaches double precision (Higham 2005, Table 2.3).
const THETA13: f64 = 5.371_920_351_148_152;

/// What [`try_expm`] names when `e^A` overflows.
const EXPM_OVERFLOW: &str = "e^A (overflow)";

/// The matrix exponential `e^a`, or an error for a non-square or non-finite matrix.
pub fn try_expm(a: &DMatrix<f64>) -> Result<DMatrix<f64>, LinalgError> {
    let n = require_square("A", a)?;
    require_finite("A", a)?;
    let identity = DMatrix::<f64>::identity(n, n);
    if n == 0 {
        return Ok(identity);
    }
    let norm = norm1(a);
    if !norm.is_finite() {
        // ‖A‖₁ = ∞ would ask for 2^s ≥ ∞ (s saturating to i32::MAX: 2³¹ squarings).
        return Err(LinalgError::NormOverflow {
            what: "A".to_string(),
        });
    }
    let squarings = if norm > THETA13 {
        // 2^s ≥ ‖A‖₁ / θ₁₃; at most 1022 for a finite ‖A‖₁ ≤ f64::MAX.
        (norm / THETA13).log2().ceil().max(0.0) as i32
    } else {
        0
    };
    let x = a * 2f64.powi(-squarings);
    let b = &PADE13;
    let x2 = &x * &x;
    let x4 = &x2 * &x2;
    let x6 = &x2 * &x4;
    // U = X [X⁶(b₁₃X⁶ + b₁₁X⁴ + b₉X²) + b₇X⁶ + b₅X⁴ + b₃X² + b₁I]
    let u_inner = &x6 * (&x6 * b[13] + &x4 * b[11] + &x2 * b[9])
        + &x6 * b[7]
        + &x4 * b[5]
        + &x2 * b[3]
        + &identity * b[1];
    let u = &x * u_inner;
    // V = X⁶(b₁₂X⁶ + b₁₀X⁴ + b₈X²) + b₆X⁶ + b₄X⁴ + b₂X² + b₀I
    let v = &x6 * (&x6 * b[12] + &x4 * b[10] + &x2 * b[8])
        + &x6 * b[6]
        + &x4 * b[4]
        + &x2 * b[2]
        + &identity * b[0];
    // r₁₃ = (V − U)⁻¹ (V + U)
    let mut result = lu_solve(&(&v - &u), &(&v + &u), "Padé denominator q₁₃(A/2^s)")?;
    for _ in 0..squarings {
        result = &result * &result;
    }
    require_finite(EXPM_OVERFLOW, &result)?;
    Ok(result)
}

/// The matrix exponential `e^a` (scaling and squaring, Padé 13; see the module doc).
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
