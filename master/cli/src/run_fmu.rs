//! `spurio run model.fmu`: one FMU straight from the command line, as `fmpy simulate` and
//! `fmusim` do. Co-Simulation runs as a one-instance system through the engine; Model
//! Exchange through the engine's Model Exchange driver and solvers. The model description's
//! `DefaultExperiment` gives what the flags do not.

use anyhow::{bail, Context, Result};
use spurio_master::fmu::me::read_description;
use spurio_master::fmu::{FmuFile, Interface, LoadOptions};
use spurio_master::model_exchange::{simulate, Method, Options};
use spurio_master::{CsvWriter, InstanceDescription, System, SystemDescription};
use std::collections::BTreeMap;
use std::io::Read;
use std::path::{Path, PathBuf};

/// The flags of `spurio run` that apply to a single FMU.
#[derive(clap::Args, Clone, Debug, Default)]
pub struct FmuArgs {
    /// For an FMU: the interface to run, `me` (Model Exchange: spurio's solvers integrate
    /// it) or `cs` (Co-Simulation). Default: Co-Simulation if the FMU offers it, else Model
    /// Exchange.
    #[arg(long, value_parser = ["me", "cs"])]
    pub interface: Option<String>,
    /// For an FMU: the start time (default: the DefaultExperiment's, else 0).
    #[arg(long, value_name = "SECONDS", allow_negative_numbers = true)]
    pub start_time: Option<f64>,
    /// For an FMU: the stop time (default: the DefaultExperiment's, else 1).
    #[arg(long, value_name = "SECONDS", allow_negative_numbers = true)]
    pub stop_time: Option<f64>,
    /// For an FMU: the output interval (Co-Simulation: the communication step). Default: the
    /// DefaultExperiment's stepSize, else (stop − start)/500.
    #[arg(long, value_name = "SECONDS", value_parser = crate::limits::parse_positive)]
    pub step_size: Option<f64>,
    /// For an FMU: a start value `name=value` (repeatable).
    #[arg(long = "set", value_name = "NAME=VALUE")]
    pub set: Vec<String>,
    /// For a Model Exchange run: the solver, `dopri5` (explicit Dormand–Prince 5(4), the
    /// default), `rodas4` (also `stiff`: Rosenbrock, L-stable, with dense output from its
    /// stages), `rodas3` or `shampine4`.
    #[arg(long, value_name = "METHOD")]
    pub solver: Option<Method>,
    /// For a Model Exchange run: the relative tolerance (the absolute one: the same times each
    /// state's nominal). Default: the DefaultExperiment's, else 1e-6.
    #[arg(long, value_parser = crate::limits::parse_positive)]
    pub tolerance: Option<f64>,
    /// For a Model Exchange run: the longest solver step.
    #[arg(long, value_name = "SECONDS", value_parser = crate::limits::parse_positive)]
    pub max_step: Option<f64>,
}

impl FmuArgs {
    /// The flags given, by name (those that only apply to an FMU).
    pub fn given(&self) -> Vec<&'static str> {
        let mut given = Vec::new();
        let flags = [
            ("--interface", self.interface.is_some()),
            ("--start-time", self.start_time.is_some()),
            ("--stop-time", self.stop_time.is_some()),
            ("--step-size", self.step_size.is_some()),
            ("--set", !self.set.is_empty()),
            ("--solver", self.solver.is_some()),
            ("--tolerance", self.tolerance.is_some()),
            ("--max-step", self.max_step.is_some()),
        ];
        for (flag, present) in flags {
            if present {
                given.push(flag);
            }
        }
        given
    }

    /// The `--set` values as (name, number).
    fn start_values(&self) -> Result<Vec<(String, f64)>> {
        self.set
            .iter()
            .map(|entry| {
                let Some((name, value)) = entry.split_once('=') else {
                    bail!("--set {entry}: expected NAME=VALUE");
                };
                let value = match value.trim() {
                    "true" => 1.0,
                    "false" => 0.0,
                    v => v.parse().with_context(|| {
                        format!("--set {entry}: `{v}` is not a number (or true/false)")
                    })?,
                };
                Ok((name.trim().to_string(), value))
            })
            .collect()
    }
}

/// What a path given to `spurio run` is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RunTarget {
    /// A TOML system file.
    System,
    /// An SSP archive.
    Ssp,
    /// An FMU.
    Fmu,
}

/// Tells a system file, an SSP archive and an FMU apart by name and content; anything else
/// is an error saying what `spurio run` expects.
pub fn classify(path: &Path) -> Result<RunTarget> {
    let extension = path
        .extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase());
    match extension.as_deref() {
        Some("fmu") => return Ok(RunTarget::Fmu),
        Some("ssp") => return Ok(RunTarget::Ssp),
        _ => {}
    }
    let mut head = [0u8; 4096];
    let n = std::fs::File::open(path)
        .and_then(|mut f| f.read(&mut head))
        .with_context(|| format!("cannot read {}", path.display()))?;
    let head = &head[..n];
    if head.starts_with(b"PK\x03\x04") {
        // A zip archive: an FMU whatever its name (the loader says what it lacks).
        return Ok(RunTarget::Fmu);
    }
    // Text cut inside a character at the end of the read is still text.
    if std::str::from_utf8(head).is_err_and(|e| e.error_len().is_some()) {
        bail!(
            "{} is neither a system file (TOML, `.toml`), an SSP archive (`.ssp`) nor an FMU (`.fmu`, a zip archive): `spurio run` takes one of these",
            path.display()
        );
    }
    Ok(RunTarget::System)
}

