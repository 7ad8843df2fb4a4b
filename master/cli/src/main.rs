//! `spurio`: the command line of the spurio FMU set.
//!
//! - `spurio package` writes the `.fmu` archives of every FMU (or the ones named) from the
//!   compiled libraries;
//! - `spurio model-descriptions` checks (or, with `--write`, regenerates) the committed
//!   `modelDescription/*.xml` against what the built FMU libraries generate;
//! - `spurio info` shows what any FMU says about itself, `spurio validate` checks its model
//!   description against the standard (schema and rules);
//! - `spurio diagnose` runs the outlier diagnostics (Grubbs, kurtosis, skewness, E_res,
//!   histogram) on a column of a results CSV.

// No unsafe code here; a module that must call into a compiled FMU library directly opts
// in with `#[allow(unsafe_code)]` on that module alone.
#![deny(unsafe_code)]

use spurio_analysis::{diagnose, plot};
use spurio_master::logging;
use spurio_master::{CsvWriter, NoRecording, Observer, TimeSeries};
use spurio_master::{RunEnd, RunError, RunOptions, Simulation, System};

/// `println!` for what a command tells the user on stdout. A closed stdout (`spurio run … |
/// head`) ends nothing: the line is dropped, the run goes on and ends with its own status
/// (`println!` would panic with a backtrace); another failure to write is said on stderr.
macro_rules! say {
    ($($arg:tt)*) => {
        $crate::say_line(format_args!($($arg)*))
    };
}

/// Writes one line of [`say!`] to stdout.
fn say_line(line: std::fmt::Arguments<'_>) {
    use std::io::Write;
    let mut out = std::io::stdout().lock();
    let written = out
        .write_fmt(line)
        .and_then(|()| out.write_all(b"\n"))
        .and_then(|()| out.flush());
    match written {
        Err(e) if e.kind() != std::io::ErrorKind::BrokenPipe => {
            eprintln!("spurio: cannot write to stdout: {e}");
        }
        _ => {}
    }
}

mod fmi3_extras;
mod guard;
mod identify;
mod inspect;
mod library_query;
mod limits;
mod package;
mod package_estimator;
#[cfg(test)]
#[path = "../../tests/common/packaged_fmus.rs"]
mod packaged_fmus;
mod progress;
mod run_fmu;
mod sweep;
mod workers;

use anyhow::{bail, Context, Result};
use clap::{Parser, Subcommand};
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

