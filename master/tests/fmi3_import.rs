//! FMI 3.0 Co-Simulation import, on the Reference FMUs (FMI 3.0) and mixed with FMI 2.0:
//! arrays addressed element-wise (`y[2]`) and whole (`a.y -> b.u`), start values of array
//! elements, `terminateSimulation` as a normal end, Scheduled Execution refused, values
//! crossing the versions (Real ↔ Float64, Integer ↔ Int32, Boolean). The same runs against
//! fmpy are in `tests/interop/test_reference_fmus3.py`.

mod common;

use common::{assert_names, instance_tables, reference, run};
use spurio_master::fmu::{Causality, FmiVersion, FmuFile, LoadError, VarType};
use spurio_master::ssp::SspVersion;
use spurio_master::{RunEnd, RunOptions};
use spurio_master::{System, SystemDescription, SystemError};
use std::path::{Path, PathBuf};

/// The system of the TOML `head` (times, connections, record) and `instances` (see
/// [`instance_tables`]).
fn system(head: &str, instances: &[(&str, &Path, &str)]) -> Result<System, SystemError> {
    let toml_text = format!("{head}\n{}", instance_tables(instances));
    let description: SystemDescription = toml::from_str(&toml_text).unwrap();
    System::resolve(&description, Path::new("."))
}

/// Asserts that the system of `head` and `instances` (see [`system`]) is refused with a
/// message naming every one of `parts`.
fn assert_refused(head: &str, instances: &[(&str, &Path, &str)], parts: &[&str]) {
    match system(head, instances) {
        Ok(_) => panic!("the system was accepted:\n{head}"),
        Err(e) => assert_names(&e.to_string(), parts),
    }
}

/// Asserts that connecting `a` to `b` by `connection` (one step of 0.5 s to t = 1) is refused
/// with a message naming every one of `parts`.
fn assert_connection_refused(connection: &str, a: &Path, b: &Path, parts: &[&str]) {
    let head = format!("stop_time = 1.0\nstep_size = 0.5\nconnections = [{connection:?}]");
    assert_refused(&head, &[("a", a, ""), ("b", b, "")], parts);
}

/// The FMI 2.0 and the FMI 3.0 Reference FMU `Feedthrough`.
fn feedthroughs() -> (PathBuf, PathBuf) {
    (
        reference("fmi2", "Feedthrough"),
        reference("fmi3", "Feedthrough"),
    )
}

fn column(series: &spurio_master::TimeSeries, name: &str) -> Vec<f64> {
    let j = series
        .names
        .iter()
        .position(|n| n == name)
        .unwrap_or_else(|| panic!("no column {name} in {:?}", series.names));
    series.rows.iter().map(|r| r[j]).collect()
}

#[test]
fn state_space_arrays_are_elements_and_wholes() {
    let fmu = FmuFile::open(&reference("fmi3", "StateSpace")).unwrap();
    assert_eq!(fmu.version, FmiVersion::Fmi3);
    assert_eq!(fmu.guid, "{D773325B-AB94-4630-BF85-643EB24FCB78}");
    // A's dimensions come from the structural parameter n (start 3).
    let a = fmu.array("A").unwrap();
    assert_eq!(a.dimensions, [3, 3]);
    assert_eq!(a.elements.len(), 9);
    let a23 = fmu.variable("A[2,3]").unwrap();
    assert_eq!((a23.head.value_reference, a23.start), (4, Some(0.0)));
    assert_eq!(fmu.variable("A[2,2]").unwrap().start, Some(1.0));
    let u = fmu.array("u").unwrap();
    let starts: Vec<_> = u.elements.iter().map(|&e| fmu.variables[e].start).collect();
    assert_eq!(starts, [Some(1.0), Some(2.0), Some(3.0)]);
    assert_eq!(
        fmu.variable("y[3]").unwrap().head.causality,
        Causality::Output
    );
    assert_eq!(
        fmu.variable("n").unwrap().head.causality,
        Causality::StructuralParameter
    );
    assert!(fmu.variable("y[4]").is_none() && fmu.variable("y").is_none());
}

