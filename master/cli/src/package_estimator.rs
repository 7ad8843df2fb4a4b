//! `spurio package-estimator`: an estimator FMU for any plant FMU (docs/estimators.md, "An
//! estimator FMU for any plant FMU"). The plant's names are checked as `spurio identify`
//! checks them (a free name that is not a Real parameter, a measurement or input that does
//! not exist, an FMU without Model Exchange: an error before anything is written); the
//! declaration ([`spurio_identify::packaged`]) goes into `resources/variant.cfg`, the plant
//! unpacked into `resources/plant/`, and the `PlantEstimator` binary of every platform the
//! plant has a binary for beside it. The page is generated with the plant's names and units.

use crate::package::{self, Extras, Packaged, Platform};
use anyhow::{anyhow, bail, Context, Result};
use spurio_export::Config;
use spurio_identify::packaged::{EstimatorDeclaration, Free, Measured, Named};
use spurio_identify::plant::{integration, FmuPlant};
pub use spurio_identify::session::Request;
use spurio_master::fmu::me::read_description;
use spurio_master::fmu::{FmuFile, Interface, LoadOptions, VarType};
use std::fmt::Write as _;
use std::io::Read;
use std::path::{Path, PathBuf};

/// The FMU binary an estimator is packaged with.
pub const ESTIMATOR_FMU: &str = "PlantEstimator";

/// The largest plant archive unpacked into the estimator (256 MiB).
pub const MAX_PLANT_BYTES: u64 = 256 << 20;

/// The variances of `outputs` in their order from `NAME=VALUE` entries: each a measured
/// variable, each finite and > 0, every output given one.
pub fn noise_in_order(outputs: &[String], entries: &[(String, f64)]) -> Result<Vec<f64>> {
    let mut noise = vec![None; outputs.len()];
    for (name, value) in entries {
        let j = outputs.iter().position(|o| o == name).ok_or_else(|| {
            anyhow!(
                "--noise {name}: `{name}` is not among the measured variables {}",
                outputs.join(", ")
            )
        })?;
        if !(value.is_finite() && *value > 0.0) {
            bail!("--noise {name}={value}: a measurement variance must be finite and > 0");
        }
        noise[j] = Some(*value);
    }
    noise
        .iter()
        .zip(outputs)
        .map(|(v, name)| {
            v.ok_or_else(|| {
                anyhow!("--noise: no variance for `{name}` (give --noise {name}=VARIANCE for every --output; an FMU cannot take it from data)")
            })
        })
        .collect()
}

/// The unit of variable `name` of `fmu`.
fn unit_of(fmu: &FmuFile, name: &str) -> Option<String> {
    fmu.variable(name).and_then(|v| v.unit.clone())
}

/// The plant's continuous states, named (FMI 2.0: by their value references; else
/// `state1`, `state2`, …) with their units.
fn states(fmu: &FmuFile, n: usize) -> Result<Vec<Named>> {
    let description = read_description(fmu)?;
    let named: Vec<Named> = description
        .state_references
        .iter()
        .filter_map(|vr| {
            fmu.variables
                .iter()
                .find(|v| v.head.value_reference == *vr && v.head.var_type == VarType::Real)
        })
        .map(|v| Named {
            name: v.head.name.clone(),
            unit: v.unit.clone(),
        })
        .collect();
    if named.len() == n {
        return Ok(named);
    }
    Ok((1..=n)
        .map(|i| Named {
            name: format!("state{i}"),
            unit: None,
        })
        .collect())
}

/// The declaration of the estimator `name` of `request` (as `spurio identify` takes it, the
/// variances given), every name checked against the plant (module documentation).
pub fn declare(request: &Request, name: &str) -> Result<EstimatorDeclaration> {
    let file = request.fmu.display();
    if !request.fmu.is_file() {
        bail!("{file}: not an FMU archive (a .fmu file)");
    }
    let spec = &request.plant;
    let noise = request
        .noise
        .clone()
        .ok_or_else(|| anyhow!("{file}: the measurement variances are needed (--noise)"))?;
    let mut plant = FmuPlant::open(&request.fmu, spec, integration(0.0, request.tolerance))?;
    plant.set_values(&request.set)?;
    let n = plant.states();
    let mut starts = plant.parameter_starts();
    for (parameter, value) in &request.starts {
        let i = spec
            .free
            .iter()
            .position(|f| f == parameter)
            .ok_or_else(|| {
                anyhow!(
                    "--start {parameter}: `{parameter}` is not among the free parameters {}",
                    spec.free.join(", ")
                )
            })?;
        starts[i] = *value;
    }
    // Initialised once here, so that a plant that cannot start at θ₀ is refused now.
    plant
        .initial_states(&starts)
        .with_context(|| format!("{file}: initialising the plant at the start values"))?;
    let fmu = FmuFile::open_for(
        &request.fmu,
        &LoadOptions::default(),
        Interface::ModelExchange,
    )?;
    let named = |names: &[String]| -> Vec<Named> {
        names
            .iter()
            .map(|name| Named {
                name: name.clone(),
                unit: unit_of(&fmu, name),
            })
            .collect()
    };
    let declared = EstimatorDeclaration {
        name: name.to_string(),
        plant: fmu.model_name.clone(),
        method: request.method,
        robust: request.robust,
        tolerance: request.tolerance,
        inputs: named(&spec.inputs),
        outputs: (named(&spec.outputs).into_iter().zip(noise))
            .map(|(variable, noise)| Measured { variable, noise })
            .collect(),
        states: states(&fmu, n)?,
        free: (named(&spec.free).into_iter().zip(starts))
            .map(|(parameter, start)| Free { parameter, start })
            .collect(),
        set: request.set.clone(),
    };
    if let Some((what, text)) = declared.uncarriable() {
        bail!("{what} `{text}` cannot be written in the FMU's configuration (`#`, a line break, surrounding spaces or empty)");
    }
    Ok(declared)
}