#[derive(Parser)]
#[command(
    name = "spurio",
    version,
    about = "Runs co-simulations of FMI 2.0 and 3.0 Co-Simulation FMUs (TOML systems, SSP), sweeps them, diagnoses their results and packages spurio's FMUs for robust identification and control"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Run a co-simulation system (TOML, or an SSP 1.0/2.0 archive) and write its results as
    /// CSV (fmpy's layout). The run ends at the stop time, or earlier when an FMU asks to end
    /// the simulation (FMI 2.0: fmi2Discard with fmi2Terminated, as the Reference FMU Stair
    /// does; FMI 3.0: terminateSimulation from fmi3DoStep): the
    /// last point is recorded and the reason printed.
    ///
    /// Or run one FMU (`spurio run model.fmu`, as `fmpy simulate` and `fmusim`): Co-Simulation,
    /// or Model Exchange integrated by spurio's solvers (`--interface me`), over the model
    /// description's DefaultExperiment unless the flags say otherwise.
    Run {
        /// The system file (`.toml`), SSP archive (`.ssp`; its FMUs are unpacked into a
        /// temporary folder, removed afterwards unless --unpack-to is given) or FMU (`.fmu`).
        system: PathBuf,
        /// Where to write the results.
        #[arg(long, default_value = "results.csv")]
        out: PathBuf,
        /// Record nothing: no CSV is written, and after a step only the outputs that feed
        /// connections are read (OMSimulator's `--resultFile=""`, fmpy's `output=[]`); for
        /// benchmarks.
        #[arg(long, conflicts_with_all = ["out", "plot", "output_interval"])]
        no_record: bool,
        /// Record every K-th communication point (the first and the last are always
        /// recorded); 1 records every one. fmpy's `output_interval` is K × step_size.
        #[arg(long, value_name = "K", default_value_t = 1,
              value_parser = clap::value_parser!(u64).range(1..))]
        output_interval: u64,
        /// Unpack an SSP archive's FMUs into this folder and keep them there.
        #[arg(long, value_name = "DIR")]
        unpack_to: Option<PathBuf>,
        /// Also plot these recorded variables (comma-separated names) to a PNG beside the CSV.
        #[arg(long, value_delimiter = ',')]
        plot: Vec<String>,
        /// Pace the run: 1 = real time, 2 = twice as fast (a positive number).
        #[arg(long, value_parser = limits::parse_positive)]
        real_time: Option<f64>,
        /// Show a progress bar.
        #[arg(long)]
        progress: bool,
        /// Print the FMUs' informational log messages too.
        #[arg(long)]
        verbose: bool,
        #[command(flatten)]
        limits: limits::Limits,
        #[command(flatten)]
        fmu: run_fmu::FmuArgs,
    },
    /// Identify an FMU's parameters (and states) from recorded data: e.g. `spurio identify
    /// plant.fmu --data rig.csv --input U=force --output x=pos --free m_c,l,b`. Online by a
    /// robust unscented Kalman filter (`--method ukf`) or offline by maximum likelihood
    /// (`--method ml`); writes estimates.csv and report.md into --out.
    Identify(identify::IdentifyArgs),
    /// Package FMUs: writes <out>/<ModelIdentifier>.fmu for every bundled FMU variant.
    Package {
        /// Model identifiers to package (default: all).
        names: Vec<String>,
        #[command(flatten)]
        packaging: Packaging,
    },
    /// Package one FMU for your own dimensions: e.g. `spurio package-variant KalmanFilter
    /// --set n=3 --set p=1 --set m=1 --name MyKalmanFilter` writes MyKalmanFilter.fmu whose
    /// modelDescription has A[1,1]…A[3,3], y[1], x_hat[1]…x_hat[3], …, and the FMI 3.0
    /// fmi3/MyKalmanFilter.fmu with the arrays A (3×3), y, x_hat, ….
    PackageVariant {
        /// Model identifier of a dimension-generic FMU.
        model_identifier: String,
        /// Configuration entries `key=value` (the FMU's page lists its keys).
        #[arg(long = "set", value_name = "KEY=VALUE")]
        settings: Vec<String>,
        /// File name of the .fmu without extension (default: the model identifier).
        #[arg(long)]
        name: Option<String>,
        #[command(flatten)]
        packaging: Packaging,
    },
    /// Package a table of recorded signals as an FMU for any FMI tool, like Modelica's
    /// CombiTimeTable: e.g. `spurio package-data rig.csv --name RigData --interpolation
    /// linear` writes RigData.fmu (FMI 2.0) and fmi3/RigData.fmu (FMI 3.0) whose outputs are
    /// the columns (`c`, `c.valid`, `c.held`, as a system's data instance), with the table
    /// in resources/ and its time range as the default experiment.
    PackageData {
        /// The table: CSV with a `time` column, one column per signal, units as
        /// `name [unit]` or a units row (the layout `spurio run` writes).
        table: PathBuf,
        /// Between samples: `hold` (the sample at or before t) or `linear`.
        #[arg(long, default_value = "hold", value_parser = ["hold", "linear"])]
        interpolation: String,
        /// File name of the .fmu without extension, and its model name (default: the
        /// table's file stem).
        #[arg(long)]
        name: Option<String>,
        #[command(flatten)]
        packaging: Packaging,
    },
    /// Package an estimator FMU for any plant FMU with Model Exchange: e.g. `spurio
    /// package-estimator GantryCrane.fmu --free M,l,f_c --input U --output x --output theta
    /// --noise x=1e-6,theta=1e-5 --name GantryCraneEstimator` writes GantryCraneEstimator.fmu
    /// (FMI 2.0) and fmi3/GantryCraneEstimator.fmu (FMI 3.0): the robust online filter of
    /// `spurio identify --method ukf|ekf` on the plant, which it carries in resources/plant/;
    /// inputs u.<input>, y.<output> (and y.<output>.valid), outputs x_hat.<state>,
    /// theta_hat.<parameter>, sd.<…>, innovation.<output>, innovation_sd.<output>,
    /// weight.<output>.
    PackageEstimator {
        /// The plant: an FMU with Model Exchange (FMI 2.0 or 3.0).
        plant: PathBuf,
        /// The parameters to estimate, comma-separated.
        #[arg(long, value_delimiter = ',', required = true)]
        free: Vec<String>,
        /// An input of the plant (repeatable, in order).
        #[arg(long)]
        input: Vec<String>,
        /// A measured variable of the plant (repeatable, in order).
        #[arg(long, required = true)]
        output: Vec<String>,
        /// The file name of the .fmu without extension, and its model name.
        #[arg(long)]
        name: String,
        /// Robust weights against outliers.
        #[arg(long, default_value = "huber", value_parser = ["huber", "tukey", "none"])]
        robust: String,
        /// The online filter: robust unscented (`ukf`) or extended (`ekf`) Kalman filter.
        #[arg(long, default_value = "ukf", value_parser = ["ukf", "ekf"])]
        method: String,
        /// The measurement variances, `NAME=VALUE` for every --output (an FMU cannot take
        /// them from data); the FMU's parameters `noise.<output>` start there.
        #[arg(long, value_delimiter = ',', required = true)]
        noise: Vec<String>,
        /// A free parameter's start value `NAME=VALUE` (default: the plant's).
        #[arg(long, value_delimiter = ',')]
        start: Vec<String>,
        /// A parameter of the plant set for the experiment, not estimated: `NAME=VALUE`.
        #[arg(long, value_delimiter = ',')]
        set: Vec<String>,
        #[command(flatten)]
        packaging: Packaging,
    },
    /// Run a system many times with one parameter varied (e.g. a seed), in parallel, and
    /// print metrics as mean ± std; or one shard of it (`--shard i/N`), or stage it as a
    /// Slurm job array (`--slurm <dir>`).
    Sweep(sweep::SweepArgs),
    /// Merge the shard files of a sweep into the table the one-machine sweep prints (checking
    /// they are of one sweep, none missing or duplicated), or show its progress.
    SweepMerge(sweep::MergeArgs),
    /// Export a system (TOML) as an SSP archive with its FMUs, for OMSimulator or fmpy. The
    /// SSD carries OMSimulator's fixed-step master annotation, so
    /// `OMSimulator <out> --stopTime <stop_time>` runs it (OMSimulator does not take the
    /// SSD's stop time by itself).
    SspExport {
        /// The system file.
        system: PathBuf,
        /// The .ssp to write.
        out: PathBuf,
        /// The SSP version of the files: 1.0 (read by fmpy and OMSimulator) or 2.0 (what
        /// OMSimulator 3.x writes; fmpy 0.3 refuses it).
        #[arg(long, default_value = "1.0")]
        ssp_version: spurio_master::ssp::SspVersion,
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
    /// Show what an FMI 2.0 or 3.0 FMU (any, ours or a third party's) says about itself:
    /// interfaces, FMI version, model name, GUID or instantiation token, generation tool,
    /// platforms, default experiment, and every variable with its value reference,
    /// causality, variability, type, unit, start value and bounds.
    Info {
        /// The FMU.
        fmu: PathBuf,
        /// Print it as JSON.
        #[arg(long)]
        json: bool,
    },
    /// Check an FMI 2.0 or 3.0 FMU's model description against the standard: its XML schema
    /// and the rules the schema cannot express (unique names and value references, names of
    /// the naming convention, causality/variability/initial, start values, units and types,
    /// ModelStructure, model identifiers and platform binaries). Prints each problem with
    /// its line; exits with 1 when there is one.
    Validate {
        /// The FMU.
        fmu: PathBuf,
    },
    /// Runs of a sweep in a worker process: values in on standard input, metrics out.
    #[command(hide = true)]
    SweepWorker(sweep::WorkerArgs),
    /// Compare the committed modelDescription/*.xml with what the built FMU libraries generate.
    ModelDescriptions {
        /// Regenerate the files instead of checking them.
        #[arg(long)]
        write: bool,
        /// The repository root (holding modelDescription/ and fmus/).
        #[arg(long, default_value = ".")]
        repo: PathBuf,
        /// Folder with the compiled FMU libraries, which generate the descriptions.
        #[arg(long, default_value = "target/release")]
        lib_dir: PathBuf,
    },
}

