//! The runs of a sweep, each in a worker process (`spurio sweep-run`, this same program), at
//! most `--threads` at once: an FMU that crashes (a signal), aborts or hangs (past
//! `--call-timeout`) costs that run only, which is reported with its parameter value and
//! why, while the other runs complete.
//!
//! A worker writes its metrics on standard output as one line of numbers (`{:?}` form,
//! comma-separated) and exits 0; on failure it exits non-zero and its last `Error: …` or
//! `spurio: …` line on standard error says why. Its output goes to files in the session
//! folder (see [`crate::guard`]), read and removed when it ends.

use crate::guard;
use crate::limits::Limits;
use std::os::unix::process::ExitStatusExt;
use std::path::{Path, PathBuf};
use std::process::{Command, ExitStatus, Stdio};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{mpsc, Arc, Mutex};
use std::time::Duration;

/// What every run of a sweep shares.
pub struct Runs<'a> {
    pub system: &'a Path,
    /// `instance.variable`.
    pub variable: &'a str,
    pub metrics: &'a [String],
    pub limits: &'a Limits,
}

/// One run's metrics, or why it failed.
pub type Outcome = Result<Vec<f64>, String>;

impl Runs<'_> {
    /// Runs `(index, value)` of `runs` on `workers` worker processes and gives each outcome,
    /// in the order of `runs`; `done` hears of each as it ends.
    pub fn run(
        &self,
        runs: &[(usize, f64)],
        workers: usize,
        mut done: impl FnMut(usize, f64, &Outcome),
    ) -> anyhow::Result<Vec<Outcome>> {
        let exe = std::env::current_exe()
            .map_err(|e| anyhow::anyhow!("cannot locate the spurio executable: {e}"))?;
        let folder = guard::folder().unwrap_or_else(std::env::temp_dir);
        let next = AtomicUsize::new(0);
        let mut outcomes: Vec<Option<Outcome>> = vec![None; runs.len()];
        std::thread::scope(|scope| {
            let (tx, rx) = mpsc::channel();
            for _ in 0..workers.clamp(1, runs.len().max(1)) {
                let tx = tx.clone();
                let (next, exe, folder) = (&next, &exe, &folder);
                scope.spawn(move || loop {
                    let j = next.fetch_add(1, Ordering::SeqCst);
                    let Some(&(index, value)) = runs.get(j) else {
                        break;
                    };
                    let outcome = self.one(exe, folder, index, value);
                    if tx.send((j, outcome)).is_err() {
                        break;
                    }
                });
            }
            drop(tx);
            for (j, outcome) in rx {
                let (index, value) = runs[j];
                done(index, value, &outcome);
                outcomes[j] = Some(outcome);
            }
        });
        Ok(outcomes
            .into_iter()
            .map(|o| o.unwrap_or_else(|| Err("the run was not started".into())))
            .collect())
    }

    /// Run `index` (the variable at `value`) in a worker process.
    fn one(&self, exe: &Path, folder: &Path, index: usize, value: f64) -> Outcome {
        let out = folder.join(format!("run-{index}.out"));
        let err = folder.join(format!("run-{index}.err"));
        let outcome = self.spawn_and_wait(exe, &out, &err, value);
        let _ = std::fs::remove_file(&out);
        let _ = std::fs::remove_file(&err);
        outcome
    }

    fn spawn_and_wait(&self, exe: &Path, out: &PathBuf, err: &PathBuf, value: f64) -> Outcome {
        let file = |p: &PathBuf| {
            std::fs::File::create(p).map_err(|e| format!("cannot create {}: {e}", p.display()))
        };
        let mut command = Command::new(exe);
        command
            .arg("sweep-run")
            .arg(self.system)
            .arg("--set")
            .arg(format!("{}={value:?}", self.variable))
            .args(self.limits.args())
            .stdin(Stdio::null())
            .stdout(file(out)?)
            .stderr(file(err)?);
        for m in self.metrics {
            command.arg("--metric").arg(m);
        }
        let child = command
            .spawn()
            .map_err(|e| format!("cannot start a worker process: {e}"))?;
        let child = Arc::new(Mutex::new(child));
        guard::add_worker(child.clone());
        let status = loop {
            let polled = child
                .lock()
                .unwrap_or_else(std::sync::PoisonError::into_inner)
                .try_wait();
            match polled {
                Ok(Some(status)) => break status,
                Ok(None) => std::thread::sleep(Duration::from_millis(2)),
                Err(e) => return Err(format!("cannot wait for the worker process: {e}")),
            }
        };
        let stdout = std::fs::read_to_string(out).unwrap_or_default();
        let stderr = std::fs::read_to_string(err).unwrap_or_default();
        if status.success() {
            return parse_metrics(&stdout);
        }
        Err(why(status, &stderr))
    }
}

/// The metrics line of a worker.
fn parse_metrics(stdout: &str) -> Outcome {
    let line = stdout.lines().last().unwrap_or("").trim();
    if line.is_empty() {
        return Ok(Vec::new());
    }
    line.split(',')
        .map(|v| {
            v.trim()
                .parse::<f64>()
                .map_err(|_| format!("the worker gave `{line}`, not its metrics"))
        })
        .collect()
}

/// Why a worker failed: what it said last, or the signal that killed it or its exit code.
fn why(status: ExitStatus, stderr: &str) -> String {
    let said: Vec<&str> = stderr
        .lines()
        .filter_map(|l| {
            l.strip_prefix("Error: ")
                .or_else(|| l.strip_prefix("spurio: "))
        })
        .collect();
    let how = match (status.signal(), status.code()) {
        (Some(s), _) => format!(
            "the worker process was killed by signal {s} ({})",
            signal_name(s)
        ),
        (None, Some(c)) => format!("the worker process exited with code {c}"),
        _ => "the worker process ended abnormally".to_string(),
    };
    if said.is_empty() {
        let tail: Vec<&str> = stderr.lines().rev().take(3).collect();
        if tail.is_empty() {
            how
        } else {
            let tail: Vec<&str> = tail.into_iter().rev().collect();
            format!("{how}; it wrote: {}", tail.join(" | "))
        }
    } else {
        format!("{} ({how})", said.join("; "))
    }
}

pub fn signal_name(signal: i32) -> &'static str {
    match signal {
        1 => "SIGHUP",
        2 => "SIGINT",
        4 => "SIGILL",
        6 => "SIGABRT",
        7 => "SIGBUS",
        8 => "SIGFPE",
        9 => "SIGKILL",
        11 => "SIGSEGV",
        13 => "SIGPIPE",
        15 => "SIGTERM",
        _ => "a signal",
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_workers_failure_is_named_by_what_it_said_or_how_it_ended() {
        let segv = ExitStatus::from_raw(11);
        assert_eq!(
            why(segv, ""),
            "the worker process was killed by signal 11 (SIGSEGV)"
        );
        let exited = ExitStatus::from_raw(3 << 8);
        assert_eq!(
            why(
                exited,
                "log line\nError: instance `c`: fmi2DoStep returned fmi2Error\n"
            ),
            "instance `c`: fmi2DoStep returned fmi2Error (the worker process exited with code 3)"
        );
        assert_eq!(
            why(exited, "a\nb\nc\nd\n"),
            "the worker process exited with code 3; it wrote: b | c | d"
        );
        assert_eq!(parse_metrics("0.5,NaN,-1e-300\n").unwrap()[2], -1e-300);
        assert!(parse_metrics("0.5,x").is_err());
    }
}
