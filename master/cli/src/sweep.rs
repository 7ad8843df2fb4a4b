//! `spurio sweep` — on this machine, one shard of it (`--shard i/N`), or staged for a Slurm
//! cluster (`--slurm <dir>`) — and `spurio sweep-merge`, which checks the shards of a sweep
//! and writes the table the one-machine sweep writes, or shows how far a sweep has come.

use anyhow::{bail, Context, Result};
use clap::Args;
use spurio_master::shard::{self, MergeOptions, RunRecord, Shard, ShardFile, SweepDefinition};
use spurio_master::slurm::{self, Manifest, SlurmOptions, SweepArguments};
use spurio_master::sweep::{self as sweeps, Metric, Variation};
use spurio_master::system::System;
use std::path::{Path, PathBuf};

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
    /// Worker threads (0: one per core).
    #[arg(long, default_value_t = 0)]
    threads: usize,
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

/// `spurio sweep`.
pub fn run(args: SweepArgs) -> Result<()> {
    let resolved = System::from_file(&args.system)?;
    let (variation, metrics, definition) = parse_sweep(&args.vary, &args.metrics)?;
    if let Some(dir) = &args.slurm {
        return stage(&args, &resolved, dir, &definition);
    }
    if let (Some(shard), Some(shard_out)) = (args.shard, &args.shard_out) {
        return run_shard(
            &args,
            &resolved,
            &variation,
            &metrics,
            &definition,
            shard,
            shard_out,
        );
    }
    let result = sweeps::sweep(&resolved, &variation, &metrics, args.threads)?;
    let table = sweeps::write_table(
        args.out.as_deref(),
        &definition.parameters,
        &definition.runs,
        &result,
    )?;
    print!("{table}");
    Ok(())
}

/// The variation, the metrics and the sweep definition of a `--vary` text and `--metric`
/// texts (as given on the command line or kept in a staged folder's manifest).
fn parse_sweep(
    vary: &str,
    metrics: &[String],
) -> Result<(Variation, Vec<Metric>, SweepDefinition)> {
    let variation = Variation::parse(vary)?;
    let metrics = metrics
        .iter()
        .map(|m| Metric::parse(m))
        .collect::<Result<Vec<_>, _>>()?;
    let definition = SweepDefinition::from_variation(&variation, &metrics);
    Ok((variation, metrics, definition))
}

fn run_shard(
    args: &SweepArgs,
    system: &System,
    variation: &Variation,
    metrics: &[Metric],
    definition: &SweepDefinition,
    shard: Shard,
    shard_out: &Path,
) -> Result<()> {
    let identity = shard::identity_of_system_file(&args.system, definition)?;
    let runs = shard.runs(variation.values.len());
    let results = sweeps::sweep_runs(system, variation, metrics, runs.clone(), args.threads)?;
    let records: Vec<RunRecord> = runs
        .clone()
        .zip(results)
        .map(|(k, result)| {
            let parameters = definition.runs[k].clone();
            match result {
                Ok(values) => RunRecord::ok(k, parameters, values),
                Err(e) => RunRecord::failed(k, parameters, e.to_string()),
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
        variation.values.len(),
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
        partition: args.partition.clone(),
        time: args.time.clone(),
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
        let (_, _, definition) = parse_sweep(&manifest.vary, &manifest.metrics)?;
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
    let table = sweeps::write_table(args.out.as_deref(), &merged.parameters, &values, &result)?;
    print!("{table}");
    Ok(())
}