/// Runs the command; the session folder (see [`guard`]) is removed whatever the outcome.
fn main() -> ExitCode {
    let cli = Cli::parse();
    let verbose = matches!(cli.command, Command::Run { verbose: true, .. });
    if matches!(cli.command, Command::SweepWorker(_)) {
        // A worker's standard error goes to a file: its errors quote what the FMUs logged.
        logging::install_unseen(verbose);
    } else {
        logging::install(verbose);
    }
    // A panic (a bug) still removes the session folder before the process ends with 101.
    let outcome = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
        guard::start().and_then(|()| match &cli.command {
            // A run goes on in a supervised child process (see guard::supervise).
            Command::Run { out, no_record, .. } if !guard::is_supervised() => {
                let code = guard::supervise((!no_record).then_some(out.as_path()))?;
                Ok(ExitCode::from(u8::try_from(code).unwrap_or(1)))
            }
            _ => command(cli.command),
        })
    }));
    guard::finish();
    let Ok(outcome) = outcome else {
        return ExitCode::from(101);
    };
    match outcome {
        Ok(code) => code,
        Err(e) => {
            eprintln!("{}", error_report(&e));
            ExitCode::FAILURE
        }
    }
}

/// `Error: ` and the error, then its causes under `Caused by:` as anyhow lays them out, without
/// a backtrace. Each error of the engine and the batch tools says its cause once (quoted in
/// its message, or as its source, never both), so no message appears twice.
fn error_report(error: &anyhow::Error) -> String {
    let mut report = format!("Error: {error}");
    let causes: Vec<String> = error.chain().skip(1).map(|c| c.to_string()).collect();
    match causes.as_slice() {
        [] => {}
        [one] => report.push_str(&format!("\n\nCaused by:\n    {one}")),
        many => {
            report.push_str("\n\nCaused by:");
            for (i, cause) in many.iter().enumerate() {
                report.push_str(&format!("\n    {i}: {cause}"));
            }
        }
    }
    report
}

