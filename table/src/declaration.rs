//! A table as the `TimeTable` FMU declares it: the `key = value` entries of the variant
//! configuration `spurio package-data` writes into the FMU (`resources/variant.cfg`, beside
//! the table itself), from which the FMU's binary builds its model description without the
//! table and against which it checks the table it reads at instantiation.
//!
//! ```text
//! table = rig.csv              the table's file in resources/
//! interpolation = hold         hold | linear
//! columns = 2                  the signal columns, in file order, as header cells
//! column.1 = force [N]
//! column.2 = x [m]
//! start = 0.0                  the first and last sample times (shortest round-trip text)
//! stop = 79.92
//! samples = 1000
//! ```

use crate::{name_and_unit, DataTable, Interpolation, Reading, Signals};

/// What is wrong with a declaration (a configuration key and why), or with a table that
/// should match it.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum DeclarationError {
    #[error("`{key}` is missing")]
    Missing { key: String },
    #[error("`{key} = {value}`: {reason}")]
    Invalid {
        key: String,
        value: String,
        reason: String,
    },
    #[error("column `{name}` cannot be declared: {reason}")]
    Column { name: String, reason: String },
    #[error("{file} does not match the model description: {reason} (the FMU was packaged from another table)")]
    Mismatch { file: String, reason: String },
}

/// The error of `key = value`, saying why.
pub fn invalid(key: &str, value: &str, reason: &str) -> DeclarationError {
    DeclarationError::Invalid {
        key: key.to_string(),
        value: value.to_string(),
        reason: reason.to_string(),
    }
}

/// The `key = value` entries of a packaged FMU's configuration, read by key, every error
/// naming the key (the TimeTable's declaration here, the PlantEstimator's in
/// `spurio-identify`).
pub struct Entries<G> {
    get: G,
}

impl<'a, G: Fn(&str) -> Option<&'a str>> Entries<G> {
    /// The entries `get` gives (`None` for a key that is absent).
    pub fn new(get: G) -> Self {
        Self { get }
    }

    /// The value of `key`, if present.
    pub fn optional(&self, key: &str) -> Option<&'a str> {
        (self.get)(key)
    }

    /// The value of `key`, or [`DeclarationError::Missing`].
    pub fn required(&self, key: &str) -> Result<&'a str, DeclarationError> {
        (self.get)(key).ok_or_else(|| DeclarationError::Missing {
            key: key.to_string(),
        })
    }

    /// `key` as a finite number.
    pub fn number(&self, key: &str) -> Result<f64, DeclarationError> {
        let value = self.required(key)?;
        value
            .parse::<f64>()
            .ok()
            .filter(|v| v.is_finite())
            .ok_or_else(|| invalid(key, value, "not a finite number"))
    }

    /// `key` as a whole number of at least `min`.
    pub fn count(&self, key: &str, min: usize) -> Result<usize, DeclarationError> {
        let value = self.required(key)?;
        value
            .parse::<usize>()
            .ok()
            .filter(|&n| n >= min)
            .ok_or_else(|| invalid(key, value, &format!("not a whole number ≥ {min}")))
    }
}

/// The declaration of one table.
#[derive(Debug, Clone, PartialEq)]
pub struct Declaration {
    /// The table's file name in `resources/`.
    pub table: String,
    /// The signals, as the table's header gives them, and their interpolation.
    pub signals: Signals,
    /// The first sample time.
    pub start: f64,
    /// The last sample time.
    pub stop: f64,
    /// The number of samples.
    pub samples: usize,
}

/// The name of the FMU's Integer parameter that chooses the interpolation (1 hold, 2 linear).
pub const INTERPOLATION_PARAMETER: &str = "interpolation";

impl Declaration {
    /// The declaration of `table`, to be packaged as file `file_name` in `resources/`.
    /// Refuses a column name the configuration file cannot carry (`#`, a line break) or that
    /// clashes with the FMU's parameter `interpolation`.
    pub fn of(table: &DataTable, file_name: &str) -> Result<Self, DeclarationError> {
        for name in &table.signals.names {
            let reason = if name.contains(['#', '\n', '\r']) {
                "a `#` or a line break cannot be written in the FMU's configuration; rename it"
            } else if name == INTERPOLATION_PARAMETER {
                "it is the name of the FMU's parameter `interpolation`; rename it"
            } else {
                continue;
            };
            return Err(DeclarationError::Column {
                name: name.clone(),
                reason: reason.into(),
            });
        }
        Ok(Self {
            table: file_name.to_string(),
            signals: table.signals.clone(),
            start: table.start(),
            stop: table.end(),
            samples: table.times.len(),
        })
    }

    /// The `key = value` entries.
    pub fn entries(&self) -> Vec<(String, String)> {
        let mut entries = vec![
            ("table".to_string(), self.table.clone()),
            (
                "interpolation".to_string(),
                self.signals.interpolation.name().to_string(),
            ),
            ("columns".to_string(), self.signals.names.len().to_string()),
            ("start".to_string(), format!("{:?}", self.start)),
            ("stop".to_string(), format!("{:?}", self.stop)),
            ("samples".to_string(), self.samples.to_string()),
        ];
        let Signals { names, units, .. } = &self.signals;
        for (j, (name, unit)) in names.iter().zip(units).enumerate() {
            let cell = match unit {
                Some(unit) => format!("{name} [{unit}]"),
                None => name.clone(),
            };
            entries.push((format!("column.{}", j + 1), cell));
        }
        entries
    }

