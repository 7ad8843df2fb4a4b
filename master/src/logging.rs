//! FMU log messages, forwarded to the master's log and kept per instance.
//!
//! rust-fmi's logger callback formats each FMU message (C variadic) and emits it through the
//! `log` crate with the instance name as the target. So that two instances with the same
//! name (say, `crane` in two parallel runs of a sweep) cannot be told apart by it, every
//! instance is created under a name of its own, `<name>#<n>` ([`LogKey`]). [`install`] sets
//! a logger that prints the messages as `[name] LEVEL: message` on standard error (warnings
//! and errors always, informational messages with `--verbose`) and keeps the most recent
//! ones of each live [`LogKey`], so an error report quotes what that very instance said
//! ([`LogKey::recent_messages`]).
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
}

static LOGGER: OnceLock<ForwardingLogger> = OnceLock::new();

/// The messages of the live instances, by their unique name.
type Kept = Mutex<HashMap<String, VecDeque<(log::Level, String)>>>;

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
            } else if record.level() <= log::Level::Warn && self.verbose {
                eprintln!("spurio: {}: {}", record.level(), record.args());
            }
            return;
        }
        let target = speaker.as_deref().unwrap_or(record.target());
        let text = record.args().to_string();
        if record.level() <= log::Level::Warn || self.verbose {
            eprintln!("[{}] {}: {}", display_name(target), record.level(), text);
        }
        if let Ok(mut kept) = kept().lock() {
            if let Some(messages) = kept.get_mut(target) {
                if messages.len() == KEPT {
                    messages.pop_front();
                }
                messages.push_back((record.level(), text));
            }
        }
    }

    fn flush(&self) {}
}

/// Installs the forwarding logger (once per process; later calls keep the first setting).
pub fn install(verbose: bool) {
    let logger = LOGGER.get_or_init(|| ForwardingLogger { verbose });
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

    /// The most recent messages this instance logged (oldest first), as `LEVEL: text`.
    pub fn recent_messages(&self) -> Vec<String> {
        let Ok(kept) = kept().lock() else {
            return Vec::new();
        };
        kept.get(&*self.unique)
            .map(|messages| {
                messages
                    .iter()
                    .map(|(level, text)| format!("{level}: {text}"))
                    .collect()
            })
            .unwrap_or_default()
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
        install(false);
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
        assert_eq!(a.recent_messages(), ["ERROR: x0 beyond the rail"]);
        assert_eq!(b.recent_messages(), ["ERROR: m_c must be positive"]);
        let name = a.instance_name().to_string();
        drop(a);
        assert!(!kept().lock().unwrap().contains_key(&name));
    }
}
