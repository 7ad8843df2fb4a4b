//! The stepping loop allocates nothing: a run of twice as many steps makes exactly as many
//! heap allocations (instantiation, initialisation and the run's set-up only), for FMI 2.0
//! and FMI 3.0 instances moving every numeric type through connections (Real/Float64,
//! Float32, the integer types, Boolean), with recording off and with a CSV written every
//! step. The Reference FMUs are C: their own memory is not counted, only the master's (and
//! rust-fmi's).

mod common;

use common::{instance_tables, reference};
use spurio_counting_allocator::{count, CountingAllocator};
use spurio_master::{CsvWriter, NoRecording, Observer};
use spurio_master::{RunOptions, Simulation};
use spurio_master::{System, SystemDescription};
use std::path::Path;

#[global_allocator]
static ALLOCATOR: CountingAllocator = CountingAllocator;

/// Two Feedthrough instances of FMI `version`, every numeric output of the first driving
/// the same input of the second, to `stop_time` in steps of 0.01.
fn feedthrough_pair(version: &str, types: &[&str], stop_time: f64) -> System {
    let fmu = reference(version, "Feedthrough");
    let connections: Vec<String> = types
        .iter()
        .map(|t| format!("\"a.{t}_output -> b.{t}_input\""))
        .collect();
    let text = format!(
        "stop_time = {stop_time:?}\nstep_size = 0.01\nconnections = [{}]\n{}",
        connections.join(", "),
        instance_tables(&[("a", &fmu, ""), ("b", &fmu, "")])
    );
    let description: SystemDescription = toml::from_str(&text).unwrap();
    System::resolve(&description, Path::new(".")).unwrap()
}

/// Allocations made by one run of `system` (set-up included), recording as `csv` says.
fn run_allocations(system: &System, csv: bool) -> u64 {
    let mut sim = Simulation::new(system).unwrap();
    let mut none = NoRecording;
    let mut file = CsvWriter::new(std::io::sink());
    let observer: &mut dyn Observer = if csv { &mut file } else { &mut none };
    let (ran, counts) = count(|| sim.run(observer, &RunOptions::default()));
    ran.unwrap();
    counts.allocations
}

#[test]
fn a_step_allocates_nothing() {
    let fmi2: Vec<&str> = "Float64_continuous Float64_discrete Int32 Boolean"
        .split_whitespace()
        .collect();
    // Every numeric type of FMI 3.0 (Enumerations are not connected).
    let fmi3: Vec<&str> =
        "Float64_continuous Float32_continuous Int8 UInt8 Int16 UInt16 Int32 UInt32 Int64 UInt64 Boolean"
            .split_whitespace()
            .collect();
    for (version, types) in [("fmi2", &fmi2[..]), ("fmi3", &fmi3[..])] {
        for csv in [false, true] {
            let short = run_allocations(&feedthrough_pair(version, types, 1.0), csv);
            let long = run_allocations(&feedthrough_pair(version, types, 3.0), csv);
            assert_eq!(
                long,
                short,
                "{version}, csv = {csv}: 200 more steps made {} more allocations",
                long as i64 - short as i64
            );
        }
    }
}

/// A data instance (`linear`, a missing sample every 7th row, sampled every 0.003 s so that
/// its cursor passes several samples per step) driving a Feedthrough's Real input with a
/// column and its Boolean input with the column's validity flag, to `stop_time` in steps of
/// 0.01.
fn data_into_feedthrough(csv: &Path, stop_time: f64) -> System {
    let fmu = reference("fmi2", "Feedthrough");
    let text = format!(
        "stop_time = {stop_time:?}\nstep_size = 0.01\n\
         connections = [\"rig.u.held -> b.Float64_continuous_input\", \"rig.u.valid -> b.Boolean_input\"]\n\
         record = [\"rig.u\", \"b.Float64_continuous_output\"]\n\
         [[instance]]\nname = \"rig\"\ndata = {:?}\ninterpolation = \"linear\"\n{}",
        csv.display().to_string(),
        instance_tables(&[("b", &fmu, "")])
    );
    let description: SystemDescription = toml::from_str(&text).unwrap();
    System::resolve(&description, Path::new(".")).unwrap()
}

#[test]
fn a_data_instance_reads_without_allocating() {
    let dir = std::env::temp_dir().join(format!("spurio-data-alloc-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let csv = dir.join("rig.csv");
    let rows: String = (0..1001)
        .map(|i| {
            let t = 0.003 * f64::from(i);
            if i % 7 == 3 {
                format!("{t},\n")
            } else {
                format!("{t},{}\n", (3.0 * t).sin())
            }
        })
        .collect();
    std::fs::write(&csv, format!("time,u\n{rows}")).unwrap();
    for recording in [false, true] {
        let short = run_allocations(&data_into_feedthrough(&csv, 1.0), recording);
        let long = run_allocations(&data_into_feedthrough(&csv, 3.0), recording);
        assert_eq!(
            long,
            short,
            "csv = {recording}: 200 more steps made {} more allocations",
            long as i64 - short as i64
        );
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// Model Exchange instances in a system, to `stop_time` in steps of 0.01: BouncingBall of
/// FMI `version` alone (state events inside the steps) and two continuous LinearSystems in a
/// chain, integrated as one ODE (inputs propagated at every right-hand side).
fn model_exchange_system(version: &str, stop_time: f64) -> System {
    let ball = reference(version, "BouncingBall");
    let plant = common::fmus().join("LinearSystem.fmu");
    let text = format!(
        "stop_time = {stop_time:?}\nstep_size = 0.01\nconnections = [\"a.y[1] -> b.u[1]\"]\n\
         [[instance]]\nname = \"ball\"\nfmu = {:?}\ninterface = \"me\"\n\
         [[instance]]\nname = \"a\"\nfmu = {:?}\ninterface = \"me\"\nparameters = {{ continuous = true, \"u[1]\" = 1.0 }}\n\
         [[instance]]\nname = \"b\"\nfmu = {:?}\ninterface = \"me\"\nsolver = \"dopri5\"\nparameters = {{ continuous = true }}\n",
        ball.display().to_string(),
        plant.display().to_string(),
        plant.display().to_string(),
    );
    let description: SystemDescription = toml::from_str(&text).unwrap();
    System::resolve(&description, Path::new(".")).unwrap()
}

#[test]
fn a_model_exchange_advance_allocates_nothing() {
    for version in ["fmi2", "fmi3"] {
        for csv in [false, true] {
            let short = run_allocations(&model_exchange_system(version, 1.0), csv);
            let long = run_allocations(&model_exchange_system(version, 3.0), csv);
            assert_eq!(
                long,
                short,
                "{version}, csv = {csv}: 200 more steps made {} more allocations",
                long as i64 - short as i64
            );
        }
    }
}
