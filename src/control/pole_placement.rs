//! Pole placement by Ackermann's formula (paper 000 §IV, eqs 8–15; docs/controllers.md §2.13).
//!
//! For the discrete single-input system `x_{k+1} = A x_k + B u_k` with reachability matrix
//! (paper eq. 14)
//!
//! ```text
//! 𝒞 = [B  A B  …  A^{n−1} B]
//! ```
//!
//! the state feedback `u_k = −L x_k` that gives `A − B L` the characteristic polynomial
//! `φ(z) = Π (z − p_i) = z^n + φ₁ z^{n−1} + … + φ_n` (paper eq. 12) is
//!
//! ```text
//! L = [0 … 0 1] 𝒞⁻¹ φ(A),      φ(A) = A^n + φ₁ A^{n−1} + … + φ_n I.
//! ```
//!
//! This is the paper's eq. (15), `L = [(p₁ − a₁) … (p_n − a_n)] W̃_C W_C⁻¹`, written without
//! the detour through the reachable canonical form (both give the same L). The row
//! `[0 … 0 1] 𝒞⁻¹` is obtained by solving `𝒞ᵀ y = e_n` (LU), never by inverting 𝒞.
//!
//! The poles must come as a self-conjugate set (complex ones in conjugate pairs) so that L is
//! real. Ackermann's formula is single-input: `B` must be one column (the crane and every
//! controller of the papers are single-input). A multi-input design needs another method
//! (e.g. [`crate::linalg::dlqr`]).
//!
//! [`poles_from_continuous`] maps continuous poles `s` to discrete ones `z = e^{s Ts}`, which
//! is exactly where the ZOH discretisation sends them.

use nalgebra::allocator::Allocator;
use nalgebra::{
    Complex, DMatrix, DVector, DefaultAllocator, Dim, DimDiff, DimMin, DimMinimum, DimSub, Matrix,
    OMatrix, OVector, Storage, U1,
};
use std::fmt;

/// Reachability matrices with a larger 2-norm condition number are treated as not reachable.
pub const DEFAULT_MAX_CONDITION_NUMBER: f64 = 1e12;

/// Relative tolerance for a pole to count as real or as the conjugate of another.
const CONJUGATE_TOLERANCE: f64 = 1e-9;

/// Why a pole-placement design could not be made.
#[derive(Debug, Clone, PartialEq)]
pub enum PolePlacementError {
    /// `A` is not square or is empty.
    NotSquare {
        /// Rows of A.
        rows: usize,
        /// Columns of A.
        cols: usize,
    },
    /// `B` does not have as many rows as `A`.
    DimensionMismatch {
        /// States (rows of A).
        states: usize,
        /// Rows of B.
        b_rows: usize,
    },
    /// `B` has more (or fewer) than one column: Ackermann's formula is single-input.
    NotSingleInput {
        /// Columns of B.
        columns: usize,
    },
    /// The number of poles is not the number of states.
    WrongPoleCount {
        /// States (rows of A).
        expected: usize,
        /// Poles given.
        got: usize,
    },
    /// A complex pole without its conjugate partner (L would not be real).
    NotConjugate {
        /// The unmatched pole.
        pole: Complex<f64>,
    },
    /// A requested pole is not strictly inside the unit circle (stability was required).
    UnstablePole {
        /// The pole.
        pole: Complex<f64>,
        /// Its modulus.
        modulus: f64,
    },
    /// A, B or a pole contains NaN or infinity.
    NonFinite {
        /// Which input (`"A"`, `"B"`, `"poles"`).
        what: &'static str,
    },
    /// The pair (A, B) is not (numerically) reachable.
    NotReachable {
        /// 2-norm condition number of the reachability matrix (∞ when singular).
        condition_number: f64,
        /// The threshold it exceeded.
        threshold: f64,
    },
    /// The computed gain contains NaN or infinity.
    NonFiniteGain,
}

