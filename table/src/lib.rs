//! Recorded signals as a table: a CSV file in the layout `spurio run` writes and fmpy reads (a
//! `time` column, one column per signal, units in the header as `name [unit]` or in a units
//! row), checked whole when it is read, and read at any time through a [`Cursor`] (no search,
//! no allocation per read). The one reader and the one interpolation of the master's data
//! source (a system instance `data = "rig.csv"`) and of the `TimeTable` FMU
//! (`spurio package-data`), so both give the same value at the same time, bit for bit.
//!
//! At time t, between samples t_i ≤ t < t_{i+1}, a column u reads
//!
//! - hold: u(t) = u_i (exactly the sample at or before t);
//! - linear: u(t) = u_i + (u_{i+1} − u_i)·((t − t_i)/(t_{i+1} − t_i)), and exactly u_i at
//!   t = t_i.
//!
//! Before the first sample a column reads it, after the last sample the last one (the
//! master refuses a system whose start or stop lies outside the samples, the FMU a step that
//! would leave them: [`DataTable::check_range`]).
//!
//! A sample time within rounding of t is at t ([`DataTable::reached`]): t_i counts as at or
//! before t when t_i ≤ t + [`instant::tolerance`]`(i)`·Δ_i, Δ_i the sampling interval at
//! sample i, the rule by which every discrete-time FMU's sample clock meets the master's
//! communication points (docs/models.md, `spurio_fmu_common::clock`).
//!
//! An empty cell or `nan` is a missing sample: it reads as NaN (hold: until the next sample;
//! linear: on both intervals next to it), and the column's validity flag
//! ([`Reading::Valid`]) reads 0 there, 1 elsewhere; [`Reading::Held`] reads the last present
//! sample instead.

pub mod declaration;
pub mod instant;

use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// How a data instance reads between its samples.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Interpolation {
    /// The last sample at or before t (zero-order hold).
    #[default]
    Hold,
    /// The straight line between the samples around t.
    Linear,
}

impl Interpolation {
    /// Its name in a system file and in the `TimeTable` FMU's configuration: `hold`, `linear`.
    pub fn name(self) -> &'static str {
        match self {
            Interpolation::Hold => "hold",
            Interpolation::Linear => "linear",
        }
    }

    /// The interpolation called `name` ([`Interpolation::name`]).
    pub fn named(name: &str) -> Option<Self> {
        [Interpolation::Hold, Interpolation::Linear]
            .into_iter()
            .find(|i| i.name() == name)
    }

    /// Its code as the `TimeTable` FMU's Integer parameter `interpolation`: 1 hold, 2 linear.
    pub fn code(self) -> i32 {
        match self {
            Interpolation::Hold => 1,
            Interpolation::Linear => 2,
        }
    }

    /// The interpolation of code `code` ([`Interpolation::code`]).
    pub fn of_code(code: i32) -> Option<Self> {
        [Interpolation::Hold, Interpolation::Linear]
            .into_iter()
            .find(|i| i.code() == code)
    }
}

/// The suffix of the Boolean output that says whether a column has a sample at t
/// (`rig.force.valid`).
pub const VALID_SUFFIX: &str = ".valid";

/// The suffix of the Real output that holds the last present sample over missing ones
/// (`rig.force.held`): finite wherever the column has had a sample (0 before its first), for
/// an input that refuses NaN while its validity flag says the value is no measurement.
pub const HELD_SUFFIX: &str = ".held";

/// What a data instance's output reads of its column.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Reading {
    /// The column (NaN at a missing sample).
    Value,
    /// 1 where the column has a sample, 0 where it is missing (`<column>.valid`).
    Valid,
    /// The column with every missing sample replaced by the last present one
    /// (`<column>.held`).
    Held,
}

impl Reading {
    /// Every reading of a column, in the order of its outputs.
    pub const ALL: [Reading; 3] = [Reading::Value, Reading::Valid, Reading::Held];

