//! Every way a system or an FMU can be wrong gets an error that names the FMU, the variable
//! and the file. These tests need the packaged FMUs (`scripts/build-fmus`).

mod common;

use common::{assert_names, crane, resolve, rewrite};
use spurio_master::fmu::{FmuFile, LoadError};
use spurio_master::System;
use spurio_master::{RunError, Simulation};
use std::path::PathBuf;

/// GantryCrane.fmu copied to `<tmp>/spurio-master-<pid>-<file>/<file>`, each entry passed
/// through `edit` (None drops it), then `extra` plain-file entries appended.
fn crane_copy(
    file: &str,
    edit: impl Fn(&str, Vec<u8>) -> Option<Vec<u8>>,
    extra: &[(&str, &[u8])],
) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("spurio-master-{}-{file}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let target = dir.join(file);
    let extra: Vec<_> = extra
        .iter()
        .map(|&(name, data)| (name, data, 0o100_644))
        .collect();
    std::fs::write(&target, rewrite(&crane(), edit, &extra)).unwrap();
    target
}

/// GantryCrane.fmu copied as `file` with the text of its modelDescription.xml from the first
/// `from` through the next `through` replaced by `with`.
fn crane_with_xml(file: &str, from: &str, through: &str, with: &str) -> PathBuf {
    let edit = |name: &str, data: Vec<u8>| {
        if name != "modelDescription.xml" {
            return Some(data);
        }
        let xml = String::from_utf8(data).unwrap();
        let start = xml.find(from).unwrap();
        let after = start + from.len();
        let end = after + xml[after..].find(through).unwrap() + through.len();
        Some(format!("{}{with}{}", &xml[..start], &xml[end..]).into_bytes())
    };
    crane_copy(file, edit, &[])
}

#[test]
fn missing_linux64_binary_is_named() {
    let target = crane_copy(
        "NoBinary.fmu",
        |name, data| (!name.starts_with("binaries/")).then_some(data),
        &[],
    );
    let e = FmuFile::open(&target).unwrap_err();
    assert!(matches!(e, LoadError::MissingBinary { .. }));
    assert_names(
        &e.to_string(),
        &["NoBinary.fmu", "binaries/linux64/GantryCrane.so"],
    );
}

#[test]
fn guid_mismatch_is_reported_with_what_the_fmu_said() {
    spurio_master::logging::install_unseen(false);
    let zero_guid = "guid=\"{00000000-0000-0000-0000-000000000000}\"";
    let target = crane_with_xml("WrongGuid.fmu", "guid=\"", "\"", zero_guid);
    let fmu = FmuFile::open(&target).unwrap();
    let e = fmu.instantiate("wrong_guid", false).unwrap_err();
    assert_names(
        &e.to_string(),
        &["wrong_guid", "WrongGuid.fmu", "GUID mismatch"],
    );
}

#[test]
fn model_exchange_only_fmu_is_rejected() {
    let model_exchange = "<ModelExchange modelIdentifier=\"GantryCrane\"/>";
    let target = crane_with_xml("OnlyME.fmu", "<CoSimulation", "/>", model_exchange);
    let e = FmuFile::open(&target).unwrap_err();
    assert!(matches!(e, LoadError::NotCoSimulation { .. }), "{e}");
    assert_names(&e.to_string(), &["OnlyME.fmu", "not a Co-Simulation FMU"]);
}

#[test]
fn archive_entry_leaving_the_directory_is_rejected() {
    let target = crane_copy(
        "Slip.fmu",
        |_, data| Some(data),
        &[("../../outside.txt", b"x")],
    );
    let e = FmuFile::open(&target).unwrap_err();
    assert!(matches!(e, LoadError::UnsafeEntry { .. }), "{e}");
    assert_names(&e.to_string(), &["../../outside.txt", "Slip.fmu"]);
}

fn system(toml_text: &str) -> Result<System, String> {
    resolve(toml_text).map_err(|e| e.to_string())
}

const TWO: &str = r#"
stop_time = 1.0
step_size = 0.05
[[instance]]
name = "crane"
fmu = "GantryCrane.fmu"
[[instance]]
name = "ctrl"
fmu = "StateFeedback.fmu"
[[instance]]
name = "adaptive"
fmu = "AdaptiveStateFeedback.fmu"
"#;

fn with_connections(connections: &[&str]) -> String {
    let list: Vec<String> = connections.iter().map(|c| format!("{c:?}")).collect();
    format!("connections = [{}]\n{TWO}", list.join(", "))
}

