//! A data file (CSV) of a data instance or the `TimeTable` FMU, parsed and checked, then
//! looked up as the engine does (columns, range).
#![no_main]
use libfuzzer_sys::fuzz_target;
use spurio_table::{DataTable, Interpolation};
use std::path::Path;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    for interpolation in [Interpolation::Hold, Interpolation::Linear] {
        if let Ok(table) = DataTable::parse(text, Path::new("fuzz.csv"), interpolation) {
            let (start, end) = (table.start(), table.end());
            drop(table.check_range(start, end));
            drop(table.column("time"));
        }
    }
});