impl fmt::Display for PolePlacementError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::NotSquare { rows, cols } => {
                write!(f, "A must be a non-empty square matrix, got {rows}×{cols}")
            }
            Self::DimensionMismatch { states, b_rows } => {
                write!(f, "B must have as many rows as A ({states}), got {b_rows}")
            }
            Self::NotSingleInput { columns } => write!(
                f,
                "Ackermann's formula is single-input: B must have 1 column, got {columns}"
            ),
            Self::WrongPoleCount { expected, got } => write!(
                f,
                "need one pole per state: expected {expected} poles, got {got}"
            ),
            Self::NotConjugate { pole } => write!(
                f,
                "complex pole {} {:+}j has no conjugate partner (poles must come in conjugate \
                 pairs for a real gain)",
                pole.re, pole.im
            ),
            Self::UnstablePole { pole, modulus } => write!(
                f,
                "pole {} {:+}j is not inside the unit circle (|z| = {modulus}); the closed loop \
                 would be unstable",
                pole.re, pole.im
            ),
            Self::NonFinite { what } => write!(f, "{what} contains NaN or infinity"),
            Self::NotReachable {
                condition_number,
                threshold,
            } => write!(
                f,
                "(A, B) is not reachable: the reachability matrix has condition number \
                 {condition_number:e} (limit {threshold:e})"
            ),
            Self::NonFiniteGain => write!(f, "the computed gain contains NaN or infinity"),
        }
    }
}

impl std::error::Error for PolePlacementError {}

/// Options of [`ackermann_with_options`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PolePlacementOptions {
    /// Reject poles with `|z| ≥ 1` (discrete-time stability). Off by default so the formula
    /// can also be used for continuous-time designs.
    pub require_stable: bool,
    /// Reachability matrices with a larger condition number are rejected as not reachable.
    pub max_condition_number: f64,
}

impl Default for PolePlacementOptions {
    fn default() -> Self {
        Self {
            require_stable: false,
            max_condition_number: DEFAULT_MAX_CONDITION_NUMBER,
        }
    }
}

/// The reachability matrix `𝒞 = [B  A B  …  A^{n−1} B]` (paper 000 eq. 14), n × (n·m).
///
/// Shapes are not checked here (a non-square `a` or mismatched `b` gives an empty matrix).
pub fn reachability_matrix(a: &DMatrix<f64>, b: &DMatrix<f64>) -> DMatrix<f64> {
    let n = a.nrows();
    if !a.is_square() || b.nrows() != n {
        return DMatrix::zeros(0, 0);
    }
    let m = b.ncols();
    let mut reach = DMatrix::zeros(n, n * m);
    let mut block = b.clone();
    for k in 0..n {
        reach.view_mut((0, k * m), (n, m)).copy_from(&block);
        block = a * &block;
    }
    reach
}

/// 2-norm condition number `σ_max / σ_min` (∞ when singular or not finite), for a matrix of
/// any dimensions, static or dynamic.
pub fn condition_number<R, C, S>(m: &Matrix<f64, R, C, S>) -> f64
where
    R: DimMin<C>,
    C: Dim,
    S: Storage<f64, R, C>,
    DimMinimum<R, C>: DimSub<U1>,
    DefaultAllocator: Allocator<R, C>
        + Allocator<C>
        + Allocator<R>
        + Allocator<DimDiff<DimMinimum<R, C>, U1>>
        + Allocator<DimMinimum<R, C>, C>
        + Allocator<R, DimMinimum<R, C>>
        + Allocator<DimMinimum<R, C>>,
{
    if m.is_empty() || !m.iter().all(|v| v.is_finite()) {
        return f64::INFINITY;
    }
    let singular_values = m.singular_values();
    let largest = singular_values.max();
    let smallest = singular_values.min();
    if smallest > 0.0 {
        largest / smallest
    } else {
        f64::INFINITY
    }
}

/// Discrete poles `z = e^{s ts}` for continuous poles `s`.
pub fn poles_from_continuous(s_poles: &[Complex<f64>], ts: f64) -> Vec<Complex<f64>> {
    s_poles.iter().map(|s| (s * ts).exp()).collect()
}

