//! What a 0.1 s WindGenerator step costs, in two parts.
//!
//! **Work against precision** (the math crate's integrators, no FMI): 10 s from rest with the
//! references below, sampled every 0.1 s; the error is the largest deviation of speed and
//! voltage from a tightly-toleranced reference (RK4 on 10⁻⁵ s substeps, ten times finer than
//! the former default; its own error ≈ 4·10⁻¹⁵ of rated), relative to 1800 rpm and 240 V. For
//! each accuracy of the ladder 10⁻⁶ … 10⁻¹¹ of rated: the default integrator (DOP853) at the
//! loosest tolerance of a sweep that reaches it, RK4 at the largest substep of a sweep that
//! reaches it, and RODAS3 the same, each with its right-hand sides per 0.1 s (exact) and its
//! time per 0.1 s (median and minimum of interleaved repetitions: on a loaded machine the
//! minimum is the steadier estimate of what the arithmetic costs), and the ratio of RK4's time
//! to DOP853's.
//!
//! **Through the FMU's entry points** (`fmi2SetReal` of both references, `fmi2DoStep`,
//! `fmi2GetReal` of speed and voltage): the default against `fixed_step_rk4` at
//! h_max = 10⁻⁴ s (the former default), interleaved batch by batch.
//!
//! Run: `cargo bench -p fmu-wind-generator --bench step`.

use ::WindGenerator::{vr, WindGeneratorFmu};
use spurio::plants::wind_generator::{
    Adaptive, WindGenerator as Generator, WindGeneratorParameters,
};
use spurio_export::harness::{time_per_call, Harness, Timing};
use spurio_export::Config;
use std::hint::black_box;

/// The references at step `k`: levels in [6, 10] V (drive) and [5, 9] V (field), each held
/// for 20–40 steps of 0.1 s (the identification experiment's kind of signal: the generator is
/// never long at rest, so most steps carry a transient).
fn references(k: u64) -> [f64; 2] {
    let segment = k / 30 + (k / 70);
    [
        6.0 + (segment * 7 % 5) as f64,
        5.0 + (segment * 3 % 5) as f64,
    ]
}

/// Communication steps of the work–precision scenario (10 s).
const STEPS: u64 = 100;

/// An integrator of the comparison: advances a generator by one 0.1 s step at the references
/// and returns the right-hand sides it evaluated.
type Integrator = Box<dyn FnMut(&mut Generator, [f64; 2]) -> usize>;

/// RK4 on substeps of `0.1 / n` s.
fn rk4(n: usize) -> Integrator {
    let mut t = 0.0;
    Box::new(move |g, [u_drive, u_field]| {
        g.advance(t, u_drive, u_field, 0.1, 0.1 / n as f64);
        t += 0.1;
        4 * n
    })
}

/// An adaptive integrator at `rtol`: DOP853 (the default) or RODAS3, its work counted in
/// right-hand sides (RODAS3 also forms a Jacobian and factors an 8 × 8 matrix per step).
fn adaptive(integrator: Adaptive, rtol: f64) -> Integrator {
    let tolerance = Generator::tolerance(rtol);
    let mut step = 1e-3;
    Box::new(move |g, references| {
        let s = g
            .advance_adaptive(integrator, references.into(), 0.1, &tolerance, &mut step)
            .expect("adaptive step");
        match integrator {
            Adaptive::Dop853 => 12 * s.accepted + 11 * s.rejected + 1,
            Adaptive::Rodas3 => 3 * (s.accepted + s.rejected),
        }
    })
}

/// The scenario with `integrator`: (speed, voltage) at each sample and the right-hand sides.
fn run(mut integrator: Integrator) -> (Vec<[f64; 2]>, usize) {
    let mut g = Generator::new(WindGeneratorParameters::default()).expect("parameters");
    let mut evaluations = 0;
    let samples = (0..STEPS)
        .map(|k| {
            evaluations += integrator(&mut g, references(k));
            [g.speed_rpm(), g.terminal_voltage()]
        })
        .collect();
    (samples, evaluations)
}

/// Largest deviation from `reference`, relative to 1800 rpm and 240 V.
fn error(samples: &[[f64; 2]], reference: &[[f64; 2]]) -> f64 {
    samples
        .iter()
        .zip(reference)
        .map(|(a, b)| {
            ((a[0] - b[0]) / 1800.0)
                .abs()
                .max(((a[1] - b[1]) / 240.0).abs())
        })
        .fold(0.0, f64::max)
}

