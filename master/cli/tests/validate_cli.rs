//! `spurio validate` and `spurio info` on any FMU: our FMUs (FMI 2.0 and 3.0) and every
//! Reference FMU pass (the Reference FMUs' one known flaw, Roberts' DAE manifest, is a
//! warning that says why); what is not an FMU is an error. The hand-made defects, each
//! refused with its message, are `defects.rs`.

#[path = "../../tests/common/mod.rs"]
mod engine;

use engine::{assert_names, fmus, reference};
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn spurio(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_spurio"))
        .args(args)
        .output()
        .unwrap()
}

fn validate(fmu: &Path) -> Output {
    spurio(&["validate", fmu.to_str().unwrap()])
}

fn stdout(out: &Output) -> String {
    String::from_utf8_lossy(&out.stdout).into_owned()
}

/// The FMUs of `dir`.
fn fmus_in(dir: &Path) -> Vec<PathBuf> {
    let mut found: Vec<PathBuf> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "fmu"))
        .collect();
    found.sort();
    found
}

/// Asserts that every FMU in `dir` validates (exit 0, no error) and returns how many there are
/// and the reports that carry a warning.
fn all_valid(dir: &Path) -> (usize, Vec<(String, String)>) {
    let mut warned = Vec::new();
    let found = fmus_in(dir);
    for fmu in &found {
        let out = validate(fmu);
        let report = stdout(&out);
        assert!(
            out.status.success() && !report.contains("error:"),
            "{}:\n{report}{}",
            fmu.display(),
            String::from_utf8_lossy(&out.stderr)
        );
        assert!(report.contains("valid FMI"), "{report}");
        if report.contains("warning:") {
            let name = fmu.file_stem().unwrap().to_string_lossy().into_owned();
            warned.push((name, report));
        }
    }
    (found.len(), warned)
}

#[test]
fn our_fmus_are_valid_in_both_versions() {
    let dir = fmus();
    // One FMU of each version for every committed model description.
    let committed = |sub: &str| {
        std::fs::read_dir(dir.join("../../modelDescription").join(sub))
            .unwrap()
            .filter(|e| {
                e.as_ref()
                    .unwrap()
                    .path()
                    .extension()
                    .is_some_and(|x| x == "xml")
            })
            .count()
    };
    let (fmi2, warned2) = all_valid(&dir);
    let (fmi3, warned3) = all_valid(&dir.join("fmi3"));
    assert!(fmi2 >= committed("") && fmi2 >= 25, "{fmi2} FMI 2.0 FMUs");
    assert!(
        fmi3 >= committed("fmi3") && fmi3 >= 25,
        "{fmi3} FMI 3.0 FMUs"
    );
    assert_eq!(warned2.len() + warned3.len(), 0, "{warned2:?} {warned3:?}");
}

#[test]
fn the_reference_fmus_are_valid_their_draft_manifests_warned_of() {
    let folder = |version| {
        reference(version, "BouncingBall")
            .parent()
            .unwrap()
            .to_path_buf()
    };
    let (fmi2, warned2) = all_valid(&folder("fmi2"));
    let (fmi3, warned3) = all_valid(&folder("fmi3"));
    assert_eq!((fmi2, fmi3), (6, 9));
    // Every one but Clocks carries reference results whose fmi-ls-ref manifest follows the
    // draft 1.0.0-alpha.1, not the schema of 1.0.0-rc.1: two warnings each.
    let names = |warned: &[(String, String)]| -> Vec<String> {
        warned.iter().map(|(name, _)| name.clone()).collect()
    };
    let all_but_clocks = |version| -> Vec<String> {
        let stems = fmus_in(&folder(version)).into_iter();
        let stems = stems.map(|p| p.file_stem().unwrap().to_string_lossy().into_owned());
        stems.filter(|stem| stem != "Clocks").collect()
    };
    assert_eq!(names(&warned2), all_but_clocks("fmi2"));
    assert_eq!(names(&warned3), all_but_clocks("fmi3"));
    assert_eq!(warned2.len() + warned3.len(), 6 + 8);
    for (name, report) in warned2.iter().chain(&warned3) {
        let draft = "(the manifest declares fmi-ls-ref version \"1.0.0-alpha.1\"; the schema is of version 1.0.0-rc.1, so this is a warning";
        assert_eq!(report.matches(draft).count(), 2, "{name}: {report}");
    }
    // Roberts' fmi-ls-dae manifest also calls the layered standard "fmi-ls-dae" in the folder
    // extra/org.fmi-standard.fmi-ls-dae/ and gives it an empty version.
    let roberts = &warned3[names(&warned3).iter().position(|n| n == "Roberts").unwrap()].1;
    assert_names(
        roberts,
        &[
            "warning: line 2: extra/org.fmi-standard.fmi-ls-dae/fmi-ls-manifest.xml: fmi-ls:fmi-ls-name is \"fmi-ls-dae\"",
            "fmi-ls:fmi-ls-version is empty",
            "valid FMI 3.0 (the standard's schema and rules), 4 warning(s)",
        ],
    );
}

