//! Cost of one `fmi2DoStep` (with the `fmi2SetReal` of the input and the `fmi2GetReal` of the
//! outputs around it) through the FMUs' C entry points, in-process.
//!
//! Run: `cargo bench -p fmu-gantry-crane --bench fmi2_step`. Prints the median over many batches,
//! so a noisy machine shifts it little.

use spurio_export::harness::Harness;
use spurio_export::{Config, FmuModel};
use GantryCrane::{vr, GantryCraneFmu};

/// `tolerance` 0: RK4 substeps of 1 ms (the default); > 0: the adaptive Dormand–Prince 5(4).
fn crane(step: f64, tolerance: f64, label: &str) {
    let mut h = Harness::<GantryCraneFmu>::new(&Config::new()).expect("instantiate");
    h.set_real(&[vr::TOLERANCE as u32], &[tolerance])
        .expect("tolerance");
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
    let integrator = if tolerance > 0.0 {
        format!("adaptive DP5(4) at tolerance {tolerance:e}")
    } else {
        format!(
            "{} RK4 substeps of 1 ms",
            spurio::ode::substep_count(step, 1e-3)
        )
    };
    println!("{label}: {}, {integrator}", timing.summary("step"));
}

fn main() {
    let _ = GantryCraneFmu::describe(&Config::new());
    for tolerance in [0.0, 1e-11] {
        crane(
            0.05,
            tolerance,
            "GantryCrane fmi2SetReal+fmi2DoStep(h = 50 ms)+fmi2GetReal",
        );
    }
    crane(
        0.001,
        0.0,
        "GantryCrane fmi2SetReal+fmi2DoStep(h = 1 ms)+fmi2GetReal",
    );
}