#[test]
fn state_space_runs_with_array_start_values_and_a_whole_array_connection() {
    // a: A = 0 set element-wise and B = 2 I set whole (a nested TOML array), so x' = B u =
    // 2 u (constant) and y = C x + D u = u (1 + 2 t), exact in the FMU's Euler steps. b gets
    // a.y whole as its input u.
    let fmu = reference("fmi3", "StateSpace");
    let s = system(
        r#"
        stop_time = 2.0
        step_size = 0.5
        connections = ["a.y -> b.u"]
        record = ["a.y", "b.u[2]", "b.u[3]"]
        "#,
        &[
            (
                "a",
                &fmu,
                r#""A[1,1]" = 0.0, "A[2,2]" = 0.0, "A[3,3]" = 0.0, "u[2]" = 5.0, B = [[2, 0, 0], [0, 2, 0], [0, 0, 2]]"#,
            ),
            ("b", &fmu, ""),
        ],
    )
    .unwrap();
    let (series, end) = run(&s, &RunOptions::default());
    assert_eq!(end, RunEnd::StopTime { time: 2.0 });
    assert_eq!(
        series.names,
        ["a.y[1]", "a.y[2]", "a.y[3]", "b.u[2]", "b.u[3]"]
    );
    assert_eq!(series.time, [0.0, 0.5, 1.0, 1.5, 2.0]);
    for (k, t) in series.time.iter().enumerate() {
        for (i, u) in [1.0, 5.0, 3.0].iter().enumerate() {
            let y = column(&series, &format!("a.y[{}]", i + 1))[k];
            assert!(
                (y - u * (1.0 + 2.0 * t)).abs() < 1e-12,
                "y[{}]({t}) = {y}",
                i + 1
            );
        }
        // The whole-array connection delivers every element at the same point.
        assert_eq!(column(&series, "b.u[2]")[k], column(&series, "a.y[2]")[k]);
        assert_eq!(column(&series, "b.u[3]")[k], column(&series, "a.y[3]")[k]);
    }
}

#[test]
fn a_whole_array_parameter_takes_all_its_elements() {
    let fmu = reference("fmi3", "StateSpace");
    assert_refused(
        "stop_time = 1.0\nstep_size = 0.5",
        &[("a", &fmu, "x0 = [1.0, 2.0]")],
        &["parameter `x0`", "an array of 3 elements"],
    );
}

#[test]
fn a_whole_array_connects_only_to_an_array_of_its_dimensions() {
    let fmu = reference("fmi3", "StateSpace");
    assert_connection_refused(
        "a.y -> b.u[1]",
        &fmu,
        &fmu,
        &[
            "a.y -> b.u[1]",
            "`a.y` is an array of dimensions [3]",
            "`b.u[1]` is a scalar",
        ],
    );
}

#[test]
fn stair_ends_the_run_normally_at_its_terminate_time() {
    let fmu = reference("fmi3", "Stair");
    let s = system("stop_time = 10.0\nstep_size = 0.2", &[("stair", &fmu, "")]).unwrap();
    let (series, end) = run(&s, &RunOptions::default());
    let RunEnd::Terminated {
        instance,
        time,
        version,
        ..
    } = &end
    else {
        panic!("{end:?}")
    };
    assert_eq!((instance.as_str(), *version), ("stair", FmiVersion::Fmi3));
    assert!((time - 9.0).abs() < 1e-12, "{time}");
    assert_eq!(series.time.last(), Some(time));
    // The counter starts at 1 and counts the seconds: 10 at t = 9.
    assert_eq!(column(&series, "stair.counter").last(), Some(&10.0));
    assert!(
        end.to_string().contains("terminateSimulation = true"),
        "{end}"
    );
}

#[test]
fn scheduled_execution_is_refused_with_the_reason() {
    let e = FmuFile::open(&reference("fmi3", "Clocks")).unwrap_err();
    assert!(matches!(e, LoadError::NotCoSimulation { .. }), "{e}");
    assert_names(
        &e.to_string(),
        &[
            "Clocks.fmu",
            "not a Co-Simulation FMU",
            "Scheduled Execution",
        ],
    );
}

