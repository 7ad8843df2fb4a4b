//! `spurio`: the command line of the spurio FMU set.
//!
//! - `spurio package` writes the `.fmu` archives of every FMU (or the ones named) from the
//!   compiled libraries;
//! - `spurio model-descriptions` checks (or, with `--write`, regenerates) the committed
//!   `modelDescription/*.xml` against the Rust variable tables;
//! - `spurio diagnose` runs the outlier diagnostics (Grubbs, kurtosis, skewness, E_res,
//!   histogram) on a column of a results CSV.

// No unsafe code here; a module that must call into a compiled FMU library directly opts
// in with `#[allow(unsafe_code)]` on that module alone.
#![deny(unsafe_code)]

use spurio_experiments::{diagnose, plot};
use spurio_master::engine::{RunOptions, Simulation};
use spurio_master::logging;
use spurio_master::record::{CsvWriter, TimeSeries};
use spurio_master::system::System;

mod package;
mod sweep;

use anyhow::{bail, Result};
use clap::{Parser, Subcommand};
use std::path::PathBuf;

#[derive(Parser)]
#[command(
    name = "spurio",
    version,
    about = "FMI 2.0 components for robust identification and control"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Run a co-simulation system (TOML) and write its results as CSV (fmpy's layout).
    Run {
        /// The system file.
        system: PathBuf,
        /// Where to write the results.
        #[arg(long, default_value = "results.csv")]
        out: PathBuf,
        /// Also plot these recorded variables (comma-separated names) to a PNG beside the CSV.
        #[arg(long, value_delimiter = ',')]
        plot: Vec<String>,
        /// Pace the run: 1 = real time, 2 = twice as fast.
        #[arg(long)]
        real_time: Option<f64>,
        /// Show a progress bar.
        #[arg(long)]
        progress: bool,
        /// Print the FMUs' informational log messages too.
        #[arg(long)]
        verbose: bool,
    },
    /// Package FMUs: writes <out>/<ModelIdentifier>.fmu for every bundled FMU variant.
    Package {
        /// Folder with the compiled `lib<ModelIdentifier>.so` files.
        #[arg(long, default_value = "target/release")]
        lib_dir: PathBuf,
        /// Where to write the .fmu files.
        #[arg(long, default_value = "build/fmus")]
        out: PathBuf,
        /// Model identifiers to package (default: all).
        names: Vec<String>,
    },
    /// Package one FMU for your own dimensions: e.g. `spurio package-variant KalmanFilter
    /// --set n=3 --set p=1 --set m=1 --name MyKalmanFilter` writes MyKalmanFilter.fmu whose
    /// modelDescription has A[1,1]…A[3,3], y[1], x_hat[1]…x_hat[3], ….
    PackageVariant {
        /// Model identifier of a dimension-generic FMU.
        model_identifier: String,
        /// Configuration entries `key=value` (the FMU's page lists its keys).
        #[arg(long = "set", value_name = "KEY=VALUE")]
        settings: Vec<String>,
        /// File name of the .fmu without extension (default: the model identifier).
        #[arg(long)]
        name: Option<String>,
        /// Folder with the compiled `lib<ModelIdentifier>.so` files.
        #[arg(long, default_value = "target/release")]
        lib_dir: PathBuf,
        /// Where to write the .fmu.
        #[arg(long, default_value = "build/fmus")]
        out: PathBuf,
    },
    /// Run the papers' experiments (examples/<name>/) and write REPORT.md, CSVs and plots.
    Experiments {
        /// Output folder.
        #[arg(long, default_value = "results")]
        out: PathBuf,
        /// Only these experiments (comma-separated; default: all).
        #[arg(long, value_delimiter = ',')]
        only: Vec<String>,
        /// Monte-Carlo runs where the papers report mean ± std.
        #[arg(long, default_value_t = 100)]
        seeds: usize,
        /// Worker threads for sweeps (0: one per core).
        #[arg(long, default_value_t = 0)]
        threads: usize,
        /// The repository root (holding examples/ and build/fmus/).
        #[arg(long, default_value = ".")]
        repo: PathBuf,
    },
    /// Run a system many times with one parameter varied (e.g. a seed), in parallel, and
    /// print metrics as mean ± std; or one shard of it (`--shard i/N`), or stage it as a
    /// Slurm job array (`--slurm <dir>`).
    Sweep(sweep::SweepArgs),
    /// Merge the shard files of a sweep into the table the one-machine sweep prints (checking
    /// they are of one sweep, none missing or duplicated), or show its progress.
    SweepMerge(sweep::MergeArgs),
    /// Export a system (TOML) as an SSP 1.0 archive with its FMUs, for OMSimulator or fmpy.
    SspExport {
        /// The system file.
        system: PathBuf,
        /// The .ssp to write.
        out: PathBuf,
    },
    /// Import an SSP archive: unpack its FMUs into a folder and write a TOML system file there.
    SspImport {
        /// The .ssp to read.
        ssp: PathBuf,
        /// The folder to write `system.toml` and the FMUs into.
        out: PathBuf,
    },
    /// Outlier diagnostics of one column of a results CSV (fmpy layout): two-sided Grubbs
    /// test, excess kurtosis, skewness, E_res against a clean column, histogram PNG.
    Diagnose {
        /// The results CSV.
        csv: PathBuf,
        /// The column to analyse.
        #[arg(long)]
        column: String,
        /// A column with the clean signal, for E_res.
        #[arg(long)]
        clean: Option<String>,
        /// Significance level of the Grubbs test.
        #[arg(long, default_value_t = 0.05)]
        alpha: f64,
        /// Write the histogram with the ±2σ band here.
        #[arg(long)]
        png: Option<PathBuf>,
    },
    /// Compare the committed modelDescription/*.xml with the Rust variable tables.
    ModelDescriptions {
        /// Regenerate the files instead of checking them.
        #[arg(long)]
        write: bool,
        /// The repository root (holding modelDescription/).
        #[arg(long, default_value = ".")]
        repo: PathBuf,
    },
}

