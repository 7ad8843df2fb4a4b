//! The variables of a data instance ([`crate::data::DataTable`]) in the form the plan compiler
//! reads for every instance: column j gives three outputs, value references 3j, 3j + 1 and
//! 3j + 2 ([`Reading`]): the column itself (Real, NaN at a missing sample), `<column>.valid`
//! (Boolean, true where the column has a sample) and `<column>.held` (Real, the last present
//! sample over missing ones). No output depends on an input (a table has none), so a data instance never
//! takes part in a direct-feedthrough chain. Nothing is imported: the engine reads the table.

use super::{
    Causality, FmiVersion, FmuFile, Import, Interface, Range, VarType, VariableHead, VariableInfo,
};
use crate::data::{DataTable, Reading};
use std::collections::HashMap;

impl FmuFile {
    /// The interface of the data instance reading `table`.
    pub(crate) fn table(table: &DataTable) -> Self {
        let output =
            |name: String, value_reference: usize, var_type, unit, description| VariableInfo {
                head: VariableHead {
                    name,
                    value_reference: u32::try_from(value_reference).unwrap_or(u32::MAX),
                    var_type,
                    causality: Causality::Output,
                },
                fixed: false,
                start: None,
                unit,
                range: Range::default(),
                description: Some(description),
                dependencies: Some(Vec::new()),
                element: None,
            };
        let signals = &table.signals;
        let mut variables = Vec::with_capacity(Reading::ALL.len() * signals.names.len());
        for (j, (name, unit)) in signals.names.iter().zip(&signals.units).enumerate() {
            for (r, reading) in Reading::ALL.into_iter().enumerate() {
                let (var_type, unit) = match reading {
                    Reading::Valid => (VarType::Boolean, None),
                    Reading::Value | Reading::Held => (VarType::Real, unit.clone()),
                };
                let description = reading.describe(name, &table.file.display().to_string());
                variables.push(output(
                    format!("{name}{}", reading.suffix()),
                    Reading::ALL.len() * j + r,
                    var_type,
                    unit,
                    description,
                ));
            }
        }
        let by_name = variables
            .iter()
            .enumerate()
            .map(|(i, v)| (v.head.name.clone(), i))
            .collect();
        let model_name = table
            .file
            .file_stem()
            .map_or_else(String::new, |s| s.to_string_lossy().into_owned());
        Self {
            path: table.file.clone(),
            version: FmiVersion::Fmi2,
            interface: Interface::CoSimulation,
            import: Import::Table,
            model_name,
            model_identifier: String::new(),
            guid: String::new(),
            variables,
            arrays: Vec::new(),
            event_mode: false,
            by_name,
            arrays_by_name: HashMap::new(),
        }
    }

    /// Whether this is the interface of a data instance ([`FmuFile::table`]), not an FMU.
    pub fn is_table(&self) -> bool {
        matches!(self.import, Import::Table)
    }
}
