//! The stepping algorithm is a trait: an algorithm the engine does not know plugs in with
//! `System::set_algorithm`, the plan compiler and the run loop call it in the order the trait
//! documents, and the built-in Gauss–Seidel and Jacobi differ where they should (the record
//! of a direct-feedthrough output at a communication point). These tests need the packaged
//! FMUs (`scripts/build-fmus`).

mod common;

use common::{crane_sensor, instance_tables, resolve};
use spurio_master::{
    Algorithm, Connection, Exchange, GaussSeidel, Jacobi, Propagation, PropagationStep,
    ResolvedInstance, RunError, StepOutcome, System, SystemError, TimeSeries,
};
use std::path::Path;
use std::sync::{Arc, Mutex};

/// Jacobi, noting every call the engine makes.
#[derive(Debug, Default)]
struct Traced {
    calls: Mutex<Vec<String>>,
}

impl Traced {
    fn note(&self, call: String) {
        self.calls.lock().unwrap().push(call);
    }
}

impl Propagation for Traced {
    fn propagation(
        &self,
        instances: &[ResolvedInstance],
        connections: &[Connection],
    ) -> Result<Vec<PropagationStep>, SystemError> {
        self.note("propagation".into());
        Jacobi.propagation(instances, connections)
    }

    fn refreshes_records(&self) -> bool {
        self.note("refreshes_records".into());
        Jacobi.refreshes_records()
    }
}

impl Algorithm for Traced {
    fn name(&self) -> &str {
        "traced jacobi"
    }

    fn initialize(&self, exchange: &mut Exchange, time: f64) -> Result<(), RunError> {
        self.note(format!("initialize {time}"));
        Jacobi.initialize(exchange, time)
    }

    fn communicate(&self, exchange: &mut Exchange, k: u64, time: f64) -> Result<(), RunError> {
        self.note(format!("communicate {k} {time}"));
        Jacobi.communicate(exchange, k, time)
    }

    fn step(&self, exchange: &mut Exchange, k: u64, time: f64) -> Result<StepOutcome, RunError> {
        self.note(format!("step {k} {time}"));
        Jacobi.step(exchange, k, time)
    }

    fn finish(&self, exchange: &mut Exchange, read_time: f64) -> Result<(), RunError> {
        self.note(format!("finish {read_time}"));
        Jacobi.finish(exchange, read_time)
    }
}

/// crane + sensor for `stop_time` s at 0.01 s, stepped by `algorithm` as the TOML names it.
fn crane_sensor_with(algorithm: &str, stop_time: f64) -> System {
    resolve(&format!(
        r#"
        stop_time = {stop_time:?}
        step_size = 0.01
        algorithm = "{algorithm}"
        connections = ["crane.x -> sensor.u[1]", "crane.theta -> sensor.u[2]"]
        record = ["crane.x", "sensor.y[1]", "sensor.y_clean[1]"]
        {}"#,
        instance_tables(&[
            ("crane", Path::new("GantryCrane.fmu"), "U = 0.5"),
            ("sensor", Path::new("Sensor2.fmu"), ""),
        ])
    ))
    .unwrap()
}

fn run(system: &System) -> TimeSeries {
    common::run(system, &Default::default()).0
}

#[test]
fn an_algorithm_of_the_callers_plugs_in_and_is_called_in_the_documented_order() {
    let mut system = crane_sensor(0.03, "U = 0.5");
    let traced = Arc::new(Traced::default());
    system.set_algorithm(traced.clone()).unwrap();
    assert_eq!(system.algorithm().name(), "traced jacobi");
    let series = run(&system);
    assert_eq!(
        *traced.calls.lock().unwrap(),
        [
            "propagation",
            "refreshes_records",
            "initialize 0",
            "communicate 0 0",
            "step 0 0",
            "communicate 1 0.01",
            "step 1 0.01",
            "communicate 2 0.02",
            "step 2 0.02",
            "finish 0.03",
        ]
    );
    // It steps as the Jacobi it delegates to, bit for bit.
    let jacobi = run(&crane_sensor_with("jacobi", 0.03));
    assert_eq!(series.time, [0.0, 0.01, 0.02, 0.03]);
    assert_eq!(series.time, jacobi.time);
    assert_eq!(series.rows, jacobi.rows);
}

#[test]
fn gauss_seidel_records_a_feedthrough_output_for_the_input_just_set_and_jacobi_a_step_late() {
    let gauss_seidel = run(&crane_sensor_with("gauss-seidel", 1.0));
    let jacobi = run(&crane_sensor_with("jacobi", 1.0));
    let column = |s: &TimeSeries, name: &str| s.column(name).unwrap();
    let x = column(&gauss_seidel, "crane.x");
    // The crane does not see the sensor: its position is the same under both.
    assert_eq!(x, column(&jacobi, "crane.x"));
    assert!(x[100] - x[0] > 1e-3, "the force moves the cart: {x:?}");
    // Gauss–Seidel: the clean measurement at t_k is the position at t_k. Jacobi: the one
    // read after the sensor's step, from the input set at t_(k-1).
    assert_eq!(column(&gauss_seidel, "sensor.y_clean[1]"), x);
    let late = column(&jacobi, "sensor.y_clean[1]");
    assert_eq!(late[0], x[0]);
    assert_eq!(late[1..], x[..x.len() - 1]);
}

#[test]
fn set_algorithm_compiles_the_plan_again_and_runs_as_the_toml_would() {
    let mut system = crane_sensor_with("gauss-seidel", 0.5);
    system.set_algorithm(Arc::new(Jacobi)).unwrap();
    assert_eq!(system.algorithm().name(), "jacobi");
    let as_toml = crane_sensor_with("jacobi", 0.5);
    assert_eq!(system.plan(), as_toml.plan());
    assert_eq!(run(&system).rows, run(&as_toml).rows);
    system.set_algorithm(Arc::new(GaussSeidel)).unwrap();
    assert_eq!(system.plan(), crane_sensor_with("gauss-seidel", 0.5).plan());
}
