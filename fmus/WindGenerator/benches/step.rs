//! Cost of one 0.1 s WindGenerator step through the FMU's entry points, in-process
//! (`fmi2SetReal` of both references, `fmi2DoStep`, `fmi2GetReal` of speed and voltage), for
//! the adaptive RODAS3 integrator (the default) and the fixed-step RK4 (`fixed_step_rk4`,
//! h_max = 10⁻⁴ s, the integrator before), interleaved batch by batch so a noisy machine
//! shifts both alike. The references follow the identification experiment's kind of signal:
//! steps between levels held 2–4 s (the generator is never long at rest), so most steps
//! carry a transient.
//!
//! Run: `cargo bench -p fmu-wind-generator --bench step`. Prints medians (and IQR) and their
//! ratio.

use spurio_export::harness::{time_per_call, Harness, Timing};
use spurio_export::Config;
use std::hint::black_box;
use WindGenerator::{vr, WindGeneratorFmu};

/// An initialised instance (from the 8 V / 7 V steady state) with the given integrator.
fn instance(fixed_step_rk4: bool) -> Harness<WindGeneratorFmu> {
    let mut h = Harness::<WindGeneratorFmu>::new(&Config::new()).expect("instantiate");
    h.set_boolean(&[vr::FIXED_STEP_RK4 as u32], &[fixed_step_rk4])
        .expect("integrator");
    h.set_boolean(&[vr::START_AT_OPERATING_POINT as u32], &[true])
        .expect("start");
    h.set_real(&[vr::U_DRIVE_0 as u32, vr::U_FIELD_0 as u32], &[8.0, 7.0])
        .expect("start references");
    h.initialize(0.0).expect("initialize");
    h
}

/// The references at step `k`: levels in [6, 10] V (drive) and [5, 9] V (field), each held
/// for 20–40 steps of 0.1 s.
fn references(k: u64) -> [f64; 2] {
    let segment = k / 30 + (k / 70);
    [
        6.0 + (segment * 7 % 5) as f64,
        5.0 + (segment * 3 % 5) as f64,
    ]
}

/// One step closure over an instance: set, step, get.
fn stepper(fixed_step_rk4: bool) -> impl FnMut() {
    let mut h = instance(fixed_step_rk4);
    let inputs = [vr::U_DRIVE as u32, vr::U_FIELD as u32];
    let outputs = [vr::SPEED as u32, vr::VOLTAGE as u32];
    let mut out = [0.0; 2];
    let step = 0.1;
    let mut k = 0u64;
    move || {
        let t = k as f64 * step;
        h.exchange(&inputs, &references(k), (t, step), &outputs, &mut out)
            .expect("step");
        black_box(&out);
        k += 1;
    }
}

fn main() {
    let mut adaptive = stepper(false);
    let mut rk4 = stepper(true);
    let rounds = 15;
    let (mut fast, mut slow) = (Vec::new(), Vec::new());
    for _ in 0..rounds {
        fast.push(time_per_call(5, 3, 40, &mut adaptive).median);
        slow.push(time_per_call(5, 3, 40, &mut rk4).median);
    }
    let median = |v: &mut Vec<f64>| {
        v.sort_by(|a, b| a.total_cmp(b));
        Timing {
            median: v[v.len() / 2],
            q1: v[v.len() / 4],
            q3: v[3 * v.len() / 4],
        }
    };
    let (fast, slow) = (median(&mut fast), median(&mut slow));
    println!(
        "WindGenerator, 0.1 s step, RODAS3 rtol 1e-7 (default): {}",
        fast.summary("step")
    );
    println!(
        "WindGenerator, 0.1 s step, RK4 h_max 1e-4 s (fixed_step_rk4): {}",
        slow.summary("step")
    );
    println!("speed-up: {:.1}x", slow.median / fast.median);
}
