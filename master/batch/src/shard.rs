//! Deterministic shards of a sweep, so that a sweep can run as many independent jobs (a
//! Slurm job array, several machines) and be merged into the table one machine would print,
//! bit for bit.
//!
//! - **Partition.** The runs `0..R` of a sweep are cut into `N` contiguous shards of sizes
//!   differing by at most one ([`Shard::runs`]). A run's parameter values (a seed among them)
//!   depend on its run index only, never on the shard that runs it, so any `N` gives the same
//!   runs. Contiguous rather than strided: every run of this master costs about the same (the
//!   step count is fixed by the system, not by the varied value), so striding would balance
//!   nothing, while a contiguous shard is one range `a..b` that a reader can map back to the
//!   rows of the table, a missing shard is one hole `a..b` in it, and the merge restores run
//!   order by concatenating the shards in shard order.
//! - **Identity.** [`SweepIdentity`] is a SHA-256 of the system file's bytes, the FMU
//!   archives' bytes and the sweep definition (varied parameters, every run's values, the
//!   metrics). Every shard file records it; shards of different sweeps are never merged.
//! - **Shard file** ([`ShardFile`], TOML): the identity, the shard `i/N`, the run count, the
//!   parameter and metric names, and per run its index, parameter values, status, metric
//!   values and error text. Floats are written in their shortest round-trip form, so reading
//!   a file back gives the same bits. Files are written to a temporary name and renamed, so a
//!   task killed while writing (pre-emption) leaves no truncated shard behind.
//! - **Merge** ([`merge`]): checks that the shards belong to one sweep and agree on its
//!   shape, that none is duplicated and none is missing (naming the missing ones and the
//!   commands that rerun them), that each holds exactly its runs (and, given the definition,
//!   that each run carries its run index's parameter values), and returns the runs in
//!   run-index order; [`progress`] does the same checks on an unfinished sweep and gives the
//!   running table of the runs done so far.
//!
//! The mean ± std of the merged runs is [`SweepResult::table`] over the rows in run-index
//! order, the same summation order as the one-machine [`crate::sweep::sweep`].
#![forbid(unsafe_code)]

use crate::sweep::{Metric, SweepResult, Variation};
use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};
use std::collections::BTreeMap;
use std::fmt::{self, Write as _};
use std::ops::Range;
use std::path::{Path, PathBuf};
use std::str::FromStr;

/// The version of the shard file layout; a reader refuses other versions.
pub const FORMAT: u32 = 1;

/// The program that writes shard files; shards of different builds are not merged.
pub const PRODUCER: &str = concat!("spurio ", env!("CARGO_PKG_VERSION"));

/// The largest shard file read (1 GiB: a million runs' rows fit many times over).
pub const MAX_SHARD_FILE_BYTES: u64 = 1 << 30;

/// Errors of shard specifications and shard files.
#[derive(Debug, thiserror::Error)]
pub enum ShardError {
    #[error("shard `{0}`: expected i/N with 0 <= i < N, e.g. 3/8")]
    Spec(String),
    /// The I/O error's text is the message's, not a source (said once).
    #[error("cannot read shard file {path}: {error}")]
    Read {
        path: PathBuf,
        error: std::io::Error,
    },
    /// As [`ShardError::Read`].
    #[error("cannot write shard file {path}: {error}")]
    Write {
        path: PathBuf,
        error: std::io::Error,
    },
    #[error("shard file {path}: {reason}")]
    Format { path: PathBuf, reason: String },
    #[error("cannot serialise a shard file: {0}")]
    Serialize(String),
}

/// One shard `index/count` of a sweep: `0 <= index < count`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct Shard {
    pub index: usize,
    pub count: usize,
}

impl Shard {
    /// Shard `index` of `count`, or an error when `count == 0` or `index >= count`.
    pub fn new(index: usize, count: usize) -> Result<Self, ShardError> {
        if count == 0 || index >= count {
            return Err(ShardError::Spec(format!("{index}/{count}")));
        }
        Ok(Self { index, count })
    }

    /// The run indices of this shard among `total` runs: the contiguous range
    /// `index·⌊R/N⌋ + min(index, R mod N) ..` of length `⌊R/N⌋ + [index < R mod N]`.
    /// Empty when there are more shards than runs.
    pub fn runs(&self, total: usize) -> Range<usize> {
        let (base, extra) = (total / self.count, total % self.count);
        let start = self.index * base + self.index.min(extra);
        let len = base + usize::from(self.index < extra);
        start..start + len
    }

    /// The shard of `count` that holds run `run` of `total` (`run < total`).
    pub fn of_run(run: usize, total: usize, count: usize) -> Result<Self, ShardError> {
        if count == 0 || run >= total {
            return Err(ShardError::Spec(format!(
                "run {run} of {total} in {count} shards"
            )));
        }
        let (base, extra) = (total / count, total % count);
        // The first `extra` shards hold base + 1 runs each.
        let index = if run < extra * (base + 1) {
            run / (base + 1)
        } else {
            extra + (run - extra * (base + 1)) / base
        };
        Ok(Self { index, count })
    }
}

impl FromStr for Shard {
    type Err = ShardError;

    /// Parses `i/N`.
    fn from_str(text: &str) -> Result<Self, ShardError> {
        let spec = || ShardError::Spec(text.to_string());
        let (i, n) = text.trim().split_once('/').ok_or_else(spec)?;
        let index = i.trim().parse().map_err(|_| spec())?;
        let count = n.trim().parse().map_err(|_| spec())?;
        Self::new(index, count).map_err(|_| spec())
    }
}

impl fmt::Display for Shard {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}/{}", self.index, self.count)
    }
}

/// What a sweep runs: the varied parameters (`instance.variable`), each run's values of
/// them (row `k` is run `k`), and the metrics' labels.
#[derive(Debug, Clone, PartialEq)]
pub struct SweepDefinition {
    pub parameters: Vec<String>,
    pub runs: Vec<Vec<f64>>,
    pub metrics: Vec<String>,
}

impl SweepDefinition {
    /// The definition of a one-parameter sweep: run `k` takes `variation.values[k]`.
    pub fn from_variation(variation: &Variation, metrics: &[Metric]) -> Self {
        Self {
            parameters: vec![variation.variable.clone()],
            runs: variation.values.iter().map(|v| vec![*v]).collect(),
            metrics: metrics.iter().map(Metric::label).collect(),
        }
    }
}

/// The identity of a sweep: `sha256:` and the hex SHA-256 of the system file, the FMU
/// archives and the definition.
#[derive(Debug, Clone, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[serde(transparent)]
pub struct SweepIdentity(pub String);

