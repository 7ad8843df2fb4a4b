//! State and parameter estimators of spurio (docs/estimators.md §2.7–§2.12, "Maximum
//! likelihood").
//!
//! | type | what | paper |
//! |---|---|---|
//! | [`KalmanFilter`] | standard Kalman filter (sKF) | 000 §IV, 001 §2 |
//! | [`RobustKalmanFilter`] | robust-statistics Kalman filter (rsKF, Cipra & Romera 1997) | 000 §V, 001 §2 |
//! | [`DualKalmanFilter`] | dual Kalman filter: states + Θ = [A B; C D] (DKF) | 000 §VI, 001 §2 (Haykin ch. 5) |
//! | [`DkfRsKf`] | rsKF cleaning the outputs feeding a DKF | 001 §3, Fig. 2 |
//! | [`RecursiveLeastSquares`] | ARX(na, nb) RLS with forgetting, continuous readout | 002 §3 |
//! | [`DistributedObserver`] | one agent of the two-agent LQ-designed observer | 004 §3–4 |
//! | [`likelihood`] | the innovations log-likelihood of a linear Gaussian model (offline maximum likelihood, diffuse initial state) | Durbin & Koopman §7.2 |
//!
//! All matrices are dynamic (`DMatrix<f64>`): the dimensions are chosen by the user when an
//! FMU is packaged. Every constructor validates its inputs and returns an
//! [`EstimationError`] naming the matrix and the reason; every step method returns an error
//! (never NaN) when a factorisation fails or a result is not finite. Covariances are updated
//! in Joseph form (the Kalman filters' in O(n²p), on one triangle, see `kalman.rs`) and kept
//! exactly symmetric, gains come from Cholesky solves, no inverse is formed. The step
//! methods work in buffers allocated by the constructors; the sizes of the packaged FMUs
//! (one state and one output, two, eight states and two outputs) run kernels of their own.
//!
//! Time convention shared by the Kalman-type filters: the model is
//! x_{k+1} = A x_k + B u_k + w_k, y_k = C x_k + D u_k + v_k. A call `step(u_k, y_k)` predicts
//! from the previous estimate x̂_{k−1|k−1} with the previous input u_{k−1} (zero before the
//! first call), then corrects with y_k. The initial x̂₀, P₀ given to a constructor are the
//! estimate one sample before the first call.

#[cfg(test)]
mod adaptive_loop;
mod distributed;
mod dual;
mod estimator;
mod kalman;
pub mod likelihood;
mod missing;
mod rls;
mod robust;

pub use distributed::{DistributedObserver, DistributedObserverConfig, ObserverDesign};
pub use dual::{
    AdaptationBounds, DkfRsKf, DualKalmanConfig, DualKalmanFilter, ParameterMeasurement,
};
pub use estimator::StateEstimator;
pub use kalman::{GaussianModel, KalmanFilter, ScalarKalmanFilter};
pub use rls::{ContinuousSecondOrder, ReadoutUnavailable, RecursiveLeastSquares};
pub use robust::{InfluenceFunction, RobustKalmanFilter, ScalarRobustKalmanFilter, MIN_WEIGHT};

use crate::linalg::dense;
use crate::ParameterError;
use nalgebra::{Cholesky, DMatrix, DVector, SymmetricEigen};
use std::fmt;

/// What can go wrong when building or stepping an estimator.
#[derive(Debug, Clone, PartialEq)]
pub enum EstimationError {
    /// A constructor argument is not acceptable (names the parameter and says why).
    Parameter(ParameterError),
    /// A step was given a vector of the wrong length.
    Dimension {
        /// Which input ("u", "y", "x_neighbour", ...).
        what: &'static str,
        /// The length the estimator was built for.
        expected: usize,
        /// The length it got.
        got: usize,
    },
    /// A matrix that must be symmetric positive definite was not, during a step.
    Factorisation {
        /// Which matrix (for example "innovation covariance C P⁻ Cᵀ + R").
        what: &'static str,
        /// The number of the step that failed (1 for the first call).
        step: u64,
    },
    /// A step produced (or was given) a value that is not finite.
    NonFinite {
        /// Which quantity.
        what: &'static str,
        /// The number of the step (1 for the first call).
        step: u64,
    },
    /// The design (gain computation) at construction is impossible, and why.
    Design {
        /// What was being designed.
        what: &'static str,
        /// Why it failed.
        reason: String,
    },
}

