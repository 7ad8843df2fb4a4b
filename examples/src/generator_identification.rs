//! Paper 001 §5: on-line identification of the wind-generator set by the dual Kalman filter
//! (DKF) alone and by the DKF-rsKF (rsKF cleaning the outputs, then the DKF; 001 Fig. 2) as
//! two connected FMUs, under white noise and spurious samples from the acquisition card.
//!
//! System `examples/generator_identification/system.toml`: two `SignalSource`s (random steps
//! of the drive and field references) → `WindGenerator` → `LinearSystem2` (the tachometer's
//! and the voltage transducer's gains: the card's volts) → `Sensor2` (noise variance 0.1 V²
//! on speed, 0.01 V² on voltage, 5 % spikes ±U(0, 4.8) V) → `DualKalmanFilterGenerator`
//! (n = 8, m = 2, p = 2) alone, and `RobustKalmanFilter2` → `DualKalmanFilterGenerator` (the
//! references reach it through a one-sample delay, so it pairs u_k with the cleaned y_k).
//!
//! **Timing.** The estimators have no direct feedthrough: the DKF's ŷ_k (after
//! `fmi2DoStep(t_k)`) is recorded at t_{k+1}; the chain's ŷ_k at t_{k+2} (the cleaner's
//! sample k reaches its DKF at t_{k+1}). E_res = (1/N) Σ_k (ŷ_k − y_clean,k)² (001 §4) is
//! computed with that alignment, per channel, over k = 0 … N − 2.

use super::{ExperimentContext, Report, Row};
use crate::plot::{panels_png, Line, Panel, Style};
use crate::runner::{
    column, mean_std, mean_std_of, monte_carlo, pm, simulate, start_value, write_csv, Edit,
};
use anyhow::Result;
use nalgebra::{DMatrix, DVector};
use spurio::estimation::{
    DualKalmanConfig, DualKalmanFilter, GaussianModel, InfluenceFunction, RobustKalmanFilter,
};
use spurio::state_space::StateSpace;
use spurio_master::System;
use spurio_master::TimeSeries;
use std::time::Instant;

const EXPERIMENT: &str = "generator_identification";
/// docs/experiments.md §4's independent reference: DKF-rsKF and DKF alone, E_res (speed, voltage).
const REFERENCE_CHAIN: [f64; 2] = [0.024, 0.021];
const REFERENCE_DKF: [f64; 2] = [0.10, 0.23];
/// The channels, in order.
const CHANNELS: [&str; 2] = ["speed", "voltage"];

/// E_res of the recorded estimate `estimate` against `clean`, the estimate of sample k
/// recorded `lag` rows later.
fn e_res(series: &TimeSeries, estimate: &str, clean: &str, lag: usize) -> Result<f64> {
    let y = column(series, estimate)?;
    let c = column(series, clean)?;
    let n = c.len().saturating_sub(2);
    anyhow::ensure!(n > 0 && y.len() >= n + lag, "too few samples recorded");
    Ok((0..n).map(|k| (y[k + lag] - c[k]).powi(2)).sum::<f64>() / n as f64)
}

/// Per run: E_res of DKF alone, DKF-rsKF and the cleaner alone, speed then voltage.
#[derive(Debug, Clone, Copy)]
struct Scores {
    dkf: [f64; 2],
    chain: [f64; 2],
    cleaner: [f64; 2],
}

fn scores(series: &TimeSeries) -> Result<Scores> {
    let mut s = Scores {
        dkf: [0.0; 2],
        chain: [0.0; 2],
        cleaner: [0.0; 2],
    };
    for ch in 0..2 {
        let clean = format!("card.y_clean[{}]", ch + 1);
        s.dkf[ch] = e_res(series, &format!("dkf.y_hat[{}]", ch + 1), &clean, 1)?;
        s.chain[ch] = e_res(series, &format!("dkf_rskf.y_hat[{}]", ch + 1), &clean, 2)?;
        s.cleaner[ch] = e_res(series, &format!("cleaner.y_hat[{}]", ch + 1), &clean, 1)?;
    }
    Ok(s)
}

