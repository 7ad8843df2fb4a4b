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
//!   time-invariant model; the exponential by scaling and squaring with Padé approximants on
//!   buffers kept in the work, [`spurio::linalg::MatrixExponential`]: nothing allocated);
//! - otherwise, and for the parameter columns Φ_xθ always (the FMU gives no derivative with
//!   respect to a parameter), by central differences of the integrator over the interval:
//!   column i = (x(t_k; ẑ + δᵢ eᵢ) − x(t_k; ẑ − δᵢ eᵢ)) / (2δᵢ), δᵢ = [`RELATIVE_STEP`]
//!   · max(|ẑᵢ|, 1); for a parameter within δᵢ of a bound of its declared range the pair is
//!   moved inside it, its width kept (θ at min: [min, min + 2δᵢ]), a one-sided difference
//!   where the central one would see the plant at the bound on one side and halve the slope
//!   (docs/estimators.md, "Parameters within their declared range"). Each perturbed start is
//!   placed with the mean's event indicators as its reference (as the UKF's sigma points
//!   are), so a start across an event surface has its event: the differences then carry the
//!   saltation of the hybrid model.
//!
//! **Measurement Jacobian** H = ∂y/∂z at (t_k, x̂⁻, θ̂) by central differences of the FMU's
//! measured variables (placed, not integrated), the same steps δᵢ.
//!
//! **Covariances.** P⁻ = Φ P Φᵀ + Q (symmetrised), S = H P⁻ Hᵀ + R, C = P⁻ Hᵀ, then
//! [`crate::filter`]'s correction with H (Joseph form). For a linear model
//! (ẋ = A x, y = C x) every difference is exact up to the integrator's error, and the filter
//! is the Kalman filter of the sampled system (x_{k+1} = e^{Ah} x_k).

use crate::plant::Start;
use crate::prediction::{symmetrise, FilterError, Prediction, Sizes, Step};
use nalgebra::{DMatrix, DVector};
use spurio::linalg::MatrixExponential;

/// δᵢ / max(|ẑᵢ|, 1) of the central differences (module documentation): the truncation
/// error O(δ²) ≈ 10⁻⁸ against the integrator's error / δ at tolerances of 10⁻⁸ and below.
pub const RELATIVE_STEP: f64 = 1e-4;

/// The extended prediction's work buffers, made once for the filter's dimensions.
#[derive(Debug, Clone)]
pub(crate) struct ExtendedWork {
    /// The steps δᵢ.
    delta: Vec<f64>,
    /// x(t₁) of the mean.
    x_prior: Vec<f64>,
    /// x(t₁) and y(t₁) of a start not kept.
    scratch: (Vec<f64>, Vec<f64>),
    /// θ of a start, and the buffers of the differences.
    differencing: Differencing,
    /// The event indicators where the mean starts and where it ends.
    start_reference: Vec<f64>,
    end_reference: Vec<f64>,
    /// ∂x/∂z (n × L) and, from H's differences, ∂x/∂z at t₁ (not used).
    dx: DMatrix<f64>,
    dx_unused: DMatrix<f64>,
    /// ∂y/∂z of Φ's differences (not used).
    dy_unused: DMatrix<f64>,
    /// A(t₀), A(t₁) (n × n, column-major), ½ h (A(t₀) + A(t₁)), its exponential Φ_xx and
    /// the exponential's buffers.
    a0: Vec<f64>,
    a1: Vec<f64>,
    exponent: DMatrix<f64>,
    transition: DMatrix<f64>,
    exponential: MatrixExponential,
    /// Φ, Φᵀ, Φ P (L × L), Hᵀ (L × p).
    phi: DMatrix<f64>,
    phi_t: DMatrix<f64>,
    phi_p: DMatrix<f64>,
    h_t: DMatrix<f64>,
}

impl ExtendedWork {
    pub fn new(sizes: &Sizes) -> Self {
        let (n, l, p) = (sizes.states, sizes.filter_states, sizes.measured);
        Self {
            delta: vec![0.0; l],
            x_prior: vec![0.0; n],
            scratch: (vec![0.0; n], vec![0.0; p]),
            differencing: Differencing {
                theta: vec![0.0; sizes.parameters],
                plus: (vec![0.0; n], vec![0.0; p]),
                minus: (vec![0.0; n], vec![0.0; p]),
                moved: DVector::zeros(l),
            },
            start_reference: Vec::with_capacity(sizes.indicators),
            end_reference: Vec::with_capacity(sizes.indicators),
            dx: DMatrix::zeros(n, l),
            dx_unused: DMatrix::zeros(n, l),
            dy_unused: DMatrix::zeros(p, l),
            a0: vec![0.0; n * n],
            a1: vec![0.0; n * n],
            exponent: DMatrix::zeros(n, n),
            transition: DMatrix::zeros(n, n),
            exponential: MatrixExponential::new(n),
            phi: DMatrix::zeros(l, l),
            phi_t: DMatrix::zeros(l, l),
            phi_p: DMatrix::zeros(l, l),
            h_t: DMatrix::zeros(l, p),
        }
    }
}

