//! `spurio validate` and `spurio info` on any FMU: our FMUs (FMI 2.0 and 3.0) and every
//! Reference FMU pass (the Reference FMUs' one known flaw, Roberts' DAE manifest, is a
//! warning that says why); each hand-made defect, a small edit of a valid model description
//! in a copy of the FMU, fails with exit code 1 and the message that names it, its place
//! and its line.

#[path = "../../tests/common/mod.rs"]
mod engine;

use engine::{assert_names, fmus, reference, rewrite};
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
fn the_reference_fmus_are_valid_and_roberts_manifest_is_a_warning() {
    let folder = |version| {
        reference(version, "BouncingBall")
            .parent()
            .unwrap()
            .to_path_buf()
    };
    let (fmi2, warned2) = all_valid(&folder("fmi2"));
    let (fmi3, warned3) = all_valid(&folder("fmi3"));
    assert_eq!((fmi2, fmi3), (6, 9));
    assert!(warned2.is_empty(), "{warned2:?}");
    // Roberts' fmi-ls-dae manifest calls the layered standard "fmi-ls-dae" in the folder
    // extra/org.fmi-standard.fmi-ls-dae/ and gives it an empty version.
    assert_eq!(warned3.len(), 1, "{warned3:?}");
    let (name, report) = &warned3[0];
    assert_eq!(name, "Roberts");
    assert_names(
        report,
        &[
            "warning: line 2: extra/org.fmi-standard.fmi-ls-dae/fmi-ls-manifest.xml: fmi-ls:fmi-ls-name is \"fmi-ls-dae\"",
            "fmi-ls:fmi-ls-version is empty",
            "valid FMI 3.0 (the standard's schema and rules), 2 warning(s)",
        ],
    );
}

/// A copy of `source` whose model description is `edit`ed (the edit must change it), with
/// the entries `extra` added, written to a fresh folder as `<case>.fmu`.
fn defective(
    case: &str,
    source: &Path,
    edit: impl Fn(&str) -> String,
    extra: &[(&str, &[u8], u32)],
) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("spurio-validate-{case}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let bytes = rewrite(
        source,
        |name, data| {
            if name != "modelDescription.xml" {
                return Some(data);
            }
            let text = String::from_utf8(data).unwrap();
            let edited = edit(&text);
            assert_ne!(edited, text, "the edit of {case} changes nothing");
            Some(edited.into_bytes())
        },
        extra,
    );
    let fmu = dir.join(format!("{case}.fmu"));
    std::fs::write(&fmu, bytes).unwrap();
    fmu
}

/// Asserts that `fmu` is refused (exit code 1) with a report holding each of `expected`,
/// and removes its folder.
fn refused(fmu: &Path, expected: &[&str]) {
    let out = validate(fmu);
    let report = stdout(&out);
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    assert_eq!(out.status.code(), Some(1), "{report}{stderr}");
    assert_names(&report, expected);
    assert!(stderr.contains("problem(s) against FMI"), "{stderr}");
    std::fs::remove_dir_all(fmu.parent().unwrap()).unwrap();
}

/// The Reference FMU BouncingBall (FMI 2.0) with its model description edited: a small,
/// well-known text whose lines the messages name (`h` on line 66, `v` on 72, `der(v)` on
/// 75, `g` on 78, `e` on 81, `ModelStructure/Outputs` from line 91).
fn ball2(case: &str, edit: impl Fn(&str) -> String) -> PathBuf {
    defective(case, &reference("fmi2", "BouncingBall"), edit, &[])
}

/// The same for its FMI 3.0 twin (`<ModelExchange>` on line 9, `v` on 57, `der(v)` on 58, `g`
/// on 59).
fn ball3(case: &str, edit: impl Fn(&str) -> String, extra: &[(&str, &[u8], u32)]) -> PathBuf {
    defective(case, &reference("fmi3", "BouncingBall"), edit, extra)
}

