//! `spurio sweep` — on this machine, one shard of it (`--shard i/N`), or staged for a Slurm
//! cluster (`--slurm <dir>`) — and `spurio sweep-merge`, which checks the shards of a sweep
//! and writes the table the one-machine sweep writes, or shows how far a sweep has come.

use crate::guard;
use crate::limits::{self, Limits};
use crate::workers;
use anyhow::{bail, Context, Result};
use clap::Args;
use spurio_batch::shard::{self, MergeOptions, RunRecord, Shard, ShardFile, SweepDefinition};
use spurio_batch::slurm::{self, Manifest, Queue, SlurmOptions, SweepArguments};
use spurio_batch::sweep::{self as sweeps, Metric, SweepResult, Variation};
use spurio_master::{RunOptions, System};
use std::ops::Range;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

#[derive(Args)]
pub struct SweepArgs {
    /// The system file.
    system: PathBuf,
    /// `instance.variable=1..100` (integers) or `instance.variable=0.1,0.2`.
    #[arg(long)]
    vary: String,
    /// Metrics: final(v), mean(v), rms(v), max_abs(v), e_res(a, b), settling(v, bound).
    #[arg(long = "metric", required = true)]
    metrics: Vec<String>,
    /// Runs at once, each in its own worker process (0: one per core; at most 4 per core).
    #[arg(long, default_value_t = 0)]
    threads: usize,
    /// Refuse a sweep of more runs than this.
    #[arg(long, value_name = "N", default_value_t = sweeps::DEFAULT_MAX_RUNS)]
    max_runs: u64,
    #[command(flatten)]
    limits: Limits,
    /// Also write every run's metrics as CSV here.
    #[arg(long, conflicts_with_all = ["shard", "slurm"])]
    out: Option<PathBuf>,
    /// Run only shard i of N (0 <= i < N; runs cut into N contiguous ranges, each run seeded
    /// by its run index as in the whole sweep) and write its shard file.
    #[arg(
        long,
        value_name = "i/N",
        requires = "shard_out",
        conflicts_with = "slurm"
    )]
    shard: Option<Shard>,
    /// The shard file to write, or a folder (existing, or ending in `/`) to write
    /// `shard-<i>.toml` into.
    #[arg(long, requires = "shard")]
    shard_out: Option<PathBuf>,
    /// The Slurm batch script this shard runs in (named by `sweep-merge` for missing shards).
    #[arg(long, requires = "shard", hide = true)]
    slurm_script: Option<PathBuf>,
    /// Stage the sweep into this folder (on a filesystem the nodes share): the system, its
    /// FMUs, this program, a job-array batch script and a dependent merge job script.
    #[arg(long, value_name = "DIR")]
    slurm: Option<PathBuf>,
    /// With --slurm: array tasks, one shard each.
    #[arg(long, default_value_t = 4, requires = "slurm")]
    shards: usize,
    /// With --slurm: the partition (default: the cluster's default).
    #[arg(long, requires = "slurm")]
    partition: Option<String>,
    /// With --slurm: time limit of a task, e.g. 00:30:00.
    #[arg(long, requires = "slurm")]
    time: Option<String>,
    /// With --slurm: CPUs of a task (its runs use that many threads).
    #[arg(long, default_value_t = 1, requires = "slurm")]
    cpus_per_task: usize,
    /// With --slurm: memory of a task, e.g. 2G.
    #[arg(long, requires = "slurm")]
    mem: Option<String>,
    /// With --slurm: how often a failed task requeues itself before it gives up.
    #[arg(long, default_value_t = 2, requires = "slurm")]
    max_requeues: u32,
    /// With --slurm: submit the array and the merge job with sbatch.
    #[arg(long, requires = "slurm")]
    submit: bool,
}

/// `spurio sweep-worker`: runs of a sweep in a worker process, one per value read from
/// standard input (see [`crate::workers`]).
#[derive(Args)]
pub struct WorkerArgs {
    /// The system file.
    system: PathBuf,
    /// The varied `instance.variable`.
    #[arg(long)]
    vary: String,
    #[arg(long = "metric")]
    metrics: Vec<String>,
    #[command(flatten)]
    limits: Limits,
}

