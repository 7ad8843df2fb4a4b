//! `scripts/bench --baseline DIR`: before and after in one run. For every row of
//! [`crate::fmus::ROWS`] whose FMU is in both DIR (an earlier build) and today's
//! `build/fmus`, the two binaries are stepped straight through their C ABI by the same C
//! driver (`tests/allocations/driver.c --time`: every Real input set, DoStep, every output
//! read, with the row's inputs and step), in interleaved batches (baseline, now, next row's
//! baseline …), and the table gives the medians and the speed-up. An FMU whose interface
//! changed between the two builds is still comparable: each driver works from its own FMU's
//! manifest (what it sets and reads), and the table says how the inputs and outputs differ.
//! `scripts/bench --baseline-rev REV` builds DIR from a git revision first.

use crate::fmus::{fmu_path, Direct, Driver, ROWS};
use crate::stats::{interleaved_batches, median, Batched};
use anyhow::{Context, Result};
use std::path::Path;

/// What a driver exchanges with an FMU in a step, from its manifest (`manifest.py`): the
/// names of the Real inputs it sets (those with a start value) and of the Real, Integer and
/// Boolean outputs it reads, each with its number of values (arrays in FMI 3.0).
#[derive(Debug, PartialEq)]
pub struct Interface {
    pub inputs: Vec<(String, usize)>,
    pub outputs: Vec<(String, usize)>,
}

impl Interface {
    /// Reads the `var` records of a manifest (fields: vr, type, causality, variability, count,
    /// start, min, max, name; tab-separated).
    pub fn parse(manifest: &str) -> Result<Self> {
        let mut inputs = Vec::new();
        let mut outputs = Vec::new();
        for line in manifest.lines() {
            let fields: Vec<&str> = line.split('\t').collect();
            if fields.first() != Some(&"var") {
                continue;
            }
            let [_, _, kind, causality, _, count, start, _, _, name] = fields[..] else {
                anyhow::bail!("a manifest line with {} fields: {line:?}", fields.len());
            };
            let count: usize = count
                .parse()
                .with_context(|| format!("the number of values of {name}: {count:?}"))?;
            let entry = (name.to_string(), count);
            match (causality, kind) {
                ("input", "R") if start != "-" => inputs.push(entry),
                ("output", "R" | "I" | "B") => outputs.push(entry),
                _ => {}
            }
        }
        Ok(Self { inputs, outputs })
    }

    fn values(list: &[(String, usize)]) -> usize {
        list.iter().map(|(_, n)| n).sum()
    }

    /// Input and output values, as "inputs/outputs".
    pub fn counts(&self) -> String {
        format!(
            "{}/{}",
            Self::values(&self.inputs),
            Self::values(&self.outputs)
        )
    }

    /// How `now` differs from `self` (the baseline): "same", the counts when they differ, or
    /// that the same counts have other names.
    pub fn change(&self, now: &Self) -> String {
        if self == now {
            "same".into()
        } else if self.counts() != now.counts() {
            format!("differs: {} → {}", self.counts(), now.counts())
        } else {
            format!("same counts ({}), other names", now.counts())
        }
    }
}

/// One row of the comparison: the medians (ns per step) and the median of the per-round
/// ratios baseline / now (each round's two batches run back to back, so a drift of the
/// machine cancels in the ratio).
pub struct Compared {
    pub label: &'static str,
    pub baseline_ns: f64,
    pub now_ns: f64,
    pub speed_up: f64,
    pub baseline: Interface,
    pub now: Interface,
    /// Instructions per step (callgrind, the same loop), baseline and now, when counted.
    pub instructions: Option<(f64, f64)>,
}

impl Compared {
    /// The figures from the interleaved samples of the two builds.
    pub fn from_samples(
        label: &'static str,
        baseline: &[f64],
        now: &[f64],
        interfaces: (Interface, Interface),
    ) -> Self {
        let ratios: Vec<f64> = baseline.iter().zip(now).map(|(b, n)| b / n).collect();
        Self {
            label,
            baseline_ns: median(baseline),
            now_ns: median(now),
            speed_up: median(&ratios),
            baseline: interfaces.0,
            now: interfaces.1,
            instructions: None,
        }
    }
}

