//! A recorded run is data: `spurio run` of the crane with its sensor and the DKF-rsKF
//! (examples/crane_adaptive/dkf_rskf.toml) records the sensor's outputs and the applied force;
//! that CSV, replayed as a data instance into the DkfRsKf estimator alone, gives the live
//! co-simulation's estimates bit for bit. In both runs the estimator's step from t_k takes
//! the values of t_k: Gauss–Seidel sets them after the sensor's and the controller's outputs
//! of t_k are read, and the record holds those values; the data instance reads the row of t_k
//! (hold, exact at the samples; the CSV's numbers are shortest round-trip text). Uses the
//! FMUs of `scripts/build-fmus`.

mod common;
#[path = "../../tests/common/packaged_fmus.rs"]
mod packaged_fmus;

use common::{ok, repo, require_fmus, s, spurio, temp};
use spurio_master::{InstanceDescription, ResultTable, SystemDescription, MAX_RESULTS_BYTES};
use std::path::{Path, PathBuf};

/// The estimator's outputs compared.
fn estimates() -> Vec<String> {
    let mut names: Vec<String> = (1..=4).map(|i| format!("est.x_hat[{i}]")).collect();
    for i in 1..=4 {
        names.extend((1..=4).map(|j| format!("est.A_hat[{i},{j}]")));
        names.push(format!("est.B_hat[{i},1]"));
    }
    names.push("est.excitation".into());
    for j in 1..=2 {
        names.push(format!("est.y_clean[{j}]"));
        names.push(format!("est.w[{j}]"));
        names.push(format!("est.y_hat[{j}]"));
    }
    names
}

/// The signals the estimator takes: (recorded column, estimator input).
const SIGNALS: [(&str, &str); 3] = [
    ("sensor.y[1]", "est.y[1]"),
    ("sensor.y[2]", "est.y[2]"),
    ("ctrl.u[1]", "est.u[1]"),
];

fn write(description: &SystemDescription, path: &Path) -> PathBuf {
    std::fs::write(path, toml::to_string(description).unwrap()).unwrap();
    path.to_path_buf()
}

/// Runs `examples/crane_adaptive/<system>` live and replayed; asserts that every estimate is
/// the same bit for bit and returns the estimates that move.
fn live_and_replayed(system: &str) -> Vec<String> {
    require_fmus(&["GantryCrane", "Sensor2", "DkfRsKf", "AdaptiveStateFeedback"]);
    let dir = temp(&format!("replay-{system}"));
    let example = repo().join("examples/crane_adaptive");
    let mut live = SystemDescription::read(&example.join(system)).unwrap();
    for instance in &mut live.instances {
        instance.fmu = example.join(&instance.fmu);
    }
    live.record = SIGNALS
        .iter()
        .map(|(column, _)| column.to_string())
        .chain(estimates())
        .collect();
    let live_csv = dir.join("live.csv");
    ok(spurio([
        "run",
        s(&write(&live, &dir.join("live.toml"))),
        "--out",
        s(&live_csv),
    ]));

    let est = live
        .instances
        .iter()
        .find(|i| i.name == "est")
        .unwrap()
        .clone();
    let replay = SystemDescription {
        name: "DKF-rsKF on the recorded sensor".into(),
        start_time: f64::NAN,
        stop_time: f64::NAN,
        instances: vec![
            InstanceDescription {
                data: Some(PathBuf::from("live.csv")),
                ..InstanceDescription::new("rig", PathBuf::new())
            },
            est,
        ],
        connections: SIGNALS
            .iter()
            .map(|(column, input)| format!("rig.{column} -> {input}"))
            .collect(),
        record: estimates(),
        ..live.clone()
    };
    let replay_toml = write(&replay, &dir.join("replay.toml"));
    let text = std::fs::read_to_string(&replay_toml).unwrap();
    assert!(text.contains("stop_time = \"data\""), "{text}");
    let replay_csv = dir.join("replay.csv");
    ok(spurio(["run", s(&replay_toml), "--out", s(&replay_csv)]));

    let live = ResultTable::read(&live_csv, MAX_RESULTS_BYTES).unwrap();
    let replayed = ResultTable::read(&replay_csv, MAX_RESULTS_BYTES).unwrap();
    assert_eq!(
        live.column("time").unwrap(),
        replayed.column("time").unwrap()
    );
    assert_eq!(live.rows.len(), 801);
    let mut moving = Vec::new();
    for name in estimates() {
        let (a, b) = (live.column(&name).unwrap(), replayed.column(&name).unwrap());
        let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(&a), bits(&b), "{name}");
        if a.iter().any(|&x| x != a[0]) {
            moving.push(name);
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
    moving
}

#[test]
fn a_recorded_run_replayed_into_the_estimator_gives_its_estimates_bit_for_bit() {
    // The paper's DKF-rsKF (Fig. 8): at rest under feedback its bounded parameter filter does
    // not adapt; the states and the cleaned outputs move.
    let moving = live_and_replayed("dkf_rskf.toml");
    for name in ["est.x_hat[1]", "est.x_hat[4]", "est.y_clean[2]", "est.w[1]"] {
        assert!(
            moving.iter().any(|m| m == name),
            "{name} never moves: {moving:?}"
        );
    }
    // With the ±0.05 N dither on the force the model adapts: Â and B̂ move too.
    let moving = live_and_replayed("dkf_rskf_dither.toml");
    for name in [
        "est.x_hat[4]",
        "est.A_hat[4,2]",
        "est.B_hat[4,1]",
        "est.excitation",
    ] {
        assert!(
            moving.iter().any(|m| m == name),
            "{name} never moves: {moving:?}"
        );
    }
}
