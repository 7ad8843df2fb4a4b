//! Structured variables of the dimension-generic FMUs: vectors `x_hat[1]…x_hat[n]` and
//! matrices `A[1,1]…A[n,n]` (FMI 2.0 structured naming, 1-based, row-major), added to a
//! variable table in one call and read back as nalgebra values.

use nalgebra::{DMatrix, DVector};
use spurio_export::{Values, Variable, VariableTable};

/// A block of consecutive variables holding a matrix (row-major) or a vector.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Block {
    /// Index (value reference) of the first element.
    pub first: usize,
    /// Rows.
    pub rows: usize,
    /// Columns (1 for a vector).
    pub cols: usize,
}

impl Block {
    /// Index of element (i, j), 0-based.
    pub fn index(&self, i: usize, j: usize) -> usize {
        self.first + i * self.cols + j
    }
    /// All indices, row-major.
    pub fn indices(&self) -> std::ops::Range<usize> {
        self.first..self.first + self.rows * self.cols
    }
    /// Reads the block as a matrix.
    pub fn matrix(&self, values: &Values) -> DMatrix<f64> {
        DMatrix::from_fn(self.rows, self.cols, |i, j| values.real(self.index(i, j)))
    }
    /// Reads the block as a vector (column-major over the block, i.e. the vector for a
    /// `rows × 1` block).
    pub fn vector(&self, values: &Values) -> DVector<f64> {
        DVector::from_iterator(
            self.rows * self.cols,
            self.indices().map(|k| values.real(k)),
        )
    }
    /// Writes a matrix (or vector) of the block's shape into the values.
    pub fn write(&self, values: &mut Values, m: &DMatrix<f64>) {
        for i in 0..self.rows.min(m.nrows()) {
            for j in 0..self.cols.min(m.ncols()) {
                values.set_real(self.index(i, j), m[(i, j)]);
            }
        }
    }
    /// Writes a vector into a `rows × 1` block.
    #[inline]
    pub fn write_vector(&self, values: &mut Values, v: &DVector<f64>) {
        if let [v] = v.as_slice() {
            if self.rows * self.cols != 0 {
                values.set_real(self.first, *v);
            }
            return;
        }
        for (index, &v) in self.indices().zip(v.as_slice()) {
            values.set_real(index, v);
        }
    }
}

/// Adds a matrix-valued variable `name[i,j]` (`rows × cols`), each element made by
/// `make(element_name, row, col)` (0-based row and col); returns its block.
pub fn add_matrix(
    table: &mut VariableTable,
    name: &str,
    rows: usize,
    cols: usize,
    mut make: impl FnMut(&str, usize, usize) -> Variable,
) -> Block {
    let first = table.variables().len();
    for i in 0..rows {
        for j in 0..cols {
            table.add(make(&format!("{name}[{},{}]", i + 1, j + 1), i, j));
        }
    }
    Block { first, rows, cols }
}

/// Adds a vector-valued variable `name[i]` of length `len`, each element made by
/// `make(element_name, index)` (0-based index); returns its block.
pub fn add_vector(
    table: &mut VariableTable,
    name: &str,
    len: usize,
    mut make: impl FnMut(&str, usize) -> Variable,
) -> Block {
    let first = table.variables().len();
    for i in 0..len {
        table.add(make(&format!("{name}[{}]", i + 1), i));
    }
    Block {
        first,
        rows: len,
        cols: 1,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn blocks_index_row_major_and_round_trip() {
        let mut t = VariableTable::new();
        t.add(Variable::input("u", 0.0));
        let a = add_matrix(&mut t, "A", 2, 3, |n, i, j| {
            Variable::parameter(n, (10 * i + j) as f64)
        });
        let x = add_vector(&mut t, "x_hat", 2, |n, _| Variable::output(n));
        let vars = t.into_variables();
        assert_eq!(vars[a.index(1, 2)].name, "A[2,3]");
        assert_eq!(vars[x.first + 1].name, "x_hat[2]");
        let mut values = Values::from_start(&vars);
        let m = a.matrix(&values);
        assert_eq!(m[(1, 2)], 12.0);
        x.write_vector(&mut values, &DVector::from_vec(vec![1.0, 2.0]));
        assert_eq!(x.vector(&values).as_slice(), &[1.0, 2.0]);
    }
}