impl fmt::Display for EstimationError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Parameter(error) => write!(f, "{error}"),
            Self::Dimension {
                what,
                expected,
                got,
            } => write!(
                f,
                "input `{what}` has length {got}, the estimator was built for length {expected}"
            ),
            Self::Factorisation { what, step } => write!(
                f,
                "step {step}: the {what} is not symmetric positive definite (Cholesky failed)"
            ),
            Self::NonFinite { what, step } => {
                write!(f, "step {step}: the {what} is not finite (NaN or infinity)")
            }
            Self::Design { what, reason } => write!(f, "cannot design the {what}: {reason}"),
        }
    }
}

impl std::error::Error for EstimationError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            Self::Parameter(error) => Some(error),
            _ => None,
        }
    }
}

impl From<ParameterError> for EstimationError {
    fn from(error: ParameterError) -> Self {
        Self::Parameter(error)
    }
}

// ---------------------------------------------------------------------------------------
// Validation helpers shared by the constructors.
// ---------------------------------------------------------------------------------------

fn parameter_error(parameter: &str, reason: impl Into<String>) -> EstimationError {
    EstimationError::Parameter(ParameterError::new(parameter, reason))
}

/// Relative tolerance for "symmetric" and "positive semidefinite" checks on user matrices.
const SYMMETRY_TOLERANCE: f64 = 1e-9;

pub(crate) fn require_finite_matrix(name: &str, m: &DMatrix<f64>) -> Result<(), EstimationError> {
    if let Some(position) = m.iter().position(|v| !v.is_finite()) {
        let (row, col) = (position % m.nrows().max(1), position / m.nrows().max(1));
        return Err(parameter_error(
            name,
            format!("entry ({row}, {col}) is not finite ({})", m[(row, col)]),
        ));
    }
    Ok(())
}

pub(crate) fn require_finite_vector(name: &str, v: &DVector<f64>) -> Result<(), EstimationError> {
    if let Some(index) = v.iter().position(|v| !v.is_finite()) {
        return Err(parameter_error(
            name,
            format!("entry {index} is not finite ({})", v[index]),
        ));
    }
    Ok(())
}

pub(crate) fn require_shape(
    name: &str,
    m: &DMatrix<f64>,
    rows: usize,
    cols: usize,
    why: &str,
) -> Result<(), EstimationError> {
    if m.nrows() != rows || m.ncols() != cols {
        return Err(parameter_error(
            name,
            format!(
                "must be {rows}×{cols} ({why}), got {}×{}",
                m.nrows(),
                m.ncols()
            ),
        ));
    }
    require_finite_matrix(name, m)
}

pub(crate) fn require_length(
    name: &str,
    v: &DVector<f64>,
    len: usize,
    why: &str,
) -> Result<(), EstimationError> {
    if v.len() != len {
        return Err(parameter_error(
            name,
            format!("must have length {len} ({why}), got {}", v.len()),
        ));
    }
    require_finite_vector(name, v)
}

fn require_symmetric(name: &str, m: &DMatrix<f64>) -> Result<(), EstimationError> {
    let scale = m.amax().max(1.0);
    for i in 0..m.nrows() {
        for j in 0..i {
            if (m[(i, j)] - m[(j, i)]).abs() > SYMMETRY_TOLERANCE * scale {
                return Err(parameter_error(
                    name,
                    format!(
                        "must be symmetric, but entry ({i}, {j}) = {} differs from ({j}, {i}) = {}",
                        m[(i, j)],
                        m[(j, i)]
                    ),
                ));
            }
        }
    }
    Ok(())
}

/// Checks that `m` is a finite, symmetric, positive definite `dim`×`dim` matrix.
pub(crate) fn require_spd(name: &str, m: &DMatrix<f64>, dim: usize) -> Result<(), EstimationError> {
    require_shape(name, m, dim, dim, "a covariance")?;
    require_symmetric(name, m)?;
    if dim > 0 && Cholesky::new(m.clone()).is_none() {
        return Err(parameter_error(
            name,
            "must be positive definite (its Cholesky factorisation failed)",
        ));
    }
    Ok(())
}

