//! `TimeTable.fmu`: recorded signals — a CSV table of a `time` column and one column per
//! signal — as a Co-Simulation FMU, like Modelica's `CombiTimeTable`, for any FMI tool (fmpy,
//! OMSimulator, Simulink, Dymola). `spurio package-data rig.csv --name RigData` packages one
//! table (the table in `resources/`, its columns, units, time range and interpolation in the
//! configuration `resources/variant.cfg`: [`spurio_table::declaration`]); the bundled
//! `TimeTable.fmu` carries the small table `fmus/TimeTable/example.csv` in its binary.
//!
//! The reader and the interpolation are the master's data source's ([`spurio_table`]), so the
//! FMU and a system's data instance `data = "rig.csv"` give the same value at the same time:
//! between samples t_i ≤ t < t_{i+1},
//!
//! ```text
//! hold   (interpolation = 1):  u(t) = u_i
//! linear (interpolation = 2):  u(t) = u_i + (u_{i+1} − u_i)·((t − t_i)/(t_{i+1} − t_i))
//! ```
//!
//! a sample time within rounding of t being at t (|t − t_i| ≤ (10⁻⁹ + i²ε)·Δ_i,
//! [`spurio_table::instant`]). Outputs of column `c` (value references 3j, 3j + 1, 3j + 2, the
//! names of the master's data instance): `c` (Real), `c.valid` (Boolean: false at a missing
//! sample, an empty cell or `nan`) and `c.held` (Real: the last present sample over missing
//! ones, 0 before the first). An FMU output is never NaN: where the master's `c` reads NaN
//! (a missing sample) the FMU's `c` reads the held value, `c.valid` saying it is no
//! measurement; everywhere else the two agree bit for bit.
//!
//! Outside the time range: a start time before the first sample is refused at
//! initialisation, a step ending after the last sample is refused (`fmi2Error`), each naming
//! the file, the line of that sample and the `time` column, as the master refuses a system
//! whose start or stop lies outside its data. A table that is missing or malformed is refused
//! at instantiation (NULL, the message naming the file, line and column).
//!
//! Bounded work, nothing allocated after instantiation: a step moves a cursor over the
//! samples it passes (one per step when the step is the sampling interval).

use spurio_export::{
    Cause, Config, Context, DefaultExperiment, Failure, FmuModel, ModelInfo, Variable,
};
use spurio_table::declaration::{Declaration, INTERPOLATION_PARAMETER};
use spurio_table::{read_text_at_most, Cursor, DataError, DataTable, Interpolation, Reading};
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// The bundled table (`TimeTable.fmu` without a variant configuration).
pub const EXAMPLE: &str = include_str!("../example.csv");

/// The name of the bundled table in messages and descriptions.
pub const EXAMPLE_NAME: &str = "example.csv";

/// The configuration key of the model name `spurio package-data --name` gives.
pub const MODEL_NAME_KEY: &str = "name";

/// The largest table file read (1 GiB): a table is held in memory whole.
pub const MAX_TABLE_BYTES: u64 = 1 << 30;

/// The bundled table, read with `interpolation`.
fn example(interpolation: Interpolation) -> Result<DataTable, DataError> {
    DataTable::parse(EXAMPLE, Path::new(EXAMPLE_NAME), interpolation)
}

/// The declaration of `config`: the packaged table's, or the bundled table's (hold) when the
/// configuration is empty.
pub fn declaration(config: &Config) -> Result<Declaration, Cause> {
    if config.is_empty() {
        return Ok(Declaration::of(
            &example(Interpolation::Hold)?,
            EXAMPLE_NAME,
        )?);
    }
    Declaration::from_entries(|key| config.get(key)).map_err(|e| format!("variant.cfg: {e}").into())
}

/// The value reference of the parameter `interpolation` (after the 3 outputs per column).
fn interpolation_vr(declared: &Declaration) -> usize {
    Reading::ALL.len() * declared.signals.names.len()
}

/// The variables of a declaration.
fn variables(declared: &Declaration) -> Vec<Variable> {
    let mut variables: Vec<Variable> = declared
        .outputs()
        .map(|(j, reading, name)| {
            let unit = declared.signals.units[j].as_deref();
            let description = reading.describe(&declared.signals.names[j], &declared.table);
            let variable = match reading {
                Reading::Valid => Variable::boolean_output(&name),
                Reading::Value | Reading::Held => Variable::discrete_output(&name),
            };
            match (reading, unit) {
                (Reading::Valid, _) | (_, None) => variable,
                (_, Some(unit)) => variable.unit(unit),
            }
            .describe(&description)
        })
        .collect();
    variables.push(
        Variable::integer_parameter(INTERPOLATION_PARAMETER, declared.signals.interpolation.code())
            .min(1.0)
            .max(2.0)
            .describe("Between samples: 1 hold (the sample at or before t), 2 linear (the line between the samples around t)"),
    );
    variables
}

/// The TimeTable FMU: the table, the interpolation chosen and where the last read was.
#[derive(Debug, Clone)]
pub struct TimeTableFmu {
    table: Arc<DataTable>,
    interpolation: Interpolation,
    cursor: Cursor,
    interpolation_vr: usize,
}

impl TimeTableFmu {
    /// The model of table `table` as `declared` (the FMU's own declaration).
    pub fn of(table: DataTable, declared: &Declaration) -> Self {
        Self {
            table: Arc::new(table),
            interpolation: declared.signals.interpolation,
            cursor: Cursor::default(),
            interpolation_vr: interpolation_vr(declared),
        }
    }

