//! A data instance: a table of recorded signals (CSV) as a member of a system. Its columns read
//! exactly at and between the samples (hold) or on the line between them (linear), a missing
//! sample reaches the system as NaN with a validity flag, a system takes its start and stop
//! time from the data, and every bad input is refused at load naming the file, the line and
//! the column. The KalmanFilter cases need the packaged FMUs (`scripts/build-fmus`).

mod common;

use common::{fmus, run};
use spurio_master::fmu::{LoadLimits, LoadOptions};
use spurio_master::ssp::SspVersion;
use spurio_master::{RunOptions, System};
use std::path::{Path, PathBuf};

/// A fresh folder with `rig.csv` = `csv` and `system.toml` = `system`.
fn case(name: &str, csv: &str, system: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("spurio-data-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(dir.join("rig.csv"), csv).unwrap();
    let path = dir.join("system.toml");
    std::fs::write(&path, system).unwrap();
    path
}

fn load(name: &str, csv: &str, system: &str) -> System {
    System::from_file(&case(name, csv, system)).unwrap()
}

fn refused(name: &str, csv: &str, system: &str) -> String {
    let path = case(name, csv, system);
    let e = System::from_file(&path).unwrap_err().to_string();
    let file = path.with_file_name("rig.csv");
    assert!(
        e.contains(&file.display().to_string()),
        "`{e}` does not name {}",
        file.display()
    );
    e
}

const SAMPLES: &str = "\"time\",\"u [N]\",\"w\"\n0,0.1,1\n0.3,0.7,2\n0.6,-2.5,\n0.9,4,3\n";

fn rig(interpolation: &str, extra: &str) -> String {
    format!(
        "step_size = 0.1\n{extra}\n[[instance]]\nname = \"rig\"\ndata = \"rig.csv\"\n\
         interpolation = \"{interpolation}\"\n"
    )
}

fn column(system: &System, name: &str) -> (Vec<f64>, Vec<f64>) {
    let (series, _) = run(system, &RunOptions::default());
    (series.time.clone(), series.column(name).unwrap())
}

#[test]
fn hold_reads_the_sample_at_or_before_t_exactly() {
    let system = load(
        "hold",
        SAMPLES,
        &rig("hold", "stop_time = 0.9\nrecord = [\"rig.u\"]"),
    );
    assert_eq!(system.unit("rig.u").unwrap(), Some("N"));
    let (time, u) = column(&system, "rig.u");
    assert_eq!(time.len(), 10);
    let samples = [(0.0, 0.1), (0.3, 0.7), (0.6, -2.5), (0.9, 4.0)];
    // The engine's t_k = 0.1·k are rounded (t_3 = 0.30000000000000004): a sample within
    // rounding of t_k is at t_k.
    let expected: Vec<f64> = time
        .iter()
        .map(|&t| samples.iter().rfind(|&&(ts, _)| ts <= t + 1e-12).unwrap().1)
        .collect();
    assert_eq!(u, expected);
}

#[test]
fn linear_is_exact_at_the_samples_and_on_the_line_between_them() {
    // A step of 0.15 lands on every other sample time exactly (0, 0.3, 0.6, 0.9).
    let system = load(
        "linear",
        SAMPLES,
        "step_size = 0.15\nstop_time = 0.9\nrecord = [\"rig.u\"]\n[[instance]]\n\
         name = \"rig\"\ndata = \"rig.csv\"\ninterpolation = \"linear\"\n",
    );
    let (time, u) = column(&system, "rig.u");
    let samples = [(0.0, 0.1), (0.3, 0.7), (0.6, -2.5), (0.9, 4.0)];
    for (&t, &v) in time.iter().zip(&u) {
        let i = samples.iter().rposition(|&(ts, _)| ts <= t).unwrap();
        let (t0, v0) = samples[i];
        if t == t0 {
            assert_eq!(v, v0, "at the sample t = {t}");
            continue;
        }
        let (t1, v1) = samples[i + 1];
        let line = v0 + (v1 - v0) * (t - t0) / (t1 - t0);
        assert!(
            (v - line).abs() <= 4.0 * f64::EPSILON * line.abs().max(1.0),
            "t = {t}: {v} vs {line}"
        );
    }
    assert!(time.contains(&0.3) && time.contains(&0.6));
}

#[test]
fn start_and_stop_come_from_the_data() {
    let csv = "time,u\n0.5,1\n1.0,2\n1.5,3\n";
    let system = load("from-data", csv, &rig("hold", "start_time = \"data\""));
    assert_eq!((system.start_time(), system.stop_time()), (0.5, 1.5));
    let (time, u) = column(&system, "rig.u");
    assert_eq!(time.first(), Some(&0.5));
    assert_eq!(time.last(), Some(&1.5));
    assert_eq!(u.last(), Some(&3.0));
    // "data" may be written for the stop time too; the start time stays 0 by default, before
    // this data: refused, naming the first sample's line.
    let e = refused("stop-data", csv, &rig("hold", "stop_time = \"data\""));
    assert!(
        e.contains(
            "line 2, column 1 (`time`): the system starts at 0, before the first sample (0.5)"
        ),
        "{e}"
    );
    let system = load(
        "stop-data-0",
        "time,u\n0,1\n1.5,2\n",
        &rig("hold", "stop_time = \"data\""),
    );
    assert_eq!((system.start_time(), system.stop_time()), (0.0, 1.5));
    // Without a data instance, a missing stop time is refused.
    let e = System::from_file(&case(
        "no-data",
        csv,
        &format!(
            "step_size = 0.1\n[[instance]]\nname = \"c\"\nfmu = \"{}\"\n",
            common::crane().display()
        ),
    ))
    .unwrap_err()
    .to_string();
    assert!(e.contains("stop_time is not given"), "{e}");
}

#[test]
fn bad_data_is_refused_at_load_naming_the_line_and_the_column() {
    let system = rig("hold", "stop_time = 0.9\nrecord = [\"rig.u\"]");
    let e = refused("not-a-number", "time,u\n0,1\n0.1,1.5e\n", &system);
    assert!(
        e.contains("line 3, column 2 (`u`): `1.5e` is not a number"),
        "{e}"
    );
    let e = refused("not-increasing", "time,u\n0,1\n0.2,1\n0.1,2\n", &system);
    assert!(
        e.contains("line 4, column 1 (`time`): time 0.1 does not increase (line 3 has 0.2)"),
        "{e}"
    );
    let e = refused("past-the-data", "time,u\n0,1\n0.5,2\n", &system);
    assert!(
        e.contains("line 3, column 1 (`time`): the system's stop time 0.9 is past the data, whose last sample is at 0.5"),
        "{e}"
    );
    let e = refused(
        "no-column",
        SAMPLES,
        &rig("hold", "stop_time = 0.9\nrecord = [\"rig.force\"]"),
    );
    assert!(
        e.contains("line 1: no column `force` (the columns are: u, w)"),
        "{e}"
    );
    let e = refused(
        "no-column-connected",
        SAMPLES,
        &format!(
            "{}connections = [\"rig.y -> kf.y[1]\"]\n{}",
            "stop_time = 0.9\n",
            kalman_filter_with_rig()
        ),
    );
    assert!(e.contains("no column `y` (the columns are: u, w)"), "{e}");
}

#[test]
fn a_data_file_is_bounded_by_the_loaders_max_unpacked() {
    let path = case("too-large", SAMPLES, &rig("hold", "stop_time = 0.9"));
    let options = LoadOptions {
        limits: LoadLimits {
            max_unpacked: 40,
            ..LoadLimits::default()
        },
        ..LoadOptions::default()
    };
    let e = System::from_file_loading(&path, None, &options)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("rig.csv: the data file is larger than 40 bytes (max_unpacked); not read"),
        "{e}"
    );
    assert!(System::from_file_loading(&path, None, &LoadOptions::default()).is_ok());
}

