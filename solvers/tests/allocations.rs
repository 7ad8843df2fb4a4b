//! No allocation per step: once a solver is made (and has taken its first step), stepping
//! allocates nothing, with either method, finite-difference Jacobians included.

use spurio_counting_allocator::{count, CountingAllocator};
use spurio_solvers::{Method, OdeSystem, Settings, Solver};

#[global_allocator]
static ALLOCATOR: CountingAllocator = CountingAllocator;

#[derive(Debug)]
struct Never;

impl std::fmt::Display for Never {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("never")
    }
}

impl std::error::Error for Never {}

/// Van der Pol with μ = 5, three copies side by side (six states).
struct Oscillators;

impl OdeSystem for Oscillators {
    type Error = Never;
    fn rhs(&mut self, _t: f64, x: &[f64], dx: &mut [f64]) -> Result<(), Never> {
        for k in 0..3 {
            let (a, b) = (x[2 * k], x[2 * k + 1]);
            dx[2 * k] = b;
            dx[2 * k + 1] = 5.0 * (1.0 - a * a) * b - a;
        }
        Ok(())
    }
}

#[test]
fn stepping_allocates_nothing() {
    for method in [
        Method::Dopri5,
        Method::Rodas4,
        Method::Rodas3,
        Method::Shampine4,
    ] {
        let mut solver = Solver::new(method, 6, Settings::with_tolerance(1e-8));
        let x0 = [2.0, 0.0, 1.0, 0.5, -1.0, 0.0];
        solver.reset::<Never>(0.0, &x0, &[1.0; 6]).unwrap();
        solver.step(&mut Oscillators, 20.0).unwrap();
        let steps_before = solver.statistics().accepted;
        let mut out = [0.0; 6];
        let (_, counts) = count(|| {
            while solver.time() < 20.0 {
                solver.step(&mut Oscillators, 20.0).unwrap();
                solver.interpolate(0.5 * (solver.previous_time() + solver.time()), &mut out);
            }
        });
        let allocations = counts.allocations;
        let steps = solver.statistics().accepted - steps_before;
        eprintln!("{method}: {steps} steps, {allocations} allocations");
        assert!(steps > 100, "{steps}");
        assert_eq!(allocations, 0, "{method}");
    }
}
