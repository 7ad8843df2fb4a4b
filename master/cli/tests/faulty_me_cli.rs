//! Faulty Model Exchange FMUs through `spurio run --interface me`: the FMU of
//! `master/tests/fixtures/faulty_me/`, FMI 2.0 and 3.0 (compiled here with `cc`, packaged with
//! its model description) fails as its `fault` parameter says from t = `at` = 0.5 s on, and
//! every fault must end the run with a message naming the FMU, the call and the time: an
//! error returned by a call, NaN derivatives, a chattering event indicator, an event iteration that never
//! settles, time events at the same time forever, crowding time events and a NaN next event
//! time. Exit code 1, no backtrace (RUST_BACKTRACE is set), and within a bound of time.

#[path = "../../tests/common/mod.rs"]
mod engine;

use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::{Duration, Instant};

/// The most a faulty run may take (each takes milliseconds; the bound is for a loaded machine).
const BOUND: Duration = Duration::from_secs(20);

/// The time at which the fixture's faults begin (its `at` parameter's default).
const FAULT_AT: f64 = 0.5;

/// An FMI version of the fixture: how it is built and packaged, and what its calls are named.
struct Version {
    label: &'static str,
    flags: &'static [&'static str],
    description: &'static str,
    platform: &'static str,
    /// (FMI 2.0 name, this version's name) of the calls that differ.
    calls: &'static [(&'static str, &'static str)],
}

const VERSIONS: [Version; 2] = [
    Version {
        label: "fmi2",
        flags: &[],
        description: "modelDescription.xml",
        platform: "linux64",
        calls: &[],
    },
    Version {
        label: "fmi3",
        flags: &["-DFMI3"],
        description: "modelDescription3.xml",
        platform: "x86_64-linux",
        calls: &[
            ("fmi2GetDerivatives", "fmi3GetContinuousStateDerivatives"),
            ("fmi2NewDiscreteStates", "fmi3UpdateDiscreteStates"),
            ("fmi2GetEventIndicators", "fmi3GetEventIndicators"),
            ("fmi2Error", "fmi3Error"),
        ],
    },
];

impl Version {
    /// `text` (written for FMI 2.0) with this version's names of the calls.
    fn named(&self, text: &str) -> String {
        self.calls
            .iter()
            .fold(text.to_string(), |t, (fmi2, own)| t.replace(fmi2, own))
    }
}

/// `<dir>/FaultyME.fmu`: faulty_me.c compiled for this machine as `version` says, beside its
/// model description.
fn faulty_fmu(dir: &Path, version: &Version) -> PathBuf {
    let so = engine::compiled_fixture("faulty_me/faulty_me.c", version.flags, dir);
    let description = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../tests/fixtures/faulty_me")
        .join(version.description);
    let path = dir.join("FaultyME.fmu");
    let mut zip = zip::ZipWriter::new(std::fs::File::create(&path).unwrap());
    let options = zip::write::SimpleFileOptions::default();
    let library = format!("binaries/{}/FaultyME.so", version.platform);
    let entries = [
        (
            "modelDescription.xml".to_string(),
            std::fs::read(description).unwrap(),
        ),
        (library, so),
    ];
    for (name, data) in entries {
        zip.start_file(name, options).unwrap();
        zip.write_all(&data).unwrap();
    }
    zip.finish().unwrap();
    path
}

/// What one run said and how long it took.
struct Outcome {
    success: bool,
    code: Option<i32>,
    stdout: String,
    stderr: String,
    took: Duration,
}

/// Runs the FMU with `fault` set, into `<dir>/fault<N>.csv`.
fn run(fmu: &Path, dir: &Path, fault: u32) -> Outcome {
    let csv = dir.join(format!("fault{fault}.csv"));
    let started = Instant::now();
    let out = Command::new(env!("CARGO_BIN_EXE_spurio"))
        .args(["run", fmu.to_str().unwrap(), "--interface", "me"])
        .args(["--set", &format!("fault={fault}"), "--out"])
        .arg(&csv)
        .env("RUST_BACKTRACE", "1")
        .output()
        .unwrap();
    Outcome {
        success: out.status.success(),
        code: out.status.code(),
        stdout: String::from_utf8_lossy(&out.stdout).into_owned(),
        stderr: String::from_utf8_lossy(&out.stderr).into_owned(),
        took: started.elapsed(),
    }
}