#[test]
fn an_instance_is_an_fmu_or_a_table_and_ssp_has_no_table() {
    let both = format!(
        "step_size = 0.1\nstop_time = 0.9\n[[instance]]\nname = \"rig\"\ndata = \"rig.csv\"\nfmu = \"{}\"\n",
        common::crane().display()
    );
    let e = System::from_file(&case("both", SAMPLES, &both))
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("instance `rig`: give `fmu` or `data`, not both"),
        "{e}"
    );
    let parameters = rig("hold", "stop_time = 0.9")
        .replace("interpolation", "parameters = { u = 1.0 }\ninterpolation");
    let e = System::from_file(&case("parameters", SAMPLES, &parameters))
        .unwrap_err()
        .to_string();
    assert!(e.contains("a data instance takes no parameters"), "{e}");
    let multirate =
        rig("hold", "stop_time = 0.9").replace("interpolation", "step_multiple = 2\ninterpolation");
    let e = System::from_file(&case("multirate", SAMPLES, &multirate))
        .unwrap_err()
        .to_string();
    assert!(e.contains("step_multiple does not apply"), "{e}");
    let system = load("ssp", SAMPLES, &rig("hold", "stop_time = 0.9"));
    let e = system
        .export_ssp(
            &std::env::temp_dir().join("never-written.ssp"),
            SspVersion::V2_0,
        )
        .unwrap_err()
        .to_string();
    assert!(e.contains("instance `rig` is a data instance"), "{e}");
    assert!(e.contains("SSP has no element for a table"), "{e}");
}

