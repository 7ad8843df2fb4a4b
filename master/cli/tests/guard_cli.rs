//! A crashing or hanging FMU costs one run, and the CLI refuses what it cannot do sensibly.
//!
//! The misbehaving FMU is the packaged GantryCrane with its linux64 library replaced by
//! `master/tests/fixtures/misbehaving.c` (compiled here with `cc`), which segfaults, aborts, exits or
//! never returns in `fmi2DoStep` as the `MISBEHAVE*` environment variables say. Every case
//! runs `spurio` with `TMPDIR` at a fresh folder and checks that the folder is empty
//! afterwards (no unpacked FMU left behind) and that nothing but the expected files was
//! written beside it.

mod common;
#[path = "../../tests/common/mod.rs"]
mod engine;
use engine::packaged_fmus;

use common::{repo, require_fmus, s};
use engine::assert_names;
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

/// A fresh folder for one case, with `tmp/` as the TMPDIR of the runs.
struct Case {
    dir: PathBuf,
    tmp: PathBuf,
}

impl Case {
    fn new(name: &str) -> Self {
        let dir = common::temp(&format!("guard-{name}"));
        let tmp = dir.join("tmp");
        std::fs::create_dir_all(&tmp).unwrap();
        Case { dir, tmp }
    }

    /// Writes `text` as `name` in the case folder.
    fn file(&self, name: &str, text: &str) -> PathBuf {
        let path = self.dir.join(name);
        std::fs::write(&path, text).unwrap();
        path
    }

    /// `spurio args` with TMPDIR at `tmp/` and the environment `env`.
    fn command(&self, args: &[&str], env: &[(&str, &str)]) -> Command {
        let mut command = Command::new(env!("CARGO_BIN_EXE_spurio"));
        command.args(args).env("TMPDIR", &self.tmp);
        for (k, v) in env {
            command.env(k, v);
        }
        command
    }

    /// Runs `spurio args` with TMPDIR at `tmp/` and the environment `env`.
    fn spurio(&self, args: &[&str], env: &[(&str, &str)]) -> Output {
        self.command(args, env).output().unwrap()
    }

    /// Starts `spurio args` with the environment `env`, waits (30 s at most) until
    /// `under_way` says the `what` is under way, then `settle` longer, and sends it SIGTERM;
    /// returns its output, checked to end with the exit code of SIGTERM (143).
    fn terminated(
        &self,
        args: &[&str],
        env: &[(&str, &str)],
        what: &str,
        under_way: impl Fn() -> bool,
        settle: Duration,
    ) -> Output {
        let child = self
            .command(args, env)
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        let deadline = Instant::now() + Duration::from_secs(30);
        while !under_way() {
            assert!(Instant::now() < deadline, "the {what} did not start");
            std::thread::sleep(Duration::from_millis(20));
        }
        std::thread::sleep(settle);
        let kill = Command::new("kill")
            .args(["-TERM", &child.id().to_string()])
            .status()
            .unwrap();
        assert!(kill.success());
        let out = child.wait_with_output().unwrap();
        assert_eq!(out.status.code(), Some(143), "{}", stderr(&out));
        out
    }

    /// Asserts that the temp folder is empty and the case folder holds only `expected`
    /// besides it.
    fn assert_clean(&self, expected: &[&str]) {
        engine::assert_only_left(&self.dir, &self.tmp, expected);
    }

    /// `Bad.fmu`: the GantryCrane's model description over `fixtures/misbehaving.c`.
    fn misbehaving_fmu(&self) -> PathBuf {
        require_fmus(&["GantryCrane"]);
        engine::misbehaving_fmu(&self.dir)
    }

    /// `system.toml`: the misbehaving FMU as instance `crane`, 0.1 s at 0.01 s, recording
    /// `crane.x` (which the fixture gives as the time) and the parameter `crane.x0`.
    fn bad_system(&self) -> PathBuf {
        self.misbehaving_fmu();
        self.file(
            "system.toml",
            "stop_time = 0.1\nstep_size = 0.01\nrecord = [\"crane.x\", \"crane.x0\"]\n\
             [[instance]]\nname = \"crane\"\nfmu = \"Bad.fmu\"\n",
        )
    }

    /// The results file of `spurio run` in the case folder.
    fn csv(&self) -> PathBuf {
        self.dir.join("out.csv")
    }

