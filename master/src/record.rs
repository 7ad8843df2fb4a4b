//! Observers: where the engine sends recorded values (the loop does not know how results are
//! written).

#[cfg(feature = "systems")]
mod csv_writer;
#[cfg(feature = "systems")]
pub use csv_writer::CsvWriter;

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
