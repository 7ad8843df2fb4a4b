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
use spurio_master::{CsvWriter, TimeSeries};
use spurio_master::{RunOptions, Simulation};
use spurio_master::{StartValue, System};
use std::path::Path;

pub use spurio_analysis::stats::{mean_std, mean_std_of, median};

/// A start value set by name: `("sensor.seed", 3.into())`.
pub type Edit<'a> = (&'a str, StartValue);

/// A copy of `system` with the start values `edits` set (with the checks of a system file's
/// `parameters` entry: a Real takes a float, an Integer an integer, a Boolean a bool).
pub fn edited(system: &System, edits: &[Edit<'_>]) -> Result<System> {
    let mut copy = system.clone();
    for (name, value) in edits {
        copy.set_start_value(name, *value)
            .with_context(|| format!("setting {name} in {}", system.name()))?;
    }
    Ok(copy)
}

/// The start value of `qualified` in `system` (the one it sets, else the FMU's).
pub fn start_value(system: &System, qualified: &str) -> Result<f64> {
    system
        .start_value(qualified)?
        .with_context(|| format!("{qualified} has no start value in {}", system.name()))
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
    spurio_master::replay(series, &mut CsvWriter::create(path)?)
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

/// "mean ± std" with `digits` decimals.
pub fn pm((mean, std): (f64, f64), digits: usize) -> String {
    format!("{mean:.digits$} ± {std:.digits$}")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn plus_minus_has_the_digits_asked_for() {
        assert_eq!(pm((1.23456, 0.1), 2), "1.23 ± 0.10");
        assert_eq!(pm((-2.0, 0.5), 1), "-2.0 ± 0.5");
    }
}
