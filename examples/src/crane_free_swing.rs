//! Free swing of the nonlinear GantryCrane (paper 000, Annex A): θ0 = 0.05 rad, U = 0. The
//! measured period (mean spacing of upward zero crossings of θ) against the linearised
//! model's (docs/reference-values.md §6: ≈ 1.17 s).

use super::{ExperimentContext, Report, Row};
use crate::plot::axis_label;
use crate::runner::{column, simulate, write_csv};
use anyhow::Result;
use spurio_master::TimeSeries;

/// The mean spacing of the upward zero crossings of `crane.theta` (interpolated).
fn measured_period(series: &TimeSeries) -> Result<f64> {
    let theta = column(series, "crane.theta")?;
    let t = &series.time;
    let crossings: Vec<f64> = (1..theta.len())
        .filter(|&i| theta[i - 1] < 0.0 && theta[i] >= 0.0)
        .map(|i| t[i - 1] + (t[i] - t[i - 1]) * (-theta[i - 1]) / (theta[i] - theta[i - 1]))
        .collect();
    anyhow::ensure!(crossings.len() >= 2, "the load did not swing");
    Ok((crossings[crossings.len() - 1] - crossings[0]) / (crossings.len() - 1) as f64)
}

/// The period of the linearised crane's oscillatory mode.
fn linear_period() -> f64 {
    let (a, _) = spurio::plants::gantry_crane::GantryCraneParameters::default().linearised();
    let w = a
        .complex_eigenvalues()
        .iter()
        .map(|e| e.im.abs())
        .fold(0.0, f64::max);
    2.0 * std::f64::consts::PI / w
}

/// Runs `examples/crane_free_swing/system.toml`.
pub fn run(ctx: &ExperimentContext) -> Result<Report> {
    let system = ctx.system("crane_free_swing", "system.toml")?;
    let series = simulate(&system)?;
    write_csv(&series, &ctx.out_dir.join("crane_free_swing.csv"))?;
    let period = measured_period(&series)?;
    let linear = linear_period();
    let error = (period - linear).abs() / linear;
    let plotted = ["crane.theta", "crane.x"]
        .iter()
        .map(|n| Ok((n.to_string(), axis_label(&system, n)?)))
        .collect::<Result<Vec<_>>>()?;
    crate::plot::labelled_time_series_png(
        &ctx.out_dir.join("crane_free_swing.png"),
        "Crane free swing (θ₀ = 0.05 rad)",
        &series,
        &plotted,
    )?;
    Ok(Report {
        title: "Crane free swing (paper 000, Annex A parameters)".into(),
        setup: "GantryCrane FMU alone, θ0 = 0.05 rad, U = 0, 20 s at 10 ms communication steps (RK4 substeps of 1 ms inside the FMU).".into(),
        rows: vec![
            Row::info("pendulum period (linearised model)", "≈ 1.17 s (docs/reference-values.md §6)", format!("{linear:.5} s")),
            Row::goal("pendulum period (nonlinear FMU)", "—", format!("{period:.5} s"), "within 0.5 % of the linear model", error < 5e-3),
        ],
        figures: vec![("crane_free_swing.png".into(), "Load angle and cart position during the free swing".into())],
        notes: vec![format!("relative period error {error:.2e}; results in crane_free_swing.csv")],
        figures_of_merit: vec![("period".into(), period), ("period_error".into(), error)],
    })
}
