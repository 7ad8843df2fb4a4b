//! What contains a run's failures to that run: one session folder per process for every
//! unpacked FMU (removed at the end, on every error, on SIGINT/SIGTERM and when a watchdog
//! ends the process), the results written so far flushed before the process exits early,
//! the sweep's worker processes killed with it, and the per-call watchdog of `--call-timeout`.
//!
//! The session folder is `$TMPDIR/spurio-<pid>/`; the process points its own `TMPDIR` at it
//! (before any thread starts), so the engine's loader, the SSP import and every worker
//! process (which inherit it) unpack into it, and removing it removes everything a crashed
//! worker left behind.

use spurio_master::CallMonitor;
use std::path::PathBuf;
use std::process::Child;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, OnceLock};
use std::time::Duration;

/// Exit code of a run a watchdog ended: an FMI call did not return within `--call-timeout`
/// (GNU `timeout`'s code).
pub const EXIT_HUNG: i32 = 124;

/// A task to do before the process exits early: flush the results so far; it gives a note
/// for the user (where they are).
type Flush = Box<dyn FnMut() -> Option<String> + Send>;

struct Session {
    dir: PathBuf,
    flushes: Mutex<Vec<Flush>>,
    workers: Mutex<Vec<Arc<Mutex<Child>>>>,
    /// The supervised run (see [`supervise`]), which SIGINT/SIGTERM are passed on to.
    supervised: Mutex<Option<Arc<Mutex<Child>>>>,
}

/// Set in the environment of a supervised run (see [`supervise`]).
const SUPERVISED: &str = "SPURIO_SUPERVISED_RUN";

static SESSION: OnceLock<Session> = OnceLock::new();
static ENDING: AtomicBool = AtomicBool::new(false);

/// The data behind a mutex, also when another thread panicked holding it.
pub(crate) fn lock<T>(m: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    m.lock().unwrap_or_else(std::sync::PoisonError::into_inner)
}

/// Creates the session folder, points `TMPDIR` at it and ends the process cleanly on
/// SIGINT/SIGTERM (exit 130/143). Call it first, before any other thread starts.
pub fn start() -> anyhow::Result<()> {
    let parent = std::env::temp_dir();
    let dir = parent.join(format!("spurio-{}", std::process::id()));
    // A folder of that name is a leftover of a dead process with the same id.
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).map_err(|e| {
        anyhow::anyhow!(
            "cannot create a temporary folder in {}: {e}",
            parent.display()
        )
    })?;
    std::env::set_var("TMPDIR", &dir);
    let session = Session {
        dir,
        flushes: Mutex::new(Vec::new()),
        workers: Mutex::new(Vec::new()),
        supervised: Mutex::new(None),
    };
    if SESSION.set(session).is_err() {
        return Ok(());
    }
    use signal_hook::consts::{SIGINT, SIGTERM};
    let mut signals = signal_hook::iterator::Signals::new([SIGINT, SIGTERM])
        .map_err(|e| anyhow::anyhow!("cannot install the SIGINT/SIGTERM handler: {e}"))?;
    std::thread::spawn(move || {
        for signal in signals.forever() {
            // A supervisor passes the signal on and waits for the run to end by it.
            let supervised = SESSION.get().and_then(|s| lock(&s.supervised).clone());
            if let Some(child) = supervised {
                let pid = lock(&child).id();
                let passed = i32::try_from(pid).ok().is_some_and(|pid| {
                    nix::sys::signal::Signal::try_from(signal).is_ok_and(|sig| {
                        nix::sys::signal::kill(nix::unistd::Pid::from_raw(pid), sig).is_ok()
                    })
                });
                if !passed {
                    // The signal could not be passed on: end the run the hard way (its rows
                    // are cut back to whole ones by the supervisor).
                    let _ = lock(&child).kill();
                }
                continue;
            }
            let name = if signal == SIGINT {
                "SIGINT"
            } else {
                "SIGTERM"
            };
            abort(
                128 + signal,
                &format!("interrupted by {name}; the run ended early"),
            );
        }
    });
    Ok(())
}

/// The session folder (`None` before [`start`]).
pub fn folder() -> Option<PathBuf> {
    SESSION.get().map(|s| s.dir.clone())
}

/// Removes the session folder (the normal end of the process, successful or not). If the
/// process is being ended early ([`abort`]), waits for that to end it instead.
pub fn finish() {
    while ENDING.load(Ordering::SeqCst) {
        std::thread::sleep(Duration::from_millis(100));
    }
    if let Some(s) = SESSION.get() {
        let _ = std::fs::remove_dir_all(&s.dir);
    }
}

/// Registers `flush`, run before the process exits early.
pub fn on_early_exit(flush: impl FnMut() -> Option<String> + Send + 'static) {
    if let Some(s) = SESSION.get() {
        lock(&s.flushes).push(Box::new(flush));
    }
}

