//! Malformed FMUs, each built from a packaged one (`scripts/build-fmus`) or from scratch: the
//! loader refuses each with a message naming the FMU and what is wrong, writes nothing outside
//! the temporary folder it is pointed at and leaves that folder empty; `spurio run` on a
//! system using such an FMU exits with 1 and the message (never Rust's panic exit 101).

mod common;

use common::{assert_names, crane, rewrite};
use spurio_master::fmu::{FmuFile, LoadError, LoadLimits, LoadOptions};
use std::path::{Path, PathBuf};
use std::process::Command;

/// A fresh folder for one case: the bad FMU goes in it, `tmp/` is the loader's temp folder.
struct Case {
    dir: PathBuf,
    tmp: PathBuf,
}

impl Case {
    fn new(name: &str) -> Self {
        let dir =
            std::env::temp_dir().join(format!("spurio-malformed-{}-{name}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        let tmp = dir.join("tmp");
        std::fs::create_dir_all(&tmp).unwrap();
        Case { dir, tmp }
    }

    fn fmu(&self, name: &str) -> PathBuf {
        self.dir.join(name)
    }

    fn options(&self) -> LoadOptions {
        LoadOptions {
            limits: LoadLimits::default(),
            temp_dir: Some(self.tmp.clone()),
        }
    }

    /// Loads `fmu`, expects an error, and checks that the temp folder is empty and that the
    /// case folder holds nothing but `expected` files besides `tmp/`.
    fn refuse(&self, fmu: &Path, options: &LoadOptions, expected: &[&str]) -> LoadError {
        let e = match FmuFile::open_with(fmu, options) {
            Ok(f) => panic!("{} was loaded: {:?}", fmu.display(), f),
            Err(e) => e,
        };
        self.assert_clean(expected);
        e
    }

    /// Writes `bytes` as the FMU `name` in the case folder and loads it with `options`,
    /// expecting a refusal (see [`Case::refuse`]) whose message names the FMU; returns the
    /// error and its message.
    fn refuse_bytes(&self, name: &str, bytes: &[u8], options: &LoadOptions) -> (LoadError, String) {
        let fmu = self.fmu(name);
        std::fs::write(&fmu, bytes).unwrap();
        let e = self.refuse(&fmu, options, &[name]);
        let text = e.to_string();
        assert!(text.contains(name), "{text}");
        (e, text)
    }

    fn assert_clean(&self, expected: &[&str]) {
        common::assert_only_left(&self.dir, &self.tmp, expected);
    }

    /// Runs `spurio run` on a one-instance system using `fmu`, with TMPDIR at the temp folder;
    /// returns the exit code and stderr.
    fn run_cli(&self, fmu: &str) -> (Option<i32>, String) {
        let system = self.dir.join("system.toml");
        std::fs::write(
            &system,
            format!(
                "stop_time = 0.1\nstep_size = 0.01\n[[instance]]\nname = \"bad\"\nfmu = \"{fmu}\"\n"
            ),
        )
        .unwrap();
        let out = Command::new(spurio())
            .arg("run")
            .arg(&system)
            .arg("--out")
            .arg(self.dir.join("out.csv"))
            .env("TMPDIR", &self.tmp)
            .output()
            .unwrap();
        std::fs::remove_file(&system).unwrap();
        (
            out.status.code(),
            String::from_utf8_lossy(&out.stderr).into_owned(),
        )
    }
}

impl Drop for Case {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.dir);
    }
}

/// The `spurio` binary of the same build profile as this test, or else the release one that
/// building the packaged FMUs leaves ([`common::fmus`]).
fn spurio() -> PathBuf {
    let exe = std::env::current_exe().unwrap();
    let profile = exe.parent().unwrap().parent().unwrap();
    let bin = profile.join("spurio");
    if bin.is_file() {
        return bin;
    }
    common::fmus();
    let release = profile.parent().unwrap().join("release/spurio");
    assert!(release.is_file(), "{} is missing", release.display());
    release
}

const LIBRARY: &str = "binaries/linux64/GantryCrane.so";

/// GantryCrane.fmu's bytes with `from` replaced by `to` in its model description (which
/// must hold `from`, so that every edit is sure to take effect).
fn crane_with_xml(from: &str, to: &str) -> Vec<u8> {
    with_xml(&crane(), from, to)
}

