//! Result files in fmpy's CSV layout: a header of quoted names (`"time","x",…`) and one row
//! of full-precision numbers per communication point. Read with the `csv` crate, so a quoted
//! name may hold commas (`"est.A_hat[1,2]"`).

use std::path::{Path, PathBuf};

/// What is wrong with a results file.
#[derive(Debug, thiserror::Error)]
pub enum ResultsError {
    // The causes are in the messages, so they are no `source()` (a chain would repeat them).
    #[error("cannot read results file {}: {reason}", file.display())]
    Read { file: PathBuf, reason: String },
    #[error("in results file {}: {error}", file.display())]
    InFile {
        file: PathBuf,
        error: Box<ResultsError>,
    },
    #[error("the file is empty")]
    Empty,
    #[error("line {line}: {reason}")]
    Csv { line: u64, reason: String },
    #[error("line {line}: `{value}` is not a number")]
    NotANumber { line: u64, value: String },
    #[error("line {line}: {values} values for {columns} columns")]
    Width {
        line: u64,
        values: usize,
        columns: usize,
    },
    #[error("no column `{name}` (columns: {columns})")]
    NoColumn { name: String, columns: String },
}

/// The largest results file read (1 GiB): the table is held in memory
/// whole.
pub const MAX_RESULTS_BYTES: u64 = 1 << 30;

/// A table of named columns read from a results CSV.
#[derive(Debug, Clone, PartialEq)]
pub struct ResultTable {
    /// Column names, in file order.
    pub names: Vec<String>,
    /// Rows of values.
    pub rows: Vec<Vec<f64>>,
}

impl ResultTable {
    /// Reads `path`, of at most `max_bytes` bytes ([`MAX_RESULTS_BYTES`] unless a caller
    /// bounds it lower; no more is read, so an endless file such as `/dev/zero` is refused
    /// too); every error names the file and the line.
    pub fn read(path: &Path, max_bytes: u64) -> Result<Self, ResultsError> {
        let text = crate::data::read_text_at_most(
            path,
            max_bytes,
            "the results file",
            "the largest results file read",
        )
        .map_err(|reason| ResultsError::Read {
            file: path.to_path_buf(),
            reason,
        })?;
        Self::parse(&text).map_err(|e| ResultsError::InFile {
            file: path.to_path_buf(),
            error: Box::new(e),
        })
    }

    /// Parses CSV text (blank lines are skipped; `True`/`False` read as 1/0).
    pub fn parse(text: &str) -> Result<Self, ResultsError> {
        let mut reader = csv::ReaderBuilder::new()
            .has_headers(false)
            .flexible(true)
            .trim(csv::Trim::All)
            .from_reader(text.as_bytes());
        let mut records = reader.records();
        let line_of = |r: &csv::StringRecord| r.position().map_or(0, |p| p.line());
        let csv_error = |e: csv::Error| ResultsError::Csv {
            line: e.position().map_or(0, |p| p.line()),
            reason: e.to_string(),
        };
        let names: Vec<String> = match records.next() {
            None => return Err(ResultsError::Empty),
            Some(header) => header
                .map_err(csv_error)?
                .iter()
                .map(str::to_string)
                .collect(),
        };
        let mut rows = Vec::new();
        for record in records {
            let record = record.map_err(csv_error)?;
            let line = line_of(&record);
            if record.len() == 1 && record[0].is_empty() {
                continue;
            }
            if record.len() != names.len() {
                return Err(ResultsError::Width {
                    line,
                    values: record.len(),
                    columns: names.len(),
                });
            }
            let row = record
                .iter()
                .map(|v| match v {
                    "True" | "true" => Ok(1.0),
                    "False" | "false" => Ok(0.0),
                    _ => v.parse::<f64>().map_err(|_| ResultsError::NotANumber {
                        line,
                        value: v.to_string(),
                    }),
                })
                .collect::<Result<Vec<f64>, _>>()?;
            rows.push(row);
        }
        Ok(Self { names, rows })
    }

    /// The column called `name`, or an error listing the columns there are.
    pub fn column(&self, name: &str) -> Result<Vec<f64>, ResultsError> {
        let Some(j) = self.names.iter().position(|n| n == name) else {
            return Err(ResultsError::NoColumn {
                name: name.to_string(),
                columns: self.names.join(", "),
            });
        };
        Ok(self.rows.iter().map(|r| r[j]).collect())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An endless file (`/dev/zero`) is read no further than the bound, then refused.
    #[test]
    fn a_results_file_is_not_read_past_its_bound() {
        let e = ResultTable::read(Path::new("/dev/zero"), 1024)
            .unwrap_err()
            .to_string();
        assert_eq!(
            e,
            "cannot read results file /dev/zero: the results file is larger than 1024 bytes \
             (the largest results file read); not read"
        );
    }

    #[test]
    fn reads_fmpy_layout_and_names_missing_columns() {
        let t =
            ResultTable::parse("\"time\",\"y\",\"flag\"\n0.0,1.5,False\n0.1,-2e-3,True\n").unwrap();
        assert_eq!(t.column("y").unwrap(), vec![1.5, -2e-3]);
        assert_eq!(t.column("flag").unwrap(), vec![0.0, 1.0]);
        let e = t.column("z").unwrap_err().to_string();
        assert!(
            e.contains("no column `z`") && e.contains("time, y, flag"),
            "{e}"
        );
        let e = ResultTable::parse("\"a\",\"b\"\n1,2\n3\n").unwrap_err();
        assert!(
            matches!(
                e,
                ResultsError::Width {
                    line: 3,
                    values: 1,
                    columns: 2
                }
            ),
            "{e}"
        );
        let e = ResultTable::parse("\"a\",\"b\"\n1,2\n3,x\n").unwrap_err();
        assert_eq!(e.to_string(), "line 3: `x` is not a number");
        assert!(matches!(ResultTable::parse(""), Err(ResultsError::Empty)));
    }

    #[test]
    fn quoted_names_may_hold_commas() {
        let t = ResultTable::parse(
            "\"time\",\"est.A_hat[1,1]\",\"est.A_hat[1,2]\"\n0.0,1.0,2.5\n0.1,nan,-inf\n",
        )
        .unwrap();
        assert_eq!(t.names, ["time", "est.A_hat[1,1]", "est.A_hat[1,2]"]);
        assert_eq!(
            t.column("est.A_hat[1,2]").unwrap(),
            vec![2.5, f64::NEG_INFINITY]
        );
        assert!(t.column("est.A_hat[1,1]").unwrap()[1].is_nan());
    }
}