impl SweepIdentity {
    /// Hashes the system file's bytes, every FMU archive (name as the system file refers to
    /// it, and bytes; their order does not matter) and the definition. Every field is
    /// length-prefixed and floats enter by their bits, so two different inputs cannot
    /// serialise to the same byte stream.
    pub fn compute(system: &[u8], fmus: &[(&str, &[u8])], definition: &SweepDefinition) -> Self {
        let mut h = Sha256::new();
        let mut put = |tag: &str, bytes: &[u8]| {
            h.update((tag.len() as u64).to_le_bytes());
            h.update(tag.as_bytes());
            h.update((bytes.len() as u64).to_le_bytes());
            h.update(bytes);
        };
        put("spurio sweep identity", &FORMAT.to_le_bytes());
        put("system", system);
        let mut fmus = fmus.to_vec();
        fmus.sort();
        for (name, bytes) in fmus {
            put("fmu name", name.as_bytes());
            put("fmu archive", bytes);
        }
        for p in &definition.parameters {
            put("parameter", p.as_bytes());
        }
        for run in &definition.runs {
            let bits: Vec<u8> = run.iter().flat_map(|v| v.to_bits().to_le_bytes()).collect();
            put("run", &bits);
        }
        for m in &definition.metrics {
            put("metric", m.as_bytes());
        }
        let digest = h.finalize();
        let mut hex = String::from("sha256:");
        for byte in digest.iter() {
            let _ = write!(hex, "{byte:02x}");
        }
        Self(hex)
    }
}

impl fmt::Display for SweepIdentity {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.0)
    }
}

/// Reads a system file and the FMU archives it refers to, and gives the identity of the
/// sweep `definition` over them. A TOML file enters with its bytes and every FMU archive
/// (named as the file refers to it); an SSP archive holds its FMUs, so its bytes are all.
pub fn identity_of_system_file(
    system: &Path,
    definition: &SweepDefinition,
) -> Result<SweepIdentity, ShardError> {
    let read = |path: &Path| {
        std::fs::read(path).map_err(|error| ShardError::Read {
            path: path.to_path_buf(),
            error,
        })
    };
    let bytes = read(system)?;
    if system.extension().is_some_and(|e| e == "ssp") {
        return Ok(SweepIdentity::compute(&bytes, &[], definition));
    }
    let format = |reason: String| ShardError::Format {
        path: system.to_path_buf(),
        reason: format!("not a TOML system file: {reason}"),
    };
    let text = std::str::from_utf8(&bytes).map_err(|e| format(e.to_string()))?;
    let description: spurio_master::SystemDescription =
        toml::from_str(text).map_err(|e| format(e.to_string()))?;
    let base = system.parent().unwrap_or(Path::new("."));
    let mut names: Vec<String> = description
        .instances
        .iter()
        .map(|i| i.fmu.to_string_lossy().into_owned())
        .collect();
    names.sort();
    names.dedup();
    let archives = names
        .iter()
        .map(|name| read(&base.join(name)))
        .collect::<Result<Vec<_>, _>>()?;
    let fmus: Vec<(&str, &[u8])> = names
        .iter()
        .zip(&archives)
        .map(|(n, b)| (n.as_str(), b.as_slice()))
        .collect();
    Ok(SweepIdentity::compute(&bytes, &fmus, definition))
}

/// Reads the shard files among `inputs`: a file is read as one, a folder gives every
/// `*.toml` file in it (by name; other files and subfolders are left alone).
pub fn read_shard_files(inputs: &[PathBuf]) -> Result<Vec<(PathBuf, ShardFile)>, ShardError> {
    let mut paths = Vec::new();
    for input in inputs {
        if input.is_dir() {
            let entries = std::fs::read_dir(input).map_err(|error| ShardError::Read {
                path: input.clone(),
                error,
            })?;
            let mut found = Vec::new();
            for entry in entries {
                let path = entry
                    .map_err(|error| ShardError::Read {
                        path: input.clone(),
                        error,
                    })?
                    .path();
                if path.is_file() && path.extension().is_some_and(|e| e == "toml") {
                    found.push(path);
                }
            }
            found.sort();
            paths.extend(found);
        } else {
            paths.push(input.clone());
        }
    }
    paths
        .into_iter()
        .map(|p| ShardFile::read(&p).map(|f| (p, f)))
        .collect()
}

/// How a run ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum RunStatus {
    Ok,
    Failed,
}

/// One run in a shard file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RunRecord {
    /// The run index in the whole sweep.
    pub index: usize,
    /// The values of the varied parameters, in the order of [`ShardFile::parameters`].
    pub parameters: Vec<f64>,
    pub status: RunStatus,
    /// The metric values, in the order of [`ShardFile::metrics`] (empty when failed).
    #[serde(default)]
    pub metrics: Vec<f64>,
    /// Why the run failed.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub error: Option<String>,
}

impl RunRecord {
    /// A run that finished with these metric values.
    pub fn ok(index: usize, parameters: Vec<f64>, metrics: Vec<f64>) -> Self {
        Self {
            index,
            parameters,
            status: RunStatus::Ok,
            metrics,
            error: None,
        }
    }

    /// A run that failed with this error.
    pub fn failed(index: usize, parameters: Vec<f64>, error: String) -> Self {
        Self {
            index,
            parameters,
            status: RunStatus::Failed,
            metrics: Vec::new(),
            error: Some(error),
        }
    }
}

/// The result file of one shard.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ShardFile {
    /// [`FORMAT`].
    pub format: u32,
    /// [`PRODUCER`] of the writer.
    pub producer: String,
    pub sweep: SweepIdentity,
    /// This shard's index `i` of `shards`.
    pub shard: usize,
    pub shards: usize,
    /// The runs of the whole sweep.
    pub total_runs: usize,
    pub parameters: Vec<String>,
    pub metrics: Vec<String>,
    /// A command that reruns one shard, `{shard}` standing for `i/N` (e.g. `spurio sweep
    /// system.toml … --shard {shard}`); the merge prints it for every missing shard.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rerun: Option<String>,
    /// The Slurm batch script of the job array, when the sweep ran on Slurm.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub slurm_script: Option<String>,
    pub runs: Vec<RunRecord>,
}

impl ShardFile {
    /// A shard file for `shard` of the sweep `definition` identified by `sweep`, holding
    /// `runs` (which must be the shard's runs, in order; [`merge`] checks it).
    pub fn new(
        sweep: SweepIdentity,
        shard: Shard,
        definition: &SweepDefinition,
        runs: Vec<RunRecord>,
    ) -> Self {
        Self {
            format: FORMAT,
            producer: PRODUCER.to_string(),
            sweep,
            shard: shard.index,
            shards: shard.count,
            total_runs: definition.runs.len(),
            parameters: definition.parameters.clone(),
            metrics: definition.metrics.clone(),
            rerun: None,
            slurm_script: None,
            runs,
        }
    }