#[test]
fn a_name_used_twice() {
    let fmu = ball2("name", |t| {
        t.replace(
            r#"name="v" valueReference="3""#,
            r#"name="h" valueReference="3""#,
        )
    });
    refused(&fmu, &["error: line 72: variable `h`: the name is taken already by the variable on line 66; names must be unique [unique-name]"]);
}

#[test]
fn two_start_values_on_one_value_reference_in_fmi2() {
    let fmu = ball2("alias", |t| {
        t.replace(
            r#"name="v" valueReference="3""#,
            r#"name="v" valueReference="1""#,
        )
    });
    refused(&fmu, &["error: line 72: variable `v`: shares value reference 1 (Real) with `h` (line 66) and both have a start value; of a set of aliases at most one non-constant variable may have one [value-reference]"]);
}

#[test]
fn a_value_reference_used_twice_in_fmi3() {
    let fmu = ball3(
        "vr3",
        |t| {
            t.replace(
                r#"name="v" valueReference="3""#,
                r#"name="v" valueReference="5""#,
            )
        },
        &[],
    );
    refused(
        &fmu,
        &[
            "error: line 59: variable `g`: value reference 5 is that of `v` (line 57) too; in FMI 3.0 each variable has its own",
            "ModelStructure/Output: no variable has value reference 3 [model-structure]",
        ],
    );
}