    /// The description of the output reading column `column` of `file`.
    pub fn describe(self, column: &str, file: &str) -> String {
        match self {
            Reading::Value => format!("column `{column}` of {file}"),
            Reading::Valid => {
                format!("whether column `{column}` has a sample (false where it is missing)")
            }
            Reading::Held => format!(
                "column `{column}` with each missing sample replaced by the last present one"
            ),
        }
    }

    /// The suffix of its output's name.
    pub fn suffix(self) -> &'static str {
        match self {
            Reading::Value => "",
            Reading::Valid => VALID_SUFFIX,
            Reading::Held => HELD_SUFFIX,
        }
    }
}

/// What is wrong with a data file, naming the file, the line and the column.
#[derive(Debug, thiserror::Error)]
pub enum DataError {
    #[error("data file {}: {reason}", file.display())]
    File { file: PathBuf, reason: String },
    #[error("data file {}, line {line}: {reason}", file.display())]
    Line {
        file: PathBuf,
        line: u64,
        reason: String,
    },
    #[error("data file {}, line {line}, column {column} (`{name}`): {reason}", file.display())]
    Cell {
        file: PathBuf,
        line: u64,
        /// 1 for the first column of the file.
        column: usize,
        name: String,
        reason: String,
    },
    #[error("data file {}, line {line}: no column `{name}` (the columns are: {columns})", file.display())]
    NoColumn {
        file: PathBuf,
        /// The header's line.
        line: u64,
        name: String,
        columns: String,
    },
}

/// A table's signals as its header gives them, and how they are read between samples: what a
/// [`DataTable`] read and its [`declaration::Declaration`] in a `TimeTable` FMU have in
/// common.
#[derive(Debug, Clone, PartialEq)]
pub struct Signals {
    pub interpolation: Interpolation,
    /// The signal columns' names, in file order (without `time`).
    pub names: Vec<String>,
    /// The unit of each signal column, if the file gives one.
    pub units: Vec<Option<String>>,
}

/// A table of recorded signals: sample times and one column of values per signal.
#[derive(Debug, Clone, PartialEq)]
pub struct DataTable {
    /// The file it was read from.
    pub file: PathBuf,
    pub signals: Signals,
    /// The sample times, strictly increasing.
    pub times: Vec<f64>,
    /// `columns[j][i]`: signal j at sample i (NaN: missing).
    pub columns: Vec<Vec<f64>>,
    /// `held[j][i]`: the last present sample of signal j at or before sample i (0 before
    /// the first).
    pub held: Vec<Vec<f64>>,
    /// The file's line of each sample.
    pub lines: Vec<u64>,
    /// The file's column (1-based) of `time`.
    pub time_column: usize,
    /// The header's line.
    pub header_line: u64,
}

/// Where a reader of a [`DataTable`] is: the last sample at or before the time last read.
/// Reading at increasing times advances it by the samples passed (none or one per step when
/// the step is not shorter than the sampling interval); reading at an earlier time starts
/// again from the first sample.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Cursor {
    index: usize,
}

impl Cursor {
    /// A cursor at sample `index` (as [`Cursor::sample`] gave it: an FMU state restored);
    /// [`DataTable::seek`] starts again from the first sample if the table has no such
    /// sample or it is after the time sought.
    pub fn at(index: usize) -> Self {
        Self { index }
    }

    /// The sample it is at.
    pub fn sample(self) -> usize {
        self.index
    }
}