#[derive(Args)]
pub struct MergeArgs {
    /// Shard files, folders of shard files, or a folder staged by `spurio sweep --slurm`.
    #[arg(required = true)]
    inputs: Vec<PathBuf>,
    /// Also write every run's metrics as CSV here (as `spurio sweep --out`).
    #[arg(long, conflicts_with = "progress")]
    out: Option<PathBuf>,
    /// Show how far the sweep has come (shards and runs done, the table of the finished
    /// runs) instead of merging.
    #[arg(long)]
    progress: bool,
    /// The number of shards of the sweep, when no staged folder says it.
    #[arg(long)]
    shards: Option<usize>,
}

/// `spurio sweep`: the table of the runs that completed, every failed run named on
/// standard error (then the exit code is 1).
pub fn run(args: SweepArgs) -> Result<ExitCode> {
    let resolved = System::from_file_loading(&args.system, None, &args.limits.load_options())?;
    let (variation, metrics, definition) = parse_sweep(&args.vary, &args.metrics, args.max_runs)?;
    variation.check(&resolved)?;
    args.limits.check_steps(&resolved)?;
    let recorded = &resolved.plan().recorded.names;
    for m in &metrics {
        for v in m.variables() {
            if !recorded.iter().any(|r| r == v) {
                bail!(
                    "metric {}: `{v}` is not recorded (recorded: {})",
                    m.label(),
                    recorded.join(", ")
                );
            }
        }
    }
    if let Some(dir) = &args.slurm {
        stage(&args, &resolved, dir, &definition)?;
        return Ok(ExitCode::SUCCESS);
    }
    let all = 0..variation.values.len();
    let runs = match (args.shard, &args.shard_out) {
        (Some(shard), Some(_)) => shard.runs(variation.values.len()),
        _ => all,
    };
    let outcomes = run_workers(&args, &variation, &metrics, runs.clone())?;
    let failed = outcomes.iter().filter(|o| o.is_err()).count();
    if let (Some(shard), Some(shard_out)) = (args.shard, &args.shard_out) {
        write_shard(&args, &definition, shard, shard_out, runs, outcomes)?;
        return Ok(ExitCode::SUCCESS);
    }
    let result = SweepResult {
        metrics,
        runs: outcomes
            .into_iter()
            .map(|o| o.unwrap_or_else(|_| vec![f64::NAN; definition.metrics.len()]))
            .collect(),
    };
    // The table first: a per-run file that cannot be written does not lose it.
    print!("{}", result.table());
    if let Some(out) = &args.out {
        sweeps::write_table(Some(out), &definition.parameters, &definition.runs, &result)?;
    }
    if failed > 0 {
        eprintln!(
            "spurio: {failed} of {} runs failed (NaN in the per-run table; the table counts the others)",
            result.runs.len()
        );
        return Ok(ExitCode::FAILURE);
    }
    Ok(ExitCode::SUCCESS)
}

/// Runs `runs` of the sweep in worker processes, naming each failed run on standard error
/// as it ends.
fn run_workers(
    args: &SweepArgs,
    variation: &Variation,
    metrics: &[Metric],
    runs: Range<usize>,
) -> Result<Vec<workers::Outcome>> {
    let metric_texts: Vec<String> = metrics.iter().map(Metric::label).collect();
    let shared = workers::Runs {
        system: &args.system,
        variable: &variation.variable,
        metrics: &metric_texts,
        limits: &args.limits,
    };
    let list: Vec<(usize, f64)> = runs.map(|k| (k, variation.values[k])).collect();
    shared.run(&list, limits::workers(args.threads), |k, value, outcome| {
        if let Err(e) = outcome {
            eprintln!(
                "spurio: run {k} ({} = {value}) failed: {e}",
                variation.variable
            );
        }
    })
}

/// `spurio sweep-worker`: loads the system once, then for each value read from standard
/// input (one a line, until its end) runs the system with the varied variable at that value
/// and answers one line (see [`crate::workers`]).
pub fn worker(args: WorkerArgs) -> Result<()> {
    use std::io::{BufRead, Write};
    let metrics = args
        .metrics
        .iter()
        .map(|m| Metric::parse(m))
        .collect::<Result<Vec<_>, _>>()?;
    let system = System::from_file_loading(&args.system, None, &args.limits.load_options())?;
    args.limits.check_steps(&system)?;
    let monitor = args.limits.call_timeout.map(guard::watchdog);
    let mut stdout = std::io::stdout().lock();
    for line in std::io::stdin().lock().lines() {
        let line = line.context("reading the values to run")?;
        let value: f64 = line
            .trim()
            .parse()
            .with_context(|| format!("`{line}` is not a value to run"))?;
        let outcome = sweeps::run_once(
            &system,
            &args.vary,
            value,
            &metrics,
            &RunOptions::default(),
            monitor.clone(),
        );
        writeln!(stdout, "{}", workers::answer(&outcome))?;
        stdout.flush()?;
    }
    Ok(())
}