#[test]
fn an_ill_formed_structured_name() {
    let fmu = defective(
        "structured",
        &fmus().join("KalmanFilter.fmu"),
        |t| t.replacen(r#"name="y[1]""#, r#"name="y[1""#, 1),
        &[],
    );
    refused(&fmu, &["variable `y[1`: not a legal name for variableNamingConvention=\"structured\": expected ']' at the end [variable-name]"]);
}

#[test]
fn an_output_missing_from_outputs() {
    let fmu = ball2("outputs", |t| {
        t.replacen("      <Unknown index=\"4\" dependencies=\"\"/>\n", "", 1)
    });
    refused(&fmu, &["error: line 91: ModelStructure/Outputs: must list exactly the variables of causality=\"output\": missing `v` [model-structure]"]);
}

#[test]
fn a_parameter_listed_as_an_output() {
    let fmu = ball2("not-output", |t| {
        t.replace(
            r#"<Unknown index="4" dependencies=""/>"#,
            r#"<Unknown index="4" dependencies=""/><Unknown index="6"/>"#,
        )
    });
    refused(&fmu, &["ModelStructure/Outputs: must list exactly the variables of causality=\"output\": not to be listed `g` [model-structure]"]);
}

#[test]
fn a_derivative_missing_from_initial_unknowns() {
    let fmu = ball2("initial-unknowns", |t| {
        let at = t.find("<InitialUnknowns>").unwrap();
        let (head, tail) = t.split_at(at);
        format!(
            "{head}{}",
            tail.replacen(
                r#"      <Unknown index="5" dependencies="6" dependenciesKind="constant"/>"#,
                "",
                1
            )
        )
    });
    refused(&fmu, &["ModelStructure/InitialUnknowns: must list exactly the outputs and continuous states and derivatives with initial=\"approx\" or \"calculated\", and the calculated parameters: missing `der(v)` [model-structure]"]);
}

#[test]
fn a_dependency_out_of_range() {
    let fmu = ball2("dependency", |t| {
        t.replacen(
            r#"dependencies="4" dependenciesKind="constant""#,
            r#"dependencies="99" dependenciesKind="constant""#,
            1,
        )
    });
    refused(&fmu, &["error: line 95: ModelStructure/Derivatives: a dependency of `der(h)`: index 99 is out of range (ModelVariables has 8 variables, numbered from 1) [dependencies]"]);
}

#[test]
fn dependencies_kind_of_another_length() {
    let fmu = ball2("kind", |t| {
        t.replacen(
            r#"dependencies="4" dependenciesKind="constant""#,
            r#"dependencies="4" dependenciesKind="constant fixed""#,
            1,
        )
    });
    refused(&fmu, &["error: line 95: ModelStructure/Derivatives: the entry of `der(h)` has 1 dependencies but 2 dependenciesKind [dependencies]"]);
}

#[test]
fn a_derivative_attribute_out_of_range() {
    let fmu = ball2("derivative", |t| {
        t.replace(r#"<Real derivative="4""#, r#"<Real derivative="40""#)
    });
    refused(&fmu, &["error: line 75: variable `der(v)`: derivative=\"40\" names no variable: index 40 is out of range (ModelVariables has 8 variables, numbered from 1) [derivative]"]);
}

#[test]
fn a_derivative_of_a_non_float_in_fmi3() {
    // `der(v)` made the derivative of an Int32 variable.
    let fmu = ball3(
        "derivative-int",
        |t| {
            t.replace(
                r#"<Float64 name="g" valueReference="5" causality="parameter" variability="fixed" initial="exact" declaredType="Acceleration" start="-9.81""#,
                r#"<Int32 name="g" valueReference="5" causality="parameter" variability="fixed" initial="exact" start="-9""#,
            )
            .replace(r#"derivative="3""#, r#"derivative="5""#)
        },
        &[],
    );
    refused(&fmu, &["error: line 58: variable `der(v)`: derivative=\"5\" names `g`, a Int32 variable; a state must be a float [derivative]"]);
}

#[test]
fn a_parameter_without_its_start_value() {
    let fmu = ball2("start", |t| {
        t.replace(
            r#"<Real start="-9.81" declaredType="Acceleration"/>"#,
            r#"<Real declaredType="Acceleration"/>"#,
        )
    });
    refused(&fmu, &["error: line 78: variable `g`: has no start value, which initial=\"exact\" requires [start-value]"]);
}

#[test]
fn a_calculated_variable_with_a_start_value() {
    let fmu = ball2("calculated", |t| {
        t.replace(
            r#"<Real derivative="4" declaredType="Acceleration"/>"#,
            r#"<Real derivative="4" declaredType="Acceleration" start="0"/>"#,
        )
    });
    refused(
        &fmu,
        &["error: line 75: variable `der(v)`: has a start value but initial=\"calculated\""],
    );
}

#[test]
fn a_continuous_parameter() {
    let fmu = ball2("combination", |t| {
        t.replace(
            r#"name="g" valueReference="5" causality="parameter" variability="fixed""#,
            r#"name="g" valueReference="5" causality="parameter" variability="continuous""#,
        )
    });
    refused(&fmu, &["error: line 78: variable `g`: causality=\"parameter\" with variability=\"continuous\" and initial=\"exact\" is not a combination FMI 2.0 allows [causality]"]);
}

#[test]
fn a_start_value_above_max() {
    let fmu = ball2("bounds", |t| {
        t.replace(
            r#"<Real start="0.7" min="0.5" max="1"/>"#,
            r#"<Real start="1.5" min="0.5" max="1"/>"#,
        )
    });
    refused(
        &fmu,
        &["error: line 81: variable `e`: the start value 1.5 is above max = 1 [bounds]"],
    );
}

#[test]
fn a_unit_not_defined() {
    let fmu = ball2("unit", |t| {
        t.replace(r#"<Unit name="m/s2">"#, r#"<Unit name="m/s^2">"#)
    });
    refused(&fmu, &["error: line 75: variable `der(v)`: its unit \"m/s2\" is not defined in UnitDefinitions [units-and-types]"]);
}

#[test]
fn a_value_the_schema_refuses() {
    let fmu = ball2("schema", |t| {
        t.replace(
            r#"name="v" valueReference="3" causality="output""#,
            r#"name="v" valueReference="3" causality="sideways""#,
        )
    });
    refused(&fmu, &["error: line 72: modelDescription.xml: Element 'ScalarVariable', attribute 'causality': [facet 'enumeration'] The value 'sideways' is not an element of the set", "[schema]"]);
}

#[test]
fn a_model_identifier_without_its_binary() {
    let fmu = ball2("binary", |t| {
        t.replace(
            r#"modelIdentifier="BouncingBall""#,
            r#"modelIdentifier="Ball""#,
        )
    });
    refused(&fmu, &["error: line 10: binaries/linux64/: has no library for modelIdentifier \"Ball\" (expected binaries/linux64/Ball.so) [binaries]"]);
}

#[test]
fn a_model_identifier_that_is_no_c_identifier() {
    let fmu = ball3(
        "identifier",
        |t| {
            t.replace(
                r#"modelIdentifier="BouncingBall""#,
                r#"modelIdentifier="Bouncing-Ball""#,
            )
        },
        &[],
    );
    refused(&fmu, &["error: line 9: <ModelExchange>: modelIdentifier \"Bouncing-Ball\" is not a valid C identifier", "[interface]"]);
}

/// A `terminalsAndIcons.xml` whose one terminal has the member `member`.
fn terminals(member: &str) -> Vec<u8> {
    format!(
        r#"<?xml version="1.0" encoding="UTF-8"?>
<fmiTerminalsAndIcons fmiVersion="3.0">
  <Terminals>
    <Terminal name="ball" matchingRule="bus">
      {member}
    </Terminal>
  </Terminals>
</fmiTerminalsAndIcons>
"#
    )
    .into_bytes()
}

#[test]
fn terminals_are_checked_against_their_schema_and_the_variables() {
    const ENTRY: &str = "terminalsAndIcons/terminalsAndIcons.xml";
    // A valid one passes (the model description is left as it is but for its description).
    let good = terminals(
        r#"<TerminalMemberVariable variableName="h" memberName="height" variableKind="signal"/>"#,
    );
    let fmu = ball3(
        "terminals-ok",
        |t| t.replacen("This model calculates", "It calculates", 1),
        &[(ENTRY, &good, 0o644)],
    );
    let out = validate(&fmu);
    assert!(out.status.success(), "{}", stdout(&out));
    std::fs::remove_dir_all(fmu.parent().unwrap()).unwrap();

    let missing_kind =
        terminals(r#"<TerminalMemberVariable variableName="h" memberName="height"/>"#);
    let fmu = ball3(
        "terminals-schema",
        |t| t.replacen("This model calculates", "It calculates", 1),
        &[(ENTRY, &missing_kind, 0o644)],
    );
    refused(&fmu, &["error: line 5: terminalsAndIcons/terminalsAndIcons.xml: Element 'TerminalMemberVariable': The attribute 'variableKind' is required but missing. [schema]"]);

    let unknown =
        terminals(r#"<TerminalMemberVariable variableName="height" variableKind="signal"/>"#);
    let fmu = ball3(
        "terminals-name",
        |t| t.replacen("This model calculates", "It calculates", 1),
        &[(ENTRY, &unknown, 0o644)],
    );
    refused(&fmu, &["error: line 5: terminalsAndIcons/terminalsAndIcons.xml: the terminal member variableName=\"height\" names no variable of modelDescription.xml [terminals]"]);
}

#[test]
fn an_archive_that_is_not_an_fmu_is_an_error_not_a_report() {
    let dir = std::env::temp_dir().join(format!("spurio-validate-zip-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("plain.fmu");
    std::fs::write(&path, b"not a zip").unwrap();
    for command in ["validate", "info"] {
        let out = spurio(&[command, path.to_str().unwrap()]);
        let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
        assert_eq!(out.status.code(), Some(1), "{stderr}");
        assert_names(
            &stderr,
            &["plain.fmu: not an FMU archive (an FMU is a zip file)"],
        );
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
            "platforms            x86_64-linux, sources",
            "default experiment   start 0, stop 3, step size 1e-2",
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
    // name, vr, causality, variability, type, unit, start, min, max, description…
    assert_eq!(
        row("e")[..9],
        [
            "e",
            "6",
            "parameter",
            "tunable",
            "Float64",
            "0.7",
            "0.5",
            "1",
            "Coefficient"
        ]
    );
    assert_eq!(
        row("g")[..7],
        ["g", "5", "parameter", "fixed", "Float64", "m/s2", "-9.81"]
    );
    assert_eq!(
        row("h_ft")[..9],
        [
            "h_ft",
            "1",
            "output",
            "continuous",
            "Float64",
            "m",
            "1",
            "(alias",
            "of"
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
