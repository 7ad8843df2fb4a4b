//! Our FMUs' cost per step through their C ABI: the packaged binary (`build/fmus/<Model>.fmu`)
//! loaded as any importer loads it, then per step `fmi2SetReal` of every input,
//! `fmi2DoStep` and the getters of every output — against the arithmetic floor estimated
//! for it and its target where there is one. Each row is measured two ways, interleaved:
//! straight through the C ABI by the allocation driver (`tests/allocations/driver.c` in its
//! timing mode, a subprocess fed batch lengths on stdin: no Rust wrapper between the loop and
//! the C functions), and through spurio's importer (`spurio_master::fmu::Instance` over
//! rust-fmi's wrappers, what a co-simulation pays). With `--instructions`, callgrind counts
//! the instructions of a step on the importer path (two runs of different lengths under
//! valgrind, so loading and initialisation cancel).

use crate::stats::{interleaved_batches, median, Batched, Timed};
use anyhow::{bail, Context, Result};
use spurio_master::fmu::{Causality, Experiment, FmuFile, Instance, VarType};
use std::ffi::OsString;
use std::io::{BufRead, BufReader, Write};
use std::path::{Path, PathBuf};
use std::process::{Child, ChildStdin, ChildStdout, Command, Stdio};
use std::time::Instant;

/// One row of the table: an FMU (its file stem in `build/fmus`), its label and communication
/// step, what it is measured against (its floor and target, where there are), and
/// how its inputs move (sines of `amplitude` around their start values, with a 5 % sprinkling
/// of outliers for the robust estimators). Floor and target in ns per step, the other target
/// in instructions per step.
pub struct Row {
    pub(crate) fmu: &'static str,
    pub(crate) label: &'static str,
    pub(crate) step: f64,
    pub(crate) floor_ns: Option<f64>,
    pub(crate) target_ns: Option<f64>,
    pub(crate) target_instructions: Option<f64>,
    pub(crate) amplitude: f64,
    pub(crate) outliers: bool,
}

impl Row {
    const fn new(fmu: &'static str, label: &'static str, step: f64) -> Self {
        Self {
            fmu,
            label,
            step,
            floor_ns: None,
            target_ns: None,
            target_instructions: None,
            amplitude: 0.1,
            outliers: false,
        }
    }

    /// Issue 17's floor and target per step (ns).
    const fn against(self, floor_ns: f64, target_ns: f64) -> Self {
        Self {
            floor_ns: Some(floor_ns),
            target_ns: Some(target_ns),
            ..self
        }
    }

    const fn with_outliers(self) -> Self {
        Self {
            outliers: true,
            ..self
        }
    }
}

/// The rows, with their constants. Where they come from (estimated and measured on an AMD Zen 4,
/// 2 shared cores):
/// - DkfRsKfGenerator (n = 8, m = p = 2): ≈ 8.1 kflop per step; 0.2 µs with AVX2+FMA
///   (0.4 µs with SSE2); target ≤ 1.0 µs and ≤ 20k instructions with every output read.
/// - LinearSystem n = 2: three Gaussian draws (state noise ×2, measurement noise) ≈ 85 ns;
///   target ≤ 120 ns.
/// - AdaptiveStateFeedback, GantryCrane: the issue estimates no floor and names no number
///   (AdaptiveStateFeedback's Â, B̂ inputs move by 1e-4 around the nominal crane model, so
///   that its gain is recomputed every step and stays within its bound).
/// - WindGenerator at 0.1 s: target ≥ 10× faster than the 120–200 µs of then: ≤ 12 µs.
/// - scalar KalmanFilter / RobustKalmanFilter: ≈ 25 flops ≈ 10 ns; target ≤ 40 ns.
pub const ROWS: &[Row] = &[
    Row {
        target_instructions: Some(20_000.0),
        ..Row::new("DkfRsKfGenerator", "DkfRsKfGenerator n=8 m=p=2", 0.05)
            .against(200.0, 1000.0)
            .with_outliers()
    },
    Row::new("LinearSystem", "LinearSystem n=2", 0.1).against(85.0, 120.0),
    Row {
        amplitude: 1e-4,
        ..Row::new("AdaptiveStateFeedback", "AdaptiveStateFeedback", 0.05)
    },
    Row {
        target_ns: Some(12_000.0),
        ..Row::new("WindGenerator", "WindGenerator h=0.1 s", 0.1)
    },
    Row::new("GantryCrane", "GantryCrane h=50 ms", 0.05),
    Row::new("KalmanFilter", "KalmanFilter n=p=1", 0.001)
        .against(10.0, 40.0)
        .with_outliers(),
    Row::new("RobustKalmanFilter", "RobustKalmanFilter n=p=1", 0.001)
        .against(10.0, 40.0)
        .with_outliers(),
];