/// The bytes of the FMU `source` with `from` replaced by `to` in its model description.
fn with_xml(source: &Path, from: &str, to: &str) -> Vec<u8> {
    let edit = |name: &str, data: Vec<u8>| {
        Some(if name == "modelDescription.xml" {
            let xml = String::from_utf8(data).unwrap();
            assert!(xml.contains(from), "`{from}` is in the model description");
            xml.replace(from, to).into_bytes()
        } else {
            data
        })
    };
    rewrite(source, edit, &[])
}

/// GantryCrane.fmu's bytes with its Linux library passed through `f`.
fn crane_with_library(f: impl Fn(Vec<u8>) -> Vec<u8>) -> Vec<u8> {
    rewrite(
        &crane(),
        |name, data| Some(if name == LIBRARY { f(data) } else { data }),
        &[],
    )
}

/// GantryCrane.fmu's bytes with `extra` entries appended (see [`rewrite`]).
fn crane_with_entries(extra: &[(&str, &[u8], u32)]) -> Vec<u8> {
    rewrite(&crane(), |_, data| Some(data), extra)
}

fn replace_all(data: &[u8], from: &[u8], to: &[u8]) -> (Vec<u8>, usize) {
    assert_eq!(from.len(), to.len());
    let mut out = data.to_vec();
    let mut count = 0;
    let mut i = 0;
    while i + from.len() <= out.len() {
        if &out[i..i + from.len()] == from {
            out[i..i + from.len()].copy_from_slice(to);
            count += 1;
            i += from.len();
        } else {
            i += 1;
        }
    }
    (out, count)
}

#[test]
fn the_good_fmu_unpacks_in_the_given_folder_and_leaves_it_clean() {
    let case = Case::new("good");
    let fmu = FmuFile::open_with(&crane(), &case.options()).unwrap();
    let inside: Vec<_> = std::fs::read_dir(&case.tmp).unwrap().collect();
    assert_eq!(inside.len(), 1, "one unpacked FMU folder");
    assert_eq!(fmu.variable("theta").unwrap().head.value_reference, 2);
    assert_eq!(
        fmu.variable("U_applied").unwrap().dependencies,
        Some(vec![0])
    );
    drop(fmu);
    case.assert_clean(&[]);
}

#[test]
fn symlink_to_a_library_outside_the_archive_is_refused() {
    let case = Case::new("symlink");
    // The library the link points at, outside the archive.
    let outside = case.dir.join("outside.so");
    std::fs::copy(crane(), &outside).unwrap();
    let bytes = rewrite(
        &crane(),
        |name, data| (name != LIBRARY).then_some(data),
        &[(LIBRARY, outside.to_str().unwrap().as_bytes(), 0o120_777)],
    );
    let fmu = case.fmu("Symlink.fmu");
    std::fs::write(&fmu, bytes).unwrap();
    let e = case.refuse(&fmu, &case.options(), &["Symlink.fmu", "outside.so"]);
    assert!(matches!(e, LoadError::UnsafeEntry { .. }), "{e}");
    let text = e.to_string();
    assert_names(
        &text,
        &["Symlink.fmu", &format!("`{LIBRARY}`"), "symbolic link"],
    );
    let (code, stderr) = case.run_cli("Symlink.fmu");
    assert_eq!(code, Some(1), "{stderr}");
    assert!(stderr.contains("symbolic link"), "{stderr}");
    case.assert_clean(&["Symlink.fmu", "outside.so"]);
}

#[test]
fn entries_that_are_not_plain_files_or_folders_are_refused() {
    let case = Case::new("fifo");
    // A named pipe (S_IFIFO).
    let bytes = crane_with_entries(&[("resources/pipe", b"", 0o100_644)]);
    let bytes = set_unix_mode(bytes, "resources/pipe", 0o010_644);
    let (_, text) = case.refuse_bytes("Fifo.fmu", &bytes, &case.options());
    assert_names(
        &text,
        &[
            "`resources/pipe`",
            "not a plain file or folder (Unix mode 10644)",
        ],
    );
}

#[test]
fn absolute_entries_are_refused_not_re_rooted() {
    let case = Case::new("absolute");
    let target = case.dir.join("planted.txt");
    let bytes = crane_with_entries(&[(target.to_str().unwrap(), b"planted", 0o100_644)]);
    let (_, text) = case.refuse_bytes("Absolute.fmu", &bytes, &case.options());
    assert!(text.contains("absolute path"), "{text}");
}