    /// Runs [`Case::bad_system`] with `spurio run … --out out.csv` (then `extra`), its FMU
    /// misbehaving as `mode` at the time `at`; returns the output and the CSV's path.
    fn run_bad(&self, mode: &str, at: &str, extra: &[&str]) -> (Output, PathBuf) {
        let (system, csv) = (self.bad_system(), self.csv());
        let args = [&["run", s(&system), "--out", s(&csv)], extra].concat();
        let out = self.spurio(&args, &[("MISBEHAVE", mode), ("MISBEHAVE_AT", at)]);
        (out, csv)
    }

    /// `spurio sweep system --vary vary --metric metric` (then `extra`) is [`refused`] with
    /// exit code 1 and a message naming every one of `parts`, having written nothing but
    /// `system.toml`.
    fn refused_sweep(
        &self,
        system: &Path,
        vary: &str,
        metric: &str,
        extra: &[&str],
        parts: &[&str],
    ) -> Output {
        let args = sweep_args(system, vary, metric, extra);
        refused(self, &args, 1, parts, &["system.toml"])
    }

    /// `spurio run system --out out.csv` (then `extra`) is [`refused`] with exit code `code`
    /// and a message naming every one of `parts`, having written nothing but `system.toml`.
    fn refused_run(&self, system: &Path, extra: &[&str], code: i32, parts: &[&str]) -> Output {
        let csv = self.csv();
        let args = [&["run", s(system), "--out", s(&csv)], extra].concat();
        refused(self, &args, code, parts, &["system.toml"])
    }
}

impl Drop for Case {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.dir);
    }
}

