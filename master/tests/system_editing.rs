//! Editing a resolved system by name: start values with the checks of a `parameters` entry,
//! another FMU file for an instance, and what the model description says of a variable.
//! These tests need the packaged FMUs (`scripts/build-fmus`).

mod common;

use common::{assert_names, crane_sensor, fmus, resolve};
use spurio_master::TimeSeries;
use spurio_master::{System, SystemError};

/// A run of `system` with the default options.
fn run(system: &System) -> TimeSeries {
    common::run(system, &Default::default()).0
}

#[test]
fn a_start_value_set_by_name_runs_like_the_same_toml_entry() {
    let from_toml = run(&crane_sensor(1.0, "U = 0.5, x0 = 0.2"));
    let mut edited = crane_sensor(1.0, "U = 0.5");
    assert_eq!(edited.start_value("crane.x0").unwrap(), Some(0.0));
    edited.set_start_value("crane.x0", 0.2).unwrap();
    assert_eq!(edited.start_value("crane.x0").unwrap(), Some(0.2));
    let by_name = run(&edited);
    let x = from_toml.column("crane.x").unwrap();
    assert_eq!(x[0], 0.2);
    assert!(x[100] > 0.2, "the force moves the cart: {}", x[100]);
    assert_eq!(by_name.column("crane.x").unwrap(), x);
    // An Integer takes a whole number; the seed changes the noise, not the clean signal.
    edited.set_start_value("sensor.seed", 7).unwrap();
    assert_eq!(edited.start_value("sensor.seed").unwrap(), Some(7.0));
    let reseeded = run(&edited);
    assert_eq!(
        reseeded.column("sensor.y_clean[1]").unwrap(),
        by_name.column("sensor.y_clean[1]").unwrap()
    );
    assert_ne!(
        reseeded.column("sensor.y[1]").unwrap(),
        by_name.column("sensor.y[1]").unwrap()
    );
}

#[test]
fn start_values_set_by_name_are_checked_like_toml_entries() {
    let mut system = crane_sensor(1.0, "");
    let text = |e: SystemError| e.to_string();
    let e = system.set_start_value("crane.x", 1.0).unwrap_err();
    assert!(matches!(e, SystemError::Parameter { .. }));
    assert!(text(e).contains("causality Output"));
    let e = system.set_start_value("sensor.seed", 1.5).unwrap_err();
    assert!(text(e)
        .contains("is of type Integer, which takes an integer (`3`); the value `1.5` is not one"));
    let e = system
        .set_start_value("sensor.seed", 1i64 << 40)
        .unwrap_err();
    assert!(text(e).contains("does not fit an Integer"));
    let e = system.set_start_value("crane.x_0", 1.0).unwrap_err();
    assert!(matches!(e, SystemError::UnknownVariable { .. }), "{e}");
    let e = system.set_start_value("cart.x0", 1.0).unwrap_err();
    assert_eq!(
        text(e),
        "no instance called `cart` (instances: crane, sensor)"
    );
    let e = system.set_start_value("x0", 1.0).unwrap_err();
    assert!(text(e).contains("not of the form instance.variable"));
    // The same check as a TOML entry gives the same message.
    let from_toml = resolve(
        r#"
        stop_time = 1.0
        step_size = 0.1
        [[instance]]
        name = "sensor"
        fmu = "Sensor2.fmu"
        parameters = { seed = 1.5 }
        "#,
    )
    .unwrap_err();
    let by_name = crane_sensor(1.0, "")
        .set_start_value("sensor.seed", 1.5)
        .unwrap_err();
    assert_eq!(from_toml.to_string(), by_name.to_string());
}

#[test]
fn units_and_descriptions_come_from_the_model_description() {
    let system = crane_sensor(1.0, "");
    assert_eq!(system.unit("crane.x").unwrap(), Some("m"));
    assert_eq!(system.unit("crane.theta").unwrap(), Some("rad"));
    assert_eq!(system.unit("sensor.seed").unwrap(), None);
    assert!(system
        .description("sensor.y[1]")
        .unwrap()
        .unwrap()
        .starts_with("Measured value"));
    assert!(system.unit("crane.nothing").is_err());
}

#[test]
fn an_instance_runs_from_another_fmu_file_resolved_again_by_name() {
    let copy_dir = std::env::temp_dir().join(format!("spurio-set-fmu-{}", std::process::id()));
    std::fs::create_dir_all(&copy_dir).unwrap();
    let copy = copy_dir.join("MySensor.fmu");
    std::fs::copy(fmus().join("Sensor2.fmu"), &copy).unwrap();

    let mut system = crane_sensor(1.0, "U = 0.5");
    system.set_start_value("sensor.seed", 11).unwrap();
    let before = run(&system);
    system.set_fmu("sensor", &copy).unwrap();
    assert_eq!(system.instance("sensor").unwrap().fmu.path, copy);
    assert_eq!(system.start_value("sensor.seed").unwrap(), Some(11.0));
    let after = run(&system);
    assert_eq!(after.names, before.names);
    assert_eq!(after.rows, before.rows);

    // A crane in the sensor's place has no `seed` to set (nor a `u[1]` to connect).
    let e = system
        .set_fmu("sensor", &fmus().join("GantryCrane.fmu"))
        .unwrap_err();
    assert!(matches!(e, SystemError::UnknownVariable { .. }), "{e}");
    assert_names(&e.to_string(), &["no variable `seed`", "GantryCrane.fmu"]);
    // A failed swap leaves the system as it was.
    assert_eq!(system.instance("sensor").unwrap().fmu.path, copy);
    assert!(system.set_fmu("nobody", &copy).is_err());
}
