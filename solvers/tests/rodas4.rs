//! RODAS4 (the stiff default): its order on smooth problems with fixed steps, its continuous
//! extension on the Prothero–Robinson problem (a stiff component following a moving
//! manifold, where a Hermite cubic through the end derivatives fails), and Robertson and
//! van der Pol (ε = 10⁻⁶, i.e. μ = 1000) against tight references.

use spurio_solvers::{Method, OdeSystem, Settings, Solver};

mod problems;

use problems::{ModelError, Robertson};

/// Prothero–Robinson: `ẏ = λ (y − sin t) + cos t`, exact `y = sin t` from `y(0) = 0`, for
/// any `λ`; stiff for `λ ≪ −1` (the solution is the slow manifold, moving with `t`).
struct ProtheroRobinson(f64);

impl OdeSystem for ProtheroRobinson {
    type Error = ModelError;
    fn rhs(&mut self, t: f64, y: &[f64], dy: &mut [f64]) -> Result<(), ModelError> {
        dy[0] = self.0 * (y[0] - t.sin()) + t.cos();
        Ok(())
    }
}

/// Van der Pol in Liénard time with `ε = 1/μ²` (Hairer & Wanner, *Solving ODEs II*, §IV.1,
/// (1.5')): `ẋ = y`, `ẏ = ((1 − x²) y − x)/ε`.
struct VanDerPol(f64);

impl OdeSystem for VanDerPol {
    type Error = ModelError;
    fn rhs(&mut self, _t: f64, x: &[f64], dx: &mut [f64]) -> Result<(), ModelError> {
        dx[0] = x[1];
        dx[1] = ((1.0 - x[0] * x[0]) * x[1] - x[0]) / self.0;
        Ok(())
    }
}

/// The largest of `|yᵢ − rᵢ| / |rᵢ|`.
fn relative_error(y: &[f64], r: &[f64]) -> f64 {
    y.iter()
        .zip(r)
        .map(|(y, r)| (y - r).abs() / r.abs())
        .fold(0.0, f64::max)
}

/// A solver of `method` from `x0` at `t = 0` with `settings`.
fn started(method: Method, x0: &[f64], settings: Settings) -> Solver {
    let mut solver = Solver::new(method, x0.len(), settings);
    let nominal = vec![1.0; x0.len()];
    solver
        .reset::<ModelError>(0.0, x0, &nominal)
        .expect("dimensions match");
    solver
}

/// Fixed steps of `h` (a tolerance no step can miss, the step bounded by `h`).
fn fixed(h: f64) -> Settings {
    Settings {
        relative: 1e10,
        absolute: 1e10,
        max_step: h,
        initial_step: Some(h),
        ..Settings::default()
    }
}

/// The largest error at the step ends and at the dense output inside the steps (θ = ¼, ½,
/// ¾) of the Prothero–Robinson problem with `λ` to `t_end`.
fn prothero_robinson(method: Method, lambda: f64, settings: Settings, t_end: f64) -> (f64, f64) {
    let mut solver = started(method, &[0.0], settings);
    let mut system = ProtheroRobinson(lambda);
    let (mut ends, mut dense) = (0.0f64, 0.0f64);
    let mut out = [0.0];
    while solver.time() < t_end {
        solver.step(&mut system, t_end).expect("steps");
        let (t0, t1) = (solver.previous_time(), solver.time());
        ends = ends.max((solver.state()[0] - t1.sin()).abs());
        for theta in [0.25, 0.5, 0.75] {
            let t = t0 + theta * (t1 - t0);
            solver.interpolate(t, &mut out);
            dense = dense.max((out[0] - t.sin()).abs());
        }
    }
    (ends, dense)
}

#[test]
fn fourth_order_at_the_step_ends_and_third_order_in_between() {
    // Non-autonomous (the γᵢ h fₜ terms), non-stiff: λ = −1, to t = 2.
    let errors: Vec<(f64, f64)> = [0.2, 0.1, 0.05]
        .iter()
        .map(|&h| prothero_robinson(Method::Rodas4, -1.0, fixed(h), 2.0))
        .collect();
    eprintln!("Prothero–Robinson λ = −1, h = 0.2, 0.1, 0.05: {errors:?}");
    for pair in errors.windows(2) {
        let order = (pair[0].0 / pair[1].0).log2();
        let dense_order = (pair[0].1 / pair[1].1).log2();
        eprintln!("orders: ends {order:.2}, dense {dense_order:.2}");
        assert!((3.7..4.6).contains(&order), "order {order}");
        assert!(dense_order > 2.7, "dense order {dense_order}");
    }
    // Nonlinear and autonomous: van der Pol μ = 1 to t = 1 against a tight DOPRI5 run.
    let mut reference = started(Method::Dopri5, &[2.0, 0.0], Settings::with_tolerance(1e-13));
    reference
        .integrate_to(&mut VanDerPol(1.0), 1.0, 1_000_000)
        .unwrap();
    let error = |h: f64| {
        let mut solver = started(Method::Rodas4, &[2.0, 0.0], fixed(h));
        solver
            .integrate_to(&mut VanDerPol(1.0), 1.0, 10_000)
            .unwrap();
        (0..2)
            .map(|i| (solver.state()[i] - reference.state()[i]).abs())
            .fold(0.0, f64::max)
    };
    let (coarse, fine) = (error(0.05), error(0.025));
    let order = (coarse / fine).log2();
    eprintln!("van der Pol μ = 1: errors {coarse:.2e}, {fine:.2e}, order {order:.2}");
    assert!((3.6..4.8).contains(&order), "order {order}");
}

