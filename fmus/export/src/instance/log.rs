//! The instance's logger: what reaches the master's callback (through a front's
//! [`LogSink`]) and what debug logging filters out.

use crate::model::EVENTS;
use crate::types::Status;

/// Where log messages go: the master's callback (a front's callback sink) or memory (tests).
pub trait LogSink {
    /// Delivers one message.
    fn deliver(&self, instance: &str, status: Status, category: &str, text: &str);
}

/// The instance's logger: filters by `loggingOn` and categories, then hands to the sink.
/// Warnings, discards, errors and fatals are always delivered: a user must learn why a call
/// failed even with debug logging off.
pub struct Logger {
    sink: Box<dyn LogSink>,
    instance_name: String,
    logging_on: bool,
    /// Enabled categories; empty means all.
    categories: Vec<String>,
    /// Whether model events (`logEvents`, [`crate::model::Context::log_event`]) are delivered: kept with
    /// `logging_on` and `categories`, so a model call asks no question of the logger.
    pub(super) events: bool,
}

impl Logger {
    /// A logger for `instance_name` writing to `sink`.
    pub fn new(instance_name: &str, sink: Box<dyn LogSink>, logging_on: bool) -> Self {
        Self {
            sink,
            instance_name: instance_name.to_string(),
            logging_on,
            categories: Vec::new(),
            events: logging_on,
        }
    }
    /// Debug logging on or off, for `categories` (empty: all).
    pub fn configure(&mut self, logging_on: bool, categories: &[String]) {
        self.logging_on = logging_on;
        self.categories = categories.to_vec();
        self.events = self.enabled(Status::Ok, EVENTS);
    }
    /// Whether a message with `status` under `category` is delivered: always for warnings
    /// and worse, for `Ok` when debug logging is on and the category enabled.
    pub fn enabled(&self, status: Status, category: &str) -> bool {
        status != Status::Ok
            || (self.logging_on
                && (self.categories.is_empty()
                    || self
                        .categories
                        .iter()
                        .any(|c| c == category || c == "logAll")))
    }
    /// Logs `text` with `status` under `category`.
    pub fn log(&self, status: Status, category: &str, text: &str) {
        if self.enabled(status, category) {
            self.sink
                .deliver(&self.instance_name, status, category, text);
        }
    }
    /// Logs an error.
    pub fn error(&self, text: &str) {
        self.log(Status::Error, Status::Error.category(), text);
    }
    /// The instance name.
    pub fn instance_name(&self) -> &str {
        &self.instance_name
    }
}
