//! `spurio identify`: the arguments, the data read from CSV, and the identification of
//! `spurio-identify` run on them (docs/estimators.md, "spurio identify").

use anyhow::{bail, Context, Result};
use spurio_identify::plant::PlantSpec;
use spurio_identify::session::{identify, write_outcome, Data, Method, Request, Robust};
use std::path::{Path, PathBuf};

/// The arguments of `spurio identify`.
#[derive(clap::Args, Debug)]
pub struct IdentifyArgs {
    /// The plant: an FMU with Model Exchange (FMI 2.0 or 3.0).
    pub fmu: PathBuf,
    /// The recorded data: CSV with a header, a `time` column (or the first column) and
    /// one column per input and measured variable; an empty or `nan` cell is missing; a
    /// row at the time of the row before replaces it (an event's two rows in fmpy's output).
    #[arg(long)]
    pub data: PathBuf,
    /// An input of the FMU from a column: `NAME=column` (or `NAME` when they agree).
    #[arg(long)]
    pub input: Vec<String>,
    /// A measured variable of the FMU from a column: `NAME=column` (or `NAME`).
    #[arg(long, required = true)]
    pub output: Vec<String>,
    /// The parameters to estimate, comma-separated.
    #[arg(long, value_delimiter = ',', required = true)]
    pub free: Vec<String>,
    /// Robust weights against outliers.
    #[arg(long, default_value = "huber", value_parser = ["huber", "tukey", "none"])]
    pub robust: String,
    /// `ukf` / `ekf`: online (robust unscented / extended Kalman filter, parameters as
    /// random-walk states); `ml`: offline maximum likelihood (Huber loss unless --robust
    /// none) with standard errors from the curvature.
    #[arg(long, default_value = "ukf", value_parser = ["ukf", "ekf", "ml"])]
    pub method: String,
    /// The fraction of the record, at its end, kept for validation.
    #[arg(long, default_value_t = 0.0)]
    pub validate: f64,
    /// The measurement noise variances, one per --output (default: from the data; `ml`
    /// estimates them).
    #[arg(long, value_delimiter = ',')]
    pub noise: Vec<f64>,
    /// A free parameter's start value: `NAME=VALUE` (default: the FMU's start value).
    #[arg(long, value_delimiter = ',')]
    pub start: Vec<String>,
    /// A parameter that is not estimated, set for the experiment: `NAME=VALUE` (a crane's
    /// initial cart position `x0=0.2`).
    #[arg(long, value_delimiter = ',')]
    pub set: Vec<String>,
    /// Where to write estimates.csv, report.md (and trajectory.csv for `ukf` and `ekf`).
    #[arg(long, default_value = "identification")]
    pub out: PathBuf,
}

/// The relative tolerance of the plant's integration (`spurio identify`, and the estimator
/// FMU `spurio package-estimator` writes).
pub const TOLERANCE: f64 = 1e-8;

/// `NAME=column` or `NAME`.
fn mapping(entry: &str) -> (String, String) {
    match entry.split_once('=') {
        Some((name, column)) => (name.trim().to_string(), column.trim().to_string()),
        None => (entry.trim().to_string(), entry.trim().to_string()),
    }
}

/// `NAME=VALUE` entries of `flag` as (name, number).
pub(crate) fn values(flag: &str, entries: &[String]) -> Result<Vec<(String, f64)>> {
    entries
        .iter()
        .map(|entry| {
            let (name, value) = entry
                .split_once('=')
                .with_context(|| format!("{flag} {entry}: expected NAME=VALUE"))?;
            let value: f64 = value
                .trim()
                .parse()
                .with_context(|| format!("{flag} {entry}: `{value}` is not a number"))?;
            Ok((name.trim().to_string(), value))
        })
        .collect()
}

/// The data's columns for `inputs` and `outputs` (names of columns).
fn read_data(path: &Path, inputs: &[String], outputs: &[String]) -> Result<Data> {
    let mut reader = csv::ReaderBuilder::new()
        .trim(csv::Trim::All)
        .from_path(path)
        .with_context(|| format!("cannot read {}", path.display()))?;
    let header: Vec<String> = reader.headers()?.iter().map(str::to_string).collect();
    let column = |name: &str| {
        header.iter().position(|h| h == name).with_context(|| {
            format!(
                "{} has no column `{name}` (its columns: {})",
                path.display(),
                header.join(", ")
            )
        })
    };
    let time = header.iter().position(|h| h == "time").unwrap_or(0);
    let input_columns = inputs
        .iter()
        .map(|c| column(c))
        .collect::<Result<Vec<_>>>()?;
    let output_columns = outputs
        .iter()
        .map(|c| column(c))
        .collect::<Result<Vec<_>>>()?;
    let mut data = Data {
        time: Vec::new(),
        inputs: Vec::new(),
        outputs: Vec::new(),
    };
    for (line, record) in reader.records().enumerate() {
        let record = record?;
        let cell = |j: usize, missing_ok: bool| -> Result<f64> {
            let text = record.get(j).unwrap_or("");
            if missing_ok && (text.is_empty() || text.eq_ignore_ascii_case("nan")) {
                return Ok(f64::NAN);
            }
            text.parse::<f64>().with_context(|| {
                format!(
                    "{} row {}: `{text}` in column `{}` is not a number",
                    path.display(),
                    line + 2,
                    header[j]
                )
            })
        };
        let t = cell(time, false)?;
        let u = input_columns
            .iter()
            .map(|&j| cell(j, false))
            .collect::<Result<Vec<_>>>()?;
        let y = output_columns
            .iter()
            .map(|&j| cell(j, true))
            .collect::<Result<Vec<_>>>()?;
        // A row at the time of the row before (fmpy records an event's time twice: before
        // and after it) replaces it: the values after the event are kept.
        if data.time.last() == Some(&t) {
            data.inputs.pop();
            data.outputs.pop();
        } else {
            data.time.push(t);
        }
        data.inputs.push(u);
        data.outputs.push(y);
    }
    if data.time.windows(2).any(|w| w[1] <= w[0]) {
        bail!(
            "{}: the times must increase from row to row",
            path.display()
        );
    }
    Ok(data)
}

/// Runs `spurio identify`; prints the report.
pub fn run(args: &IdentifyArgs) -> Result<()> {
    let (input_names, input_columns): (Vec<String>, Vec<String>) =
        args.input.iter().map(|e| mapping(e)).unzip();
    let (output_names, output_columns): (Vec<String>, Vec<String>) =
        args.output.iter().map(|e| mapping(e)).unzip();
    let request = Request {
        fmu: args.fmu.clone(),
        plant: PlantSpec {
            free: args.free.clone(),
            inputs: input_names,
            outputs: output_names,
        },
        tolerance: TOLERANCE,
        robust: Robust::named(&args.robust).unwrap_or(Robust::Huber),
        method: Method::named(&args.method).unwrap_or(Method::Ukf),
        validate: args.validate,
        noise: (!args.noise.is_empty()).then(|| args.noise.clone()),
        starts: values("--start", &args.start)?,
        set: values("--set", &args.set)?,
    };
    // The FMU and the names are checked before the data are read.
    let states = spurio_identify::session::check(&request)?;
    let data = read_data(&args.data, &input_columns, &output_columns)?;
    let outcome = identify(&request, &data)?;
    let report = write_outcome(&request, &outcome, states, &args.out)?;
    print!("{report}");
    println!("\nwrote {}", args.out.join("estimates.csv").display());
    Ok(())
}
