//! Where a simulation notes each FMI call it enters and leaves, so that a watchdog on another
//! thread can name a call that does not return (the instance, its FMU, the call, the time);
//! what to do then is the caller's (the CLI ends the process, keeping the results so far).

use std::sync::Mutex;
use std::time::Instant;

/// The FMI call in progress, for a watchdog on another thread: which instance, which call,
/// at which simulation time, since when.
#[derive(Debug, Clone, PartialEq)]
pub struct CallInProgress {
    pub instance: String,
    pub file: String,
    pub call: &'static str,
    pub time: f64,
    pub since: Instant,
}

impl std::fmt::Display for CallInProgress {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "instance `{}` ({}): {} at t = {}",
            self.instance, self.file, self.call, self.time
        )
    }
}

/// Where a [`crate::Simulation`] made with [`crate::Simulation::with_monitor`] notes each FMI call it
/// enters and leaves, so that a watchdog thread can tell a call that does not return
/// ([`CallMonitor::current`]) and name it. The loop pays one uncontended lock and one clock
/// read per call.
#[derive(Debug, Default)]
pub struct CallMonitor {
    /// (instance name, FMU file) by instance index.
    instances: Mutex<Vec<(String, String)>>,
    /// (instance index, call, time, since).
    current: Mutex<Option<(usize, &'static str, f64, Instant)>>,
}

impl CallMonitor {
    /// The call in progress, if any.
    pub fn current(&self) -> Option<CallInProgress> {
        let (i, call, time, since) = (*lock(&self.current))?;
        let (instance, file) = lock(&self.instances).get(i).cloned().unwrap_or_default();
        Some(CallInProgress {
            instance,
            file,
            call,
            time,
            since,
        })
    }

    /// Names the instances by index: (instance name, FMU file).
    pub(crate) fn name_instances(&self, instances: Vec<(String, String)>) {
        *lock(&self.instances) = instances;
    }

    fn enter(&self, member: usize, call: &'static str, time: f64) {
        *lock(&self.current) = Some((member, call, time, Instant::now()));
    }

    fn leave(&self) {
        *lock(&self.current) = None;
    }
}

/// The data behind a mutex, also when another thread panicked holding it (the data here is
/// plain values, valid at any time).
fn lock<T>(m: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    m.lock().unwrap_or_else(std::sync::PoisonError::into_inner)
}

/// Runs `f` as FMI call `call` of member `member` at `time`, noted in `monitor` (if any).
#[inline(always)]
pub(crate) fn watched<T>(
    monitor: Option<&CallMonitor>,
    member: usize,
    call: &'static str,
    time: f64,
    f: impl FnOnce() -> T,
) -> T {
    match monitor {
        None => f(),
        Some(m) => {
            m.enter(member, call, time);
            let out = f();
            m.leave();
            out
        }
    }
}