#[test]
fn missing_entry_point_is_named_not_a_panic() {
    let case = Case::new("entry");
    let bytes = crane_with_library(|lib| {
        // Rename the exported symbol in the dynamic string table (same length).
        let (lib, n) = replace_all(&lib, b"\0fmi2DoStep\0", b"\0fmi2DoStoq\0");
        assert!(n >= 1, "fmi2DoStep not found in the library");
        lib
    });
    let (e, text) = case.refuse_bytes("NoDoStep.fmu", &bytes, &case.options());
    match &e {
        LoadError::MissingFunctions { missing, .. } => assert_eq!(missing, &["fmi2DoStep"]),
        other => panic!("{other}"),
    }
    assert_names(&text, &[LIBRARY, "fmi2DoStep"]);
    let (code, stderr) = case.run_cli("NoDoStep.fmu");
    assert_eq!(code, Some(1), "{stderr}");
    assert!(
        stderr.contains("does not export fmi2DoStep") && !stderr.contains("panicked"),
        "{stderr}"
    );
    case.assert_clean(&["NoDoStep.fmu"]);
}

#[test]
fn library_for_another_architecture_is_named() {
    let case = Case::new("arch");
    let bytes = crane_with_library(|mut lib| {
        // e_machine (ELF header offset 18, little-endian): 183 = AArch64.
        lib[18..20].copy_from_slice(&183u16.to_le_bytes());
        lib
    });
    let (e, text) = case.refuse_bytes("Arm.fmu", &bytes, &case.options());
    assert!(matches!(e, LoadError::WrongBinary { .. }), "{e}");
    assert!(
        text.contains("is an ELF shared library for aarch64 (64-bit)")
            && text.contains(&format!(
                "needs an ELF shared library for {}",
                std::env::consts::ARCH
            ))
            && !text.contains("No such file"),
        "{text}"
    );
    let (code, stderr) = case.run_cli("Arm.fmu");
    assert_eq!(code, Some(1), "{stderr}");
    assert!(stderr.contains("aarch64"), "{stderr}");
    case.assert_clean(&["Arm.fmu"]);
}

#[test]
fn file_that_is_not_a_library_is_named() {
    let case = Case::new("notelf");
    let bytes = crane_with_library(|_| b"this is not a shared library\n".to_vec());
    let (_, text) = case.refuse_bytes("Text.fmu", &bytes, &case.options());
    assert!(
        text.contains("is a text file, not a shared library"),
        "{text}"
    );
}

#[test]
fn damaged_zip_is_not_a_valid_fmu_archive() {
    let case = Case::new("zip");
    let good = std::fs::read(crane()).unwrap();
    let fmu = case.fmu("Truncated.fmu");
    std::fs::write(&fmu, &good[..good.len() / 2]).unwrap();
    let e = case.refuse(&fmu, &case.options(), &["Truncated.fmu"]);
    assert!(matches!(e, LoadError::NotZip { .. }), "{e}");
    let text = e.to_string();
    assert_names(
        &text,
        &[
            "Truncated.fmu",
            "not a valid FMU archive (an FMU is a zip file)",
        ],
    );
    let (code, stderr) = case.run_cli("Truncated.fmu");
    assert_eq!(code, Some(1), "{stderr}");
    assert!(stderr.contains("not a valid FMU archive"), "{stderr}");
    case.assert_clean(&["Truncated.fmu"]);
}

fn refuse_xml(case_name: &str, from: &str, to: &str) -> String {
    let case = Case::new(case_name);
    let bytes = crane_with_xml(from, to);
    let (e, text) = case.refuse_bytes("Bad.fmu", &bytes, &case.options());
    assert!(matches!(e, LoadError::ModelDescription { .. }), "{e}");
    assert!(text.contains("Bad.fmu: modelDescription.xml"), "{text}");
    text
}

/// [`refuse_xml`] for each `(case, text replaced, its replacement, what the refusal must
/// say)`; no refusal names rust-fmi's Rust types or fields for the standard's elements.
fn refuse_each(cases: &[(&str, &str, &str, &str)]) {
    for (case_name, from, to, expected) in cases {
        let text = refuse_xml(case_name, from, to);
        assert!(text.contains(expected), "{case_name}: {text}");
        for internal in [
            "Fmi2",
            "value_reference",
            "model_identifier",
            "missing field",
        ] {
            assert!(
                !text.contains(internal),
                "{case_name}: `{internal}` in {text}"
            );
        }
    }
}