/// One initialised instance of a row's FMU and what a step moves.
pub struct Stepper {
    instance: Instance,
    step: f64,
    /// Value references of the Real inputs.
    inputs: Vec<u32>,
    /// The inputs of [`SIGNAL_PERIOD`] consecutive steps, one row of `inputs.len()` values a
    /// step, formed before the measurement so the timed loop costs no sine.
    signals: Vec<f64>,
    /// The outputs, one getter call per type.
    outputs: Vec<(VarType, Vec<u32>, Vec<f64>)>,
    time: f64,
    k: u64,
}

impl Stepper {
    /// Loads `fmu` (its model description's variables), instantiates and initialises it.
    pub fn new(fmu: &Path, row: &Row) -> Result<Self> {
        let file = FmuFile::open(fmu).with_context(|| format!("loading {}", fmu.display()))?;
        let mut inputs = Vec::new();
        let mut starts = Vec::new();
        let mut outputs: Vec<(VarType, Vec<u32>, Vec<f64>)> = Vec::new();
        for v in &file.variables {
            let (t, vr) = (v.head.var_type, v.head.value_reference);
            match v.head.causality {
                Causality::Input if t == VarType::Real => {
                    inputs.push(vr);
                    starts.push(v.start.unwrap_or(0.0));
                }
                Causality::Output if t.is_numeric() => {
                    match outputs
                        .iter_mut()
                        .find(|(output_type, _, _)| *output_type == t)
                    {
                        Some((_, vrs, out)) => {
                            vrs.push(vr);
                            out.push(0.0);
                        }
                        None => outputs.push((t, vec![vr], vec![0.0])),
                    }
                }
                _ => {}
            }
        }
        let mut instance = file.instantiate("bench", false)?;
        let experiment = Experiment {
            tolerance: None,
            start: 0.0,
            stop: None,
        };
        let init = |i: &mut Instance| {
            i.setup_experiment(experiment)?;
            i.enter_initialization_mode(experiment)?;
            i.exit_initialization_mode()
        };
        init(&mut instance)
            .map_err(|e| anyhow::anyhow!("initialising {}: {}", fmu.display(), e.0))?;
        let signals = input_signals(&starts, row.amplitude, row.outliers);
        Ok(Self {
            instance,
            step: row.step,
            signals,
            inputs,
            outputs,
            time: 0.0,
            k: 0,
        })
    }

    /// The number of values read per step.
    pub fn outputs_read(&self) -> usize {
        self.outputs.iter().map(|(_, vrs, _)| vrs.len()).sum()
    }

