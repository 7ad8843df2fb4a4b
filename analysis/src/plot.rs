//! Every picture of the experiments and of `spurio run --plot`, with plotters and the embedded
//! DejaVu Sans (nothing needed from the system). One look for all: legends in a column right
//! of the axes (they hide no data), ticks without needless decimals (sample axes read "200",
//! not "200.0"), axis labels with units given by the caller (`crane.x [m]`).
//!
//! Text note: plotters' glyph layout over-applies kerning ("Ts" overlaps) and misplaces
//! combining accents ("x̂"); write subscripts as Unicode letters ("Tₛ", "x₀"), which DejaVu
//! renders cleanly, and name estimates in words.

use anyhow::{anyhow, Result};
use plotters::coord::Shift;
use plotters::prelude::*;
use spurio_master::{System, SystemError, TimeSeries};
use std::path::Path;
use std::sync::Once;

/// A colour of a plotted series (plotters' RGB colour).
pub use plotters::style::RGBColor;

static FONT: Once = Once::new();

/// Registers the embedded DejaVu Sans as "sans-serif" (once).
fn register_font() {
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

/// Width of the legend column right of each panel (pixels).
const LEGEND_WIDTH: u32 = 230;
/// The colours of lines that do not choose one, in order.
const PALETTE: [RGBColor; 5] = [
    RGBColor(150, 150, 150),
    RGBColor(0, 0, 0),
    RGBColor(200, 30, 30),
    RGBColor(30, 80, 200),
    RGBColor(20, 150, 60),
];

/// A tick label with no needless digits on an axis spanning `span`: `200`, `0.5`,
/// `-0.025`, `1.5e-5`; a tick within rounding error of zero reads `0`.
fn tick(v: f64, span: f64) -> String {
    if !v.is_finite() {
        return v.to_string();
    }
    if v.abs() <= 1e-9 * span.abs() || v == 0.0 {
        return "0".into();
    }
    let trim = |text: String| -> String {
        if text.contains('.') {
            text.trim_end_matches('0').trim_end_matches('.').to_string()
        } else {
            text
        }
    };
    if v.abs() < 1e-3 || v.abs() >= 1e6 {
        let text = format!("{v:.3e}");
        let (mantissa, exponent) = text.split_once('e').unwrap_or((&text, "0"));
        return format!("{}e{exponent}", trim(mantissa.to_string()));
    }
    trim(format!("{v:.6}"))
}

/// How a line's samples are drawn.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Style {
    /// Joined by a line.
    Line,
    /// A dot per sample.
    Points,
    /// A cross per sample (outliers).
    Crosses,
}

/// One line (or point cloud) of a [`Panel`].
#[derive(Debug, Clone)]
pub struct Line {
    /// Its legend entry.
    pub label: String,
    /// x values.
    pub x: Vec<f64>,
    /// y values.
    pub y: Vec<f64>,
    /// How it is drawn.
    pub style: Style,
    /// Its colour (None: the panel's palette by position).
    pub colour: Option<RGBColor>,
}

impl Line {
    /// `label`: y against x, joined.
    pub fn new(label: impl Into<String>, x: Vec<f64>, y: Vec<f64>) -> Self {
        Self {
            label: label.into(),
            x,
            y,
            style: Style::Line,
            colour: None,
        }
    }

    /// Drawn as `style`.
    pub fn style(mut self, style: Style) -> Self {
        self.style = style;
        self
    }

    /// Drawn in `colour`.
    pub fn colour(mut self, colour: RGBColor) -> Self {
        self.colour = Some(colour);
        self
    }
}

