//! The FMI 3.0 view of a variable table: structured scalar names become array variables.
//!
//! The table declares scalars (value reference = index), with the FMI 2.0 structured names
//! `x_hat[3]`, `A_hat[1,2]` (1-based, row-major, see `fmus/common/src/structured.rs`). FMI 3.0
//! has arrays, so the export layer groups, generically, every run of consecutive scalars
//! that share a base name, a type, causality, variability, initial, unit and bounds and
//! whose indices fill a full row-major grid `[1..d1, 1..d2, …]` (all the
//! consecutive elements of that base name, or none): one array
//! variable with one value reference, `nValues` counted in elements. Everything else stays a
//! scalar.
//!
//! FMI 3.0 value references: 0 is the independent variable `time` (FMI 3.0 requires one);
//! `k ≥ 1` is the `k`-th FMI 3.0 variable, in table order.

use crate::variables::Variable;

/// One FMI 3.0 variable: a scalar of the table or an array over consecutive scalars.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Fmi3Variable {
    /// Its FMI 3.0 name (the base name of an array).
    pub name: String,
    /// Index in the table of its first element.
    pub first: usize,
    /// Dimensions, outermost first; empty for a scalar.
    pub dims: Vec<usize>,
}

impl Fmi3Variable {
    /// Number of scalars it covers.
    pub fn len(&self) -> usize {
        self.dims.iter().product()
    }
    /// Whether it covers no scalar (never: dimensions are at least 1).
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
    /// Its description: the elements' one when they share it, else each element's, named.
    pub fn description(&self, table: &[Variable]) -> String {
        let elements = &table[self.indices()];
        let first = &elements[0].description;
        if elements.iter().all(|v| &v.description == first) {
            return first.clone();
        }
        elements
            .iter()
            .map(|v| format!("{}: {}", v.name, v.description))
            .collect::<Vec<_>>()
            .join("; ")
    }
    /// The table indices it covers, in row-major order.
    pub fn indices(&self) -> std::ops::Range<usize> {
        self.first..self.first + self.len()
    }
}

/// An element an FMI 3.0 value reference stands for.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Target<'a> {
    /// Value reference 0: the independent variable.
    Time,
    /// A variable of the table (scalar or array).
    Variable(&'a Fmi3Variable),
}

/// The FMI 3.0 variables of a table.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct Layout {
    variables: Vec<Fmi3Variable>,
    /// For each table index, the FMI 3.0 value reference of the variable holding it.
    value_reference_of: Vec<u32>,
}

/// Value reference of the independent variable `time`.
pub const TIME: u32 = 0;

/// `name` as `(base, indices)` when it is a structured name `base[i,j,…]` with 1-based
/// integer indices.
fn split_name(name: &str) -> Option<(&str, Vec<usize>)> {
    let open = name.find('[')?;
    let inner = name[open + 1..].strip_suffix(']')?;
    let indices = inner
        .split(',')
        .map(|s| s.trim().parse::<usize>().ok().filter(|i| *i >= 1))
        .collect::<Option<Vec<usize>>>()?;
    (open > 0).then(|| (&name[..open], indices))
}

/// Whether `b` may be an element of the same array as `a` (all but name, description, start
/// and dependencies equal).
fn same_kind(a: &Variable, b: &Variable) -> bool {
    a.variable_type() == b.variable_type()
        && a.causality == b.causality
        && a.variability == b.variability
        && a.initial == b.initial
        && a.unit == b.unit
        && a.min == b.min
        && a.max == b.max
}

/// The row-major 1-based indices of element `k` of an array of `dims`.
fn unravel(mut k: usize, dims: &[usize]) -> Vec<usize> {
    let mut out = vec![0; dims.len()];
    for (slot, d) in out.iter_mut().zip(dims).rev() {
        *slot = k % d + 1;
        k /= d;
    }
    out
}

impl Layout {
    /// Groups the table's structured scalars into arrays.
    pub fn of(table: &[Variable]) -> Self {
        let mut variables = Vec::new();
        let mut i = 0;
        while i < table.len() {
            let group = Self::array_at(table, i);
            let (name, dims) = match &group {
                Some((base, dims)) => (base.to_string(), dims.clone()),
                None => (table[i].name.clone(), Vec::new()),
            };
            let v = Fmi3Variable {
                name,
                first: i,
                dims,
            };
            i += v.len();
            variables.push(v);
        }
        let mut value_reference_of = vec![0; table.len()];
        for (k, v) in variables.iter().enumerate() {
            for index in v.indices() {
                value_reference_of[index] = k as u32 + 1;
            }
        }
        Self {
            variables,
            value_reference_of,
        }
    }