#[test]
fn values_cross_fmi_versions_and_fmi3_types() {
    // FMI 2.0 Feedthrough -> FMI 3.0 Feedthrough -> FMI 2.0 Feedthrough, and the FMI 3.0
    // one's Int8/UInt64/Float32 outputs into a second FMI 3.0 instance.
    let (fmu2, fmu3) = feedthroughs();
    let s = system(
        r#"
        stop_time = 1.0
        step_size = 0.25
        connections = [
          "a.Float64_continuous_output -> b.Float64_continuous_input",
          "a.Int32_output -> b.Int32_input",
          "a.Boolean_output -> b.Boolean_input",
          "b.Float64_continuous_output -> c.Float64_continuous_input",
          "b.Int32_output -> c.Int32_input",
          "b.Boolean_output -> c.Boolean_input",
          "b.Int8_output -> d.Int8_input",
          "b.UInt64_output -> d.UInt64_input",
          "b.Float32_continuous_output -> d.Float32_continuous_input",
        ]
        record = ["c.Float64_continuous_output", "c.Int32_output", "c.Boolean_output",
                  "d.Int8_output", "d.UInt64_output", "d.Float32_continuous_output"]
        "#,
        &[
            (
                "a",
                &fmu2,
                "Float64_continuous_input = 2.5, Int32_input = -7, Boolean_input = true",
            ),
            (
                "b",
                &fmu3,
                "Int8_input = -100, UInt64_input = 4000000000, Float32_continuous_input = 0.25",
            ),
            ("c", &fmu2, ""),
            ("d", &fmu3, ""),
        ],
    )
    .unwrap();
    assert_eq!(
        s.instances()[1]
            .fmu
            .variable("Int8_output")
            .unwrap()
            .head
            .var_type,
        VarType::Int8
    );
    let (series, _) = run(&s, &RunOptions::default());
    assert_eq!(series.rows.len(), 5);
    for row in &series.rows {
        assert_eq!(row, &[2.5, -7.0, 1.0, -100.0, 4e9, 0.25]);
    }
}

#[test]
fn types_must_match_across_versions() {
    let (fmu2, fmu3) = feedthroughs();
    assert_connection_refused(
        "a.Float64_continuous_output -> b.Float32_continuous_input",
        &fmu2,
        &fmu3,
        &["type mismatch", "Real", "Float32"],
    );
}

#[test]
fn an_ssp_export_names_array_elements_and_wholes_and_runs_the_same() {
    // A whole-array connection, an element feeding an FMI 2.0 FMU, a whole-array parameter
    // (written as its elements) and an element parameter, through SSP 1.0 and 2.0.
    let (space, feed) = (
        reference("fmi3", "StateSpace"),
        reference("fmi2", "Feedthrough"),
    );
    let s = system(
        r#"
        stop_time = 2.0
        step_size = 0.5
        connections = ["a.y -> b.u", "a.y[1] -> c.Float64_continuous_input"]
        record = ["a.y", "b.y[2]", "c.Float64_continuous_output"]
        "#,
        &[
            (
                "a",
                &space,
                r#""A[1,1]" = 0.0, B = [[2, 0, 0], [0, 2, 0], [0, 0, 2]]"#,
            ),
            ("b", &space, ""),
            ("c", &feed, ""),
        ],
    )
    .unwrap();
    let (direct, _) = run(&s, &RunOptions::default());
    // a.y[1] = u1 (1 + 2 t) with u1 = 1, A[1,1] = 0, B = 2 I.
    // (to 1e-12: the FMU integrates in internal steps of its own.)
    assert!((column(&direct, "c.Float64_continuous_output")[4] - 5.0).abs() < 1e-12);
    let dir = tempfile::tempdir().unwrap();
    for version in [SspVersion::V1_0, SspVersion::V2_0] {
        let ssp = dir.path().join("s.ssp");
        s.export_ssp(&ssp, version).unwrap();
        let imported = System::from_file(&ssp).unwrap();
        let b = imported.instance("a").unwrap();
        assert_eq!(
            b.start_values.len(),
            10,
            "A[1,1] and the nine elements of B"
        );
        let (series, _) = run(&imported, &RunOptions::default());
        assert_eq!(series.names, direct.names);
        assert_eq!(series.rows, direct.rows, "{version:?}");
    }
}