/// The measured samples `y` against `x` as two lines of a [`Panel`]: the good ones as grey
/// points labelled `label`, those `outlier(k)` flags as red crosses labelled "outliers".
pub fn measured_lines(
    label: &str,
    x: &[f64],
    y: &[f64],
    outlier: impl Fn(usize) -> bool,
) -> [Line; 2] {
    let split = |wild: bool| -> (Vec<f64>, Vec<f64>) {
        x.iter()
            .zip(y)
            .enumerate()
            .filter(|(k, _)| outlier(*k) == wild)
            .map(|(_, (x, y))| (*x, *y))
            .unzip()
    };
    let ((x_good, y_good), (x_wild, y_wild)) = (split(false), split(true));
    [
        Line::new(label, x_good, y_good)
            .style(Style::Points)
            .colour(RGBColor(150, 150, 150)),
        Line::new("outliers", x_wild, y_wild)
            .style(Style::Crosses)
            .colour(RGBColor(220, 0, 0)),
    ]
}

/// One panel of [`panels_png`]: a y-axis label (with its unit) and the lines drawn in it.
#[derive(Debug, Clone)]
pub struct Panel {
    /// The y-axis label, `cart position x [m]`.
    pub label: String,
    /// The lines, drawn in order (the first underneath).
    pub lines: Vec<Line>,
}

/// The smallest and largest finite value (a unit-wide range around a constant, 0…1 if none).
fn range(values: impl Iterator<Item = f64>) -> (f64, f64) {
    let (lo, hi) = values
        .filter(|v| v.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), x| {
            (a.min(x), b.max(x))
        });
    if lo < hi {
        (lo, hi)
    } else if lo.is_finite() {
        (lo - 1.0, lo + 1.0)
    } else {
        (0.0, 1.0)
    }
}

/// The legend's sample of a line drawn as `style` at (x, y).
fn legend_mark(
    area: &DrawingArea<BitMapBackend<'_>, Shift>,
    style: Style,
    colour: RGBColor,
    (x, y): (i32, i32),
) -> Result<()> {
    match style {
        Style::Line => area.draw(&PathElement::new(
            vec![(x, y), (x + 22, y)],
            colour.stroke_width(2),
        )),
        Style::Points => area.draw(&Circle::new((x + 11, y), 3, colour.filled())),
        Style::Crosses => area.draw(&Cross::new((x + 11, y), 4, colour.stroke_width(2))),
    }
    .map_err(err)
}

/// A legend in its own column: one entry per (label, style, colour), from the top.
fn legend(
    area: &DrawingArea<BitMapBackend<'_>, Shift>,
    entries: &[(&str, Style, RGBColor)],
) -> Result<()> {
    let font = ("sans-serif", 15).into_font().color(&BLACK);
    for (k, (label, style, colour)) in entries.iter().enumerate() {
        let y = 30 + 22 * k as i32;
        legend_mark(area, *style, *colour, (8, y))?;
        area.draw(&Text::new(label.to_string(), (38, y - 8), font.clone()))
            .map_err(err)?;
    }
    Ok(())
}

/// One panel: axes, lines, and the legend column at its right.
fn draw_panel(
    area: &DrawingArea<BitMapBackend<'_>, Shift>,
    x_label: &str,
    panel: &Panel,
) -> Result<()> {
    let (width, _) = area.dim_in_pixel();
    let (plot_area, legend_area) = area.split_horizontally(width.saturating_sub(LEGEND_WIDTH));
    let (x0, x1) = range(panel.lines.iter().flat_map(|l| l.x.iter().copied()));
    let (y0, y1) = range(panel.lines.iter().flat_map(|l| l.y.iter().copied()));
    let pad = 0.05 * (y1 - y0);
    let mut chart = ChartBuilder::on(&plot_area)
        .margin(8)
        .x_label_area_size(40)
        .y_label_area_size(70)
        .build_cartesian_2d(x0..x1, (y0 - pad)..(y1 + pad))
        .map_err(err)?;
    chart
        .configure_mesh()
        .x_desc(x_label)
        .y_desc(panel.label.as_str())
        .x_label_formatter(&|v| tick(*v, x1 - x0))
        .y_label_formatter(&|v| tick(*v, y1 - y0))
        .label_style(("sans-serif", 14))
        .axis_desc_style(("sans-serif", 15))
        .draw()
        .map_err(err)?;
    let mut entries = Vec::new();
    for (k, line) in panel.lines.iter().enumerate() {
        let colour = line.colour.unwrap_or(PALETTE[k % PALETTE.len()]);
        let data = line.x.iter().copied().zip(line.y.iter().copied());
        match line.style {
            Style::Line => chart
                .draw_series(LineSeries::new(data, colour.stroke_width(2)))
                .map(|_| ()),
            Style::Points => chart
                .draw_series(data.map(|p| Circle::new(p, 2, colour.filled())))
                .map(|_| ()),
            Style::Crosses => chart
                .draw_series(data.map(|p| Cross::new(p, 4, colour.stroke_width(2))))
                .map(|_| ()),
        }
        .map_err(err)?;
        entries.push((line.label.as_str(), line.style, colour));
    }
    legend(&legend_area, &entries)
}

