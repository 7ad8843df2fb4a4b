//! fmpy's CSV layout of a run's records.

use super::Observer;
use std::io::Write;
use std::path::Path;

/// Writes fmpy's CSV layout with the `csv` crate: a header of quoted names (`"time","a.x",…`)
/// then full-precision rows (shortest representation that reads back to the same `f64`).
pub struct CsvWriter<W: Write> {
    state: CsvState<W>,
    number: ryu::Buffer,
}

enum CsvState<W: Write> {
    /// Before the header.
    Fresh(W),
    /// Writing rows.
    Rows(Box<csv::Writer<W>>),
    /// A write failed and took the output with it.
    Broken,
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
            state: CsvState::Fresh(out),
            number: ryu::Buffer::new(),
        }
    }

    /// Writes the rows so far (whole rows) through to the output.
    pub fn flush(&mut self) -> std::io::Result<()> {
        rows(&mut self.state)?.flush()
    }
}

/// The row writer, once the header is written.
fn rows<W: Write>(state: &mut CsvState<W>) -> std::io::Result<&mut csv::Writer<W>> {
    match state {
        CsvState::Rows(w) => Ok(w),
        _ => Err(std::io::Error::other(
            "CSV rows written before the header (Observer::start)",
        )),
    }
}

/// The text of one number: the shortest that reads back to the same `f64` (ryu), `nan`,
/// `inf` or `-inf` otherwise (as fmpy and pandas read them).
fn format_number(buffer: &mut ryu::Buffer, v: f64) -> &str {
    if v.is_finite() {
        buffer.format_finite(v)
    } else if v.is_nan() {
        "nan"
    } else if v > 0.0 {
        "inf"
    } else {
        "-inf"
    }
}

impl<W: Write> Observer for CsvWriter<W> {
    fn start(&mut self, names: &[String]) -> std::io::Result<()> {
        let CsvState::Fresh(out) = std::mem::replace(&mut self.state, CsvState::Broken) else {
            return Err(std::io::Error::other("the CSV header is written once"));
        };
        // The header quotes every name (as fmpy does); the rows quote nothing, they are
        // numbers.
        let mut header = csv::WriterBuilder::new()
            .quote_style(csv::QuoteStyle::Always)
            .from_writer(out);
        header.write_record(std::iter::once("time").chain(names.iter().map(String::as_str)))?;
        let out = header.into_inner().map_err(|e| e.into_error())?;
        self.state = CsvState::Rows(Box::new(
            csv::WriterBuilder::new()
                .quote_style(csv::QuoteStyle::Never)
                .from_writer(out),
        ));
        Ok(())
    }
    fn sample(&mut self, time: f64, values: &[f64]) -> std::io::Result<()> {
        let rows = rows(&mut self.state)?;
        for v in std::iter::once(&time).chain(values) {
            rows.write_field(format_number(&mut self.number, *v))?;
        }
        rows.write_record(None::<&[u8]>)?;
        Ok(())
    }
    fn finish(&mut self) -> std::io::Result<()> {
        rows(&mut self.state)?.flush()
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
        // Names with commas and quotes (matrix entries) stay one field each.
        let mut buf = Vec::new();
        {
            let mut w = CsvWriter::new(&mut buf);
            w.start(&["est.A_hat[1,2]".into(), "say \"hi\"".into()])
                .unwrap();
            w.sample(0.0, &[f64::NAN, f64::NEG_INFINITY]).unwrap();
            w.finish().unwrap();
        }
        assert_eq!(
            String::from_utf8(buf).unwrap(),
            "\"time\",\"est.A_hat[1,2]\",\"say \"\"hi\"\"\"\n0.0,nan,-inf\n"
        );
    }

    #[test]
    fn every_number_reads_back_to_the_same_f64() {
        // Shortest round-trip text: the values in the file are the values computed.
        let mut x = 0x2545_f491_4f6c_dd1d_u64;
        let mut values = vec![
            0.0,
            -0.0,
            1.0,
            1e16,
            1e-7,
            f64::MAX,
            f64::MIN_POSITIVE,
            5e-324,
            123456.789e-300,
        ];
        for _ in 0..2000 {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            let v = f64::from_bits(x);
            if v.is_finite() {
                values.push(v);
            }
        }
        let mut buf = Vec::new();
        {
            let mut w = CsvWriter::new(&mut buf);
            w.start(&["v".into()]).unwrap();
            for v in &values {
                w.sample(0.5, &[*v]).unwrap();
            }
            w.finish().unwrap();
        }
        let text = String::from_utf8(buf).unwrap();
        let read: Vec<f64> = text
            .lines()
            .skip(1)
            .map(|l| l.split_once(',').unwrap().1.parse().unwrap())
            .collect();
        assert_eq!(read.len(), values.len());
        for (r, v) in read.iter().zip(&values) {
            assert_eq!(r.to_bits(), v.to_bits(), "{v:?} read back as {r:?}");
        }
    }
}
