//! Sweeps: the same system run N times with different parameter values (seeds, gains, …) in
//! parallel, each run's instances created on its worker thread (rust-fmi instances are
//! `!Send`), and chosen metrics aggregated into a mean ± std table.

use rayon::prelude::*;
use spurio_master::fmu::VarType;
use spurio_master::{CallMonitor, Observer, RunError, RunOptions, Simulation};
use spurio_master::{StartValue, System, SystemError};
use std::fmt::Write as _;
use std::ops::Range;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// A metric or a variation that cannot be parsed; the text says where and why.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SpecError {
    #[error("{0}")]
    Metric(String),
    #[error("{0}")]
    Variation(String),
}

/// A summary of one recorded variable over a run.
#[derive(Debug, Clone, PartialEq)]
pub enum Metric {
    /// Value at the stop time.
    Final(String),
    /// Mean over the communication points.
    Mean(String),
    /// Root mean square.
    Rms(String),
    /// Largest absolute value.
    MaxAbs(String),
    /// Mean squared difference of two variables: E_res = (1/N)‖a − b‖².
    MeanSquaredError(String, String),
    /// First time after which |variable| stays below the bound for good (NaN if never).
    SettlingTime(String, f64),
}

impl Metric {
    /// Parses `final(x)`, `mean(x)`, `rms(x)`, `max_abs(x)`, `e_res(a, b)`, `settling(x, 0.005)`
    /// (`;` may separate the arguments too; labels use `;` so they stay one CSV field).
    pub fn parse(text: &str) -> Result<Self, SpecError> {
        Self::parse_text(text).map_err(SpecError::Metric)
    }

    fn parse_text(text: &str) -> Result<Self, String> {
        let text = text.trim();
        let (kind, rest) = text
            .split_once('(')
            .ok_or_else(|| format!("metric `{text}`: expected kind(variable)"))?;
        let args: Vec<String> = rest
            .strip_suffix(')')
            .ok_or_else(|| format!("metric `{text}`: missing `)`"))?
            .split([',', ';'])
            .map(|a| a.trim().to_string())
            .collect();
        let one = |m: fn(String) -> Metric| match args.as_slice() {
            [a] => Ok(m(a.clone())),
            _ => Err(format!("metric `{text}` takes one variable")),
        };
        match kind.trim() {
            "final" => one(Metric::Final),
            "mean" => one(Metric::Mean),
            "rms" => one(Metric::Rms),
            "max_abs" => one(Metric::MaxAbs),
            "e_res" => match args.as_slice() {
                [a, b] => Ok(Metric::MeanSquaredError(a.clone(), b.clone())),
                _ => Err(format!("metric `{text}` takes two variables")),
            },
            "settling" => match args.as_slice() {
                [a, b] => {
                    let bound: f64 = b
                        .parse()
                        .map_err(|_| format!("metric `{text}`: `{b}` is not a number"))?;
                    if !(bound.is_finite() && bound > 0.0) {
                        return Err(format!(
                            "metric `{text}`: the bound must be a positive number, got `{b}` \
                             (|value| < bound never holds)"
                        ));
                    }
                    Ok(Metric::SettlingTime(a.clone(), bound))
                }
                _ => Err(format!("metric `{text}` takes a variable and a bound")),
            },
            k => Err(format!(
                "unknown metric kind `{k}` (final, mean, rms, max_abs, e_res, settling)"
            )),
        }
    }

    /// The variables the metric reads.
    pub fn variables(&self) -> Vec<&str> {
        match self {
            Metric::Final(a)
            | Metric::Mean(a)
            | Metric::Rms(a)
            | Metric::MaxAbs(a)
            | Metric::SettlingTime(a, _) => {
                vec![a]
            }
            Metric::MeanSquaredError(a, b) => vec![a, b],
        }
    }

