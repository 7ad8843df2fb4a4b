//! FMI 3.0 Co-Simulation with Event Mode (FMI 3.0 §4.2): an FMU whose `<CoSimulation>`
//! declares `hasEventMode="true"` is instantiated with `eventModeUsed = true`; after
//! `fmi3ExitInitializationMode` and after every `fmi3DoStep` that returns
//! `eventHandlingNeeded = true` the master runs the event iteration (`fmi3EnterEventMode`,
//! `fmi3UpdateDiscreteStates` until `discreteStatesNeedUpdate` is false, `fmi3EnterStepMode`).
//! On the Reference FMUs with event mode the results equal, value for value, the reference
//! results each FMU carries (`extra/org.fmi-standard.fmi-ls-ref/<Model>_out.csv`), as fmpy's
//! `simulate_fmu(..., use_event_mode=True)` does (`tests/interop/test_reference_fmus3.py`).
//! `fixtures/event_mode.c` checks the call sequence against the state machine and misbehaves
//! on request: an iteration that never settles, `terminateSimulation` in the iteration.

mod common;

use common::{assert_names, compiled_fixture, instance_tables, reference, run};
use spurio_master::fmu::FmuFile;
use spurio_master::{RunEnd, RunOptions, Simulation, System, SystemDescription, TimeSeries};
use std::io::{Read, Write};
use std::path::{Path, PathBuf};

/// The system of `head` (times, record) and `instances` (see [`instance_tables`]).
fn system(head: &str, instances: &[(&str, &Path, &str)]) -> System {
    let toml_text = format!("{head}\n{}", instance_tables(instances));
    let description: SystemDescription = toml::from_str(&toml_text).unwrap();
    System::resolve(&description, Path::new(".")).unwrap()
}

fn column<'a>(series: &'a TimeSeries, name: &str) -> impl Iterator<Item = f64> + 'a {
    let j = series
        .names
        .iter()
        .position(|n| n == name)
        .unwrap_or_else(|| panic!("no column {name} in {:?}", series.names));
    series.rows.iter().map(move |r| r[j])
}

/// The reference results an FMU carries: (column names, rows), an array cell (`1 2 3`) as
/// its elements `y[1]`, `y[2]`, …; `true`/`false` as 1/0; other text columns left out.
fn reference_results(fmu: &Path, model: &str) -> (Vec<String>, Vec<Vec<f64>>) {
    let mut archive = zip::ZipArchive::new(std::fs::File::open(fmu).unwrap()).unwrap();
    let mut text = String::new();
    archive
        .by_name(&format!(
            "extra/org.fmi-standard.fmi-ls-ref/{model}_out.csv"
        ))
        .unwrap()
        .read_to_string(&mut text)
        .unwrap();
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let mut names = Vec::new();
    let mut rows = Vec::new();
    for (r, line) in lines.enumerate() {
        let mut row = Vec::new();
        for (cell, name) in line.split(',').zip(&header) {
            let parts: Vec<&str> = cell.split_whitespace().collect();
            let values: Option<Vec<f64>> = parts
                .iter()
                .map(|p| match *p {
                    "true" => Some(1.0),
                    "false" => Some(0.0),
                    p => p.parse().ok(),
                })
                .collect();
            let Some(values) = values.filter(|_| !cell.contains('!')) else {
                continue;
            };
            for (k, v) in values.iter().enumerate() {
                if r == 0 {
                    names.push(if parts.len() > 1 {
                        format!("{name}[{}]", k + 1)
                    } else {
                        name.to_string()
                    });
                }
                row.push(*v);
            }
        }
        rows.push(row);
    }
    (names, rows)
}