/// x(t₁) and y(t₁) from z at t₀ (y read at t₀ when t₁ = t₀), the parameters of z set in
/// `theta`; the event indicators where z was placed into `placed` (a reference for the states
/// near it), when asked for.
fn evaluate(
    step: &mut Step,
    z: &[f64],
    (t0, t1): (f64, f64),
    (reference, placed): (Option<&[f64]>, Option<&mut Vec<f64>>),
    theta: &mut [f64],
    out: (&mut [f64], &mut [f64]),
) -> Result<(), FilterError> {
    step.parameters_of(z, theta);
    let start = Start {
        time: t0,
        states: &z[..step.states],
        parameters: theta,
        inputs: step.u,
        reference,
    };
    step.plant.propagate(&start, t1, out.0, out.1)?;
    if let Some(placed) = placed {
        placed.clear();
        placed.extend_from_slice(step.plant.event_indicators());
    }
    Ok(())
}

/// The buffers of central differences: θ of a start, the ± starts' images, the moved start.
#[derive(Debug, Clone)]
struct Differencing {
    theta: Vec<f64>,
    plus: (Vec<f64>, Vec<f64>),
    minus: (Vec<f64>, Vec<f64>),
    moved: DVector<f64>,
}

/// Central differences (module documentation) of x(t₁) and y(t₁) from z at t₀ over the
/// entries `columns` of `centre`, each start placed with `reference`: ∂x/∂z (n×L) into `dx`,
/// ∂y/∂z (p×L) into `dy`, the columns not asked for zero.
fn differences(
    step: &mut Step,
    centre: &DVector<f64>,
    (columns, delta): (std::ops::Range<usize>, &[f64]),
    (interval, reference): ((f64, f64), &[f64]),
    work: &mut Differencing,
    (dx, dy): (&mut DMatrix<f64>, &mut DMatrix<f64>),
) -> Result<(), FilterError> {
    let (n, p_out) = (step.states, step.r.len());
    let Differencing {
        theta,
        plus,
        minus,
        moved,
    } = work;
    dx.fill(0.0);
    dy.fill(0.0);
    moved.copy_from(centre);
    for i in columns {
        let (low, high) = pair(step, i, centre[i], delta[i]);
        let width = high - low;
        if width <= 0.0 {
            continue; // a parameter whose range is one value: no slope
        }
        for (image, end) in [(&mut *plus, high), (&mut *minus, low)] {
            moved[i] = end;
            let out = (&mut image.0[..], &mut image.1[..]);
            let reference = (Some(reference), None);
            evaluate(step, moved.as_slice(), interval, reference, theta, out)?;
        }
        moved[i] = centre[i];
        for r in 0..n {
            dx[(r, i)] = (plus.0[r] - minus.0[r]) / width;
        }
        for j in 0..p_out {
            dy[(j, i)] = (plus.1[j] - minus.1[j]) / width;
        }
    }
    Ok(())
}

/// The two ends of entry i's difference: ẑᵢ ∓ δᵢ, or, for a parameter where one end would
/// leave its declared range, the pair of the same width 2δᵢ moved inside it, [min, min + 2δᵢ]
/// or [max − 2δᵢ, max] (cut to the range if it is narrower). The plant sees Π(θ), so a
/// central pair across a bound would measure half the slope; the moved pair is the one-sided
/// difference, first-order accurate (module documentation).
fn pair(step: &Step, i: usize, centre: f64, delta: f64) -> (f64, f64) {
    let (mut low, mut high) = (centre - delta, centre + delta);
    let parameter = i.checked_sub(step.states).map(|k| step.augmented[k]);
    if let Some(range) = parameter.map(|k| step.plant.parameters()[k].range) {
        if let Some(min) = range.min.filter(|min| low < *min) {
            (low, high) = (min, min + 2.0 * delta);
        }
        if let Some(max) = range.max.filter(|max| high > *max) {
            (low, high) = (max - 2.0 * delta, max);
        }
        (low, high) = (range.clamp(low), range.clamp(high));
    }
    (low, high)
}