    /// The TOML text of the file.
    pub fn to_toml(&self) -> Result<String, ShardError> {
        toml::to_string(self).map_err(|e| ShardError::Serialize(e.to_string()))
    }

    /// Parses TOML text; `path` names the file in errors.
    pub fn from_toml(text: &str, path: &Path) -> Result<Self, ShardError> {
        let file: Self = toml::from_str(text).map_err(|e| ShardError::Format {
            path: path.to_path_buf(),
            reason: e.to_string(),
        })?;
        if file.format != FORMAT {
            return Err(ShardError::Format {
                path: path.to_path_buf(),
                reason: format!(
                    "format {} (this program reads format {FORMAT})",
                    file.format
                ),
            });
        }
        Ok(file)
    }

    /// Reads a shard file, of at most [`MAX_SHARD_FILE_BYTES`] bytes (no more is read, so an
    /// endless file such as `/dev/zero` is refused too).
    pub fn read(path: &Path) -> Result<Self, ShardError> {
        Self::read_at_most(path, MAX_SHARD_FILE_BYTES)
    }

    /// [`ShardFile::read`] of a file of at most `max_bytes` bytes.
    pub fn read_at_most(path: &Path, max_bytes: u64) -> Result<Self, ShardError> {
        let text = spurio_master::read_text_at_most(
            path,
            max_bytes,
            "the shard file",
            "the largest shard file read",
        )
        .map_err(|reason| ShardError::Read {
            path: path.to_path_buf(),
            error: std::io::Error::other(reason),
        })?;
        Self::from_toml(&text, path)
    }

    /// Writes the file under a temporary name beside `path`, then renames it to `path`, so
    /// that readers see either the whole file or none (a rerun replaces it the same way).
    pub fn write(&self, path: &Path) -> Result<(), ShardError> {
        let text = self.to_toml()?;
        let write_error = |error| ShardError::Write {
            path: path.to_path_buf(),
            error,
        };
        let mut tmp = path.as_os_str().to_owned();
        tmp.push(format!(".tmp{}", std::process::id()));
        let tmp = PathBuf::from(tmp);
        std::fs::write(&tmp, text).map_err(write_error)?;
        std::fs::rename(&tmp, path).map_err(|e| {
            let _ = std::fs::remove_file(&tmp);
            write_error(e)
        })
    }
}

/// What the caller of [`merge`]/[`progress`] knows independently of the shard files.
#[derive(Debug, Clone, Default)]
pub struct MergeOptions {
    /// The identity the shards must have (recomputed from the system, FMUs and definition);
    /// without it the shards must merely agree with each other.
    pub expected_sweep: Option<SweepIdentity>,
    /// The number of shards the sweep was cut into; without it, the count the files record.
    pub expected_shards: Option<usize>,
    /// The sweep definition: every run's parameter values must be the definition's values
    /// for its run index (bit for bit), whichever shard ran it.
    pub definition: Option<SweepDefinition>,
}

/// A run that failed, for [`MergeError::FailedRuns`].
#[derive(Debug, Clone, PartialEq)]
pub struct FailedRun {
    pub index: usize,
    pub shard: usize,
    pub parameters: Vec<f64>,
    pub error: String,
}

/// A missing shard and how to produce it.
#[derive(Debug, Clone, PartialEq)]
pub struct MissingShard {
    pub shard: Shard,
    pub runs: Range<usize>,
    /// The command that reruns it, when a present shard recorded one.
    pub rerun: Option<String>,
}

/// Why shards do not merge.
#[derive(Debug, thiserror::Error)]
pub enum MergeError {
    #[error("no shard files to merge")]
    NoShards,
    #[error("{}", foreign_message(expected, foreign))]
    ForeignShards {
        expected: SweepIdentity,
        foreign: Vec<(PathBuf, SweepIdentity)>,
    },
    #[error("{}", mixed_message(groups))]
    MixedSweeps {
        groups: Vec<(SweepIdentity, Vec<PathBuf>)>,
    },
    #[error("shard file {}: {field} is {found}, but {expected} in {}", path.display(), reference.display())]
    Inconsistent {
        path: PathBuf,
        reference: PathBuf,
        field: &'static str,
        found: String,
        expected: String,
    },
    #[error("shard file {}: shard {shard} of {shards} does not exist", path.display())]
    ShardOutOfRange {
        path: PathBuf,
        shard: usize,
        shards: usize,
    },
    #[error("shard {shard} appears more than once: {}", list_paths(paths))]
    DuplicateShard { shard: usize, paths: Vec<PathBuf> },
    #[error("shard file {}: shard {shard} must hold runs {}..{} in order, {found}", path.display(), expected.start, expected.end)]
    WrongRuns {
        path: PathBuf,
        shard: Shard,
        expected: Range<usize>,
        found: String,
    },
    #[error("shard file {}: not of this sweep's definition: {reason}", path.display())]
    NotOfDefinition { path: PathBuf, reason: String },
    #[error("{}", missing_message(missing, slurm_script.as_deref()))]
    MissingShards {
        missing: Vec<MissingShard>,
        slurm_script: Option<String>,
    },
    #[error("{}", failed_message(failed))]
    FailedRuns { failed: Vec<FailedRun> },
    #[error("metric `{label}` of the shard files: {reason}")]
    Metric { label: String, reason: String },
}

/// `paths` as one line, separated by commas (as the errors name them).
pub fn list_paths(paths: &[PathBuf]) -> String {
    paths
        .iter()
        .map(|p| p.display().to_string())
        .collect::<Vec<_>>()
        .join(", ")
}

fn foreign_message(expected: &SweepIdentity, foreign: &[(PathBuf, SweepIdentity)]) -> String {
    let mut s = format!(
        "{} shard file(s) belong to another sweep than {expected} (system, FMUs or sweep definition differ):",
        foreign.len()
    );
    for (path, id) in foreign {
        let _ = write!(s, "\n  {} is of {id}", path.display());
    }
    s
}

fn mixed_message(groups: &[(SweepIdentity, Vec<PathBuf>)]) -> String {
    let mut s = format!(
        "the shard files belong to {} different sweeps (system, FMUs or sweep definition differ):",
        groups.len()
    );
    for (id, paths) in groups {
        let _ = write!(s, "\n  {id}: {}", list_paths(paths));
    }
    s
}