/// The interface to run `path` with: the one asked for, or Co-Simulation when the FMU offers
/// it and Model Exchange otherwise; the FMU loaded for it.
fn open(path: &Path, asked: Option<&str>, options: &LoadOptions) -> Result<FmuFile> {
    let interface = asked.map(|a| match a {
        "me" => Interface::ModelExchange,
        _ => Interface::CoSimulation,
    });
    Ok(FmuFile::open_preferring(path, options, interface)?)
}

/// The experiment of a run: the flags, else the DefaultExperiment, else fmpy's defaults.
struct Experiment {
    start: f64,
    stop: f64,
    step: f64,
    tolerance: Option<f64>,
}

fn experiment(fmu: &FmuFile, args: &FmuArgs) -> Result<Experiment> {
    let default = read_description(fmu)?.default_experiment;
    let start = args.start_time.or(default.start_time).unwrap_or(0.0);
    let stop = args.stop_time.or(default.stop_time).unwrap_or(start + 1.0);
    let step = args
        .step_size
        .or(default.step_size)
        .unwrap_or((stop - start) / 500.0);
    if !(stop > start && step > 0.0 && step.is_finite()) {
        bail!(
            "{}: the run from {start} to {stop} every {step} s is empty: give --stop-time after the start time and a positive --step-size",
            fmu.path.display()
        );
    }
    Ok(Experiment {
        start,
        stop,
        step,
        tolerance: args.tolerance.or(default.tolerance),
    })
}

/// Runs the FMU at `path`; the results go to `out` as CSV (fmpy's layout).
pub fn run(
    path: &Path,
    out: &Path,
    args: &FmuArgs,
    verbose: bool,
    options: &LoadOptions,
    run_system: impl FnOnce(System) -> Result<()>,
) -> Result<()> {
    let fmu = open(path, args.interface.as_deref(), options)?;
    let e = experiment(&fmu, args)?;
    if fmu.interface == Interface::CoSimulation {
        for flag in ["--solver", "--tolerance", "--max-step"] {
            if args.given().contains(&flag) {
                bail!("{flag} applies to a Model Exchange run (--interface me); {} runs as Co-Simulation with its own solver", path.display());
            }
        }
        // As a system file writes them: true/false, integers, numbers.
        let parameters: BTreeMap<String, toml::Value> = args
            .set
            .iter()
            .zip(args.start_values()?)
            .map(|(entry, (name, value))| {
                let text = entry.split_once('=').map_or("", |(_, v)| v.trim());
                let value = match text {
                    "true" => toml::Value::Boolean(true),
                    "false" => toml::Value::Boolean(false),
                    t => t
                        .parse::<i64>()
                        .map_or(toml::Value::Float(value), toml::Value::Integer),
                };
                (name, value)
            })
            .collect();
        let absolute: PathBuf = std::path::absolute(path)?;
        let description = SystemDescription {
            name: fmu.model_name.clone(),
            start_time: e.start,
            stop_time: e.stop,
            step_size: e.step,
            algorithm: Default::default(),
            instances: vec![InstanceDescription {
                parameters,
                ..InstanceDescription::new(fmu.model_identifier.clone(), absolute)
            }],
            connections: Vec::new(),
            record: Vec::new(),
        };
        drop(fmu);
        let system = System::resolve_loading(&description, Path::new("."), options)?;
        return run_system(system);
    }
    let mut instance = fmu.instantiate_model_exchange(&fmu.model_identifier, false)?;
    let layout = instance
        .layout(&fmu, &args.start_values()?)
        .map_err(anyhow::Error::msg)?;
    let method = args.solver.unwrap_or_default();
    let run_options = Options {
        method,
        tolerance: e.tolerance.unwrap_or(1e-6),
        max_step: args.max_step,
        ..Options::new(e.start, e.stop, e.step)
    };
    let mut csv =
        CsvWriter::create(out).with_context(|| format!("cannot write {}", out.display()))?;
    let mut on_event = |event: &spurio_master::model_exchange::Event| {
        if verbose {
            eprintln!("spurio: t = {:.17}: {}", event.time, event.kind);
        }
    };
    let summary = simulate(
        &mut instance,
        &layout,
        &run_options,
        &mut csv,
        &mut on_event,
    )
    .with_context(|| {
        format!(
            "the run ended early; the rows recorded before are in {}",
            out.display()
        )
    })?;
    let s = summary.statistics;
    say!(
        "{}: Model Exchange, {method} at tolerance {:e}: {} steps ({} rejected), {} right-hand sides, {} Jacobians ({} directional-derivative calls); {} state, {} time, {} step events",
        fmu.model_name,
        run_options.tolerance,
        s.accepted,
        s.rejected,
        s.rhs,
        s.jacobians,
        s.jacobian_products,
        summary.state_events,
        summary.time_events,
        summary.step_events,
    );
    if summary.terminated {
        say!(
            "the FMU ended the simulation at t = {} (terminateSimulation)",
            summary.end_time
        );
    }
    say!("wrote {}", out.display());
    Ok(())
}