/// A row left out of the comparison, and why (its FMU is missing from one of the builds).
pub type LeftOut = (&'static str, &'static str);

/// The markdown table: one line per compared row (with the instructions per step if they
/// were counted), then a line per row left out (its FMU missing from one of the builds).
pub fn table(label: &str, compared: &[Compared], left_out: &[LeftOut]) -> String {
    let counted = compared.iter().any(|c| c.instructions.is_some());
    let (head, rule, none) = if counted {
        (
            " instructions per step, baseline | now | ratio |",
            "---|---|---|",
            " — | — | — |",
        )
    } else {
        ("", "", "")
    };
    let mut out = format!(
        "| FMU | baseline ({label}) | now | speed-up | inputs/outputs (values set/read per \
         step) |{head}\n|---|---|---|---|---|{rule}\n"
    );
    for c in compared {
        let instructions = match c.instructions {
            Some((before, after)) if counted => {
                format!(" {before:.0} | {after:.0} | {:.2}× |", before / after)
            }
            _ => none.into(),
        };
        out.push_str(&format!(
            "| {} | {} | {} | {:.2}× | {} |{instructions}\n",
            c.label,
            crate::ns(c.baseline_ns),
            crate::ns(c.now_ns),
            c.speed_up,
            match c.baseline.change(&c.now) {
                same if same == "same" => format!("{} (same)", c.now.counts()),
                change => change,
            }
        ));
    }
    for (row, why) in left_out {
        out.push_str(&format!("| {row} | — | — | — | {why} |{none}\n"));
    }
    out
}

/// Times every row present in both `baseline` and `now` (directories of `.fmu` files):
/// `rounds` rounds, each a batch of about `batch_ms` per row and build, in turn (row 1
/// baseline, row 1 now, row 2 baseline …); then, with `instructions` = (short, long) run
/// lengths, counts each one's instructions per step of the same loop under callgrind. Gives
/// the compared rows and the rows left out, with why.
pub fn compare(
    repo: &Path,
    baseline: &Path,
    now: &Path,
    (rounds, batch_ms): (usize, f64),
    instructions: Option<(u64, u64)>,
) -> Result<(Vec<Compared>, Vec<LeftOut>)> {
    let dir = tempfile::tempdir()?;
    let driver = Driver::compile(repo, dir.path())?;
    let mut subjects = Vec::new();
    let mut rows = Vec::new();
    let mut left_out = Vec::new();
    for row in ROWS {
        let (old, new) = (fmu_path(baseline, row.fmu), fmu_path(now, row.fmu));
        let (old, new) = match (old, new) {
            (Ok(old), Ok(new)) => (old, new),
            (Err(_), _) => {
                left_out.push((row.label, "not in the baseline"));
                continue;
            }
            (_, Err(_)) => {
                left_out.push((row.label, "not in today's build"));
                continue;
            }
        };
        let mut interfaces = Vec::new();
        let mut manifests = Vec::new();
        for (fmu, build) in [(&old, "baseline"), (&new, "now")] {
            let unpacked = dir.path().join(build).join(row.fmu);
            let direct = Direct::new(&driver, fmu, row, &unpacked)
                .with_context(|| format!("{} ({build})", row.label))?;
            let manifest = std::fs::read_to_string(unpacked.join("manifest.txt"))?;
            interfaces.push(
                Interface::parse(&manifest)
                    .with_context(|| format!("the manifest of {}", fmu.display()))?,
            );
            subjects.push(Batched::new(direct, batch_ms)?);
            manifests.push(unpacked.join("manifest.txt"));
        }
        rows.push((row, interfaces, manifests));
    }
    let samples = interleaved_batches(rounds, &mut subjects)?;
    drop(subjects);
    let mut compared = Vec::new();
    for (pair, (row, mut interfaces, manifests)) in samples.chunks(2).zip(rows) {
        let (Some(n), Some(b)) = (interfaces.pop(), interfaces.pop()) else {
            anyhow::bail!("{}: an interface is missing", row.label);
        };
        let mut c = Compared::from_samples(row.label, &pair[0], &pair[1], (b, n));
        if let Some((short, long)) = instructions {
            let count = |manifest: &Path| {
                driver
                    .instructions(manifest, row, short, long)
                    .with_context(|| row.label)
            };
            c.instructions = Some((count(&manifests[0])?, count(&manifests[1])?));
        }
        compared.push(c);
    }
    Ok((compared, left_out))
}

