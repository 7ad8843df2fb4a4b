//! The solvers on problems with known solutions: exponential decay, the harmonic oscillator
//! (errors proportional to the tolerance, dense output as accurate as the steps), Robertson's
//! stiff chemistry (the Rosenbrock method in far fewer evaluations than the explicit one),
//! Jacobian–vector products used when given, and bounded work on a model that fails.

use spurio_solvers::{Direction, Method, OdeSystem, Settings, Solver, SolverErrorKind};

mod problems;

use problems::{ModelError, Robertson};

/// `ẋ = −λ x`.
struct Decay(f64);

impl OdeSystem for Decay {
    type Error = ModelError;
    fn rhs(&mut self, _t: f64, x: &[f64], dx: &mut [f64]) -> Result<(), ModelError> {
        dx[0] = -self.0 * x[0];
        Ok(())
    }
}

/// `ẍ = −ω² x` as `(x, v)`, optionally with exact Jacobian–vector products.
struct Oscillator {
    omega: f64,
    products: bool,
}

impl OdeSystem for Oscillator {
    type Error = ModelError;
    fn rhs(&mut self, _t: f64, x: &[f64], dx: &mut [f64]) -> Result<(), ModelError> {
        dx[0] = x[1];
        dx[1] = -self.omega * self.omega * x[0];
        Ok(())
    }
    fn jacobian_times(&mut self, at: Direction<'_>, out: &mut [f64]) -> Result<bool, ModelError> {
        let v = at.v;
        if !self.products {
            return Ok(false);
        }
        out[0] = v[1];
        out[1] = -self.omega * self.omega * v[0];
        Ok(true)
    }
}

fn solve(method: Method, system: &mut impl OdeSystem, x0: &[f64], t_end: f64, tol: f64) -> Solver {
    let mut solver = Solver::new(method, x0.len(), Settings::with_tolerance(tol));
    let nominal = vec![1.0; x0.len()];
    solver
        .reset::<ModelError>(0.0, x0, &nominal)
        .expect("dimensions match");
    solver
        .integrate_to(system, t_end, 1_000_000)
        .map_err(|e| e.to_string())
        .expect("integrates");
    solver
}

#[test]
fn exponential_decay_to_the_tolerance() {
    for method in [
        Method::Dopri5,
        Method::Rodas4,
        Method::Rodas3,
        Method::Shampine4,
    ] {
        for tol in [1e-4, 1e-7, 1e-10] {
            let solver = solve(method, &mut Decay(2.0), &[1.0], 3.0, tol);
            let exact = (-6f64).exp();
            let error = (solver.state()[0] - exact).abs();
            eprintln!(
                "{method} tol {tol:e}: error {error:.2e}, {:?}",
                solver.statistics()
            );
            assert!(error < 10.0 * tol, "{method} {tol}: {error}");
            assert_eq!(solver.time(), 3.0, "ends exactly on the target");
        }
    }
}

#[test]
fn the_oscillator_error_is_proportional_to_the_tolerance_and_the_dense_output_as_good() {
    let omega = 2.0;
    for method in [Method::Dopri5, Method::Rodas4, Method::Rodas3] {
        let mut errors = Vec::new();
        for tol in [1e-6, 1e-8, 1e-10] {
            let mut system = Oscillator {
                omega,
                products: false,
            };
            let mut solver = Solver::new(method, 2, Settings::with_tolerance(tol));
            solver
                .reset::<ModelError>(0.0, &[1.0, 0.0], &[1.0, 1.0])
                .unwrap();
            let (mut worst, mut worst_dense) = (0.0f64, 0.0f64);
            let mut out = [0.0; 2];
            while solver.time() < 10.0 {
                solver.step(&mut system, 10.0).unwrap();
                let t = solver.time();
                worst = worst.max((solver.state()[0] - (omega * t).cos()).abs());
                // the dense output at three points inside the step
                let t0 = solver.previous_time();
                for theta in [0.25, 0.5, 0.75] {
                    let tm = t0 + theta * (t - t0);
                    solver.interpolate(tm, &mut out);
                    worst_dense = worst_dense.max((out[0] - (omega * tm).cos()).abs());
                }
            }
            eprintln!(
                "{method} tol {tol:e}: error {worst:.2e}, dense {worst_dense:.2e}, {:?}",
                solver.statistics()
            );
            assert!(worst < 100.0 * tol, "{method} {tol}: {worst}");
            assert!(
                worst_dense < 200.0 * tol,
                "{method} {tol}: dense {worst_dense}"
            );
            errors.push(worst);
        }
        // A hundred times tighter: tens of times smaller errors (proportional to the tolerance).
        for pair in errors.windows(2) {
            let ratio = pair[0] / pair[1];
            assert!((10.0..1000.0).contains(&ratio), "{method}: ratio {ratio}");
        }
    }
}

#[test]
fn jacobian_vector_products_replace_finite_differences() {
    let with = solve(
        Method::Rodas3,
        &mut Oscillator {
            omega: 1.0,
            products: true,
        },
        &[1.0, 0.0],
        5.0,
        1e-8,
    );
    let without = solve(
        Method::Rodas3,
        &mut Oscillator {
            omega: 1.0,
            products: false,
        },
        &[1.0, 0.0],
        5.0,
        1e-8,
    );
    let (a, b) = (with.statistics(), without.statistics());
    eprintln!("with products {a:?}\nwithout {b:?}");
    assert_eq!(a.jacobian_products, 2 * a.jacobians);
    assert_eq!(b.jacobian_products, 0);
    // finite differences cost two evaluations per Jacobian (one per state)
    if (a.accepted, a.rejected) == (b.accepted, b.rejected) {
        assert_eq!(b.rhs, a.rhs + 2 * b.jacobians);
    } else {
        assert!(b.rhs > a.rhs);
    }
    assert!((with.state()[0] - 5f64.cos()).abs() < 1e-6);
}

