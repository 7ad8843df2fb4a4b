//! Paper 004 §5: the two-agent distributed observer of a three-state system, as FMUs.
//!
//! System `examples/distributed_observer/system.toml`: a `DistributedObserverPlant`
//! (x⁺ = A x + w, y₁ = x₁ + n₁, y₂ = x₂ + n₂, Q = 0.2 I, R = 0.1 I, x₀ = [1, 1, 1]) feeds two
//! `DistributedObserverAgent` FMUs that exchange their estimates through the master
//! (`agent1.x_hat → agent2.x_neighbour` and back), and a centralised `KalmanFilter` (n = 3,
//! m = 0, p = 2, variant `DistributedObserverCentralKalman`) on both outputs as the lower
//! bound.
//!
//! **Timing.** The agents have no direct feedthrough: after `fmi2DoStep(t_k)` with y(k) and
//! the neighbour's x̂_j(k) their `x_hat` is x̂_i(k+1), the prediction of x(k+1) (004 eq. 6),
//! recorded at t_{k+1} beside the plant's x(k+1). At t_k the master hands each agent the
//! neighbour's x̂_j(k) — the same instant, as eq. (6) wants — and no algebraic loop forms.
//! The central filter's `x_hat` recorded at t_{k+1} is x̂(k|k); its one-step prediction
//! x̂(k+1|k) = A x̂(k|k) is what an agent's x̂_i(k+1) competes with.
//!
//! **Scores** (004 §5): e_ac = Σ_{k=1..100} Σ_{i=1,2} ‖x(k) − x̂_i(k)‖². The central filter
//! is scored as if both agents held its estimate, 2 Σ_k ‖x(k) − x̂(k|k−1)‖² (and filtered,
//! 2 Σ_k ‖x(k) − x̂(k|k)‖²), so the numbers compare like for like.

use super::{ExperimentContext, Report, Row};
use crate::plot::{heatmap_png, panels_png, Panel};
use anyhow::{anyhow, Context, Result};
use rayon::prelude::*;
use spurio_master::engine::{RunOptions, Simulation};
use spurio_master::record::{CsvWriter, TimeSeries};
use spurio_master::system::System;
use std::fmt::Write as _;

const EXPERIMENT: &str = "distributed_observer";
/// Paper 004's A (§5).
const A: [[f64; 3]; 3] = [
    [1.005, 0.0, 0.0],
    [0.0, 0.9954, -0.08757],
    [0.0, 0.1248, 0.9945],
];
/// Samples scored (k = 1..100).
const HORIZON: usize = 100;
/// The 1 = LQ, 2 = local Kalman values of the agents' `design` parameter.
const LQ: f64 = 1.0;
const LOCAL_KALMAN: f64 = 2.0;

/// A copy of `system` with start values changed: (instance, variable, value).
pub(crate) fn with_start_values(system: &System, changes: &[(&str, &str, f64)]) -> Result<System> {
    let mut s = system.clone();
    for (instance, variable, value) in changes {
        let inst = s
            .instances
            .iter_mut()
            .find(|i| i.name == *instance)
            .ok_or_else(|| anyhow!("no instance `{instance}` in {}", system.name))?;
        let index = inst
            .fmu
            .index_of(variable)
            .ok_or_else(|| anyhow!("instance `{instance}` has no variable `{variable}`"))?;
        inst.start_values.retain(|(i, _)| *i != index);
        inst.start_values.push((index, *value));
    }
    Ok(s)
}

/// Runs `system` once, keeping every recorded value.
pub(crate) fn run_series(system: &System) -> Result<TimeSeries> {
    let mut sim = Simulation::new(system)?;
    let mut series = TimeSeries::default();
    sim.run(&mut series, &RunOptions::default())?;
    sim.terminate()?;
    Ok(series)
}

/// Mean and sample standard deviation.
pub(crate) fn mean_std(values: &[f64]) -> (f64, f64) {
    let n = values.len().max(1) as f64;
    let mean = values.iter().sum::<f64>() / n;
    let var = values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1.0).max(1.0);
    (mean, var.sqrt())
}