    /// The metric's label in tables.
    pub fn label(&self) -> String {
        match self {
            Metric::Final(a) => format!("final({a})"),
            Metric::Mean(a) => format!("mean({a})"),
            Metric::Rms(a) => format!("rms({a})"),
            Metric::MaxAbs(a) => format!("max_abs({a})"),
            Metric::MeanSquaredError(a, b) => format!("e_res({a};{b})"),
            Metric::SettlingTime(a, bound) => format!("settling({a};{bound})"),
        }
    }
}

/// Computes metrics while the run goes, without keeping the series.
struct MetricObserver<'a> {
    metrics: &'a [Metric],
    columns: Vec<Vec<usize>>,
    sums: Vec<f64>,
    last: Vec<f64>,
    samples: usize,
}

impl Observer for MetricObserver<'_> {
    fn start(&mut self, names: &[String]) -> std::io::Result<()> {
        self.columns = Vec::new();
        for m in self.metrics {
            let mut idx = Vec::new();
            for v in m.variables() {
                let j = names.iter().position(|n| n == v).ok_or_else(|| {
                    std::io::Error::other(format!(
                        "metric {}: `{v}` is not recorded (recorded: {})",
                        m.label(),
                        names.join(", ")
                    ))
                })?;
                idx.push(j);
            }
            self.columns.push(idx);
        }
        self.sums = vec![0.0; self.metrics.len()];
        self.last = vec![f64::NAN; self.metrics.len()];
        Ok(())
    }

    fn sample(&mut self, time: f64, values: &[f64]) -> std::io::Result<()> {
        self.samples += 1;
        for (k, m) in self.metrics.iter().enumerate() {
            let a = values[self.columns[k][0]];
            match m {
                Metric::Final(_) => self.last[k] = a,
                Metric::Mean(_) => self.sums[k] += a,
                Metric::Rms(_) => self.sums[k] += a * a,
                Metric::MaxAbs(_) => self.sums[k] = self.sums[k].max(a.abs()),
                Metric::MeanSquaredError(_, _) => {
                    let d = a - values[self.columns[k][1]];
                    self.sums[k] += d * d;
                }
                Metric::SettlingTime(_, bound) => {
                    if a.abs() >= *bound || a.is_nan() {
                        self.last[k] = f64::NAN; // not settled yet
                        self.sums[k] = f64::NAN;
                    } else if self.sums[k].is_nan() || self.samples == 1 {
                        self.sums[k] = time;
                    }
                }
            }
        }
        Ok(())
    }
}

impl MetricObserver<'_> {
    fn values(&self) -> Vec<f64> {
        let n = self.samples.max(1) as f64;
        self.metrics
            .iter()
            .enumerate()
            .map(|(k, m)| match m {
                Metric::Final(_) => self.last[k],
                Metric::Mean(_) | Metric::MeanSquaredError(_, _) => self.sums[k] / n,
                Metric::Rms(_) => (self.sums[k] / n).sqrt(),
                Metric::MaxAbs(_) | Metric::SettlingTime(_, _) => self.sums[k],
            })
            .collect()
    }
}

/// One parameter varied across the runs: `instance.variable` and one value per run.
#[derive(Debug, Clone)]
pub struct Variation {
    pub variable: String,
    pub values: Vec<f64>,
}

/// The most runs [`Variation::parse`] accepts.
pub const DEFAULT_MAX_RUNS: u64 = 1_000_000;

impl Variation {
    /// Parses `instance.var=1..100` (integers, inclusive) or `instance.var=0.1,0.2,0.3`, of
    /// at most [`DEFAULT_MAX_RUNS`] values.
    pub fn parse(text: &str) -> Result<Self, SpecError> {
        Self::parse_at_most(text, DEFAULT_MAX_RUNS)
    }

    /// [`Variation::parse`] of at most `max_runs` values: a longer range is refused before
    /// any value is made.
    pub fn parse_at_most(text: &str, max_runs: u64) -> Result<Self, SpecError> {
        Self::parse_text(text, max_runs).map_err(SpecError::Variation)
    }

