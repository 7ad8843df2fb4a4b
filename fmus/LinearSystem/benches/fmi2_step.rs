//! Cost of one step of the default LinearSystem (n = 2, m = 1, p = 1, discrete, with process and
//! measurement noise, so 3 Gaussian draws per step): `fmi2SetReal` of `u`, `fmi2DoStep`,
//! `fmi2GetReal` of `y`, `y_clean`, `x[1]`, `x[2]`, through the FMU's C entry points in-process;
//! then the same in continuous time (exact discretisation, cached).
//!
//! Run: `cargo bench -p fmu-linear-system --bench fmi2_step`. Prints the median over many batches.

use spurio_export::harness::Harness;
use spurio_export::{Config, FmuModel};
use std::hint::black_box;
use LinearSystem::LinearSystemFmu;

fn system(continuous: bool, label: &str) {
    let config = Config::new();
    let info = LinearSystemFmu::describe(&config).expect("describe");
    let vr = |name: &str| info.index_of(name).expect(name) as u32;
    let mut h = Harness::<LinearSystemFmu>::new(&config).expect("instantiate");
    h.set_boolean(&[vr("continuous")], &[continuous])
        .expect("continuous");
    if continuous {
        // stable poles −0.5 (the default chain's 0.9 is for discrete time)
        h.set_real(&[vr("A[1,1]"), vr("A[2,2]")], &[-0.5, -0.5])
            .expect("A");
    }
    h.initialize(0.0).expect("initialize");
    let outputs = [vr("y[1]"), vr("y_clean[1]"), vr("x[1]"), vr("x[2]")];
    let input = [vr("u[1]")];
    let mut y = [0.0; 4];
    let (step, mut t, mut k) = (0.1, 0.0, 0u64);
    let timing = spurio_export::harness::time_per_call(1000, 200, 1000, || {
        let u = (k as f64 * 0.01).sin();
        h.exchange(&input, &[u], (t, step), &outputs, &mut y)
            .expect("step");
        black_box(&y);
        t += step;
        k += 1;
    });
    println!("{label}: {}", timing.summary("step"));
}

fn main() {
    system(
        false,
        "LinearSystem n = 2 discrete fmi2SetReal+fmi2DoStep+fmi2GetReal",
    );
    system(
        true,
        "LinearSystem n = 2 continuous fmi2SetReal+fmi2DoStep+fmi2GetReal",
    );
}