/// The variation, the metrics and the sweep definition of a `--vary` text and `--metric`
/// texts (as given on the command line or kept in a staged folder's manifest).
fn parse_sweep(
    vary: &str,
    metrics: &[String],
    max_runs: u64,
) -> Result<(Variation, Vec<Metric>, SweepDefinition)> {
    let variation = Variation::parse_at_most(vary, max_runs)?;
    let metrics = metrics
        .iter()
        .map(|m| Metric::parse(m))
        .collect::<Result<Vec<_>, _>>()?;
    let definition = SweepDefinition::from_variation(&variation, &metrics);
    Ok((variation, metrics, definition))
}

/// Writes the shard file of the runs `runs` of shard `shard`.
fn write_shard(
    args: &SweepArgs,
    definition: &SweepDefinition,
    shard: Shard,
    shard_out: &Path,
    runs: Range<usize>,
    outcomes: Vec<workers::Outcome>,
) -> Result<()> {
    let identity = shard::identity_of_system_file(&args.system, definition)?;
    let total = definition.runs.len();
    let records: Vec<RunRecord> = runs
        .clone()
        .zip(outcomes)
        .map(|(k, result)| {
            let parameters = definition.runs[k].clone();
            match result {
                Ok(values) => RunRecord::ok(k, parameters, values),
                Err(e) => RunRecord::failed(k, parameters, e),
            }
        })
        .collect();
    let failed = records.iter().filter(|r| r.error.is_some()).count();
    let mut file = ShardFile::new(identity, shard, definition, records);
    let is_folder = shard_out.is_dir() || shard_out.to_string_lossy().ends_with('/');
    let (path, folder) = if is_folder {
        std::fs::create_dir_all(shard_out)
            .with_context(|| format!("cannot create {}", shard_out.display()))?;
        (
            shard_out.join(slurm::shard_file_name(shard)),
            shard_out.to_path_buf(),
        )
    } else {
        let parent = shard_out.parent().unwrap_or(Path::new(""));
        let folder = if parent.as_os_str().is_empty() {
            PathBuf::from(".")
        } else {
            parent.to_path_buf()
        };
        (shard_out.to_path_buf(), folder)
    };
    file.rerun = Some(rerun_command(args, &folder)?);
    file.slurm_script = args.slurm_script.as_ref().map(|p| p.display().to_string());
    file.write(&path)?;
    println!(
        "shard {shard}: runs {}..{} of {}, {failed} failed; wrote {}",
        runs.start,
        runs.end,
        total,
        path.display()
    );
    Ok(())
}

/// The command that runs shard `{shard}` of this sweep into `folder`.
fn rerun_command(args: &SweepArgs, folder: &Path) -> Result<String> {
    let exe = std::env::current_exe().context("cannot locate the spurio executable")?;
    let absolute = |p: &Path| p.canonicalize().unwrap_or_else(|_| p.to_path_buf());
    let q = |p: &Path| slurm::shell_quote(&absolute(p).display().to_string());
    let mut cmd = format!(
        "{} sweep {} --vary {}",
        q(&exe),
        q(&args.system),
        slurm::shell_quote(&args.vary)
    );
    for m in &args.metrics {
        cmd.push_str(" --metric ");
        cmd.push_str(&slurm::shell_quote(m));
    }
    cmd.push_str(&format!(" --shard {{shard}} --shard-out {}", q(folder)));
    Ok(cmd)
}