/// Several panels stacked vertically, each with any number of lines (or point clouds) and a
/// legend at its right; `x_label` names the common x axis (with its unit).
pub fn panels_png(path: &Path, title: &str, x_label: &str, panels: &[Panel]) -> Result<()> {
    register_font();
    let height = (60 + 260 * panels.len().max(1) as u32).max(480);
    let root = BitMapBackend::new(path, (1100, height)).into_drawing_area();
    root.fill(&WHITE).map_err(err)?;
    let root = root.titled(title, ("sans-serif", 22)).map_err(err)?;
    for (area, panel) in root
        .split_evenly((panels.len().max(1), 1))
        .iter()
        .zip(panels)
    {
        draw_panel(area, x_label, panel)?;
    }
    root.present().map_err(err)
}

/// An axis label for `qualified` with its FMU's unit: `"crane.x [m]"` (the bare name if the
/// FMU declares none).
pub fn axis_label(system: &System, qualified: &str) -> Result<String, SystemError> {
    Ok(match system.unit(qualified)? {
        Some(unit) => format!("{qualified} [{unit}]"),
        None => qualified.to_string(),
    })
}

/// The recorded variables `(name, label)` of `series` against time, one panel each, the
/// label (with the unit, `crane.x [m]`) on its y axis.
pub fn labelled_time_series_png(
    path: &Path,
    title: &str,
    series: &TimeSeries,
    variables: &[(String, String)],
) -> Result<()> {
    let panels = variables
        .iter()
        .map(|(name, label)| {
            let values = series.column(name).ok_or_else(|| {
                anyhow!(
                    "cannot plot `{name}`: it is not recorded (recorded: {})",
                    series.names.join(", ")
                )
            })?;
            Ok(Panel {
                label: label.clone(),
                lines: vec![
                    Line::new(name.as_str(), series.time.clone(), values).colour(PALETTE[3])
                ],
            })
        })
        .collect::<Result<Vec<_>>>()?;
    panels_png(path, title, "time [s]", &panels)
}

/// The named variables of `series` against time, one panel each, labelled with the name.
pub fn time_series_png(
    path: &Path,
    title: &str,
    series: &TimeSeries,
    names: &[String],
) -> Result<()> {
    let variables: Vec<(String, String)> = names.iter().map(|n| (n.clone(), n.clone())).collect();
    labelled_time_series_png(path, title, series, &variables)
}

