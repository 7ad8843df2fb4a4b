//! The linear state-space model with Gaussian noise that the plants and the estimators share
//! (docs/models.md §2.4, docs/estimators.md §2.7):
//!
//! ```text
//! x_{k+1} = A x_k + B u_k + w_k,   w_k ~ N(0, Q)
//! y_k     = C x_k + D u_k + v_k,   v_k ~ N(0, R)
//! ```
//!
//! with `n` states (at least one), `m` inputs (may be 0: `B` n×0, `D` p×0) and `p` outputs
//! (at least one). [`StateSpace`] holds the six matrices and checks that their shapes agree;
//! what a covariance must be beyond its shape (semidefinite for a plant's noise, definite for
//! a filter's R) is the user's to check. The container is generic so that the FMUs can keep
//! the same six blocks of their variables (`StateSpace<Block>`) and read them into matrices
//! with [`StateSpace::map`].

use crate::ParameterError;
use nalgebra::DMatrix;

/// The matrices A, B, C, D, Q, R of a linear Gaussian state-space model (module docs).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct StateSpace<M = DMatrix<f64>> {
    /// State matrix A (n×n).
    pub a: M,
    /// Input matrix B (n×m).
    pub b: M,
    /// Output matrix C (p×n).
    pub c: M,
    /// Feedthrough D (p×m).
    pub d: M,
    /// Process-noise covariance Q (n×n).
    pub q: M,
    /// Measurement-noise covariance R (p×p).
    pub r: M,
}

impl<M> StateSpace<M> {
    /// The same six blocks, each transformed by `f` (e.g. variable blocks read into matrices).
    pub fn map<N>(&self, mut f: impl FnMut(&M) -> N) -> StateSpace<N> {
        StateSpace {
            a: f(&self.a),
            b: f(&self.b),
            c: f(&self.c),
            d: f(&self.d),
            q: f(&self.q),
            r: f(&self.r),
        }
    }
}

impl StateSpace {
    /// A model without input: `B` n×0 and `D` p×0.
    pub fn without_input(
        a: DMatrix<f64>,
        c: DMatrix<f64>,
        q: DMatrix<f64>,
        r: DMatrix<f64>,
    ) -> Self {
        let (n, p) = (a.nrows(), c.nrows());
        Self {
            a,
            b: DMatrix::zeros(n, 0),
            c,
            d: DMatrix::zeros(p, 0),
            q,
            r,
        }
    }

    /// Number of states n.
    pub fn states(&self) -> usize {
        self.a.nrows()
    }

    /// Number of inputs m.
    pub fn inputs(&self) -> usize {
        self.b.ncols()
    }

    /// Number of outputs p.
    pub fn outputs(&self) -> usize {
        self.c.nrows()
    }

    /// Checks that the shapes agree (n ≥ 1 states, p ≥ 1 outputs) and that every entry is
    /// finite; the error names the first bad matrix ("A", "B", "C", "D", "Q", "R").
    pub fn check_dimensions(&self) -> Result<(), ParameterError> {
        let (n, m, p) = (self.states(), self.inputs(), self.outputs());
        if n == 0 {
            return Err(ParameterError::new("A", "must have at least one state"));
        }
        if p == 0 {
            return Err(ParameterError::new(
                "C",
                "must have at least one output row",
            ));
        }
        for (name, matrix, rows, cols, why) in [
            ("A", &self.a, n, n, "square: n×n"),
            ("B", &self.b, n, m, "n rows, like A"),
            ("C", &self.c, p, n, "n columns, like A"),
            ("D", &self.d, p, m, "rows of C × columns of B"),
            ("Q", &self.q, n, n, "a covariance, n×n"),
            ("R", &self.r, p, p, "a covariance, p×p"),
        ] {
            if matrix.shape() != (rows, cols) {
                return Err(ParameterError::new(
                    name,
                    format!(
                        "must be {rows}×{cols} ({why}), got {}×{}",
                        matrix.nrows(),
                        matrix.ncols()
                    ),
                ));
            }
            if let Some(position) = matrix.iter().position(|v| !v.is_finite()) {
                let (row, col) = (position % rows, position / rows);
                return Err(ParameterError::new(
                    name,
                    format!(
                        "entry ({row}, {col}) is not finite ({})",
                        matrix[(row, col)]
                    ),
                ));
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn model() -> StateSpace {
        StateSpace {
            a: DMatrix::identity(2, 2),
            b: DMatrix::zeros(2, 1),
            c: DMatrix::from_row_slice(1, 2, &[1.0, 0.0]),
            d: DMatrix::zeros(1, 1),
            q: DMatrix::identity(2, 2),
            r: DMatrix::identity(1, 1),
        }
    }

    #[test]
    fn dimensions_come_from_a_b_and_c() {
        let m = model();
        assert_eq!((m.states(), m.inputs(), m.outputs()), (2, 1, 1));
        assert_eq!(m.check_dimensions(), Ok(()));
        let free = StateSpace::without_input(m.a, m.c, m.q, m.r);
        assert_eq!((free.b.shape(), free.d.shape()), ((2, 0), (1, 0)));
        assert_eq!(free.check_dimensions(), Ok(()));
    }

    #[test]
    fn the_first_bad_matrix_is_named() {
        let mut m = model();
        m.d = DMatrix::zeros(2, 1);
        let error = m.check_dimensions().unwrap_err();
        assert_eq!(error.parameter, "D");
        assert_eq!(
            error.reason,
            "must be 1×1 (rows of C × columns of B), got 2×1"
        );
        let mut m = model();
        m.q[(1, 0)] = f64::NAN;
        let error = m.check_dimensions().unwrap_err();
        assert_eq!(error.parameter, "Q");
        assert_eq!(error.reason, "entry (1, 0) is not finite (NaN)");
        let mut m = model();
        m.a = DMatrix::zeros(0, 0);
        assert_eq!(m.check_dimensions().unwrap_err().parameter, "A");
    }

    #[test]
    fn map_keeps_the_order_of_the_blocks() {
        let names = StateSpace {
            a: "A",
            b: "B",
            c: "C",
            d: "D",
            q: "Q",
            r: "R",
        };
        let lengths = names.map(|s| s.to_lowercase());
        assert_eq!(lengths.d, "d");
        assert_eq!(lengths.r, "r");
    }
}