    /// One step: every input set (the next row of the precomputed signals), `fmi2DoStep`, every
    /// output read.
    pub fn step(&mut self) -> Result<()> {
        let n = self.inputs.len();
        let row = (self.k % SIGNAL_PERIOD) as usize * n;
        let values = &self.signals[row..row + n];
        let failed = |call: &str, e: String| anyhow::anyhow!("{call} at t = {}: {e}", self.time);
        if !self.inputs.is_empty() {
            self.instance
                .set(VarType::Real, &self.inputs, values)
                .map_err(|e| failed("fmi2SetReal", e.0))?;
        }
        if let Err(e) = self.instance.do_step(self.time, self.step) {
            bail!(failed("fmi2DoStep", format!("{e:?}")));
        }
        for (t, vrs, out) in &mut self.outputs {
            self.instance
                .get(*t, vrs, out)
                .map_err(|e| anyhow::anyhow!("fmi2Get* at t = {}: {}", self.time, e.0))?;
        }
        std::hint::black_box(&self.outputs);
        self.time += self.step;
        self.k += 1;
        Ok(())
    }

    /// Nanoseconds per step over `steps` steps.
    pub fn time_steps(&mut self, steps: u64) -> Result<f64> {
        let start = Instant::now();
        for _ in 0..steps {
            self.step()?;
        }
        Ok(start.elapsed().as_nanos() as f64 / steps as f64)
    }
}

/// Steps after which the precomputed input signals repeat.
const SIGNAL_PERIOD: u64 = 1024;

/// The inputs of [`SIGNAL_PERIOD`] steps, row by row: input i at step k is its start value plus
/// `amplitude`·sin(0.05 (i + 1) k), with an outlier of +3 on 5 % of the samples when `outliers`.
/// The C driver's direct path forms the same inputs (`form_signals` in
/// tests/allocations/driver.c): keep the two alike.
fn input_signals(starts: &[f64], amplitude: f64, outliers: bool) -> Vec<f64> {
    (0..SIGNAL_PERIOD)
        .flat_map(|k| {
            starts.iter().enumerate().map(move |(i, start)| {
                let phase = k as f64 * 0.05 * (i + 1) as f64;
                let outlier = outliers && (k * 7 + i as u64).is_multiple_of(20);
                start + amplitude * phase.sin() + if outlier { 3.0 } else { 0.0 }
            })
        })
        .collect()
}

/// One row's FMU stepped straight through its C ABI by the allocation driver in timing mode:
/// the driver's process holds one initialised instance and runs, for each step count written
/// to its stdin, that many steps (the same precomputed inputs as [`Stepper`]), answering with
/// the nanoseconds per step it timed around its own loop.
pub struct Direct {
    child: Child,
    stdin: Option<ChildStdin>,
    stdout: BufReader<ChildStdout>,
    label: &'static str,
}

impl Direct {
    /// Starts `driver` on the manifest of `fmu` (`manifest.py` unpacks it into `unpacked`
    /// and writes `unpacked/manifest.txt`).
    pub fn new(driver: &Driver, fmu: &Path, row: &Row, unpacked: &Path) -> Result<Self> {
        run(
            Command::new("python3")
                .arg(&driver.manifest_script)
                .arg(fmu)
                .arg(unpacked),
            &format!("tests/allocations/manifest.py on {}", fmu.display()),
        )?;
        let mut command = Command::new(&driver.binary);
        command.args(Driver::timing_args(
            &unpacked.join("manifest.txt"),
            row,
            100,
            0,
        ));
        let mut child = command
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .spawn()
            .with_context(|| format!("starting {}", driver.binary.display()))?;
        let (Some(stdin), Some(stdout)) = (child.stdin.take(), child.stdout.take()) else {
            bail!("the driver's pipes are missing");
        };
        Ok(Self {
            child,
            stdin: Some(stdin),
            stdout: BufReader::new(stdout),
            label: row.label,
        })
    }
}

impl Timed for Direct {
    /// Nanoseconds per step over `steps` steps, as the driver timed them.
    fn time_steps(&mut self, steps: u64) -> Result<f64> {
        let stdin = self
            .stdin
            .as_mut()
            .context("the driver's stdin is closed")?;
        writeln!(stdin, "{steps}")?;
        stdin.flush()?;
        let mut line = String::new();
        self.stdout.read_line(&mut line)?;
        line.trim().parse().map_err(|_| {
            anyhow::anyhow!(
                "{}: the C driver answered {line:?} (its error is on stderr above)",
                self.label
            )
        })
    }
}

