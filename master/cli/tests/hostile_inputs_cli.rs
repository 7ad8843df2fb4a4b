//! Hostile inputs to `spurio run`: an SSP whose FMU or SSD is a zip bomb, a system file that
//! never ends, and the errors of bad inputs, each message printed once.
//!
//! The bombs are small (a few MiB of zeros, deflated to a few KiB) and the limits lowered
//! below them (`--max-unpacked`, `--max-model-description`), so the tests show the refusal
//! comes from the declared size, before anything is inflated, as it would for 3 GB.

mod common;
#[path = "../../tests/common/packaged_fmus.rs"]
mod packaged_fmus;

use common::{failed, s};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

/// A system structure description with one FMU component, `source`.
fn ssd(source: &str, padding: usize) -> String {
    format!(
        r#"<?xml version="1.0" encoding="UTF-8"?>
<ssd:SystemStructureDescription xmlns:ssd="http://ssp-standard.org/SSP1/SystemStructureDescription" version="1.0" name="bomb">
  <!--{}-->
  <ssd:System name="bomb">
    <ssd:Elements>
      <ssd:Component name="big" type="application/x-fmu-sharedlibrary" source="{source}"/>
    </ssd:Elements>
  </ssd:System>
  <ssd:DefaultExperiment startTime="0" stopTime="1"/>
</ssd:SystemStructureDescription>
"#,
        " ".repeat(padding)
    )
}

/// Writes an SSP archive at `path` with `entries` (name, bytes), deflated.
fn write_ssp(path: &Path, entries: &[(&str, &[u8])]) {
    let mut zip = zip::ZipWriter::new(std::fs::File::create(path).unwrap());
    let options = zip::write::SimpleFileOptions::default()
        .compression_method(zip::CompressionMethod::Deflated)
        .large_file(false);
    for (name, bytes) in entries {
        zip.start_file(*name, options).unwrap();
        zip.write_all(bytes).unwrap();
    }
    zip.finish().unwrap();
}

/// `spurio run` on `system` with `extra` flags, TMPDIR at `tmp`, results into `dir`;
/// returns the standard error of the failure and how long the run took.
fn refused_run(dir: &Path, tmp: &Path, system: &Path, extra: &[&str]) -> (String, Duration) {
    let start = Instant::now();
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_spurio"))
        .args(["run", s(system), "--out", s(&dir.join("out.csv"))])
        .args(extra)
        .env("TMPDIR", tmp)
        .output()
        .unwrap();
    let took = start.elapsed();
    (failed(out), took)
}

/// A fresh case folder with an empty `tmp/` for TMPDIR.
fn case(name: &str) -> (PathBuf, PathBuf) {
    let dir = common::temp(&format!("hostile-{name}"));
    let tmp = dir.join("tmp");
    std::fs::create_dir_all(&tmp).unwrap();
    (dir, tmp)
}

fn assert_empty(dir: &Path) {
    let left: Vec<_> = std::fs::read_dir(dir).unwrap().flatten().collect();
    assert!(left.is_empty(), "left in {}: {left:?}", dir.display());
}

#[test]
fn an_ssp_whose_fmu_declares_more_than_max_unpacked_is_refused_before_inflating() {
    let (dir, tmp) = case("ssp-fmu");
    let ssp = dir.join("bomb.ssp");
    let zeros = vec![0u8; 4 << 20];
    write_ssp(
        &ssp,
        &[
            (
                "SystemStructure.ssd",
                ssd("resources/big.fmu", 0).as_bytes(),
            ),
            ("resources/big.fmu", &zeros),
        ],
    );
    assert!(std::fs::metadata(&ssp).unwrap().len() < 64 << 10);
    let (stderr, _) = refused_run(&dir, &tmp, &ssp, &["--max-unpacked", "1M"]);
    for part in [
        "bomb.ssp",
        "its FMUs declare more than 1048576 bytes unpacked",
        "resources/big.fmu",
        "4194304 bytes",
        "max_unpacked",
        "nothing was unpacked",
    ] {
        assert!(stderr.contains(part), "no `{part}` in:\n{stderr}");
    }
    assert!(!stderr.contains("not a valid FMU archive"), "{stderr}");
    assert_empty(&tmp);
    // Kept where --unpack-to says: nothing was written there either.
    let unpacked = dir.join("unpacked");
    let (stderr, _) = refused_run(
        &dir,
        &tmp,
        &ssp,
        &["--max-unpacked", "1M", "--unpack-to", s(&unpacked)],
    );
    assert!(stderr.contains("nothing was unpacked"), "{stderr}");
    assert!(!unpacked.join("resources/big.fmu").exists());
}