/// Runs the Reference FMU `model` (FMI 3.0) from 0 to `stop` at `step` and returns the
/// largest difference from its reference results over every value both have, and the run's
/// end.
fn largest_difference_from_reference(model: &str, stop: f64, step: f64) -> (f64, RunEnd) {
    let fmu = reference("fmi3", model);
    assert!(FmuFile::open(&fmu).unwrap().event_mode, "{model}");
    let (names, expected) = reference_results(&fmu, model);
    let s = system(
        &format!("stop_time = {stop:?}\nstep_size = {step:?}"),
        &[("m", &fmu, "")],
    );
    let (series, end) = run(&s, &RunOptions::default());
    assert_eq!(series.rows.len(), expected.len(), "{model}: points");
    let mut largest = 0.0_f64;
    let mut compared = 0;
    for (j, name) in names.iter().enumerate().skip(1) {
        if !series.names.contains(&format!("m.{name}")) {
            continue;
        }
        for (got, want) in column(&series, &format!("m.{name}")).zip(&expected) {
            largest = largest.max((got - want[j]).abs());
            compared += 1;
        }
    }
    for (got, want) in series.time.iter().zip(&expected) {
        largest = largest.max((got - want[0]).abs());
    }
    assert!(compared >= expected.len(), "{model}: compared {compared}");
    (largest, end)
}

#[test]
fn reference_fmus_with_event_mode_reproduce_their_reference_results() {
    // BouncingBall: h, v at 0.01 s to 3 s, its bounces handled in event mode.
    let (d, end) = largest_difference_from_reference("BouncingBall", 3.0, 0.01);
    assert_eq!(d, 0.0, "BouncingBall");
    assert_eq!(end, RunEnd::StopTime { time: 3.0 });
    // StateSpace: y = C x + D u at 1 s to 10 s.
    let (d, _) = largest_difference_from_reference("StateSpace", 10.0, 1.0);
    assert!(d < 1e-12, "StateSpace: {d}");
    // Feedthrough: every numeric output at 0.1 s to 2 s.
    let (d, _) = largest_difference_from_reference("Feedthrough", 2.0, 0.1);
    assert_eq!(d, 0.0, "Feedthrough");
    // Stair: the counter's time events handled in event mode, terminateSimulation at t = 9
    // from the event iteration ends the run normally there.
    let (d, end) = largest_difference_from_reference("Stair", 10.0, 0.2);
    assert_eq!(d, 0.0, "Stair");
    let RunEnd::Terminated { instance, time, .. } = &end else {
        panic!("{end:?}")
    };
    assert_eq!(instance, "m");
    assert!((time - 9.0).abs() < 1e-12, "{time}");
    assert_names(
        &end.to_string(),
        &[
            "asked to end the simulation at t = 9",
            "terminateSimulation = true",
        ],
    );
}

#[test]
fn bouncing_ball_bounces_where_the_closed_form_says() {
    // Free fall from h = 1 m at g = 9.81 m/s²: the first impact at t = √(2/9.81) = 0.4515 s
    // (the FMU's Euler steps of 1 ms put it within a step of 0.01 s of that), after which v
    // is e = 0.7 times the impact speed √(2·9.81) = 4.429 m/s, upwards.
    let fmu = reference("fmi3", "BouncingBall");
    let s = system("stop_time = 1.0\nstep_size = 0.01", &[("b", &fmu, "")]);
    let (series, _) = run(&s, &RunOptions::default());
    let v: Vec<f64> = column(&series, "b.v").collect();
    let k = v.iter().position(|&v| v > 0.0).unwrap();
    let bounce = series.time[k];
    assert!((bounce - (2.0_f64 / 9.81).sqrt()).abs() < 0.01, "{bounce}");
    let rebound = v[k] + 9.81 * (series.time[k] - (2.0_f64 / 9.81).sqrt());
    assert!(
        (rebound - 0.7 * (2.0_f64 * 9.81).sqrt()).abs() < 0.05,
        "{rebound}"
    );
}

#[test]
fn an_fmu_that_refuses_event_mode_runs_without_it() {
    // The Reference FMU Roberts declares hasEventMode="true" but refuses eventModeUsed =
    // true ("Event Mode is not supported"): it is instantiated again without, as before.
    let fmu = reference("fmi3", "Roberts");
    assert!(FmuFile::open(&fmu).unwrap().event_mode);
    let s = system(
        "start_time = 0.0\nstop_time = 0.1\nstep_size = 0.01",
        &[("r", &fmu, "")],
    );
    let (series, end) = run(&s, &RunOptions::default());
    assert_eq!(end, RunEnd::StopTime { time: 0.1 });
    // y1 + y2 + y3 = 1 (the reactions conserve mass).
    let total: Vec<f64> = ["r.y1", "r.y2", "r.y3"]
        .iter()
        .map(|n| column(&series, n).last().unwrap())
        .collect();
    assert!((total.iter().sum::<f64>() - 1.0).abs() < 1e-9, "{total:?}");
    assert!(
        !FmuFile::open(&reference("fmi3", "Dahlquist"))
            .unwrap()
            .event_mode
    );
}