/// Checks that `poles` is a self-conjugate set of finite values (and, if asked, inside the
/// unit circle).
pub fn check_poles(poles: &[Complex<f64>], require_stable: bool) -> Result<(), PolePlacementError> {
    if poles
        .iter()
        .any(|p| !(p.re.is_finite() && p.im.is_finite()))
    {
        return Err(PolePlacementError::NonFinite { what: "poles" });
    }
    let mut matched = vec![false; poles.len()];
    for (i, p) in poles.iter().enumerate() {
        if matched[i] {
            continue;
        }
        let tolerance = CONJUGATE_TOLERANCE * p.norm().max(1.0);
        if p.im.abs() <= tolerance {
            matched[i] = true;
            continue;
        }
        let partner = (i + 1..poles.len())
            .find(|&j| !matched[j] && (poles[j] - p.conj()).norm() <= tolerance);
        match partner {
            Some(j) => {
                matched[i] = true;
                matched[j] = true;
            }
            None => return Err(PolePlacementError::NotConjugate { pole: *p }),
        }
    }
    if require_stable {
        if let Some(p) = poles.iter().find(|p| p.norm() >= 1.0) {
            return Err(PolePlacementError::UnstablePole {
                pole: *p,
                modulus: p.norm(),
            });
        }
    }
    Ok(())
}

/// Monic characteristic polynomial `Π (z − p_i)` as real coefficients
/// `[1, φ₁, …, φ_n]` (descending powers). The poles must be self-conjugate.
pub fn characteristic_polynomial(poles: &[Complex<f64>]) -> Vec<f64> {
    let mut coefficients = vec![Complex::new(1.0, 0.0)];
    for p in poles {
        let mut next = coefficients.clone();
        next.push(Complex::new(0.0, 0.0));
        for (k, c) in coefficients.iter().enumerate() {
            next[k + 1] -= c * p;
        }
        coefficients = next;
    }
    coefficients.iter().map(|c| c.re).collect()
}

/// Single-input Ackermann pole placement with the default options (no stability check,
/// condition-number limit 1e12). Returns the 1 × n gain `L` of `u = −L x`.
pub fn ackermann(
    a: &DMatrix<f64>,
    b: &DMatrix<f64>,
    poles: &[Complex<f64>],
) -> Result<DMatrix<f64>, PolePlacementError> {
    ackermann_with_options(a, b, poles, &PolePlacementOptions::default())
}

/// Single-input Ackermann pole placement `L = [0 … 0 1] 𝒞⁻¹ φ(A)` (see the module doc).
pub fn ackermann_with_options(
    a: &DMatrix<f64>,
    b: &DMatrix<f64>,
    poles: &[Complex<f64>],
    options: &PolePlacementOptions,
) -> Result<DMatrix<f64>, PolePlacementError> {
    let n = a.nrows();
    if !a.is_square() || n == 0 {
        return Err(PolePlacementError::NotSquare {
            rows: a.nrows(),
            cols: a.ncols(),
        });
    }
    if b.nrows() != n {
        return Err(PolePlacementError::DimensionMismatch {
            states: n,
            b_rows: b.nrows(),
        });
    }
    if b.ncols() != 1 {
        return Err(PolePlacementError::NotSingleInput { columns: b.ncols() });
    }
    if poles.len() != n {
        return Err(PolePlacementError::WrongPoleCount {
            expected: n,
            got: poles.len(),
        });
    }
    if !a.iter().all(|v| v.is_finite()) {
        return Err(PolePlacementError::NonFinite { what: "A" });
    }
    if !b.iter().all(|v| v.is_finite()) {
        return Err(PolePlacementError::NonFinite { what: "B" });
    }
    check_poles(poles, options.require_stable)?;

    let characteristic = characteristic_polynomial(poles);
    let b = DVector::from_column_slice(b.as_slice());
    let gain = gain_of(a, &b, &characteristic, options.max_condition_number)?;
    Ok(DMatrix::from_row_slice(1, n, gain.as_slice()))
}

