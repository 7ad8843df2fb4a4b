//! Result files in fmpy's CSV layout: a header of quoted names (`"time","x",…`) and one row
//! of full-precision numbers per communication point.

use anyhow::{bail, Context, Result};
use std::path::Path;

/// A table of named columns read from a results CSV.
#[derive(Debug, Clone, PartialEq)]
pub struct ResultTable {
    /// Column names, in file order.
    pub names: Vec<String>,
    /// Rows of values.
    pub rows: Vec<Vec<f64>>,
}

impl ResultTable {
    /// Reads `path`; every error names the file and the line.
    pub fn read(path: &Path) -> Result<Self> {
        let text = std::fs::read_to_string(path)
            .with_context(|| format!("cannot read results file {}", path.display()))?;
        Self::parse(&text).with_context(|| format!("in results file {}", path.display()))
    }

    /// Parses CSV text.
    pub fn parse(text: &str) -> Result<Self> {
        let mut lines = text.lines().filter(|l| !l.trim().is_empty());
        let Some(header) = lines.next() else {
            bail!("the file is empty");
        };
        let names: Vec<String> = header
            .split(',')
            .map(|n| n.trim().trim_matches('"').to_string())
            .collect();
        let mut rows = Vec::new();
        for (k, line) in lines.enumerate() {
            let row: Vec<f64> = line
                .split(',')
                .map(|v| {
                    let v = v.trim();
                    match v {
                        "True" | "true" => Ok(1.0),
                        "False" | "false" => Ok(0.0),
                        _ => v.parse::<f64>(),
                    }
                })
                .collect::<Result<_, _>>()
                .with_context(|| format!("line {}: not a number", k + 2))?;
            if row.len() != names.len() {
                bail!(
                    "line {}: {} values for {} columns",
                    k + 2,
                    row.len(),
                    names.len()
                );
            }
            rows.push(row);
        }
        Ok(Self { names, rows })
    }

    /// The column called `name`, or an error listing the columns there are.
    pub fn column(&self, name: &str) -> Result<Vec<f64>> {
        let Some(j) = self.names.iter().position(|n| n == name) else {
            bail!("no column `{name}` (columns: {})", self.names.join(", "));
        };
        Ok(self.rows.iter().map(|r| r[j]).collect())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

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
        assert!(format!("{e:#}").contains("line 3"));
    }
}