/// The text of file `path` (`what`, e.g. "the data file"), refused when it is larger than
/// `max_bytes` (named as the loader's limit `limit`); no more than `max_bytes + 1` bytes are
/// read, so an endless file such as `/dev/zero` is refused too.
pub fn read_text_at_most(
    path: &Path,
    max_bytes: u64,
    what: &str,
    limit: &str,
) -> Result<String, String> {
    use std::io::Read;
    let too_large = || format!("{what} is larger than {max_bytes} bytes ({limit}); not read");
    let file = std::fs::File::open(path).map_err(|e| e.to_string())?;
    if file
        .metadata()
        .is_ok_and(|m| m.is_file() && m.len() > max_bytes)
    {
        return Err(too_large());
    }
    let mut bytes = Vec::new();
    file.take(max_bytes.saturating_add(1))
        .read_to_end(&mut bytes)
        .map_err(|e| e.to_string())?;
    if bytes.len() as u64 > max_bytes {
        return Err(too_large());
    }
    String::from_utf8(bytes).map_err(|e| format!("{what} is not UTF-8 text: {e}"))
}

/// One cell as a number: empty or `nan` is a missing sample (NaN), `true`/`false` are 1/0.
fn cell_value(text: &str) -> Option<f64> {
    match text {
        "" => Some(f64::NAN),
        "true" | "True" | "TRUE" => Some(1.0),
        "false" | "False" | "FALSE" => Some(0.0),
        _ => text.parse::<f64>().ok(),
    }
}

/// A header cell `name [unit]` as (name, unit).
pub fn name_and_unit(cell: &str) -> (String, Option<String>) {
    if let Some(open) = cell.rfind(" [") {
        if let Some(unit) = cell[open + 2..].strip_suffix(']') {
            let unit = unit.trim();
            return (
                cell[..open].trim().to_string(),
                (!unit.is_empty()).then(|| unit.to_string()),
            );
        }
    }
    (cell.to_string(), None)
}

/// A units-row cell (`m`, `[m]`, or empty) as a unit.
fn unit_cell(cell: &str) -> Option<String> {
    let unit = cell
        .strip_prefix('[')
        .and_then(|u| u.strip_suffix(']'))
        .unwrap_or(cell)
        .trim();
    (!unit.is_empty()).then(|| unit.to_string())
}

impl DataTable {
    /// Reads and checks `path` (see [`DataTable::parse`]), refusing a file of more than
    /// `max_bytes` bytes (the loader's `max_unpacked`: a table is held in memory whole, as an
    /// FMU's unpacked files are on disk).
    pub fn read(
        path: &Path,
        interpolation: Interpolation,
        max_bytes: u64,
    ) -> Result<Self, DataError> {
        let text = read_text_at_most(path, max_bytes, "the data file", "max_unpacked").map_err(
            |reason| DataError::File {
                file: path.to_path_buf(),
                reason,
            },
        )?;
        Self::parse(&text, path, interpolation)
    }