/// Checks that `m` is a finite, symmetric, positive semidefinite `dim`×`dim` matrix.
pub(crate) fn require_psd(name: &str, m: &DMatrix<f64>, dim: usize) -> Result<(), EstimationError> {
    require_shape(name, m, dim, dim, "a covariance")?;
    require_symmetric(name, m)?;
    if dim == 0 {
        return Ok(());
    }
    let eigen = SymmetricEigen::new(m.clone());
    let smallest = eigen.eigenvalues.min();
    if smallest < -SYMMETRY_TOLERANCE * m.amax().max(1.0) {
        return Err(parameter_error(
            name,
            format!("must be positive semidefinite, but has eigenvalue {smallest}"),
        ));
    }
    Ok(())
}

pub(crate) fn require_input_length(
    what: &'static str,
    v: &DVector<f64>,
    expected: usize,
) -> Result<(), EstimationError> {
    if v.len() != expected {
        return Err(EstimationError::Dimension {
            what,
            expected,
            got: v.len(),
        });
    }
    Ok(())
}

/// Solves `s · X = rhs` in place (`rhs` becomes X) with a Cholesky factorisation of the
/// symmetric matrix in `s`, whose lower triangle is overwritten by its lower factor (zeros
/// when the factorisation fails). No allocation. A 1×1 `s` gives `x = b / √s / √s`, nalgebra's
/// order (bit-identical).
pub(crate) fn cholesky_solve_in_place(
    s: &mut DMatrix<f64>,
    rhs: &mut DMatrix<f64>,
    what: &'static str,
    step: u64,
) -> Result<(), EstimationError> {
    let dim = s.nrows();
    if s.iter().any(|v| !v.is_finite()) {
        return Err(EstimationError::NonFinite { what, step });
    }
    if !s.is_square() || rhs.nrows() != dim || !dense::cholesky(s.as_mut_slice(), dim) {
        s.fill(0.0);
        return Err(EstimationError::Factorisation { what, step });
    }
    dense::cholesky_solve(s.as_slice(), dim, rhs.as_mut_slice());
    Ok(())
}

/// Replaces `m` by (m + mᵀ)/2 in place.
pub(crate) fn symmetrize_in_place(m: &mut DMatrix<f64>) {
    crate::linalg::symmetrize(m);
}

// ---------------------------------------------------------------------------------------
// Dynamic state as a flat list of numbers (FMU state serialization).
// ---------------------------------------------------------------------------------------

/// An estimator part whose evolving numbers go into FMU states: [`Saved::save`] appends them,
/// [`Saved::restore`] reads them back in the same order. The provided methods are the
/// estimators' `dynamic_state` and `set_dynamic_state`.
pub(crate) trait Saved {
    /// Appends every evolving number to `out`.
    fn save(&self, out: &mut Vec<f64>);
    /// Reads back what [`Saved::save`] wrote (same dimensions).
    fn restore(&mut self, input: &mut StateReader<'_>) -> Result<(), EstimationError>;

    /// All that [`Saved::save`] writes, as one list.
    fn saved(&self) -> Vec<f64> {
        let mut out = Vec::new();
        self.save(&mut out);
        out
    }
    /// Restores exactly what [`Saved::saved`] returned.
    fn restore_saved(&mut self, state: &[f64]) -> Result<(), EstimationError> {
        let mut input = StateReader::new(state);
        self.restore(&mut input)?;
        input.finish()
    }
}

/// Reads back, in order, the numbers an estimator's `dynamic_state` wrote, into buffers of
/// the estimator (built with the same parameters, so every length is known).
pub(crate) struct StateReader<'a> {
    data: &'a [f64],
    position: usize,
}

/// The largest step counter a saved state may carry: 2^53, the largest whole number below
/// which every whole number is an f64 (the form a state is saved in).
pub(crate) const MAX_SAVED_COUNTER: u64 = 1 << 53;

impl<'a> StateReader<'a> {
    pub(crate) fn new(data: &'a [f64]) -> Self {
        Self { data, position: 0 }
    }

