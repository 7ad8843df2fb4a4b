//! Physical plants of the papers (docs/models.md §2.1–§2.4).

pub mod gantry_crane;
pub mod linear_system;
pub mod opamp_filter;
pub mod wind_generator;

/// `∂f/∂x` at `x` by central differences, the step along `xⱼ` being
/// `relative_step · max(|xⱼ|, 1)` (the plants' tests hold their Jacobians to it).
#[cfg(test)]
pub(crate) fn central_differences<const N: usize, const M: usize>(
    f: impl Fn(&nalgebra::SVector<f64, N>) -> nalgebra::SVector<f64, M>,
    x: &nalgebra::SVector<f64, N>,
    relative_step: f64,
) -> nalgebra::SMatrix<f64, M, N> {
    let mut jacobian = nalgebra::SMatrix::<f64, M, N>::zeros();
    for j in 0..N {
        let step = relative_step * x[j].abs().max(1.0);
        let (mut plus, mut minus) = (*x, *x);
        plus[j] += step;
        minus[j] -= step;
        jacobian.set_column(j, &((f(&plus) - f(&minus)) / (2.0 * step)));
    }
    jacobian
}

/// `|a − b| ≤ 1e-6 · max(|a|, |b|, largest entry of the row)`: a Jacobian entry against its
/// central difference.
#[cfg(test)]
pub(crate) fn close_in_row(a: f64, b: f64, row_scale: f64) -> bool {
    (a - b).abs() <= 1e-6 * a.abs().max(b.abs()).max(row_scale)
}

/// [`central_differences`] of `f(x, u)` along the state `x` and along a scalar input `u`.
#[cfg(test)]
pub(crate) fn state_and_input_differences<const N: usize>(
    f: impl Fn(&nalgebra::SVector<f64, N>, f64) -> nalgebra::SVector<f64, N>,
    x: &nalgebra::SVector<f64, N>,
    u: f64,
    relative_step: f64,
) -> (nalgebra::SMatrix<f64, N, N>, nalgebra::SVector<f64, N>) {
    let along_x = central_differences(|x| f(x, u), x, relative_step);
    let along_u = central_differences(
        |u: &nalgebra::Vector1<f64>| f(x, u[0]),
        &nalgebra::Vector1::new(u),
        relative_step,
    );
    (along_x, along_u.column(0).into_owned())
}
