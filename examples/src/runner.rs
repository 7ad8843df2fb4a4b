//! What every experiment does, once: a scenario is a bundled system with start values set by
//! name ([`edited`]); a Monte-Carlo study runs it once per seed on the context's thread pool
//! ([`ExperimentContext::for_each_seed`], [`monte_carlo`]) and scores each run; the scores
//! are summarised as mean ± std ([`mean_std`], [`pm`]) for the report's table.
//!
//! Each run creates its FMU instances on the worker thread that runs it (rust-fmi instances
//! are `!Send`); the resolved [`System`] is shared.

use crate::ExperimentContext;
use anyhow::{Context as _, Result};
use rayon::prelude::*;
use spurio_master::engine::{RunOptions, Simulation};
use spurio_master::record::{CsvWriter, TimeSeries};
use spurio_master::system::{StartValue, System};
use std::path::Path;

/// A start value set by name: `("sensor.seed", 3.into())`.
pub type Edit<'a> = (&'a str, StartValue);

/// A copy of `system` with the start values `edits` set (with the checks of a system file's
/// `parameters` entry: a Real takes a float, an Integer an integer, a Boolean a bool).
pub fn edited(system: &System, edits: &[Edit<'_>]) -> Result<System> {
    let mut copy = system.clone();
    for (name, value) in edits {
        copy.set_start_value(name, *value)
            .with_context(|| format!("setting {name} in {}", system.name))?;
    }
    Ok(copy)
}

/// The start value of `qualified` in `system` (the one it sets, else the FMU's).
pub fn start_value(system: &System, qualified: &str) -> Result<f64> {
    system
        .start_value(qualified)?
        .with_context(|| format!("{qualified} has no start value in {}", system.name))
}

/// Runs `system` once, keeping every recorded sample.
pub fn simulate(system: &System) -> Result<TimeSeries> {
    let mut sim = Simulation::new(system)?;
    let mut series = TimeSeries::default();
    sim.run(&mut series, &RunOptions::default())?;
    sim.terminate()?;
    Ok(series)
}

/// The recorded column `name`, or an error naming what is recorded.
pub fn column(series: &TimeSeries, name: &str) -> Result<Vec<f64>> {
    series
        .column(name)
        .with_context(|| format!("`{name}` is not recorded ({})", series.names.join(", ")))
}

/// Writes `series` as CSV to `path`.
pub fn write_csv(series: &TimeSeries, path: &Path) -> Result<()> {
    spurio_master::record::replay(series, &mut CsvWriter::create(path)?)
        .with_context(|| format!("writing {}", path.display()))
}

impl ExperimentContext {
    /// The Monte-Carlo seeds: 1 ..= `seeds` (at least one).
    pub fn seed_list(&self) -> Vec<u32> {
        (1..=self.seeds.max(1) as u32).collect()
    }

    /// `work(seed)` for every seed, on the context's thread pool; results in seed order.
    pub fn for_each_seed<T: Send>(
        &self,
        seeds: &[u32],
        work: impl Fn(u32) -> Result<T> + Sync,
    ) -> Result<Vec<T>> {
        self.pool.install(|| {
            seeds
                .par_iter()
                .map(|seed| work(*seed).with_context(|| format!("seed {seed}")))
                .collect()
        })
    }
}

/// Runs `system` once per seed of `seeds` with the start values `seed_edits(seed)` set, and
/// scores each run: the Monte-Carlo study of one scenario, scores in seed order.
pub fn monte_carlo<S: Send>(
    ctx: &ExperimentContext,
    system: &System,
    seeds: &[u32],
    seed_edits: impl Fn(u32) -> Vec<Edit<'static>> + Sync,
    score: impl Fn(&TimeSeries) -> Result<S> + Sync,
) -> Result<Vec<S>> {
    ctx.for_each_seed(seeds, |seed| {
        score(&simulate(&edited(system, &seed_edits(seed))?)?)
    })
}

/// Mean and sample standard deviation (N − 1) of the finite values (NaN if none).
pub fn mean_std(values: &[f64]) -> (f64, f64) {
    let finite: Vec<f64> = values.iter().copied().filter(|v| v.is_finite()).collect();
    let n = finite.len();
    if n == 0 {
        return (f64::NAN, f64::NAN);
    }
    let mean = finite.iter().sum::<f64>() / n as f64;
    let var = if n > 1 {
        finite.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1) as f64
    } else {
        0.0
    };
    (mean, var.sqrt())
}

/// [`mean_std`] of `pick` over `items`.
pub fn mean_std_of<T>(items: &[T], pick: impl Fn(&T) -> f64) -> (f64, f64) {
    mean_std(&items.iter().map(pick).collect::<Vec<_>>())
}

/// Median of the finite values (NaN if none).
pub fn median(values: &[f64]) -> f64 {
    let mut finite: Vec<f64> = values.iter().copied().filter(|v| v.is_finite()).collect();
    if finite.is_empty() {
        return f64::NAN;
    }
    finite.sort_by(f64::total_cmp);
    let n = finite.len();
    if n % 2 == 1 {
        finite[n / 2]
    } else {
        0.5 * (finite[n / 2 - 1] + finite[n / 2])
    }
}

/// "mean ± std" with `digits` decimals.
pub fn pm((mean, std): (f64, f64), digits: usize) -> String {
    format!("{mean:.digits$} ± {std:.digits$}")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn statistics_skip_non_finite_values() {
        let (m, s) = mean_std(&[1.0, f64::NAN, 3.0]);
        assert_eq!(m, 2.0);
        assert!((s - 2f64.sqrt()).abs() < 1e-15);
        assert!(mean_std(&[f64::NAN]).0.is_nan());
        assert_eq!(mean_std(&[4.0]), (4.0, 0.0));
        assert_eq!(median(&[3.0, 1.0, f64::INFINITY, 2.0]), 2.0);
        assert_eq!(median(&[4.0, 1.0]), 2.5);
        assert!(median(&[]).is_nan());
        assert_eq!(pm((1.23456, 0.1), 2), "1.23 ± 0.10");
    }
}