/// `spurio run`.
#[allow(clippy::too_many_arguments)]
fn run(
    system: &Path,
    out: &Path,
    no_record: bool,
    output_interval: u64,
    unpack_to: Option<&Path>,
    plotted: &[String],
    real_time: Option<f64>,
    progress: bool,
    limits: &limits::Limits,
) -> Result<()> {
    let resolved = System::from_file_loading(system, unpack_to, &limits.load_options())?;
    run_resolved(
        resolved,
        system,
        out,
        no_record,
        output_interval,
        plotted,
        real_time,
        progress,
        limits,
    )
}

/// `spurio run` of a resolved system (`system`: where it came from, for messages).
#[allow(clippy::too_many_arguments)]
fn run_resolved(
    mut resolved: System,
    system: &Path,
    out: &Path,
    no_record: bool,
    output_interval: u64,
    plotted: &[String],
    real_time: Option<f64>,
    progress: bool,
    limits: &limits::Limits,
) -> Result<()> {
    if no_record {
        // Only the outputs that feed connections are read after a step.
        resolved.record_nothing()?;
    }
    for note in resolved.notes() {
        eprintln!("spurio: {}: {note}", system.display());
    }
    limits.check_steps(&resolved)?;
    // The plotted variables and their axis labels (with units), checked before the run.
    let plotted = plotted
        .iter()
        .map(|name| {
            let label = plot::axis_label(&resolved, name)?;
            if !resolved.plan().recorded.names.contains(name) {
                bail!(
                    "cannot plot `{name}`: it is not recorded (recorded: {})",
                    resolved.plan().recorded.names.join(", ")
                );
            }
            Ok((name.clone(), label))
        })
        .collect::<Result<Vec<_>>>()?;
    let monitor = limits.call_timeout.map(guard::watchdog);
    let mut sim = Simulation::with_monitor(&resolved, monitor)?;
    let options = RunOptions {
        real_time_factor: real_time,
        output_interval,
    };
    // The progress bar, if asked for, is an observer around the run's own.
    let steps = sim.step_count();
    let (start, step) = (resolved.start_time(), resolved.step_size());
    let run = |sim: &mut Simulation, observer: &mut dyn Observer| {
        if progress {
            let mut bar = progress::Progress::new(observer, steps, start, step);
            sim.run(&mut bar, &options)
        } else {
            sim.run(observer, &options)
        }
    };
    if no_record {
        let end = run(&mut sim, &mut NoRecording)?;
        sim.terminate()?;
        if let RunEnd::Terminated { .. } = end {
            say!("{end}");
        }
        return Ok(());
    }
    let csv = CsvWriter::create(out).with_context(|| format!("cannot write {}", out.display()))?;
    let csv = Arc::new(Mutex::new(csv));
    let shown = out.display().to_string();
    guard::on_early_exit({
        let csv = csv.clone();
        move || {
            let mut csv = guard::lock(&csv);
            Some(match csv.finish() {
                Ok(()) => format!("the rows recorded so far are in {shown}"),
                Err(e) => format!("cannot write {shown}: {e}"),
            })
        }
    });
    let mut observer = Recorder {
        csv: csv.clone(),
        series: (!plotted.is_empty()).then(TimeSeries::default),
        flushed: Instant::now(),
    };
    let end = match run(&mut sim, &mut observer) {
        Ok(end) => end,
        Err(RunError::Output(e)) => bail!("cannot write {}: {e}", out.display()),
        Err(e) => {
            let flushed = guard::lock(&csv).finish();
            let note = match flushed {
                Ok(()) => format!("the rows recorded before are in {}", out.display()),
                Err(w) => format!("cannot write {}: {w}", out.display()),
            };
            return Err(anyhow::Error::new(e).context(format!("the run ended early; {note}")));
        }
    };
    sim.terminate()?;
    if let Some(series) = &observer.series {
        let png = out.with_extension("png");
        plot::labelled_time_series_png(&png, resolved.name(), series, &plotted)?;
        say!("wrote {}", png.display());
    }
    if let RunEnd::Terminated { .. } = end {
        say!("{end}");
    }
    say!("wrote {}", out.display());
    Ok(())
}