/// `<dir>/EventMode.fmu`: the library of `fixtures/event_mode.c` (compiled with `cc`) with
/// its model description, `hasEventMode` as `has_event_mode` says.
fn event_mode_fmu(dir: &Path, has_event_mode: bool) -> PathBuf {
    let library = compiled_fixture("event_mode.c", &[], dir);
    let description = format!(
        r#"<?xml version="1.0" encoding="UTF-8"?>
<fmiModelDescription fmiVersion="3.0" modelName="EventMode" instantiationToken="{{event-mode}}">
  <CoSimulation modelIdentifier="EventMode" hasEventMode="{has_event_mode}"/>
  <ModelVariables>
    <Float64 name="time" valueReference="0" causality="independent" variability="continuous"/>
    <Float64 name="mode" valueReference="1" causality="parameter" variability="fixed" start="0"/>
    <Float64 name="period" valueReference="2" causality="parameter" variability="fixed" start="0.5"/>
    <Float64 name="count" valueReference="3" causality="output" variability="discrete"/>
    <Float64 name="updates" valueReference="4" causality="output" variability="discrete"/>
  </ModelVariables>
  <ModelStructure>
    <Output valueReference="3"/>
    <Output valueReference="4"/>
  </ModelStructure>
</fmiModelDescription>
"#
    );
    let path = dir.join("EventMode.fmu");
    let mut out = zip::ZipWriter::new(std::fs::File::create(&path).unwrap());
    let options = zip::write::SimpleFileOptions::default();
    out.start_file("modelDescription.xml", options).unwrap();
    out.write_all(description.as_bytes()).unwrap();
    out.start_file("binaries/x86_64-linux/EventMode.so", options)
        .unwrap();
    out.write_all(&library).unwrap();
    out.finish().unwrap();
    path
}

/// The fixture FMU as instance `e` with `parameters`, 0.1 s steps to `stop`.
fn event_system(dir: &Path, has_event_mode: bool, stop: f64, parameters: &str) -> System {
    let fmu = event_mode_fmu(dir, has_event_mode);
    system(
        &format!("stop_time = {stop:?}\nstep_size = 0.1"),
        &[("e", &fmu, parameters)],
    )
}

/// Asserts that a run of the fixture FMU (see [`event_system`]) stops with an error naming
/// every one of `parts`.
fn assert_run_fails(has_event_mode: bool, stop: f64, parameters: &str, parts: &[&str]) {
    let dir = tempfile::tempdir().unwrap();
    let s = event_system(dir.path(), has_event_mode, stop, parameters);
    let error = match Simulation::new(&s) {
        Ok(mut sim) => sim
            .run(&mut TimeSeries::default(), &RunOptions::default())
            .unwrap_err()
            .to_string(),
        Err(e) => e.to_string(),
    };
    assert_names(&error, parts);
}

#[test]
fn events_are_handled_in_event_mode_and_the_outputs_read_after_the_iteration() {
    let dir = tempfile::tempdir().unwrap();
    let s = event_system(dir.path(), true, 2.0, "");
    let (series, end) = run(&s, &RunOptions::default());
    assert_eq!(end, RunEnd::StopTime { time: 2.0 });
    // An event at every multiple of 0.5 s, counted at the communication point where the step
    // that reaches it ends: count(t) = ⌊t / 0.5⌋.
    for (t, count) in series.time.iter().zip(column(&series, "e.count")) {
        assert_eq!(count, (t / 0.5 + 1e-9).floor(), "t = {t}");
    }
    // The initial iteration's one update, then two per event (a super-dense step each).
    let updates: Vec<f64> = column(&series, "e.updates").collect();
    assert_eq!(updates[0], 1.0);
    assert_eq!(updates.last(), Some(&(1.0 + 2.0 * 4.0)));
}

