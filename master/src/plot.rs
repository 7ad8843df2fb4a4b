//! PNG pictures with plotters (fonts embedded: DejaVu Sans, so nothing is needed from the
//! system).

use anyhow::{anyhow, Result};
use plotters::prelude::*;
use std::path::Path;
use std::sync::Once;

static FONT: Once = Once::new();

/// Registers the embedded font (once) for plotters' "sans-serif".
pub(crate) fn register_font() {
    FONT.call_once(|| {
        let _ = plotters::style::register_font(
            "sans-serif",
            FontStyle::Normal,
            dejavu::sans::regular(),
        );
    });
}

fn err<E: std::fmt::Debug>(e: E) -> anyhow::Error {
    anyhow!("plotting failed: {e:?}")
}

/// A histogram of `data` (bin `edges`, `counts`) with the mean ± 2σ band shaded.
pub fn histogram_png(
    path: &Path,
    title: &str,
    edges: &[f64],
    counts: &[usize],
    band: (f64, f64),
) -> Result<()> {
    register_font();
    let root = BitMapBackend::new(path, (800, 480)).into_drawing_area();
    root.fill(&WHITE).map_err(err)?;
    let (lo, hi) = (edges[0], edges[edges.len() - 1]);
    let x_lo = lo.min(band.0);
    let x_hi = hi.max(band.1);
    let top = counts.iter().copied().max().unwrap_or(1) as f64 * 1.1;
    let mut chart = ChartBuilder::on(&root)
        .caption(title, ("sans-serif", 22))
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(55)
        .build_cartesian_2d(x_lo..x_hi, 0f64..top)
        .map_err(err)?;
    chart
        .configure_mesh()
        .x_desc("value")
        .y_desc("count")
        .draw()
        .map_err(err)?;
    chart
        .draw_series(std::iter::once(Rectangle::new(
            [(band.0, 0.0), (band.1, top)],
            RGBColor(255, 220, 150).mix(0.5).filled(),
        )))
        .map_err(err)?
        .label("mean ± 2σ")
        .legend(|(x, y)| {
            Rectangle::new(
                [(x, y - 5), (x + 15, y + 5)],
                RGBColor(255, 220, 150).filled(),
            )
        });
    chart
        .draw_series(
            edges.windows(2).zip(counts).map(|(e, c)| {
                Rectangle::new([(e[0], 0.0), (e[1], *c as f64)], BLUE.mix(0.6).filled())
            }),
        )
        .map_err(err)?;
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .draw()
        .map_err(err)?;
    root.present().map_err(err)?;
    Ok(())
}

/// Line plots of the named variables of `series` against time, one panel per variable.
pub fn time_series_png(
    path: &Path,
    title: &str,
    series: &crate::record::TimeSeries,
    names: &[String],
) -> Result<()> {
    register_font();
    let columns: Vec<(String, Vec<f64>)> = names
        .iter()
        .map(|n| {
            series.column(n).map(|c| (n.clone(), c)).ok_or_else(|| {
                anyhow!(
                    "cannot plot `{n}`: it is not recorded (recorded: {})",
                    series.names.join(", ")
                )
            })
        })
        .collect::<Result<_>>()?;
    let height = 60 + 220 * columns.len() as u32;
    let root = BitMapBackend::new(path, (900, height)).into_drawing_area();
    root.fill(&WHITE).map_err(err)?;
    let root = root.titled(title, ("sans-serif", 22)).map_err(err)?;
    let panels = root.split_evenly((columns.len(), 1));
    let (t0, t1) = (
        series.time.first().copied().unwrap_or(0.0),
        series.time.last().copied().unwrap_or(1.0),
    );
    for (panel, (name, values)) in panels.iter().zip(&columns) {
        let (lo, hi) = values
            .iter()
            .filter(|v| v.is_finite())
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
                (a.min(*v), b.max(*v))
            });
        let (lo, hi) = if lo < hi {
            (lo, hi)
        } else {
            (lo - 1.0, lo + 1.0)
        };
        let pad = 0.05 * (hi - lo);
        let mut chart = ChartBuilder::on(panel)
            .margin(8)
            .x_label_area_size(30)
            .y_label_area_size(60)
            .build_cartesian_2d(t0..t1.max(t0 + 1e-9), (lo - pad)..(hi + pad))
            .map_err(err)?;
        chart
            .configure_mesh()
            .x_desc("time [s]")
            .y_desc(name.as_str())
            .draw()
            .map_err(err)?;
        chart
            .draw_series(LineSeries::new(
                series.time.iter().copied().zip(values.iter().copied()),
                &BLUE,
            ))
            .map_err(err)?;
    }
    root.present().map_err(err)?;
    Ok(())
}
