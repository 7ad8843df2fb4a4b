//! Model Exchange import on the Reference FMUs (FMI 2.0 and 3.0): BouncingBall's bounces at
//! the closed-form times, Stair's time events on the integer seconds, and clear errors; on our
//! FMUs, the directional derivatives against differences and WindGenerator's stiff start-up
//! with the stiff method in fewer right-hand sides than the explicit one.

mod common;

use spurio_master::fmu::me::MeInstance;
use spurio_master::fmu::{
    CallError, Experiment, FmuFile, Interface, LoadError, LoadOptions, VarType,
};
use spurio_master::model_exchange::{
    event_time_tolerance, simulate, Event, EventKind, EventUpdate, MeError, ModelExchangeCalls,
    Options, Summary,
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
        for method in [Method::Dopri5, Method::Rodas4, Method::Rodas3] {
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

/// An ME instance whose every call goes to `inner`; after every `every`-th accepted step
/// (`CompletedIntegratorStep`, the FMU then holding the accepted state) it compares the
/// FMU's directional derivatives `∂ẋ/∂x · eⱼ` with central differences of `GetDerivatives`
/// and keeps the worst relative difference (to the column's largest entry plus
/// `1e-6 ·` the matrix's largest).
struct JacobianCheck<'a> {
    inner: &'a mut MeInstance,
    every: usize,
    steps: usize,
    checked: usize,
    worst: f64,
}

impl JacobianCheck<'_> {
    fn compare(&mut self) -> Result<(), spurio_master::fmu::CallError> {
        let n = self.inner.description().states;
        let (mut x, mut nominal) = (vec![0.0; n], vec![0.0; n]);
        self.inner.get_continuous_states(&mut x)?;
        self.inner.get_nominals(&mut nominal)?;
        let (mut given, mut differences) = (vec![0.0; n * n], vec![0.0; n * n]);
        let (mut plus, mut minus, mut seed) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
        for j in 0..n {
            seed.fill(0.0);
            seed[j] = 1.0;
            assert!(self
                .inner
                .directional_derivative(&seed, &mut given[j * n..(j + 1) * n])?);
            let delta = 1e-6 * x[j].abs().max(nominal[j].abs().max(1e-3));
            let mut y = x.clone();
            y[j] = x[j] + delta;
            self.inner.set_continuous_states(&y)?;
            self.inner.get_derivatives(&mut plus)?;
            y[j] = x[j] - delta;
            self.inner.set_continuous_states(&y)?;
            self.inner.get_derivatives(&mut minus)?;
            for i in 0..n {
                differences[i + j * n] = (plus[i] - minus[i]) / (2.0 * delta);
            }
        }
        self.inner.set_continuous_states(&x)?;
        let largest = given.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        for j in 0..n {
            let column = &given[j * n..(j + 1) * n];
            let scale = column.iter().fold(0.0f64, |m, v| m.max(v.abs())) + 1e-6 * largest;
            for i in 0..n {
                let d = (column[i] - differences[i + j * n]).abs() / scale.max(1e-300);
                self.worst = self.worst.max(d);
            }
        }
        self.checked += 1;
        Ok(())
    }
}

impl ModelExchangeCalls for JacobianCheck<'_> {
    fn name(&self) -> String {
        self.inner.name()
    }
    fn is_fmi3(&self) -> bool {
        self.inner.is_fmi3()
    }
    fn setup_experiment(&mut self, e: Experiment) -> Result<(), CallError> {
        self.inner.setup_experiment(e)
    }
    fn set(&mut self, t: VarType, vrs: &[u32], values: &[f64]) -> Result<(), CallError> {
        self.inner.set(t, vrs, values)
    }
    fn get(&mut self, t: VarType, vrs: &[u32], out: &mut [f64]) -> Result<(), CallError> {
        self.inner.get(t, vrs, out)
    }
    fn enter_initialization_mode(&mut self, e: Experiment) -> Result<(), CallError> {
        self.inner.enter_initialization_mode(e)
    }
    fn exit_initialization_mode(&mut self) -> Result<(), CallError> {
        self.inner.exit_initialization_mode()
    }
    fn enter_event_mode(&mut self) -> Result<(), CallError> {
        self.inner.enter_event_mode()
    }
    fn update_discrete_states(&mut self) -> Result<EventUpdate, CallError> {
        self.inner.update_discrete_states()
    }
    fn enter_continuous_time_mode(&mut self) -> Result<(), CallError> {
        self.inner.enter_continuous_time_mode()
    }
    fn completed_integrator_step(&mut self) -> Result<(bool, bool), CallError> {
        self.steps += 1;
        if self.steps.is_multiple_of(self.every) {
            self.compare()?;
        }
        self.inner.completed_integrator_step()
    }
    fn set_time(&mut self, time: f64) -> Result<(), CallError> {
        self.inner.set_time(time)
    }
    fn set_continuous_states(&mut self, x: &[f64]) -> Result<(), CallError> {
        self.inner.set_continuous_states(x)
    }
    fn get_continuous_states(&mut self, x: &mut [f64]) -> Result<(), CallError> {
        self.inner.get_continuous_states(x)
    }
    fn get_nominals(&mut self, nominals: &mut [f64]) -> Result<(), CallError> {
        self.inner.get_nominals(nominals)
    }
    fn get_derivatives(&mut self, dx: &mut [f64]) -> Result<(), CallError> {
        self.inner.get_derivatives(dx)
    }
    fn get_event_indicators(&mut self, z: &mut [f64]) -> Result<(), CallError> {
        self.inner.get_event_indicators(z)
    }
    fn directional_derivative(&mut self, seed: &[f64], out: &mut [f64]) -> Result<bool, CallError> {
        self.inner.directional_derivative(seed, out)
    }
    fn terminate(&mut self) -> Result<(), CallError> {
        self.inner.terminate()
    }
}