#[test]
fn unknown_variable_names_the_instance_the_variable_and_the_file() {
    let e = system(&with_connections(&["crane.position -> ctrl.x_hat[1]"])).unwrap_err();
    assert_names(&e, &["`crane`", "`position`", "GantryCrane.fmu"]);
    let e = system(&with_connections(&["crane.x -> ctrl.x_hat[9]"])).unwrap_err();
    assert_names(&e, &["x_hat[9]", "did you mean", "x_hat[1]"]);
    let e = system(&with_connections(&["crane.x -> nobody.u"])).unwrap_err();
    assert!(e.contains("no instance called `nobody`"), "{e}");
}

#[test]
fn causality_and_type_mismatches_are_named() {
    let e = system(&with_connections(&["crane.U -> ctrl.x_hat[1]"])).unwrap_err();
    assert_names(&e, &["crane.U", "starts at an output"]);
    let e = system(&with_connections(&["crane.x -> ctrl.u[1]"])).unwrap_err();
    assert_names(&e, &["ctrl.u[1]", "ends at an input"]);
    let e = system(&with_connections(&[
        "adaptive.estimate_rejected -> ctrl.x_hat[1]",
    ]))
    .unwrap_err();
    assert_names(&e, &["type mismatch", "Boolean", "Real"]);
}

#[test]
fn an_input_driven_twice_is_named() {
    let e = system(&with_connections(&[
        "crane.x -> ctrl.x_hat[1]",
        "crane.theta -> ctrl.x_hat[1]",
    ]))
    .unwrap_err();
    assert_names(&e, &["ctrl.x_hat[1]", "crane.x", "crane.theta"]);
}

#[test]
fn a_loop_of_direct_feedthrough_is_reported_not_delayed() {
    let text = format!(
        "connections = [\"ctrl.u[1] -> other.x_hat[1]\", \"other.u[1] -> ctrl.x_hat[1]\"]\n{TWO}\n[[instance]]\nname = \"other\"\nfmu = \"StateFeedback.fmu\"\n"
    );
    let e = system(&text).unwrap_err();
    assert_names(&e, &["algebraic loop", "ctrl.u[1]", "other.u[1]"]);
    // The same loop closed through the crane (no feedthrough) is fine.
    system(&with_connections(&[
        "ctrl.u[1] -> crane.U",
        "crane.x -> ctrl.x_hat[1]",
    ]))
    .unwrap();
}

#[test]
fn bad_parameter_values_are_named() {
    let text = TWO.replace(
        "fmu = \"GantryCrane.fmu\"",
        "fmu = \"GantryCrane.fmu\"\nparameters = { x0 = true }",
    );
    let e = system(&text).unwrap_err();
    assert_names(&e, &["`crane`", "`x0`", "Real"]);
}

#[test]
fn an_error_inside_the_fmu_names_the_instance_and_the_call() {
    spurio_master::logging::install_unseen(false);
    let text = TWO.replace(
        "fmu = \"GantryCrane.fmu\"",
        "fmu = \"GantryCrane.fmu\"\nparameters = { x0 = 0.9 }",
    );
    let s = system(&text).unwrap();
    let e = match Simulation::new(&s) {
        Err(e) => e,
        Ok(_) => panic!("x0 beyond the rail must fail"),
    };
    assert!(matches!(e, RunError::Fmi { .. }));
    let text = e.to_string();
    assert_names(
        &text,
        &["`crane`", "GantryCrane.fmu", "returned fmi2Error", "`x0`"],
    );
}

#[test]
fn an_error_in_a_step_names_the_instance_the_call_and_the_time() {
    spurio_master::logging::install_unseen(false);
    let s = system(
        "stop_time = 1.0\nstep_size = 0.1\n[[instance]]\nname = \"plant\"\nfmu = \"LinearSystem.fmu\"\nparameters = { \"A[1,1]\" = 1e200, \"x0[1]\" = 1e200 }\n",
    )
    .unwrap();
    let mut sim = Simulation::new(&s).unwrap();
    let e = sim
        .run(&mut spurio_master::NoRecording, &Default::default())
        .unwrap_err();
    let text = e.to_string();
    assert_names(
        &text,
        &[
            "`plant`",
            "LinearSystem.fmu",
            "fmi2DoStep returned fmi2Error at t = 0",
            "non-finite",
        ],
    );
}