/// Run `seed`: the card's noise and outliers and both references' steps all change.
fn seed_edits(seed: u32) -> Vec<Edit<'static>> {
    let s = i64::from(seed);
    vec![
        ("card.seed", s.into()),
        ("drive_ref.seed", (1000 + 2 * s).into()),
        ("field_ref.seed", (1001 + 2 * s).into()),
    ]
}

fn matrix(
    system: &System,
    instance: &str,
    name: &str,
    rows: usize,
    cols: usize,
) -> Result<DMatrix<f64>> {
    let mut m = DMatrix::zeros(rows, cols);
    for i in 0..rows {
        for j in 0..cols {
            m[(i, j)] = start_value(system, &format!("{instance}.{name}[{},{}]", i + 1, j + 1))?;
        }
    }
    Ok(m)
}

fn vector(system: &System, instance: &str, name: &str, n: usize) -> Result<DVector<f64>> {
    (0..n)
        .map(|i| start_value(system, &format!("{instance}.{name}[{}]", i + 1)))
        .collect::<Result<Vec<_>>>()
        .map(DVector::from_vec)
}

/// The library filters with the settings of the system's `dkf` and `cleaner` instances.
fn library_filters(system: &System) -> Result<(DualKalmanFilter, RobustKalmanFilter)> {
    let (n, m, p) = (8, 2, 2);
    let mut config = DualKalmanConfig::new(GaussianModel {
        system: StateSpace {
            a: matrix(system, "dkf", "A", n, n)?,
            b: matrix(system, "dkf", "B", n, m)?,
            c: matrix(system, "dkf", "C", p, n)?,
            d: matrix(system, "dkf", "D", p, m)?,
            q: matrix(system, "dkf", "Q", n, n)?,
            r: matrix(system, "dkf", "R", p, p)?,
        },
        x0: vector(system, "dkf", "x0", n)?,
        p0: matrix(system, "dkf", "P0", n, n)?,
    })
    .fix_output_matrices();
    let rows = n + p;
    for row in 0..n {
        for col in 0..n + m {
            config.parameter_q[(row, col)] = start_value(system, "dkf.q_theta")?;
            config.parameter_p0[(row, col)] = start_value(system, "dkf.p0_theta")?;
        }
    }
    config.parameter_r = DVector::from_element(rows, start_value(system, "dkf.r_theta")?);
    let dkf = DualKalmanFilter::new(config)?;
    let cleaner = RobustKalmanFilter::new(
        GaussianModel {
            system: StateSpace {
                a: matrix(system, "cleaner", "A", p, p)?,
                b: DMatrix::zeros(p, 0),
                c: matrix(system, "cleaner", "C", p, p)?,
                d: DMatrix::zeros(p, 0),
                q: matrix(system, "cleaner", "Q", p, p)?,
                r: matrix(system, "cleaner", "R", p, p)?,
            },
            x0: vector(system, "cleaner", "x0", p)?,
            p0: matrix(system, "cleaner", "P0", p, p)?,
        },
        InfluenceFunction::Huber {
            c: start_value(system, "cleaner.c")?,
        },
    )?;
    Ok((dkf, cleaner))
}