fn columns(series: &TimeSeries, prefix: &str) -> Result<Vec<Vec<f64>>> {
    (1..=3)
        .map(|i| {
            let name = format!("{prefix}[{i}]");
            series
                .column(&name)
                .with_context(|| format!("`{name}` is not recorded"))
        })
        .collect()
}

/// The scores of one run (module documentation).
#[derive(Debug, Clone, Copy)]
struct Scores {
    /// e_ac of both agents.
    distributed: f64,
    agent1: f64,
    agent2: f64,
    /// 2 Σ ‖x(k) − A x̂(k−1|k−1)‖².
    central_prediction: f64,
    /// 2 Σ ‖x(k) − x̂(k|k)‖².
    central_filtered: f64,
}

fn scores(series: &TimeSeries) -> Result<Scores> {
    let x = columns(series, "plant.x")?;
    let x1 = columns(series, "agent1.x_hat")?;
    let x2 = columns(series, "agent2.x_hat")?;
    let xc = columns(series, "central.x_hat")?;
    anyhow::ensure!(
        series.time.len() > HORIZON + 1,
        "{} rows recorded, need {} (stop_time must be ≥ {} samples)",
        series.time.len(),
        HORIZON + 2,
        HORIZON + 1
    );
    let mut s = Scores {
        distributed: 0.0,
        agent1: 0.0,
        agent2: 0.0,
        central_prediction: 0.0,
        central_filtered: 0.0,
    };
    for k in 1..=HORIZON {
        for i in 0..3 {
            let e1 = x[i][k] - x1[i][k];
            let e2 = x[i][k] - x2[i][k];
            s.agent1 += e1 * e1;
            s.agent2 += e2 * e2;
            let prediction: f64 = (0..3).map(|j| A[i][j] * xc[j][k]).sum();
            s.central_prediction += 2.0 * (x[i][k] - prediction).powi(2);
            s.central_filtered += 2.0 * (x[i][k] - xc[i][k + 1]).powi(2);
        }
    }
    s.distributed = s.agent1 + s.agent2;
    Ok(s)
}

/// Both agents' design and weights.
fn design(system: &System, design: f64, rho: f64, lambda: f64) -> Result<System> {
    with_start_values(
        system,
        &[
            ("agent1", "design", design),
            ("agent2", "design", design),
            ("agent1", "rho", rho),
            ("agent2", "rho", rho),
            ("agent1", "lambda", lambda),
            ("agent2", "lambda", lambda),
        ],
    )
}

/// The scores over plant seeds 1..=seeds, in parallel.
fn monte_carlo(system: &System, seeds: usize, pool: &rayon::ThreadPool) -> Result<Vec<Scores>> {
    pool.install(|| {
        (1..=seeds)
            .into_par_iter()
            .map(|seed| {
                let s = with_start_values(system, &[("plant", "seed", seed as f64)])?;
                scores(&run_series(&s)?)
            })
            .collect()
    })
}

fn summary(values: &[Scores], pick: fn(&Scores) -> f64) -> (f64, f64) {
    mean_std(&values.iter().map(pick).collect::<Vec<_>>())
}