/// The number after the first `t = ` of `message`.
fn time_in(message: &str) -> f64 {
    let after = message
        .split_once("t = ")
        .unwrap_or_else(|| panic!("no `t = ` in: {message}"))
        .1;
    let end = after
        .find(|c: char| !(c.is_ascii_digit() || matches!(c, '.' | 'e' | '-' | '+')))
        .unwrap_or(after.len());
    after[..end]
        .parse()
        .unwrap_or_else(|_| panic!("no time after `t = ` in: {message}"))
}

/// (fault, the call named, what else the message says, the time's bracket), in FMI 2.0's names.
const CASES: [(u32, &str, &str, (f64, f64)); 7] = [
    (1, "fmi2GetDerivatives failed", "fmi2Error", (FAULT_AT, 0.6)),
    (
        2,
        "fmi2GetDerivatives gave a value that is not finite",
        "",
        (0.499, FAULT_AT),
    ),
    (
        3,
        "events come from fmi2GetEventIndicators",
        "chattering",
        (FAULT_AT, 0.500001),
    ),
    (
        4,
        "fmi2NewDiscreteStates still asked for another iteration",
        "did not settle",
        (FAULT_AT, FAULT_AT),
    ),
    (
        5,
        "events come from fmi2NewDiscreteStates",
        "chattering",
        (FAULT_AT, FAULT_AT),
    ),
    (
        6,
        "events come from fmi2NewDiscreteStates",
        "chattering",
        (FAULT_AT, 0.500001),
    ),
    (
        7,
        "fmi2NewDiscreteStates gave a value that is not finite",
        "the next event time is NaN",
        (FAULT_AT, FAULT_AT),
    ),
];

#[test]
fn every_fault_of_a_model_exchange_fmu_is_a_clear_error_naming_the_fmu_the_call_and_the_time() {
    let root = std::env::temp_dir().join(format!("spurio-faulty-me-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&root);
    for version in &VERSIONS {
        let dir = root.join(version.label);
        std::fs::create_dir_all(&dir).unwrap();
        let fmu = faulty_fmu(&dir, version);

        // Without a fault the FMU is sound: x = exp(-t), recorded as y up to t = 1.
        let sound = run(&fmu, &dir, 0);
        assert!(sound.success, "{}: {}", version.label, sound.stderr);
        let table = std::fs::read_to_string(dir.join("fault0.csv")).unwrap();
        let last = table.lines().last().unwrap();
        let (t, y) = last.split_once(',').unwrap();
        let (t, y): (f64, f64) = (t.parse().unwrap(), y.parse().unwrap());
        assert_eq!(t, 1.0, "{table}");
        assert!((y - (-1.0f64).exp()).abs() < 1e-6, "y(1) = {y}");

        for (fault, call, what, (earliest, latest)) in CASES {
            let (call, what) = (version.named(call), version.named(what));
            let out = run(&fmu, &dir, fault);
            let said = format!(
                "{} fault {fault}: {}\n{}",
                version.label, out.stdout, out.stderr
            );
            assert!(!out.success && out.code == Some(1), "{said}");
            assert!(out.took < BOUND, "{said}\ntook {:?}", out.took);
            assert!(out.stderr.contains(&fmu.display().to_string()), "{said}");
            assert!(out.stderr.contains(&call), "{said}");
            assert!(out.stderr.contains(&what), "{said}");
            assert!(!out.stderr.contains("backtrace"), "{said}");
            assert!(!out.stderr.contains("panicked"), "{said}");
            let cause = out.stderr.split_once("Caused by:").map_or("", |c| c.1);
            let t = time_in(cause);
            assert!(
                (earliest..=latest).contains(&t),
                "t = {t}, not in [{earliest}, {latest}]\n{said}"
            );
        }
    }
    std::fs::remove_dir_all(&root).unwrap();
}
