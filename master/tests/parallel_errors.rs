//! Failures reported per instance: every instance that fails in one step is named, and an
//! instance's error quotes what that instance logged, even when a parallel run has an
//! instance of the same name that logged something else. Needs `scripts/build-fmus`.

mod common;

use common::resolve;
use spurio_master::NoRecording;
use spurio_master::System;
use spurio_master::{RunError, Simulation};
use std::sync::{Arc, Barrier};

fn system(text: &str) -> System {
    resolve(text).unwrap()
}

#[test]
fn every_instance_that_fails_in_a_step_is_named() {
    spurio_master::logging::install_unseen(false);
    let plant = |name: &str| {
        format!(
            "[[instance]]\nname = \"{name}\"\nfmu = \"LinearSystem.fmu\"\nparameters = {{ \"A[1,1]\" = 1e200, \"x0[1]\" = 1e200 }}\n"
        )
    };
    let s = system(&format!(
        "stop_time = 1.0\nstep_size = 0.1\n{}{}[[instance]]\nname = \"fine\"\nfmu = \"GantryCrane.fmu\"\n",
        plant("first"),
        plant("second")
    ));
    let mut sim = Simulation::new(&s).unwrap();
    let e = sim.run(&mut NoRecording, &Default::default()).unwrap_err();
    let RunError::Fmi { failures } = &e else {
        panic!("expected FMU failures, got {e}");
    };
    let names: Vec<&str> = failures.iter().map(|f| f.instance.as_str()).collect();
    assert_eq!(names, ["first", "second"]);
    for f in failures {
        assert_eq!(
            (f.call, f.status.as_str(), f.time),
            ("fmi2DoStep", "fmi2Error", 0.0)
        );
        assert!(f.log.contains("non-finite"), "{}", f.log);
    }
    let text = e.to_string();
    assert!(
        text.starts_with("2 instances failed: instance `first`")
            && text.contains("; instance `second`"),
        "{text}"
    );
}

/// Runs `parameters` for an instance called `crane`, returning the error text.
fn failing_crane(parameters: &str, start: &Barrier) -> String {
    let s = system(&format!(
        "stop_time = 1.0\nstep_size = 0.05\n[[instance]]\nname = \"crane\"\nfmu = \"GantryCrane.fmu\"\nparameters = {{ {parameters} }}\n"
    ));
    start.wait();
    match Simulation::new(&s) {
        Err(e) => e.to_string(),
        Ok(mut sim) => match sim.run(&mut NoRecording, &Default::default()) {
            Err(e) => e.to_string(),
            Ok(end) => panic!("{parameters} must fail ({end})"),
        },
    }
}

#[test]
fn parallel_runs_quote_their_own_instances_messages() {
    spurio_master::logging::install_unseen(false);
    for _ in 0..10 {
        let start = Arc::new(Barrier::new(2));
        let (a, b) = (start.clone(), start);
        let rail = std::thread::spawn(move || failing_crane("x0 = 0.9", &a));
        let length = std::thread::spawn(move || failing_crane("l = -1.0", &b));
        let (rail, length) = (rail.join().unwrap(), length.join().unwrap());
        assert!(rail.contains("`crane`") && rail.contains("`x0`"), "{rail}");
        assert!(!rail.contains("`l`"), "quotes the other run: {rail}");
        assert!(
            length.contains("`crane`") && length.contains("`l`"),
            "{length}"
        );
        assert!(!length.contains("`x0`"), "quotes the other run: {length}");
    }
}