#[test]
fn an_event_iteration_that_never_settles_is_an_error_naming_the_fmu_call_and_time() {
    assert_run_fails(
        true,
        2.0,
        "mode = 1",
        &[
            "instance `e`",
            "EventMode.fmu",
            "fmi3UpdateDiscreteStates",
            "discreteStatesNeedUpdate = true 1000 times in a row",
            "did not settle",
            "t = 0.5",
        ],
    );
}

#[test]
fn an_initial_event_iteration_that_never_settles_is_an_error() {
    assert_run_fails(
        true,
        1.0,
        "mode = 3",
        &[
            "instance `e`",
            "fmi3ExitInitializationMode",
            "fmi3UpdateDiscreteStates, in the event iteration that follows it",
            "did not settle",
            "t = 0",
        ],
    );
}

#[test]
fn terminate_simulation_in_the_event_iteration_ends_the_run_normally() {
    let dir = tempfile::tempdir().unwrap();
    let s = event_system(dir.path(), true, 3.0, "mode = 2");
    let (series, end) = run(&s, &RunOptions::default());
    // The third event, at t = 1.5, asks to end the simulation: recorded there, and said.
    let RunEnd::Terminated { instance, time, .. } = &end else {
        panic!("{end:?}")
    };
    assert_eq!(instance, "e");
    assert!((time - 1.5).abs() < 1e-12, "{time}");
    assert_eq!(series.time.last(), Some(time));
    assert_eq!(column(&series, "e.count").last(), Some(3.0));
    assert_names(&end.to_string(), &["terminateSimulation = true"]);
}

#[test]
fn event_handling_needed_without_event_mode_is_an_error() {
    // hasEventMode="false": instantiated with eventModeUsed = false, the fixture still asks
    // for event handling at t = 0.5, which the master cannot give.
    assert_run_fails(
        false,
        1.0,
        "",
        &[
            "instance `e`",
            "fmi3DoStep",
            "eventHandlingNeeded = true",
            "eventModeUsed = false",
            "t = 0.4",
        ],
    );
}

#[test]
fn event_mode_instances_in_a_system_pass_their_values_after_each_event_iteration() {
    // Stair (event mode) counts the seconds; its counter drives an FMI 2.0 Feedthrough's
    // Int32 input and BouncingBall's height an FMI 3.0 Feedthrough's (event mode) Float64
    // input: Gauss–Seidel passes each value read after the event iteration on at the same
    // communication point.
    let s = system(
        r#"stop_time = 3.0
step_size = 0.1
connections = ["stair.counter -> f2.Int32_input",
               "ball.h -> f3.Float64_continuous_input"]
record = ["stair.counter", "f2.Int32_output", "ball.h", "f3.Float64_continuous_output"]"#,
        &[
            ("stair", &reference("fmi3", "Stair"), ""),
            ("f2", &reference("fmi2", "Feedthrough"), ""),
            ("ball", &reference("fmi3", "BouncingBall"), ""),
            ("f3", &reference("fmi3", "Feedthrough"), ""),
        ],
    );
    let (series, end) = run(&s, &RunOptions::default());
    assert_eq!(end, RunEnd::StopTime { time: 3.0 });
    assert_eq!(series.rows.len(), 31);
    let passed: Vec<f64> = column(&series, "f2.Int32_output").collect();
    for ((t, counter), out) in series
        .time
        .iter()
        .zip(column(&series, "stair.counter"))
        .zip(&passed)
    {
        assert_eq!(counter, (t + 1e-9).floor() + 1.0, "t = {t}");
        assert_eq!(*out, counter, "t = {t}");
    }
    let heights: Vec<f64> = column(&series, "ball.h").collect();
    assert_eq!(
        heights,
        column(&series, "f3.Float64_continuous_output").collect::<Vec<_>>()
    );
    // The ball bounces: falling until the impact near 0.45 s, rising after it.
    assert!(
        heights[4] < heights[3] && heights[6] > heights[5],
        "{heights:?}"
    );
}
