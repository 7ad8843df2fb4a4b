//! Cost of one `fmi2DoStep` (with the `fmi2SetReal` of the input and the `fmi2GetReal` of the
//! outputs around it) through the FMUs' C entry points, in-process.
//!
//! Run: `cargo bench -p fmu-gantry-crane --bench fmi2_step`. Prints the median over many batches,
//! so a noisy machine shifts it little.

use spurio_export::harness::Harness;
use spurio_export::{Config, FmuModel};
use GantryCrane::{vr, GantryCraneFmu};

fn crane(step: f64, label: &str) {
    let mut h = Harness::<GantryCraneFmu>::new(&Config::new()).expect("instantiate");
    h.initialize(0.0).expect("initialize");
    let outputs = [
        vr::X as u32,
        vr::THETA as u32,
        vr::V as u32,
        vr::OMEGA as u32,
    ];
    // A gentle input that keeps the cart away from the rail stops.
    let timing = h
        .time_exchanges(
            (&[vr::U as u32], &outputs),
            (0.0, step),
            (50, 200, 50),
            |k, u| u[0] = 0.5 * ((k as f64) * 0.01).sin(),
        )
        .expect("step");
    println!(
        "{label}: {}, {} RK4 substeps of {} s",
        timing.summary("step"),
        spurio::ode::substep_count(step, 1e-3),
        1e-3
    );
}

fn main() {
    let _ = GantryCraneFmu::describe(&Config::new());
    crane(
        0.05,
        "GantryCrane fmi2SetReal+fmi2DoStep(h = 50 ms)+fmi2GetReal",
    );
    crane(
        0.001,
        "GantryCrane fmi2SetReal+fmi2DoStep(h = 1 ms)+fmi2GetReal",
    );
}