/// Writes every sample to the CSV (shared with the early-exit flush), and keeps them in
/// memory too when they are to be plotted.
struct Recorder {
    csv: Arc<Mutex<CsvWriter<std::io::BufWriter<std::fs::File>>>>,
    series: Option<TimeSeries>,
    /// When the rows were last flushed to the file: at most [`FLUSH_EVERY`] of rows are
    /// lost if an FMU kills the process.
    flushed: Instant,
}

/// How often the rows of a run are flushed to the results file.
const FLUSH_EVERY: Duration = Duration::from_millis(50);

impl Recorder {
    fn csv(&self) -> std::sync::MutexGuard<'_, CsvWriter<std::io::BufWriter<std::fs::File>>> {
        guard::lock(&self.csv)
    }
}

impl Observer for Recorder {
    fn start(&mut self, names: &[String]) -> std::io::Result<()> {
        if let Some(s) = &mut self.series {
            s.start(names)?;
        }
        let mut csv = self.csv();
        csv.start(names)?;
        csv.flush()
    }
    fn sample(&mut self, time: f64, values: &[f64]) -> std::io::Result<()> {
        if let Some(s) = &mut self.series {
            s.sample(time, values)?;
        }
        let flush = self.flushed.elapsed() >= FLUSH_EVERY;
        let mut csv = self.csv();
        csv.sample(time, values)?;
        if flush {
            csv.flush()?;
            drop(csv);
            self.flushed = Instant::now();
        }
        Ok(())
    }
    fn finish(&mut self) -> std::io::Result<()> {
        self.csv().finish()
    }
}