    fn short(&self, wanted: usize) -> EstimationError {
        parameter_error(
            "state",
            format!(
                "the saved estimator state is too short: {} numbers, needed at least {}",
                self.data.len(),
                self.position + wanted
            ),
        )
    }

    /// Fills `target` with the next `target.len()` numbers.
    pub(crate) fn fill(&mut self, target: &mut [f64]) -> Result<(), EstimationError> {
        let end = self.position + target.len();
        let source = self
            .data
            .get(self.position..end)
            .ok_or_else(|| self.short(target.len()))?;
        target.copy_from_slice(source);
        self.position = end;
        Ok(())
    }

    /// The next number.
    pub(crate) fn scalar(&mut self) -> Result<f64, EstimationError> {
        let mut v = [0.0];
        self.fill(&mut v)?;
        Ok(v[0])
    }

    /// The next number as a step counter: a whole number in 0..=[`MAX_SAVED_COUNTER`]. A
    /// larger one no estimator could have saved (it counts by one from 0 and is saved as an
    /// f64), and it would overflow on the next step (`1e20` reads as `u64::MAX`).
    pub(crate) fn counter(&mut self) -> Result<u64, EstimationError> {
        let v = self.scalar()?;
        if !(v.is_finite() && (0.0..=MAX_SAVED_COUNTER as f64).contains(&v) && v.fract() == 0.0) {
            return Err(parameter_error(
                "state",
                format!("a saved step counter must be a whole number in 0..=2^53, got {v}"),
            ));
        }
        Ok(v as u64)
    }

    /// Checks that every number was read.
    pub(crate) fn finish(self) -> Result<(), EstimationError> {
        if self.position != self.data.len() {
            return Err(parameter_error(
                "state",
                format!(
                    "the saved estimator state has {} numbers, this estimator reads {} (built with other dimensions?)",
                    self.data.len(),
                    self.position
                ),
            ));
        }
        Ok(())
    }
}

#[cfg(test)]
mod state_tests {
    use super::robust::test_rng::TestRng;
    use super::*;
    use crate::state_space::StateSpace;

    fn dkf_rskf() -> DkfRsKf {
        let n = 2;
        let a = DMatrix::from_row_slice(n, n, &[0.9, 0.1, -0.1, 0.8]);
        let b = DMatrix::from_row_slice(n, 1, &[0.0, 1.0]);
        let c = DMatrix::from_row_slice(1, n, &[1.0, 0.0]);
        let config = DualKalmanConfig::new(GaussianModel {
            system: StateSpace {
                a,
                b,
                c,
                d: DMatrix::zeros(1, 1),
                q: DMatrix::identity(n, n) * 1e-3,
                r: DMatrix::identity(1, 1) * 1e-2,
            },
            x0: DVector::zeros(n),
            p0: DMatrix::identity(n, n),
        })
        .fix_output_matrices();
        let cleaner =
            RobustKalmanFilter::random_walk(1, 1e-2, 1e-2, 1.0, InfluenceFunction::default())
                .unwrap();
        DkfRsKf::new(cleaner, DualKalmanFilter::new(config).unwrap()).unwrap()
    }

    #[test]
    fn restored_dynamic_state_continues_bit_for_bit() {
        let mut rng = TestRng::new(7);
        let samples: Vec<(f64, f64)> = (0..60)
            .map(|k| ((k as f64 * 0.3).sin(), rng.normal()))
            .collect();
        let mut original = dkf_rskf();
        let mut rls = RecursiveLeastSquares::with_prefilter(2, 2, 0.98, 1e4, 5).unwrap();
        for &(u, y) in &samples[..30] {
            original
                .step(&DVector::from_element(1, u), &DVector::from_element(1, y))
                .unwrap();
            rls.step(u, y).unwrap();
        }
        let mut copy = dkf_rskf();
        copy.set_dynamic_state(&original.dynamic_state()).unwrap();
        let mut rls_copy = RecursiveLeastSquares::with_prefilter(2, 2, 0.98, 1e4, 5).unwrap();
        rls_copy.set_dynamic_state(&rls.dynamic_state()).unwrap();
        for &(u, y) in &samples[30..] {
            let (u, y1) = (DVector::from_element(1, u), DVector::from_element(1, y));
            original.step(&u, &y1).unwrap();
            copy.step(&u, &y1).unwrap();
            assert_eq!(original.dual().theta(), copy.dual().theta());
            assert_eq!(original.dual().state(), copy.dual().state());
            assert_eq!(rls.step(u[0], y).unwrap(), rls_copy.step(u[0], y).unwrap());
            assert_eq!(rls.parameters(), rls_copy.parameters());
        }
        let too_short = &original.dynamic_state()[1..];
        let error = copy.set_dynamic_state(too_short).unwrap_err().to_string();
        assert!(error.contains("state"), "{error}");
        assert!(rls_copy.set_dynamic_state(&[1.0]).is_err());
    }
}