/// One configuration of the sweep: its label, error and right-hand sides per 0.1 s.
struct Point {
    label: String,
    error: f64,
    evaluations: f64,
    make: Box<dyn Fn() -> Integrator>,
}

fn sweep(
    reference: &[[f64; 2]],
    settings: &[f64],
    label: impl Fn(f64) -> String,
    make: impl Fn(f64) -> Integrator + Clone + 'static,
) -> Vec<Point> {
    settings
        .iter()
        .map(|&s| {
            let (samples, evaluations) = run(make(s));
            let make = make.clone();
            Point {
                label: label(s),
                error: error(&samples, reference),
                evaluations: evaluations as f64 / STEPS as f64,
                make: Box::new(move || make(s)),
            }
        })
        .collect()
}

/// The cheapest point (fewest right-hand sides) that reaches `accuracy`.
fn cheapest(points: &[Point], accuracy: f64) -> Option<&Point> {
    points
        .iter()
        .filter(|p| p.error <= accuracy)
        .min_by(|a, b| a.evaluations.total_cmp(&b.evaluations))
}

/// Time of one 0.1 s step over one run of the scenario [µs].
fn time_per_step(make: &dyn Fn() -> Integrator) -> f64 {
    let start = std::time::Instant::now();
    black_box(run(make()));
    start.elapsed().as_secs_f64() * 1e6 / STEPS as f64
}

fn work_precision() {
    let (reference, _) = run(rk4(10_000));
    let rtols = [
        1e-5, 3e-6, 1e-6, 3e-7, 1e-7, 3e-8, 1e-8, 3e-9, 1e-9, 3e-10, 1e-10, 3e-11, 2e-11, 1e-11,
        8e-12, 7e-12, 6e-12, 5e-12, 4e-12, 3e-12, 2e-12, 1e-12,
    ];
    let substeps: Vec<f64> = [
        50, 80, 100, 125, 160, 200, 250, 320, 400, 500, 640, 800, 1000, 1250, 1600, 2000,
    ]
    .map(f64::from)
    .to_vec();
    let dop = sweep(
        &reference,
        &rtols,
        |r| format!("rtol {r:.0e}"),
        |r| adaptive(Adaptive::Dop853, r),
    );
    let rk = sweep(
        &reference,
        &substeps,
        |n| format!("h {:.3} ms", 100.0 / n),
        |n| rk4(n as usize),
    );
    let rodas = sweep(
        &reference,
        &rtols[..13],
        |r| format!("rtol {r:.0e}"),
        |r| adaptive(Adaptive::Rodas3, r),
    );
    for (name, points) in [("DOP853", &dop), ("RK4", &rk), ("RODAS3", &rodas)] {
        let listed: Vec<String> = points
            .iter()
            .map(|p| format!("{} {:.1e} ({:.0} f)", p.label, p.error, p.evaluations))
            .collect();
        println!("{name} sweep: {}", listed.join(", "));
    }
    println!(
        "Work against precision, 10 s from rest, references held 2-4 s; error = largest deviation of speed and voltage from RK4 at 1e-5 s, relative to 1800 rpm / 240 V; cost per 0.1 s step: right-hand sides (f) and µs, median (minimum) of 11 interleaved runs:"
    );
    println!(
        "{:>9} | {:>36} | {:>36} | {:>36} | {:>13}",
        "accuracy", "DOP853 (default)", "RK4 (fixed substeps)", "RODAS3", "RK4/DOP853"
    );
    for accuracy in [1e-6, 1e-7, 1e-8, 1e-9, 1e-10, 2e-11, 1e-11] {
        let chosen = [&dop, &rk, &rodas].map(|points| cheapest(points, accuracy));
        let mut times = [Vec::new(), Vec::new(), Vec::new()];
        for _ in 0..11 {
            for (point, samples) in chosen.iter().zip(times.iter_mut()) {
                if let Some(p) = point {
                    samples.push(time_per_step(&p.make));
                }
            }
        }
        let sorted = times.map(|mut v| {
            v.sort_by(|a, b| a.total_cmp(b));
            v
        });
        let medians = sorted.clone().map(|v| v.get(v.len() / 2).copied());
        let minima = sorted.map(|v| v.first().copied());
        let cell = |point: Option<&Point>, time: Option<f64>, least: Option<f64>| match (
            point, time, least,
        ) {
            (Some(p), Some(t), Some(m)) => format!(
                "{} {:.1e}, {:>4.0} f, {:>5.1} ({:.1}) µs",
                p.label, p.error, p.evaluations, t, m
            ),
            _ => "—".to_string(),
        };
        let ratio = match (medians[1], medians[0], minima[1], minima[0]) {
            (Some(rk), Some(dop), Some(rk_min), Some(dop_min)) => {
                format!("{:.1}x ({:.1}x)", rk / dop, rk_min / dop_min)
            }
            _ => "—".to_string(),
        };
        println!(
            "{accuracy:>9.0e} | {:>36} | {:>36} | {:>36} | {ratio:>13}",
            cell(chosen[0], medians[0], minima[0]),
            cell(chosen[1], medians[1], minima[1]),
            cell(chosen[2], medians[2], minima[2]),
        );
    }
    // The default tolerance (chosen on several scenarios, not only this one), timed alike.
    let default = Generator::DEFAULT_RELATIVE_TOLERANCE;
    if let Some(p) = dop
        .iter()
        .find(|p| p.label == format!("rtol {default:.0e}"))
    {
        let mut times: Vec<f64> = (0..11).map(|_| time_per_step(&p.make)).collect();
        times.sort_by(|a, b| a.total_cmp(b));
        println!(
            "  default | {} {:.1e}, {:>4.0} f, {:>5.1} ({:.1}) µs",
            p.label, p.error, p.evaluations, times[5], times[0]
        );
    }
}

