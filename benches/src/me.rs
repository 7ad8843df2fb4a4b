//! `spurio-bench-me`: times spurio's Model Exchange import of one FMU in process, for
//! `scripts/bench-me` (which sets it beside fmpy's CVode and OMSimulator's CVODE at equal
//! accuracy). Each repetition instantiates the FMU (not timed), then times
//! `model_exchange::simulate` from the experiment's setup to `fmi2Terminate` /
//! `fmi3Terminate`, its outputs recorded into memory at every output point; the FMU is
//! unpacked and its model description read once, before. Prints one line per repetition,
//! `seconds <wall time> rhs <right-hand sides> steps <accepted> rejected <rejected>`, and
//! writes the last run's outputs as CSV (fmpy's layout) to `--out`.

#![forbid(unsafe_code)]

use anyhow::{Context, Result};
use clap::Parser;
use spurio_master::fmu::{FmuFile, Interface, LoadOptions};
use spurio_master::model_exchange::{simulate, Method, Options};
use spurio_master::{replay, CsvWriter, TimeSeries};
use std::path::PathBuf;
use std::time::Instant;

#[derive(Parser)]
#[command(about = "Times spurio's Model Exchange run of one FMU in process")]
struct Args {
    /// The FMU (FMI 2.0 or 3.0, with Model Exchange).
    fmu: PathBuf,
    /// dopri5, rodas4, rodas3 or shampine4.
    #[arg(long, default_value = "dopri5")]
    solver: Method,
    /// The relative tolerance (the absolute one: the same times each state's nominal).
    #[arg(long)]
    tolerance: f64,
    #[arg(long, default_value_t = 0.0)]
    start_time: f64,
    #[arg(long)]
    stop_time: f64,
    /// The output interval.
    #[arg(long)]
    step_size: f64,
    /// The number of timed runs.
    #[arg(long, default_value_t = 1)]
    repeat: usize,
    /// A start value `name=value` (repeatable).
    #[arg(long = "set", value_name = "NAME=VALUE", value_parser = start_value)]
    set: Vec<(String, f64)>,
    /// Where the last run's outputs go (CSV).
    #[arg(long)]
    out: Option<PathBuf>,
}

/// `name=value` as (name, number).
fn start_value(text: &str) -> Result<(String, f64), String> {
    let (name, value) = text
        .split_once('=')
        .ok_or_else(|| format!("`{text}`: expected NAME=VALUE"))?;
    let value = value
        .trim()
        .parse()
        .map_err(|_| format!("`{text}`: `{value}` is not a number"))?;
    Ok((name.trim().to_string(), value))
}

fn main() -> Result<()> {
    let args = Args::parse();
    let fmu = FmuFile::open_for(&args.fmu, &LoadOptions::default(), Interface::ModelExchange)?;
    let options = Options {
        method: args.solver,
        tolerance: args.tolerance,
        ..Options::new(args.start_time, args.stop_time, args.step_size)
    };
    let mut series = TimeSeries::default();
    for _ in 0..args.repeat {
        let mut instance = fmu.instantiate_model_exchange(&fmu.model_identifier, false)?;
        let layout = instance
            .layout(&fmu, &args.set)
            .map_err(anyhow::Error::msg)?;
        series = TimeSeries::default();
        let started = Instant::now();
        let summary = simulate(&mut instance, &layout, &options, &mut series, &mut |_| {})?;
        let seconds = started.elapsed().as_secs_f64();
        let s = summary.statistics;
        println!(
            "seconds {seconds:e} rhs {} steps {} rejected {}",
            s.rhs, s.accepted, s.rejected
        );
    }
    if let Some(out) = &args.out {
        let mut csv =
            CsvWriter::create(out).with_context(|| format!("cannot write {}", out.display()))?;
        replay(&series, &mut csv)?;
    }
    Ok(())
}
