//! Names are checked before anything runs: each bad name is an error naming it.

mod common;

use spurio_identify::plant::{integration, FmuPlant, PlantError, PlantSpec, Start};

fn open(
    model: &str,
    free: &[&str],
    inputs: &[&str],
    outputs: &[&str],
) -> Result<FmuPlant, PlantError> {
    let strings = |names: &[&str]| names.iter().map(|s| s.to_string()).collect();
    FmuPlant::open(
        &common::reference(model),
        &PlantSpec {
            free: strings(free),
            inputs: strings(inputs),
            outputs: strings(outputs),
        },
        integration(0.0, 1e-8),
    )
}

#[test]
fn a_state_is_not_a_parameter() {
    let e = open("BouncingBall", &["h"], &[], &["h"]).unwrap_err();
    assert!(matches!(e, PlantError::NotAParameter { .. }), "{e}");
    let text = e.to_string();
    assert!(
        text.contains("`h`") && text.contains("an output") && text.contains("g, e"),
        "{text}"
    );
}

#[test]
fn a_missing_output_is_named() {
    let e = open("VanDerPol", &["mu"], &[], &["x2"]).unwrap_err();
    assert!(
        matches!(e, PlantError::UnknownVariable { ref name, .. } if name == "x2"),
        "{e}"
    );
}

#[test]
fn a_parameter_is_not_a_measurement_nor_an_input() {
    let e = open("Dahlquist", &["k"], &[], &["k"]).unwrap_err();
    assert!(matches!(e, PlantError::NotMeasurable { .. }), "{e}");
    let e = open("Dahlquist", &["k"], &["x"], &["x"]).unwrap_err();
    assert!(matches!(e, PlantError::NotAnInput { .. }), "{e}");
}

#[test]
fn tunable_and_fixed_are_told_apart() {
    let plant = open("BouncingBall", &["g", "e"], &[], &["h"]).unwrap();
    let tunable: Vec<bool> = plant.parameters().iter().map(|p| p.tunable).collect();
    assert_eq!(tunable, [false, true]);
    assert_eq!(plant.parameter_starts(), [-9.81, 0.7]);
    assert_eq!(plant.states(), 2);
}

#[test]
fn a_fixed_parameter_resets_the_instance_a_tunable_one_does_not() {
    let mut plant = open("BouncingBall", &["g", "e"], &[], &["h"]).unwrap();
    let x0 = plant.initial_states(&[-9.81, 0.7]).unwrap();
    let resets = plant.resets();
    let (mut x, mut y) = (vec![0.0; 2], vec![0.0]);
    let start = |parameters: &'static [f64]| Start {
        time: 0.0,
        states: &x0,
        parameters,
        inputs: &[],
        reference: None,
    };
    plant
        .propagate(&start(&[-9.81, 0.9]), 0.2, &mut x, &mut y)
        .unwrap();
    assert_eq!(plant.resets(), resets);
    assert!((y[0] - (1.0 - 0.5 * 9.81 * 0.04)).abs() < 1e-6, "{y:?}");
    plant
        .propagate(&start(&[-4.0, 0.9]), 0.2, &mut x, &mut y)
        .unwrap();
    assert_eq!(plant.resets(), resets + 1);
    assert!((y[0] - (1.0 - 0.5 * 4.0 * 0.04)).abs() < 1e-6, "{y:?}");
}