/// Files of an archive: (name, bytes).
type Files = Vec<(String, Vec<u8>)>;

/// The plant archive's files as `plant/<name>` resources, and the `binaries/` folders it has.
fn plant_files(path: &Path) -> Result<(Files, Vec<String>)> {
    let file = std::fs::File::open(path).with_context(|| format!("opening {}", path.display()))?;
    let mut archive = zip::ZipArchive::new(file)
        .with_context(|| format!("{}: not a zip archive", path.display()))?;
    let mut files = Vec::new();
    let mut folders = Vec::new();
    let mut total = 0u64;
    for i in 0..archive.len() {
        let mut entry = archive.by_index(i)?;
        if entry.is_dir() {
            continue;
        }
        let Some(name) = entry.enclosed_name() else {
            bail!("{}: entry {i} leaves the archive", path.display());
        };
        let name = name.to_string_lossy().replace('\\', "/");
        total += entry.size();
        if total > MAX_PLANT_BYTES {
            bail!(
                "{}: more than {MAX_PLANT_BYTES} bytes unpacked",
                path.display()
            );
        }
        let mut bytes = Vec::with_capacity(entry.size() as usize);
        entry.read_to_end(&mut bytes)?;
        if let Some(folder) = name
            .strip_prefix("binaries/")
            .and_then(|r| r.split('/').next())
        {
            if !folders.iter().any(|f| f == folder) {
                folders.push(folder.to_string());
            }
        }
        files.push((format!("plant/{name}"), bytes));
    }
    Ok((files, folders))
}

/// The platforms of `platforms` the plant has a binary for (FMI 2.0 folder or FMI 3.0
/// tuple); each dropped one is said on stderr.
fn platforms_of_plant(platforms: &[Platform], folders: &[String]) -> Vec<Platform> {
    platforms
        .iter()
        .filter(|p| {
            let tuple = package::FmiVersion::Fmi3.platform_folder(&p.name);
            let has = folders.iter().any(|f| *f == p.name || *f == tuple);
            if !has {
                let folders = if tuple == p.name {
                    format!("binaries/{tuple}")
                } else {
                    format!("binaries/{} or binaries/{tuple}", p.name)
                };
                eprintln!(
                    "package-estimator: the plant has no {} binary ({folders}): the estimator is packaged without that platform",
                    p.name
                );
            }
            has
        })
        .cloned()
        .collect()
}

/// A table of the page's variables: the rows `prefix` + name + `suffix` of every one of
/// `items`, each with its unit when `with_unit`, and `what` it is.
type Rows<'a> = (&'a str, &'a str, &'a [&'a Named], bool, &'a str);

/// The Markdown rows of `table` ([`Rows`]).
fn rows(page: &mut String, table: &[Rows]) {
    for (prefix, suffix, items, with_unit, what) in table {
        for n in *items {
            let unit = n.unit.as_deref().filter(|_| *with_unit).unwrap_or("");
            let _ = writeln!(
                page,
                "| `{prefix}{}{suffix}` | {unit} | {what} `{}` |",
                n.name, n.name
            );
        }
    }
}