    fn parse_text(text: &str, max_runs: u64) -> Result<Self, String> {
        let too_many = |n: u128| {
            format!(
                "--vary `{text}`: {n} runs, more than the {max_runs} allowed (--max-runs); \
                 cut the sweep into shards or raise --max-runs"
            )
        };
        let (variable, values) = text
            .split_once('=')
            .ok_or_else(|| format!("--vary `{text}`: expected instance.variable=values"))?;
        let values = if let Some((a, b)) = values.split_once("..") {
            let (a, b): (i64, i64) = (
                a.trim()
                    .parse()
                    .map_err(|_| format!("--vary `{text}`: `{a}` is not an integer"))?,
                b.trim()
                    .parse()
                    .map_err(|_| format!("--vary `{text}`: `{b}` is not an integer"))?,
            );
            let count = (i128::from(b) - i128::from(a) + 1).max(0) as u128;
            if count > u128::from(max_runs) {
                return Err(too_many(count));
            }
            (a..=b).map(|v| v as f64).collect()
        } else {
            let count = values.split(',').count() as u128;
            if count > u128::from(max_runs) {
                return Err(too_many(count));
            }
            values
                .split(',')
                .map(|v| {
                    v.trim()
                        .parse::<f64>()
                        .map_err(|_| format!("--vary `{text}`: `{v}` is not a number"))
                })
                .collect::<Result<Vec<_>, _>>()?
        };
        if values.is_empty() {
            return Err(format!("--vary `{text}`: no values"));
        }
        Ok(Self {
            variable: variable.trim().to_string(),
            values,
        })
    }
}

/// The metrics of every run (one row per run) and their mean ± std.
#[derive(Debug, Clone)]
pub struct SweepResult {
    pub metrics: Vec<Metric>,
    pub runs: Vec<Vec<f64>>,
}

impl SweepResult {
    /// Mean and sample standard deviation of metric `k` over the runs (NaN runs skipped).
    pub fn mean_std(&self, k: usize) -> (f64, f64, usize) {
        let v: Vec<f64> = self
            .runs
            .iter()
            .map(|r| r[k])
            .filter(|x| x.is_finite())
            .collect();
        let n = v.len();
        if n == 0 {
            return (f64::NAN, f64::NAN, 0);
        }
        let mean = v.iter().sum::<f64>() / n as f64;
        let var = if n > 1 {
            v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1) as f64
        } else {
            0.0
        };
        (mean, var.sqrt(), n)
    }

    /// A Markdown table: metric, mean ± std, runs counted.
    pub fn table(&self) -> String {
        let mut s = String::from("| metric | mean ± std | runs |\n|---|---|---|\n");
        for (k, m) in self.metrics.iter().enumerate() {
            let (mean, std, n) = self.mean_std(k);
            let _ = writeln!(
                s,
                "| {} | {mean:.6} ± {std:.6} | {n}/{} |",
                m.label(),
                self.runs.len()
            );
        }
        s
    }
}

/// Runs `system` once per value of `variation` on `threads` worker threads (0: one per core).
/// The first failed run (by run index) is the error.
pub fn sweep(
    system: &System,
    variation: &Variation,
    metrics: &[Metric],
    threads: usize,
) -> Result<SweepResult, RunError> {
    let runs = sweep_runs(
        system,
        variation,
        metrics,
        0..variation.values.len(),
        threads,
    )?;
    Ok(SweepResult {
        metrics: metrics.to_vec(),
        runs: runs.into_iter().collect::<Result<_, _>>()?,
    })
}

