//! `spurio diagnose`: the outlier diagnostics of docs/diagnostics.md §3 on one column of a results CSV —
//! two-sided Grubbs test (one pass and iterated), sample moments (excess kurtosis, skewness,
//! paper 001 eqs 18–19), E_res against a clean column, and a histogram with the ±2σ band.

use crate::diagnostics;
use anyhow::{Context, Result};
use spurio_master::{ResultTable, MAX_RESULTS_BYTES};
use std::fmt::Write;
use std::path::Path;

/// What the diagnostics found, as Markdown.
pub fn diagnose(
    csv: &Path,
    column: &str,
    clean: Option<&str>,
    alpha: f64,
    png: Option<&Path>,
) -> Result<String> {
    let table = ResultTable::read(csv, MAX_RESULTS_BYTES)?;
    let data = table
        .column(column)
        .with_context(|| format!("in {}", csv.display()))?;
    let what = |e: diagnostics::DiagnosticsError| anyhow::anyhow!("column `{column}`: {e}");
    let moments = diagnostics::sample_moments(&data).map_err(what)?;
    let grubbs = diagnostics::grubbs_test(&data, alpha).map_err(what)?;
    let rejected = diagnostics::grubbs_iterative(&data, alpha).map_err(what)?;
    let mut out = String::new();
    let _ = writeln!(out, "# Diagnostics of `{column}` ({})\n", csv.display());
    let _ = writeln!(out, "| quantity | value |\n|---|---|");
    let _ = writeln!(out, "| samples N | {} |", moments.samples);
    let _ = writeln!(out, "| mean | {:.6} |", moments.mean);
    let _ = writeln!(out, "| standard deviation | {:.6} |", moments.std_dev);
    let _ = writeln!(out, "| skewness | {:.4} |", moments.skewness);
    let _ = writeln!(out, "| excess kurtosis | {:.4} |", moments.excess_kurtosis);
    let _ = writeln!(
        out,
        "| Grubbs G = max abs(y − ȳ) / s | {:.4} (sample {}, value {:.6}) |",
        grubbs.statistic, grubbs.suspect_index, grubbs.suspect_value
    );
    let _ = writeln!(
        out,
        "| Grubbs critical value (α = {alpha}, two-sided) | {:.4} |",
        grubbs.critical_value
    );
    let _ = writeln!(
        out,
        "| outlier by one Grubbs pass | {} |",
        if grubbs.is_outlier { "yes" } else { "no" }
    );
    let _ = writeln!(
        out,
        "| outliers rejected by iterated Grubbs | {} |",
        rejected.len()
    );
    if let Some(clean) = clean {
        let reference = table
            .column(clean)
            .with_context(|| format!("in {}", csv.display()))?;
        let e = diagnostics::residual_error(&reference, &data).map_err(what)?;
        let _ = writeln!(out, "| E_res = ‖{clean} − {column}‖²/N | {e:.6} |");
    }
    if let Some(png) = png {
        let (edges, counts) = diagnostics::histogram(&data, 40).map_err(what)?;
        let band = diagnostics::two_sigma_band(&data).map_err(what)?;
        crate::plot::histogram_png(
            png,
            &format!("Histogram of {column}"),
            column,
            (&edges, &counts),
            band,
        )
        .with_context(|| format!("writing {}", png.display()))?;
        let _ = writeln!(out, "\n![histogram]({})", png.display());
    }
    Ok(out)
}
