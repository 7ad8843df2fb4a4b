//! What the engine's integration tests (and the CLI's, which include this file) share: the
//! packaged FMUs (`scripts/build-fmus`), an FMU that misbehaves on purpose, systems written as
//! TOML, running a system into memory, and checking error messages.

#![allow(dead_code)]

use spurio_master::TimeSeries;
use spurio_master::{RunEnd, RunOptions, Simulation};
use spurio_master::{System, SystemDescription, SystemError};
use std::io::{Read, Write};
use std::path::{Path, PathBuf};

pub mod packaged_fmus;

/// The `master/` folder (this file serves the engine's tests and, included by path, the
/// CLI's).
fn master_dir() -> PathBuf {
    let manifest = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    match manifest.parent() {
        Some(master) if manifest.ends_with("cli") => master.to_path_buf(),
        _ => manifest,
    }
}

/// The folder of the packaged FMUs, built first if they are missing ([`packaged_fmus`]).
pub fn fmus() -> PathBuf {
    packaged_fmus::packaged_fmus(&master_dir().join(".."))
}

/// The Reference FMUs of FMI `version` (`fmi2`, `fmi3`) in the third-party folder: the
/// repository's `tests/third_party/` (its README says what each is and where it came from),
/// or the folder `SPURIO_THIRD_PARTY` names.
pub fn reference(version: &str, model: &str) -> PathBuf {
    let third_party = std::env::var_os("SPURIO_THIRD_PARTY")
        .map(PathBuf::from)
        .unwrap_or_else(|| master_dir().join("../tests/third_party"));
    let fmu = third_party
        .join("reference-fmus")
        .join(version)
        .join(format!("{model}.fmu"));
    assert!(fmu.is_file(), "{} is missing", fmu.display());
    fmu
}

/// The packaged GantryCrane.fmu.
pub fn crane() -> PathBuf {
    fmus().join("GantryCrane.fmu")
}

/// Bytes of a copy of `source` with each entry passed through `edit` (None drops it) and
/// `extra` entries appended (name, data, Unix mode; a mode of 0o120777 writes a symlink).
pub fn rewrite(
    source: &Path,
    edit: impl Fn(&str, Vec<u8>) -> Option<Vec<u8>>,
    extra: &[(&str, &[u8], u32)],
) -> Vec<u8> {
    let mut archive = zip::ZipArchive::new(std::fs::File::open(source).unwrap()).unwrap();
    let mut out = zip::ZipWriter::new(std::io::Cursor::new(Vec::new()));
    let options = zip::write::SimpleFileOptions::default();
    for i in 0..archive.len() {
        let mut entry = archive.by_index(i).unwrap();
        let name = entry.name().unwrap().to_string();
        let mut data = Vec::new();
        entry.read_to_end(&mut data).unwrap();
        if let Some(data) = edit(&name, data) {
            out.start_file(name, options).unwrap();
            out.write_all(&data).unwrap();
        }
    }
    for (name, data, mode) in extra {
        if *mode == 0o120_777 {
            out.add_symlink(*name, std::str::from_utf8(data).unwrap(), options)
                .unwrap();
        } else {
            out.start_file(*name, options.unix_permissions(*mode))
                .unwrap();
            out.write_all(data).unwrap();
        }
    }
    out.finish().unwrap().into_inner()
}

/// The bytes of the shared library of `fixtures/<source>`, compiled in `dir` with `cc -shared
/// -fPIC -O1` (and `-lm`).
pub fn compiled_fixture(source: &str, dir: &Path) -> Vec<u8> {
    let library = dir.join(format!("{source}.so"));
    let cc = std::process::Command::new("cc")
        .args(["-shared", "-fPIC", "-O1", "-o"])
        .arg(&library)
        .arg(master_dir().join("tests/fixtures").join(source))
        .arg("-lm")
        .output()
        .expect("a C compiler (cc) builds the fixture");
    assert!(
        cc.status.success(),
        "{}",
        String::from_utf8_lossy(&cc.stderr)
    );
    let so = std::fs::read(&library).unwrap();
    std::fs::remove_file(&library).unwrap();
    so
}

