//! Free swing of the nonlinear GantryCrane (paper 000, Annex A): θ0 = 0.05 rad, U = 0. The
//! measured period (mean spacing of upward zero crossings of θ) against the linearised
//! model's (SPEC §6: ≈ 1.17 s).

use super::{ExperimentContext, Report, Row};
use anyhow::{Context, Result};
use spurio_master::engine::{RunOptions, Simulation};
use spurio_master::record::{CsvWriter, TimeSeries};

/// Runs `examples/crane_free_swing/system.toml`.
pub fn run(ctx: &ExperimentContext) -> Result<Report> {
    let system = ctx.system("crane_free_swing", "system.toml")?;
    let mut sim = Simulation::new(&system)?;
    let mut series = TimeSeries::default();
    sim.run(&mut series, &RunOptions::default())?;
    sim.terminate()?;
    spurio_master::record::replay(
        &series,
        &mut CsvWriter::create(&ctx.out_dir.join("crane_free_swing.csv"))?,
    )?;
    let theta = series
        .column("crane.theta")
        .context("crane.theta is not recorded")?;
    let t = &series.time;
    let crossings: Vec<f64> = (1..theta.len())
        .filter(|&i| theta[i - 1] < 0.0 && theta[i] >= 0.0)
        .map(|i| t[i - 1] + (t[i] - t[i - 1]) * (-theta[i - 1]) / (theta[i] - theta[i - 1]))
        .collect();
    anyhow::ensure!(crossings.len() >= 2, "the load did not swing");
    let period = (crossings[crossings.len() - 1] - crossings[0]) / (crossings.len() - 1) as f64;
    let (a, _) = spurio::plants::gantry_crane::GantryCraneParameters::default().linearised();
    let w = a
        .complex_eigenvalues()
        .iter()
        .map(|e| e.im.abs())
        .fold(0.0, f64::max);
    let linear = 2.0 * std::f64::consts::PI / w;
    let error = (period - linear).abs() / linear;
    crate::plot::time_series_png(
        &ctx.out_dir.join("crane_free_swing.png"),
        "Crane free swing (theta0 = 0.05 rad)",
        &series,
        &["crane.theta".to_string(), "crane.x".to_string()],
    )?;
    Ok(Report {
        title: "Crane free swing (paper 000, Annex A parameters)".into(),
        setup: "GantryCrane FMU alone, θ0 = 0.05 rad, U = 0, 20 s at 10 ms communication steps (RK4 substeps of 1 ms inside the FMU).".into(),
        rows: vec![
            Row::info("pendulum period (linearised model)", "≈ 1.17 s (SPEC §6)", format!("{linear:.5} s")),
            Row::goal("pendulum period (nonlinear FMU)", "—", format!("{period:.5} s"), "within 0.5 % of the linear model", error < 5e-3),
        ],
        figures: vec![("crane_free_swing.png".into(), "Load angle and cart position during the free swing".into())],
        notes: vec![format!("relative period error {error:.2e}; results in crane_free_swing.csv")],
        figures_of_merit: vec![("period".into(), period), ("period_error".into(), error)],
    })
}