/// An archive at `path` with the one entry `modelDescription.xml`, deflated.
fn archive_with_description(path: &Path, text: &[u8]) {
    use std::io::Write;
    let mut zip = zip::ZipWriter::new(std::fs::File::create(path).unwrap());
    let options = zip::write::SimpleFileOptions::default()
        .compression_method(zip::CompressionMethod::Deflated);
    zip.start_file("modelDescription.xml", options).unwrap();
    zip.write_all(text).unwrap();
    zip.finish().unwrap();
}

#[test]
fn what_is_not_a_readable_fmu_is_an_error_not_a_report() {
    let dir = std::env::temp_dir().join(format!("spurio-validate-bad-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let plain = dir.join("plain.fmu");
    std::fs::write(&plain, b"not a zip").unwrap();
    // A model description that inflates beyond 64 MiB (65 MiB of spaces, 65 KiB deflated).
    let bomb = dir.join("bomb.fmu");
    archive_with_description(&bomb, &vec![b' '; 65 << 20]);
    // An entity that expands a billion times: refused with the DTD, never expanded.
    let laughs = dir.join("laughs.fmu");
    let dtd = r#"<?xml version="1.0"?><!DOCTYPE m [<!ENTITY a "aaaaaaaaaa"><!ENTITY b "&a;&a;&a;&a;&a;&a;&a;&a;&a;&a;">]><fmiModelDescription fmiVersion="2.0" modelName="&b;"/>"#;
    archive_with_description(&laughs, dtd.as_bytes());
    let cases = [
        (
            &plain,
            "plain.fmu: not an FMU archive (an FMU is a zip file)",
        ),
        (
            &bomb,
            "bomb.fmu: modelDescription.xml is larger than 67108864 bytes",
        ),
        (
            &laughs,
            "laughs.fmu: modelDescription.xml is not well-formed XML",
        ),
    ];
    for (fmu, message) in cases {
        for command in ["validate", "info"] {
            let started = std::time::Instant::now();
            let out = spurio(&[command, fmu.to_str().unwrap()]);
            let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
            assert_eq!(out.status.code(), Some(1), "{stderr}");
            assert_names(&stderr, &[message]);
            assert_eq!(stderr.matches(message).count(), 1, "said once: {stderr}");
            assert!(!stderr.contains("Caused by"), "{stderr}");
            assert!(started.elapsed().as_secs_f64() < 5.0, "{command} {message}");
        }
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn info_lists_every_variable_with_its_attributes() {
    let ball = reference("fmi3", "BouncingBall");
    let out = spurio(&["info", ball.to_str().unwrap()]);
    let text = stdout(&out);
    assert!(out.status.success(), "{text}");
    assert_names(
        &text,
        &[
            "FMI version          3.0",
            "interfaces           ModelExchange (BouncingBall), CoSimulation (BouncingBall)",
            "instantiation token  {1AE5E10D-9521-4DE3-80B9-D0EAAA7D5AF1}",
            "platforms            x86_64-linux",
            "C sources            true",
            "default experiment   startTime 0, stepSize 1e-2, stopTime 3",
            "variables            9",
        ],
    );
    let row = |name: &str| -> Vec<String> {
        let line = text
            .lines()
            .find(|l| l.split_whitespace().next() == Some(name))
            .unwrap_or_else(|| panic!("no row {name} in {text}"));
        line.split_whitespace().map(str::to_string).collect()
    };
    // name, value reference, causality, variability, initial, type, unit, start, min, max,
    // alias of, description…
    let e = [
        "e",
        "6",
        "parameter",
        "tunable",
        "exact",
        "Float64",
        "-",
        "0.7",
        "0.5",
        "1",
        "-",
    ];
    assert_eq!(row("e")[..11], e);
    assert_eq!(
        row("g")[..8],
        [
            "g",
            "5",
            "parameter",
            "fixed",
            "exact",
            "Float64",
            "m/s2",
            "-9.81"
        ]
    );
    assert_eq!(
        row("h_ft")[..11],
        [
            "h_ft",
            "1",
            "output",
            "continuous",
            "exact",
            "Float64",
            "m",
            "1",
            "-",
            "-",
            "h"
        ]
    );
    // An FMI 3.0 array of ours shows its extent.
    let kalman = fmus().join("fmi3/DualKalmanFilter.fmu");
    let text = stdout(&spurio(&["info", kalman.to_str().unwrap()]));
    assert!(
        text.lines()
            .any(|l| l.contains("A_hat") && l.contains("Float64[4,4]")),
        "{text}"
    );
}