    /// Parses CSV `text` (named `file` in errors): a header of column names, one of them
    /// `time`, each `name` or `name [unit]`; optionally a units row right after it (a row none
    /// of whose cells is a number); then one row per sample. Every cell of a sample is a number
    /// (`true`/`false` read as 1/0), or empty or `nan` for a missing sample; the times are
    /// finite, present and strictly increasing. Blank lines are skipped. Every error names
    /// the line and the column.
    pub fn parse(text: &str, file: &Path, interpolation: Interpolation) -> Result<Self, DataError> {
        let file = file.to_path_buf();
        let mut reader = csv::ReaderBuilder::new()
            .has_headers(false)
            .flexible(true)
            .trim(csv::Trim::All)
            .from_reader(text.as_bytes());
        // The csv crate gives a record the position where it began reading it, before the
        // blank lines it skips: the line is counted past them.
        let line_of = |r: &csv::StringRecord| {
            r.position().map_or(0, |p| {
                let rest = text
                    .get(usize::try_from(p.byte()).unwrap_or(0)..)
                    .unwrap_or("");
                let blank = rest.bytes().take_while(|b| matches!(b, b'\n' | b'\r'));
                p.line() + blank.filter(|&b| b == b'\n').count() as u64
            })
        };
        let mut records = reader.records().filter(|r| match r {
            Ok(r) => !(r.len() == 1 && r[0].is_empty()),
            Err(_) => true,
        });
        let csv_error = |e: csv::Error| DataError::Line {
            file: file.clone(),
            line: e.position().map_or(0, |p| p.line()),
            reason: e.to_string(),
        };
        let header = match records.next() {
            None => {
                return Err(DataError::File {
                    file,
                    reason: "the file is empty (expected a header with a `time` column)".into(),
                })
            }
            Some(h) => h.map_err(csv_error)?,
        };
        let header_line = line_of(&header);
        let mut all_names = Vec::with_capacity(header.len());
        let mut all_units = Vec::with_capacity(header.len());
        for (c, cell) in header.iter().enumerate() {
            let (name, unit) = name_and_unit(cell);
            let fail = |reason: String| DataError::Cell {
                file: file.clone(),
                line: header_line,
                column: c + 1,
                name: cell.to_string(),
                reason,
            };
            if name.is_empty() {
                return Err(fail("the column has no name".into()));
            }
            if all_names.contains(&name) {
                return Err(fail(format!("a second column called `{name}`")));
            }
            all_names.push(name);
            all_units.push(unit);
        }
        let Some(time_column) = all_names.iter().position(|n| n == "time") else {
            return Err(DataError::Line {
                file,
                line: header_line,
                reason: format!(
                    "no `time` column (the columns are: {})",
                    all_names.join(", ")
                ),
            });
        };
        for (c, name) in all_names.iter().enumerate() {
            for suffix in [VALID_SUFFIX, HELD_SUFFIX] {
                let Some(base) = name.strip_suffix(suffix) else {
                    continue;
                };
                if all_names.iter().any(|n| n == base) {
                    return Err(DataError::Cell {
                        file,
                        line: header_line,
                        column: c + 1,
                        name: name.clone(),
                        reason: format!(
                            "clashes with the output `{name}` derived from column `{base}`; rename it"
                        ),
                    });
                }
            }
        }
        let width = all_names.len();
        let mut times = Vec::new();
        let mut lines = Vec::new();
        let mut columns: Vec<Vec<f64>> = vec![Vec::new(); width - 1];
        let mut first_row = true;
        for record in records {
            let record = record.map_err(csv_error)?;
            let line = line_of(&record);
            if record.len() != width {
                return Err(DataError::Line {
                    file,
                    line,
                    reason: format!("{} cells for {width} columns", record.len()),
                });
            }
            if std::mem::take(&mut first_row)
                && record
                    .iter()
                    .all(|c| c.is_empty() || cell_value(c).is_none())
            {
                for (c, cell) in record.iter().enumerate() {
                    if let Some(u) = unit_cell(cell) {
                        all_units[c] = Some(u);
                    }
                }
                continue;
            }
            let mut signal = 0;
            for (c, cell) in record.iter().enumerate() {
                let fail = |reason: String| DataError::Cell {
                    file: file.clone(),
                    line,
                    column: c + 1,
                    name: all_names[c].clone(),
                    reason,
                };
                let Some(value) = cell_value(cell) else {
                    return Err(fail(format!(
                        "`{cell}` is not a number (an empty cell or `nan` is a missing sample)"
                    )));
                };
                if c == time_column {
                    if !value.is_finite() {
                        return Err(fail(if cell.is_empty() {
                            "the time is missing".to_string()
                        } else {
                            format!("the time `{cell}` is not finite")
                        }));
                    }
                    if let (Some(&before), Some(&before_line)) = (times.last(), lines.last()) {
                        if value <= before {
                            return Err(fail(format!(
                                "time {value} does not increase (line {before_line} has {before})"
                            )));
                        }
                    }
                    times.push(value);
                } else {
                    columns[signal].push(value);
                    signal += 1;
                }
            }
            lines.push(line);
        }
        if times.is_empty() {
            return Err(DataError::Line {
                file,
                line: header_line,
                reason: "no samples after the header".into(),
            });
        }
        let held = columns
            .iter()
            .map(|column| {
                let mut last = 0.0;
                column
                    .iter()
                    .map(|&v| {
                        if !v.is_nan() {
                            last = v;
                        }
                        last
                    })
                    .collect()
            })
            .collect();
        let mut names = all_names;
        let mut units = all_units;
        names.remove(time_column);
        units.remove(time_column);
        Ok(Self {
            file,
            signals: Signals {
                interpolation,
                names,
                units,
            },
            times,
            columns,
            held,
            lines,
            time_column: time_column + 1,
            header_line,
        })
    }