fn stderr(out: &Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

fn stdout(out: &Output) -> String {
    String::from_utf8_lossy(&out.stdout).into_owned()
}

/// The rows of a results CSV (header excluded), each checked to have as many numbers as
/// the header has names.
fn rows(csv: &Path) -> Vec<Vec<f64>> {
    let text = std::fs::read_to_string(csv).unwrap();
    assert!(text.ends_with('\n'), "the last row is cut: {text:?}");
    let columns = text.lines().next().unwrap_or("").split("\",\"").count();
    text.lines()
        .skip(1)
        .map(|line| {
            let row: Vec<f64> = line.split(',').map(|v| v.parse().unwrap()).collect();
            assert_eq!(row.len(), columns, "{line}");
            row
        })
        .collect()
}

#[test]
fn a_hanging_call_ends_the_run_by_the_watchdog_keeping_the_rows_before_it() {
    let case = Case::new("hang");
    let started = Instant::now();
    let (out, csv) = case.run_bad("hang", "0.05", &["--call-timeout", "0.5"]);
    assert!(started.elapsed().as_secs_f64() < 20.0);
    assert_eq!(out.status.code(), Some(124), "{}", stderr(&out));
    assert_names(
        &stderr(&out),
        &[
            "instance `crane`",
            "Bad.fmu",
            "fmi2DoStep at t = 0.05 did not return within 0.5 s (--call-timeout)",
            "the run ended early",
            &format!("the rows recorded so far are in {}", csv.display()),
        ],
    );
    // The points up to the one whose step hung, whole.
    let rows = rows(&csv);
    let times: Vec<f64> = rows.iter().map(|r| r[0]).collect();
    assert_eq!(times, [0.0, 0.01, 0.02, 0.03, 0.04, 0.05]);
    assert!(rows.iter().all(|r| (r[1] - r[0]).abs() < 1e-12), "{rows:?}");
    case.assert_clean(&["Bad.fmu", "system.toml", "out.csv"]);
}

#[test]
fn an_fmu_that_kills_the_run_leaves_whole_rows_and_no_unpacked_fmu() {
    for (mode, code, signal) in [
        ("segv", 139, "signal 11 (SIGSEGV)"),
        ("abort", 134, "signal 6 (SIGABRT)"),
    ] {
        let case = Case::new(&format!("run-{mode}"));
        let (out, csv) = case.run_bad(mode, "0.05", &[]);
        assert_eq!(out.status.code(), Some(code), "{mode}: {}", stderr(&out));
        assert_names(
            &stderr(&out),
            &[
                &format!("the run crashed: its process was killed by {signal}"),
                "the run ended early",
                &format!("the rows recorded before are in {}", csv.display()),
            ],
        );
        // The header, then whole rows from the start (those flushed before the crash).
        let text = std::fs::read_to_string(&csv).unwrap();
        assert!(
            text.starts_with("\"time\",\"crane.x\",\"crane.x0\"\n"),
            "{text}"
        );
        for (k, row) in rows(&csv).iter().enumerate() {
            assert!(
                (row[0] - k as f64 * 0.01).abs() < 1e-12 && row[0] <= 0.05,
                "{text}"
            );
        }
        case.assert_clean(&["Bad.fmu", "system.toml", "out.csv"]);
    }
}

#[test]
fn a_failing_step_keeps_the_rows_before_it_and_says_the_run_ended_early() {
    let case = Case::new("error");
    let (out, csv) = case.run_bad("error", "0.03", &[]);
    assert_eq!(out.status.code(), Some(1), "{}", stderr(&out));
    assert_names(
        &stderr(&out),
        &[
            "the run ended early; the rows recorded before are in",
            "instance `crane`",
            "fmi2DoStep returned fmi2Error at t = 0.03",
        ],
    );
    assert_eq!(rows(&csv).len(), 4);
    case.assert_clean(&["Bad.fmu", "system.toml", "out.csv"]);
}

#[test]
fn sigterm_ends_a_run_cleanly_with_the_rows_so_far() {
    let case = Case::new("sigterm");
    let system = case.bad_system();
    let csv = case.csv();
    // Once the FMU is unpacked and the run under way (hanging at t = 0.02).
    let out = case.terminated(
        &["run", s(&system), "--out", s(&csv)],
        &[("MISBEHAVE", "hang"), ("MISBEHAVE_AT", "0.02")],
        "run",
        || std::fs::read_dir(&case.tmp).unwrap().count() > 0 && csv.exists(),
        Duration::from_millis(500),
    );
    assert_names(
        &stderr(&out),
        &[
            "interrupted by SIGTERM; the run ended early",
            "the rows recorded so far are in",
        ],
    );
    let times: Vec<f64> = rows(&csv).iter().map(|r| r[0]).collect();
    assert_eq!(times, [0.0, 0.01, 0.02]);
    case.assert_clean(&["Bad.fmu", "system.toml", "out.csv"]);
}

#[test]
fn sigterm_ends_a_sweep_with_its_workers_and_leaves_nothing_behind() {
    let case = Case::new("sweep-sigterm");
    let system = case.bad_system();
    // Once both workers are under way (each has its session folder in the sweep's).
    let workers = || {
        std::fs::read_dir(&case.tmp)
            .unwrap()
            .filter_map(|e| std::fs::read_dir(e.unwrap().path()).ok())
            .flat_map(|d| d.map(|e| e.unwrap().file_name().to_string_lossy().into_owned()))
            .filter(|n| n.starts_with("spurio-"))
            .count()
    };
    let out = case.terminated(
        &[
            "sweep",
            s(&system),
            "--vary",
            "crane.x0=0.1,0.2",
            "--metric",
            "final(crane.x)",
            "--threads",
            "2",
        ],
        &[("MISBEHAVE", "hang")],
        "workers",
        || workers() >= 2,
        Duration::from_millis(300),
    );
    assert_names(
        &stderr(&out),
        &["interrupted by SIGTERM; the run ended early"],
    );
    // The workers are gone with it.
    std::thread::sleep(Duration::from_millis(200));
    let ps = Command::new("ps").args(["-eo", "args"]).output().unwrap();
    let left: Vec<String> = String::from_utf8_lossy(&ps.stdout)
        .lines()
        .filter(|l| l.contains("sweep-run") && l.contains(s(&system)))
        .map(String::from)
        .collect();
    assert!(left.is_empty(), "workers left running: {left:?}");
    case.assert_clean(&["Bad.fmu", "system.toml"]);
}

#[test]
fn a_run_that_crashes_or_hangs_costs_that_run_of_a_sweep_only() {
    for (mode, why) in [
        (
            "segv",
            "the worker process was killed by signal 11 (SIGSEGV)",
        ),
        (
            "abort",
            "the worker process was killed by signal 6 (SIGABRT)",
        ),
        ("exit", "the worker process exited with code 3"),
        // An FMI error is an answer: that worker goes on with the next runs.
        (
            "error",
            "instance `crane` (", // then the FMU and the call
        ),
        (
            "hang",
            "instance `crane` (", // then the FMU, the call and the time
        ),
    ] {
        let case = Case::new(&format!("sweep-{mode}"));
        let system = case.bad_system();
        let csv = case.dir.join("runs.csv");
        let out = case.spurio(
            &[
                "sweep",
                s(&system),
                "--vary",
                "crane.x0=0.1,0.25,0.3,0.4",
                "--metric",
                "final(crane.x)",
                "--metric",
                "mean(crane.x0)",
                "--threads",
                "2",
                "--call-timeout",
                "1",
                "--out",
                s(&csv),
            ],
            &[("MISBEHAVE", mode), ("MISBEHAVE_VALUE", "0.25")],
        );
        let err = stderr(&out);
        assert_eq!(out.status.code(), Some(1), "{mode}: {err}");
        assert_names(
            &err,
            &[
                "run 1 (crane.x0 = 0.25) failed: ",
                why,
                "1 of 4 runs failed",
            ],
        );
        if mode == "hang" {
            assert_names(&err, &["fmi2DoStep at t = 0 did not return within 1 s"]);
        }
        if mode == "error" {
            assert_names(&err, &["fmi2DoStep returned fmi2Error at t = 0"]);
        }
        // The other three runs: final(crane.x) is the stop time, mean(crane.x0) the value.
        let table = stdout(&out);
        assert_names(
            &table,
            &[
                "| final(crane.x) | 0.100000 ± 0.000000 | 3/4 |",
                "| mean(crane.x0) | 0.266667 ± 0.152753 | 3/4 |",
            ],
        );
        let text = std::fs::read_to_string(&csv).unwrap();
        assert!(
            text.starts_with("\"crane.x0\",\"final(crane.x)\",\"mean(crane.x0)\"\n"),
            "{text}"
        );
        let rows: Vec<Vec<f64>> = text
            .lines()
            .skip(1)
            .map(|l| l.split(',').map(|v| v.parse().unwrap()).collect())
            .collect();
        assert_eq!(rows.len(), 4, "{text}");
        for (row, x0) in rows.iter().zip([0.1, 0.25, 0.3, 0.4]) {
            assert_eq!(row[0], x0);
            if x0 == 0.25 {
                assert!(row[1].is_nan() && row[2].is_nan(), "{mode}: {text}");
            } else {
                assert!(
                    (row[1] - 0.1).abs() < 1e-12 && (row[2] - x0).abs() < 1e-12,
                    "{text}"
                );
            }
        }
        case.assert_clean(&["Bad.fmu", "system.toml", "runs.csv"]);
    }
}

/// A system of the packaged crane and sensor (FMUs in build/fmus) with `extra` TOML lines
/// at the top level and `parameters` for the sensor.
fn crane_sensor(case: &Case, extra: &str, sensor_parameters: &str) -> PathBuf {
    require_fmus(&["GantryCrane", "Sensor2"]);
    let fmus = repo().join("build/fmus");
    case.file(
        "system.toml",
        &format!(
            "{extra}\nconnections = [\"crane.x -> sensor.u[1]\", \"crane.theta -> sensor.u[2]\"]\n\
             [[instance]]\nname = \"crane\"\nfmu = \"{}\"\n\
             [[instance]]\nname = \"sensor\"\nfmu = \"{}\"\nparameters = {{ {sensor_parameters} }}\n",
            fmus.join("GantryCrane.fmu").display(),
            fmus.join("Sensor2.fmu").display()
        ),
    )
}

/// `sweep system --vary vary --metric metric`, then `extra`.
fn sweep_args<'a>(
    system: &'a Path,
    vary: &'a str,
    metric: &'a str,
    extra: &[&'a str],
) -> Vec<&'a str> {
    [
        &["sweep", s(system), "--vary", vary, "--metric", metric],
        extra,
    ]
    .concat()
}

