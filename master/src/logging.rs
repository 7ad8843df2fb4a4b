//! FMU log messages, forwarded to the master's log with the instance name.
//!
//! rust-fmi's logger callback formats each FMU message (C variadic) and emits it through the
//! `log` crate with the instance name as the target. [`install`] sets a logger that prints
//! those messages as `[instance] LEVEL: message` on standard error (warnings and errors always,
//! informational messages with `--verbose`) and keeps the most recent ones, so an error report
//! can quote what an FMU said about it ([`recent_messages`]).

use std::collections::VecDeque;
use std::sync::{Mutex, OnceLock};

const KEPT: usize = 500;

struct ForwardingLogger {
    verbose: bool,
    recent: Mutex<VecDeque<(String, log::Level, String)>>,
}

static LOGGER: OnceLock<ForwardingLogger> = OnceLock::new();

impl log::Log for ForwardingLogger {
    fn enabled(&self, metadata: &log::Metadata) -> bool {
        metadata.level() <= log::Level::Info
    }

    fn log(&self, record: &log::Record) {
        // Only the FMUs' messages: rust-fmi marks them with module path "logger".
        if record.module_path() != Some("logger") {
            if record.level() <= log::Level::Warn && self.verbose {
                eprintln!("spurio: {}: {}", record.level(), record.args());
            }
            return;
        }
        let text = record.args().to_string();
        if record.level() <= log::Level::Warn || self.verbose {
            eprintln!("[{}] {}: {}", record.target(), record.level(), text);
        }
        if let Ok(mut recent) = self.recent.lock() {
            if recent.len() == KEPT {
                recent.pop_front();
            }
            recent.push_back((record.target().to_string(), record.level(), text));
        }
    }

    fn flush(&self) {}
}

/// Installs the forwarding logger (once per process; later calls keep the first setting).
pub fn install(verbose: bool) {
    let logger = LOGGER.get_or_init(|| ForwardingLogger {
        verbose,
        recent: Mutex::new(VecDeque::new()),
    });
    if log::set_logger(logger).is_ok() {
        log::set_max_level(log::LevelFilter::Info);
    }
}

/// The most recent messages that instance `name` logged (oldest first).
pub fn recent_messages(name: &str) -> Vec<String> {
    let Some(logger) = LOGGER.get() else {
        return Vec::new();
    };
    let Ok(recent) = logger.recent.lock() else {
        return Vec::new();
    };
    recent
        .iter()
        .filter(|(target, _, _)| target == name)
        .map(|(_, level, text)| format!("{level}: {text}"))
        .collect()
}