#[test]
fn an_ssp_whose_ssd_declares_more_than_max_model_description_is_refused_before_inflating() {
    let (dir, tmp) = case("ssp-ssd");
    let ssp = dir.join("bigssd.ssp");
    let text = ssd("resources/big.fmu", 3 << 20);
    write_ssp(&ssp, &[("SystemStructure.ssd", text.as_bytes())]);
    let (stderr, _) = refused_run(&dir, &tmp, &ssp, &["--max-model-description", "1M"]);
    let declared = format!(
        "SystemStructure.ssd: declares {} bytes unpacked",
        text.len()
    );
    for part in [
        "bigssd.ssp",
        declared.as_str(),
        "more than the limit of 1048576; not inflated",
        "max_model_description",
    ] {
        assert!(stderr.contains(part), "no `{part}` in:\n{stderr}");
    }
    assert_empty(&tmp);
}

#[test]
fn a_system_file_larger_than_max_model_description_is_not_read_past_the_limit() {
    let (dir, tmp) = case("system-file");
    // A regular file: refused by its size.
    let big = dir.join("big.toml");
    std::fs::write(&big, format!("stop_time = 1.0\n#{}\n", " ".repeat(4096))).unwrap();
    let (stderr, _) = refused_run(&dir, &tmp, &big, &["--max-model-description", "1K"]);
    assert!(
        stderr.contains(
            "big.toml: the system file is larger than 1024 bytes (max_model_description); not read"
        ),
        "{stderr}"
    );
    // An endless one: read up to the limit only, so refused at once whatever it holds.
    let (stderr, took) = refused_run(
        &dir,
        &tmp,
        Path::new("/dev/zero"),
        &["--max-model-description", "1M"],
    );
    assert!(
        stderr.contains("/dev/zero: the system file is larger than 1048576 bytes"),
        "{stderr}"
    );
    assert!(took < Duration::from_secs(10), "took {took:?}");
    assert_empty(&tmp);
}

#[test]
fn an_ill_formed_ssd_is_refused_with_its_line_and_an_empty_one_in_ssd_terms() {
    let (dir, tmp) = case("ssd-xml");
    // A valid system whose root is not closed but followed by 10⁵ unclosed elements.
    let unclosed = ssd("resources/a.fmu", 0).replace(
        "</ssd:SystemStructureDescription>\n",
        &"<a>".repeat(100_000),
    );
    let cases: [(&str, String, &[&str]); 3] = [
        (
            "unclosed.ssp",
            unclosed,
            &[
                "SystemStructure.ssd: ill-formed XML at line 10: the text ends with <a> \
                 still open (100001 element(s) unclosed)",
            ],
        ),
        (
            "empty.ssp",
            String::new(),
            &["SystemStructure.ssd: ill-formed XML at line 1: no root element"],
        ),
        (
            "nocomponent.ssp",
            r#"<ssd:SystemStructureDescription version="1.0" name="none"><ssd:System name="none"/></ssd:SystemStructureDescription>"#
                .to_string(),
            &["SystemStructure.ssd: system `none` has no <ssd:Component> (an FMU): nothing to simulate"],
        ),
    ];
    for (name, text, parts) in cases {
        let ssp = dir.join(name);
        write_ssp(&ssp, &[("SystemStructure.ssd", text.as_bytes())]);
        let (stderr, _) = refused_run(&dir, &tmp, &ssp, &[]);
        for part in parts {
            assert!(stderr.contains(part), "{name}: no `{part}` in:\n{stderr}");
        }
        assert!(!stderr.contains("[[instance]]"), "{name}: {stderr}");
    }
    assert_empty(&tmp);
}

/// The lines of an error report with anyhow's cause numbers (`0: `) taken off.
fn messages(stderr: &str) -> Vec<String> {
    stderr
        .lines()
        .map(str::trim)
        .filter(|l| !l.is_empty() && *l != "Caused by:" && !l.starts_with("Stack backtrace"))
        .take_while(|l| !l.starts_with("0: anyhow") && !l.starts_with("at "))
        .map(|l| {
            let l = l.strip_prefix("Error: ").unwrap_or(l);
            match l.split_once(": ") {
                Some((n, rest)) if n.parse::<u32>().is_ok() => rest.to_string(),
                _ => l.to_string(),
            }
        })
        .collect()
}