/// `spurio args` fails with exit code `code` and a message naming every one of `parts`;
/// the temp folder is left empty and only `files` were written.
fn refused(case: &Case, args: &[&str], code: i32, parts: &[&str], files: &[&str]) -> Output {
    let out = case.spurio(args, &[]);
    assert_eq!(out.status.code(), Some(code), "{args:?}: {}", stderr(&out));
    assert_names(&stderr(&out), parts);
    case.assert_clean(files);
    out
}

#[test]
fn run_refuses_a_real_time_factor_that_is_not_positive() {
    let case = Case::new("real-time");
    let system = crane_sensor(&case, "stop_time = 0.1\nstep_size = 0.01", "");
    for bad in ["0", "-1", "nan", "inf"] {
        case.refused_run(
            &system,
            &[&format!("--real-time={bad}")],
            2,
            &[
                &format!("invalid value '{bad}' for '--real-time"),
                "is not a positive number",
            ],
        );
    }
}

#[test]
fn run_and_sweep_refuse_more_steps_than_max_steps_unless_asked() {
    let case = Case::new("max-steps");
    let system = crane_sensor(&case, "stop_time = 1e300\nstep_size = 1e-300", "");
    let csv = case.csv();
    case.refused_run(
        &system,
        &[],
        1,
        &[
            "the run would take infinitely many steps",
            "more than --max-steps 100000000",
        ],
    );
    case.refused_sweep(
        &system,
        "sensor.seed=1..2",
        "final(crane.x)",
        &[],
        &["more than --max-steps 100000000"],
    );
    // Asked for: 20 steps against a limit of 20 run.
    let system = crane_sensor(&case, "stop_time = 0.2\nstep_size = 0.01", "");
    case.refused_run(
        &system,
        &["--max-steps", "19"],
        1,
        &["the run would take 20 steps", "more than --max-steps 19"],
    );
    let out = case.spurio(
        &["run", s(&system), "--out", s(&csv), "--max-steps", "20"],
        &[],
    );
    assert!(out.status.success(), "{}", stderr(&out));
    assert_eq!(rows(&csv).len(), 21);
    case.assert_clean(&["system.toml", "out.csv"]);
}