impl Drop for Direct {
    fn drop(&mut self) {
        // End of input ends the driver, which frees its instance.
        drop(self.stdin.take());
        let _ = self.child.wait();
    }
}

/// The allocation driver compiled for timing (`gcc -O2`, as the callgrind script builds it
/// but optimised), with the script that writes its manifests.
pub struct Driver {
    binary: PathBuf,
    manifest_script: PathBuf,
}

impl Driver {
    /// Compiles `tests/allocations/driver.c` of `repo` into `dir`.
    pub fn compile(repo: &Path, dir: &Path) -> Result<Self> {
        let here = repo.join("tests/allocations");
        let binary = dir.join("driver");
        run(
            Command::new("gcc")
                .args(["-std=c11", "-O2", "-rdynamic", "-o"])
                .arg(&binary)
                .arg(here.join("driver.c"))
                .args(["-ldl", "-lm"]),
            "gcc (scripts/setup installs it) on driver.c",
        )?;
        Ok(Self {
            binary,
            manifest_script: here.join("manifest.py"),
        })
    }

    /// The arguments of the driver's timing mode on `manifest` with the row's inputs and
    /// step: a warm-up of `steps` steps then `batches` batches of `steps` (0: from stdin).
    fn timing_args(manifest: &Path, row: &Row, steps: u64, batches: u32) -> Vec<OsString> {
        let mut args: Vec<OsString> = vec![manifest.into()];
        args.extend(
            [
                steps.to_string(),
                "1".into(),
                "--time".into(),
                batches.to_string(),
                "--amplitude".into(),
                row.amplitude.to_string(),
                "--step".into(),
                row.step.to_string(),
            ]
            .map(OsString::from),
        );
        if row.outliers {
            args.push("--outliers".into());
        }
        args
    }

    /// Instructions per step of the driver's timed loop on `manifest` (written by
    /// [`Direct::new`]), counted by callgrind: runs of `short` and `long` steps (a warm-up and
    /// one batch each), the difference over the difference of the steps, so that loading and
    /// initialisation cancel. What the direct column times, the driver's loop included (a
    /// few instructions a step).
    pub fn instructions(&self, manifest: &Path, row: &Row, short: u64, long: u64) -> Result<f64> {
        let per_run = callgrind_per_step(
            row.fmu,
            &self.binary,
            |steps| Self::timing_args(manifest, row, steps, 1),
            (short, long),
        )?;
        // A run of `steps` steps times a warm-up and one batch of `steps`.
        Ok(per_run / 2.0)
    }
}

/// Instructions per step of `program` under callgrind, run with `args(steps)` for `short`
/// and `long` steps: the difference of the totals over the difference of the step counts.
fn callgrind_per_step(
    what: &str,
    program: &Path,
    args: impl Fn(u64) -> Vec<OsString>,
    (short, long): (u64, u64),
) -> Result<f64> {
    let dir = tempfile::tempdir()?;
    let total = |steps: u64| -> Result<f64> {
        let out = dir.path().join(format!("callgrind.{steps}"));
        run(
            Command::new("valgrind")
                .arg("--tool=callgrind")
                .arg(format!("--callgrind-out-file={}", out.display()))
                .arg(program)
                .args(args(steps)),
            &format!("callgrind (valgrind, scripts/setup installs it) on {what}"),
        )?;
        callgrind_total(&out)
    };
    let a = total(short)?;
    let b = total(long)?;
    Ok((b - a) / (long - short) as f64)
}

/// The instruction total of a callgrind output file.
fn callgrind_total(out: &Path) -> Result<f64> {
    let text = std::fs::read_to_string(out)?;
    text.lines()
        .find_map(|l| {
            l.strip_prefix("summary:")
                .or_else(|| l.strip_prefix("totals:"))
        })
        .and_then(|n| n.split_whitespace().next()?.parse::<f64>().ok())
        .with_context(|| format!("no instruction total in {}", out.display()))
}