/// `<dir>/Bad.fmu`: the packaged GantryCrane's model description over the library of
/// `fixtures/misbehaving.c` (compiled with `cc`), which misbehaves in `fmi2DoStep` as the
/// `MISBEHAVE*` environment variables say (see that file); the FMU has no other binary.
pub fn misbehaving_fmu(dir: &Path) -> PathBuf {
    let so = compiled_fixture("misbehaving.c", dir);
    let library_entry = "binaries/linux64/GantryCrane.so";
    let bytes = rewrite(
        &crane(),
        |name, data| match name {
            n if n == library_entry => Some(so.clone()),
            n if n.starts_with("binaries/") => None,
            _ => Some(data),
        },
        &[],
    );
    let path = dir.join("Bad.fmu");
    std::fs::write(&path, bytes).unwrap();
    path
}

/// The system a TOML text describes, its FMUs taken from [`fmus`].
pub fn resolve(toml_text: &str) -> Result<System, SystemError> {
    let description: SystemDescription = toml::from_str(toml_text).unwrap();
    System::resolve(&description, &fmus())
}

/// A GantryCrane (`crane`, with the inline parameter table `crane_parameters`) measured by a
/// Sensor2 (`sensor`) for `stop_time` s at 0.01 s, recording the cart position and the
/// sensor's measured and clean first values.
pub fn crane_sensor(stop_time: f64, crane_parameters: &str) -> System {
    resolve(&format!(
        r#"
        stop_time = {stop_time:?}
        step_size = 0.01
        connections = ["crane.x -> sensor.u[1]", "crane.theta -> sensor.u[2]"]
        record = ["crane.x", "sensor.y[1]", "sensor.y_clean[1]"]
        {}"#,
        instance_tables(&[
            ("crane", Path::new("GantryCrane.fmu"), crane_parameters),
            ("sensor", Path::new("Sensor2.fmu"), ""),
        ])
    ))
    .unwrap()
}

/// The `[[instance]]` tables of a system's TOML, one for each (name, FMU, parameters: the
/// inside of an inline table, e.g. `x0 = 0.1, "u[2]" = 5.0`, empty for none).
pub fn instance_tables(instances: &[(&str, &Path, &str)]) -> String {
    instances
        .iter()
        .map(|(name, fmu, parameters)| {
            let mut table = format!(
                "[[instance]]\nname = \"{name}\"\nfmu = \"{}\"\n",
                fmu.display()
            );
            if !parameters.is_empty() {
                table += &format!("parameters = {{ {parameters} }}\n");
            }
            table
        })
        .collect()
}

/// Runs `system` into memory with `options`, then terminates it.
pub fn run(system: &System, options: &RunOptions) -> (TimeSeries, RunEnd) {
    let mut sim = Simulation::new(system).unwrap();
    let mut series = TimeSeries::default();
    let end = sim.run(&mut series, options).unwrap();
    sim.terminate().unwrap();
    (series, end)
}

/// Asserts that the message `text` names every one of `parts`.
pub fn assert_names(text: &str, parts: &[&str]) {
    for part in parts {
        assert!(text.contains(part), "no `{part}` in: {text}");
    }
}

/// Asserts that the temporary folder `tmp` is empty and that `dir` holds nothing but the
/// files `expected` besides it: what a refused FMU or an ended run may leave behind.
pub fn assert_only_left(dir: &Path, tmp: &Path, expected: &[&str]) {
    let left: Vec<_> = std::fs::read_dir(tmp)
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert!(left.is_empty(), "left in the temp folder: {left:?}");
    let mut found: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p != tmp)
        .map(|p| p.file_name().unwrap().to_string_lossy().into_owned())
        .collect();
    found.sort();
    let mut expected: Vec<String> = expected.iter().map(|s| s.to_string()).collect();
    expected.sort();
    assert_eq!(found, expected, "written outside the temp folder");
}