#[test]
fn sweep_refuses_too_many_runs_before_making_them_and_caps_threads() {
    let case = Case::new("sweep-size");
    let system = crane_sensor(&case, "stop_time = 0.05\nstep_size = 0.01", "");
    let metric = "final(crane.x)";
    case.refused_sweep(
        &system,
        "sensor.seed=1..99999999999",
        metric,
        &[],
        &["99999999999 runs, more than the 1000000 allowed (--max-runs)"],
    );
    case.refused_sweep(
        &system,
        "sensor.seed=1..3",
        metric,
        &["--max-runs", "2"],
        &["3 runs, more than the 2 allowed"],
    );
    let args = sweep_args(
        &system,
        "sensor.seed=1..3",
        metric,
        &["--threads", "100000"],
    );
    let out = case.spurio(&args, &[]);
    assert!(out.status.success(), "{}", stderr(&out));
    let cores = std::thread::available_parallelism().unwrap().get();
    assert_names(
        &stderr(&out),
        &[&format!(
            "--threads 100000 capped at {} (4 per core",
            4 * cores
        )],
    );
    assert_names(&stdout(&out), &["| final(crane.x) |", "| 3/3 |"]);
    case.assert_clean(&["system.toml"]);
}

#[test]
fn sweep_refuses_a_value_run_would_refuse_and_a_bound_that_cannot_hold() {
    let case = Case::new("sweep-values");
    let system = crane_sensor(&case, "stop_time = 0.05\nstep_size = 0.01", "");
    case.refused_sweep(
        &system,
        "sensor.seed=1,0.5",
        "final(crane.x)",
        &[],
        &[
            "instance `sensor`",
            "parameter `seed`",
            "is of type Integer",
            "`0.5` is not one",
        ],
    );
    case.refused_sweep(
        &system,
        "sensor.u[1]=1,2",
        "final(crane.x)",
        &[],
        &[
            "parameter `u[1]`",
            "driven by the connection `crane.x -> sensor.u[1]`",
        ],
    );
    for bound in ["-1", "0", "nan"] {
        let metric = format!("settling(crane.x, {bound})");
        case.refused_sweep(
            &system,
            "sensor.seed=1,2",
            &metric,
            &[],
            &["the bound must be a positive number", &format!("`{bound}`")],
        );
    }
}

