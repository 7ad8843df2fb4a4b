//! LU factorisation with partial pivoting of a square matrix stored column by column in a
//! slice (`a[i + j·n]` is row `i`, column `j`, as nalgebra stores its matrices), in place:
//! `P A = L U`, `L` with a unit diagonal below, `U` on and above the diagonal. No inverse is
//! ever formed; a solve is a forward and a backward substitution. Allocation-free: the row
//! permutation goes into a slice the caller owns.

/// Factorises the `n × n` matrix `a` (column-major) in place, recording the row order in
/// `rows` (`rows[k]` is the original row now at `k`). `false` when a pivot is zero or not
/// finite (the matrix is singular, or holds NaN); `a` is then left partly factorised.
///
/// The pivot of column `k` is the entry of largest magnitude on or below the diagonal (the
/// last one among equals).
pub fn factorise(a: &mut [f64], n: usize, rows: &mut [usize]) -> bool {
    debug_assert!(a.len() >= n * n && rows.len() >= n);
    for (k, row) in rows.iter_mut().enumerate().take(n) {
        *row = k;
    }
    for k in 0..n {
        let mut pivot = k;
        for i in k + 1..n {
            if a[i + k * n]
                .abs()
                .total_cmp(&a[pivot + k * n].abs())
                .is_ge()
            {
                pivot = i;
            }
        }
        let p = a[pivot + k * n];
        if p == 0.0 || !p.is_finite() {
            return false;
        }
        if pivot != k {
            for j in 0..n {
                a.swap(k + j * n, pivot + j * n);
            }
            rows.swap(k, pivot);
        }
        for i in k + 1..n {
            let m = a[i + k * n] / a[k + k * n];
            a[i + k * n] = m;
            for j in k + 1..n {
                a[i + j * n] -= m * a[k + j * n];
            }
        }
    }
    true
}

/// Solves `A x = b` with the factors of [`factorise`]: `x` receives the solution (`b` and `x`
/// are distinct slices of length `n`).
pub fn solve(lu: &[f64], n: usize, rows: &[usize], b: &[f64], x: &mut [f64]) {
    for i in 0..n {
        x[i] = b[rows[i]];
    }
    for i in 0..n {
        for j in 0..i {
            x[i] -= lu[i + j * n] * x[j];
        }
    }
    for i in (0..n).rev() {
        for j in i + 1..n {
            x[i] -= lu[i + j * n] * x[j];
        }
        x[i] /= lu[i + i * n];
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn solves_with_pivoting_and_refuses_a_singular_matrix() {
        // A = [[1e-20, 1], [1, 1]] column-major; b = (1, 2): x = (1/(1 − 1e-20), …) ≈ (1, 1).
        let mut a = [1e-20, 1.0, 1.0, 1.0];
        let mut rows = [0; 2];
        assert!(factorise(&mut a, 2, &mut rows));
        let mut x = [0.0; 2];
        solve(&a, 2, &rows, &[1.0, 2.0], &mut x);
        assert!(
            (x[0] - 1.0).abs() < 1e-15 && (x[1] - 1.0).abs() < 1e-15,
            "{x:?}"
        );
        let mut singular = [1.0, 2.0, 2.0, 4.0];
        assert!(!factorise(&mut singular, 2, &mut rows));
        let mut nan = [f64::NAN, 0.0, 0.0, 1.0];
        assert!(!factorise(&mut nan, 2, &mut rows));
    }

    #[test]
    fn a_random_system_is_solved_to_round_off() {
        // A deterministic, well-conditioned 6 × 6 matrix (diagonally weighted).
        let n = 6;
        let mut a = vec![0.0; n * n];
        let mut seed = 7u64;
        for (k, v) in a.iter_mut().enumerate() {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            *v = (seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5
                + if k % (n + 1) == 0 { 3.0 } else { 0.0 };
        }
        let original = a.clone();
        let expected: Vec<f64> = (0..n).map(|i| i as f64 - 2.5).collect();
        let b: Vec<f64> = (0..n)
            .map(|i| (0..n).map(|j| original[i + j * n] * expected[j]).sum())
            .collect();
        let mut rows = vec![0; n];
        assert!(factorise(&mut a, n, &mut rows));
        let mut x = vec![0.0; n];
        solve(&a, n, &rows, &b, &mut x);
        for (x, e) in x.iter().zip(&expected) {
            assert!((x - e).abs() < 1e-13, "{x} {e}");
        }
    }
}