#[test]
fn model_descriptions_with_an_inconsistency_are_refused_with_the_reason() {
    // (case, text replaced, its replacement, what the refusal must say)
    let cases = [
        (
            "dupname",
            "name=\"theta\"",
            "name=\"x\"",
            "two variables are called `x` (variables 2 and 3 of ModelVariables)",
        ),
        // `m` (vr 7) moved onto `M`'s vr 6: two start values for one value.
        (
            "alias",
            "name=\"m\" valueReference=\"7\"",
            "name=\"m\" valueReference=\"6\"",
            "variables `M` (parameter) and `m` (parameter) share value reference 6 (Real) and both have a start value",
        ),
        (
            "index",
            "<Unknown index=\"6\" dependencies=\"1\"/>",
            "<Unknown index=\"99\" dependencies=\"1\"/>",
            "ModelStructure/Outputs: index 99 is out of range (ModelVariables has 28 variables",
        ),
        (
            "dependency",
            "<Unknown index=\"6\" dependencies=\"1\"/>",
            "<Unknown index=\"6\" dependencies=\"0\"/>",
            "a dependency of `U_applied` 0 is out of range",
        ),
        (
            "notoutput",
            "<Unknown index=\"6\" dependencies=\"1\"/>",
            "<Unknown index=\"7\" dependencies=\"1\"/>",
            "index 7 is `M`, whose causality is parameter, not output",
        ),
    ];
    refuse_each(&cases);
}

#[test]
fn a_wrong_fmi_version_and_an_unknown_unit_child_are_said_in_the_standard_s_terms() {
    // fmiVersion 3.0 on an FMI 2.0 description: the version is read first, then the mismatch.
    let text = refuse_xml("fmi3version", "fmiVersion=\"2.0\"", "fmiVersion=\"3.0\"");
    assert!(
        text.contains(
            "fmiVersion is `3.0`, but the description is FMI 2.0: it declares its variables \
             as <ScalarVariable>"
        ),
        "{text}"
    );
    assert!(!text.contains("has no name"), "{text}");
    // An unknown child of <Unit>: the element, not rust-fmi's type for it, and what it allows.
    let text = refuse_xml(
        "unitchild",
        "<Unit name=\"N\">",
        "<Unit name=\"N\">\n      <Scale factor=\"2\"/>",
    );
    assert!(
        text.contains(
            "<Unit> has `Scale`, which FMI 2.0 does not allow there (allowed: the attribute \
             name and the elements <BaseUnit> (at most one) and <DisplayUnit>)"
        ),
        "{text}"
    );
    assert!(!text.contains("Fmi2Unit"), "{text}");
}

/// Every refusal of an FMI 2.0 description speaks the standard's element and attribute
/// names (never rust-fmi's Rust types or fields: `Fmi2Unit`, `value_reference`), a version
/// that does not match the description's shape says so, and ill-formed XML names its line.
#[test]
fn model_description_refusals_name_the_standard_s_elements_attributes_and_lines() {
    // (case, text replaced, its replacement, what the refusal must say)
    let cases = [
        (
            "unitname",
            "<Unit name=\"N\">",
            "<Unit>",
            "<Unit> has no `name`, which FMI 2.0 requires there",
        ),
        (
            "valuereference",
            "name=\"x\" valueReference=\"1\"",
            "name=\"x\"",
            "<ScalarVariable> has no `valueReference`, which FMI 2.0 requires there",
        ),
        (
            "modelidentifier",
            "<CoSimulation modelIdentifier=\"GantryCrane\"",
            "<CoSimulation",
            "<CoSimulation> has no `modelIdentifier`, which FMI 2.0 requires there",
        ),
        (
            "guid",
            "guid=\"{ae27508b-3946-7ebc-ec7a-9503eda8c018}\"",
            "",
            "<fmiModelDescription> has no `guid`, which FMI 2.0 requires there",
        ),
        (
            "mismatched",
            "</UnitDefinitions>",
            "</UnitDefinition>",
            "ill-formed XML at line ",
        ),
    ];
    refuse_each(&cases);
    // An FMI 3.0 description that says fmiVersion 2.0, and a version of neither.
    let fmi3 = common::fmus().join("fmi3/GantryCrane.fmu");
    let with_version = |version: &str| with_xml(&fmi3, "fmiVersion=\"3.0\"", version);
    let case = Case::new("version-shape");
    let (_, text) = case.refuse_bytes(
        "Shape.fmu",
        &with_version("fmiVersion=\"2.0\""),
        &case.options(),
    );
    assert!(
        text.contains(
            "fmiVersion is `2.0`, but the description is FMI 3.0: its <fmiModelDescription> \
             has an instantiationToken (FMI 2.0: guid); correct fmiVersion to 3.0"
        ),
        "{text}"
    );
    let case = Case::new("version-four");
    let (e, text) = case.refuse_bytes(
        "Four.fmu",
        &with_version("fmiVersion=\"4.0\""),
        &case.options(),
    );
    assert!(matches!(e, LoadError::NotFmi2 { .. }), "{e}");
    assert!(
        text.contains("fmiVersion is `4.0`; this master runs FMI 2.0 and FMI 3.0 FMUs"),
        "{text}"
    );
}