    /// The table read.
    pub fn table(&self) -> &DataTable {
        &self.table
    }

    /// The error of time `t` outside the samples, at sample `i` (the first or the last).
    fn outside(&self, i: usize, reason: String) -> Failure {
        let table = &self.table;
        Failure::error(DataError::Cell {
            file: table.file.clone(),
            line: table.lines.get(i).copied().unwrap_or(table.header_line),
            column: table.time_column,
            name: "time".into(),
            reason,
        })
    }

    /// Moves to time `t` and writes every output there.
    fn write_outputs(&mut self, ctx: &mut Context, t: f64) {
        let table = &self.table;
        table.seek(&mut self.cursor, t);
        let mut vr = 0;
        for j in 0..table.signals.names.len() {
            let read = |r| table.reading_as(self.interpolation, self.cursor, j, r, t);
            // An output is never NaN: `c` reads the held value at a missing sample.
            ctx.values.set_real(vr, read(Reading::Held));
            ctx.values.set_boolean(vr + 1, read(Reading::Valid) == 1.0);
            ctx.values.set_real(vr + 2, read(Reading::Held));
            vr += Reading::ALL.len();
        }
    }
}

impl FmuModel for TimeTableFmu {
    fn describe(config: &Config) -> Result<ModelInfo, Cause> {
        let declared = declaration(config)?;
        let step = if declared.samples > 1 {
            (declared.stop - declared.start) / (declared.samples - 1) as f64
        } else {
            1.0
        };
        let info = ModelInfo::new(
            "TimeTable",
            &format!(
                "Recorded signals of {}: {} samples from t = {} s to {} s, interpolation {} (like Modelica's CombiTimeTable); a start before the first sample or a step past the last is an error",
                declared.table,
                declared.samples,
                declared.start,
                declared.stop,
                declared.signals.interpolation.name()
            ),
            variables(&declared),
            Some(DefaultExperiment {
                start_time: declared.start,
                stop_time: declared.stop,
                step_size: step,
            }),
            config.clone(),
        );
        Ok(match config.get(MODEL_NAME_KEY) {
            Some(name) => info.with_model_name(name),
            None => info,
        })
    }

    fn create(info: &ModelInfo) -> Result<Self, Cause> {
        Self::create_with_resources(info, None)
    }

    fn create_with_resources(info: &ModelInfo, resources: Option<&Path>) -> Result<Self, Cause> {
        let declared = declaration(&info.config)?;
        if info.config.is_empty() {
            return Ok(Self::of(
                example(declared.signals.interpolation)?,
                &declared,
            ));
        }
        let Some(dir) = resources else {
            return Err(format!(
                "the table resources/{} cannot be read: no resource location is given",
                declared.table
            )
            .into());
        };
        let path: PathBuf = dir.join(&declared.table);
        let text =
            read_text_at_most(&path, MAX_TABLE_BYTES, "the table", "1 GiB").map_err(|reason| {
                DataError::File {
                    file: path.clone(),
                    reason,
                }
            })?;
        let table = DataTable::parse(&text, &path, declared.signals.interpolation)?;
        declared.check(&table)?;
        Ok(Self::of(table, &declared))
    }

    fn initialize(&mut self, ctx: &mut Context) -> Result<(), Failure> {
        let code = ctx.values.integer(self.interpolation_vr);
        self.interpolation = Interpolation::of_code(code).ok_or_else(|| {
            Failure::error(format!(
                "parameter `interpolation`: must be 1 (hold) or 2 (linear), got {code}"
            ))
        })?;
        let start = ctx.time();
        if !self.table.reached(0, start) {
            return Err(self.outside(
                0,
                format!(
                    "the start time {start} is before the first sample ({})",
                    self.table.start()
                ),
            ));
        }
        self.write_outputs(ctx, start);
        Ok(())
    }

    fn check_step(&self, _ctx: &Context, time: f64, step: f64) -> Result<(), Cause> {
        let end = time + step;
        if self.table.not_passed(end) {
            return Ok(());
        }
        Err(self
            .outside(
                self.table.times.len() - 1,
                format!(
                    "the step from {time} to {end} goes past the data, whose last sample is at {}",
                    self.table.end()
                ),
            )
            .cause()
            .to_string()
            .into())
    }

    fn do_step(&mut self, ctx: &mut Context, time: f64, step: f64) -> Result<(), Failure> {
        self.write_outputs(ctx, time + step);
        Ok(())
    }

    fn save_state(&self, out: &mut spurio_export::ByteWriter) {
        out.put_u64(self.cursor.sample() as u64);
        out.put_i32(self.interpolation.code());
    }

    fn load_state(&mut self, input: &mut spurio_export::ByteReader) -> Result<(), Cause> {
        let sample = input.u64()?;
        let code = input.i32()?;
        let sample = usize::try_from(sample)
            .ok()
            .filter(|&i| i < self.table.times.len())
            .ok_or_else(|| {
                format!(
                    "sample {sample} of a table of {} samples",
                    self.table.times.len()
                )
            })?;
        let interpolation = Interpolation::of_code(code)
            .ok_or_else(|| format!("interpolation code {code} (1 hold, 2 linear)"))?;
        self.cursor = Cursor::at(sample);
        self.interpolation = interpolation;
        Ok(())
    }
}

spurio_export::export_fmu!(TimeTableFmu);

#[cfg(test)]
mod tests;
