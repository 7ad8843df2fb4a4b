//! The speed-up of a 100-run sweep of crane + sensor (10 s each) on two threads against one.
//!
//! Run: `cargo bench -p spurio-batch --bench sweep_speedup` (after `scripts/build-fmus`).
//! Figures are medians of 5 sweeps.

use spurio_analysis::median;
use spurio_batch::sweep::{sweep, Metric, Variation};
use spurio_master::{System, SystemDescription};
use std::path::{Path, PathBuf};
use std::time::Instant;

fn main() {
    spurio_master::logging::install(false);
    let fmus = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../build/fmus");
    assert!(
        fmus.join("GantryCrane.fmu").is_file(),
        "run scripts/build-fmus first"
    );
    // 100 runs of crane + sensor, 10 s each, one thread vs two.
    let d: SystemDescription = toml::from_str(&format!(
        "stop_time = 10.0\nstep_size = 0.01\nalgorithm = \"jacobi\"\nconnections = [\"crane.x -> sensor.u[1]\", \"crane.theta -> sensor.u[2]\"]\nrecord = [\"crane.x\", \"sensor.y[1]\"]\n[[instance]]\nname = \"crane\"\nfmu = {:?}\nparameters = {{ U = 0.5 }}\n[[instance]]\nname = \"sensor\"\nfmu = {:?}\n",
        fmus.join("GantryCrane.fmu").display().to_string(),
        fmus.join("Sensor2.fmu").display().to_string()
    ))
    .expect("toml");
    let system = System::resolve(&d, Path::new(".")).expect("resolve");
    let variation = Variation::parse("sensor.seed=1..100").expect("vary");
    let metrics = [Metric::parse("e_res(sensor.y[1], crane.x)").expect("metric")];
    let time = |threads| {
        let seconds: Vec<f64> = (0..5)
            .map(|_| {
                let start = Instant::now();
                sweep(&system, &variation, &metrics, threads).expect("sweep");
                start.elapsed().as_secs_f64()
            })
            .collect();
        median(&seconds)
    };
    let one = time(1);
    let two = time(2);
    println!("Sweep of 100 runs (crane + sensor, 1000 steps each), median of 5:");
    println!("  1 thread  {:.3} s", one);
    println!("  2 threads {:.3} s  (speed-up {:.2}x)", two, one / two);
}
