//! The master's cost per instance per step, beside the bare FMU calls and fmpy's loop (the
//! speed-up of a sweep on two threads is `spurio-batch`'s bench `sweep_speedup`).
//!
//! Run: `cargo bench -p spurio-master --bench master_overhead` (after `scripts/build-fmus`).
//! Everything is measured in this one run; figures are medians of repeated batches.

use fmi::fmi2::instance::{CoSimulation, Common};
use spurio_master::fmu::FmuFile;
use spurio_master::{CsvWriter, NoRecording, Observer, RunOptions, Simulation};
use spurio_master::{System, SystemDescription};
use std::path::{Path, PathBuf};
use std::time::Instant;

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(|a, b| a.total_cmp(b));
    v[v.len() / 2]
}

fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// Bare rust-fmi calls: setReal(u), doStep, getReal(y) on one LinearSystem instance.
fn bare_loop(fmu: &Path, steps: usize, batches: usize) -> f64 {
    let file = FmuFile::open(fmu).expect("open");
    let u = file.variable("u[1]").expect("u").head.value_reference;
    let y = file.variable("y[1]").expect("y").head.value_reference;
    let mut instance = file.instantiate("bare", false).expect("instantiate");
    let inst = instance.fmi2_mut().expect("an FMI 2.0 FMU");
    Common::setup_experiment(inst, None, 0.0, None).expect("setup");
    Common::enter_initialization_mode(inst).expect("enter");
    Common::exit_initialization_mode(inst).expect("exit");
    let mut out = [0.0];
    let mut t = 0.0;
    let samples = (0..batches)
        .map(|_| {
            let start = Instant::now();
            for _ in 0..steps {
                Common::set_real(inst, &[u], &[0.5]).expect("set");
                inst.do_step(t, 0.01, true).expect("step");
                Common::get_real(inst, &[y], &mut out).expect("get");
                t += 0.01;
            }
            start.elapsed().as_nanos() as f64 / steps as f64
        })
        .collect();
    median(samples)
}

/// A chain of `k` LinearSystem instances (y[1] → next u[1]), Jacobi.
fn chain(fmu: &Path, k: usize, steps: usize) -> System {
    let mut text = format!(
        "stop_time = {}\nstep_size = 0.01\nalgorithm = \"jacobi\"\n",
        steps as f64 * 0.01
    );
    let connections: Vec<String> = (1..k)
        .map(|i| format!("\"s{}.y[1] -> s{i}.u[1]\"", i - 1))
        .collect();
    text += &format!("connections = [{}]\n", connections.join(", "));
    for i in 0..k {
        text += &format!(
            "[[instance]]\nname = \"s{i}\"\nfmu = {:?}\n",
            fmu.display().to_string()
        );
    }
    let d: SystemDescription = toml::from_str(&text).expect("toml");
    System::resolve(&d, Path::new(".")).expect("resolve")
}

fn master_loop(system: &System, k: usize, csv: bool, batches: usize) -> f64 {
    let samples = (0..batches)
        .map(|_| {
            let mut sim = Simulation::new(system).expect("simulation");
            let steps = sim.step_count() as f64;
            let mut none = NoRecording;
            let path = std::env::temp_dir().join("spurio-bench.csv");
            let mut file = CsvWriter::create(&path).expect("csv");
            let observer: &mut dyn Observer = if csv { &mut file } else { &mut none };
            let start = Instant::now();
            sim.run(observer, &RunOptions::default()).expect("run");
            start.elapsed().as_nanos() as f64 / (steps * k as f64)
        })
        .collect();
    median(samples)
}

fn main() {
    spurio_master::logging::install(false);
    let fmus = repo().join("build/fmus");
    let linear = fmus.join("LinearSystem.fmu");
    assert!(linear.is_file(), "run scripts/build-fmus first");
    let (steps, batches, k) = (20_000, 15, 8);
    let bare = bare_loop(&linear, steps, batches);
    let system = chain(&linear, k, steps);
    let master = master_loop(&system, k, false, batches);
    let master_csv = master_loop(&system, k, true, batches);
    println!("LinearSystem (n=2, m=1, p=1), set u + fmi2DoStep + get y, median per instance-step:");
    println!("  bare rust-fmi calls          {bare:8.1} ns");
    println!(
        "  master, {k} instances, no CSV {master:8.1} ns  (overhead {:.1} ns)",
        master - bare
    );
    println!(
        "  master, {k} instances, CSV    {master_csv:8.1} ns  (overhead {:.1} ns)",
        master_csv - bare
    );
    let python = repo().join(".venv/bin/python");
    if python.is_file() {
        let out = std::process::Command::new(&python)
            .arg(repo().join("tests/bench/fmpy_loop.py"))
            .arg(&linear)
            .args(["20000", "7"])
            .output()
            .expect("python");
        let text = String::from_utf8_lossy(&out.stdout);
        match text.trim().parse::<f64>() {
            Ok(ns) => println!(
                "  fmpy FMU2Slave loop          {ns:8.1} ns  ({:.0}x the master)",
                ns / master
            ),
            Err(_) => println!(
                "  fmpy loop failed: {}",
                String::from_utf8_lossy(&out.stderr)
            ),
        }
    }
}