impl Variation {
    /// The varied variable of `system` (instance index, variable index), every value
    /// checked as a `parameters` entry is (a parameter or an unconnected input; an Integer
    /// takes only whole numbers, a Boolean 0 or 1).
    pub fn check(&self, system: &System) -> Result<(usize, usize), SystemError> {
        let (instance, variable) = self.variable.split_once('.').ok_or_else(|| {
            SystemError::Invalid(format!(
                "--vary `{}`: expected instance.variable",
                self.variable
            ))
        })?;
        let i = system
            .instances()
            .iter()
            .position(|inst| inst.name == instance)
            .ok_or_else(|| {
                SystemError::Invalid(format!("--vary: no instance called `{instance}`"))
            })?;
        let v = system.instances()[i]
            .fmu
            .index_of(variable)
            .ok_or_else(|| {
                SystemError::Invalid(format!(
                    "--vary: instance `{instance}` has no variable `{variable}`"
                ))
            })?;
        let var_type = system.instances()[i].fmu.variables[v].head.var_type;
        for value in &self.values {
            system.check_start_value(&self.variable, start_value(var_type, *value))?;
        }
        Ok((i, v))
    }
}

/// `x` as the start value of a variable of type `var_type`: a whole number for an Integer
/// or Enumeration, 0 or 1 for a Boolean (anything else stays a Real, which such a variable
/// refuses).
pub fn start_value(var_type: VarType, x: f64) -> StartValue {
    match var_type {
        VarType::Integer | VarType::Enumeration
            if x.fract() == 0.0 && x.abs() <= i64::MAX as f64 =>
        {
            StartValue::Integer(x as i64)
        }
        VarType::Boolean if x == 0.0 || x == 1.0 => StartValue::Boolean(x == 1.0),
        _ => StartValue::Real(x),
    }
}

/// Runs `system` once with `variable` (`instance.variable`) set to `value` and gives the
/// metrics; `monitor` (if any) sees every FMI call (see [`CallMonitor`]).
pub fn run_once(
    system: &System,
    variable: &str,
    value: f64,
    metrics: &[Metric],
    options: &RunOptions,
    monitor: Option<Arc<CallMonitor>>,
) -> Result<Vec<f64>, RunError> {
    let mut s = system.clone();
    let var_type = s.variable(variable)?.head.var_type;
    s.set_start_value(variable, start_value(var_type, value))?;
    let mut sim = Simulation::with_monitor(&s, monitor)?;
    let mut observer = MetricObserver {
        metrics,
        columns: Vec::new(),
        sums: Vec::new(),
        last: Vec::new(),
        samples: 0,
    };
    sim.run(&mut observer, options)?;
    sim.terminate()?;
    Ok(observer.values())
}

/// Runs the runs `runs` of the sweep (run `k` takes `variation.values[k]`, whoever runs it)
/// on `threads` worker threads (0: one per core), and gives each run's metrics or error, in
/// run order. The error of the whole call is a sweep that cannot start (an unknown varied
/// variable, a run range beyond the values, no thread pool).
pub fn sweep_runs(
    system: &System,
    variation: &Variation,
    metrics: &[Metric],
    runs: Range<usize>,
    threads: usize,
) -> Result<Vec<Result<Vec<f64>, RunError>>, RunError> {
    variation.check(system)?;
    let Some(values) = variation.values.get(runs.clone()) else {
        return Err(SystemError::Invalid(format!(
            "runs {}..{} of a sweep of {} runs",
            runs.start,
            runs.end,
            variation.values.len()
        ))
        .into());
    };
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .map_err(|e| SystemError::Invalid(format!("thread pool: {e}")))?;
    Ok(pool.install(|| {
        values
            .par_iter()
            .map(|value| {
                run_once(
                    system,
                    &variation.variable,
                    *value,
                    metrics,
                    &RunOptions::default(),
                    None,
                )
            })
            .collect()
    }))
}

/// The per-run table of a sweep cannot be written.
#[derive(Debug, thiserror::Error)]
pub enum TableError {
    /// The CSV error's text is the message's, not a source (said once).
    #[error("cannot write {}: {error}", path.display())]
    Write { path: PathBuf, error: csv::Error },
    #[error("{rows} rows of parameter values for {runs} runs")]
    Rows { rows: usize, runs: usize },
}

