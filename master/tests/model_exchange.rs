//! Model Exchange import on the Reference FMUs (FMI 2.0 and 3.0): BouncingBall's bounces at
//! the closed-form times, Stair's time events on the integer seconds, and clear errors.

mod common;

use spurio_master::fmu::me::MeInstance;
use spurio_master::fmu::{FmuFile, Interface, LoadError, LoadOptions};
use spurio_master::model_exchange::{
    event_time_tolerance, simulate, Event, EventKind, MeError, Options, Summary,
};
use spurio_master::TimeSeries;
use spurio_solvers::Method;

/// Opens a Reference FMU for Model Exchange and instantiates it.
fn open(version: &str, model: &str) -> (FmuFile, MeInstance) {
    let fmu = FmuFile::open_for(
        &common::reference(version, model),
        &LoadOptions::default(),
        Interface::ModelExchange,
    )
    .unwrap();
    let instance = fmu.instantiate_model_exchange("me", false).unwrap();
    (fmu, instance)
}

/// Runs `model` with `method` at `tolerance` from 0 to `stop` recorded every `interval`.
fn run(
    version: &str,
    model: &str,
    method: Method,
    (stop, interval, tolerance): (f64, f64, f64),
) -> (TimeSeries, Vec<Event>, Summary) {
    let (fmu, mut instance) = open(version, model);
    let layout = instance.layout(&fmu, &[]).unwrap();
    let options = Options {
        method,
        tolerance,
        ..Options::new(0.0, stop, interval)
    };
    let mut series = TimeSeries::default();
    let mut events = Vec::new();
    let summary = simulate(&mut instance, &layout, &options, &mut series, &mut |e| {
        events.push(*e)
    })
    .unwrap();
    (series, events, summary)
}

/// The bounce times of a ball dropped from `h0` under `g`, restitution `e`, until the speed
/// after a bounce is below `v_min` (that bounce included).
fn bounce_times(h0: f64, g: f64, e: f64, v_min: f64) -> Vec<f64> {
    let mut t = (2.0 * h0 / g).sqrt();
    let mut v = g * t;
    let mut times = vec![t];
    loop {
        v *= e;
        if v < v_min {
            return times;
        }
        t += 2.0 * v / g;
        times.push(t);
    }
}

#[test]
fn bouncing_ball_bounces_at_the_closed_form_times() {
    let expected = bounce_times(1.0, 9.81, 0.7, 0.1);
    for version in ["fmi2", "fmi3"] {
        for method in [Method::Dopri5, Method::Rodas3] {
            let (series, events, summary) = run(version, "BouncingBall", method, (3.0, 0.01, 1e-8));
            let bounces: Vec<f64> = events
                .iter()
                .filter(|e| matches!(e.kind, EventKind::State { indicator: 0 }))
                .map(|e| e.time)
                .collect();
            let worst = bounces
                .iter()
                .zip(&expected)
                .map(|(a, b)| (a - b).abs())
                .fold(0.0, f64::max);
            eprintln!(
                "{version} {method}: {} bounces, worst error {worst:.2e} s, {:?}",
                bounces.len(),
                summary.statistics
            );
            assert_eq!(
                bounces.len(),
                expected.len(),
                "{version} {method}: {bounces:?}"
            );
            assert!(worst < 1e-8, "{version} {method}: {worst:e}");
            // the ball rests on the floor afterwards, and the rows end at the stop time
            let h = series.column("h").unwrap();
            assert!(h.last().unwrap().abs() < 1e-9, "{:?}", h.last());
            assert_eq!(*series.time.last().unwrap(), 3.0);
            assert_eq!(series.time.len(), 301);
            assert!(event_time_tolerance(2.0) == 2e-12);
        }
    }
}

#[test]
fn stair_time_events_land_on_the_integer_seconds() {
    for version in ["fmi2", "fmi3"] {
        let (series, events, summary) = run(version, "Stair", Method::Dopri5, (10.0, 0.1, 1e-6));
        let times: Vec<f64> = events
            .iter()
            .filter(|e| e.kind == EventKind::Time)
            .map(|e| e.time)
            .collect();
        eprintln!("{version}: time events {times:?}, {summary:?}");
        assert!(!times.is_empty());
        for (k, t) in times.iter().enumerate() {
            assert_eq!(*t, (k + 1) as f64, "{version}: event {k} at {t:?}");
        }
        // the counter steps at each second: at t = k.0 it reads k + 1 (after the event)
        let counter = series.column("counter").unwrap();
        for (t, c) in series.time.iter().zip(&counter) {
            if *t <= summary.end_time && *t < times.len() as f64 + 0.5 {
                assert_eq!(*c, t.floor() + 1.0, "{version} at t = {t}");
            }
        }
    }
}

#[test]
fn a_co_simulation_only_fmu_is_refused_for_model_exchange_by_name() {
    let source = common::fmus().join("SignalSource.fmu");
    let e =
        FmuFile::open_for(&source, &LoadOptions::default(), Interface::ModelExchange).unwrap_err();
    assert!(matches!(e, LoadError::NotModelExchange { .. }), "{e}");
    assert!(e.to_string().contains("SignalSource.fmu"), "{e}");
    assert!(e.to_string().contains("<ModelExchange>"), "{e}");
    // and the FMU still loads for Co-Simulation
    FmuFile::open(&source).unwrap();
}

#[test]
fn errors_name_the_fmu_the_call_and_the_time() {
    // Dahlquist with a stop time before the start: a layout error naming the FMU.
    let (fmu, mut instance) = open("fmi2", "Dahlquist");
    let layout = instance.layout(&fmu, &[]).unwrap();
    let e = simulate(
        &mut instance,
        &layout,
        &Options::new(1.0, 0.0, 0.1),
        &mut TimeSeries::default(),
        &mut |_| {},
    )
    .unwrap_err();
    assert!(matches!(e, MeError::Layout { .. }), "{e}");
    assert!(e.to_string().contains("Dahlquist.fmu"), "{e}");
    // An unknown start value name.
    let e = instance
        .layout(&fmu, &[("nobody".into(), 1.0)])
        .unwrap_err();
    assert!(e.contains("nobody"), "{e}");
}