    /// The first sample time.
    pub fn start(&self) -> f64 {
        self.times.first().copied().unwrap_or(f64::NAN)
    }

    /// The last sample time.
    pub fn end(&self) -> f64 {
        self.times.last().copied().unwrap_or(f64::NAN)
    }

    /// The index of the column called `name`, or an error naming the file, the header line
    /// and the columns there are.
    pub fn column(&self, name: &str) -> Result<usize, DataError> {
        self.signals
            .names
            .iter()
            .position(|n| n == name)
            .ok_or_else(|| self.no_column(name))
    }

    /// The error for a column `name` this table does not have.
    pub fn no_column(&self, name: &str) -> DataError {
        DataError::NoColumn {
            file: self.file.clone(),
            line: self.header_line,
            name: name.to_string(),
            columns: self.signals.names.join(", "),
        }
    }

    /// Checks that [`start`, `stop`] lies within the samples (a value exists at every
    /// communication point), naming the first or last sample's line.
    pub fn check_range(&self, start: f64, stop: f64) -> Result<(), DataError> {
        let cell = |i: usize, reason: String| DataError::Cell {
            file: self.file.clone(),
            line: self.lines[i],
            column: self.time_column,
            name: "time".into(),
            reason,
        };
        if !self.reached(0, start) {
            return Err(cell(
                0,
                format!(
                    "the system starts at {start}, before the first sample ({})",
                    self.start()
                ),
            ));
        }
        if !self.not_passed(stop) {
            return Err(cell(
                self.times.len() - 1,
                format!(
                    "the system's stop time {stop} is past the data, whose last sample is at {}",
                    self.end()
                ),
            ));
        }
        Ok(())
    }

    /// The sampling interval at sample `i`: Δ_i = t_i − t_{i−1}, for the first sample the
    /// interval after it, t_1 − t_0; 0 for a table of one sample (then times compare exactly).
    #[inline]
    pub fn interval(&self, i: usize) -> f64 {
        let t = &self.times;
        match (
            i.checked_sub(1).and_then(|b| t.get(b)),
            t.get(i),
            t.get(i + 1),
        ) {
            (Some(&before), Some(&ti), _) => ti - before,
            (None, Some(&ti), Some(&next)) => next - ti,
            _ => 0.0,
        }
    }

    /// Whether sample `i` is at or before time `t`, up to rounding:
    /// t_i ≤ t + [`instant::tolerance`]`(i)`·Δ_i ([`DataTable::interval`]), so that decimal
    /// sample times (0.15) and the communication points of a master (t_0 + k·h,
    /// 0.15000000000000002, or time accumulated step by step as OMSimulator does) are the same
    /// instant; the tolerance grows with the accumulated drift (k²·ε/2 intervals after k
    /// steps) and stays far below any interval. Times written by `spurio run` are the
    /// t_k themselves, exactly. `false` for a sample the table does not have.
    #[inline]
    pub fn reached(&self, i: usize, t: f64) -> bool {
        self.times
            .get(i)
            .is_some_and(|&ti| ti <= t + instant::tolerance(i as f64) * self.interval(i))
    }