/// A histogram (bin `edges`, `counts`) with the band `band` (mean ± 2σ) shaded; `x_label`
/// names the value axis (with its unit).
pub fn histogram_png(
    path: &Path,
    title: &str,
    x_label: &str,
    (edges, counts): (&[f64], &[usize]),
    band: (f64, f64),
) -> Result<()> {
    register_font();
    let band_colour = RGBColor(255, 220, 150);
    let bar_colour = RGBColor(30, 80, 200);
    let root = BitMapBackend::new(path, (1000, 480)).into_drawing_area();
    root.fill(&WHITE).map_err(err)?;
    let root = root.titled(title, ("sans-serif", 22)).map_err(err)?;
    let (plot_area, legend_area) = root.split_horizontally(1000 - LEGEND_WIDTH);
    let (lo, hi) = range(edges.iter().copied());
    let (lo, hi) = (lo.min(band.0), hi.max(band.1));
    let top = counts.iter().copied().max().unwrap_or(1) as f64 * 1.1;
    let mut chart = ChartBuilder::on(&plot_area)
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(60)
        .build_cartesian_2d(lo..hi, 0f64..top)
        .map_err(err)?;
    chart
        .configure_mesh()
        .x_desc(x_label)
        .y_desc("count")
        .x_label_formatter(&|v| tick(*v, hi - lo))
        .y_label_formatter(&|v| tick(*v, top))
        .label_style(("sans-serif", 14))
        .axis_desc_style(("sans-serif", 15))
        .draw()
        .map_err(err)?;
    chart
        .draw_series(std::iter::once(Rectangle::new(
            [(band.0, 0.0), (band.1, top)],
            band_colour.mix(0.5).filled(),
        )))
        .map_err(err)?;
    chart
        .draw_series(edges.windows(2).zip(counts).map(|(e, c)| {
            Rectangle::new(
                [(e[0], 0.0), (e[1], *c as f64)],
                bar_colour.mix(0.6).filled(),
            )
        }))
        .map_err(err)?;
    let font = ("sans-serif", 15).into_font().color(&BLACK);
    for (k, (label, colour)) in [("mean ± 2σ", band_colour), ("samples per bin", bar_colour)]
        .into_iter()
        .enumerate()
    {
        let y = 50 + 22 * k as i32;
        legend_area
            .draw(&Rectangle::new([(8, y - 6), (30, y + 6)], colour.filled()))
            .map_err(err)?;
        legend_area
            .draw(&Text::new(label, (38, y - 8), font.clone()))
            .map_err(err)?;
    }
    root.present().map_err(err)
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
    let (lo, hi) = range(values.iter().flatten().copied());
    let span = hi - lo;
    let mut chart = ChartBuilder::on(&root)
        .caption(title, ("sans-serif", 20))
        .margin(16)
        .x_label_area_size(50)
        .y_label_area_size(70)
        .build_cartesian_2d(0f64..cols as f64, 0f64..rows as f64)
        .map_err(err)?;
    let centre_label = |labels: &[String], v: f64| {
        let i = v.floor() as usize;
        if (v - v.floor() - 0.5).abs() < 1e-6 && i < labels.len() {
            labels[i].clone()
        } else {
            String::new()
        }
    };
    let col_fmt = |x: &f64| centre_label(column_labels, *x);
    let row_fmt = |y: &f64| centre_label(row_labels, *y);
    chart
        .configure_mesh()
        .disable_mesh()
        .x_labels(2 * cols + 1)
        .y_labels(2 * rows + 1)
        .x_label_formatter(&col_fmt)
        .y_label_formatter(&row_fmt)
        .label_style(("sans-serif", 16))
        .axis_desc_style(("sans-serif", 16))
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
    root.present().map_err(err)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ticks_carry_no_needless_digits() {
        assert_eq!(tick(200.0, 1000.0), "200");
        assert_eq!(tick(0.5, 1.0), "0.5");
        assert_eq!(tick(-0.025, 0.1), "-0.025");
        assert_eq!(tick(0.30000000000000004, 1.0), "0.3");
        assert_eq!(tick(2.783e-17, 0.6), "0");
        assert_eq!(tick(1.5e-5, 1e-4), "1.5e-5");
        assert_eq!(tick(-1.0000000000000002e-7, 1e-6), "-1e-7");
        assert_eq!(tick(2e6, 1e7), "2e6");
    }

    #[test]
    fn ranges_skip_non_finite_values_and_widen_constants() {
        assert_eq!(range([1.0, f64::NAN, 3.0].into_iter()), (1.0, 3.0));
        assert_eq!(range([2.0, 2.0].into_iter()), (1.0, 3.0));
        assert_eq!(range(std::iter::empty()), (0.0, 1.0));
    }
}
