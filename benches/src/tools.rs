//! Whole runs side by side: `spurio run` against OMSimulator and the FMU Compliance Checker
//! on the Reference FMUs, and the master's own overhead per instance-step.
//!
//! Every process is timed from spawn to exit at two run lengths; the time per step is the
//! difference over the difference of the step counts, so process start-up, unpacking and
//! initialisation cancel. The runs of one comparison alternate (A short, A long, B short,
//! B long, then again), and the figure is the median over the rounds.

use crate::stats::{interleaved, median};
use anyhow::{bail, Context, Result};
use spurio_master::fmu::{Experiment, FmuFile, Instance, VarType};
use std::ffi::OsString;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::Instant;

/// The communication step of every run here: 2⁻¹⁰ s, exact in binary, so that no tool ends
/// with an extra tiny step from accumulated rounding.
pub const STEP: f64 = 1.0 / 1024.0;

/// The third-party tools and FMUs: the repository's `tests/third_party/` (its README says
/// what each is and where it came from), or the folder `SPURIO_THIRD_PARTY` names.
pub struct ThirdParty {
    dir: PathBuf,
}

impl ThirdParty {
    pub fn find(repo: &Path) -> Option<Self> {
        let dir = std::env::var_os("SPURIO_THIRD_PARTY")
            .map(PathBuf::from)
            .unwrap_or_else(|| repo.join("tests/third_party"));
        dir.join("reference-fmus").is_dir().then_some(Self { dir })
    }

    pub fn reference(&self, model: &str) -> PathBuf {
        self.dir
            .join("reference-fmus/fmi2")
            .join(format!("{model}.fmu"))
    }

    pub fn omsimulator(&self) -> PathBuf {
        self.dir.join("omsimulator/bin/OMSimulator")
    }

    pub fn fmu_check(&self) -> PathBuf {
        self.dir.join("fmuCheck.linux64")
    }
}

/// A program whose run of a given number of steps is timed.
pub struct Runner {
    pub label: String,
    program: PathBuf,
    /// The arguments of a run of `steps` steps.
    args: Box<dyn Fn(u64) -> Vec<OsString>>,
    /// The working directory (OMSimulator unpacks there).
    dir: Option<PathBuf>,
}

impl Runner {
    pub fn new(
        label: impl Into<String>,
        program: impl Into<PathBuf>,
        args: impl Fn(u64) -> Vec<OsString> + 'static,
    ) -> Self {
        Self {
            label: label.into(),
            program: program.into(),
            args: Box::new(args),
            dir: None,
        }
    }

    /// Runs in `dir`.
    pub fn in_dir(mut self, dir: &Path) -> Self {
        self.dir = Some(dir.to_path_buf());
        self
    }

    /// Seconds from spawn to exit of a run of `steps` steps (which must succeed).
    fn seconds(&self, steps: u64) -> Result<f64> {
        let start = Instant::now();
        let mut command = Command::new(&self.program);
        if let Some(dir) = &self.dir {
            command.current_dir(dir);
        }
        let out = command
            .args((self.args)(steps))
            .stdin(Stdio::null())
            .output()
            .with_context(|| format!("running {}", self.program.display()))?;
        let seconds = start.elapsed().as_secs_f64();
        // OMSimulator may say `error:` and still exit with 0.
        let said = format!(
            "{}{}",
            String::from_utf8_lossy(&out.stdout),
            String::from_utf8_lossy(&out.stderr)
        );
        if !out.status.success() || said.contains("error:") {
            bail!("{} failed ({}): {said}", self.label, out.status);
        }
        Ok(seconds)
    }
}

/// Nanoseconds per step of each runner: runs of `short` and `long` steps, interleaved over
/// `rounds` rounds, the median of (long − short time) / (long − short steps).
pub fn per_step(runners: &mut [Runner], short: u64, long: u64, rounds: usize) -> Result<Vec<f64>> {
    let samples = interleaved(rounds, runners, |r| {
        let a = r.seconds(short)?;
        let b = r.seconds(long)?;
        Ok((b - a) * 1e9 / (long - short) as f64)
    })?;
    Ok(samples.into_iter().map(|s| median(&s)).collect())
}

/// Writes a system TOML of `steps` steps of [`STEP`] with `instances` (name, FMU) and
/// `connections`, in `dir`; gives its path.
pub fn system_file(
    dir: &Path,
    name: &str,
    steps: u64,
    algorithm: &str,
    connections: &[String],
    instances: &[(String, PathBuf)],
) -> Result<PathBuf> {
    let mut text = format!(
        "name = \"{name}\"\nstop_time = {:?}\nstep_size = {STEP:?}\nalgorithm = \"{algorithm}\"\nconnections = [{}]\n",
        steps as f64 * STEP,
        connections
            .iter()
            .map(|c| format!("{c:?}"))
            .collect::<Vec<_>>()
            .join(", ")
    );
    for (instance, fmu) in instances {
        text += &format!(
            "[[instance]]\nname = \"{instance}\"\nfmu = {:?}\n",
            fmu.display().to_string()
        );
    }
    let path = dir.join(format!("{name}_{steps}.toml"));
    std::fs::write(&path, text)?;
    Ok(path)
}

