//! Sweeps on a Slurm cluster: one job-array task per shard ([`crate::shard`]) and a merge job
//! that runs when every task succeeded.
//!
//! [`stage`] prepares a folder on a filesystem the nodes share:
//!
//! ```text
//! <dir>/sweep.toml        the manifest: sweep identity, system, --vary, metrics, shard count
//! <dir>/system.toml       the system, its FMU paths pointing into fmus/
//! <dir>/fmus/*.fmu        copies of the system's FMU archives
//! <dir>/bin/spurio        the program that stages (so every task runs the same build)
//! <dir>/sweep.sbatch      the job array: task i runs shard i/N into shards/shard-i.toml
//! <dir>/merge.sbatch      the merge job: sweep-merge → runs.csv (per-run rows), table.md
//! <dir>/shards/ logs/     the shard files; each task's and the merge job's output
//! ```
//!
//! A task whose shard command fails requeues itself (`scontrol requeue <array>_<task>`) while
//! `SLURM_RESTART_COUNT` is below the bound, and Slurm reruns it: a rerun writes the same
//! shard file (runs seeded by run index), so the result does not depend on how often a task
//! ran. The task must requeue itself rather than fail: Slurm marks an `afterok` dependent job
//! `DependencyNeverSatisfied` as soon as a task ends failed, and a later external requeue does
//! not release it. A run that fails inside a shard is not a failed task: the shard file
//! records it (a rerun would fail the same way) and the merge names it. Tasks pre-empted or
//! lost with their node are requeued by Slurm (`--requeue`). [`submit`] calls `sbatch` for
//! the array and for the merge job with `--dependency=afterok:<array>`.
#![forbid(unsafe_code)]

use crate::shard::{Shard, SweepIdentity};
use serde::{Deserialize, Serialize};
use spurio_master::{System, SystemDescription};
use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::Command;

/// The manifest's file name in a staged folder.
pub const MANIFEST: &str = "sweep.toml";

/// The file a task's test hook looks for: `<dir>/inject-failure/<i>` makes task `i` fail once.
pub const INJECT_FAILURE_DIR: &str = "inject-failure";

/// Errors of staging and submitting a sweep.
#[derive(Debug, thiserror::Error)]
pub enum SlurmError {
    /// The I/O error's text is the message's, not a source (said once).
    #[error("{}: {error}", path.display())]
    Io {
        path: PathBuf,
        error: std::io::Error,
    },
    #[error("{0}")]
    Invalid(String),
    #[error("cannot serialise {what}: {reason}")]
    Serialize { what: &'static str, reason: String },
    #[error("{}: not a sweep manifest: {reason}", path.display())]
    Manifest { path: PathBuf, reason: String },
    #[error("`{command}` failed: {reason}")]
    Sbatch { command: String, reason: String },
}

fn io(path: &Path) -> impl FnOnce(std::io::Error) -> SlurmError + '_ {
    move |error| SlurmError::Io {
        path: path.to_path_buf(),
        error,
    }
}

/// Resources and behaviour of the job array.
#[derive(Debug, Clone, PartialEq)]
pub struct SlurmOptions {
    /// Array tasks, one shard each.
    pub shards: usize,
    /// Where and how long the jobs run (the array's tasks and the merge job alike).
    pub queue: Queue,
    /// CPUs of a task; its runs go on that many threads.
    pub cpus_per_task: usize,
    /// Memory of a task (`--mem`, e.g. `2G`).
    pub mem: Option<String>,
    /// How often a task that failed requeues itself before it gives up.
    pub max_requeues: u32,
}

impl Default for SlurmOptions {
    fn default() -> Self {
        Self {
            shards: 4,
            queue: Queue::default(),
            cpus_per_task: 1,
            mem: None,
            max_requeues: 2,
        }
    }
}

/// The directives every job of a sweep carries: its partition and time limit (each the
/// cluster's default when not given).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Queue {
    pub partition: Option<String>,
    /// Time limit of a job (`--time`, e.g. `00:30:00`).
    pub time: Option<String>,
}

impl Queue {
    /// Appends the `#SBATCH` lines of the directives given.
    fn write_directives(&self, s: &mut String) {
        if let Some(p) = &self.partition {
            let _ = writeln!(s, "#SBATCH --partition={p}");
        }
        if let Some(t) = &self.time {
            let _ = writeln!(s, "#SBATCH --time={t}");
        }
    }
}