#[cfg(test)]
mod tests {
    use super::*;

    const MANIFEST: &str = "label\tLinearSystem\nversion\t2\nid\tLinearSystem\n\
        var\t0\tR\tparameter\tfixed\t1\t0.5\t-\t-\ta\n\
        var\t1\tR\tinput\tcontinuous\t1\t0\t-\t-\tu\n\
        var\t2\tR\tinput\tcontinuous\t1\t-\t-\t-\tunset\n\
        var\t3\tR\toutput\tcontinuous\t1\t-\t-\t-\ty\n\
        var\t4\tB\toutput\tdiscrete\t1\t-\t-\t-\tok\n\
        var\t5\tS\toutput\tdiscrete\t1\t-\t-\t-\tnote\n\
        var\t6\tR\toutput\tcontinuous\t3\t-\t-\t-\tx\n";

    fn interface(inputs: &[&str], outputs: &[&str]) -> Interface {
        let named = |names: &[&str]| names.iter().map(|n| (n.to_string(), 1)).collect();
        Interface {
            inputs: named(inputs),
            outputs: named(outputs),
        }
    }

    #[test]
    fn a_manifest_gives_what_the_driver_sets_and_reads() {
        let i = Interface::parse(MANIFEST).unwrap();
        // The input without a start value is not set; String outputs are not read.
        assert_eq!(i.inputs, [("u".to_string(), 1)]);
        assert_eq!(
            i.outputs,
            [("y".into(), 1), ("ok".into(), 1), ("x".into(), 3)]
        );
        assert_eq!(i.counts(), "1/5");
        assert!(Interface::parse("var\t1\tR\tinput").is_err());
        assert!(Interface::parse("var\t0\tR\tinput\tcontinuous\tmany\t0\t-\t-\tu").is_err());
    }

    #[test]
    fn interface_changes_are_named() {
        let before = interface(&["u"], &["y", "z"]);
        assert_eq!(before.change(&interface(&["u"], &["y", "z"])), "same");
        assert_eq!(
            before.change(&interface(&["u", "v"], &["y", "z", "w"])),
            "differs: 1/2 → 2/3"
        );
        assert_eq!(
            before.change(&interface(&["v"], &["y", "z"])),
            "same counts (1/2), other names"
        );
    }

    #[test]
    fn the_table_gives_medians_and_the_median_of_paired_ratios() {
        // Round 2 ran on a slower machine for both: the paired ratio stays 2.
        let c = Compared::from_samples(
            "KalmanFilter n=p=1",
            &[100.0, 300.0, 90.0],
            &[50.0, 150.0, 45.0],
            (interface(&["u"], &["y"]), interface(&["u"], &["y", "P"])),
        );
        assert_eq!((c.baseline_ns, c.now_ns, c.speed_up), (100.0, 50.0, 2.0));
        let left_out = [("WindGenerator h=0.1 s", "not in the baseline")];
        let text = table("e1b4845", std::slice::from_ref(&c), &left_out);
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(lines.len(), 4, "{text}");
        assert!(lines[0].starts_with("| FMU | baseline (e1b4845) | now | speed-up |"));
        assert_eq!(
            lines[2],
            "| KalmanFilter n=p=1 | 100 ns | 50.0 ns | 2.00× | differs: 1/1 → 1/2 |"
        );
        assert_eq!(
            lines[3],
            "| WindGenerator h=0.1 s | — | — | — | not in the baseline |"
        );
        // With instructions counted: three more columns on every line.
        let counted = Compared {
            instructions: Some((1500.0, 600.0)),
            ..c
        };
        let text = table("e1b4845", &[counted], &left_out);
        let lines: Vec<&str> = text.lines().collect();
        assert!(lines[0].ends_with("| instructions per step, baseline | now | ratio |"));
        assert_eq!(lines[1].matches("---").count(), 8);
        assert!(lines[2].ends_with("| differs: 1/1 → 1/2 | 1500 | 600 | 2.50× |"));
        assert!(lines[3].ends_with("| not in the baseline | — | — | — |"));
    }
}
