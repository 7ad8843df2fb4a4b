//! Helpers for Monte-Carlo experiments that need more than [`spurio_master::sweep`]: several start
//! values changed per run, the whole recorded series kept for custom metrics, runs spread
//! over a rayon pool with each run's instances created on its worker thread (rust-fmi
//! instances are `!Send`, the resolved [`System`] is shared).

use anyhow::{anyhow, Context, Result};
use rayon::prelude::*;
use spurio_master::engine::{RunOptions, Simulation};
use spurio_master::record::TimeSeries;
use spurio_master::system::System;

/// A copy of `system` with start values replaced: `("instance.variable", value)` pairs
/// (Boolean and Integer parameters take 0/1 and whole numbers).
pub fn with_start_values(system: &System, overrides: &[(&str, f64)]) -> Result<System> {
    let mut copy = system.clone();
    for (name, value) in overrides {
        let (instance, variable) = name
            .split_once('.')
            .ok_or_else(|| anyhow!("`{name}`: expected instance.variable"))?;
        let inst = copy
            .instances
            .iter_mut()
            .find(|i| i.name == instance)
            .ok_or_else(|| anyhow!("`{name}`: no instance called `{instance}`"))?;
        let index = inst
            .fmu
            .index_of(variable)
            .ok_or_else(|| anyhow!("`{name}`: instance `{instance}` has no such variable"))?;
        inst.start_values.retain(|(i, _)| *i != index);
        inst.start_values.push((index, *value));
    }
    Ok(copy)
}

/// Runs `system` once, keeping every recorded sample.
pub fn run_series(system: &System) -> Result<TimeSeries> {
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

/// `work(seed)` for every seed, in parallel on `threads` workers (0: one per core), results
/// in seed order.
pub fn for_each_seed<T: Send>(
    seeds: &[u64],
    threads: usize,
    work: impl Fn(u64) -> Result<T> + Sync,
) -> Result<Vec<T>> {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .map_err(|e| anyhow!("thread pool: {e}"))?;
    pool.install(|| {
        seeds
            .par_iter()
            .map(|seed| work(*seed).with_context(|| format!("seed {seed}")))
            .collect()
    })
}

/// Mean and sample standard deviation (N − 1) of the finite values, and how many there were.
pub fn mean_std(values: &[f64]) -> (f64, f64, usize) {
    let finite: Vec<f64> = values.iter().copied().filter(|v| v.is_finite()).collect();
    let n = finite.len();
    if n == 0 {
        return (f64::NAN, f64::NAN, 0);
    }
    let mean = finite.iter().sum::<f64>() / n as f64;
    let var = if n > 1 {
        finite.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1) as f64
    } else {
        0.0
    };
    (mean, var.sqrt(), n)
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn statistics_skip_non_finite_values() {
        let (m, s, n) = mean_std(&[1.0, f64::NAN, 3.0]);
        assert_eq!((m, n), (2.0, 2));
        assert!((s - 2f64.sqrt()).abs() < 1e-15);
        assert_eq!(median(&[3.0, 1.0, f64::INFINITY, 2.0]), 2.0);
        assert_eq!(median(&[4.0, 1.0]), 2.5);
        assert!(median(&[]).is_nan());
    }
}