/// The linearised prediction over the step's interval (module documentation), into `out`.
pub(crate) fn predict(
    step: &mut Step,
    work: &mut ExtendedWork,
    out: &mut Prediction,
) -> Result<(), FilterError> {
    let n = step.states;
    let l = step.z.len();
    let (t0, t1) = (step.t0, step.t1);
    let z0: &DVector<f64> = step.z;
    let Prediction {
        z: z_prior,
        p,
        y: y_hat,
        s,
        cross,
        jacobian,
    } = out;
    let Some(h) = jacobian else {
        return Err(FilterError::Settings(
            "the extended prediction was given no room for H".into(),
        ));
    };
    for (d, v) in work.delta.iter_mut().zip(z0.iter()) {
        *d = RELATIVE_STEP * v.abs().max(1.0);
    }
    // The mean, and the reference event indicators of the start and of the end.
    let placed = (None, Some(&mut work.start_reference));
    let out = (&mut work.x_prior[..], y_hat.as_mut_slice());
    evaluate(
        step,
        z0.as_slice(),
        (t0, t1),
        placed,
        &mut work.differencing.theta,
        out,
    )?;
    let events = step.plant.events_in_last_propagation();
    z_prior.copy_from(z0);
    z_prior.rows_mut(0, n).copy_from_slice(&work.x_prior);
    // H at (t₁, x̂⁻, θ̂).
    let placed = (None, Some(&mut work.end_reference));
    let out = (&mut work.scratch.0[..], &mut work.scratch.1[..]);
    evaluate(
        step,
        z_prior.as_slice(),
        (t1, t1),
        placed,
        &mut work.differencing.theta,
        out,
    )?;
    let at = ((t1, t1), &work.end_reference[..]);
    let into = (&mut work.dx_unused, &mut *h);
    let columns = (0..l, &work.delta[..]);
    differences(step, z_prior, columns, at, &mut work.differencing, into)?;
    p.copy_from(step.p);
    if t1 > t0 {
        let phi = &mut work.phi;
        phi.fill_with_identity();
        // Φ_xx from the variational equation where the FMU gives A and no event intervened.
        let variational = events == 0 && {
            step.parameters_of(z0.as_slice(), &mut work.differencing.theta);
            let mut jacobian_at = |time: f64, states: &[f64], a: &mut [f64]| {
                let start = Start {
                    time,
                    states,
                    parameters: &work.differencing.theta,
                    inputs: step.u,
                    reference: None,
                };
                step.plant.state_jacobian_into(&start, a)
            };
            jacobian_at(t0, &z0.as_slice()[..n], &mut work.a0)?
                && jacobian_at(t1, &work.x_prior, &mut work.a1)?
        };
        let differenced = if variational {
            let half_step = 0.5 * (t1 - t0);
            let exponent = work.exponent.as_mut_slice();
            for ((e, a0), a1) in exponent.iter_mut().zip(&work.a0).zip(&work.a1) {
                *e = (a0 + a1) * half_step;
            }
            work.exponential
                .exp_into(&work.exponent, &mut work.transition)
                .map_err(|source| FilterError::TransitionMatrix { time: t1, source })?;
            phi.view_mut((0, 0), (n, n)).copy_from(&work.transition);
            n..l
        } else {
            0..l
        };
        let columns = differenced.clone();
        let at = ((t0, t1), &work.start_reference[..]);
        let into = (&mut work.dx, &mut work.dy_unused);
        let asked = (differenced, &work.delta[..]);
        differences(step, z0, asked, at, &mut work.differencing, into)?;
        for i in columns {
            phi.view_mut((0, i), (n, 1)).copy_from(&work.dx.column(i));
        }
        // P⁻ = Φ P Φᵀ.
        phi.mul_to(p, &mut work.phi_p);
        phi.transpose_to(&mut work.phi_t);
        work.phi_p.mul_to(&work.phi_t, p);
    }
    if let Some(q) = step.q {
        for i in 0..l {
            p[(i, i)] += q[i];
        }
    }
    symmetrise(p);
    if !p.iter().all(|v| v.is_finite()) {
        return Err(FilterError::NotPositive {
            what: "state covariance P",
            sample: step.sample,
            time: t1,
        });
    }
    h.transpose_to(&mut work.h_t);
    p.mul_to(&work.h_t, cross);
    h.mul_to(cross, s);
    for (j, r) in step.r.iter().enumerate() {
        s[(j, j)] += r;
    }
    symmetrise(s);
    Ok(())
}
