//! The runs of a sweep in worker processes (`spurio sweep-worker`, this same program), at
//! most `--threads` at once: an FMU that crashes (a signal), aborts, exits or hangs (past
//! `--call-timeout`) costs the run it was in only, which is reported with its parameter
//! value and why; a fresh worker takes the runs that remain.
//!
//! A worker loads the system once, then reads one value a line on standard input and
//! answers each on standard output with one line: `ok ` and the metrics (`{:?}` form,
//! comma-separated), or `error ` and why the run failed. A worker that ends without
//! answering took its run with it: its exit (the signal that killed it, or its code) and its
//! last `Error: …` or `spurio: …` line on standard error (kept in a file in the session
//! folder, see [`crate::guard`]) say why.

use crate::guard;
use crate::limits::Limits;
use std::io::{BufRead, BufReader, Read, Seek, Write};
use std::os::unix::process::ExitStatusExt;
use std::path::{Path, PathBuf};
use std::process::{ChildStdin, ChildStdout, Command, ExitStatus, Stdio};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{mpsc, Arc, Mutex};

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

/// A worker's answer line for a run's outcome.
pub fn answer<E: std::fmt::Display>(outcome: &Result<Vec<f64>, E>) -> String {
    match outcome {
        Ok(values) => {
            let values: Vec<String> = values.iter().map(|v| format!("{v:?}")).collect();
            format!("ok {}", values.join(","))
        }
        Err(e) => format!("error {}", e.to_string().replace('\n', "; ")),
    }
}

/// The outcome an answer line gives.
fn parse_answer(line: &str) -> Outcome {
    let line = line.trim_end();
    if let Some(why) = line.strip_prefix("error ") {
        return Err(why.to_string());
    }
    let Some(values) = line.strip_prefix("ok") else {
        return Err(format!("the worker answered `{line}`"));
    };
    let values = values.trim();
    if values.is_empty() {
        return Ok(Vec::new());
    }
    values
        .split(',')
        .map(|v| {
            v.parse::<f64>()
                .map_err(|_| format!("the worker answered `{line}`"))
        })
        .collect()
}

/// A running worker process: where to send values and read answers, and its standard error.
struct Worker {
    child: Arc<Mutex<std::process::Child>>,
    input: ChildStdin,
    output: BufReader<ChildStdout>,
    stderr: PathBuf,
}

impl Drop for Worker {
    fn drop(&mut self) {
        let mut child = guard::lock(&self.child);
        let _ = child.kill();
        let _ = child.wait();
        let _ = std::fs::remove_file(&self.stderr);
    }
}

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
        let spawned = AtomicUsize::new(0);
        let mut outcomes: Vec<Option<Outcome>> = vec![None; runs.len()];
        std::thread::scope(|scope| {
            let (tx, rx) = mpsc::channel();
            for _ in 0..workers.clamp(1, runs.len().max(1)) {
                let tx = tx.clone();
                let (next, spawned, exe, folder) = (&next, &spawned, &exe, &folder);
                scope.spawn(move || {
                    let mut worker: Option<Worker> = None;
                    loop {
                        let j = next.fetch_add(1, Ordering::SeqCst);
                        let Some(&(_, value)) = runs.get(j) else {
                            break;
                        };
                        if worker.is_none() {
                            let id = spawned.fetch_add(1, Ordering::SeqCst);
                            match self.spawn(exe, &folder.join(format!("worker-{id}.err"))) {
                                Ok(w) => worker = Some(w),
                                Err(e) => {
                                    let _ = tx.send((j, Err(e)));
                                    continue;
                                }
                            }
                        }
                        let Some(w) = worker.as_mut() else {
                            continue;
                        };
                        let outcome = ask(w, value);
                        if outcome.is_err() && !matches!(child_alive(w), Some(true)) {
                            // The worker died with that run: a fresh one takes the next.
                            worker = None;
                        }
                        if tx.send((j, outcome)).is_err() {
                            break;
                        }
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

    /// Starts a worker process, its standard error into `stderr`.
    fn spawn(&self, exe: &Path, stderr: &Path) -> Result<Worker, String> {
        let file = std::fs::File::create(stderr)
            .map_err(|e| format!("cannot create {}: {e}", stderr.display()))?;
        let mut command = Command::new(exe);
        command
            .arg("sweep-worker")
            .arg(self.system)
            .arg("--vary")
            .arg(self.variable)
            .args(self.limits.args())
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(file);
        for m in self.metrics {
            command.arg("--metric").arg(m);
        }
        let mut child = command
            .spawn()
            .map_err(|e| format!("cannot start a worker process: {e}"))?;
        let (Some(input), Some(output)) = (child.stdin.take(), child.stdout.take()) else {
            let _ = child.kill();
            return Err("a worker process without pipes".into());
        };
        let child = Arc::new(Mutex::new(child));
        guard::add_worker(child.clone());
        Ok(Worker {
            child,
            input,
            output: BufReader::new(output),
            stderr: stderr.to_path_buf(),
        })
    }
}

/// Whether the worker's process still runs (`None`: cannot tell).
fn child_alive(w: &Worker) -> Option<bool> {
    let mut child = guard::lock(&w.child);
    child.try_wait().ok().map(|s| s.is_none())
}

/// Sends `value` to the worker and reads its answer; if it ends instead, says why.
fn ask(w: &mut Worker, value: f64) -> Outcome {
    let said_before = std::fs::metadata(&w.stderr).map_or(0, |m| m.len());
    let mut line = String::new();
    let answered = writeln!(w.input, "{value:?}")
        .and_then(|()| w.input.flush())
        .and_then(|()| w.output.read_line(&mut line));
    if let Ok(n) = answered {
        if n > 0 {
            return parse_answer(&line);
        }
    }
    // No answer: the worker ended (or its pipes broke); wait for it to say how.
    let status = {
        let mut child = guard::lock(&w.child);
        child.wait()
    };
    let said = std::fs::File::open(&w.stderr)
        .and_then(|mut f| {
            f.seek(std::io::SeekFrom::Start(said_before))?;
            let mut text = String::new();
            f.read_to_string(&mut text)?;
            Ok(text)
        })
        .unwrap_or_default();
    match status {
        Ok(status) => Err(why(status, &said)),
        Err(e) => Err(format!("the worker process was lost: {e}")),
    }
}

/// Why a worker ended during a run: what it said last, or the signal that killed it or its
/// exit code.
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
            guard::signal_name(s)
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
    }

    #[test]
    fn answers_carry_the_metrics_exactly_or_the_error_on_one_line() {
        let ok: Result<Vec<f64>, String> = Ok(vec![0.1 + 0.2, f64::NAN, -1e-300]);
        let line = answer(&ok);
        assert_eq!(line, "ok 0.30000000000000004,NaN,-1e-300");
        let back = parse_answer(&line).unwrap();
        assert_eq!(back[0], 0.1 + 0.2);
        assert!(back[1].is_nan());
        assert_eq!(back[2], -1e-300);
        let failed: Result<Vec<f64>, String> = Err("a\nb".into());
        assert_eq!(answer(&failed), "error a; b");
        assert_eq!(parse_answer("error a; b\n"), Err("a; b".into()));
        assert_eq!(parse_answer("ok\n"), Ok(vec![]));
        assert!(parse_answer("ok 0.5,x").is_err());
        assert!(parse_answer("hello").is_err());
    }
}