/// Cost per iteration (mean ± std over the run's samples, like 001 §5's 1500 iterations) of
/// the DKF alone and of rsKF + DKF, in µs, on the recorded inputs and measurements.
fn cost_per_iteration(system: &System, series: &TimeSeries) -> Result<([f64; 2], [f64; 2])> {
    let col = |n: &str| column(series, n);
    let (u1, u2, y1, y2) = (
        col("drive_ref.y")?,
        col("field_ref.y")?,
        col("card.y[1]")?,
        col("card.y[2]")?,
    );
    let none = DVector::zeros(0);
    let mut dkf_times = Vec::new();
    let mut chain_times = Vec::new();
    for _ in 0..3 {
        let (mut dkf, _) = library_filters(system)?;
        let (mut dual, mut cleaner) = library_filters(system)?;
        dkf_times.clear();
        chain_times.clear();
        for k in 0..u1.len() {
            let u = DVector::from_vec(vec![u1[k], u2[k]]);
            let y = DVector::from_vec(vec![y1[k], y2[k]]);
            let t0 = Instant::now();
            dkf.step(&u, &y)?;
            let t1 = Instant::now();
            cleaner.step(&none, &y)?;
            let cleaned = cleaner.output().clone();
            dual.step(&u, &cleaned)?;
            let t2 = Instant::now();
            dkf_times.push((t1 - t0).as_secs_f64() * 1e6);
            chain_times.push((t2 - t1).as_secs_f64() * 1e6);
        }
    }
    let (a, b) = mean_std(&dkf_times);
    let (c, d) = mean_std(&chain_times);
    Ok(([a, b], [c, d]))
}

/// E_res of every run, mean ± std over the seeds: DKF alone, DKF-rsKF, the cleaner alone.
struct Summary {
    dkf: [(f64, f64); 2],
    chain: [(f64, f64); 2],
    cleaner: [(f64, f64); 2],
    /// DKF-rsKF / DKF alone, per channel.
    ratio: [f64; 2],
}

impl Summary {
    fn new(runs: &[Scores]) -> Self {
        let per_channel =
            |pick: fn(&Scores) -> [f64; 2]| [0, 1].map(|ch| mean_std_of(runs, |s| pick(s)[ch]));
        let (dkf, chain) = (per_channel(|s| s.dkf), per_channel(|s| s.chain));
        Self {
            dkf,
            chain,
            cleaner: per_channel(|s| s.cleaner),
            ratio: [0, 1].map(|ch| chain[ch].0 / dkf[ch].0),
        }
    }
}

/// The table: per channel E_res and ratio, then the cost per iteration.
fn rows(sum: &Summary, dkf_cost: [f64; 2], chain_cost: [f64; 2]) -> Vec<Row> {
    let mut rows = Vec::new();
    for (ch, channel) in CHANNELS.iter().enumerate() {
        rows.push(Row::goal(
            &format!("E_res DKF-rsKF, {channel} [V²]"),
            format!(
                "≈ {} (docs/experiments.md §4 reference)",
                REFERENCE_CHAIN[ch]
            ),
            pm(sum.chain[ch], 4),
            "≤ 0.03",
            sum.chain[ch].0 <= 0.03,
        ));
        rows.push(Row::info(
            &format!("E_res DKF alone, {channel} [V²]"),
            format!("≈ {} (docs/experiments.md §4 reference)", REFERENCE_DKF[ch]),
            pm(sum.dkf[ch], 4),
        ));
        rows.push(Row::goal(
            &format!("DKF-rsKF / DKF alone, {channel}"),
            format!("{:.2}", REFERENCE_CHAIN[ch] / REFERENCE_DKF[ch]),
            format!("{:.3}", sum.ratio[ch]),
            "≤ 1/3",
            sum.ratio[ch] <= 1.0 / 3.0,
        ));
        rows.push(Row::info(
            &format!("E_res rsKF cleaner alone, {channel} [V²]"),
            "—",
            pm(sum.cleaner[ch], 4),
        ));
    }
    rows.push(Row::info(
        "cost per iteration, DKF-rsKF (rsKF + DKF, n = 8, library)",
        "12.0 ± 3.9 ms (Matlab R2009a)",
        format!("{:.1} ± {:.1} µs", chain_cost[0], chain_cost[1]),
    ));
    rows.push(Row::info(
        "cost per iteration, DKF alone",
        "10.9 ± 0.77 ms",
        format!("{:.1} ± {:.1} µs", dkf_cost[0], dkf_cost[1]),
    ));
    rows
}