/// An FMI 3.0 description is refused, not read otherwise, when a variable's causality is
/// none of the standard's or an interface has no modelIdentifier (the FMU would run as
/// another interface, or a variable as local).
#[test]
fn fmi3_descriptions_with_an_unknown_causality_or_no_model_identifier_are_refused() {
    let fmi3 = common::fmus().join("fmi3/GantryCrane.fmu");
    let cases = [
        (
            "causality",
            "(saturated at ±U_max)\" causality=\"input\"",
            "(saturated at ±U_max)\" causality=\"inptu\"",
            "variable `U`: causality `inptu` is none of FMI 3.0's (parameter, \
             calculatedParameter, structuralParameter, input, output, local, independent)",
        ),
        (
            "cs-identifier",
            "<CoSimulation modelIdentifier=\"GantryCrane\"",
            "<CoSimulation",
            "<CoSimulation> has no modelIdentifier, which FMI 3.0 requires",
        ),
        (
            "me-identifier",
            "<ModelExchange modelIdentifier=\"GantryCrane\"",
            "<ModelExchange",
            "<ModelExchange> has no modelIdentifier, which FMI 3.0 requires",
        ),
    ];
    for (case_name, from, to, expected) in cases {
        let case = Case::new(&format!("fmi3-{case_name}"));
        let (e, text) = case.refuse_bytes("Bad3.fmu", &with_xml(&fmi3, from, to), &case.options());
        assert!(matches!(e, LoadError::ModelDescription { .. }), "{e}");
        assert!(text.contains(expected), "{case_name}: {text}");
    }
}

#[test]
fn an_output_aliasing_another_output_is_accepted() {
    // `theta` (vr 2) as an alias of `x` (vr 1): same base type, no start values: allowed.
    let case = Case::new("alias-ok");
    let bytes = crane_with_xml(
        "name=\"theta\" valueReference=\"2\"",
        "name=\"theta\" valueReference=\"1\"",
    );
    let fmu = case.fmu("Alias.fmu");
    std::fs::write(&fmu, bytes).unwrap();
    let f = FmuFile::open_with(&fmu, &case.options()).unwrap();
    assert_eq!(f.variable("theta").unwrap().head.value_reference, 1);
    drop(f);
    case.assert_clean(&["Alias.fmu"]);
}

/// Offsets of the zip headers with signature `sig` whose file name, `name_at` bytes in, is `name`.
fn headers(zip: &[u8], sig: &[u8; 4], name_at: usize, name: &str) -> Vec<usize> {
    (0..zip.len().saturating_sub(name_at + name.len()))
        .filter(|&i| {
            zip[i..i + 4] == *sig && zip[i + name_at..i + name_at + name.len()] == *name.as_bytes()
        })
        .collect()
}

const LOCAL: (&[u8; 4], usize) = (b"PK\x03\x04", 30);
const CENTRAL: (&[u8; 4], usize) = (b"PK\x01\x02", 46);

/// Sets the Unix mode (file type included) recorded for `name` in the central directory.
fn set_unix_mode(mut zip: Vec<u8>, name: &str, mode: u32) -> Vec<u8> {
    let central = headers(&zip, CENTRAL.0, CENTRAL.1, name);
    assert_eq!(central.len(), 1, "the central header of {name}");
    for i in central {
        zip[i + 5] = 3; // made by: Unix
        zip[i + 38..i + 42].copy_from_slice(&(mode << 16).to_le_bytes());
    }
    zip
}

