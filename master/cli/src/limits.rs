//! The bounds of `run` and `sweep`: the loader's size limits, the most steps a run may take
//! and the per-call watchdog, as flags; and the parsers of their values.

use anyhow::{bail, Result};
use spurio_master::fmu::{LoadLimits, LoadOptions};
use spurio_master::System;
use std::time::Duration;

/// The flags every command that runs a system takes.
#[derive(clap::Args, Clone, Debug)]
pub struct Limits {
    /// Refuse an FMU whose archive unpacks to more than SIZE, or an SSP whose FMUs do
    /// together (bytes, or with a K, M or G suffix: powers of 1024).
    #[arg(long, value_name = "SIZE", default_value = "2G", value_parser = parse_size)]
    pub max_unpacked: u64,
    /// Refuse an FMU whose modelDescription.xml, an SSP whose SystemStructure.ssd, or a
    /// system file larger than SIZE (read no further than that).
    #[arg(long, value_name = "SIZE", default_value = "64M", value_parser = parse_size)]
    pub max_model_description: u64,
    /// Refuse an FMU archive of more than N entries.
    #[arg(long, value_name = "N", default_value_t = 10_000)]
    pub max_entries: usize,
    /// Refuse a run of more than N base steps ((stop_time − start_time) / step_size).
    #[arg(long, value_name = "N", default_value_t = 100_000_000)]
    pub max_steps: u64,
    /// End a run whose FMI call has not returned after SECONDS, naming the instance and the
    /// call (`run`: exit code 124, the rows so far kept; `sweep`: that run fails).
    #[arg(long, value_name = "SECONDS", value_parser = parse_seconds)]
    pub call_timeout: Option<Duration>,
}

impl Limits {
    /// The loader's options (its temporary folder: the session's, through `TMPDIR`).
    pub fn load_options(&self) -> LoadOptions {
        LoadOptions {
            limits: LoadLimits {
                max_unpacked: self.max_unpacked,
                max_model_description: self.max_model_description,
                max_entries: self.max_entries,
            },
            temp_dir: None,
        }
    }

    /// These flags as arguments, for a worker process.
    pub fn args(&self) -> Vec<String> {
        let mut args = vec![
            format!("--max-unpacked={}", self.max_unpacked),
            format!("--max-model-description={}", self.max_model_description),
            format!("--max-entries={}", self.max_entries),
            format!("--max-steps={}", self.max_steps),
        ];
        if let Some(t) = self.call_timeout {
            args.push(format!("--call-timeout={}", t.as_secs_f64()));
        }
        args
    }

    /// Refuses a system whose run takes more than `--max-steps` steps.
    pub fn check_steps(&self, system: &System) -> Result<()> {
        let steps = system.plan().steps;
        if steps > self.max_steps {
            let ratio = (system.stop_time() - system.start_time()) / system.step_size();
            let count = if ratio < 1e15 {
                steps.to_string()
            } else if ratio.is_finite() {
                format!("{ratio:e}")
            } else {
                "infinitely many".to_string()
            };
            bail!(
                "the run would take {count} steps ((stop_time {:?} − start_time {:?}) / step_size {:?}), \
                 more than --max-steps {}; give a larger --max-steps to run it anyway",
                system.stop_time(),
                system.start_time(),
                system.step_size(),
                self.max_steps
            );
        }
        Ok(())
    }
}

/// `1024`, `64K`, `64M`, `2G` (powers of 1024).
pub fn parse_size(text: &str) -> Result<u64, String> {
    let t = text.trim();
    let (digits, shift) = match t.char_indices().last() {
        Some((i, 'K' | 'k')) => (&t[..i], 10),
        Some((i, 'M' | 'm')) => (&t[..i], 20),
        Some((i, 'G' | 'g')) => (&t[..i], 30),
        _ => (t, 0),
    };
    let n: u64 = digits
        .parse()
        .map_err(|_| format!("`{text}` is not a size (bytes, or with K, M or G)"))?;
    n.checked_mul(1 << shift)
        .ok_or_else(|| format!("`{text}` is too large"))
}

/// A positive, finite number.
pub fn parse_positive(text: &str) -> Result<f64, String> {
    match text.trim().parse::<f64>() {
        Ok(x) if x.is_finite() && x > 0.0 => Ok(x),
        _ => Err(format!("`{text}` is not a positive number")),
    }
}

/// A positive duration in seconds.
pub fn parse_seconds(text: &str) -> Result<Duration, String> {
    let s = parse_positive(text)?;
    Duration::try_from_secs_f64(s).map_err(|e| format!("`{text}`: {e}"))
}

/// The number of concurrent workers for `--threads` (0: one per core), capped at four per
/// core with a message.
pub fn workers(threads: usize) -> usize {
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    let bound = 4 * cores;
    match threads {
        0 => cores,
        t if t > bound => {
            eprintln!("spurio: --threads {t} capped at {bound} (4 per core, {cores} cores here)");
            bound
        }
        t => t,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::Parser;

    #[derive(Parser)]
    struct Flags {
        #[command(flatten)]
        limits: Limits,
    }

    #[test]
    fn the_default_flags_are_the_loaders_default_limits_and_round_trip_to_a_worker() {
        let flags = Flags::parse_from(["spurio"]);
        assert_eq!(flags.limits.load_options(), LoadOptions::default());
        assert_eq!(flags.limits.max_steps, 100_000_000);
        let again = Flags::parse_from(
            std::iter::once("spurio".to_string()).chain(
                Flags::parse_from(["x", "--call-timeout", "2.5", "--max-unpacked", "3K"])
                    .limits
                    .args(),
            ),
        );
        assert_eq!(again.limits.call_timeout, Some(Duration::from_millis(2500)));
        assert_eq!(again.limits.max_unpacked, 3072);
    }

    #[test]
    fn sizes_and_positive_numbers_parse_and_refuse() {
        assert_eq!(parse_size("64M"), Ok(64 << 20));
        assert_eq!(parse_size("2g"), Ok(2 << 30));
        assert_eq!(parse_size("1000"), Ok(1000));
        assert!(parse_size("-1").is_err());
        assert!(parse_size("99999999999999G")
            .unwrap_err()
            .contains("too large"));
        for bad in ["0", "-1", "nan", "inf", "x"] {
            assert_eq!(
                parse_positive(bad),
                Err(format!("`{bad}` is not a positive number"))
            );
        }
        assert_eq!(parse_positive("0.5"), Ok(0.5));
    }
}