#[cfg(test)]
mod factor_tests {
    use super::*;

    #[test]
    fn one_by_one_solve_matches_nalgebra_bit_for_bit_and_rejects_non_positive() {
        for s0 in [0.37, 1.0, 2.0, 1e-9, 12345.678] {
            let rhs = DMatrix::from_row_slice(1, 3, &[1.0, -0.3, 1.0 / 7.0]);
            let mut expected = rhs.clone();
            let factor = Cholesky::new(DMatrix::from_element(1, 1, s0)).unwrap();
            factor.solve_mut(&mut expected);
            let (mut s, mut x) = (DMatrix::from_element(1, 1, s0), rhs);
            cholesky_solve_in_place(&mut s, &mut x, "S", 1).unwrap();
            for (x, e) in x.iter().zip(expected.iter()) {
                assert_eq!(x.to_bits(), e.to_bits(), "s = {s0}");
            }
            assert_eq!(s[(0, 0)], factor.l()[(0, 0)]);
        }
        // Larger S: the solution of nalgebra's Cholesky within rounding, L in the lower
        // triangle.
        let mut rng = robust::test_rng::TestRng::new(3);
        for dim in [2, 3, 5, 8] {
            let m = DMatrix::from_fn(dim, dim, |_, _| rng.normal());
            let spd = &m * m.transpose() + DMatrix::identity(dim, dim);
            let rhs = DMatrix::from_fn(dim, 4, |_, _| rng.normal());
            let factor = Cholesky::new(spd.clone()).unwrap();
            let expected = factor.solve(&rhs);
            let (mut s, mut x) = (spd, rhs);
            cholesky_solve_in_place(&mut s, &mut x, "S", 1).unwrap();
            assert!((&x - &expected).amax() <= 1e-12 * expected.amax(), "{dim}");
            let l = factor.l();
            assert!(
                (s.lower_triangle() - &l).amax() <= 1e-12 * l.amax(),
                "{dim}"
            );
        }
        for s0 in [0.0, -1.0] {
            let (mut s, mut x) = (DMatrix::from_element(1, 1, s0), DMatrix::zeros(1, 1));
            let e = cholesky_solve_in_place(&mut s, &mut x, "S", 4).unwrap_err();
            assert!(
                matches!(e, EstimationError::Factorisation { step: 4, .. }),
                "{e}"
            );
        }
    }
}

#[cfg(test)]
mod saved_counter_tests {
    use super::*;

    /// A saved step counter above 2^53 is refused: 1e19 read as `u64::MAX` overflowed the
    /// next step's `steps += 1` (found by fuzzing `fmi2DeSerializeFMUstate`,
    /// fmus/kalman/tests/fuzz_findings.rs).
    #[test]
    fn a_step_counter_no_estimator_could_have_saved_is_refused() {
        let limit = MAX_SAVED_COUNTER as f64;
        for ok in [0.0, 1.0, 12345.0, limit] {
            assert_eq!(StateReader::new(&[ok]).counter().unwrap() as f64, ok);
        }
        for bad in [
            limit * 2.0,
            1e19,
            1.8446744073709552e19,
            f64::MAX,
            -1.0,
            0.5,
            f64::NAN,
        ] {
            let e = StateReader::new(&[bad]).counter().unwrap_err().to_string();
            assert!(
                e.contains("step counter") && e.contains("2^53"),
                "{bad}: {e}"
            );
        }
    }
}