    /// Whether time `t` is not past the last sample, by the rule of [`DataTable::reached`]:
    /// t ≤ t_n + tolerance(n)·Δ_n.
    #[inline]
    pub fn not_passed(&self, t: f64) -> bool {
        let n = self.times.len().saturating_sub(1);
        t <= self.end() + instant::tolerance(n as f64) * self.interval(n)
    }

    /// Moves `cursor` to the last sample at or before `t` (the first sample when `t` is
    /// before it); a sample time within rounding of t ([`DataTable::reached`]) counts as at t.
    #[inline]
    pub fn seek(&self, cursor: &mut Cursor, t: f64) {
        if !self.reached(cursor.index, t) {
            cursor.index = 0;
        }
        while self.reached(cursor.index + 1, t) {
            cursor.index += 1;
        }
    }

    /// Column `j` at time `t`, `cursor` having been moved to `t` ([`DataTable::seek`]).
    #[inline]
    pub fn value(&self, cursor: Cursor, j: usize, t: f64) -> f64 {
        self.value_as(self.signals.interpolation, cursor, j, t)
    }

    /// Column `j` at time `t` interpolated as `interpolation` (whatever the table's own),
    /// `cursor` having been moved to `t` ([`DataTable::seek`]).
    #[inline]
    pub fn value_as(&self, interpolation: Interpolation, cursor: Cursor, j: usize, t: f64) -> f64 {
        let (i, column) = (cursor.index, &self.columns[j]);
        let (ti, ui) = (self.times[i], column[i]);
        match interpolation {
            Interpolation::Hold => ui,
            Interpolation::Linear => {
                // A time within rounding of the sample ([`DataTable::reached`]) is at it:
                // exactly u_i, never a hair along the line (to a missing sample: NaN).
                if t - ti <= instant::tolerance(i as f64) * self.interval(i) {
                    return ui;
                }
                match (self.times.get(i + 1), column.get(i + 1)) {
                    (Some(&tn), Some(&un)) => ui + (un - ui) * ((t - ti) / (tn - ti)),
                    _ => ui,
                }
            }
        }
    }

    /// Column `j` read as `reading` at time `t`, `cursor` having been moved to `t`
    /// ([`DataTable::seek`]).
    #[inline]
    pub fn reading(&self, cursor: Cursor, j: usize, reading: Reading, t: f64) -> f64 {
        self.reading_as(self.signals.interpolation, cursor, j, reading, t)
    }

