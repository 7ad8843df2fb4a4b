//! `spurio-experiments`: runs the papers' experiments (`examples/<name>/`) and writes
//! `REPORT.md`, the CSVs and the plots into the output folder (`scripts/experiments` builds the
//! FMUs and runs it into `results/`).

use anyhow::Result;
use clap::Parser;
use std::path::PathBuf;
use std::process::ExitCode;

/// Run the papers' experiments (examples/<name>/) and write REPORT.md, CSVs and plots.
#[derive(Parser)]
#[command(name = "spurio-experiments", version)]
struct Args {
    /// Output folder.
    #[arg(long, default_value = "results")]
    out: PathBuf,
    /// Only these experiments (comma-separated; default: all).
    #[arg(long, value_delimiter = ',')]
    only: Vec<String>,
    /// Monte-Carlo runs where the papers report mean ± std.
    #[arg(long, default_value_t = 100)]
    seeds: usize,
    /// Worker threads for the Monte-Carlo runs (0: one per core; at most four per core).
    #[arg(long, default_value_t = 0)]
    threads: usize,
    /// The repository root (holding examples/ and build/fmus/).
    #[arg(long, default_value = ".")]
    repo: PathBuf,
}

/// The worker threads for `--threads` (0: one per core), capped at four per core with a
/// message.
fn workers(threads: usize) -> usize {
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    let bound = 4 * cores;
    if threads > bound {
        eprintln!("spurio-experiments: --threads {threads} capped at {bound} (4 per core, {cores} cores here)");
        return bound;
    }
    threads
}

fn run(args: Args) -> Result<()> {
    spurio_master::logging::install(false);
    let threads = workers(args.threads);
    let reports =
        spurio_experiments::run_all(&args.repo, &args.out, &args.only, args.seeds, threads)?;
    let failed: Vec<&str> = reports
        .iter()
        .filter(|(_, r)| !r.all_goals_met())
        .map(|(n, _)| n.as_str())
        .collect();
    println!("wrote {}", args.out.join("REPORT.md").display());
    if !failed.is_empty() {
        println!("goals not met in: {}", failed.join(", "));
    }
    Ok(())
}

fn main() -> ExitCode {
    match run(Args::parse()) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("Error: {e:?}");
            ExitCode::FAILURE
        }
    }
}
