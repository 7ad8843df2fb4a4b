//! The panic guard of every C entry point: `catch_unwind` around each call (a panic never
//! crosses the ABI; the instance is then `Fatal`), the panic hook and the call marker.
//!
//! **Panic text goes to the FMI logger only.** A panic hook (installed once, by the first
//! call) captures the message and location of a panic raised inside one of the FMU calls on
//! this thread and prints nothing; the catching site logs it as `fmi2Fatal`/`fmi3Fatal`. Panics
//! outside an FMU call go to the hook that was there before. An FMU `cdylib` links its own
//! `std`, so the hook is the FMU's and never the importing tool's.
//!
//! How the hook knows that its thread is inside a call: a call on an instance marks the
//! instance's [`CallMarker`] with the identity of its thread (the thread pointer register,
//! read without a thread-local access: a `cdylib`'s thread-locals cost a `__tls_get_addr`
//! call each) and clears it on return; the hook, which runs only when a panic happens, looks
//! for its own thread among the markers of the live instances. The calls that have no
//! instance yet (`fmi2Instantiate`, the queries: [`guarded`]) set a thread-local flag instead.
//!
//! Imports nothing of the crate: the fronts stand on it.

use std::cell::{Cell, RefCell};
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Arc, Mutex, Once};

pub(crate) fn panic_message(payload: &(dyn std::any::Any + Send)) -> String {
    if let Some(s) = payload.downcast_ref::<&str>() {
        (*s).to_string()
    } else if let Some(s) = payload.downcast_ref::<String>() {
        s.clone()
    } else {
        "panic".to_string()
    }
}

thread_local! {
    /// This thread is inside an FMU call ([`guarded`]).
    static IN_CALL: Cell<bool> = const { Cell::new(false) };
    /// The text of the last panic raised inside an FMU call on this thread.
    static PANIC_TEXT: RefCell<Option<String>> = const { RefCell::new(None) };
}

static HOOK: Once = Once::new();

/// Which thread runs a call on one instance (0: none): the `thread_identity` of the caller
/// while `guarded_call` runs the call. Shared with `MARKERS`, which the panic hook reads.
#[derive(Debug, Default)]
pub struct CallMarker(AtomicUsize);

/// The markers of the live instances (added when a handle is made, removed when it is freed).
static MARKERS: Mutex<Vec<Arc<CallMarker>>> = Mutex::new(Vec::new());

impl CallMarker {
    /// A marker, registered for the panic hook until [`CallMarker::unregister`].
    pub(crate) fn registered() -> Arc<Self> {
        let marker = Arc::new(Self::default());
        MARKERS
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .push(Arc::clone(&marker));
        marker
    }

    /// Removes the marker from the registry.
    pub(crate) fn unregister(marker: &Arc<Self>) {
        MARKERS
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .retain(|m| !Arc::ptr_eq(m, marker));
    }

    /// Whether a call on some live instance runs on thread `me` (the hook's question).
    fn any_runs_on(me: usize) -> bool {
        MARKERS
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .iter()
            .any(|m| m.0.load(Ordering::Relaxed) == me)
    }
}

/// Whether this thread is inside an FMU call (the panic hook's question).
fn inside_call() -> bool {
    IN_CALL.with(Cell::get) || CallMarker::any_runs_on(thread_identity())
}

/// A number that identifies the running thread among the live ones, never 0: the thread
/// pointer (x86-64 Linux `fs:0`, x86-64 Windows `gs:[0x30]`, the self pointers of the TCB and
/// the TEB; AArch64 `tpidr_el0`), read with one instruction; elsewhere the address of a
/// thread-local.
#[inline(always)]
fn thread_identity() -> usize {
    #[cfg(all(target_arch = "x86_64", target_os = "linux"))]
    {
        let tp: usize;
        // SAFETY: the x86-64 System V TLS ABI keeps the thread pointer at fs:0 on every
        // thread; the read has no other effect.
        unsafe {
            std::arch::asm!("mov {}, fs:0", out(reg) tp, options(nostack, readonly, preserves_flags))
        };
        tp
    }
    #[cfg(all(target_arch = "x86_64", target_os = "windows"))]
    {
        let tp: usize;
        // SAFETY: on x86-64 Windows gs:[0x30] is the running thread's TEB self pointer; the
        // read has no other effect.
        unsafe {
            std::arch::asm!("mov {}, gs:[0x30]", out(reg) tp, options(nostack, readonly, preserves_flags))
        };
        tp
    }
    #[cfg(all(target_arch = "aarch64", target_os = "linux"))]
    {
        let tp: usize;
        // SAFETY: tpidr_el0 holds the running thread's thread pointer; reading it has no
        // other effect.
        unsafe {
            std::arch::asm!("mrs {}, tpidr_el0", out(reg) tp, options(nostack, nomem, preserves_flags))
        };
        tp
    }
    #[cfg(not(any(
        all(
            target_arch = "x86_64",
            any(target_os = "linux", target_os = "windows")
        ),
        all(target_arch = "aarch64", target_os = "linux")
    )))]
    {
        thread_local! {
            static ANCHOR: u8 = const { 0 };
        }
        ANCHOR.with(|a| a as *const u8 as usize)
    }
}