/// Registers a worker process, killed if this process exits early.
pub fn add_worker(child: Arc<Mutex<Child>>) {
    if let Some(s) = SESSION.get() {
        let mut workers = lock(&s.workers);
        workers.retain(|w| matches!(lock(w).try_wait(), Ok(None)));
        workers.push(child);
    }
}

/// Ends the process now with `code`: kills the workers, runs the flushes, removes the
/// session folder and says `message` (and what the flushes say) on standard error. Only the
/// first caller ends it; a second one (the watchdog and a signal at once) waits for that.
pub fn abort(code: i32, message: &str) -> ! {
    if ENDING.swap(true, Ordering::SeqCst) {
        loop {
            std::thread::sleep(Duration::from_secs(1));
        }
    }
    let mut notes = Vec::new();
    if let Some(s) = SESSION.get() {
        for w in lock(&s.workers).iter() {
            let _ = lock(w).kill();
        }
        for flush in lock(&s.flushes).iter_mut() {
            notes.extend(flush());
        }
        let _ = std::fs::remove_dir_all(&s.dir);
    }
    eprintln!("spurio: {message}");
    for note in notes {
        eprintln!("spurio: {note}");
    }
    std::process::exit(code)
}

/// A call monitor watched by a thread that ends the process ([`abort`] with [`EXIT_HUNG`])
/// when an FMI call has not returned after `timeout`, naming the instance, its FMU, the
/// call and the simulation time.
pub fn watchdog(timeout: Duration) -> Arc<CallMonitor> {
    let monitor = Arc::new(CallMonitor::default());
    let watched = monitor.clone();
    let tick = (timeout / 20).clamp(Duration::from_millis(1), Duration::from_millis(100));
    std::thread::spawn(move || loop {
        std::thread::sleep(tick);
        if let Some(call) = watched.current() {
            if call.since.elapsed() >= timeout {
                abort(
                    EXIT_HUNG,
                    &format!(
                        "{call} did not return within {} s (--call-timeout); the run ended early",
                        timeout.as_secs_f64()
                    ),
                );
            }
        }
    });
    monitor
}

/// Whether this process is a run under a supervisor.
pub fn is_supervised() -> bool {
    std::env::var_os(SUPERVISED).is_some()
}

/// Runs this same command line in a child process and waits for it, so that an FMU that
/// kills the process (a segfault, an abort) cannot leave the unpacked FMUs behind or a cut
/// row at the end of `csv`: the child's exit code is passed on; if a signal killed it, the
/// results file is cut back to its last whole row, the session folder (holding the child's)
/// removed, and the exit code is 128 + the signal. SIGINT and SIGTERM are passed on to the
/// child, which ends by them cleanly.
pub fn supervise(csv: Option<&std::path::Path>) -> anyhow::Result<i32> {
    use std::os::unix::process::ExitStatusExt;
    let exe = std::env::current_exe()
        .map_err(|e| anyhow::anyhow!("cannot locate the spurio executable: {e}"))?;
    let child = std::process::Command::new(exe)
        .args(std::env::args_os().skip(1))
        .env(SUPERVISED, "1")
        .spawn()
        .map_err(|e| anyhow::anyhow!("cannot start the run's process: {e}"))?;
    let child = Arc::new(Mutex::new(child));
    if let Some(s) = SESSION.get() {
        *lock(&s.supervised) = Some(child.clone());
    }
    // Polled, so that the signal thread can reach the child in between.
    let status = loop {
        match lock(&child).try_wait() {
            Ok(Some(status)) => break status,
            Ok(None) => std::thread::sleep(Duration::from_millis(10)),
            Err(e) => anyhow::bail!("cannot wait for the run's process: {e}"),
        }
    };
    if let Some(s) = SESSION.get() {
        *lock(&s.supervised) = None;
    }
    let Some(signal) = status.signal() else {
        return Ok(status.code().unwrap_or(1));
    };
    let mut message = format!(
        "the run crashed: its process was killed by signal {signal} ({}), most likely by an \
         FMU; the run ended early",
        signal_name(signal)
    );
    if let Some(path) = csv {
        message.push_str(&match whole_rows(path) {
            Ok(()) => format!("; the rows recorded before are in {}", path.display()),
            Err(e) => format!("; cannot cut {} back to whole rows: {e}", path.display()),
        });
    }
    eprintln!("spurio: {message}");
    Ok(128 + signal)
}

/// Cuts `path` back to its last complete line.
fn whole_rows(path: &std::path::Path) -> std::io::Result<()> {
    let bytes = std::fs::read(path)?;
    let keep = bytes.iter().rposition(|&b| b == b'\n').map_or(0, |i| i + 1);
    if keep < bytes.len() {
        std::fs::OpenOptions::new()
            .write(true)
            .open(path)?
            .set_len(keep as u64)?;
    }
    Ok(())
}
/// The name of a signal a process may die of.
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