/// The Ackermann gain `[0 … 0 1] 𝒞⁻¹ φ(A)` of a checked single-input pair (`A` square, `B`
/// one column of as many rows, both finite) for the monic polynomial `characteristic`
/// (`[1, φ₁, …, φ_n]`), on matrices of dimension `D`: the same arithmetic for a static
/// dimension (no heap: what the controllers use for the packaged sizes) and for [`Dyn`].
pub fn gain_of<D>(
    a: &OMatrix<f64, D, D>,
    b: &OVector<f64, D>,
    characteristic: &[f64],
    max_condition_number: f64,
) -> Result<OMatrix<f64, U1, D>, PolePlacementError>
where
    D: DimMin<D, Output = D> + DimSub<U1>,
    DefaultAllocator: Allocator<D, D> + Allocator<D> + Allocator<U1, D> + Allocator<DimDiff<D, U1>>,
{
    let (dim, _) = a.shape_generic();
    let n = dim.value();
    // 𝒞 = [B  A B  …  A^{n−1} B], column by column.
    let mut reach = OMatrix::<f64, D, D>::zeros_generic(dim, dim);
    let mut block = b.clone_owned();
    for k in 0..n {
        reach.set_column(k, &block);
        block = a * &block;
    }
    // yᵀ = e_nᵀ 𝒞⁻¹  ⇔  𝒞ᵀ y = e_n, by LU.
    let lu = reach.transpose().lu();
    // Reachable enough? First the cheap bound cond₂(𝒞) ≤ ‖𝒞‖_F ‖𝒞⁻¹‖_F from the LU; the
    // singular values (most of the cost) only when the bound does not settle it, so an
    // estimate is accepted or refused as by the 2-norm condition number itself.
    let bound = lu
        .try_inverse()
        .map(|inverse| reach.norm() * inverse.norm());
    if !bound.is_some_and(|b| b <= max_condition_number) {
        let condition = condition_number(&reach);
        if condition.is_nan() || condition > max_condition_number {
            return Err(PolePlacementError::NotReachable {
                condition_number: condition,
                threshold: max_condition_number,
            });
        }
    }
    // φ(A) by Horner: M ← M A + φ_k I.
    let identity = OMatrix::<f64, D, D>::identity_generic(dim, dim);
    let mut phi_of_a = identity.clone();
    for coefficient in characteristic.iter().skip(1) {
        phi_of_a = &phi_of_a * a + &identity * *coefficient;
    }
    let mut last_unit = OVector::<f64, D>::zeros_generic(dim, U1);
    if let Some(last) = n.checked_sub(1) {
        last_unit[last] = 1.0;
    }
    let y = lu
        .solve(&last_unit)
        .ok_or(PolePlacementError::NotReachable {
            condition_number: f64::INFINITY,
            threshold: max_condition_number,
        })?;
    let gain = y.transpose() * phi_of_a;
    if gain.iter().all(|v| v.is_finite()) {
        Ok(gain)
    } else {
        Err(PolePlacementError::NonFiniteGain)
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use nalgebra::dmatrix;

    /// Largest distance between two multisets of complex numbers, after greedy
    /// nearest-neighbour matching.
    pub(crate) fn max_pole_mismatch(got: &[Complex<f64>], want: &[Complex<f64>]) -> f64 {
        assert_eq!(got.len(), want.len());
        let mut used = vec![false; got.len()];
        let mut worst: f64 = 0.0;
        for w in want {
            let (best, distance) = got
                .iter()
                .enumerate()
                .filter(|(i, _)| !used[*i])
                .map(|(i, g)| (i, (g - w).norm()))
                .fold((usize::MAX, f64::INFINITY), |acc, x| {
                    if x.1 < acc.1 {
                        x
                    } else {
                        acc
                    }
                });
            used[best] = true;
            worst = worst.max(distance);
        }
        worst
    }

    fn closed_loop_poles(
        a: &DMatrix<f64>,
        b: &DMatrix<f64>,
        l: &DMatrix<f64>,
    ) -> Vec<Complex<f64>> {
        (a - b * l).complex_eigenvalues().iter().copied().collect()
    }

    #[test]
    fn places_poles_of_a_double_integrator() {
        let ts = 0.1;
        let a = dmatrix![1.0, ts; 0.0, 1.0];
        let b = dmatrix![0.5 * ts * ts; ts];
        let poles = [Complex::new(0.6, 0.2), Complex::new(0.6, -0.2)];
        let l = ackermann(&a, &b, &poles).unwrap();
        assert!(max_pole_mismatch(&closed_loop_poles(&a, &b, &l), &poles) < 1e-12);
    }

    #[test]
    fn deadbeat_placement_makes_the_closed_loop_nilpotent() {
        let a = dmatrix![0.0, 1.0, 0.0; 0.0, 0.0, 1.0; -0.5, 0.2, 1.1];
        let b = dmatrix![0.0; 0.0; 1.0];
        let zero = Complex::new(0.0, 0.0);
        let l = ackermann(&a, &b, &[zero, zero, zero]).unwrap();
        let closed = &a - &b * &l;
        assert!((&closed * &closed * &closed).amax() < 1e-14);
        // Companion form: L is the difference of the polynomial coefficients.
        assert!((l - dmatrix![-0.5, 0.2, 1.1]).amax() < 1e-14);
    }

    #[test]
    fn characteristic_polynomial_of_a_conjugate_pair() {
        let p = characteristic_polynomial(&[Complex::new(1.0, 2.0), Complex::new(1.0, -2.0)]);
        assert_eq!(p, vec![1.0, -2.0, 5.0]);
    }

    #[test]
    fn continuous_poles_map_through_the_exponential() {
        let z = poles_from_continuous(&[Complex::new(-1.0, 0.5)], 0.05);
        let expected = Complex::new(
            (-0.05f64).exp() * 0.025f64.cos(),
            (-0.05f64).exp() * 0.025f64.sin(),
        );
        assert!((z[0] - expected).norm() < 1e-15);
    }

    #[test]
    fn every_bad_input_gives_a_named_error() {
        let a = dmatrix![1.0, 0.1; 0.0, 1.0];
        let b = dmatrix![0.0; 0.1];
        let half = Complex::new(0.5, 0.0);
        let e = ackermann(&a, &b, &[half]).unwrap_err();
        assert_eq!(
            e,
            PolePlacementError::WrongPoleCount {
                expected: 2,
                got: 1
            }
        );
        assert!(e.to_string().contains("expected 2 poles, got 1"));

        let e = ackermann(&a, &b, &[Complex::new(0.5, 0.1), Complex::new(0.4, -0.1)]).unwrap_err();
        assert!(matches!(e, PolePlacementError::NotConjugate { .. }), "{e}");

        let e = ackermann(&a, &dmatrix![0.0, 1.0; 0.1, 0.0], &[half, half]).unwrap_err();
        assert_eq!(e, PolePlacementError::NotSingleInput { columns: 2 });

        let e = ackermann(&a, &dmatrix![0.0; 0.1; 0.0], &[half, half]).unwrap_err();
        assert!(
            matches!(e, PolePlacementError::DimensionMismatch { .. }),
            "{e}"
        );

        let e = ackermann(&dmatrix![1.0, 0.0], &b, &[half]).unwrap_err();
        assert!(matches!(e, PolePlacementError::NotSquare { .. }), "{e}");

        // Unreachable: B feeds only the first state, which does not drive the second.
        let e = ackermann(&a, &dmatrix![1.0; 0.0], &[half, half]).unwrap_err();
        match e {
            PolePlacementError::NotReachable {
                condition_number, ..
            } => assert!(condition_number > 1e12),
            other => panic!("expected NotReachable, got {other}"),
        }
        let e = ackermann(&a, &dmatrix![0.0; 0.0], &[half, half]).unwrap_err();
        assert!(e.to_string().contains("not reachable"), "{e}");

        let e = ackermann(&dmatrix![f64::NAN, 0.1; 0.0, 1.0], &b, &[half, half]).unwrap_err();
        assert_eq!(e, PolePlacementError::NonFinite { what: "A" });
        let e = ackermann(&a, &dmatrix![0.0; f64::INFINITY], &[half, half]).unwrap_err();
        assert_eq!(e, PolePlacementError::NonFinite { what: "B" });
        let e = ackermann(&a, &b, &[half, Complex::new(f64::NAN, 0.0)]).unwrap_err();
        assert_eq!(e, PolePlacementError::NonFinite { what: "poles" });

        let unstable = [Complex::new(1.2, 0.0), half];
        assert!(ackermann(&a, &b, &unstable).is_ok());
        let options = PolePlacementOptions {
            require_stable: true,
            ..PolePlacementOptions::default()
        };
        let e = ackermann_with_options(&a, &b, &unstable, &options).unwrap_err();
        assert!(matches!(e, PolePlacementError::UnstablePole { .. }), "{e}");
    }

    #[test]
    fn reachability_matrix_stacks_the_powers() {
        let a = dmatrix![1.0, 2.0; 0.0, 3.0];
        let b = dmatrix![1.0; 1.0];
        assert_eq!(reachability_matrix(&a, &b), dmatrix![1.0, 3.0; 1.0, 3.0]);
    }
}