#[test]
fn robertson_stiff_method_far_cheaper_than_the_explicit_one() {
    // To t = 40 (Hairer & Wanner's reference values at t = 40: y₁ = 0.7158271, y₃ = 0.2841637).
    let robertson = |method| {
        let settings = Settings {
            relative: 1e-6,
            absolute: 1e-10,
            ..Settings::default()
        };
        let mut solver = Solver::new(method, 3, settings);
        solver
            .reset::<ModelError>(0.0, &[1.0, 0.0, 0.0], &[1.0; 3])
            .unwrap();
        solver
            .integrate_to(&mut Robertson, 40.0, 1_000_000)
            .unwrap();
        solver
    };
    let solver = robertson(Method::Rodas3);
    let stiff = solver.statistics();
    let y = solver.state();
    eprintln!("rodas3: y = {y:?}, {stiff:?}");
    assert!((y[0] - 0.7158271).abs() < 1e-6, "{y:?}");
    assert!((y[2] - 0.2841637).abs() < 1e-6, "{y:?}");
    assert!(
        (y.iter().sum::<f64>() - 1.0).abs() < 1e-10,
        "mass kept: {y:?}"
    );
    let explicit = robertson(Method::Dopri5);
    let nonstiff = explicit.statistics();
    eprintln!("dopri5: y = {:?}, {nonstiff:?}", explicit.state());
    assert!(
        10 * stiff.rhs < nonstiff.rhs,
        "rodas3 {} vs dopri5 {} evaluations",
        stiff.rhs,
        nonstiff.rhs
    );
}

/// A model that fails after `t = 1`: by returning an error, or NaN.
struct Failing {
    nan: bool,
}

impl OdeSystem for Failing {
    type Error = ModelError;
    fn rhs(&mut self, t: f64, _x: &[f64], dx: &mut [f64]) -> Result<(), ModelError> {
        if t > 1.0 {
            if self.nan {
                dx[0] = f64::NAN;
                return Ok(());
            }
            return Err(ModelError(format!("no value at t = {t}")));
        }
        dx[0] = 1.0;
        Ok(())
    }
}

#[test]
fn a_failing_model_ends_in_an_error_naming_the_time_and_nothing_hangs() {
    let start = std::time::Instant::now();
    for method in [Method::Dopri5, Method::Rodas4, Method::Rodas3] {
        let mut solver = Solver::new(method, 1, Settings::default());
        solver.reset::<ModelError>(0.0, &[0.0], &[1.0]).unwrap();
        let e = solver
            .integrate_to(&mut Failing { nan: false }, 2.0, 1000)
            .unwrap_err();
        assert!(matches!(e.kind, SolverErrorKind::Model(_)), "{e}");
        assert!(e.to_string().contains("no value at t ="), "{e}");
        let mut solver = Solver::new(method, 1, Settings::default());
        solver.reset::<ModelError>(0.0, &[0.0], &[1.0]).unwrap();
        let e = solver
            .integrate_to(&mut Failing { nan: true }, 2.0, 1000)
            .unwrap_err();
        eprintln!("{method}: {e}");
        assert!(
            matches!(e.kind, SolverErrorKind::NonFiniteStages { .. }),
            "{e}"
        );
        assert!((e.time - 1.0).abs() < 1e-6, "{}", e.time);
    }
    // bounded steps: a tight tolerance over a long span stops at the step limit
    let mut solver = Solver::new(Method::Dopri5, 2, Settings::with_tolerance(1e-12));
    solver
        .reset::<ModelError>(0.0, &[1.0, 0.0], &[1.0, 1.0])
        .unwrap();
    let e = solver
        .integrate_to(
            &mut Oscillator {
                omega: 1.0,
                products: false,
            },
            1e6,
            500,
        )
        .unwrap_err();
    assert!(
        matches!(e.kind, SolverErrorKind::TooManySteps { max_steps: 500, .. }),
        "{e}"
    );
    assert!(start.elapsed().as_secs_f64() < 5.0);
}

#[test]
fn max_step_is_kept() {
    let mut solver = Solver::new(
        Method::Dopri5,
        1,
        Settings {
            max_step: 0.01,
            ..Settings::default()
        },
    );
    solver.reset::<ModelError>(0.0, &[1.0], &[1.0]).unwrap();
    solver.integrate_to(&mut Decay(1.0), 1.0, 10_000).unwrap();
    assert!(
        solver.statistics().accepted >= 100,
        "{:?}",
        solver.statistics()
    );
}

/// Van der Pol, μ = 1 (the Reference FMU's): a rejection now and then where the step must
/// shrink, not more.
struct VanDerPol;

impl OdeSystem for VanDerPol {
    type Error = ModelError;
    fn rhs(&mut self, _t: f64, x: &[f64], dx: &mut [f64]) -> Result<(), ModelError> {
        dx[0] = x[1];
        dx[1] = (1.0 - x[0] * x[0]) * x[1] - x[0];
        Ok(())
    }
}

#[test]
fn van_der_pol_takes_few_rejections() {
    let loose = solve(Method::Dopri5, &mut VanDerPol, &[2.0, 0.0], 20.0, 1e-6);
    let tight = solve(Method::Dopri5, &mut VanDerPol, &[2.0, 0.0], 20.0, 1e-11);
    let s = loose.statistics();
    let error = (loose.state()[0] - tight.state()[0]).abs();
    eprintln!("van der Pol: {s:?}, error {error:.1e}");
    assert!(s.rejected * 3 < s.accepted, "{s:?}");
    assert!(error < 1e-4, "{error}");
}
