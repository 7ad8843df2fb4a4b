//! Observers: where the engine sends recorded values (the loop does not know how results are
//! written).

use std::io::Write;
use std::path::Path;

/// Receives the recorded variables at every communication point.
pub trait Observer {
    /// Called once before the first sample, with the recorded variables' names.
    fn start(&mut self, names: &[String]) -> std::io::Result<()>;
    /// One sample: the time and the values, in the order of `names`.
    fn sample(&mut self, time: f64, values: &[f64]) -> std::io::Result<()>;
    /// Called after the last sample.
    fn finish(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

/// Records nothing (for benchmarks and sweeps that keep only metrics).
#[derive(Debug, Default)]
pub struct NoRecording;

impl Observer for NoRecording {
    fn start(&mut self, _: &[String]) -> std::io::Result<()> {
        Ok(())
    }
    fn sample(&mut self, _: f64, _: &[f64]) -> std::io::Result<()> {
        Ok(())
    }
}

/// Keeps every sample in memory.
#[derive(Debug, Default, Clone)]
pub struct TimeSeries {
    pub names: Vec<String>,
    pub time: Vec<f64>,
    /// One row per sample.
    pub rows: Vec<Vec<f64>>,
}

impl TimeSeries {
    /// The series of variable `name`.
    pub fn column(&self, name: &str) -> Option<Vec<f64>> {
        let j = self.names.iter().position(|n| n == name)?;
        Some(self.rows.iter().map(|r| r[j]).collect())
    }
}

impl Observer for TimeSeries {
    fn start(&mut self, names: &[String]) -> std::io::Result<()> {
        self.names = names.to_vec();
        Ok(())
    }
    fn sample(&mut self, time: f64, values: &[f64]) -> std::io::Result<()> {
        self.time.push(time);
        self.rows.push(values.to_vec());
        Ok(())
    }
}

/// Sends a recorded series to another observer (e.g. memory → CSV).
pub fn replay(series: &TimeSeries, observer: &mut dyn Observer) -> std::io::Result<()> {
    observer.start(&series.names)?;
    for (t, row) in series.time.iter().zip(&series.rows) {
        observer.sample(*t, row)?;
    }
    observer.finish()
}

/// Writes fmpy's CSV layout: `"time","a.x",…` then full-precision rows (shortest
/// representation that reads back to the same `f64`).
pub struct CsvWriter<W: Write> {
    out: W,
    line: String,
}

impl CsvWriter<std::io::BufWriter<std::fs::File>> {
    /// A writer to `path`.
    pub fn create(path: &Path) -> std::io::Result<Self> {
        Ok(Self::new(std::io::BufWriter::new(std::fs::File::create(
            path,
        )?)))
    }
}

impl<W: Write> CsvWriter<W> {
    /// A writer to `out`.
    pub fn new(out: W) -> Self {
        Self {
            out,
            line: String::with_capacity(256),
        }
    }
}

fn push_number(line: &mut String, v: f64) {
    use std::fmt::Write as _;
    if v.is_finite() {
        let _ = write!(line, "{v:?}");
    } else {
        line.push_str(if v.is_nan() {
            "nan"
        } else if v > 0.0 {
            "inf"
        } else {
            "-inf"
        });
    }
}

impl<W: Write> Observer for CsvWriter<W> {
    fn start(&mut self, names: &[String]) -> std::io::Result<()> {
        let header: Vec<String> = std::iter::once("time".to_string())
            .chain(names.iter().cloned())
            .map(|n| format!("\"{}\"", n.replace('"', "\"\"")))
            .collect();
        writeln!(self.out, "{}", header.join(","))
    }
    fn sample(&mut self, time: f64, values: &[f64]) -> std::io::Result<()> {
        self.line.clear();
        push_number(&mut self.line, time);
        for v in values {
            self.line.push(',');
            push_number(&mut self.line, *v);
        }
        self.line.push('\n');
        self.out.write_all(self.line.as_bytes())
    }
    fn finish(&mut self) -> std::io::Result<()> {
        self.out.flush()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn csv_is_in_fmpy_layout_with_full_precision() {
        let mut buf = Vec::new();
        {
            let mut w = CsvWriter::new(&mut buf);
            w.start(&["crane.x".into(), "s.y[1]".into()]).unwrap();
            w.sample(0.1, &[0.1 + 0.2, -1e-300]).unwrap();
            w.finish().unwrap();
        }
        let text = String::from_utf8(buf).unwrap();
        assert_eq!(
            text,
            "\"time\",\"crane.x\",\"s.y[1]\"\n0.1,0.30000000000000004,-1e-300\n"
        );
    }
}