fn missing_message(missing: &[MissingShard], slurm_script: Option<&str>) -> String {
    let count = missing.first().map_or(0, |m| m.shard.count);
    let mut s = format!("{} of {count} shards missing:", missing.len());
    for m in missing {
        let _ = write!(
            s,
            "\n  shard {} (runs {}..{})",
            m.shard, m.runs.start, m.runs.end
        );
    }
    s.push_str("\nrerun them with");
    if missing.iter().all(|m| m.rerun.is_some()) {
        s.push(':');
        for m in missing {
            if let Some(cmd) = &m.rerun {
                let _ = write!(s, "\n  {cmd}");
            }
        }
    } else {
        let _ = write!(
            s,
            " the sweep's command and `--shard i/{count}` for each missing i"
        );
    }
    if let Some(script) = slurm_script {
        let indices: Vec<String> = missing.iter().map(|m| m.shard.index.to_string()).collect();
        let _ = write!(
            s,
            "\nor on Slurm: sbatch --array={} {script}",
            indices.join(",")
        );
    }
    s
}

fn failed_message(failed: &[FailedRun]) -> String {
    let mut s = format!("{} run(s) failed:", failed.len());
    for f in failed {
        let _ = write!(
            s,
            "\n  run {} (shard {}, parameters {:?}): {}",
            f.index, f.shard, f.parameters, f.error
        );
    }
    s
}

fn parse_metrics(labels: &[String]) -> Result<Vec<Metric>, MergeError> {
    labels
        .iter()
        .map(|label| {
            let metric = Metric::parse(label).map_err(|reason| MergeError::Metric {
                label: label.clone(),
                reason: reason.to_string(),
            })?;
            if metric.label() != *label {
                return Err(MergeError::Metric {
                    label: label.clone(),
                    reason: format!("reads back as `{}`", metric.label()),
                });
            }
            Ok(metric)
        })
        .collect()
}

/// How far a sharded sweep has come: the shards done and missing, and the running table
/// ([`progress`]); from [`merge`], a whole sweep, every shard present.
#[derive(Debug, Clone, PartialEq)]
pub struct Progress {
    pub sweep: SweepIdentity,
    pub shards: usize,
    pub total_runs: usize,
    /// The varied parameters, in the order of each run's values.
    pub parameters: Vec<String>,
    /// Indices of the shards whose files are present, ascending.
    pub done: Vec<usize>,
    pub missing: Vec<MissingShard>,
    /// The runs of the present shards, in run-index order.
    pub runs: Vec<RunRecord>,
    pub metrics: Vec<String>,
}

impl Progress {
    /// The runs that failed so far.
    pub fn failed(&self) -> Vec<FailedRun> {
        self.runs
            .iter()
            .filter(|r| r.status == RunStatus::Failed)
            .map(|r| FailedRun {
                index: r.index,
                // The runs were checked against the partition, so the run is in range.
                shard: Shard::of_run(r.index, self.total_runs, self.shards).map_or(0, |s| s.index),
                parameters: r.parameters.clone(),
                error: r.error.clone().unwrap_or_default(),
            })
            .collect()
    }

    /// The [`SweepResult`] of the runs (its `table()` is the one-machine sweep's table), or
    /// the list of failed runs: like the one-machine sweep, a sweep with a failed run has no
    /// table.
    pub fn result(&self) -> Result<SweepResult, MergeError> {
        let failed = self.failed();
        if !failed.is_empty() {
            return Err(MergeError::FailedRuns { failed });
        }
        self.running_result()
    }

    /// The table over the runs that finished so far (failed runs left out), in run order.
    pub fn running_result(&self) -> Result<SweepResult, MergeError> {
        Ok(SweepResult {
            metrics: parse_metrics(&self.metrics)?,
            runs: self
                .runs
                .iter()
                .filter(|r| r.status == RunStatus::Ok)
                .map(|r| r.metrics.clone())
                .collect(),
        })
    }
}

impl fmt::Display for Progress {
    /// `5/8 shards done (62/100 runs, 1 failed); missing: 2, 6, 7`.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{}/{} shards done ({}/{} runs",
            self.done.len(),
            self.shards,
            self.runs.len(),
            self.total_runs
        )?;
        let failed = self.failed().len();
        if failed > 0 {
            write!(f, ", {failed} failed")?;
        }
        f.write_str(")")?;
        if !self.missing.is_empty() {
            let list: Vec<String> = self
                .missing
                .iter()
                .map(|m| m.shard.index.to_string())
                .collect();
            write!(f, "; missing: {}", list.join(", "))?;
        }
        Ok(())
    }
}

/// Checks the shard files of one sweep — one identity, one shape, no duplicate, every shard
/// holding exactly its runs — and reports how far the sweep has come. A missing shard is not
/// an error here (see [`merge`]).
pub fn progress(
    files: &[(PathBuf, ShardFile)],
    options: &MergeOptions,
) -> Result<Progress, MergeError> {
    let Some((ref_path, reference)) = files.first() else {
        return Err(MergeError::NoShards);
    };
    check_identity(files, options)?;
    let shards = options.expected_shards.unwrap_or(reference.shards);
    let mut by_shard: BTreeMap<usize, Vec<&PathBuf>> = BTreeMap::new();
    for (path, file) in files {
        let inconsistent = |field: &'static str, found: String, expected: String| {
            Err(MergeError::Inconsistent {
                path: path.clone(),
                reference: ref_path.clone(),
                field,
                found,
                expected,
            })
        };
        if file.producer != reference.producer {
            return inconsistent(
                "the producer",
                file.producer.clone(),
                reference.producer.clone(),
            );
        }
        if file.shards != shards {
            let reference = match options.expected_shards {
                Some(_) => "expected".to_string(),
                None => reference.shards.to_string(),
            };
            return inconsistent("the shard count", file.shards.to_string(), reference);
        }
        if file.total_runs != reference.total_runs {
            return inconsistent(
                "the run count",
                file.total_runs.to_string(),
                reference.total_runs.to_string(),
            );
        }
        if file.parameters != reference.parameters {
            return inconsistent(
                "the parameter list",
                format!("{:?}", file.parameters),
                format!("{:?}", reference.parameters),
            );
        }
        if file.metrics != reference.metrics {
            return inconsistent(
                "the metric list",
                format!("{:?}", file.metrics),
                format!("{:?}", reference.metrics),
            );
        }
        if file.shard >= shards {
            return Err(MergeError::ShardOutOfRange {
                path: path.clone(),
                shard: file.shard,
                shards,
            });
        }
        check_runs(path, file)?;
        if let Some(definition) = &options.definition {
            check_definition(path, file, definition)?;
        }
        by_shard.entry(file.shard).or_default().push(path);
    }
    if let Some((shard, paths)) = by_shard.iter().find(|(_, p)| p.len() > 1) {
        return Err(MergeError::DuplicateShard {
            shard: *shard,
            paths: paths.iter().map(|p| (*p).clone()).collect(),
        });
    }
    let rerun = files.iter().find_map(|(_, f)| f.rerun.clone());
    let missing = (0..shards)
        .filter(|i| !by_shard.contains_key(i))
        .map(|index| {
            let shard = Shard {
                index,
                count: shards,
            };
            MissingShard {
                shard,
                runs: shard.runs(reference.total_runs),
                rerun: rerun
                    .as_ref()
                    .map(|cmd| cmd.replace("{shard}", &shard.to_string())),
            }
        })
        .collect();
    let mut ordered: Vec<&ShardFile> = files.iter().map(|(_, f)| f).collect();
    ordered.sort_by_key(|f| f.shard);
    Ok(Progress {
        sweep: reference.sweep.clone(),
        shards,
        total_runs: reference.total_runs,
        parameters: reference.parameters.clone(),
        done: by_shard.keys().copied().collect(),
        missing,
        runs: ordered.iter().flat_map(|f| f.runs.clone()).collect(),
        metrics: reference.metrics.clone(),
    })
}