/// Runs the experiment (module documentation).
pub fn run(ctx: &ExperimentContext) -> Result<Report> {
    let system = ctx.system(EXPERIMENT, "system.toml")?;
    let representative = simulate(&system)?;
    write_csv(
        &representative,
        &ctx.out_dir.join("generator_identification_seed.csv"),
    )?;
    figures(ctx, &representative)?;
    let (dkf_cost, chain_cost) = cost_per_iteration(&system, &representative)?;
    let runs = monte_carlo(ctx, &system, &ctx.seed_list(), seed_edits, scores)?;
    let sum = Summary::new(&runs);
    Ok(Report {
        rows: rows(&sum, dkf_cost, chain_cost),
        title: "Wind-generator identification under outliers (paper 001 §5)".into(),
        setup: format!(
            "SignalSource ×2 (random steps of the drive and field references, levels U[6, 10] V and U[5, 9] V held 2–8 s) → WindGenerator (8 states, from the 8 V / 7 V steady state) → LinearSystem2 as the tachometer (5 V per 1000 rpm) and voltage transducer (1/30) → Sensor2 (the card: noise variance 0.1 V² on speed, 0.01 V² on voltage, 5 % spikes ±U(0, 4.8) V) → DualKalmanFilterGenerator alone, and RobustKalmanFilter2 → DualKalmanFilterGenerator (paper 001 Fig. 2, two connected FMUs). Ts = 0.1 s, 150 s (1500 samples, the paper's run length); E_res against the clean card signal, mean ± std over {} runs (card, drive and field seeds all varied).",
            ctx.seeds
        ),
        figures: vec![
            (
                "generator_dkf.png".into(),
                "DKF alone follows the spurious samples (paper 001 Fig. 5): measured (grey points), clean and DKF output".into(),
            ),
            (
                "generator_dkf_rskf.png".into(),
                "DKF-rsKF does not (paper 001 Fig. 7): measured, clean and DKF-rsKF output".into(),
            ),
            (
                "generator_zoom.png".into(),
                "Zoom on 30 s of the run (paper 001 Figs. 6 and 8): both estimates against the clean signal".into(),
            ),
        ],
        notes: vec![
            "Units: the paper's DKF is fed the NI USB-6009's voltages (±10 V), and noise variances of 0.1 and 0.01 (and E_res ≈ 0.02) only make sense there, not in rpm and volts RMS. We model the signal conditioning explicitly: tachogenerator 5 V / 1000 rpm (1800 rpm → 9 V), voltage transducer 1/30 (240 V → 8 V); all E_res are in V² at the card.".into(),
            "Settings (same for both DKFs): Θ₀ = [I 0; C 0] with C = [I₂ 0] fixed, Q = 0.01 I₈, R = diag(0.1, 0.01) (the card's noise), P₀ = I, q_θ = 1e-6, r_θ = 0.1 (the paper's 0.5 adapts too slowly), x̂₀ at the initial operating point's readings (7.2 V, 5.73 V) — started from x̂₀ = 0 the DKF learns the start-up jump as dynamics and needs most of the run to forget it. Cleaner: random walk per channel, Q = diag(0.1, 0.02), R = diag(0.1, 0.01), Huber c = 1.645 (5 % contamination).".into(),
            "The cleaner has no direct feedthrough, so its cleaned sample k reaches the second DKF at t_(k+1); a one-sample delay (LinearSystem2 with A = 0, B = C = I) on the references keeps that DKF's (u_k, y_k) pairs consistent. Feeding it u_(k+1) with y_k instead costs little once identified, but a wrong start-up pair is learnt as dynamics.".into(),
            "Cost: the library's DKF and rsKF steps timed on this run's 1500 samples (3 passes, mean ± std per iteration, one core), i.e. the algorithm as the paper timed its Matlab code. Through the FMU interface (`cargo bench -p spurio-fmu-common --bench estimators`: fmi2SetReal + fmi2DoStep + fmi2GetReal of all 92 outputs) one DKF-rsKF sample costs about 4 µs. Either way three to four orders of magnitude below the paper's 12 ms.".into(),
            "docs/experiments.md §4's reference figures come from an independent implementation with its own plant, scaling and outlier model; they are beside ours for scale, not for exact agreement.".into(),
            "Representative run (seed of the TOML): generator_identification_seed.csv.".into(),
        ],
        figures_of_merit: vec![
            ("e_res_chain_speed".into(), sum.chain[0].0),
            ("e_res_chain_voltage".into(), sum.chain[1].0),
            ("e_res_dkf_speed".into(), sum.dkf[0].0),
            ("e_res_dkf_voltage".into(), sum.dkf[1].0),
            ("ratio_speed".into(), sum.ratio[0]),
            ("ratio_voltage".into(), sum.ratio[1]),
            ("cost_chain_us".into(), chain_cost[0]),
            ("cost_dkf_us".into(), dkf_cost[0]),
        ],
    })
}

