//! Cost of one estimator sample through the FMUs' C entry points, in-process: `fmi2SetReal`
//! of the inputs, `fmi2DoStep`, `fmi2GetReal` of the outputs (docs/experiments.md §4: the papers' Matlab
//! DKF-rsKF took 12 ms per iteration; a numpy one of order 8 ≈ 0.14 ms; goal here ≤ 1 µs for
//! n = 8, m = p = 2 with all 92 outputs read, ≤ 40 ns for the scalar sKF and rsKF).
//!
//! Run: `cargo bench -p spurio-fmu-kalman --bench estimators`. Prints the median (and IQR) over
//! many batches, so a noisy machine shifts it little.

use spurio_export::harness::Harness;
use spurio_export::{Config, FmuModel};
use spurio_fmu_kalman::{dims_config, DkfRsKfFmu, KalmanFilterFmu, RobustKalmanFilterFmu};

/// Steps `M` on a deterministic test signal (sines plus a 5 % sprinkling of outliers) and
/// reports the median cost.
fn bench<M: FmuModel>(label: &str, config: &Config, inputs: &[&str], outputs: &[&str]) {
    if std::env::var("ESTIMATORS_ONLY").is_ok_and(|only| !label.starts_with(&only)) {
        return;
    }
    let info = M::describe(config).expect("describe");
    let vr = |name: &str| info.index_of(name).expect("variable") as u32;
    let input_vrs: Vec<u32> = inputs.iter().map(|n| vr(n)).collect();
    let output_vrs: Vec<u32> = outputs.iter().map(|n| vr(n)).collect();
    let mut h = Harness::<M>::new(config).expect("instantiate");
    h.initialize(0.0).expect("initialize");
    let input_values = |k: u64, values: &mut [f64]| {
        for (i, v) in values.iter_mut().enumerate() {
            let phase = k as f64 * 0.05 * (i + 1) as f64;
            let outlier = if (k * 7 + i as u64).is_multiple_of(20) {
                3.0
            } else {
                0.0
            };
            *v = phase.sin() + outlier;
        }
    };
    if let Some(steps) = profile_steps() {
        // Under callgrind: a fixed number of samples (the warm-up), one more timed.
        h.time_exchanges(
            (&input_vrs, &output_vrs),
            (0.0, 0.05),
            (steps as usize, 1, 1),
            input_values,
        )
        .expect("step");
        println!("{label}: {steps} samples");
        return;
    }
    let timing = h
        .time_exchanges(
            (&input_vrs, &output_vrs),
            (0.0, 0.05),
            (1000, 300, 100),
            input_values,
        )
        .expect("step");
    println!(
        "{label}: {}, {} inputs set, {} outputs read",
        timing.summary("sample"),
        input_vrs.len(),
        output_vrs.len()
    );
}

/// `ESTIMATORS_PROFILE_STEPS=N`: run N samples of each FMU untimed (for instruction counts
/// under `valgrind --tool=callgrind`: the difference between two N over the difference of
/// the N is the cost of one sample). `ESTIMATORS_ONLY=<label start>` runs only the FMUs whose
/// label starts so.
fn profile_steps() -> Option<u64> {
    std::env::var("ESTIMATORS_PROFILE_STEPS").ok()?.parse().ok()
}

fn main() {
    bench::<KalmanFilterFmu>(
        "KalmanFilter n = p = 1 fmi2SetReal+fmi2DoStep+fmi2GetReal",
        &dims_config(1, 0, 1),
        &["y[1]"],
        &["y_hat[1]"],
    );
    bench::<RobustKalmanFilterFmu>(
        "RobustKalmanFilter n = p = 1 fmi2SetReal+fmi2DoStep+fmi2GetReal",
        &dims_config(1, 0, 1),
        &["y[1]"],
        &["y_hat[1]", "w[1]"],
    );
    let mut outputs: Vec<String> = Vec::new();
    for i in 1..=8 {
        outputs.push(format!("x_hat[{i}]"));
        for j in 1..=8 {
            outputs.push(format!("A_hat[{i},{j}]"));
        }
        for j in 1..=2 {
            outputs.push(format!("B_hat[{i},{j}]"));
        }
    }
    outputs.extend(["y_hat[1]", "y_hat[2]", "w[1]", "w[2]"].map(String::from));
    let outputs: Vec<&str> = outputs.iter().map(String::as_str).collect();
    bench::<DkfRsKfFmu>(
        "DkfRsKf n = 8, m = 2, p = 2 (DkfRsKfGenerator) fmi2SetReal+fmi2DoStep+fmi2GetReal",
        &dims_config(8, 2, 2),
        &["u[1]", "u[2]", "y[1]", "y[2]"],
        &outputs,
    );
    bench::<DkfRsKfFmu>(
        "DkfRsKf n = 8, m = 2, p = 2, only y_hat read",
        &dims_config(8, 2, 2),
        &["u[1]", "u[2]", "y[1]", "y[2]"],
        &["y_hat[1]", "y_hat[2]"],
    );
}