/// Merges the shard files of one sweep: [`progress`]'s checks, and every shard present.
/// The runs come back in run-index order; [`Progress::result`] is the sweep's table.
pub fn merge(
    files: &[(PathBuf, ShardFile)],
    options: &MergeOptions,
) -> Result<Progress, MergeError> {
    if files.is_empty() {
        if let Some(count) = options.expected_shards.filter(|n| *n > 0) {
            // Nothing ran yet: every shard is missing, and no file says how to rerun it.
            return Err(MergeError::MissingShards {
                missing: (0..count)
                    .map(|index| MissingShard {
                        shard: Shard { index, count },
                        runs: 0..0,
                        rerun: None,
                    })
                    .collect(),
                slurm_script: None,
            });
        }
        return Err(MergeError::NoShards);
    }
    let progress = progress(files, options)?;
    if !progress.missing.is_empty() {
        return Err(MergeError::MissingShards {
            missing: progress.missing,
            slurm_script: files.iter().find_map(|(_, f)| f.slurm_script.clone()),
        });
    }
    Ok(progress)
}

fn check_identity(
    files: &[(PathBuf, ShardFile)],
    options: &MergeOptions,
) -> Result<(), MergeError> {
    if let Some(expected) = &options.expected_sweep {
        let foreign: Vec<(PathBuf, SweepIdentity)> = files
            .iter()
            .filter(|(_, f)| f.sweep != *expected)
            .map(|(p, f)| (p.clone(), f.sweep.clone()))
            .collect();
        if !foreign.is_empty() {
            return Err(MergeError::ForeignShards {
                expected: expected.clone(),
                foreign,
            });
        }
        return Ok(());
    }
    let mut groups: Vec<(SweepIdentity, Vec<PathBuf>)> = Vec::new();
    for (path, file) in files {
        match groups.iter_mut().find(|(id, _)| *id == file.sweep) {
            Some((_, paths)) => paths.push(path.clone()),
            None => groups.push((file.sweep.clone(), vec![path.clone()])),
        }
    }
    if groups.len() > 1 {
        return Err(MergeError::MixedSweeps { groups });
    }
    Ok(())
}

fn check_runs(path: &Path, file: &ShardFile) -> Result<(), MergeError> {
    let shard = Shard {
        index: file.shard,
        count: file.shards,
    };
    let expected = shard.runs(file.total_runs);
    let wrong = |found: String| {
        Err(MergeError::WrongRuns {
            path: path.to_path_buf(),
            shard,
            expected: expected.clone(),
            found,
        })
    };
    if file.runs.len() != expected.len() {
        return wrong(format!("it holds {} runs", file.runs.len()));
    }
    for (run, index) in file.runs.iter().zip(expected.clone()) {
        if run.index != index {
            return wrong(format!("found run {} where run {index} belongs", run.index));
        }
        if run.parameters.len() != file.parameters.len() {
            return wrong(format!(
                "run {index} has {} parameter values for {} parameters",
                run.parameters.len(),
                file.parameters.len()
            ));
        }
        match run.status {
            RunStatus::Ok if run.metrics.len() != file.metrics.len() => {
                return wrong(format!(
                    "run {index} has {} metric values for {} metrics",
                    run.metrics.len(),
                    file.metrics.len()
                ));
            }
            RunStatus::Failed if run.error.is_none() => {
                return wrong(format!("failed run {index} has no error text"));
            }
            _ => {}
        }
    }
    Ok(())
}

