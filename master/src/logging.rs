//! FMU log messages, forwarded to the master's log and kept per instance.
//!
//! rust-fmi's logger callback formats each FMU message (C variadic) and emits it through the
//! `log` crate with the instance name as the target. So that two instances with the same
//! name (say, `crane` in two parallel runs of a sweep) cannot be told apart by it, every
//! instance is created under a name of its own, `<name>#<n>` ([`LogKey`]). [`install`] sets
//! a logger that prints the messages as `[name] LEVEL: message` on standard error (warnings
//! and errors always, informational messages with `--verbose`) and keeps the most recent
//! ones of each live [`LogKey`], so an error report says what that very instance said
//! ([`LogKey::failure_note`]): it quotes the messages the user has not seen, and points to
//! those printed already instead of repeating them (each message is said once).
//!
//! rust-fmi's FMI 3.0 logger does not pass the instance (its callback gets a null instance
//! environment and emits the log category as the target, with module path `fmu`): every call
//! into an FMI 3.0 instance runs inside [`speaking`], so its messages are kept under the key
//! of the instance the calling thread is in.

use std::collections::{HashMap, VecDeque};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Mutex, OnceLock};

/// Messages kept per instance.
const KEPT: usize = 100;

struct ForwardingLogger {
    verbose: bool,
    /// Whether messages are printed on standard error at all (false: only kept, for a
    /// library inside an FMU whose errors quote them, [`install_quiet`]).
    print: bool,
    /// Whether what is printed on standard error reaches the user ([`install`]), or not
    /// ([`install_unseen`]): only messages the user has seen are left out of a quote.
    seen: bool,
}

static LOGGER: OnceLock<ForwardingLogger> = OnceLock::new();

/// One message an instance logged.
struct Message {
    level: log::Level,
    text: String,
    /// Printed on a standard error the user sees.
    shown: bool,
}

/// The messages of the live instances, by their unique name.
type Kept = Mutex<HashMap<String, VecDeque<Message>>>;

fn kept() -> &'static Kept {
    static KEPT_MESSAGES: OnceLock<Kept> = OnceLock::new();
    KEPT_MESSAGES.get_or_init(|| Mutex::new(HashMap::new()))
}

/// The name the user gave an instance, from the unique name it was created under.
fn display_name(target: &str) -> &str {
    match target.rsplit_once('#') {
        Some((name, n)) if !n.is_empty() && n.bytes().all(|b| b.is_ascii_digit()) => name,
        _ => target,
    }
}

thread_local! {
    /// The unique name of the instance this thread is calling into, if any.
    static SPEAKING: std::cell::RefCell<Option<std::sync::Arc<str>>> = const { std::cell::RefCell::new(None) };
}

/// Runs `call` (a call into the instance whose key is `key`) with the messages logged
/// meanwhile on this thread attributed to that instance.
pub(crate) fn speaking<T>(key: &LogKey, call: impl FnOnce() -> T) -> T {
    let before = SPEAKING.with(|s| s.replace(Some(std::sync::Arc::clone(&key.unique))));
    let result = call();
    SPEAKING.with(|s| *s.borrow_mut() = before);
    result
}

impl log::Log for ForwardingLogger {
    fn enabled(&self, metadata: &log::Metadata) -> bool {
        metadata.level() <= log::Level::Info
    }

    fn log(&self, record: &log::Record) {
        // Only the FMUs' messages: rust-fmi marks them with module path "logger" (FMI 2.0,
        // the target is the instance) or "fmu" (FMI 3.0, the instance is the one speaking).
        let speaker = match record.module_path() {
            Some("fmu") => SPEAKING.with(|s| s.borrow().as_deref().map(str::to_string)),
            _ => None,
        };
        if record.module_path() != Some("logger") && speaker.is_none() {
            // the engine's own notes (events in a system) with `--verbose`, as `spurio: …`
            let ours = record.target().starts_with("spurio_master");
            if self.verbose && ours && record.level() == log::Level::Info {
                eprintln!("spurio: {}", record.args());
            } else if record.level() <= log::Level::Warn && self.verbose && self.print {
                eprintln!("spurio: {}: {}", record.level(), record.args());
            }
            return;
        }
        let target = speaker.as_deref().unwrap_or(record.target());
        let text = record.args().to_string();
        let printed = self.print && (record.level() <= log::Level::Warn || self.verbose);
        if printed {
            eprintln!("[{}] {}: {}", display_name(target), record.level(), text);
        }
        if let Ok(mut kept) = kept().lock() {
            if let Some(messages) = kept.get_mut(target) {
                if messages.len() == KEPT {
                    messages.pop_front();
                }
                messages.push_back(Message {
                    level: record.level(),
                    text,
                    shown: printed && self.seen,
                });
            }
        }
    }

    fn flush(&self) {}
}