    /// The array starting at `first`: base name and dimensions, if the scalars there form a
    /// full row-major grid.
    fn array_at(table: &[Variable], first: usize) -> Option<(&str, Vec<usize>)> {
        let head = &table[first];
        let (base, start) = split_name(&head.name)?;
        if start.iter().any(|i| *i != 1) {
            return None;
        }
        // Every consecutive element of the same base name: all of them form the array, or
        // none does (no array `w` beside a scalar `w[2]`).
        let mut members = Vec::new();
        for v in &table[first..] {
            match split_name(&v.name) {
                Some((b, idx)) if b == base && idx.len() == start.len() => {
                    if !same_kind(head, v) {
                        return None;
                    }
                    members.push(idx)
                }
                _ => break,
            }
        }
        let dims: Vec<usize> = (0..start.len())
            .map(|d| members.iter().map(|m| m[d]).max().unwrap_or(1))
            .collect();
        let grid = members.len() == dims.iter().product::<usize>()
            && members
                .iter()
                .enumerate()
                .all(|(k, idx)| *idx == unravel(k, &dims));
        grid.then_some((base, dims))
    }

    /// The FMI 3.0 variables (value reference = position + 1).
    pub fn variables(&self) -> &[Fmi3Variable] {
        &self.variables
    }

    /// What value reference `vr` stands for.
    pub fn target(&self, vr: u32) -> Option<Target<'_>> {
        if vr == TIME {
            return Some(Target::Time);
        }
        self.variables.get(vr as usize - 1).map(Target::Variable)
    }

    /// The table indices the value references `vrs` name, in order (arrays row-major; `time`
    /// and unknown references name none).
    pub fn indices_of<'a>(&'a self, vrs: &'a [u32]) -> impl Iterator<Item = usize> + Clone + 'a {
        vrs.iter().flat_map(|&vr| match self.target(vr) {
            Some(Target::Variable(v)) => v.indices(),
            _ => 0..0,
        })
    }

    /// The FMI 3.0 value reference of the variable holding table index `index`.
    pub fn value_reference_of(&self, index: usize) -> Option<u32> {
        self.value_reference_of.get(index).copied()
    }

    /// The highest value reference.
    pub fn max_value_reference(&self) -> u32 {
        self.variables.len() as u32
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn table() -> Vec<Variable> {
        let mut t = vec![Variable::parameter("k", 1.0), Variable::input("u[1]", 0.0)];
        for i in 1..=2 {
            for j in 1..=3 {
                t.push(Variable::parameter(
                    &format!("A[{i},{j}]"),
                    (i * 10 + j) as f64,
                ));
            }
        }
        t.push(Variable::output("y[1]"));
        t.push(Variable::output("y[2]"));
        // Not a grid: starts at 2.
        t.push(Variable::output("z[2]"));
        // Same base, other kind: two scalars, not an array.
        t.push(Variable::parameter("w[1]", 0.0).min(0.0));
        t.push(Variable::parameter("w[2]", 0.0));
        // Element descriptions differ: kept, named.
        t.push(Variable::output("v[1]").describe("first"));
        t.push(Variable::output("v[2]").describe("second"));
        t
    }

    #[test]
    fn structured_scalars_become_row_major_arrays() {
        let layout = Layout::of(&table());
        let summary: Vec<(&str, usize, Vec<usize>)> = layout
            .variables()
            .iter()
            .map(|v| (v.name.as_str(), v.first, v.dims.clone()))
            .collect();
        assert_eq!(
            summary,
            [
                ("k", 0, vec![]),
                ("u", 1, vec![1]),
                ("A", 2, vec![2, 3]),
                ("y", 8, vec![2]),
                ("z[2]", 10, vec![]),
                ("w[1]", 11, vec![]),
                ("w[2]", 12, vec![]),
                ("v", 13, vec![2]),
            ]
        );
        let t = table();
        assert_eq!(
            layout.variables()[7].description(&t),
            "v[1]: first; v[2]: second"
        );
        assert_eq!(layout.variables()[2].description(&t), "");
        assert_eq!(layout.value_reference_of(7), Some(3));
        assert_eq!(layout.value_reference_of(9), Some(4));
        assert_eq!(layout.target(0), Some(Target::Time));
        assert_eq!(layout.target(9), None);
        assert_eq!(layout.max_value_reference(), 8);
    }

    #[test]
    fn a_matrix_with_a_missing_element_stays_scalars() {
        let t = vec![
            Variable::parameter("A[1,1]", 0.0),
            Variable::parameter("A[1,2]", 0.0),
            Variable::parameter("A[2,1]", 0.0),
        ];
        let layout = Layout::of(&t);
        assert_eq!(layout.variables().len(), 3);
        assert!(layout.variables().iter().all(|v| v.dims.is_empty()));
        assert_eq!(unravel(5, &[2, 3]), vec![2, 3]);
        assert_eq!(split_name("x_hat[3]"), Some(("x_hat", vec![3])));
        assert_eq!(split_name("x[0]"), None);
        assert_eq!(split_name("[1]"), None);
    }
}