#[test]
fn a_connected_input_parameter_a_repeated_record_and_an_unrecorded_plot_are_refused() {
    // (the system's record line, the sensor's parameters, more arguments, the refusal);
    // nothing is written: the checks come before the run.
    let cases: [(&str, &str, &[&str], &[&str]); 3] = [
        (
            "",
            "\"u[1]\" = 0.3",
            &[],
            &[
                "instance `sensor`",
                "parameter `u[1]`",
                "driven by the connection `crane.x -> sensor.u[1]`",
            ],
        ),
        (
            "record = [\"crane.x\", \"sensor.y[1]\", \"crane.x\"]",
            "",
            &[],
            &["record lists `crane.x` twice"],
        ),
        (
            "record = [\"crane.x\"]",
            "",
            &["--plot", "crane.x,crane.v"],
            &["cannot plot `crane.v`: it is not recorded (recorded: crane.x)"],
        ),
    ];
    for (record, sensor_parameters, extra, parts) in cases {
        let case = Case::new("system");
        let head = format!("stop_time = 0.05\nstep_size = 0.01\n{record}");
        let system = crane_sensor(&case, &head, sensor_parameters);
        case.refused_run(&system, extra, 1, parts);
    }
}

#[test]
fn write_errors_name_the_file_and_a_sweep_still_prints_its_table() {
    let case = Case::new("dev-full");
    let system = crane_sensor(&case, "stop_time = 0.05\nstep_size = 0.01", "");
    refused(
        &case,
        &["run", s(&system), "--out", "/dev/full"],
        1,
        &["cannot write /dev/full", "No space left on device"],
        &["system.toml"],
    );
    let out = case.refused_sweep(
        &system,
        "sensor.seed=1,2",
        "final(crane.x)",
        &["--out", "/dev/full"],
        &["cannot write /dev/full", "No space left on device"],
    );
    assert_names(
        &stdout(&out),
        &["| final(crane.x) | 0.000000 ± 0.000000 | 2/2 |"],
    );
}

#[test]
fn the_loaders_limits_are_flags() {
    let case = Case::new("limits");
    let system = crane_sensor(&case, "stop_time = 0.05\nstep_size = 0.01", "");
    let cases: [(&str, &str, &[&str]); 3] = [
        (
            "--max-model-description",
            "1K",
            &[
                "modelDescription.xml",
                "beyond the loader's limit of at most 1024 bytes",
            ],
        ),
        (
            "--max-entries",
            "2",
            &["beyond the loader's limit of at most 2 entries"],
        ),
        (
            "--max-unpacked",
            "64K",
            &["beyond the loader's limit of at most 65536 bytes"],
        ),
    ];
    for (flag, value, parts) in cases {
        case.refused_run(
            &system,
            &[flag, value],
            1,
            &[&["GantryCrane.fmu"], parts].concat(),
        );
    }
}

#[test]
fn bad_systems_are_refused_naming_what_is_wrong_and_leave_nothing_behind() {
    require_fmus(&["GantryCrane"]);
    let crane = repo().join("build/fmus/GantryCrane.fmu");
    let crane = crane.display();
    let instance = format!("[[instance]]\nname = \"crane\"\nfmu = \"{crane}\"\n");
    let cases: [(&str, String, &[&str]); 6] = [
        (
            "no FMU file",
            "stop_time = 1.0\nstep_size = 0.1\n[[instance]]\nname = \"c\"\nfmu = \"nowhere.fmu\"\n"
                .into(),
            &["nowhere.fmu"],
        ),
        (
            "not TOML",
            "stop_time = = 1\n".into(),
            &["system.toml"],
        ),
        (
            "zero step",
            format!("stop_time = 1.0\nstep_size = 0.0\n{instance}"),
            &["step_size must be > 0, got 0"],
        ),
        (
            "unknown instance",
            format!("stop_time = 1.0\nstep_size = 0.1\nconnections = [\"crane.x -> nobody.u\"]\n{instance}"),
            &["connection `crane.x -> nobody.u`", "no instance called `nobody`"],
        ),
        (
            "unknown variable",
            format!("stop_time = 1.0\nstep_size = 0.1\nrecord = [\"crane.nothing\"]\n{instance}"),
            &["instance `crane`", "no variable `nothing`"],
        ),
        (
            "not a zip",
            "stop_time = 1.0\nstep_size = 0.1\n[[instance]]\nname = \"c\"\nfmu = \"system.toml\"\n"
                .into(),
            &["system.toml", "not a valid FMU archive"],
        ),
    ];
    for (what, text, parts) in cases {
        let case = Case::new("bad-system");
        let system = case.file("system.toml", &text);
        let out = case.refused_run(&system, &[], 1, parts);
        assert!(
            !stderr(&out).contains("panicked"),
            "{what}: {}",
            stderr(&out)
        );
        case.refused_sweep(&system, "crane.x0=0.1,0.2", "final(crane.x)", &[], parts);
    }
}
