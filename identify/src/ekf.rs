//! The robust extended Kalman filter on an FMU (docs/estimators.md, "Identifying an FMU",
//! "Extended filter"): the state z = [x; θ_a], the settings, the robust correction (in
//! Joseph form) and the trajectory are [`crate::filter`]'s; this module is the linearised
//! prediction.
//!
//! **Mean.** x̂⁻ = x(t_k) integrated by the master's Model Exchange stepper from
//! (t_{k−1}, x̂) at θ̂ with u_{k−1} held (events included), θ̂_a⁻ = θ̂_a (random walk), and
//! ŷ = h(x̂⁻) read from the FMU at t_k.
//!
//! **State-transition matrix** Φ = ∂z(t_k)/∂z(t_{k−1}) (the θ_a rows those of the identity):
//! - the state block Φ_xx, when the FMU gives directional derivatives
//!   (`providesDirectionalDerivative`: A = ∂ẋ/∂x through the master's importer) and no event
//!   happened on the interval, from the variational equation Φ̇ = A(t) Φ, Φ(t_{k−1}) = I,
//!   by its second-order Magnus step with the trapezoidal rule:
//!   Φ_xx = exp(½ h (A(t_{k−1}, x̂) + A(t_k, x̂⁻))), h = t_k − t_{k−1} (exact for a linear
//!   time-invariant model);
//! - otherwise, and for the parameter columns Φ_xθ always (the FMU gives no derivative with
//!   respect to a parameter), by central differences of the integrator over the interval:
//!   column i = (x(t_k; ẑ + δᵢ eᵢ) − x(t_k; ẑ − δᵢ eᵢ)) / (2δᵢ), δᵢ = [`RELATIVE_STEP`]
//!   · max(|ẑᵢ|, 1). Each perturbed start is placed with the mean's event indicators as its
//!   reference (as the UKF's sigma points are), so a start across an event surface has its
//!   event: the differences then carry the saltation of the hybrid model.
//!
//! **Measurement Jacobian** H = ∂y/∂z at (t_k, x̂⁻, θ̂) by central differences of the FMU's
//! measured variables (placed, not integrated), the same steps δᵢ.
//!
//! **Covariances.** P⁻ = Φ P Φᵀ + Q (symmetrised), S = H P⁻ Hᵀ + R, C = P⁻ Hᵀ, then
//! [`crate::filter`]'s correction with H (Joseph form). For a linear model
//! (ẋ = A x, y = C x) every difference is exact up to the integrator's error, and the filter
//! is the Kalman filter of the sampled system (x_{k+1} = e^{Ah} x_k).

use crate::plant::Start;
use crate::prediction::{symmetrise, FilterError, Prediction, Step};
use nalgebra::{DMatrix, DVector};

/// δᵢ / max(|ẑᵢ|, 1) of the central differences (module documentation): the truncation
/// error O(δ²) ≈ 10⁻⁸ against the integrator's error / δ at tolerances of 10⁻⁸ and below.
pub const RELATIVE_STEP: f64 = 1e-4;

/// x(t₁) and y(t₁) from z at t₀ (y read at t₀ when t₁ = t₀), the parameters of z set in θ;
/// gives the event indicators where z was placed (a reference for the states near it).
fn evaluate(
    step: &mut Step,
    z: &[f64],
    (t0, t1): (f64, f64),
    reference: Option<&[f64]>,
    out: (&mut [f64], &mut [f64]),
) -> Result<Vec<f64>, FilterError> {
    let mut theta = step.theta.to_vec();
    step.parameters_of(z, &mut theta);
    let start = Start {
        time: t0,
        states: &z[..step.states],
        parameters: &theta,
        inputs: step.u,
        reference,
    };
    step.plant.propagate(&start, t1, out.0, out.1)?;
    Ok(step.plant.placed_indicators())
}