/// What a staged folder holds: read back by `sweep-merge` to know the shard count, the
/// identity the shards must have and the definition to check them against.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Manifest {
    pub format: u32,
    pub sweep: SweepIdentity,
    /// The system file, relative to the folder.
    pub system: String,
    /// The `--vary` argument.
    pub vary: String,
    /// The `--metric` arguments.
    pub metrics: Vec<String>,
    pub shards: usize,
    pub total_runs: usize,
}

impl Manifest {
    /// Reads `<dir>/sweep.toml`, or `None` when there is none.
    pub fn read(dir: &Path) -> Result<Option<Self>, SlurmError> {
        let path = dir.join(MANIFEST);
        if !path.is_file() {
            return Ok(None);
        }
        let text = std::fs::read_to_string(&path).map_err(io(&path))?;
        let manifest: Self = toml::from_str(&text).map_err(|e| SlurmError::Manifest {
            path: path.clone(),
            reason: e.to_string(),
        })?;
        if manifest.format != crate::shard::FORMAT {
            return Err(SlurmError::Manifest {
                path,
                reason: format!("format {}", manifest.format),
            });
        }
        Ok(Some(manifest))
    }
}

/// A staged sweep.
#[derive(Debug, Clone)]
pub struct Staged {
    /// The folder, absolute.
    pub dir: PathBuf,
    pub manifest: Manifest,
    pub array_script: PathBuf,
    pub merge_script: PathBuf,
}

impl Staged {
    pub fn shards_dir(&self) -> PathBuf {
        self.dir.join("shards")
    }
    pub fn system(&self) -> PathBuf {
        self.dir.join(&self.manifest.system)
    }
}

/// Quotes `text` for a POSIX shell (bare when it is made of safe characters only).
pub fn shell_quote(text: &str) -> String {
    let safe = |c: char| c.is_ascii_alphanumeric() || "-_./=:,+@%".contains(c);
    if !text.is_empty() && text.chars().all(safe) {
        text.to_string()
    } else {
        format!("'{}'", text.replace('\'', r"'\''"))
    }
}

/// The sweep as its command line gives it.
#[derive(Debug, Clone, PartialEq)]
pub struct SweepArguments {
    /// The `--vary` argument.
    pub vary: String,
    /// The `--metric` arguments.
    pub metrics: Vec<String>,
    /// The runs it makes.
    pub total_runs: usize,
}

/// Stages the sweep of `system` into `dir`:
/// copies `spurio` and the system's FMU archives, writes the system file, the manifest and
/// both batch scripts. `identity` computes the sweep identity of the staged system file (the
/// caller knows the definition). `dir` must be empty of shard files (a folder of an earlier
/// sweep is refused rather than mixed).
pub fn stage(
    system: &System,
    spurio: &Path,
    dir: &Path,
    sweep: &SweepArguments,
    options: &SlurmOptions,
    identity: impl FnOnce(&Path) -> Result<SweepIdentity, String>,
) -> Result<Staged, SlurmError> {
    if options.shards == 0 {
        return Err(SlurmError::Invalid("--shards must be at least 1".into()));
    }
    if options.cpus_per_task == 0 {
        return Err(SlurmError::Invalid(
            "--cpus-per-task must be at least 1".into(),
        ));
    }
    std::fs::create_dir_all(dir).map_err(io(dir))?;
    let dir = dir.canonicalize().map_err(io(dir))?;
    let shards = dir.join("shards");
    if std::fs::read_dir(&shards).is_ok_and(|mut entries| entries.next().is_some()) {
        return Err(SlurmError::Invalid(format!(
            "{} holds shard files of an earlier sweep: stage into an empty folder",
            shards.display()
        )));
    }
    for sub in ["bin", "fmus", "shards", "logs"] {
        let path = dir.join(sub);
        std::fs::create_dir_all(&path).map_err(io(&path))?;
    }
    let bin = dir.join("bin/spurio");
    copy(spurio, &bin)?;

    // The FMUs, each archive once, under its own file name (made unique if two differ).
    let mut description: SystemDescription = system.source_description().clone();
    let mut staged: BTreeMap<PathBuf, String> = BTreeMap::new();
    for instance in &mut description.instances {
        // A data instance's table is staged beside the FMUs.
        let source = instance
            .data
            .clone()
            .unwrap_or_else(|| instance.fmu.clone());
        let name = match staged.get(&source) {
            Some(name) => name.clone(),
            None => {
                let file = source
                    .file_name()
                    .map(|n| n.to_string_lossy().into_owned())
                    .unwrap_or_else(|| "model.fmu".into());
                let mut name = file.clone();
                let mut k = 2;
                while staged.values().any(|n| *n == name) {
                    name = format!("{k}-{file}");
                    k += 1;
                }
                copy(&source, &dir.join("fmus").join(&name))?;
                staged.insert(source, name.clone());
                name
            }
        };
        let staged_path = PathBuf::from("fmus").join(name);
        match &mut instance.data {
            Some(data) => *data = staged_path,
            None => instance.fmu = staged_path,
        }
    }
    let system_path = dir.join("system.toml");
    let text = toml::to_string_pretty(&description).map_err(|e| SlurmError::Serialize {
        what: "the system",
        reason: e.to_string(),
    })?;
    write(&system_path, &text)?;
    let identity = identity(&system_path).map_err(SlurmError::Invalid)?;

    let manifest = Manifest {
        format: crate::shard::FORMAT,
        sweep: identity,
        system: "system.toml".into(),
        vary: sweep.vary.clone(),
        metrics: sweep.metrics.clone(),
        shards: options.shards,
        total_runs: sweep.total_runs,
    };
    let text = toml::to_string(&manifest).map_err(|e| SlurmError::Serialize {
        what: "the manifest",
        reason: e.to_string(),
    })?;
    write(&dir.join(MANIFEST), &text)?;
    let staged = Staged {
        array_script: dir.join("sweep.sbatch"),
        merge_script: dir.join("merge.sbatch"),
        dir,
        manifest,
    };
    write(
        &staged.array_script,
        &array_script(&staged, &description.name, options),
    )?;
    write(
        &staged.merge_script,
        &merge_script(&staged, &description.name, options),
    )?;
    Ok(staged)
}

