//! `spurio run model.fmu`: one FMU straight from the command line (Model Exchange through
//! spurio's solvers, or Co-Simulation), and what it says when the argument is neither a system
//! file nor an FMU: a message saying what it expected, never a backtrace.

#[path = "../../tests/common/mod.rs"]
mod engine;

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// Runs `spurio` with `args` (RUST_BACKTRACE set, to show that none is printed).
fn spurio(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_spurio"))
        .args(args)
        .env("RUST_BACKTRACE", "1")
        .output()
        .unwrap()
}

/// Runs `fmu` as Model Exchange into `csv`, with the flags `extra`.
fn run_me(fmu: &Path, csv: &Path, extra: &[&str]) -> Output {
    let (fmu, csv) = (fmu.to_str().unwrap(), csv.to_str().unwrap());
    let mut args = vec!["run", fmu, "--interface", "me", "--out", csv];
    args.extend_from_slice(extra);
    spurio(&args)
}

/// A case's fresh folder, its results file and the Reference FMU `model` of `version`.
fn case(name: &str, version: &str, model: &str) -> (PathBuf, PathBuf, PathBuf) {
    let dir = folder(name);
    let csv = dir.join("results.csv");
    (dir, csv, engine::reference(version, model))
}

/// A fresh folder for one case.
fn folder(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("spurio-run-fmu-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn text(bytes: &[u8]) -> String {
    String::from_utf8_lossy(bytes).into_owned()
}

#[test]
fn an_argument_that_is_neither_a_system_nor_an_fmu_is_named_without_a_backtrace() {
    let dir = folder("neither");
    let binary = dir.join("data.bin");
    std::fs::write(&binary, [0xff, 0xfe, 0x00, 0x81, 0x7f]).unwrap();
    let out = spurio(&["run", binary.to_str().unwrap()]);
    let stderr = text(&out.stderr);
    assert!(!out.status.success());
    assert!(stderr.contains("neither a system file"), "{stderr}");
    assert!(stderr.contains(".fmu"), "{stderr}");
    assert!(!stderr.contains("backtrace"), "{stderr}");
    // A flag of single-FMU runs given with a system file: said, not ignored.
    let system = dir.join("s.toml");
    std::fs::write(&system, "stop_time = 1.0\nstep_size = 0.1\n").unwrap();
    let out = spurio(&["run", system.to_str().unwrap(), "--solver", "rodas3"]);
    let stderr = text(&out.stderr);
    assert!(!out.status.success());
    assert!(
        stderr.contains("--solver apply to running one FMU"),
        "{stderr}"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn a_reference_fmu_runs_as_model_exchange_and_reports_its_events() {
    let (dir, csv, fmu) = case("me", "fmi3", "BouncingBall");
    let out = run_me(&fmu, &csv, &["--verbose"]);
    let (stdout, stderr) = (text(&out.stdout), text(&out.stderr));
    assert!(out.status.success(), "{stderr}");
    // the DefaultExperiment: 0 to 3 s every 0.01 s, the outputs by name
    let rows = std::fs::read_to_string(&csv).unwrap();
    let mut lines = rows.lines();
    assert_eq!(lines.next(), Some("\"time\",\"h\",\"v\""));
    assert_eq!(rows.lines().count(), 302);
    assert!(rows.lines().last().unwrap().starts_with("3.0,"), "{rows}");
    // every bounce reported with its time, the first at sqrt(2/9.81) = 0.45152364098...
    let events: Vec<&str> = stderr
        .lines()
        .filter(|l| l.contains("state event"))
        .collect();
    assert_eq!(events.len(), 11, "{stderr}");
    assert!(events[0].contains("t = 0.4515236409"), "{}", events[0]);
    assert!(
        stdout.contains("11 state, 0 time, 0 step events"),
        "{stdout}"
    );
    // Stair: the FMU ends the run at t = 9 (terminateSimulation), said and recorded.
    let stair = engine::reference("fmi2", "Stair");
    let out = run_me(&stair, &csv, &[]);
    let stdout = text(&out.stdout);
    assert!(out.status.success(), "{}", text(&out.stderr));
    assert!(stdout.contains("ended the simulation at t = 9"), "{stdout}");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn the_events_of_a_model_exchange_instance_in_a_system_are_told_with_verbose() {
    // BouncingBall (FMI 2.0) as a system instance: each bounce said with the instance's name
    // and the time the single-FMU run gives (the first at √(2 h₀/g) = 0.45152364098…).
    let (dir, csv, fmu) = case("system-events", "fmi2", "BouncingBall");
    let system = dir.join("ball.toml");
    std::fs::write(
        &system,
        format!(
            "stop_time = 3.0\nstep_size = 0.01\n\n[[instance]]\nname = \"ball\"\nfmu = {:?}\ninterface = \"me\"\ntolerance = 1e-9\n",
            fmu.display().to_string()
        ),
    )
    .unwrap();
    let out = spurio(&[
        "run",
        system.to_str().unwrap(),
        "--out",
        csv.to_str().unwrap(),
        "--verbose",
    ]);
    let stderr = text(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    let told: Vec<&str> = stderr
        .lines()
        .filter(|l| {
            l.starts_with("spurio: instance `ball`: t = ")
                && l.contains("state event (indicator 1)")
        })
        .collect();
    let alone = run_me(&fmu, &dir.join("alone.csv"), &["--verbose"]);
    let alone_stderr = text(&alone.stderr);
    let alone_times: Vec<&str> = alone_stderr
        .lines()
        .filter(|l| l.contains("state event"))
        .map(|l| l.split(": ").nth(1).unwrap())
        .collect();
    assert!(told.len() >= 8, "{stderr}");
    assert_eq!(told.len(), alone_times.len(), "{stderr}\n{alone_stderr}");
    assert!(told[0].contains("t = 0.451523640"), "{}", told[0]);
    for (line, time) in told.iter().zip(&alone_times) {
        let t: f64 = line
            .split("t = ")
            .nth(1)
            .unwrap()
            .split(':')
            .next()
            .unwrap()
            .parse()
            .unwrap();
        let t_alone: f64 = time.trim_start_matches("t = ").parse().unwrap();
        assert!((t - t_alone).abs() < 1e-9, "{line} against {time}");
    }
    // without --verbose nothing is said
    let quiet = spurio(&[
        "run",
        system.to_str().unwrap(),
        "--out",
        csv.to_str().unwrap(),
    ]);
    assert!(
        !text(&quiet.stderr).contains("state event"),
        "{}",
        text(&quiet.stderr)
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn model_exchange_errors_name_the_fmu_and_stop_without_a_backtrace() {
    // Robertson's stiff problem to 1e8 s with the explicit method: bounded work, an error.
    // (Model Exchange asked for: the FMU's own Co-Simulation takes fixed Euler steps.)
    let (dir, csv, roberts) = case("me-errors", "fmi3", "Roberts");
    let out = run_me(&roberts, &csv, &[]);
    let stderr = text(&out.stderr);
    assert!(!out.status.success());
    assert!(stderr.contains("Roberts.fmu"), "{stderr}");
    assert!(
        stderr.contains("steps without reaching an output point"),
        "{stderr}"
    );
    assert!(!stderr.contains("backtrace"), "{stderr}");
    // with the stiff method it runs
    let out = run_me(&roberts, &csv, &["--solver", "rodas3"]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    // an unknown start value
    let vdp = engine::reference("fmi2", "VanDerPol");
    let out = run_me(&vdp, &csv, &["--set", "nobody=1"]);
    let stderr = text(&out.stderr);
    assert!(!out.status.success());
    assert!(stderr.contains("has no variable `nobody`"), "{stderr}");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn a_closed_stdout_ends_the_run_quietly() {
    // `spurio run … | head`: stdout is a pipe whose reader has gone before the run speaks.
    for interface in ["me", "cs"] {
        let (dir, csv, fmu) = case(&format!("pipe-{interface}"), "fmi2", "BouncingBall");
        let (reader, writer) = std::io::pipe().unwrap();
        drop(reader);
        let out = Command::new(env!("CARGO_BIN_EXE_spurio"))
            .args(["run", fmu.to_str().unwrap(), "--interface", interface])
            .args(["--out", csv.to_str().unwrap()])
            .env("RUST_BACKTRACE", "1")
            .stdout(writer)
            .stderr(std::process::Stdio::piped())
            .output()
            .unwrap();
        let stderr = text(&out.stderr);
        assert!(
            out.status.success(),
            "{interface}: {:?}: {stderr}",
            out.status
        );
        assert!(!stderr.contains("panicked"), "{interface}: {stderr}");
        assert!(!stderr.contains("backtrace"), "{interface}: {stderr}");
        // the run itself went on: its rows are written
        let rows = std::fs::read_to_string(&csv).unwrap();
        assert_eq!(rows.lines().count(), 302, "{interface}");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}

#[test]
fn an_fmi3_fmu_with_event_mode_runs_as_co_simulation_through_its_event_iterations() {
    // Stair declares hasEventMode: its counter's time events are handled in event mode and
    // the event iteration at t = 9 asks to end the run, which ends there normally, said.
    let (dir, csv, fmu) = case("cs-event-mode", "fmi3", "Stair");
    let (fmu, out_csv) = (fmu.to_str().unwrap(), csv.to_str().unwrap());
    let out = spurio(&["run", fmu, "--interface", "cs", "--out", out_csv]);
    let stdout = text(&out.stdout);
    assert!(out.status.success(), "{}", text(&out.stderr));
    assert!(
        stdout.contains(
            "asked to end the simulation at t = 9 (fmi3DoStep, or the event iteration after \
             it, returned terminateSimulation = true)"
        ),
        "{stdout}"
    );
    // The counter counts the seconds from 1: ⌊t⌋ + 1 at every 0.2 s, 10 at t = 9.
    let rows = std::fs::read_to_string(&csv).unwrap();
    let mut points = 0;
    for line in rows.lines().skip(1) {
        let (t, counter) = line.split_once(',').unwrap();
        let (t, counter): (f64, f64) = (t.parse().unwrap(), counter.parse().unwrap());
        assert_eq!(counter, (t + 1e-9).floor() + 1.0, "{line}");
        points += 1;
    }
    assert_eq!(points, 46);
    assert!(rows.ends_with("9.0,10.0\n"), "{rows}");
    std::fs::remove_dir_all(&dir).unwrap();
}