/// A row's medians over the interleaved rounds: straight through the C ABI and through
/// spurio's importer.
pub struct Measured {
    pub direct_ns: f64,
    pub importer_ns: f64,
    pub outputs_read: usize,
}

/// Measures every row both ways: `rounds` rounds, each a batch of about `batch_ms` per row and
/// path, in turn (row 1 importer, row 1 direct, row 2 importer …).
pub fn measure(repo: &Path, fmus: &Path, rounds: usize, batch_ms: f64) -> Result<Vec<Measured>> {
    enum Route {
        Importer(Box<Stepper>),
        Direct(Direct),
    }
    impl Timed for Route {
        fn time_steps(&mut self, steps: u64) -> Result<f64> {
            match self {
                Self::Importer(s) => s.time_steps(steps),
                Self::Direct(d) => d.time_steps(steps),
            }
        }
    }
    let dir = tempfile::tempdir()?;
    let driver = Driver::compile(repo, dir.path())?;
    let mut subjects = Vec::new();
    let mut outputs_read = Vec::new();
    for row in ROWS {
        let fmu = fmu_path(fmus, row.fmu)?;
        let stepper = Stepper::new(&fmu, row).with_context(|| row.label)?;
        outputs_read.push(stepper.outputs_read());
        let direct = Direct::new(&driver, &fmu, row, &dir.path().join(row.fmu))
            .with_context(|| row.label)?;
        for route in [Route::Importer(Box::new(stepper)), Route::Direct(direct)] {
            subjects.push(Batched::new(route, batch_ms)?);
        }
    }
    let samples = interleaved_batches(rounds, &mut subjects)?;
    Ok(samples
        .chunks(2)
        .zip(outputs_read)
        .map(|(pair, outputs_read)| Measured {
            importer_ns: median(&pair[0]),
            direct_ns: median(&pair[1]),
            outputs_read,
        })
        .collect())
}

/// `build/fmus/<stem>.fmu`, which must exist.
pub fn fmu_path(fmus: &Path, stem: &str) -> Result<PathBuf> {
    let path = fmus.join(format!("{stem}.fmu"));
    if !path.is_file() {
        bail!(
            "{} is missing: run scripts/build-fmus --host-only",
            path.display()
        );
    }
    Ok(path)
}

/// `spurio-bench --count <row> --steps N`: loads and steps the row's FMU `steps` times
/// (what callgrind counts).
pub fn count_run(fmus: &Path, fmu: &str, steps: u64) -> Result<()> {
    let row = ROWS
        .iter()
        .find(|r| r.fmu == fmu)
        .with_context(|| format!("no row for {fmu}"))?;
    let mut stepper = Stepper::new(&fmu_path(fmus, row.fmu)?, row)?;
    for _ in 0..steps {
        stepper.step()?;
    }
    Ok(())
}

/// Instructions per step of `fmu` under callgrind: two runs of `short` and `long` steps,
/// the difference divided by the difference of the step counts.
pub fn instructions(fmus: &Path, fmu: &str, short: u64, long: u64) -> Result<f64> {
    let me = std::env::current_exe()?;
    callgrind_per_step(
        fmu,
        &me,
        |steps| {
            let mut a: Vec<OsString> = vec!["--fmus".into(), fmus.into()];
            a.extend(["--count", fmu, "--steps", &steps.to_string()].map(OsString::from));
            a
        },
        (short, long),
    )
}

/// Runs `command` to its end; an error names `what` and carries its stderr if it fails.
fn run(command: &mut Command, what: &str) -> Result<()> {
    let out = command
        .output()
        .with_context(|| format!("running {what}"))?;
    if !out.status.success() {
        bail!("{what} failed: {}", String::from_utf8_lossy(&out.stderr));
    }
    Ok(())
}