#[test]
fn every_error_message_is_printed_once() {
    let (dir, tmp) = case("once");
    let write = |name: &str, text: &[u8]| {
        let path = dir.join(name);
        std::fs::write(&path, text).unwrap();
        path
    };
    write("bad.fmu", b"not a zip archive");
    let system = |fmu: &str| {
        format!("stop_time = 1.0\nstep_size = 0.1\n[[instance]]\nname = \"a\"\nfmu = \"{fmu}\"\n")
    };
    let not_zip = write("not_zip.toml", system("bad.fmu").as_bytes());
    let missing = write("missing.toml", system("nowhere.fmu").as_bytes());
    let bad_ssp = dir.join("bad_fmu.ssp");
    write_ssp(
        &bad_ssp,
        &[
            (
                "SystemStructure.ssd",
                ssd("resources/bad.fmu", 0).as_bytes(),
            ),
            ("resources/bad.fmu", b"not a zip archive"),
        ],
    );
    let csv = write("results.csv", b"\"time\",\"x\"\n0.0,abc\n");
    let cases: Vec<(&str, Vec<String>)> = vec![
        ("not a zip", vec!["run".into(), s(&not_zip).into()]),
        ("missing FMU", vec!["run".into(), s(&missing).into()]),
        (
            "FMU in an SSP not a zip",
            vec!["run".into(), s(&bad_ssp).into()],
        ),
        (
            "sweep over a missing FMU",
            vec![
                "sweep".into(),
                s(&missing).into(),
                "--vary".into(),
                "a.seed=1,2".into(),
                "--metric".into(),
                "rms(a.x)".into(),
            ],
        ),
        (
            "merge shards that are not there",
            vec!["sweep-merge".into(), s(&dir.join("no-shards.toml")).into()],
        ),
        (
            "diagnose a missing file",
            vec![
                "diagnose".into(),
                "--column".into(),
                "x".into(),
                s(&dir.join("none.csv")).into(),
            ],
        ),
        (
            "diagnose a bad number",
            vec![
                "diagnose".into(),
                "--column".into(),
                "x".into(),
                s(&csv).into(),
            ],
        ),
    ];
    for (what, args) in cases {
        let out = std::process::Command::new(env!("CARGO_BIN_EXE_spurio"))
            .args(&args)
            .env("TMPDIR", &tmp)
            .env("RUST_BACKTRACE", "0")
            .output()
            .unwrap();
        let stderr = failed(out);
        let lines = messages(&stderr);
        assert!(!lines.is_empty(), "{what}: {stderr}");
        for (i, line) in lines.iter().enumerate() {
            if let Some(earlier) = lines[..i].iter().find(|e| e.contains(line.as_str())) {
                panic!("{what}: `{line}` is said again (after `{earlier}`):\n{stderr}");
            }
        }
        // No temporary path of an unpacked archive leaks into the message.
        assert!(!stderr.contains("spurio-ssp-"), "{what}: {stderr}");
    }
}

/// An FMU's message printed as it logs it (`[name] ERROR: …`) is not quoted again by the
/// error of the call that failed: the error points to it. FMI 2.0 and 3.0, a failed step
/// (LinearSystem's step too long to discretise) and a failed first read of the outputs.
#[test]
fn what_an_fmu_logged_is_said_once_with_the_failure() {
    common::require_fmus(&["LinearSystem"]);
    let (dir, tmp) = case("logged-once");
    let fmus = common::repo().join("build/fmus");
    let cases: [(&str, &[&str], &str); 2] = [
        (
            "a step too long to discretise",
            &[
                "--set",
                "continuous=true",
                "--set",
                "B[1,1]=0.854",
                "--step-size",
                "1e308",
                "--stop-time",
                "1e308",
            ],
            "cannot discretise",
        ),
        (
            "a negative variance",
            &["--set", "Q[1,1]=-1"],
            "negative variance -1",
        ),
    ];
    for fmu in [
        fmus.join("LinearSystem.fmu"),
        fmus.join("fmi3/LinearSystem.fmu"),
    ] {
        for (what, flags, message) in cases {
            let out = std::process::Command::new(env!("CARGO_BIN_EXE_spurio"))
                .args(["run", s(&fmu), "--out", s(&dir.join("out.csv"))])
                .args(flags)
                .env("TMPDIR", &tmp)
                .env("RUST_BACKTRACE", "0")
                .output()
                .unwrap();
            let stderr = failed(out);
            assert_eq!(
                stderr.matches(message).count(),
                1,
                "{}, {what}: `{message}` is said more than once:\n{stderr}",
                fmu.display()
            );
            assert!(
                stderr.contains("the FMU's message is printed above"),
                "{}, {what}:\n{stderr}",
                fmu.display()
            );
            assert_empty(&tmp);
        }
    }
}