    /// The declaration whose entries `get` gives (`None` for a key that is absent).
    pub fn from_entries<'a>(
        get: impl Fn(&str) -> Option<&'a str>,
    ) -> Result<Self, DeclarationError> {
        let entries = Entries::new(get);
        let required = |key: &str| entries.required(key);
        let number = |key: &str| entries.number(key);
        let count = |key: &str| entries.count(key, 1);
        let table = required("table")?.to_string();
        let interpolation = required("interpolation")?;
        let interpolation = Interpolation::named(interpolation)
            .ok_or_else(|| invalid("interpolation", interpolation, "not `hold` or `linear`"))?;
        let (start, stop, samples) = (number("start")?, number("stop")?, count("samples")?);
        if stop < start {
            return Err(invalid("stop", &format!("{stop:?}"), "before `start`"));
        }
        let columns = count("columns")?;
        let mut names = Vec::with_capacity(columns.min(1 << 16));
        let mut units = Vec::with_capacity(columns.min(1 << 16));
        for j in 1..=columns {
            let key = format!("column.{j}");
            let (name, unit) = name_and_unit(required(&key)?);
            if name.is_empty() || names.contains(&name) || name == INTERPOLATION_PARAMETER {
                return Err(invalid(&key, &name, "empty, repeated or `interpolation`"));
            }
            names.push(name);
            units.push(unit);
        }
        Ok(Self {
            table,
            signals: Signals {
                interpolation,
                names,
                units,
            },
            start,
            stop,
            samples,
        })
    }

    /// Checks that `table` is the table declared: the same columns and units, the same
    /// first and last sample times and number of samples.
    pub fn check(&self, table: &DataTable) -> Result<(), DeclarationError> {
        let mismatch = |reason: String| DeclarationError::Mismatch {
            file: table.file.display().to_string(),
            reason,
        };
        let (found, declared) = (&table.signals, &self.signals);
        if found.names != declared.names || found.units != declared.units {
            return Err(mismatch(format!(
                "its columns are {:?} with units {:?}, the description's {:?} with units {:?}",
                found.names, found.units, declared.names, declared.units
            )));
        }
        if (table.start(), table.end(), table.times.len()) != (self.start, self.stop, self.samples)
        {
            return Err(mismatch(format!(
                "its {} samples span {} to {}, the description's {} samples {} to {}",
                table.times.len(),
                table.start(),
                table.end(),
                self.samples,
                self.start,
                self.stop
            )));
        }
        Ok(())
    }

    /// The output names of the FMU, in value-reference order: for column j,
    /// `name`, `name.valid`, `name.held` (value references 3j, 3j + 1, 3j + 2), as the
    /// master's data instance names them.
    pub fn outputs(&self) -> impl Iterator<Item = (usize, Reading, String)> + '_ {
        self.signals.names.iter().enumerate().flat_map(|(j, name)| {
            Reading::ALL
                .into_iter()
                .map(move |r| (j, r, format!("{name}{}", r.suffix())))
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::BTreeMap;
    use std::path::Path;

    #[test]
    fn a_declaration_round_trips_through_its_entries_and_checks_its_table() {
        let text = "time,force [N],x\n0,1,2\n0.1,,3\n0.30000000000000004,5,6\n";
        let table = DataTable::parse(text, Path::new("rig.csv"), Interpolation::Linear).unwrap();
        let declared = Declaration::of(&table, "rig.csv").unwrap();
        let entries: BTreeMap<String, String> = declared.entries().into_iter().collect();
        assert_eq!(entries["column.1"], "force [N]");
        assert_eq!(entries["stop"], "0.30000000000000004");
        let back = Declaration::from_entries(|k| entries.get(k).map(String::as_str)).unwrap();
        assert_eq!(back, declared);
        back.check(&table).unwrap();
        let outputs: Vec<String> = back.outputs().map(|(_, _, n)| n).collect();
        assert_eq!(
            outputs,
            [
                "force",
                "force.valid",
                "force.held",
                "x",
                "x.valid",
                "x.held"
            ]
        );
        let other = DataTable::parse(
            "time,force [N],x\n0,1,2\n0.1,,3\n",
            Path::new("other.csv"),
            Interpolation::Hold,
        )
        .unwrap();
        let err = back.check(&other).unwrap_err().to_string();
        assert!(
            err.starts_with("other.csv does not match the model description: its 2 samples"),
            "{err}"
        );
        let mut broken = entries.clone();
        broken.insert("interpolation".into(), "cubic".into());
        let err = Declaration::from_entries(|k| broken.get(k).map(String::as_str)).unwrap_err();
        assert_eq!(
            err.to_string(),
            "`interpolation = cubic`: not `hold` or `linear`"
        );
        broken.remove("column.2");
        broken.insert("interpolation".into(), "hold".into());
        let err = Declaration::from_entries(|k| broken.get(k).map(String::as_str)).unwrap_err();
        assert_eq!(err.to_string(), "`column.2` is missing");
    }

    #[test]
    fn names_the_configuration_cannot_carry_are_refused() {
        let table =
            DataTable::parse("time,a#b\n0,1\n", Path::new("r.csv"), Interpolation::Hold).unwrap();
        let err = Declaration::of(&table, "r.csv").unwrap_err().to_string();
        assert!(err.starts_with("column `a#b` cannot be declared"), "{err}");
        let table = DataTable::parse(
            "time,interpolation\n0,1\n",
            Path::new("r.csv"),
            Interpolation::Hold,
        )
        .unwrap();
        assert!(Declaration::of(&table, "r.csv").is_err());
    }
}