fn command(command: Command) -> Result<ExitCode> {
    match command {
        Command::Run {
            system,
            out,
            no_record,
            output_interval,
            unpack_to,
            plot: plotted,
            real_time,
            progress,
            verbose,
            limits,
            fmu,
        } => match run_fmu::classify(&system)? {
            run_fmu::RunTarget::Fmu => run_fmu::run(
                &system,
                &out,
                &fmu,
                verbose,
                &limits.load_options(),
                |resolved| {
                    run_resolved(
                        resolved,
                        &system,
                        &out,
                        no_record,
                        output_interval,
                        &plotted,
                        real_time,
                        progress,
                        &limits,
                    )
                },
            )?,
            _ => {
                let given = fmu.given();
                if !given.is_empty() {
                    bail!(
                        "{} apply to running one FMU, not a system file: set the values in {}",
                        given.join(", "),
                        system.display()
                    );
                }
                run(
                    &system,
                    &out,
                    no_record,
                    output_interval,
                    unpack_to.as_deref(),
                    &plotted,
                    real_time,
                    progress,
                    &limits,
                )?
            }
        },
        Command::Package { names, packaging } => {
            let Packaging {
                lib_dir,
                out,
                platform_dirs,
                repo,
            } = packaging;
            let platforms = parse_platforms(&platform_dirs)?;
            for path in package::package_bundled(&repo, &lib_dir, &platforms, &names, &out)? {
                say!("wrote {}", path.display());
            }
        }
        Command::PackageVariant {
            model_identifier,
            settings,
            name,
            packaging:
                Packaging {
                    lib_dir,
                    out,
                    platform_dirs,
                    repo,
                },
        } => {
            let platforms = parse_platforms(&platform_dirs)?;
            let stem = name.unwrap_or_else(|| model_identifier.clone());
            for path in package::package_custom(
                &repo,
                &lib_dir,
                &platforms,
                &model_identifier,
                &settings,
                &stem,
                &out,
            )? {
                say!("wrote {}", path.display());
            }
        }
        Command::PackageData {
            table,
            interpolation,
            name,
            packaging,
        } => {
            let interpolation = spurio_master::Interpolation::named(&interpolation)
                .with_context(|| format!("--interpolation {interpolation}: hold or linear"))?;
            let stem = match name {
                Some(name) => name,
                None => table
                    .file_stem()
                    .map(|s| s.to_string_lossy().into_owned())
                    .with_context(|| format!("{}: no file name", table.display()))?,
            };
            let written = package::package_data(
                &packaging.repo,
                &packaging.lib_dir,
                &parse_platforms(&packaging.platform_dirs)?,
                &table,
                interpolation,
                &stem,
                &packaging.out,
            )?;
            for path in written {
                println!("wrote {}", path.display());
            }
        }
        Command::PackageEstimator {
            plant,
            free,
            input,
            output,
            name,
            robust,
            method,
            noise,
            start,
            set,
            packaging,
        } => {
            let noise = identify::values("--noise", &noise)?;
            let request = package_estimator::Request {
                noise: Some(package_estimator::noise_in_order(&output, &noise)?),
                fmu: plant,
                plant: spurio_identify::plant::PlantSpec {
                    free,
                    inputs: input,
                    outputs: output,
                },
                tolerance: identify::TOLERANCE,
                robust: spurio_identify::online::Robust::named(&robust)
                    .with_context(|| format!("--robust {robust}: huber, tukey or none"))?,
                method: spurio_identify::online::Method::named(&method)
                    .with_context(|| format!("--method {method}: ukf or ekf"))?,
                validate: 0.0,
                starts: identify::values("--start", &start)?,
                set: identify::values("--set", &set)?,
            };
            let written = package_estimator::package_estimator(
                &packaging.repo,
                &packaging.lib_dir,
                &parse_platforms(&packaging.platform_dirs)?,
                &request,
                &name,
                &packaging.out,
            )?;
            for path in written {
                println!("wrote {}", path.display());
            }
        }
        Command::Info { fmu, json } => inspect::info(&fmu, json)?,
        Command::Validate { fmu } => inspect::validate(&fmu)?,
        Command::Sweep(args) => return sweep::run(args),
        Command::SweepWorker(args) => sweep::worker(args)?,
        Command::SweepMerge(args) => sweep::merge(args)?,
        Command::SspExport {
            system,
            out,
            ssp_version,
        } => {
            let resolved = System::from_file(&system)?;
            resolved.export_ssp(&out, ssp_version)?;
            say!("wrote {} (SSP {ssp_version})", out.display());
            say!(
                "run it with: OMSimulator {} --stopTime {:?}   or: spurio run {}",
                out.display(),
                resolved.stop_time(),
                out.display()
            );
        }
        Command::Identify(args) => identify::run(&args)?,
        Command::SspImport { ssp, out } => {
            let imported = spurio_master::ssp::import(&ssp, &out)?;
            for note in &imported.notes {
                eprintln!("spurio: {}: {note}", ssp.display());
            }
            let path = out.join("system.toml");
            std::fs::write(&path, toml::to_string_pretty(&imported.description)?)?;
            say!("wrote {}", path.display());
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
        Command::ModelDescriptions {
            write,
            repo,
            lib_dir,
        } => {
            let touched = package::model_descriptions(&repo, &lib_dir, write)?;
            if write {
                for path in &touched {
                    say!("wrote {}", path.display());
                }
            } else if !touched.is_empty() {
                let stale: Vec<String> = touched.iter().map(|p| p.display().to_string()).collect();
                bail!(
                    "these model descriptions differ from the FMUs' declarations (run `spurio model-descriptions --write`): {}",
                    stale.join(", ")
                );
            }
        }
    }
    Ok(ExitCode::SUCCESS)
}

/// `--platform-dir NAME=DIR` values.
/// Where `package` and `package-variant` find the libraries and the FMUs' pages, and where
/// they write the .fmu files.
#[derive(clap::Args)]
struct Packaging {
    /// Folder with the compiled `lib<ModelIdentifier>.so` files.
    #[arg(long, default_value = "target/release")]
    lib_dir: PathBuf,
    /// Where to write the .fmu files.
    #[arg(long, default_value = "build/fmus")]
    out: PathBuf,
    /// Also add the binaries of another platform: `PLATFORM=DIR` (repeatable), e.g.
    /// `win64=target/x86_64-pc-windows-gnu/release` (`<Id>.dll`) or
    /// `aarch64-linux=…/release` (`lib<Id>.so`); `linux64` comes from `--lib-dir`.
    #[arg(long = "platform-dir", value_name = "PLATFORM=DIR")]
    platform_dirs: Vec<String>,
    /// The repository root (holding fmus/<Id>/ with each FMU's page).
    #[arg(long, default_value = ".")]
    repo: PathBuf,
}

fn parse_platforms(values: &[String]) -> Result<Vec<package::Platform>> {
    values.iter().map(|v| package::Platform::parse(v)).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn plot_axes_carry_the_units_of_the_model_description() {
        let repo = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..");
        crate::packaged_fmus::packaged_fmus(&repo);
        let system = System::from_file(&repo.join("examples/systems/crane_sensor.toml")).unwrap();
        let label = |name: &str| plot::axis_label(&system, name).map_err(|e| e.to_string());
        assert_eq!(label("crane.x").unwrap(), "crane.x [m]");
        assert_eq!(label("crane.theta").unwrap(), "crane.theta [rad]");
        assert_eq!(label("sensor.y[1]").unwrap(), "sensor.y[1]");
        let unknown = label("nobody.x").unwrap_err();
        assert!(unknown.contains("nobody"), "{unknown}");
    }
}