/// An OMSimulator Lua script running the SSP `ssp` (its system called `name`) for `steps`
/// steps of [`STEP`], writing its results to `result` (empty: no result file), in `dir`;
/// gives its path. (The command line cannot switch results off; the Lua API can.)
pub fn oms_script(dir: &Path, ssp: &Path, name: &str, steps: u64, result: &str) -> Result<PathBuf> {
    let text = format!(
        "oms_setTempDirectory(\".\")\noms_importFile({ssp:?})\noms_setStopTime({name:?}, {stop:?})\n\
         oms_setResultFile({name:?}, {result:?})\noms_instantiate({name:?})\noms_initialize({name:?})\n\
         oms_simulate({name:?})\noms_terminate({name:?})\noms_delete({name:?})\n",
        ssp = ssp.display().to_string(),
        stop = steps as f64 * STEP,
    );
    let tag = if result.is_empty() { "none" } else { "csv" };
    let path = dir.join(format!("oms_{tag}_{steps}.lua"));
    std::fs::write(&path, text)?;
    Ok(path)
}

/// The chain of the master-overhead measurement: VanDerPol → Feedthrough → … (`count`
/// instances in all), each Feedthrough's continuous output driving the next one's input.
pub fn chain(third: &ThirdParty, count: usize) -> (Vec<(String, PathBuf)>, Vec<String>) {
    let mut instances = vec![("vdp".to_string(), third.reference("VanDerPol"))];
    let mut connections = Vec::new();
    for i in 1..count {
        let source = if i == 1 {
            "vdp.x0".to_string()
        } else {
            format!("ft{}.Float64_continuous_output", i - 1)
        };
        connections.push(format!("{source} -> ft{i}.Float64_continuous_input"));
        instances.push((format!("ft{i}"), third.reference("Feedthrough")));
    }
    (instances, connections)
}

/// The FMI calls `spurio run --no-record` makes per communication point on [`chain`] with
/// Jacobi, made directly on the loaded instances: per instance one `fmi2DoStep`, per
/// connection one `fmi2GetReal` of its source and one `fmi2SetReal` of its input. Gives
/// nanoseconds per instance-step (median of `rounds` batches of `steps` steps).
pub fn bare_chain(third: &ThirdParty, count: usize, steps: u64, rounds: usize) -> Result<f64> {
    let (instances, _) = chain(third, count);
    let vdp = FmuFile::open(&third.reference("VanDerPol"))?;
    let ft = FmuFile::open(&third.reference("Feedthrough"))?;
    let vr = |f: &FmuFile, name: &str| -> Result<u32> {
        Ok(f.variable(name)
            .with_context(|| format!("no variable {name}"))?
            .head
            .value_reference)
    };
    let (x0, input, output) = (
        vr(&vdp, "x0")?,
        vr(&ft, "Float64_continuous_input")?,
        vr(&ft, "Float64_continuous_output")?,
    );
    let experiment = Experiment {
        tolerance: None,
        start: 0.0,
        stop: None,
    };
    let mut members: Vec<Instance> = Vec::new();
    for (i, (name, _)) in instances.iter().enumerate() {
        let file = if i == 0 { &vdp } else { &ft };
        let mut inst = file.instantiate(name, false)?;
        let ok = inst
            .setup_experiment(experiment)
            .and_then(|()| inst.enter_initialization_mode(experiment))
            .and_then(|()| inst.exit_initialization_mode());
        ok.map_err(|e| anyhow::anyhow!("initialising {name}: {}", e.0))?;
        members.push(inst);
    }
    let sources: Vec<u32> = (0..count - 1)
        .map(|i| if i == 0 { x0 } else { output })
        .collect();
    let mut value = [0.0];
    let mut k = 0u64;
    let mut batch = || -> Result<f64> {
        let start = Instant::now();
        for _ in 0..steps {
            let time = k as f64 * STEP;
            for (i, source) in sources.iter().enumerate() {
                let fail = |e: spurio_master::fmu::CallError| anyhow::anyhow!("{}", e.0);
                members[i]
                    .get(VarType::Real, &[*source], &mut value)
                    .map_err(fail)?;
                members[i + 1]
                    .set(VarType::Real, &[input], &value)
                    .map_err(fail)?;
            }
            for m in &mut members {
                if let Err(e) = m.do_step(time, STEP) {
                    bail!("fmi2DoStep at t = {time}: {e:?}");
                }
            }
            k += 1;
        }
        Ok(start.elapsed().as_nanos() as f64 / (steps * count as u64) as f64)
    };
    batch()?;
    let samples = (0..rounds).map(|_| batch()).collect::<Result<Vec<_>>>()?;
    Ok(median(&samples))
}