    /// Column `j` read as `reading` at time `t` and interpolated as `interpolation`,
    /// `cursor` having been moved to `t` ([`DataTable::seek`]).
    #[inline]
    pub fn reading_as(
        &self,
        interpolation: Interpolation,
        cursor: Cursor,
        j: usize,
        reading: Reading,
        t: f64,
    ) -> f64 {
        let value = self.value_as(interpolation, cursor, j, t);
        match reading {
            Reading::Value => value,
            Reading::Valid => {
                if value.is_nan() {
                    0.0
                } else {
                    1.0
                }
            }
            Reading::Held if value.is_nan() => self.held[j][cursor.index],
            Reading::Held => value,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn table(text: &str, interpolation: Interpolation) -> DataTable {
        DataTable::parse(text, Path::new("rig.csv"), interpolation).unwrap()
    }

    fn error(text: &str) -> String {
        DataTable::parse(text, Path::new("rig.csv"), Interpolation::Hold)
            .unwrap_err()
            .to_string()
    }

    fn at(t: &DataTable, j: usize, times: &[f64]) -> Vec<f64> {
        let mut cursor = Cursor::default();
        times
            .iter()
            .map(|&time| {
                t.seek(&mut cursor, time);
                t.value(cursor, j, time)
            })
            .collect()
    }

    #[test]
    fn units_come_from_the_header_or_a_units_row() {
        let t = table(
            "\"time\",\"force [N]\",\"x\"\n1.0,2,3\n",
            Interpolation::Hold,
        );
        assert_eq!(t.signals.names, ["force", "x"]);
        assert_eq!(t.signals.units, [Some("N".to_string()), None]);
        let t = table("time,force,y[1]\n[s],N,[m]\n0,2,3\n", Interpolation::Hold);
        assert_eq!(t.signals.names, ["force", "y[1]"]);
        assert_eq!(
            t.signals.units,
            [Some("N".to_string()), Some("m".to_string())]
        );
        assert_eq!(t.times, [0.0]);
        assert_eq!(t.lines, [3]);
    }

    #[test]
    fn hold_is_exact_at_and_between_samples() {
        let t = table("time,u\n0,0.1\n0.3,0.7\n0.6,-2.5\n", Interpolation::Hold);
        let times = [0.0, 0.1, 0.2999, 0.3, 0.45, 0.6];
        assert_eq!(at(&t, 0, &times), [0.1, 0.1, 0.1, 0.7, 0.7, -2.5]);
        // A communication point within rounding of a sample time is at it: 0.1·3 and one
        // ulp below 0.3.
        let below = f64::from_bits(0.3f64.to_bits() - 1);
        assert_eq!(at(&t, 0, &[0.1 * 3.0, below]), [0.7, 0.7]);
        assert_eq!(at(&t, 0, &[0.3 - 1e-9]), [0.1]);
        // Going back in time starts again from the first sample.
        assert_eq!(at(&t, 0, &[0.6, 0.0]), [-2.5, 0.1]);
    }

    #[test]
    fn time_accumulated_step_by_step_meets_every_sample() {
        // 200 000 samples 1 ms apart, read at t += 0.001 (OMSimulator's clock): the sum drifts
        // from k·0.001 by about 2·10⁻⁹ s at the end, 10⁴ times the old 16 ε·t; the growing
        // tolerance keeps every read on its own sample.
        let n = 200_000;
        let mut text = String::from("time,k\n");
        for k in 0..n {
            text.push_str(&format!("{},{k}\n", k as f64 * 0.001));
        }
        let t = table(&text, Interpolation::Hold);
        let (mut cursor, mut time, mut off) = (Cursor::default(), 0.0f64, 0usize);
        for k in 0..n {
            t.seek(&mut cursor, time);
            off += usize::from(t.value(cursor, 0, time) != k as f64);
            time += 0.001;
        }
        assert_eq!(off, 0);
        let drift = (time - 0.001 - (n - 1) as f64 * 0.001).abs();
        assert!(drift > 16.0 * f64::EPSILON * 200.0, "{drift}");
    }

    #[test]
    fn linear_is_exact_at_samples_and_on_the_line_between() {
        let t = table("time,u\n0,0.1\n0.3,0.7\n0.6,-2.5\n", Interpolation::Linear);
        let v = at(&t, 0, &[0.0, 0.1, 0.3, 0.45, 0.6]);
        assert_eq!(v[0], 0.1);
        assert_eq!(v[2], 0.7);
        assert_eq!(v[4], -2.5);
        assert!((v[1] - 0.3).abs() <= 4.0 * f64::EPSILON * 0.3, "{}", v[1]);
        // Within rounding of a sample time (0.1·3, one ulp above 0.3): exactly the sample.
        let above = f64::from_bits(0.3f64.to_bits() + 1);
        assert_eq!(at(&t, 0, &[0.1 * 3.0, above]), [0.7, 0.7]);
        // Next to a missing sample, a hair after the present one still reads it.
        let gap = table("time,u\n0,1\n0.1,2\n0.2,\n", Interpolation::Linear);
        assert_eq!(
            at(&gap, 0, &[0.1 + 1e-17, 0.30000000000000004 - 0.2]),
            [2.0, 2.0]
        );
        assert!((v[3] - (-0.9)).abs() <= 4.0 * f64::EPSILON, "{}", v[3]);
    }

    #[test]
    fn missing_samples_read_nan_and_invalid() {
        let t = table("time,a,b\n0,1,\n1,nan,2\n2,3,NaN\n", Interpolation::Hold);
        let a = at(&t, 0, &[0.0, 0.5, 1.0, 2.0]);
        assert_eq!(a[0], 1.0);
        assert_eq!(a[1], 1.0);
        assert!(a[2].is_nan());
        assert_eq!(a[3], 3.0);
        let read = |reading| -> Vec<f64> {
            let mut cursor = Cursor::default();
            [0.0, 0.5, 1.0, 1.5, 2.0]
                .iter()
                .map(|&time| {
                    t.seek(&mut cursor, time);
                    t.reading(cursor, 0, reading, time)
                })
                .collect()
        };
        assert_eq!(read(Reading::Valid), [1.0, 1.0, 0.0, 0.0, 1.0]);
        assert_eq!(read(Reading::Held), [1.0, 1.0, 1.0, 1.0, 3.0]);
        // Before a column's first sample, held reads 0.
        let mut cursor = Cursor::default();
        t.seek(&mut cursor, 0.0);
        assert_eq!(t.reading(cursor, 1, Reading::Held, 0.0), 0.0);
        let b = at(&t, 1, &[0.0, 1.0, 1.5, 2.0]);
        assert!(b[0].is_nan() && b[3].is_nan());
        assert_eq!(b[1..3], [2.0, 2.0]);
        let lin = table("time,a\n0,1\n1,\n2,3\n", Interpolation::Linear);
        let a = at(&lin, 0, &[0.0, 0.5, 1.0, 1.5, 2.0]);
        assert_eq!(a[0], 1.0);
        assert!(a[1].is_nan() && a[2].is_nan() && a[3].is_nan());
        assert_eq!(a[4], 3.0);
    }

    #[test]
    fn bad_input_names_the_file_line_and_column() {
        assert_eq!(
            error("time,a,b\n0,1,2\n0.5,1,x2\n"),
            "data file rig.csv, line 3, column 3 (`b`): `x2` is not a number (an empty cell or `nan` is a missing sample)"
        );
        assert_eq!(
            error("a,time\n1,0\n\n2,0.5\n3,0.5\n"),
            "data file rig.csv, line 5, column 2 (`time`): time 0.5 does not increase (line 4 has 0.5)"
        );
        assert_eq!(
            error("time,a\n0,1\n,2\n"),
            "data file rig.csv, line 3, column 1 (`time`): the time is missing"
        );
        assert_eq!(
            error("t,a\n0,1\n"),
            "data file rig.csv, line 1: no `time` column (the columns are: t, a)"
        );
        assert_eq!(
            error("time,a\n0,1\n1,2,3\n"),
            "data file rig.csv, line 3: 3 cells for 2 columns"
        );
        assert_eq!(
            error("time,a,a\n0,1,2\n"),
            "data file rig.csv, line 1, column 3 (`a`): a second column called `a`"
        );
        assert_eq!(
            error("time,a,a.valid\n0,1,2\n"),
            "data file rig.csv, line 1, column 3 (`a.valid`): clashes with the output `a.valid` derived from column `a`; rename it"
        );
        assert!(error("time,a.held,a\n0,1,2\n").contains("column 2 (`a.held`): clashes"));
        let t = table("time,a\n0,1\n\n2,3\n", Interpolation::Hold);
        assert_eq!(
            t.check_range(0.0, 2.5).unwrap_err().to_string(),
            "data file rig.csv, line 4, column 1 (`time`): the system's stop time 2.5 is past the data, whose last sample is at 2"
        );
        assert_eq!(
            t.check_range(-1.0, 2.0).unwrap_err().to_string(),
            "data file rig.csv, line 2, column 1 (`time`): the system starts at -1, before the first sample (0)"
        );
        assert_eq!(
            t.column("force").unwrap_err().to_string(),
            "data file rig.csv, line 1: no column `force` (the columns are: a)"
        );
    }
}
