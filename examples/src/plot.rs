//! PNG pictures with plotters (fonts embedded: DejaVu Sans, so nothing is needed from the
//! system).

use anyhow::{anyhow, Result};
use plotters::prelude::*;
use std::path::Path;
use std::sync::Once;

static FONT: Once = Once::new();

/// Registers the embedded DejaVu Sans as "sans-serif" (once).
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
    series: &spurio_master::record::TimeSeries,
    names: &[String],
) -> Result<()> {
    labelled_time_series_png(path, title, series, names, names)
}

/// [`time_series_png`] with the y-axis of `names[i]` labelled `labels[i]` (e.g. with its
/// unit: `crane.x [m]`).
pub fn labelled_time_series_png(
    path: &Path,
    title: &str,
    series: &spurio_master::record::TimeSeries,
    names: &[String],
    labels: &[String],
) -> Result<()> {
    register_font();
    let columns: Vec<(String, Vec<f64>)> = names
        .iter()
        .zip(labels.iter().chain(names.iter().skip(labels.len())))
        .map(|(n, label)| {
            series.column(n).map(|c| (label.clone(), c)).ok_or_else(|| {
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

/// One panel of [`panels_png`]: a y-axis label and the lines drawn in it.
pub struct Panel {
    /// The y-axis label.
    pub label: String,
    /// (legend, x values, y values, draw as points instead of a line).
    pub lines: Vec<(String, Vec<f64>, Vec<f64>, bool)>,
    /// The colour of each line, in order; lines beyond it take the default palette.
    pub colours: Vec<RGBColor>,
}

/// Several panels stacked vertically, each with any number of lines (or point clouds) and a
/// legend; `x_label` names the common x axis.
pub fn panels_png(path: &Path, title: &str, x_label: &str, panels: &[Panel]) -> Result<()> {
    register_font();
    const COLOURS: [RGBColor; 5] = [
        RGBColor(150, 150, 150),
        RGBColor(0, 0, 0),
        RGBColor(200, 30, 30),
        RGBColor(30, 80, 200),
        RGBColor(20, 150, 60),
    ];
    let height = 60 + 260 * panels.len().max(1) as u32;
    let root = BitMapBackend::new(path, (1000, height)).into_drawing_area();
    root.fill(&WHITE).map_err(err)?;
    let root = root.titled(title, ("sans-serif", 22)).map_err(err)?;
    let areas = root.split_evenly((panels.len().max(1), 1));
    for (area, panel) in areas.iter().zip(panels) {
        let finite = |v: &Vec<f64>| {
            v.iter()
                .copied()
                .filter(|x| x.is_finite())
                .collect::<Vec<_>>()
        };
        let xs: Vec<f64> = panel.lines.iter().flat_map(|l| finite(&l.1)).collect();
        let ys: Vec<f64> = panel.lines.iter().flat_map(|l| finite(&l.2)).collect();
        let range = |v: &[f64]| {
            let (lo, hi) = v
                .iter()
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), x| {
                    (a.min(*x), b.max(*x))
                });
            if lo < hi {
                (lo, hi)
            } else if lo.is_finite() {
                (lo - 1.0, lo + 1.0)
            } else {
                (0.0, 1.0)
            }
        };
        let (x0, x1) = range(&xs);
        let (y0, y1) = range(&ys);
        let pad = 0.05 * (y1 - y0);
        let mut chart = ChartBuilder::on(area)
            .margin(8)
            .x_label_area_size(30)
            .y_label_area_size(60)
            .build_cartesian_2d(x0..x1, (y0 - pad)..(y1 + pad))
            .map_err(err)?;
        chart
            .configure_mesh()
            .x_desc(x_label)
            .y_desc(panel.label.as_str())
            .draw()
            .map_err(err)?;
        for (k, (legend, x, y, points)) in panel.lines.iter().enumerate() {
            let colour = panel
                .colours
                .get(k)
                .copied()
                .unwrap_or(COLOURS[k % COLOURS.len()]);
            let data = x.iter().copied().zip(y.iter().copied());
            let series = if *points {
                chart
                    .draw_series(data.map(|p| Circle::new(p, 2, colour.filled())))
                    .map_err(err)?
            } else {
                chart
                    .draw_series(LineSeries::new(data, colour.stroke_width(2)))
                    .map_err(err)?
            };
            series.label(legend.as_str()).legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 20, y)], colour.stroke_width(2))
            });
        }
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK)
            .draw()
            .map_err(err)?;
    }
    root.present().map_err(err)?;
    Ok(())
}

/// A heat map of `values[row][column]` with the value written in each cell; rows are drawn
/// bottom to top.
pub fn heatmap_png(
    path: &Path,
    title: &str,
    (x_label, column_labels): (&str, &[String]),
    (y_label, row_labels): (&str, &[String]),
    values: &[Vec<f64>],
) -> Result<()> {
    register_font();
    let root = BitMapBackend::new(path, (720, 600)).into_drawing_area();
    root.fill(&WHITE).map_err(err)?;
    let (cols, rows) = (column_labels.len(), row_labels.len());
    let all: Vec<f64> = values
        .iter()
        .flatten()
        .copied()
        .filter(|v| v.is_finite())
        .collect();
    let lo = all.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = all.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let span = if hi > lo { hi - lo } else { 1.0 };
    let mut chart = ChartBuilder::on(&root)
        .caption(title, ("sans-serif", 20))
        .margin(16)
        .x_label_area_size(50)
        .y_label_area_size(70)
        .build_cartesian_2d(0f64..cols as f64, 0f64..rows as f64)
        .map_err(err)?;
    let col_fmt = |x: &f64| {
        let i = x.floor() as usize;
        if (x - x.floor() - 0.5).abs() < 1e-6 && i < cols {
            column_labels[i].clone()
        } else {
            String::new()
        }
    };
    let row_fmt = |y: &f64| {
        let i = y.floor() as usize;
        if (y - y.floor() - 0.5).abs() < 1e-6 && i < rows {
            row_labels[i].clone()
        } else {
            String::new()
        }
    };
    chart
        .configure_mesh()
        .disable_mesh()
        .x_labels(2 * cols + 1)
        .y_labels(2 * rows + 1)
        .x_label_formatter(&col_fmt)
        .y_label_formatter(&row_fmt)
        .x_desc(x_label)
        .y_desc(y_label)
        .draw()
        .map_err(err)?;
    for (r, row) in values.iter().enumerate() {
        for (c, v) in row.iter().enumerate() {
            let s = if v.is_finite() { (v - lo) / span } else { 0.0 };
            let colour = RGBColor(
                (255.0 * s) as u8,
                (60.0 + 120.0 * (1.0 - s)) as u8,
                (255.0 * (1.0 - s)) as u8,
            );
            let (x, y) = (c as f64, r as f64);
            chart
                .draw_series(std::iter::once(Rectangle::new(
                    [(x, y), (x + 1.0, y + 1.0)],
                    colour.filled(),
                )))
                .map_err(err)?;
            chart
                .draw_series(std::iter::once(Text::new(
                    format!("{v:.0}"),
                    (x + 0.38, y + 0.55),
                    ("sans-serif", 20).into_font().color(&WHITE),
                )))
                .map_err(err)?;
        }
    }
    root.present().map_err(err)?;
    Ok(())
}