fn copy(from: &Path, to: &Path) -> Result<(), SlurmError> {
    std::fs::copy(from, to).map_err(io(from))?;
    Ok(())
}

fn write(path: &Path, text: &str) -> Result<(), SlurmError> {
    std::fs::write(path, text).map_err(io(path))
}

fn job_name(system_name: &str) -> String {
    let name: String = system_name
        .chars()
        .map(|c| if c.is_ascii_alphanumeric() { c } else { '_' })
        .collect();
    if name.is_empty() {
        "spurio-sweep".into()
    } else {
        format!("spurio-{name}")
    }
}

/// The job-array batch script: task `i` runs shard `i/N`.
pub fn array_script(staged: &Staged, system_name: &str, options: &SlurmOptions) -> String {
    let dir = staged.dir.display().to_string();
    let m = &staged.manifest;
    let n = m.shards;
    let mut s = String::from("#!/bin/bash\n");
    let _ = writeln!(s, "#SBATCH --job-name={}", job_name(system_name));
    let _ = writeln!(s, "#SBATCH --array=0-{}", n - 1);
    s.push_str("#SBATCH --requeue\n");
    s.push_str("#SBATCH --ntasks=1\n");
    let _ = writeln!(s, "#SBATCH --cpus-per-task={}", options.cpus_per_task);
    options.queue.write_directives(&mut s);
    if let Some(mem) = &options.mem {
        let _ = writeln!(s, "#SBATCH --mem={mem}");
    }
    // Every attempt appends to the task's log, so a requeued task's history stays readable.
    let _ = writeln!(s, "#SBATCH --output={dir}/logs/shard-%a.out");
    s.push_str("#SBATCH --open-mode=append\n");
    let _ = writeln!(
        s,
        "# A sweep of {} runs ({}) in {n} shards, written by `spurio sweep --slurm`.",
        m.total_runs, m.vary
    );
    let _ = writeln!(s, "# Sweep identity {}.", m.sweep);
    s.push_str(
        "# Task i runs shard i/N into shards/shard-i.toml. A task whose shard fails requeues\n\
         # itself (up to max_requeues times): an afterok merge job then waits for the rerun.\n\
         # Rerun shards by hand with: sbatch --array=2,5 sweep.sbatch\n",
    );
    s.push_str("set -u\n");
    let _ = writeln!(s, "dir={}", shell_quote(&dir));
    let _ = writeln!(s, "max_requeues={}", options.max_requeues);
    s.push_str("i=${SLURM_ARRAY_TASK_ID:?not a job array task}\n");
    s.push_str("attempt=${SLURM_RESTART_COUNT:-0}\n");
    let _ = writeln!(
        s,
        "echo \"shard $i/{n} attempt $attempt on $(hostname) start $(date +%s.%N)\""
    );
    let _ = writeln!(
        s,
        "# Test hook (tests/slurm/test_sweep.sh): a file $dir/{INJECT_FAILURE_DIR}/<i> makes task i\n\
         # fail once, as a lost node would; the task removes it. spurio never creates it."
    );
    let _ = writeln!(
        s,
        "if [ -e \"$dir/{INJECT_FAILURE_DIR}/$i\" ]; then\n  rm -f \"$dir/{INJECT_FAILURE_DIR}/$i\"\n  echo \"shard $i: injected failure\" >&2\n  status=75\nelse"
    );
    let mut cmd = format!(
        "  \"$dir/bin/spurio\" sweep \"$dir/{}\" --vary {}",
        m.system,
        shell_quote(&m.vary)
    );
    for metric in &m.metrics {
        let _ = write!(cmd, " --metric {}", shell_quote(metric));
    }
    let _ = write!(
        cmd,
        " \\\n    --threads \"${{SLURM_CPUS_PER_TASK:-1}}\" --shard \"$i/{n}\" --shard-out \"$dir/shards\" \\\n    --slurm-script \"$dir/sweep.sbatch\""
    );
    s.push_str(&cmd);
    s.push_str("\n  status=$?\nfi\n");
    s.push_str("echo \"shard $i attempt $attempt end $(date +%s.%N) exit $status\"\n");
    s.push_str(
        "if [ \"$status\" -ne 0 ]; then\n\
         \x20 if [ \"$attempt\" -lt \"$max_requeues\" ]; then\n\
         \x20   echo \"shard $i: attempt $attempt failed (exit $status), requeueing\" >&2\n\
         \x20   # Slurm ends this attempt and runs the task again.\n\
         \x20   scontrol requeue \"${SLURM_ARRAY_JOB_ID}_${SLURM_ARRAY_TASK_ID}\" && sleep 300\n\
         \x20 fi\n\
         \x20 echo \"shard $i: attempt $attempt failed (exit $status), giving up\" >&2\n\
         \x20 exit \"$status\"\n\
         fi\n",
    );
    s
}