/// An initialised instance (from the 8 V / 7 V steady state) with the given integrator.
fn instance(fixed_step_rk4: bool) -> Harness<WindGeneratorFmu> {
    let mut h = Harness::<WindGeneratorFmu>::new(&Config::new()).expect("instantiate");
    h.set_boolean(&[vr::FIXED_STEP_RK4 as u32], &[fixed_step_rk4])
        .expect("integrator");
    h.set_boolean(&[vr::START_AT_OPERATING_POINT as u32], &[true])
        .expect("start");
    h.set_real(&[vr::U_DRIVE_0 as u32, vr::U_FIELD_0 as u32], &[8.0, 7.0])
        .expect("start references");
    h.initialize(0.0).expect("initialize");
    h
}

/// One step closure over an instance: set, step, get.
fn stepper(fixed_step_rk4: bool) -> impl FnMut() {
    let mut h = instance(fixed_step_rk4);
    let inputs = [vr::U_DRIVE as u32, vr::U_FIELD as u32];
    let outputs = [vr::SPEED as u32, vr::VOLTAGE as u32];
    let mut out = [0.0; 2];
    let step = 0.1;
    let mut k = 0u64;
    move || {
        let t = k as f64 * step;
        h.exchange(&inputs, &references(k), (t, step), &outputs, &mut out)
            .expect("step");
        black_box(&out);
        k += 1;
    }
}

fn through_the_fmu() {
    let mut default = stepper(false);
    let mut rk4 = stepper(true);
    let rounds = 15;
    let (mut fast, mut slow) = (Vec::new(), Vec::new());
    for _ in 0..rounds {
        fast.push(time_per_call(5, 3, 40, &mut default).median);
        slow.push(time_per_call(5, 3, 40, &mut rk4).median);
    }
    let median = |v: &mut Vec<f64>| {
        v.sort_by(|a, b| a.total_cmp(b));
        Timing {
            median: v[v.len() / 2],
            q1: v[v.len() / 4],
            q3: v[3 * v.len() / 4],
        }
    };
    let (fast, slow) = (median(&mut fast), median(&mut slow));
    println!(
        "WindGenerator FMU, 0.1 s step, DOP853 rtol {:e} (default): {}",
        Generator::DEFAULT_RELATIVE_TOLERANCE,
        fast.summary("step")
    );
    println!(
        "WindGenerator FMU, 0.1 s step, RK4 h_max 1e-4 s (fixed_step_rk4, the former default): {}",
        slow.summary("step")
    );
    println!("speed-up: {:.1}x", slow.median / fast.median);
}

fn main() {
    work_precision();
    through_the_fmu();
}