/// Runs one of our packaged FMUs (FMI 2.0) for Model Exchange over its default experiment
/// with `method` at `tolerance`, checking its Jacobian every `every` steps (0: never).
fn run_ours(
    name: &str,
    method: Method,
    tolerance: f64,
    every: usize,
) -> (TimeSeries, Summary, f64) {
    let path = common::fmus().join(format!("{name}.fmu"));
    let fmu = FmuFile::open_for(&path, &LoadOptions::default(), Interface::ModelExchange).unwrap();
    let mut instance = fmu.instantiate_model_exchange("me", false).unwrap();
    let layout = instance.layout(&fmu, &[]).unwrap();
    let experiment = instance.description().default_experiment;
    let options = Options {
        method,
        tolerance,
        ..Options::new(
            experiment.start_time.unwrap_or(0.0),
            experiment.stop_time.unwrap_or(1.0),
            experiment.step_size.unwrap_or(0.01),
        )
    };
    let mut check = JacobianCheck {
        inner: &mut instance,
        every: if every == 0 { usize::MAX } else { every },
        steps: 0,
        checked: 0,
        worst: 0.0,
    };
    let mut series = TimeSeries::default();
    let summary = simulate(&mut check, &layout, &options, &mut series, &mut |_| {}).unwrap();
    if every > 0 {
        assert!(check.checked > 0, "{name}: no step checked");
    }
    let worst = check.worst;
    (series, summary, worst)
}

/// The largest |a − b| over every recorded output, relative to the output's range in `b`.
fn worst_relative_difference(a: &TimeSeries, b: &TimeSeries) -> f64 {
    assert_eq!(a.time, b.time);
    let mut worst = 0.0f64;
    for name in &b.names {
        let (x, y) = (a.column(name).unwrap(), b.column(name).unwrap());
        let (lo, hi) = y
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), v| {
                (l.min(*v), h.max(*v))
            });
        let range = (hi - lo).max(1e-12);
        for (p, q) in x.iter().zip(&y) {
            worst = worst.max((p - q).abs() / range);
        }
    }
    worst
}

#[test]
fn our_fmus_directional_derivatives_equal_finite_differences_along_a_run() {
    for name in [
        "GantryCrane",
        "WindGenerator",
        "OpAmpFilter",
        "LinearSystem",
        "LinearSystem2",
    ] {
        let (_, summary, worst) = run_ours(name, Method::Rodas4, 1e-6, 3);
        let s = summary.statistics;
        eprintln!("{name}: worst |J v − differences| {worst:.1e}, {s:?}");
        assert!(worst < 1e-5, "{name}: {worst:e}");
        // the solver took its Jacobians from them: one call per state and Jacobian
        assert!(s.jacobians > 0 && s.jacobian_products > 0, "{name}: {s:?}");
        assert!(
            s.jacobian_products.is_multiple_of(s.jacobians),
            "{name}: {s:?}"
        );
    }
}

#[test]
fn a_reference_fmu_without_directional_derivatives_is_differentiated_by_differences() {
    // BouncingBall declares no `providesDirectionalDerivative` (VanDerPol does, and gives them).
    let (_, _, summary) = run("fmi2", "BouncingBall", Method::Rodas4, (3.0, 0.01, 1e-6));
    let s = summary.statistics;
    eprintln!("BouncingBall rodas4: {s:?}");
    assert!(s.jacobians > 0, "{s:?}");
    assert_eq!(s.jacobian_products, 0, "{s:?}");
}

#[test]
fn wind_generator_stiff_method_fewer_right_hand_sides_than_dopri5_at_equal_accuracy() {
    // The reference: DOPRI5 at 10⁻¹⁰; the two methods at 10⁻⁶ and 10⁻⁸.
    let (reference, _, _) = run_ours("WindGenerator", Method::Dopri5, 1e-10, 0);
    for tolerance in [1e-6, 1e-8] {
        let (stiff, stiff_summary, _) = run_ours("WindGenerator", Method::Rodas4, tolerance, 0);
        let (explicit, explicit_summary, _) =
            run_ours("WindGenerator", Method::Dopri5, tolerance, 0);
        let (s, e) = (stiff_summary.statistics, explicit_summary.statistics);
        let stiff_error = worst_relative_difference(&stiff, &reference);
        let explicit_error = worst_relative_difference(&explicit, &reference);
        eprintln!(
            "tolerance {tolerance:e}: rodas4 {} right-hand sides + {} directional derivatives, \
             error {stiff_error:.1e} of the range; dopri5 {} right-hand sides, error \
             {explicit_error:.1e}",
            s.rhs, s.jacobian_products, e.rhs
        );
        // As accurate (within the tolerance's order), in fewer derivative calls even counting
        // each directional derivative as one.
        assert!(stiff_error < 10.0 * tolerance, "{stiff_error:e}");
        assert!(
            stiff_error <= 2.0 * explicit_error,
            "{stiff_error:e} {explicit_error:e}"
        );
        assert!(2 * s.rhs < e.rhs, "{s:?} {e:?}");
        assert!(s.rhs + s.jacobian_products < e.rhs, "{s:?} {e:?}");
    }
}