/// The merge job's batch script: merges the shards into `runs.csv` and `table.md`.
pub fn merge_script(staged: &Staged, system_name: &str, options: &SlurmOptions) -> String {
    let dir = staged.dir.display().to_string();
    let mut s = String::from("#!/bin/bash\n");
    let _ = writeln!(s, "#SBATCH --job-name={}-merge", job_name(system_name));
    s.push_str("#SBATCH --ntasks=1\n");
    options.queue.write_directives(&mut s);
    let _ = writeln!(s, "#SBATCH --output={dir}/logs/merge.out");
    s.push_str(
        "# Submitted with --dependency=afterok:<array job>: runs when every shard succeeded.\n",
    );
    s.push_str("set -euo pipefail\n");
    let _ = writeln!(s, "dir={}", shell_quote(&dir));
    s.push_str(
        "\"$dir/bin/spurio\" sweep-merge \"$dir\" --out \"$dir/runs.csv\" >\"$dir/table.md.partial\"\n\
         mv \"$dir/table.md.partial\" \"$dir/table.md\"\n\
         cat \"$dir/table.md\"\n",
    );
    s
}

/// The job ids of a submitted sweep.
#[derive(Debug, Clone, PartialEq)]
pub struct Submitted {
    pub array_job: String,
    pub merge_job: String,
}

/// Submits the array, then the merge job depending on it (`afterok`), with `sbatch` (from
/// `PATH`; `SLURM_CONF` and the like pass through).
pub fn submit(staged: &Staged) -> Result<Submitted, SlurmError> {
    let array_job = sbatch(&[], &staged.array_script)?;
    let merge_job = sbatch(
        &[format!("--dependency=afterok:{array_job}")],
        &staged.merge_script,
    )?;
    Ok(Submitted {
        array_job,
        merge_job,
    })
}