/// Installs the forwarding logger (once per process; later calls keep the first setting).
/// Standard error is taken to reach the user: an error report points to the messages printed
/// there instead of quoting them again ([`LogKey::failure_note`]).
pub fn install(verbose: bool) {
    install_logger(ForwardingLogger {
        verbose,
        print: true,
        seen: true,
    });
}

/// [`install`] for a process whose standard error the user does not see (a sweep's worker
/// writes it to a file read only if the worker crashes): the messages are printed all the
/// same, and an error report quotes them.
pub fn install_unseen(verbose: bool) {
    install_logger(ForwardingLogger {
        verbose,
        print: true,
        seen: false,
    });
}

/// [`install`] for a library that imports FMUs inside an FMU of its own (an estimator FMU
/// carrying its plant): nothing is printed (the process's standard error is its host's);
/// each instance's messages are kept, and an error report quotes them
/// ([`LogKey::failure_note`]), so the outer FMU's error says what the inner one said.
pub fn install_quiet() {
    install_logger(ForwardingLogger {
        verbose: false,
        print: false,
        seen: false,
    });
}

fn install_logger(logger: ForwardingLogger) {
    let logger = LOGGER.get_or_init(|| logger);
    if log::set_logger(logger).is_ok() {
        log::set_max_level(log::LevelFilter::Info);
    }
}

/// The unique name one instance is created under: its messages are kept under it while the
/// key lives, and dropped with it.
#[derive(Debug)]
pub struct LogKey {
    unique: std::sync::Arc<str>,
}

impl LogKey {
    /// A new key for an instance the user calls `name`.
    pub fn new(name: &str) -> Self {
        static NEXT: AtomicU64 = AtomicU64::new(1);
        let unique = format!("{name}#{}", NEXT.fetch_add(1, Ordering::Relaxed));
        if let Ok(mut kept) = kept().lock() {
            kept.insert(unique.clone(), VecDeque::new());
        }
        Self {
            unique: unique.into(),
        }
    }

    /// The name to give `fmi2Instantiate`.
    pub fn instance_name(&self) -> &str {
        &self.unique
    }

    /// What an error report of this instance adds about what it logged, each message said
    /// once: the recent messages the user has not seen (oldest first, as `LEVEL: text`)
    /// quoted, `the FMU logged: …`; those printed on standard error already are pointed to,
    /// not repeated. `None` when it logged nothing.
    pub fn failure_note(&self) -> Option<String> {
        let kept = kept().lock().ok()?;
        let messages = kept.get(&*self.unique)?;
        let unseen: Vec<String> = messages
            .iter()
            .filter(|m| !m.shown)
            .map(|m| format!("{}: {}", m.level, m.text))
            .collect();
        let shown = messages.iter().filter(|m| m.shown).count();
        match (unseen.is_empty(), shown) {
            (true, 0) => None,
            (true, 1) => Some("the FMU's message is printed above".to_string()),
            (true, _) => Some("the FMU's messages are printed above".to_string()),
            (false, 0) => Some(format!("the FMU logged: {}", unseen.join("; "))),
            (false, _) => Some(format!(
                "the FMU logged: {}, beside what is printed above",
                unseen.join("; ")
            )),
        }
    }

    /// The end of the error of a failed call `error` of this instance: what it logged
    /// ([`Self::failure_note`]) or, when it logged nothing, the error itself.
    pub(crate) fn failed_call(&self, error: impl std::fmt::Display) -> String {
        match self.failure_note() {
            Some(note) => format!(": {note}"),
            None => format!(" ({error})"),
        }
    }
}

impl Drop for LogKey {
    fn drop(&mut self) {
        if let Ok(mut kept) = kept().lock() {
            kept.remove(&*self.unique);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn messages_are_kept_per_key_and_printed_under_the_users_name() {
        // Unseen: the test harness captures standard error, so the notes quote the messages.
        install_unseen(false);
        let a = LogKey::new("crane");
        let b = LogKey::new("crane");
        assert_ne!(a.instance_name(), b.instance_name());
        assert_eq!(display_name(a.instance_name()), "crane");
        assert_eq!(display_name("odd#name"), "odd#name");
        let emit = |target: &str, text: &str| {
            log::logger().log(
                &log::Record::builder()
                    .target(target)
                    .module_path_static(Some("logger"))
                    .level(log::Level::Error)
                    .args(format_args!("{text}"))
                    .build(),
            )
        };
        emit(a.instance_name(), "x0 beyond the rail");
        emit(b.instance_name(), "m_c must be positive");
        emit("crane", "not kept: no key");
        assert_eq!(
            a.failure_note().as_deref(),
            Some("the FMU logged: ERROR: x0 beyond the rail")
        );
        assert_eq!(
            b.failed_call("no such call"),
            ": the FMU logged: ERROR: m_c must be positive"
        );
        assert_eq!(
            LogKey::new("quiet").failed_call("it failed"),
            " (it failed)"
        );
        let name = a.instance_name().to_string();
        drop(a);
        assert!(!kept().lock().unwrap().contains_key(&name));
    }
}