#[test]
fn a_rejected_instantiation_token_is_reported_with_what_the_fmu_logged() {
    // The FMU's messages reach the error although rust-fmi's FMI 3.0 logger does not say
    // which instance spoke: the master attributes them to the instance it is calling.
    spurio_master::logging::install_unseen(false);
    let dir = tempfile::tempdir().unwrap();
    let fmu = dir.path().join("Dahlquist.fmu");
    let bytes = common::rewrite(
        &reference("fmi3", "Dahlquist"),
        |name, data| {
            Some(if name == "modelDescription.xml" {
                let text = String::from_utf8(data).unwrap();
                let token = text
                    .split("instantiationToken=\"")
                    .nth(1)
                    .and_then(|rest| rest.split('"').next())
                    .unwrap()
                    .to_string();
                text.replace(&token, "{00000000-0000-0000-0000-000000000000}")
                    .into_bytes()
            } else {
                data
            })
        },
        &[],
    );
    std::fs::write(&fmu, bytes).unwrap();
    let e = FmuFile::open(&fmu)
        .unwrap()
        .instantiate("dq", true)
        .unwrap_err();
    assert!(matches!(e, LoadError::Instantiate { .. }), "{e}");
    assert_names(
        &e.to_string(),
        &[
            "instance `dq`",
            "fmi3InstantiateCoSimulation failed: ",
            "ERROR",
        ],
    );
}

#[test]
fn an_fmi3_fmu_without_its_platform_tuple_binary_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let fmu = dir.path().join("Dahlquist.fmu");
    let bytes = common::rewrite(
        &reference("fmi3", "Dahlquist"),
        |name, data| (!name.starts_with("binaries/x86_64-linux")).then_some(data),
        &[],
    );
    std::fs::write(&fmu, bytes).unwrap();
    let e = FmuFile::open(&fmu).unwrap_err();
    assert!(matches!(e, LoadError::MissingBinary { .. }), "{e}");
    assert_names(
        &e.to_string(),
        &[
            "Dahlquist.fmu",
            "`binaries/x86_64-linux/Dahlquist.so` is missing",
        ],
    );
}

#[test]
fn an_ssp_1_0_export_writes_fmi3_types_it_holds_and_refuses_the_others() {
    // Int8 and Float32 connectors (SSP 1.0: Integer and Real) run the same after the round
    // trip; a UInt64 one has no SSP 1.0 type: SSP 1.0 refuses it, SSP 2.0 writes UInt64.
    let (_, fmu3) = feedthroughs();
    let head = |extra: &str| {
        format!(
            r#"
            stop_time = 1.0
            step_size = 0.25
            connections = [
              "a.Int8_output -> b.Int8_input",
              "a.Float32_continuous_output -> b.Float32_continuous_input",
              {extra}
            ]
            record = ["b.Int8_output", "b.Float32_continuous_output"]
            "#
        )
    };
    let parameters =
        "Int8_input = -100, Float32_continuous_input = 0.25, UInt64_input = 4000000000";
    let instances = [("a", fmu3.as_path(), parameters), ("b", fmu3.as_path(), "")];
    let dir = tempfile::tempdir().unwrap();
    let ssp = dir.path().join("s.ssp");
    let held = system(&head(""), &instances).unwrap();
    held.export_ssp(&ssp, SspVersion::V1_0).unwrap();
    let mut ssd = String::new();
    std::io::Read::read_to_string(
        &mut zip::ZipArchive::new(std::fs::File::open(&ssp).unwrap())
            .unwrap()
            .by_name("SystemStructure.ssd")
            .unwrap(),
        &mut ssd,
    )
    .unwrap();
    for written in ["<ssc:Integer/>", "<ssc:Real/>"] {
        assert_eq!(ssd.matches(written).count(), 3, "{written} in\n{ssd}");
    }
    let (direct, _) = run(&held, &RunOptions::default());
    let (imported, _) = run(&System::from_file(&ssp).unwrap(), &RunOptions::default());
    assert_eq!(imported.rows, direct.rows);
    assert_eq!(direct.rows[4], [-100.0, 0.25]);

    let unheld = system(&head(r#""a.UInt64_output -> b.UInt64_input","#), &instances).unwrap();
    let e = unheld.export_ssp(&ssp, SspVersion::V1_0).unwrap_err();
    assert_names(
        &e.to_string(),
        &[
            "s.ssp: component `a`, connector `UInt64_output`: its type UInt64 has no lossless SSP 1.0 type",
            "--ssp-version 2.0",
        ],
    );
    unheld.export_ssp(&ssp, SspVersion::V2_0).unwrap();
    let (imported, _) = run(&System::from_file(&ssp).unwrap(), &RunOptions::default());
    assert_eq!(imported.rows, run(&unheld, &RunOptions::default()).0.rows);
}