fn sbatch(args: &[String], script: &Path) -> Result<String, SlurmError> {
    let mut command = Command::new("sbatch");
    command.arg("--parsable").args(args).arg(script);
    let shown = format!("sbatch --parsable {} {}", args.join(" "), script.display());
    let output = command.output().map_err(|e| SlurmError::Sbatch {
        command: shown.clone(),
        reason: e.to_string(),
    })?;
    if !output.status.success() {
        return Err(SlurmError::Sbatch {
            command: shown,
            reason: String::from_utf8_lossy(&output.stderr).trim().to_string(),
        });
    }
    // `--parsable` prints `<job id>` or `<job id>;<cluster>`.
    let text = String::from_utf8_lossy(&output.stdout);
    let id = text.trim().split(';').next().unwrap_or("").to_string();
    if id.is_empty() || !id.chars().all(|c| c.is_ascii_digit()) {
        return Err(SlurmError::Sbatch {
            command: shown,
            reason: format!("unexpected output `{}`", text.trim()),
        });
    }
    Ok(id)
}

/// The shard file of shard `shard` in a folder of shard files.
pub fn shard_file_name(shard: Shard) -> String {
    format!("shard-{}.toml", shard.index)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shell_quoting_keeps_safe_words_and_quotes_the_rest() {
        assert_eq!(shell_quote("sensor.seed=1..100"), "sensor.seed=1..100");
        assert_eq!(shell_quote("rms(crane.x)"), "'rms(crane.x)'");
        assert_eq!(shell_quote("e_res(a, b)"), "'e_res(a, b)'");
        assert_eq!(shell_quote("it's"), r"'it'\''s'");
        assert_eq!(shell_quote(""), "''");
    }

    fn staged(shards: usize) -> Staged {
        Staged {
            dir: PathBuf::from("/shared/sweeps/a b"),
            manifest: Manifest {
                format: crate::shard::FORMAT,
                sweep: SweepIdentity("sha256:00".into()),
                system: "system.toml".into(),
                vary: "sensor.seed=1..100".into(),
                metrics: vec!["rms(sensor.y[1])".into(), "max_abs(crane.x)".into()],
                shards,
                total_runs: 100,
            },
            array_script: PathBuf::from("/shared/sweeps/a b/sweep.sbatch"),
            merge_script: PathBuf::from("/shared/sweeps/a b/merge.sbatch"),
        }
    }

    #[test]
    fn the_array_script_runs_one_shard_per_task_and_requeues_itself() {
        let options = SlurmOptions {
            shards: 8,
            queue: Queue {
                partition: Some("compute".into()),
                time: Some("00:20:00".into()),
            },
            cpus_per_task: 4,
            mem: Some("2G".into()),
            max_requeues: 3,
        };
        let s = array_script(&staged(8), "crane sensor", &options);
        for line in [
            "#SBATCH --job-name=spurio-crane_sensor\n",
            "#SBATCH --array=0-7\n",
            "#SBATCH --requeue\n",
            "#SBATCH --cpus-per-task=4\n",
            "#SBATCH --partition=compute\n",
            "#SBATCH --time=00:20:00\n",
            "#SBATCH --mem=2G\n",
            "#SBATCH --output=/shared/sweeps/a b/logs/shard-%a.out\n",
            "dir='/shared/sweeps/a b'\n",
            "max_requeues=3\n",
            "--vary sensor.seed=1..100 --metric 'rms(sensor.y[1])' --metric 'max_abs(crane.x)'",
            "--shard \"$i/8\" --shard-out \"$dir/shards\"",
            "scontrol requeue \"${SLURM_ARRAY_JOB_ID}_${SLURM_ARRAY_TASK_ID}\"",
        ] {
            assert!(s.contains(line), "`{line}` not in:\n{s}");
        }
        // The #SBATCH lines come before the first command, or sbatch ignores them.
        let first_command = s.find("\nset -u").unwrap();
        assert!(s.rfind("#SBATCH").unwrap() < first_command);
        let m = merge_script(&staged(8), "crane sensor", &options);
        assert!(
            m.contains("sweep-merge \"$dir\" --out \"$dir/runs.csv\""),
            "{m}"
        );
        assert!(!m.contains("--array"), "{m}");
        let plain = array_script(&staged(1), "", &SlurmOptions::default());
        assert!(plain.contains("#SBATCH --array=0-0\n"), "{plain}");
        assert!(
            plain.contains("#SBATCH --job-name=spurio-sweep\n"),
            "{plain}"
        );
        assert!(
            !plain.contains("--partition") && !plain.contains("--mem"),
            "{plain}"
        );
    }
}