/// The estimator's page: what it estimates, its variables with the plant's names and units,
/// its settings and its conventions.
pub fn page(d: &EstimatorDeclaration) -> String {
    let mut p = String::new();
    let free: Vec<&str> = d.free.iter().map(|f| f.parameter.name.as_str()).collect();
    let measured: Vec<&Named> = d.outputs.iter().map(|m| &m.variable).collect();
    let parameters: Vec<&Named> = d.free.iter().map(|f| &f.parameter).collect();
    let _ = writeln!(p, "# {}\n", d.name);
    let _ = writeln!(
        p,
        "The robust online filter of `spurio identify --method {}` (robust weights: {}) on the plant FMU **{}**, which this FMU carries unpacked in `resources/plant/`: it estimates the plant's {} continuous states and the parameters {} from the plant's inputs and measurements, sample by sample.\n",
        d.method.name(),
        d.robust.name(),
        d.plant,
        d.states.len(),
        free.join(", ")
    );
    p.push_str("## Equations\n\nz = [x; θ] (the states, then the free parameters as random walks); ẑ₀ = [x₀(θ₀); θ₀], the plant's initial states at θ₀ and the `set.*` parameters; P₀ = diag((1 % of max(|x₀,i|, 1))², (0.2 · max(|θ₀,i|, 10⁻³))²); Q = diag(10⁻¹⁰ per state, 0 per parameter) per sample; R = diag(`noise.*`). Between samples the plant is integrated (relative tolerance ");
    let _ = write!(p, "{}", d.tolerance);
    p.push_str(") with the inputs of the earlier sample held. The correction is the robust one of docs/estimators.md: standardised innovations rⱼ = eⱼ/√Sⱼⱼ, weights wⱼ = ψ(rⱼ)/rⱼ (Huber c = 1.645, Tukey c = 4.685), R inflated by 1/wⱼ. Each parameter is held to the plant's declared range [min, max]: a sigma point beyond a bound sees the plant at the bound, and θ̂ is projected onto the range after each correction.\n\n");
    p.push_str("## Sampling\n\nThe step from t to t + h processes the samples whose instants t_k = t₀ + k·T lie in [t, t + h) (T: parameter `sample_period`, 0 = the first step's size), each with the inputs set before the step, and shows the estimates of the last at t + h. A sample with `y.<name>.valid` = false is missing: predicted only, its innovation, deviation and weight read 0.\n\n");
    p.push_str("## Variables\n\n| name | unit | what |\n|---|---|---|\n");
    let inputs: Vec<&Named> = d.inputs.iter().collect();
    let states: Vec<&Named> = d.states.iter().collect();
    rows(
        &mut p,
        &[
            ("u.", "", &inputs, true, "input (plant input)"),
            ("y.", "", &measured, true, "input (measurement of)"),
            (
                "y.",
                ".valid",
                &measured,
                false,
                "input: true when present, the sample of",
            ),
            (
                "theta0.",
                "",
                &parameters,
                true,
                "parameter: start value of",
            ),
        ],
    );
    for Measured { variable: n, noise } in &d.outputs {
        let name = &n.name;
        let _ = writeln!(
            p,
            "| `noise.{name}` | | parameter: variance R of `{name}` (start {noise}) |"
        );
    }
    for (name, v) in &d.set {
        let _ = writeln!(
            p,
            "| `set.{name}` | | parameter of the plant for the experiment (start {v}) |"
        );
    }
    let deviation = "output: standard deviation of the estimate of";
    rows(
        &mut p,
        &[
            ("x_hat.", "", &states, true, "output: estimate of the state"),
            (
                "theta_hat.",
                "",
                &parameters,
                true,
                "output: estimate of the parameter",
            ),
            ("sd.", "", &states, true, deviation),
            ("sd.", "", &parameters, true, deviation),
            (
                "innovation.",
                "",
                &measured,
                true,
                "output: innovation y − ŷ of",
            ),
            (
                "innovation_sd.",
                "",
                &measured,
                true,
                "output: its standard deviation √S, of",
            ),
            ("weight.", "", &measured, false, "output: robust weight of"),
        ],
    );
    p.push_str("| `sample_period` | s | parameter: T |\n\n");
    p.push_str("## FMU state\n\n`fmi2GetFMUstate`/`fmi2SetFMUstate` are supported, and so are `fmi2SerializeFMUstate`/`fmi2DeSerializeFMUstate` (a restored state continues bit for bit).\n\nWritten by `spurio package-estimator`.\n");
    p
}

/// `spurio package-estimator`: writes `<out_dir>/<name>.fmu` and `<out_dir>/fmi3/<name>.fmu`.
pub fn package_estimator(
    repo: &Path,
    lib_dir: &Path,
    extra_platforms: &[Platform],
    request: &Request,
    name: &str,
    out_dir: &Path,
) -> Result<Vec<PathBuf>> {
    let declared = declare(request, name)?;
    let (resources, folders) = plant_files(&request.fmu)?;
    let platforms = platforms_of_plant(extra_platforms, &folders);
    if !folders
        .iter()
        .any(|f| f == "linux64" || f == "x86_64-linux")
    {
        bail!(
            "{}: the plant has no linux64 binary, which the estimator's host binary needs",
            request.fmu.display()
        );
    }
    let mut config = Config::new();
    for (key, value) in declared.entries() {
        config.set(&key, value);
    }
    let page = page(&declared);
    let target = Packaged {
        stem: &declared.name,
        config: &config,
        extras: Extras {
            resources: &resources,
            page: Some(&page),
        },
    };
    let source = package::source_of(repo, ESTIMATOR_FMU)?;
    package::package_both(lib_dir, &platforms, source, &target, out_dir)
}