/// Writes a sweep's table: the per-run rows as CSV at `out` (when given; the varied
/// parameters then the metrics, names quoted, numbers bare in their shortest round-trip
/// form, fmpy's layout) and gives the Markdown mean ± std table ([`SweepResult::table`]).
/// The one writer of both the one-machine sweep and the merge of its shards, so that the
/// two give the same bytes.
pub fn write_table(
    out: Option<&Path>,
    parameters: &[String],
    values: &[Vec<f64>],
    result: &SweepResult,
) -> Result<String, TableError> {
    if values.len() != result.runs.len() {
        return Err(TableError::Rows {
            rows: values.len(),
            runs: result.runs.len(),
        });
    }
    if let Some(path) = out {
        let error = |error| TableError::Write {
            path: path.to_path_buf(),
            error,
        };
        let mut csv = csv::WriterBuilder::new()
            .quote_style(csv::QuoteStyle::NonNumeric)
            .from_path(path)
            .map_err(error)?;
        csv.write_record(
            parameters
                .iter()
                .cloned()
                .chain(result.metrics.iter().map(Metric::label)),
        )
        .map_err(error)?;
        for (row, metrics) in values.iter().zip(&result.runs) {
            csv.write_record(row.iter().chain(metrics).map(|v| format!("{v:?}")))
                .map_err(error)?;
        }
        csv.flush().map_err(|e| error(e.into()))?;
    }
    Ok(result.table())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn metrics_and_variations_parse_and_name_their_errors() {
        assert_eq!(
            Metric::parse("e_res(a.y[1], b.x)").unwrap(),
            Metric::MeanSquaredError("a.y[1]".into(), "b.x".into())
        );
        assert_eq!(
            Metric::parse("settling(c.x; 0.005)").unwrap(),
            Metric::SettlingTime("c.x".into(), 0.005)
        );
        assert!(Metric::parse("median(x)")
            .unwrap_err()
            .to_string()
            .contains("unknown metric kind `median`"));
        assert!(Metric::parse("rms(a, b)")
            .unwrap_err()
            .to_string()
            .contains("takes one variable"));
        assert_eq!(
            Variation::parse("s.seed=1..3").unwrap().values,
            vec![1.0, 2.0, 3.0]
        );
        assert_eq!(
            Variation::parse("c.k=0.5, 2").unwrap().values,
            vec![0.5, 2.0]
        );
        assert!(Variation::parse("c.k=a")
            .unwrap_err()
            .to_string()
            .contains("`a` is not a number"));
    }

    #[test]
    fn a_sweep_too_long_or_a_bound_that_cannot_hold_is_refused_at_parsing() {
        let e = Variation::parse("s.seed=1..99999999999").unwrap_err();
        assert_eq!(
            e.to_string(),
            "--vary `s.seed=1..99999999999`: 99999999999 runs, more than the 1000000 allowed \
             (--max-runs); cut the sweep into shards or raise --max-runs"
        );
        assert!(Variation::parse_at_most("s.seed=1..3", 2).is_err());
        assert!(Variation::parse_at_most("c.k=1,2,3", 2).is_err());
        assert_eq!(
            Variation::parse_at_most("s.seed=-9223372036854775808..9223372036854775807", 5)
                .unwrap_err()
                .to_string()
                .split(": ")
                .nth(1),
            Some("18446744073709551616 runs, more than the 5 allowed (--max-runs); cut the sweep into shards or raise --max-runs")
        );
        assert_eq!(
            Variation::parse_at_most("s.seed=1..2", 2)
                .unwrap()
                .values
                .len(),
            2
        );
        for bound in ["-1", "0", "nan", "inf"] {
            let e = Metric::parse(&format!("settling(x, {bound})")).unwrap_err();
            assert!(
                e.to_string()
                    .contains("the bound must be a positive number"),
                "{e}"
            );
        }
    }

    #[test]
    fn sweep_values_become_start_values_of_the_variables_type() {
        assert_eq!(start_value(VarType::Integer, 3.0), StartValue::Integer(3));
        assert_eq!(start_value(VarType::Integer, 0.5), StartValue::Real(0.5));
        assert_eq!(
            start_value(VarType::Enumeration, -2.0),
            StartValue::Integer(-2)
        );
        assert_eq!(
            start_value(VarType::Boolean, 1.0),
            StartValue::Boolean(true)
        );
        assert_eq!(
            start_value(VarType::Boolean, 0.0),
            StartValue::Boolean(false)
        );
        assert_eq!(start_value(VarType::Boolean, 2.0), StartValue::Real(2.0));
        assert_eq!(start_value(VarType::Real, 2.0), StartValue::Real(2.0));
        assert!(matches!(
            start_value(VarType::Integer, f64::NAN),
            StartValue::Real(x) if x.is_nan()
        ));
    }

    #[test]
    fn the_table_writer_gives_rows_in_round_trip_form_and_checks_their_count() {
        let result = SweepResult {
            metrics: vec![
                Metric::parse("rms(a.y[1])").unwrap(),
                Metric::parse("e_res(a.y, b.x)").unwrap(),
            ],
            runs: vec![vec![0.1 + 0.2, f64::NAN], vec![-0.0, 1e-300]],
        };
        let dir = std::env::temp_dir().join(format!("spurio-table-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("runs.csv");
        let parameters = vec!["a.seed".to_string()];
        let table =
            write_table(Some(&path), &parameters, &[vec![1.0], vec![2.5]], &result).unwrap();
        assert_eq!(table, result.table());
        assert_eq!(
            std::fs::read_to_string(&path).unwrap(),
            "\"a.seed\",\"rms(a.y[1])\",\"e_res(a.y;b.x)\"\n\
             1.0,0.30000000000000004,NaN\n\
             2.5,-0.0,1e-300\n"
        );
        let e = write_table(None, &parameters, &[vec![1.0]], &result).unwrap_err();
        assert_eq!(e.to_string(), "1 rows of parameter values for 2 runs");
        let empty = SweepResult {
            metrics: vec![],
            runs: vec![],
        };
        let e = write_table(Some(&dir.join("no/such.csv")), &parameters, &[], &empty).unwrap_err();
        assert!(e.to_string().contains("cannot write"), "{e}");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn metric_observer_computes_each_summary() {
        let metrics = [
            Metric::parse("final(a)").unwrap(),
            Metric::parse("mean(a)").unwrap(),
            Metric::parse("rms(a)").unwrap(),
            Metric::parse("max_abs(a)").unwrap(),
            Metric::parse("e_res(a, b)").unwrap(),
            Metric::parse("settling(a, 1.5)").unwrap(),
        ];
        let mut o = MetricObserver {
            metrics: &metrics,
            columns: Vec::new(),
            sums: Vec::new(),
            last: Vec::new(),
            samples: 0,
        };
        o.start(&["a".into(), "b".into()]).unwrap();
        for (t, a, b) in [
            (0.0, 3.0, 0.0),
            (1.0, -2.0, 0.0),
            (2.0, 1.0, 1.0),
            (3.0, 0.0, 0.0),
        ] {
            o.sample(t, &[a, b]).unwrap();
        }
        let v = o.values();
        assert_eq!(v[0], 0.0);
        assert_eq!(v[1], 0.5);
        assert!((v[2] - (14.0f64 / 4.0).sqrt()).abs() < 1e-15);
        assert_eq!(v[3], 3.0);
        assert_eq!(v[4], (9.0 + 4.0 + 0.0 + 0.0) / 4.0);
        assert_eq!(v[5], 2.0);
        assert!(o.start(&["b".into()]).is_err());
    }
}