#[test]
fn the_dense_output_stays_on_a_stiff_moving_manifold() {
    // λ = −10⁶: the steps are far longer than 1/|λ|. The error estimate sees only the
    // (damped) step ends, not how far sin t bends within a step, so the step is bounded, as
    // an output interval bounds it in a run. The dense output from the stages keeps its
    // order 3 there; RODAS3's Hermite cubic multiplies a step end's distance from the
    // manifold by λ through the end derivative.
    let mut dense_errors = Vec::new();
    for max_step in [0.1, 0.05, 0.025] {
        let settings = Settings {
            max_step,
            ..Settings::with_tolerance(1e-8)
        };
        let (ends, dense) = prothero_robinson(Method::Rodas4, -1e6, settings, 10.0);
        let (_, hermite) = prothero_robinson(Method::Rodas3, -1e6, settings, 10.0);
        eprintln!(
            "max step {max_step}: rodas4 ends {ends:.2e} dense {dense:.2e}; rodas3 dense {hermite:.2e}"
        );
        assert!(ends < 1e-8, "max step {max_step}: ends {ends}");
        assert!(dense < 2e-5, "max step {max_step}: dense {dense}");
        assert!(5.0 * dense < hermite, "{dense} against {hermite}");
        dense_errors.push(dense);
    }
    for pair in dense_errors.windows(2) {
        let order = (pair[0] / pair[1]).log2();
        assert!(order > 2.7, "dense order {order}: {dense_errors:?}");
    }
}

#[test]
fn robertson_against_a_tight_reference() {
    let settings = |relative: f64| Settings {
        relative,
        absolute: relative * 1e-4,
        ..Settings::default()
    };
    let run = |method, relative| {
        let mut solver = started(method, &[1.0, 0.0, 0.0], settings(relative));
        solver
            .integrate_to(&mut Robertson, 40.0, 1_000_000)
            .unwrap();
        solver
    };
    // The reference: RODAS3 (another method) at 10⁻¹²; Hairer & Wanner give y₁ = 0.7158271,
    // y₃ = 0.2841637 at t = 40.
    let reference = run(Method::Rodas3, 1e-12);
    let r = reference.state().to_vec();
    assert!(
        (r[0] - 0.7158271).abs() < 1e-7 && (r[2] - 0.2841637).abs() < 1e-7,
        "{r:?}"
    );
    for relative in [1e-5, 1e-7, 1e-9] {
        let solver = run(Method::Rodas4, relative);
        let y = solver.state();
        let error = relative_error(y, &r);
        eprintln!(
            "rtol {relative:e}: relative error {error:.2e}, {:?}",
            solver.statistics()
        );
        assert!(error < 10.0 * relative, "rtol {relative}: {error}");
        assert!(
            (y.iter().sum::<f64>() - 1.0).abs() < 1e-12,
            "mass kept: {y:?}"
        );
    }
}

#[test]
fn van_der_pol_mu_1000_against_a_tight_reference() {
    // ε = 10⁻⁶ from (2, 0) to t = 2 (Hairer & Wanner, §IV.10: y₁(2) = 1.706167732170483,
    // y₂(2) = −0.8928097010247975); the reference, RODAS3 at 10⁻¹², is checked against them.
    let run = |method, tol| {
        let mut solver = started(method, &[2.0, 0.0], Settings::with_tolerance(tol));
        solver
            .integrate_to(&mut VanDerPol(1e-6), 2.0, 10_000_000)
            .unwrap();
        solver
    };
    let reference = run(Method::Rodas3, 1e-12);
    let r = reference.state().to_vec();
    eprintln!("reference {r:?}, {:?}", reference.statistics());
    let published = [1.706167732170483, -0.8928097010247975];
    for i in 0..2 {
        assert!((r[i] - published[i]).abs() < 1e-8, "{r:?}");
    }
    let mut evaluations = Vec::new();
    for tol in [1e-5, 1e-7, 1e-9] {
        let solver = run(Method::Rodas4, tol);
        let y = solver.state();
        let error = relative_error(y, &r);
        let s = solver.statistics();
        eprintln!("tol {tol:e}: relative error {error:.2e}, {s:?}");
        assert!(error < 50.0 * tol, "tol {tol}: {error}");
        evaluations.push(s.rhs);
    }
    // Bounded work, growing about as the fourth root of the tolerance.
    assert!(evaluations[0] < 10_000, "{evaluations:?}");
    for pair in evaluations.windows(2) {
        let ratio = pair[1] as f64 / pair[0] as f64;
        assert!((1.5..8.0).contains(&ratio), "{evaluations:?}");
    }
}