/// Each plotted variable's axis label: its name and the unit its model description gives
/// (`crane.x [m]`).
fn axis_labels(system: &System, names: &[String]) -> Vec<String> {
    names
        .iter()
        .map(|name| match system.unit(name).ok().flatten() {
            Some(unit) if !unit.is_empty() => format!("{name} [{unit}]"),
            _ => name.clone(),
        })
        .collect()
}

fn main() -> Result<()> {
    let cli = Cli::parse();
    let verbose = matches!(cli.command, Command::Run { verbose: true, .. });
    logging::install(verbose);
    match cli.command {
        Command::Run {
            system,
            out,
            plot: plotted,
            real_time,
            progress,
            verbose: _,
        } => {
            let resolved = System::from_file(&system)?;
            let mut sim = Simulation::new(&resolved)?;
            let options = RunOptions {
                real_time_factor: real_time,
                progress,
            };
            if plotted.is_empty() {
                let mut csv = CsvWriter::create(&out)
                    .map_err(|e| anyhow::anyhow!("cannot write {}: {e}", out.display()))?;
                sim.run(&mut csv, &options)?;
            } else {
                let mut series = TimeSeries::default();
                sim.run(&mut series, &options)?;
                let mut csv = CsvWriter::create(&out)
                    .map_err(|e| anyhow::anyhow!("cannot write {}: {e}", out.display()))?;
                spurio_master::record::replay(&series, &mut csv)?;
                let png = out.with_extension("png");
                let labels = axis_labels(&resolved, &plotted);
                plot::labelled_time_series_png(&png, &resolved.name, &series, &plotted, &labels)?;
                println!("wrote {}", png.display());
            }
            sim.terminate()?;
            println!("wrote {}", out.display());
        }
        Command::Package {
            lib_dir,
            out,
            names,
        } => {
            let catalogue = spurio_fmus::catalogue();
            for name in &names {
                if !catalogue.iter().any(|e| e.model_identifier == name) {
                    let known: Vec<&str> = catalogue.iter().map(|e| e.model_identifier).collect();
                    bail!("unknown FMU `{name}` (known: {})", known.join(", "));
                }
            }
            for entry in catalogue
                .iter()
                .filter(|e| names.is_empty() || names.iter().any(|n| n == e.model_identifier))
            {
                for (stem, config) in &entry.variants {
                    let path = package::package_variant(entry, stem, config, &lib_dir, &out)?;
                    println!("wrote {}", path.display());
                }
            }
        }
        Command::PackageVariant {
            model_identifier,
            settings,
            name,
            lib_dir,
            out,
        } => {
            let catalogue = spurio_fmus::catalogue();
            let Some(entry) = catalogue
                .iter()
                .find(|e| e.model_identifier == model_identifier)
            else {
                let known: Vec<&str> = catalogue.iter().map(|e| e.model_identifier).collect();
                bail!(
                    "unknown FMU `{model_identifier}` (known: {})",
                    known.join(", ")
                );
            };
            let mut config = spurio_fmi2::Config::new();
            for setting in &settings {
                let Some((key, value)) = setting.split_once('=') else {
                    bail!("--set takes KEY=VALUE, got `{setting}`");
                };
                config.set(key.trim(), value.trim());
            }
            let stem = name.unwrap_or_else(|| model_identifier.clone());
            let path = package::package_variant(entry, &stem, &config, &lib_dir, &out)?;
            println!("wrote {}", path.display());
        }
        Command::Experiments {
            out,
            only,
            seeds,
            threads,
            repo,
        } => {
            let reports = spurio_experiments::run_all(&repo, &out, &only, seeds, threads)?;
            let failed: Vec<&str> = reports
                .iter()
                .filter(|(_, r)| !r.all_goals_met())
                .map(|(n, _)| n.as_str())
                .collect();
            println!("wrote {}", out.join("REPORT.md").display());
            if !failed.is_empty() {
                println!("goals not met in: {}", failed.join(", "));
            }
        }
        Command::Sweep(args) => sweep::run(args)?,
        Command::SweepMerge(args) => sweep::merge(args)?,
        Command::SspExport { system, out } => {
            System::from_file(&system)?.export_ssp(&out)?;
            println!("wrote {}", out.display());
        }
        Command::SspImport { ssp, out } => {
            let description = spurio_master::ssp::import(&ssp, &out)?;
            let path = out.join("system.toml");
            std::fs::write(&path, toml::to_string_pretty(&description)?)?;
            println!("wrote {}", path.display());
        }
        Command::Diagnose {
            csv,
            column,
            clean,
            alpha,
            png,
        } => {
            print!(
                "{}",
                diagnose::diagnose(&csv, &column, clean.as_deref(), alpha, png.as_deref())?
            );
        }
        Command::ModelDescriptions { write, repo } => {
            let mut stale = Vec::new();
            for entry in spurio_fmus::catalogue() {
                for (stem, config) in &entry.variants {
                    let xml = (entry.describe)(config)
                        .map_err(|e| anyhow::anyhow!("{stem}: {e}"))?
                        .to_xml();
                    let path = package::committed_model_description(&repo, stem);
                    if write {
                        std::fs::write(&path, xml)?;
                        println!("wrote {}", path.display());
                    } else if std::fs::read_to_string(&path).ok().as_deref() != Some(xml.as_str()) {
                        stale.push(path.display().to_string());
                    }
                }
            }
            if !stale.is_empty() {
                bail!(
                    "these model descriptions differ from the Rust variable tables (run `spurio model-descriptions --write`): {}",
                    stale.join(", ")
                );
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn plot_axes_carry_the_units_of_the_model_description() {
        let repo = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..");
        assert!(
            repo.join("build/fmus/GantryCrane.fmu").is_file(),
            "run scripts/build-fmus first"
        );
        let system = System::from_file(&repo.join("examples/systems/crane_sensor.toml")).unwrap();
        let names: Vec<String> = ["crane.x", "crane.theta", "sensor.y[1]", "nobody.x"]
            .map(String::from)
            .into();
        assert_eq!(
            axis_labels(&system, &names),
            [
                "crane.x [m]",
                "crane.theta [rad]",
                "sensor.y[1]",
                "nobody.x"
            ]
        );
    }
}