/// Runs the experiment (module documentation).
pub fn run(ctx: &ExperimentContext) -> Result<Report> {
    let system = ctx.system(EXPERIMENT, "system.toml")?;
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(ctx.threads)
        .build()
        .context("thread pool")?;

    // Representative runs (seed 1) of both designs: gains, CSV, the paper's Fig. 2.
    let lq_system = design(&system, LQ, 1.0, 1.0)?;
    let local_system = design(&system, LOCAL_KALMAN, 1.0, 1.0)?;
    let lq_run = run_series(&lq_system)?;
    let local_run = run_series(&local_system)?;
    spurio_master::record::replay(
        &lq_run,
        &mut CsvWriter::create(&ctx.out_dir.join("distributed_observer_lq_seed1.csv"))?,
    )?;
    spurio_master::record::replay(
        &local_run,
        &mut CsvWriter::create(
            &ctx.out_dir
                .join("distributed_observer_local_kalman_seed1.csv"),
        )?,
    )?;
    let gain = |series: &TimeSeries, name: &str| -> Result<f64> {
        series
            .column(name)
            .and_then(|c| c.first().copied())
            .with_context(|| format!("`{name}` is not recorded"))
    };
    let l1 = gain(&lq_run, "agent1.L[1,1]")?;
    let n12 = [
        gain(&lq_run, "agent1.N[1,1]")?,
        gain(&lq_run, "agent1.N[1,2]")?,
        gain(&lq_run, "agent1.N[2,1]")?,
        gain(&lq_run, "agent1.N[2,2]")?,
    ];
    let n21 = gain(&lq_run, "agent2.N[1,1]")?;
    let l2_lq = [
        gain(&lq_run, "agent2.L[1,1]")?,
        gain(&lq_run, "agent2.L[2,1]")?,
    ];
    let l2_local = [
        gain(&local_run, "agent2.L[1,1]")?,
        gain(&local_run, "agent2.L[2,1]")?,
    ];
    let l1_local = gain(&local_run, "agent1.L[1,1]")?;
    let reference_n12 = [0.35345, 0.05317, -0.02291, 0.36055];
    let gain_error = n12
        .iter()
        .zip(reference_n12)
        .map(|(a, b)| (a - b).abs())
        .fold((l1 - 0.73628).abs().max((n21 - 0.36258).abs()), f64::max);

    figure_states(ctx, &lq_run, &local_run)?;

    // Monte-Carlo over the plant's seed, both designs, ρ = λ = 1.
    let lq = monte_carlo(&lq_system, ctx.seeds, &pool)?;
    let local = monte_carlo(&local_system, ctx.seeds, &pool)?;
    let (lq_mean, lq_std) = summary(&lq, |s| s.distributed);
    let (local_mean, local_std) = summary(&local, |s| s.distributed);
    let (cp_mean, cp_std) = summary(&lq, |s| s.central_prediction);
    let (cf_mean, cf_std) = summary(&lq, |s| s.central_filtered);
    let (lq1, _) = summary(&lq, |s| s.agent1);
    let (lq2, _) = summary(&lq, |s| s.agent2);
    let (lk1, _) = summary(&local, |s| s.agent1);
    let (lk2, _) = summary(&local, |s| s.agent2);
    let ratio = local_mean / cp_mean;

    // The ρ × λ grid (same seeds for every cell, as the paper's "same noise vector").
    let grid = [0.1, 1.0, 10.0];
    let mut cells = Vec::new();
    for d in [LQ, LOCAL_KALMAN] {
        for &lambda in &grid {
            for &rho in &grid {
                cells.push((d, rho, lambda));
            }
        }
    }
    let grid_values: Vec<f64> = cells
        .iter()
        .map(|&(d, rho, lambda)| {
            let runs = monte_carlo(&design(&system, d, rho, lambda)?, ctx.seeds, &pool)?;
            Ok(summary(&runs, |s| s.distributed).0)
        })
        .collect::<Result<_>>()?;
    // Cells with the same ρ/λ must give the same e_ac.
    let mut ratio_spread: f64 = 0.0;
    for (a, va) in cells.iter().zip(&grid_values) {
        for (b, vb) in cells.iter().zip(&grid_values) {
            if a.0 == b.0 && ((a.1 / a.2) / (b.1 / b.2) - 1.0).abs() < 1e-9 {
                ratio_spread = ratio_spread.max((va - vb).abs() / va.abs().max(1e-300));
            }
        }
    }
    let labels: Vec<String> = grid.iter().map(|v| format!("{v}")).collect();
    let mut grid_table = String::from(
        "e_ac (mean over the seeds) on the ρ × λ grid — rows λ, columns ρ:\n\n| design | λ \\ ρ | 0.1 | 1 | 10 |\n|---|---|---|---|---|\n",
    );
    let mut grid_rows = Vec::new();
    for (di, name) in ["LQ (paper)", "local Kalman"].iter().enumerate() {
        let mut rows = Vec::new();
        for (li, lambda) in grid.iter().enumerate() {
            let row: Vec<f64> = (0..3).map(|ri| grid_values[di * 9 + li * 3 + ri]).collect();
            let _ = writeln!(
                grid_table,
                "| {name} | {lambda} | {:.1} | {:.1} | {:.1} |",
                row[0], row[1], row[2]
            );
            grid_rows.push(Row::info(
                &format!("e_ac grid, {name}, λ = {lambda} (ρ = 0.1 / 1 / 10)"),
                if di == 0 {
                    "Fig. 1 (surface, no numbers)"
                } else {
                    "—"
                },
                format!("{:.0} / {:.0} / {:.0}", row[0], row[1], row[2]),
            ));
            rows.push(row);
        }
        let file = format!(
            "distributed_observer_grid_{}.png",
            if di == 0 { "lq" } else { "local_kalman" }
        );
        heatmap_png(
            &ctx.out_dir.join(&file),
            &format!(
                "e_ac over rho x lambda, {name} design ({} seeds)",
                ctx.seeds
            ),
            ("rho", &labels),
            ("lambda", &labels),
            &rows,
        )?;
    }
    std::fs::write(ctx.out_dir.join("rho_lambda_grid.md"), &grid_table)?;

    let pm = |m: f64, s: f64| format!("{m:.0} ± {s:.0}");
    let n = ctx.seeds;
    Ok(Report {
        title: "Distributed observer (paper 004 §5)".into(),
        setup: format!(
            "DistributedObserverPlant (A of 004 §5, Q = 0.2 I, R₁ = R₂ = 0.1, x₀ = [1, 1, 1]) → two DistributedObserverAgent FMUs exchanging x̂ through the master (Gauss–Seidel; the agents have no direct feedthrough, so each receives the neighbour's x̂(k) of the same instant, eq. 6), plus a centralised KalmanFilter FMU (variant DistributedObserverCentralKalman: n = 3, m = 0, p = 2, P₀ = I one sample before x₀) on both outputs. x̂₀ = 0; e_ac = Σ_(k=1..100) Σ_i ‖x(k) − x̂_i(k)‖², mean ± std over plant seeds 1..{n}; ρ = λ = 1, D = I unless stated."
        ),
        rows: vec![
            Row::goal(
                "agent 1 L₁ (LQ)",
                "0.73628 (SPEC §6)",
                format!("{l1:.5}"),
                "paper's LQ design reproduced: every gain within 1e-4",
                gain_error < 1e-4,
            ),
            Row::info(
                "agent 1 N₁₂ (LQ)",
                "[[0.35345, 0.05317], [−0.02291, 0.36055]]",
                format!(
                    "[[{:.5}, {:.5}], [{:.5}, {:.5}]]",
                    n12[0], n12[1], n12[2], n12[3]
                ),
            ),
            Row::info("agent 2 N₂₁ (LQ)", "0.36258", format!("{n21:.5}")),
            Row::info(
                "agent 2 L₂ (LQ, least squares; basis V₂)",
                "—",
                format!("[{:.5}, {:.5}]ᵀ", l2_lq[0], l2_lq[1]),
            ),
            Row::info(
                "local Kalman gains: L₁; L₂ (basis V₂)",
                "—",
                format!(
                    "{l1_local:.5}; [{:.5}, {:.5}]ᵀ",
                    l2_local[0], l2_local[1]
                ),
            ),
            Row::info(
                "e_ac, paper's LQ design",
                "Fig. 1 (no number); reference 1507 ± 1287",
                format!("{} (agent 1 {lq1:.0}, agent 2 {lq2:.0})", pm(lq_mean, lq_std)),
            ),
            Row::info(
                "e_ac, local Kalman gain",
                "reference 695 ± 272",
                format!(
                    "{} (agent 1 {lk1:.0}, agent 2 {lk2:.0})",
                    pm(local_mean, local_std)
                ),
            ),
            Row::info(
                "centralised KF, one-step prediction (×2 agents)",
                "reference 573 ± 238",
                pm(cp_mean, cp_std),
            ),
            Row::info(
                "centralised KF, filtered (×2 agents)",
                "reference 462 ± 217",
                pm(cf_mean, cf_std),
            ),
            Row::goal(
                "better local design / centralised prediction",
                "reference 1.21",
                format!("{ratio:.3}"),
                "≤ 1.3",
                ratio <= 1.3,
            ),
            Row::goal(
                "e_ac depends only on ρ/λ: largest relative difference between grid cells of equal ρ/λ",
                "paper's Fig. 1 suggests ρ and λ separately",
                format!("{ratio_spread:.1e}"),
                "≤ 1e-9",
                ratio_spread <= 1e-9,
            ),
        ]
        .into_iter()
        .chain(grid_rows)
        .collect(),
        figures: vec![
            (
                "distributed_observer_states.png".into(),
                "Seed 1: the states and agent 1's estimates (paper 004 Fig. 2), LQ and local-Kalman designs".into(),
            ),
            (
                "distributed_observer_grid_lq.png".into(),
                "e_ac over the ρ × λ grid, paper's LQ design (paper 004 Fig. 1): constant along ρ/λ".into(),
            ),
            (
                "distributed_observer_grid_local_kalman.png".into(),
                "e_ac over the ρ × λ grid, local-Kalman L".into(),
            ),
        ],
        notes: vec![
            "Why only ρ/λ matters: U = ρQ, S = λC̃ᵀRC̃ and T = λ(…) scale both Riccati problems; multiplying every weight by c multiplies P by c and leaves K = (S + P)⁻¹PA unchanged, so the gains — and e_ac — depend on ρ/λ alone.".into(),
            "Agent 2 measures one output of its two-dimensional observable part, so S₂ is singular and L₂C̃₂ = K_L has no exact solution; the least-squares L₂ leaves a slow local error mode (0.9935) — hence the LQ design's large and very variable e_ac. The local-Kalman design keeps the paper's N (consensus) gains and takes L from the steady-state Kalman predictor of the observable part (a sound choice when S is singular).".into(),
            "Centralised lower bound: the KalmanFilter FMU (variant DistributedObserverCentralKalman, not the library filter) in the same co-simulation, fed the same y(k); its x̂(k|k) is propagated by A to x̂(k+1|k) in the scoring, and counted once per agent (2 Σ‖·‖²) so that it compares with e_ac, which sums two agents.".into(),
            "References: SPEC §4's independent implementation (different random streams, so the means agree only within their spread); the estimation library's own Monte-Carlo test found LQ 1438 ± 1035, local 733 ± 242, central prediction 601 ± 216 with the same scoring.".into(),
            "Results: distributed_observer_lq_seed1.csv, distributed_observer_local_kalman_seed1.csv (seed 1), rho_lambda_grid.md.".into(),
        ],
        figures_of_merit: vec![
            ("L1".into(), l1),
            ("N12_11".into(), n12[0]),
            ("N12_12".into(), n12[1]),
            ("N12_21".into(), n12[2]),
            ("N12_22".into(), n12[3]),
            ("N21".into(), n21),
            ("gain_error".into(), gain_error),
            ("e_ac_lq".into(), lq_mean),
            ("e_ac_local_kalman".into(), local_mean),
            ("e_ac_central_prediction".into(), cp_mean),
            ("e_ac_central_filtered".into(), cf_mean),
            ("local_over_central".into(), ratio),
            ("rho_lambda_spread".into(), ratio_spread),
        ],
    })
}

/// The paper's Fig. 2: the three states and agent 1's estimates, for both designs.
fn figure_states(ctx: &ExperimentContext, lq: &TimeSeries, local: &TimeSeries) -> Result<()> {
    let x = columns(lq, "plant.x")?;
    let e_lq = columns(lq, "agent1.x_hat")?;
    let e_local = columns(local, "agent1.x_hat")?;
    let t: Vec<f64> = lq.time.iter().copied().take(HORIZON + 1).collect();
    let cut = |v: &Vec<f64>| v.iter().copied().take(HORIZON + 1).collect::<Vec<_>>();
    let panels: Vec<Panel> = (0..3)
        .map(|i| Panel {
            colours: Vec::new(),
            label: format!("x{}", i + 1),
            lines: vec![
                (format!("x{}", i + 1), t.clone(), cut(&x[i]), false),
                ("agent 1, LQ".into(), t.clone(), cut(&e_lq[i]), false),
                (
                    "agent 1, local Kalman".into(),
                    t.clone(),
                    cut(&e_local[i]),
                    false,
                ),
            ],
        })
        .collect();
    panels_png(
        &ctx.out_dir.join("distributed_observer_states.png"),
        "States and agent 1's estimates (seed 1)",
        "sample k",
        &panels,
    )
}