/// Central differences (module documentation) of x(t₁) and y(t₁) from z at t₀ over the
/// entries `columns` of `centre`, steps `delta`, each start placed with `reference`: (∂x/∂z
/// (n×L), ∂y/∂z (p×L)), the columns not asked for zero.
fn differences(
    step: &mut Step,
    centre: &DVector<f64>,
    delta: &[f64],
    columns: std::ops::Range<usize>,
    interval: (f64, f64),
    reference: &[f64],
) -> Result<(DMatrix<f64>, DMatrix<f64>), FilterError> {
    let (n, l, p_out) = (step.states, centre.len(), step.r.len());
    let mut dx = DMatrix::zeros(n, l);
    let mut dy = DMatrix::zeros(p_out, l);
    let mut plus = (vec![0.0; n], vec![0.0; p_out]);
    let mut minus = plus.clone();
    let mut moved = centre.clone();
    for i in columns {
        moved[i] = centre[i] + delta[i];
        let out = (&mut plus.0[..], &mut plus.1[..]);
        evaluate(step, moved.as_slice(), interval, Some(reference), out)?;
        moved[i] = centre[i] - delta[i];
        let out = (&mut minus.0[..], &mut minus.1[..]);
        evaluate(step, moved.as_slice(), interval, Some(reference), out)?;
        moved[i] = centre[i];
        for r in 0..n {
            dx[(r, i)] = (plus.0[r] - minus.0[r]) / (2.0 * delta[i]);
        }
        for j in 0..p_out {
            dy[(j, i)] = (plus.1[j] - minus.1[j]) / (2.0 * delta[i]);
        }
    }
    Ok((dx, dy))
}

/// The linearised prediction over the step's interval (module documentation).
pub(crate) fn predict(step: &mut Step) -> Result<Prediction, FilterError> {
    let n = step.states;
    let l = step.z.len();
    let p_out = step.r.len();
    let (t0, t1) = (step.t0, step.t1);
    let z0 = step.z.clone();
    let delta: Vec<f64> = z0
        .iter()
        .map(|v| RELATIVE_STEP * v.abs().max(1.0))
        .collect();
    // The mean, and the reference event indicators of the start and of the end.
    let mut x_prior = vec![0.0; n];
    let mut y_hat = vec![0.0; p_out];
    let out = (&mut x_prior[..], &mut y_hat[..]);
    let start_reference = evaluate(step, z0.as_slice(), (t0, t1), None, out)?;
    let events = step.plant.events_in_last_propagation();
    let mut z_prior = z0.clone();
    z_prior.rows_mut(0, n).copy_from_slice(&x_prior);
    // H at (t₁, x̂⁻, θ̂).
    let mut x_scratch = vec![0.0; n];
    let mut y_scratch = vec![0.0; p_out];
    let out = (&mut x_scratch[..], &mut y_scratch[..]);
    let end_reference = evaluate(step, z_prior.as_slice(), (t1, t1), None, out)?;
    let (_, h) = differences(step, &z_prior, &delta, 0..l, (t1, t1), &end_reference)?;
    let mut p = step.p.clone();
    if t1 > t0 {
        let mut phi = DMatrix::identity(l, l);
        // Φ_xx from the variational equation where the FMU gives A and no event intervened.
        let variational = if events == 0 {
            let theta = {
                let mut theta = step.theta.to_vec();
                step.parameters_of(z0.as_slice(), &mut theta);
                theta
            };
            let u = step.u;
            let mut jacobian_at = |time: f64, states: &[f64]| {
                step.plant.state_jacobian(&Start {
                    time,
                    states,
                    parameters: &theta,
                    inputs: u,
                    reference: None,
                })
            };
            let a0 = jacobian_at(t0, &z0.as_slice()[..n])?;
            let a1 = match a0 {
                Some(_) => jacobian_at(t1, &x_prior)?,
                None => None,
            };
            a0.zip(a1).map(|(a0, a1)| {
                let sum = DMatrix::from_vec(n, n, a0) + DMatrix::from_vec(n, n, a1);
                (sum * (0.5 * (t1 - t0))).exp()
            })
        } else {
            None
        };
        let differenced = match variational {
            Some(phi_xx) => {
                phi.view_mut((0, 0), (n, n)).copy_from(&phi_xx);
                n..l
            }
            None => 0..l,
        };
        let columns = differenced.clone();
        let (dx, _) = differences(step, &z0, &delta, differenced, (t0, t1), &start_reference)?;
        for i in columns {
            phi.view_mut((0, i), (n, 1)).copy_from(&dx.column(i));
        }
        p = &phi * p * phi.transpose();
    }
    if let Some(q) = step.q {
        for i in 0..l {
            p[(i, i)] += q[i];
        }
    }
    symmetrise(&mut p);
    if !p.iter().all(|v| v.is_finite()) {
        return Err(FilterError::NotPositive {
            what: "state covariance P",
            sample: step.sample,
            time: t1,
        });
    }
    let cross = &p * h.transpose();
    let mut s = &h * &cross;
    for (j, r) in step.r.iter().enumerate() {
        s[(j, j)] += r;
    }
    symmetrise(&mut s);
    Ok(Prediction {
        z: z_prior,
        p,
        y: DVector::from_vec(y_hat),
        s,
        cross,
        jacobian: Some(h),
    })
}