/// Sample numbers 0 … n − 1 as an x axis.
fn samples(n: usize) -> Vec<f64> {
    (0..n).map(|k| k as f64).collect()
}

/// The recorded `name` over samples `range`, the estimate of sample k recorded `lag` rows
/// later (so the line sits at its sample).
fn at_samples(
    series: &TimeSeries,
    name: &str,
    lag: usize,
    range: std::ops::Range<usize>,
) -> Result<(Vec<f64>, Vec<f64>)> {
    let values = column(series, name)?;
    let end = range.end.min(values.len().saturating_sub(lag));
    let start = range.start.min(end);
    Ok((
        samples(end)[start..].to_vec(),
        values[start + lag..end + lag].to_vec(),
    ))
}

/// One channel's panel: measured, clean and the estimates `(legend, instance, lag)`.
fn channel_panel(
    series: &TimeSeries,
    ch: usize,
    estimates: &[(&str, &str, usize)],
    range: std::ops::Range<usize>,
) -> Result<Panel> {
    let signal =
        |name: &str, lag| at_samples(series, &format!("{name}[{}]", ch + 1), lag, range.clone());
    let (xm, ym) = signal("card.y", 0)?;
    let (xc, yc) = signal("card.y_clean", 0)?;
    let mut lines = vec![
        Line::new("measured", xm, ym).style(Style::Points),
        Line::new("clean", xc, yc),
    ];
    for (legend, instance, lag) in estimates {
        let (x, y) = signal(&format!("{instance}.y_hat"), *lag)?;
        lines.push(Line::new(*legend, x, y));
    }
    Ok(Panel {
        label: format!("{} channel [V]", CHANNELS[ch]),
        lines,
    })
}

/// The paper's Figs. 5–8 from the representative run (estimates shifted to their sample).
fn figures(ctx: &ExperimentContext, series: &TimeSeries) -> Result<()> {
    let all = 0..series.time.len();
    let x_label = "sample k (Tₛ = 0.1 s)";
    for (file, estimates, title) in [
        (
            "generator_dkf.png",
            [("estimate", "dkf", 1)],
            "DKF alone on the card's samples",
        ),
        (
            "generator_dkf_rskf.png",
            [("estimate", "dkf_rskf", 2)],
            "DKF-rsKF (rsKF → DKF, two FMUs)",
        ),
    ] {
        let panels = (0..2)
            .map(|ch| channel_panel(series, ch, &estimates, all.clone()))
            .collect::<Result<Vec<_>>>()?;
        panels_png(&ctx.out_dir.join(file), title, x_label, &panels)?;
    }
    let both = [("DKF", "dkf", 1), ("DKF-rsKF", "dkf_rskf", 2)];
    let panels = (0..2)
        .map(|ch| channel_panel(series, ch, &both, 600..900))
        .collect::<Result<Vec<_>>>()?;
    panels_png(
        &ctx.out_dir.join("generator_zoom.png"),
        "Samples 600–900",
        x_label,
        &panels,
    )
}