fn stage(
    args: &SweepArgs,
    system: &System,
    dir: &Path,
    definition: &SweepDefinition,
) -> Result<()> {
    let options = SlurmOptions {
        shards: args.shards,
        queue: Queue {
            partition: args.partition.clone(),
            time: args.time.clone(),
        },
        cpus_per_task: args.cpus_per_task,
        mem: args.mem.clone(),
        max_requeues: args.max_requeues,
    };
    let sweep = SweepArguments {
        vary: args.vary.clone(),
        metrics: args.metrics.clone(),
        total_runs: definition.runs.len(),
    };
    let exe = std::env::current_exe().context("cannot locate the spurio executable")?;
    let staged = slurm::stage(system, &exe, dir, &sweep, &options, |path| {
        shard::identity_of_system_file(path, definition).map_err(|e| e.to_string())
    })?;
    let d = staged.dir.display();
    println!(
        "staged a sweep of {} runs in {} shards into {d}",
        sweep.total_runs, options.shards
    );
    println!("  job array:  {}", staged.array_script.display());
    println!("  merge job:  {}", staged.merge_script.display());
    if args.submit {
        let jobs = slurm::submit(&staged)?;
        println!(
            "submitted array job {} ({} tasks) and merge job {} (afterok:{})",
            jobs.array_job, options.shards, jobs.merge_job, jobs.array_job
        );
        println!("watch:  squeue -j {},{}", jobs.array_job, jobs.merge_job);
        println!("        spurio sweep-merge --progress {d}");
    } else {
        println!(
            "submit: array=$(sbatch --parsable {})",
            staged.array_script.display()
        );
        println!(
            "        sbatch --dependency=afterok:$array {}",
            staged.merge_script.display()
        );
        println!("watch:  spurio sweep-merge --progress {d}");
    }
    println!("result: {d}/table.md (mean ± std), {d}/runs.csv (per run)");
    Ok(())
}

/// The shard files to read and what is known of the sweep beside them.
fn gather(args: &MergeArgs) -> Result<(Vec<PathBuf>, MergeOptions, Option<Manifest>)> {
    let mut paths = Vec::new();
    let mut options = MergeOptions {
        expected_shards: args.shards,
        ..Default::default()
    };
    let mut found: Option<Manifest> = None;
    for input in &args.inputs {
        let manifest = if input.is_dir() {
            Manifest::read(input)?
        } else {
            None
        };
        let Some(manifest) = manifest else {
            paths.push(input.clone());
            continue;
        };
        if found.as_ref().is_some_and(|m| m.sweep != manifest.sweep) {
            bail!(
                "{} is a staged folder of another sweep than the first one given",
                input.display()
            );
        }
        // The staged system and FMUs give the identity every shard must have.
        let (_, _, definition) = parse_sweep(
            &manifest.vary,
            &manifest.metrics,
            manifest.total_runs as u64,
        )?;
        let identity = shard::identity_of_system_file(&input.join(&manifest.system), &definition)?;
        if identity != manifest.sweep {
            bail!(
                "{}: the staged system or FMUs changed since staging (identity {identity}, manifest {})",
                input.display(),
                manifest.sweep
            );
        }
        if args.shards.is_some_and(|n| n != manifest.shards) {
            bail!(
                "--shards {} but {} was staged in {} shards",
                args.shards.unwrap_or_default(),
                input.display(),
                manifest.shards
            );
        }
        options.expected_sweep = Some(identity);
        options.expected_shards = Some(manifest.shards);
        options.definition = Some(definition);
        paths.push(input.join("shards"));
        found = Some(manifest);
    }
    Ok((paths, options, found))
}

/// `spurio sweep-merge`.
pub fn merge(args: MergeArgs) -> Result<()> {
    let (paths, options, manifest) = gather(&args)?;
    let files = shard::read_shard_files(&paths)?;
    if args.progress {
        if files.is_empty() {
            let Some(m) = manifest else {
                bail!("no shard files in {}", shard::list_paths(&paths));
            };
            println!(
                "0/{} shards done (0/{} runs); missing: all",
                m.shards, m.total_runs
            );
            return Ok(());
        }
        let p = shard::progress(&files, &options)?;
        println!("{p}");
        for f in p.failed() {
            println!(
                "  run {} (shard {}, parameters {:?}) failed: {}",
                f.index, f.shard, f.parameters, f.error
            );
        }
        let running = p.running_result()?;
        if !running.runs.is_empty() {
            println!();
            print!("{}", running.table());
        }
        return Ok(());
    }
    let merged = shard::merge(&files, &options)?;
    let result = merged.result()?;
    let values: Vec<Vec<f64>> = merged.runs.iter().map(|r| r.parameters.clone()).collect();
    // The table first: a per-run file that cannot be written does not lose it.
    print!(
        "{}",
        sweeps::write_table(None, &merged.parameters, &values, &result)?
    );
    sweeps::write_table(args.out.as_deref(), &merged.parameters, &values, &result)?;
    Ok(())
}