/// Sets the uncompressed size recorded for `name` in both the local and the central header.
fn lie_about_size(mut zip: Vec<u8>, name: &str, size: u32) -> Vec<u8> {
    // The uncompressed size stands 22 bytes into a local header, 24 into a central one.
    let local = headers(&zip, LOCAL.0, LOCAL.1, name);
    let central = headers(&zip, CENTRAL.0, CENTRAL.1, name);
    assert_eq!(
        (local.len(), central.len()),
        (1, 1),
        "both headers of {name}"
    );
    for i in local
        .iter()
        .map(|i| i + 22)
        .chain(central.iter().map(|i| i + 24))
    {
        zip[i..i + 4].copy_from_slice(&size.to_le_bytes());
    }
    zip
}

/// GantryCrane.fmu with 8 MiB of zeros as `resources/bomb.bin`, and `case`'s options with
/// 4 MiB allowed unpacked.
fn bomb(case: &Case) -> (Vec<u8>, LoadOptions) {
    let zeros = vec![0u8; 8 << 20];
    let bytes = crane_with_entries(&[("resources/bomb.bin", &zeros, 0o100_644)]);
    let mut options = case.options();
    options.limits.max_unpacked = 4 << 20;
    (bytes, options)
}

#[test]
fn a_zip_bomb_stops_at_the_declared_size_limit() {
    let case = Case::new("bomb-declared");
    let (bytes, options) = bomb(&case);
    let good = std::fs::metadata(crane()).unwrap().len() as usize;
    assert!(bytes.len() < good + (1 << 20), "the bomb compresses");
    let (e, text) = case.refuse_bytes("Bomb.fmu", &bytes, &options);
    assert!(matches!(e, LoadError::TooLarge { .. }), "{e}");
    assert_names(
        &text,
        &[
            "declare more than 4194304 bytes unpacked (reached at `resources/bomb.bin`)",
            "at most 4194304 bytes (max_unpacked)",
        ],
    );
}

#[test]
fn a_zip_bomb_that_lies_about_its_size_stops_while_inflating() {
    let case = Case::new("bomb-lying");
    let (bytes, options) = bomb(&case);
    let bytes = lie_about_size(bytes, "resources/bomb.bin", 1000);
    let (e, text) = case.refuse_bytes("Liar.fmu", &bytes, &options);
    assert!(text.contains("resources/bomb.bin"), "{text}");
    // Either the count while inflating stops it at the limit, or the zip reader itself
    // refuses data beyond the declared size: never 8 MiB on disk.
    assert!(
        matches!(e, LoadError::TooLarge { .. }) || matches!(e, LoadError::Unpack { .. }),
        "{text}"
    );
}

#[test]
fn an_oversized_model_description_is_refused_before_parsing() {
    let case = Case::new("bigxml");
    let bytes = crane_with_xml(
        "</fmiModelDescription>",
        &format!("<!--{}--></fmiModelDescription>", " ".repeat(1 << 20)),
    );
    let mut options = case.options();
    options.limits.max_model_description = 64 << 10;
    let (_, text) = case.refuse_bytes("BigXml.fmu", &bytes, &options);
    assert_names(
        &text,
        &[
            "BigXml.fmu: modelDescription.xml declares",
            "at most 65536 bytes (max_model_description)",
        ],
    );
    // The same archive with its declared size forged small is stopped while inflating.
    let case = Case::new("bigxml-lying");
    let (_, text) = case.refuse_bytes(
        "BigXml.fmu",
        &lie_about_size(bytes, "modelDescription.xml", 100),
        &options,
    );
    assert!(text.contains("modelDescription.xml"), "{text}");
}

#[test]
fn too_many_entries_are_refused() {
    let case = Case::new("entries");
    let names: Vec<String> = (0..20).map(|i| format!("resources/{i}.txt")).collect();
    let extra: Vec<(&str, &[u8], u32)> = names
        .iter()
        .map(|n| (n.as_str(), b"x".as_slice(), 0o100_644))
        .collect();
    let bytes = crane_with_entries(&extra);
    let good_entries = zip::ZipArchive::new(std::fs::File::open(crane()).unwrap())
        .unwrap()
        .len();
    let mut options = case.options();
    options.limits.max_entries = 10;
    let (_, text) = case.refuse_bytes("Many.fmu", &bytes, &options);
    assert!(
        text.contains(&format!(
            "Many.fmu: the archive has {} entries",
            good_entries + names.len()
        )) && text.contains("at most 10 entries (max_entries)"),
        "{text}"
    );
}