/// Installs (once) the hook that keeps panics inside FMU calls off stderr (module docs).
/// Called by [`guarded`] and, for the calls on an instance ([`guarded_call`]), once when the
/// instance handle is made (`Slot::into_handle`).
pub(crate) fn install_panic_hook() {
    HOOK.call_once(|| {
        let previous = std::panic::take_hook();
        std::panic::set_hook(Box::new(move |info| {
            if inside_call() {
                let mut text = panic_message(info.payload());
                if let Some(location) = info.location() {
                    text.push_str(&format!(" (at {location})"));
                }
                PANIC_TEXT.with(|t| *t.borrow_mut() = Some(text));
            } else {
                previous(info);
            }
        }));
    });
}

/// Runs `body` as an FMU call: panics are caught and their text (message and location)
/// returned instead of printed.
pub fn guarded<T>(body: impl FnOnce() -> T) -> Result<T, String> {
    install_panic_hook();
    guarded_flagged(body).map_err(|payload| panic_text(payload.as_ref()))
}

/// What a caught panic carries; [`panic_text`] turns it into the message to log.
pub(crate) type Payload = Box<dyn std::any::Any + Send>;

/// [`guarded`] once the hook is installed (without the thread-local flag).
#[inline(always)]
fn guarded_flagged<T>(body: impl FnOnce() -> T) -> Result<T, Payload> {
    let flag: *const Cell<bool> = IN_CALL.with(|flag| flag as *const Cell<bool>);
    // SAFETY: the flag is this thread's, alive as long as the thread, which runs this call;
    // nothing else borrows it across the call (a `Cell`: no reference is handed out).
    let outer = unsafe { (*flag).replace(true) };
    let result = catch_unwind(AssertUnwindSafe(body));
    // SAFETY: as above.
    unsafe { (*flag).set(outer) };
    result
}

/// The path of every call on an instance, whose handle installed the hook: `marker` (the
/// instance's) holds this thread's identity while `body` runs, then what it held before (a
/// load and two stores, no thread-local access), and the unwinding landing pad; the panic's
/// text is fetched on the cold path ([`panic_text`]).
#[inline(always)]
pub(crate) fn guarded_call<T>(marker: &CallMarker, body: impl FnOnce() -> T) -> Result<T, Payload> {
    let outer = marker.0.load(Ordering::Relaxed);
    marker.0.store(thread_identity(), Ordering::Relaxed);
    let result = catch_unwind(AssertUnwindSafe(body));
    marker.0.store(outer, Ordering::Relaxed);
    result
}

/// The text of the panic just caught: the one the hook captured (message and location), or
/// the payload's.
#[cold]
#[inline(never)]
pub(crate) fn panic_text(payload: &(dyn std::any::Any + Send)) -> String {
    PANIC_TEXT
        .with(|t| t.borrow_mut().take())
        .unwrap_or_else(|| panic_message(payload))
}

#[cfg(test)]
mod marker_tests {
    use super::*;
    use std::sync::mpsc;

    #[test]
    fn a_thread_is_inside_a_call_exactly_while_it_runs_one() {
        install_panic_hook();
        let marker = CallMarker::registered();
        assert!(!inside_call());
        assert_eq!(guarded_call(&marker, inside_call).ok(), Some(true));
        assert!(!inside_call());
        // a nested call on the same marker leaves it marked until the outer one returns
        let nested = guarded_call(&marker, || {
            let inner = guarded_call(&marker, inside_call).ok();
            (inner, inside_call())
        });
        assert_eq!(nested.ok(), Some((Some(true), true)));
        // a panic caught by the call clears the mark too
        assert!(guarded_call(&marker, || panic!("caught")).is_err());
        assert!(!inside_call());
        assert!(panic_text(&()).contains("caught"));
        // another thread inside a call on another instance: it is, this one is not
        let other = CallMarker::registered();
        let (entered, wait) = (mpsc::channel(), mpsc::channel::<()>());
        let worker = {
            let other = Arc::clone(&other);
            let (entered, wait) = (entered.0, wait.1);
            std::thread::spawn(move || {
                guarded_call(&other, || {
                    entered.send((thread_identity(), inside_call())).unwrap();
                    wait.recv().unwrap();
                })
                .is_ok()
            })
        };
        let (identity, inside) = entered.1.recv().unwrap();
        assert!(inside);
        assert_ne!(identity, thread_identity());
        assert_ne!(identity, 0);
        assert!(!inside_call(), "the other thread's call is not this one's");
        wait.0.send(()).unwrap();
        assert!(worker.join().unwrap());
        // an unregistered marker is not looked at
        CallMarker::unregister(&marker);
        assert!(guarded_call(&marker, inside_call).is_ok_and(|inside| !inside));
        CallMarker::unregister(&other);
    }
}
