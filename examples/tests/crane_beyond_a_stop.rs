//! A filter's sigma point beyond a rail stop (the packaged GantryCrane): the GantryCrane ME
//! FMU on a rail of ±0.02 m, the mean at x = 0.0088 m, a sigma point at 0.029 m. The importer
//! places it (an event there: the cart is put on the stop) and integrates 10 ms. The load
//! swings in slightly, so the cart is released at once and moves in. Before, every event put
//! the cart back on the stop (its indicator 0 again): an event after every step, 10⁻⁷ s apart,
//! some 10⁶ of them in the 10 ms, a call that did not end in any useful time. Now: a handful.

use spurio_identify::plant::{integration, FmuPlant, PlantSpec, Start};
use std::path::PathBuf;

#[path = "../../master/tests/common/packaged_fmus.rs"]
mod packaged_fmus;

#[test]
fn a_sigma_point_beyond_a_stop_is_put_on_it_released_and_integrated_in_a_few_events() {
    spurio_identify::plant::keep_plant_messages();
    let repo = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..");
    let fmu = packaged_fmus::packaged_fmus(&repo).join("GantryCrane.fmu");
    let spec = PlantSpec {
        free: vec!["M".into(), "l".into(), "f_c".into()],
        inputs: vec!["U".into()],
        outputs: vec!["x".into(), "theta".into()],
    };
    let mut plant = FmuPlant::open(&fmu, &spec, integration(0.0, 1e-8)).unwrap();
    plant
        .set_values(&[("x0".into(), 0.01), ("x_limit".into(), 0.02)])
        .unwrap();
    let theta = [1.01262, 0.41208, 0.536];
    plant.initial_states(&theta).unwrap();
    let (mut x, mut y) = (vec![0.0; 4], vec![0.0; 2]);
    let at = |states: &'static [f64], reference| Start {
        time: 0.0,
        states,
        parameters: &theta,
        inputs: &[0.0],
        reference,
    };
    // The mean, placed first: its event indicators are the sigma points' reference.
    let mean: &[f64] = &[0.008778014929328892, 9.002944820056254e-6, 0.0, 0.0];
    plant
        .propagate(&at(mean, None), 0.0, &mut x, &mut y)
        .unwrap();
    let reference = plant.placed_indicators();
    let beyond: &[f64] = &[0.028959430966244384, 9.002944820056254e-6, 0.0, 0.0];
    let start = std::time::Instant::now();
    plant
        .propagate(&at(beyond, Some(&reference)), 0.01, &mut x, &mut y)
        .unwrap();
    let events = plant.events_in_last_propagation();
    assert!(events <= 3, "{events} events");
    // Put on the stop, released, moving in.
    assert!(x[0] < 0.02 && x[2] < 0.0, "{x:?}");
    assert!(start.elapsed().as_secs_f64() < 5.0);
}