fn check_definition(
    path: &Path,
    file: &ShardFile,
    definition: &SweepDefinition,
) -> Result<(), MergeError> {
    let wrong = |reason: String| {
        Err(MergeError::NotOfDefinition {
            path: path.to_path_buf(),
            reason,
        })
    };
    if file.total_runs != definition.runs.len() {
        return wrong(format!(
            "{} runs, the definition has {}",
            file.total_runs,
            definition.runs.len()
        ));
    }
    if file.parameters != definition.parameters || file.metrics != definition.metrics {
        return wrong(format!(
            "parameters {:?} and metrics {:?}, the definition has {:?} and {:?}",
            file.parameters, file.metrics, definition.parameters, definition.metrics
        ));
    }
    for run in &file.runs {
        let Some(expected) = definition.runs.get(run.index) else {
            return wrong(format!("run {} is not in the definition", run.index));
        };
        let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        if bits(&run.parameters) != bits(expected) {
            return wrong(format!(
                "run {} has parameter values {:?}, the definition {expected:?}",
                run.index, run.parameters
            ));
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A sweep of `total` runs with two metrics whose values are awkward floats (no short
    /// decimal form, subnormal, huge), as a one-machine sweep would produce them.
    fn local_sweep(total: usize) -> (SweepDefinition, SweepResult) {
        let variation = Variation::parse(&format!("src.seed=1..{total}")).unwrap();
        let metrics = vec![
            Metric::parse("e_res(kf.x_hat[1], plant.x)").unwrap(),
            Metric::parse("settling(plant.x; 0.005)").unwrap(),
        ];
        let definition = SweepDefinition::from_variation(&variation, &metrics);
        let runs = (0..total)
            .map(|k| {
                let x = (k as f64 + 1.0).sqrt() * std::f64::consts::PI / 7.0;
                let second = match k % 5 {
                    0 => f64::NAN, // never settled
                    1 => 5e-324,
                    2 => 1.0e300 / (k as f64),
                    _ => -x.ln_1p(),
                };
                vec![x.sin() * 1e-3, second]
            })
            .collect();
        (definition, SweepResult { metrics, runs })
    }

    fn identity(definition: &SweepDefinition) -> SweepIdentity {
        SweepIdentity::compute(
            b"stop_time = 1.0\n",
            &[("crane.fmu", b"PK crane"), ("kf.fmu", b"PK kf")],
            definition,
        )
    }

    /// The shard files that `N` array tasks would write, round-tripped through their TOML.
    fn shard_files(
        definition: &SweepDefinition,
        local: &SweepResult,
        count: usize,
    ) -> Vec<(PathBuf, ShardFile)> {
        let id = identity(definition);
        (0..count)
            .map(|i| {
                let shard = Shard::new(i, count).unwrap();
                let runs = shard
                    .runs(definition.runs.len())
                    .map(|k| RunRecord::ok(k, definition.runs[k].clone(), local.runs[k].clone()))
                    .collect();
                let mut file = ShardFile::new(id.clone(), shard, definition, runs);
                file.rerun = Some(format!(
                    "spurio sweep sys.toml --vary src.seed=1..{} --shard {{shard}}",
                    definition.runs.len()
                ));
                file.slurm_script = Some("sweep.sbatch".into());
                let path = PathBuf::from(format!("shard-{i}.toml"));
                let text = file.to_toml().unwrap();
                (path.clone(), ShardFile::from_toml(&text, &path).unwrap())
            })
            .collect()
    }

    #[test]
    fn every_run_is_in_exactly_one_shard_for_any_count() {
        for total in 0..=60 {
            for count in 1..=70 {
                let mut next = 0;
                let mut sizes = Vec::new();
                for index in 0..count {
                    let shard = Shard::new(index, count).unwrap();
                    let runs = shard.runs(total);
                    assert_eq!(runs.start, next, "R={total} N={count} shard {index}");
                    for run in runs.clone() {
                        assert_eq!(Shard::of_run(run, total, count).unwrap(), shard);
                    }
                    next = runs.end;
                    sizes.push(runs.len());
                }
                assert_eq!(next, total, "R={total} N={count}: runs not covered");
                let (min, max) = (sizes.iter().min().unwrap(), sizes.iter().max().unwrap());
                assert!(max - min <= 1, "R={total} N={count}: sizes {sizes:?}");
            }
        }
        assert_eq!(Shard::new(0, 4).unwrap().runs(10), 0..3);
        assert_eq!(Shard::new(1, 4).unwrap().runs(10), 3..6);
        assert_eq!(Shard::new(2, 4).unwrap().runs(10), 6..8);
        assert_eq!(Shard::new(3, 4).unwrap().runs(10), 8..10);
        assert_eq!(Shard::new(5, 8).unwrap().runs(3), 3..3);
        assert!(Shard::of_run(10, 10, 4).is_err());
    }

    #[test]
    fn shard_specs_parse_and_reject_what_is_not_a_shard() {
        assert_eq!(
            "3/8".parse::<Shard>().unwrap(),
            Shard { index: 3, count: 8 }
        );
        assert_eq!(" 0 / 1 ".parse::<Shard>().unwrap().to_string(), "0/1");
        for bad in ["8/8", "0/0", "3", "-1/4", "a/4", "1/b", ""] {
            let e = bad.parse::<Shard>().unwrap_err().to_string();
            assert!(e.contains(&format!("shard `{bad}`")), "{bad}: {e}");
        }
    }

    #[test]
    fn identity_changes_with_system_fmus_and_definition_only() {
        let (definition, _) = local_sweep(10);
        let id = identity(&definition);
        assert!(id.0.starts_with("sha256:") && id.0.len() == 7 + 64, "{id}");
        // FMU order does not matter.
        let swapped = SweepIdentity::compute(
            b"stop_time = 1.0\n",
            &[("kf.fmu", b"PK kf"), ("crane.fmu", b"PK crane")],
            &definition,
        );
        assert_eq!(swapped, id);
        let other_system = SweepIdentity::compute(
            b"stop_time = 2.0\n",
            &[("crane.fmu", b"PK crane"), ("kf.fmu", b"PK kf")],
            &definition,
        );
        let other_fmu = SweepIdentity::compute(
            b"stop_time = 1.0\n",
            &[("crane.fmu", b"PK crane2"), ("kf.fmu", b"PK kf")],
            &definition,
        );
        // Moving bytes between fields must not give the same stream.
        let shifted = SweepIdentity::compute(
            b"stop_time = 1.0\n",
            &[("crane.fmu", b"PK cran"), ("kf.fmu", b"ePK kf")],
            &definition,
        );
        let mut values = definition.clone();
        values.runs[3][0] = 4.000000000000001;
        let mut metrics = definition.clone();
        metrics.metrics.pop();
        let mut zero = definition.clone();
        zero.runs[0][0] = 0.0;
        let mut negative_zero = definition.clone();
        negative_zero.runs[0][0] = -0.0;
        let ids = [
            id.clone(),
            other_system,
            other_fmu,
            shifted,
            identity(&values),
            identity(&metrics),
            identity(&zero),
            identity(&negative_zero),
        ];
        for (a, x) in ids.iter().enumerate() {
            for (b, y) in ids.iter().enumerate() {
                assert_eq!(a == b, x == y, "identities {a} and {b}");
            }
        }
        // Stable across builds and machines: a pinned value.
        let pinned = SweepIdentity::compute(
            b"",
            &[],
            &SweepDefinition {
                parameters: vec!["s.seed".into()],
                runs: vec![vec![1.0]],
                metrics: vec!["rms(x)".into()],
            },
        );
        assert_eq!(pinned, SweepIdentity(PINNED.into()));
    }

    // SHA-256 of the byte stream of `SweepIdentity::compute` for the definition above,
    // computed independently with Python's hashlib.
    const PINNED: &str = "sha256:83d88ce25e3eba1865ac747c50b56b187ae566d0f1d739e2b130c919c19f019f";

    #[test]
    fn merged_shards_reproduce_the_local_table_bit_for_bit() {
        for total in [1, 7, 100, 103] {
            let (definition, local) = local_sweep(total);
            for count in [1, 2, 4, 7, 13, 150] {
                let mut files = shard_files(&definition, &local, count);
                // The order the files come in (a directory listing) does not matter.
                files.reverse();
                files.swap(0, count / 2);
                let merged = merge(&files, &MergeOptions::default()).unwrap();
                assert_eq!(merged.runs.len(), total);
                for (k, run) in merged.runs.iter().enumerate() {
                    assert_eq!(run.index, k);
                    assert_eq!(run.parameters, vec![k as f64 + 1.0]);
                    let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
                    let (a, b) = (bits(&run.metrics), bits(&local.runs[k]));
                    // NaN's payload need not survive; that it is NaN must.
                    assert_eq!(a[0], b[0], "R={total} N={count} run {k}");
                    assert!(
                        a[1] == b[1] || (run.metrics[1].is_nan() && local.runs[k][1].is_nan()),
                        "R={total} N={count} run {k}: {:?} vs {:?}",
                        run.metrics,
                        local.runs[k]
                    );
                }
                let result = merged.result().unwrap();
                assert_eq!(result.table(), local.table(), "R={total} N={count}");
                assert_eq!(result.metrics, local.metrics);
            }
        }
        // The table is a real one: 100 runs, a fifth of the settling times NaN.
        let (_, local) = local_sweep(100);
        assert!(local.table().contains("| 80/100 |"), "{}", local.table());
    }

    #[test]
    fn a_missing_shard_is_named_with_the_commands_that_rerun_it() {
        let (definition, local) = local_sweep(100);
        let mut files = shard_files(&definition, &local, 8);
        files.remove(6);
        files.remove(2);
        let e = merge(&files, &MergeOptions::default()).unwrap_err();
        let MergeError::MissingShards { missing, .. } = &e else {
            panic!("{e}");
        };
        let shards: Vec<(usize, Range<usize>)> = missing
            .iter()
            .map(|m| (m.shard.index, m.runs.clone()))
            .collect();
        assert_eq!(shards, vec![(2, 26..39), (6, 76..88)]);
        let text = e.to_string();
        for expected in [
            "2 of 8 shards missing",
            "shard 2/8 (runs 26..39)",
            "spurio sweep sys.toml --vary src.seed=1..100 --shard 2/8",
            "spurio sweep sys.toml --vary src.seed=1..100 --shard 6/8",
            "sbatch --array=2,6 sweep.sbatch",
        ] {
            assert!(text.contains(expected), "`{expected}` not in:\n{text}");
        }
        // The same files as progress: 6 of 8 shards, the running table over their runs.
        let p = progress(&files, &MergeOptions::default()).unwrap();
        assert_eq!(
            p.to_string(),
            "6/8 shards done (75/100 runs); missing: 2, 6"
        );
        let running = p.running_result().unwrap();
        let kept: Vec<Vec<f64>> = (0..100)
            .filter(|k| !(26..39).contains(k) && !(76..88).contains(k))
            .map(|k| local.runs[k].clone())
            .collect();
        assert_eq!(running.runs.len(), 75);
        assert_eq!(
            running.table(),
            SweepResult {
                metrics: local.metrics.clone(),
                runs: kept
            }
            .table()
        );
        // Expected 10 shards, the files say 8: the count is inconsistent.
        let options = MergeOptions {
            expected_shards: Some(10),
            ..Default::default()
        };
        let e = merge(&files, &options).unwrap_err().to_string();
        assert!(e.contains("the shard count is 8, but expected"), "{e}");
        // Nothing ran yet, but the shard count is known.
        let e = merge(&[], &options).unwrap_err().to_string();
        assert!(e.starts_with("10 of 10 shards missing"), "{e}");
        assert!(matches!(
            merge(&[], &MergeOptions::default()),
            Err(MergeError::NoShards)
        ));
    }

    #[test]
    fn a_duplicated_shard_is_refused() {
        let (definition, local) = local_sweep(20);
        let mut files = shard_files(&definition, &local, 4);
        let mut copy = files[1].clone();
        copy.0 = PathBuf::from("requeued/shard-1.toml");
        files.push(copy);
        let e = merge(&files, &MergeOptions::default()).unwrap_err();
        assert!(
            matches!(&e, MergeError::DuplicateShard { shard: 1, paths } if paths.len() == 2),
            "{e}"
        );
        assert!(e
            .to_string()
            .contains("shard 1 appears more than once: shard-1.toml, requeued/shard-1.toml"));
    }

    #[test]
    fn a_shard_of_another_sweep_is_refused() {
        let (definition, local) = local_sweep(20);
        let mut files = shard_files(&definition, &local, 4);
        let mut other = definition.clone();
        other.runs[19][0] = 21.0;
        let foreign = identity(&other);
        files[3].1.sweep = foreign.clone();
        let e = merge(&files, &MergeOptions::default()).unwrap_err();
        let MergeError::MixedSweeps { groups } = &e else {
            panic!("{e}");
        };
        assert_eq!(groups.len(), 2);
        assert_eq!(
            groups[1],
            (foreign.clone(), vec![PathBuf::from("shard-3.toml")])
        );
        // With the identity recomputed by the caller, the odd one out is named as foreign.
        let options = MergeOptions {
            expected_sweep: Some(identity(&definition)),
            ..Default::default()
        };
        let e = merge(&files, &options).unwrap_err();
        assert!(
            matches!(&e, MergeError::ForeignShards { foreign: f, .. } if f.len() == 1),
            "{e}"
        );
        assert!(e
            .to_string()
            .contains(&format!("shard-3.toml is of {foreign}")));
        // All four from the other sweep: each is foreign.
        let options = MergeOptions {
            expected_sweep: Some(foreign),
            ..Default::default()
        };
        let e = merge(&files, &options).unwrap_err();
        assert!(
            matches!(&e, MergeError::ForeignShards { foreign: f, .. } if f.len() == 3),
            "{e}"
        );
    }

    #[test]
    fn inconsistent_shapes_and_wrong_runs_are_named() {
        let (definition, local) = local_sweep(20);
        let files = shard_files(&definition, &local, 4);
        let check = |edit: &dyn Fn(&mut ShardFile), expected: &str| {
            let mut files = files.clone();
            edit(&mut files[2].1);
            let e = merge(&files, &MergeOptions::default())
                .unwrap_err()
                .to_string();
            assert!(e.contains(expected), "`{expected}` not in: {e}");
            assert!(e.contains("shard-2.toml"), "{e}");
        };
        check(
            &|f| f.total_runs = 21,
            "the run count is 21, but 20 in shard-0.toml",
        );
        check(&|f| f.shards = 5, "the shard count is 5, but 4");
        check(&|f| f.producer = "spurio 0.0.1".into(), "the producer");
        check(&|f| f.metrics.pop().map(|_| ()).unwrap(), "the metric list");
        check(
            &|f| f.parameters = vec!["src.gain".into()],
            "the parameter list",
        );
        check(&|f| f.runs.pop().map(|_| ()).unwrap(), "it holds 4 runs");
        check(
            &|f| f.runs.swap(0, 1),
            "runs 10..15 in order, found run 11 where run 10 belongs",
        );
        check(
            &|f| f.runs[1].metrics.push(0.0),
            "run 11 has 3 metric values for 2 metrics",
        );
        check(
            &|f| f.runs[1].parameters.clear(),
            "run 11 has 0 parameter values",
        );
        check(
            &|f| {
                f.runs[0].status = RunStatus::Failed;
                f.runs[0].metrics.clear();
            },
            "failed run 10 has no error text",
        );
        let mut out_of_range = files.clone();
        out_of_range[2].1.shard = 4;
        out_of_range[2].1.shards = 4;
        let e = merge(&out_of_range, &MergeOptions::default()).unwrap_err();
        assert!(e.to_string().contains("shard 4 of 4 does not exist"), "{e}");
    }

    #[test]
    fn runs_must_carry_the_definitions_values_for_their_index() {
        let (definition, local) = local_sweep(20);
        let mut files = shard_files(&definition, &local, 4);
        let options = MergeOptions {
            definition: Some(definition.clone()),
            ..Default::default()
        };
        assert_eq!(merge(&files, &options).unwrap().runs.len(), 20);
        // A shard that seeded its runs by their position in the shard, not their run index.
        for (j, run) in files[1].1.runs.iter_mut().enumerate() {
            run.parameters = vec![j as f64 + 1.0];
        }
        assert!(merge(&files, &MergeOptions::default()).is_ok());
        let e = merge(&files, &options).unwrap_err().to_string();
        assert!(
            e.contains("shard-1.toml: not of this sweep's definition: run 5 has parameter values [1.0], the definition [6.0]"),
            "{e}"
        );
        let mut shorter = definition.clone();
        shorter.runs.pop();
        let options = MergeOptions {
            definition: Some(shorter),
            ..Default::default()
        };
        let e = merge(&files, &options).unwrap_err().to_string();
        assert!(e.contains("20 runs, the definition has 19"), "{e}");
    }

    #[test]
    fn failed_runs_are_kept_in_the_files_and_named_by_the_merge() {
        let (definition, local) = local_sweep(20);
        let mut files = shard_files(&definition, &local, 4);
        files[1].1.runs[2] = RunRecord::failed(
            7,
            vec![8.0],
            "instance `kf` (kf.fmu): fmi2DoStep returned Error at t = 0.5".into(),
        );
        let path = files[1].0.clone();
        let text = files[1].1.to_toml().unwrap();
        assert!(text.contains("status = \"failed\""), "{text}");
        files[1].1 = ShardFile::from_toml(&text, &path).unwrap();
        let merged = merge(&files, &MergeOptions::default()).unwrap();
        assert_eq!(merged.runs[7].status, RunStatus::Failed);
        let e = merged.result().unwrap_err().to_string();
        assert!(
            e.contains("1 run(s) failed:\n  run 7 (shard 1, parameters [8.0]): instance `kf`"),
            "{e}"
        );
        let p = progress(&files, &MergeOptions::default()).unwrap();
        assert_eq!(p.to_string(), "4/4 shards done (20/20 runs, 1 failed)");
        assert_eq!(p.running_result().unwrap().runs.len(), 19);
    }

    #[test]
    fn every_float_reads_back_with_the_bits_it_was_written_with() {
        let values = [
            0.0,
            -0.0,
            f64::INFINITY,
            f64::NEG_INFINITY,
            5e-324,
            f64::MIN_POSITIVE,
            f64::MAX,
            -f64::MAX,
            0.1 + 0.2,
            1.0 / 3.0,
            -2.5e-17,
            123456789.0,
            f64::NAN,
        ];
        let definition = SweepDefinition {
            parameters: vec!["p".into()],
            runs: values.iter().map(|v| vec![*v]).collect(),
            metrics: vec!["final(p)".into()],
        };
        let runs = values
            .iter()
            .enumerate()
            .map(|(k, v)| RunRecord::ok(k, vec![*v], vec![-*v]))
            .collect();
        let file = ShardFile::new(
            identity(&definition),
            Shard::new(0, 1).unwrap(),
            &definition,
            runs,
        );
        let path = PathBuf::from("floats.toml");
        let back = ShardFile::from_toml(&file.to_toml().unwrap(), &path).unwrap();
        for (k, v) in values.iter().enumerate() {
            let run = &back.runs[k];
            if v.is_nan() {
                assert!(run.parameters[0].is_nan() && run.metrics[0].is_nan());
            } else {
                assert_eq!(run.parameters[0].to_bits(), v.to_bits(), "{v:e}");
                assert_eq!(run.metrics[0].to_bits(), (-v).to_bits(), "{v:e}");
            }
        }
    }

    #[test]
    fn shard_files_round_trip_through_disk_and_reject_other_formats() {
        let (definition, local) = local_sweep(9);
        let files = shard_files(&definition, &local, 2);
        let dir = std::env::temp_dir().join(format!("spurio-shard-test-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("shard-0.toml");
        files[0].1.write(&path).unwrap();
        let back = ShardFile::read(&path).unwrap();
        // (NaN != NaN, so compare the texts; the bits were checked in the merge test.)
        assert_eq!(back.to_toml().unwrap(), files[0].1.to_toml().unwrap());
        assert!(back.runs[0].metrics[1].is_nan());
        assert_eq!(back.runs[1].metrics[1].to_bits(), 1);
        // No temporary file is left beside it.
        assert_eq!(std::fs::read_dir(&dir).unwrap().count(), 1);
        let text = std::fs::read_to_string(&path).unwrap();
        let newer = text.replace("format = 1", "format = 2");
        let e = ShardFile::from_toml(&newer, &path).unwrap_err().to_string();
        assert!(e.contains("format 2 (this program reads format 1)"), "{e}");
        let e = ShardFile::from_toml("format = 1\n", &path)
            .unwrap_err()
            .to_string();
        assert!(e.contains("missing field"), "{e}");
        let e = ShardFile::read(&dir.join("absent.toml"))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("cannot read shard file") && e.contains("absent.toml"),
            "{e}"
        );
        // A file larger than the bound, and an endless one, are not read past it.
        let e = ShardFile::read_at_most(&path, 16).unwrap_err().to_string();
        assert!(
            e.contains("the shard file is larger than 16 bytes (the largest shard file read)"),
            "{e}"
        );
        let e = ShardFile::read_at_most(Path::new("/dev/zero"), 1024)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("cannot read shard file /dev/zero: the shard file is larger than 1024"),
            "{e}"
        );
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