/// A one-state KalmanFilter (random walk, the defaults) `kf` beside the data instance `rig`.
fn kalman_filter_with_rig() -> String {
    format!(
        "step_size = 0.1\n[[instance]]\nname = \"rig\"\ndata = \"rig.csv\"\n\n\
         [[instance]]\nname = \"kf\"\nfmu = \"{}\"\n",
        kalman_filter().display()
    )
}

fn kalman_filter() -> PathBuf {
    fmus().join("KalmanFilter.fmu")
}

#[test]
fn missing_samples_reach_an_estimator_as_its_validity_flag() {
    // Samples 3 to 5 of y missing (empty cells and nan).
    let csv = "time,y\n0,1\n0.1,1.2\n0.2,0.9\n0.3,\n0.4,nan\n0.5,\n0.6,1.1\n0.7,1.0\n";
    let system = load(
        "missing",
        csv,
        &format!(
            "stop_time = \"data\"\nconnections = [\"rig.y.held -> kf.y[1]\", \"rig.y.valid -> kf.y_valid[1]\"]\n\
             record = [\"rig.y\", \"rig.y.valid\", \"rig.y.held\", \"kf.x_hat[1]\", \"kf.innovation[1]\"]\n{}",
            kalman_filter_with_rig()
        ),
    );
    let (series, _) = run(&system, &RunOptions::default());
    let y = series.column("rig.y").unwrap();
    let valid = series.column("rig.y.valid").unwrap();
    let held = series.column("rig.y.held").unwrap();
    let x_hat = series.column("kf.x_hat[1]").unwrap();
    let innovation = series.column("kf.innovation[1]").unwrap();
    assert_eq!(series.time.len(), 8);
    let gap = 3..6;
    for k in 0..8 {
        assert_eq!(y[k].is_nan(), gap.contains(&k), "k = {k}");
        assert_eq!(valid[k], if gap.contains(&k) { 0.0 } else { 1.0 });
        assert_eq!(held[k], if gap.contains(&k) { 0.9 } else { y[k] });
        assert!(x_hat[k].is_finite(), "k = {k}");
    }
    // Records hold the values of the communication point before its step; the filter's
    // step over [t_k, t_k+1) takes the sample of t_k, its outputs show at t_k+1. Over the
    // gap a random walk only predicts: its estimate stands still, no innovation.
    for k in 4..7 {
        assert_eq!(x_hat[k], x_hat[3], "k = {k}");
        assert_eq!(innovation[k], 0.0, "k = {k}");
    }
    assert_ne!(x_hat[7], x_hat[6]);

    // The column itself carries NaN to the input it is connected to; the filter's
    // fmi2SetReal refuses a NaN and the run stops at the first missing sample, naming the
    // instance.
    let system = load(
        "missing-nan",
        csv,
        &format!(
            "stop_time = \"data\"\nconnections = [\"rig.y -> kf.y[1]\"]\n{}",
            kalman_filter_with_rig()
        ),
    );
    let mut sim = spurio_master::Simulation::new(&system).unwrap();
    let e = sim
        .run(
            &mut spurio_master::TimeSeries::default(),
            &RunOptions::default(),
        )
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("instance `kf`") && e.contains("fmi2Set* returned fmi2Error at t = 0.3"),
        "{e}"
    );
}

#[test]
fn the_example_system_runs() {
    let example = Path::new(env!("CARGO_MANIFEST_DIR")).join("../examples/systems/rig_replay.toml");
    let _ = fmus();
    let system = System::from_file(&example).unwrap();
    let (series, _) = run(&system, &RunOptions::default());
    assert!(series.time.len() > 10);
}
