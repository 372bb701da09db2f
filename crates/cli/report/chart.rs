//! Time-series line charts: residuals per particle over time, cost history on a log axis.
//!
//! Drawn with plotters' bitmap backend into an RGB buffer, then encoded as PNG by [`super::write_png`].

use std::ops::Range;
use std::path::Path;

use anyhow::Context;
use image::RgbImage;
use plotters::chart::ChartBuilder;
use plotters::coord::ranged1d::{AsRangedCoord, ValueFormatter};
use plotters::coord::Shift;
use plotters::element::{Circle, DashedPathElement, PathElement, Text};
use plotters::prelude::{BitMapBackend, DrawingArea, DrawingBackend, IntoDrawingArea, IntoLogRange};
use plotters::style::{RGBColor, ShapeStyle, TRANSPARENT, WHITE};

use super::colour::palette_colour;
use super::font;
use super::legend::{draw_legend, legend_width, LegendEntry, Swatch};

/// How a series' line is drawn.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum LineStyle {
    /// A continuous line (e.g. residuals before a model change, observed tracks).
    #[default]
    Solid,
    /// Dashes of 8 px with 5 px gaps (e.g. residuals after a model change, a model's prediction).
    Dashed,
    /// Dashes of 2 px with 4 px gaps (e.g. a second model's prediction).
    Dotted,
}

impl LineStyle {
    /// (dash length, gap length) in pixels; a dash length of 0 means a continuous line.
    pub(crate) fn dash_pattern(self) -> (i32, i32) {
        match self {
            LineStyle::Solid => (0, 0),
            LineStyle::Dashed => (8, 5),
            LineStyle::Dotted => (2, 4),
        }
    }
}

/// One named curve of a [`LineChart`]: a sequence of (x, y) samples joined in order.
#[derive(Debug, Clone, PartialEq)]
pub struct Series {
    /// The legend text, e.g. `"p3 before"` or `"cost"`.
    pub name: String,
    /// Samples in chart units (e.g. time in s, residual in px). A sample with a NaN or infinite coordinate (or,
    /// on a log axis, y <= 0) is not drawn and breaks the line there.
    pub points: Vec<(f64, f64)>,
    /// Solid, dashed or dotted.
    pub style: LineStyle,
    /// Index into the report palette (`palette_colour`); `None` takes the series' position in the chart.
    /// Give the same index to the same particle's "before" and "after" series.
    pub colour: Option<usize>,
}

impl Series {
    /// A solid series in the colour of its position in the chart.
    pub fn new(name: impl Into<String>, points: Vec<(f64, f64)>) -> Self {
        Series {
            name: name.into(),
            points,
            style: LineStyle::Solid,
            colour: None,
        }
    }

    /// The same series drawn in `style`.
    #[must_use]
    pub fn with_style(mut self, style: LineStyle) -> Self {
        self.style = style;
        self
    }

    /// The same series drawn in palette colour `index`.
    #[must_use]
    pub fn with_colour(mut self, index: usize) -> Self {
        self.colour = Some(index);
        self
    }
}

/// A line chart: title, labelled axes (put the units in the labels, e.g. `"time (s)"`), a legend, and series.
#[derive(Debug, Clone, PartialEq)]
pub struct LineChart {
    /// Title drawn above the plot.
    pub title: String,
    /// Label of the horizontal axis, with its unit.
    pub x_label: String,
    /// Label of the vertical axis, with its unit.
    pub y_label: String,
    /// True for a base-10 logarithmic y axis (cost histories); non-positive y values are then skipped.
    pub log_y: bool,
    /// The curves, drawn in order (later ones on top).
    pub series: Vec<Series>,
    /// Picture size in pixels (width, height); [`LineChart::new`] sets 900 x 420.
    pub size: (u32, u32),
    /// Fixed y-axis bounds (data units), so that two charts share one scale; from the data
    /// when `None`.
    pub y_range: Option<(f64, f64)>,
}

impl LineChart {
    /// An empty linear chart of 900 x 420 pixels.
    pub fn new(title: impl Into<String>, x_label: impl Into<String>, y_label: impl Into<String>) -> Self {
        LineChart {
            title: title.into(),
            x_label: x_label.into(),
            y_label: y_label.into(),
            log_y: false,
            series: Vec::new(),
            size: (900, 420),
            y_range: None,
        }
    }
}

/// Draws `chart` and writes it to `path` as a PNG (atomically). Errors name the file.
pub fn line_chart(path: &Path, chart: &LineChart) -> anyhow::Result<()> {
    let image = render_line_chart(chart).with_context(|| format!("drawing chart {}", path.display()))?;
    super::write_png(path, &image)
}

/// Draws `chart` into an RGB image of `chart.size` pixels (what [`line_chart`] writes).
pub fn render_line_chart(chart: &LineChart) -> anyhow::Result<RgbImage> {
    render_with_mapping(chart).map(|(image, _)| image)
}

/// Where the data went: the plot rectangle in pixels and the data ranges it shows (for tests and for callers that
/// annotate a chart afterwards).
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct PlotMapping {
    /// Data range shown horizontally.
    pub x: Range<f64>,
    /// Data range shown vertically (the values themselves, also on a log axis).
    pub y: Range<f64>,
    /// True for a logarithmic y axis.
    pub log_y: bool,
    /// Pixel columns of the plot rectangle.
    pub px: Range<i32>,
    /// Pixel rows of the plot rectangle.
    pub py: Range<i32>,
}

#[cfg(test)]
impl PlotMapping {
    /// The pixel (column, row) where the data point (x, y) is drawn.
    pub fn to_pixel(&self, x: f64, y: f64) -> (i32, i32) {
        let fx = (x - self.x.start) / (self.x.end - self.x.start);
        let fy = if self.log_y {
            (y.log10() - self.y.start.log10()) / (self.y.end.log10() - self.y.start.log10())
        } else {
            (y - self.y.start) / (self.y.end - self.y.start)
        };
        let col = f64::from(self.px.start) + fx * f64::from(self.px.end - self.px.start);
        let row = f64::from(self.py.end) - fy * f64::from(self.py.end - self.py.start);
        (col.round() as i32, row.round() as i32)
    }
}

/// True if and only if the sample can be drawn on the chart's axes.
fn drawable((x, y): (f64, f64), log_y: bool) -> bool {
    x.is_finite() && y.is_finite() && (!log_y || y > 0.0)
}

/// The runs of consecutive drawable samples of `points`: an undrawable sample ends a run.
pub(crate) fn segments(points: &[(f64, f64)], log_y: bool) -> Vec<Vec<(f64, f64)>> {
    let mut runs = Vec::new();
    let mut run = Vec::new();
    for &p in points {
        if drawable(p, log_y) {
            run.push(p);
        } else if !run.is_empty() {
            runs.push(std::mem::take(&mut run));
        }
    }
    if !run.is_empty() {
        runs.push(run);
    }
    runs
}

/// (min, max) of the finite values, or None when there is none.
pub(crate) fn finite_bounds(values: impl Iterator<Item = f64>) -> Option<(f64, f64)> {
    values.filter(|v| v.is_finite()).fold(None, |acc, v| match acc {
        None => Some((v, v)),
        Some((lo, hi)) => Some((lo.min(v), hi.max(v))),
    })
}

/// A linear axis range around [lo, hi], widened by `pad` of its span on each side, never empty.
pub(crate) fn linear_range(bounds: Option<(f64, f64)>, pad: f64) -> Range<f64> {
    let (lo, hi) = bounds.unwrap_or((0.0, 1.0));
    let span = hi - lo;
    if span > 1e-12 * hi.abs().max(lo.abs()).max(1e-300) {
        (lo - pad * span)..(hi + pad * span)
    } else {
        let half = if lo.abs() > 0.0 { 0.1 * lo.abs() } else { 1.0 };
        (lo - half)..(hi + half)
    }
}

/// A log axis range around the positive [lo, hi], widened by 5 % of its span in decades, never empty.
fn log_range(bounds: Option<(f64, f64)>) -> Range<f64> {
    let (lo, hi) = bounds.unwrap_or((0.1, 10.0));
    let (l0, l1) = (lo.log10(), hi.log10());
    let (l0, l1) = if l1 - l0 > 1e-9 {
        (l0 - 0.05 * (l1 - l0), l1 + 0.05 * (l1 - l0))
    } else {
        (l0 - 0.5, l1 + 0.5)
    };
    10f64.powf(l0)..10f64.powf(l1)
}

/// Tick label for `v` on a linear axis spanning `span`: enough decimals for the tick spacing, scientific
/// notation for very large or very small magnitudes.
pub(crate) fn linear_tick_label(v: f64, span: f64) -> String {
    let step = span / 10.0;
    let v = if v.abs() < step * 1e-6 { 0.0 } else { v };
    let magnitude = v.abs().max(step);
    if !(1e-3..1e5).contains(&magnitude) {
        return trim_exponent(&format!("{v:.1e}"));
    }
    // Enough decimals for the tick spacing, more if the tick itself needs them (2.5 on an axis ticked in 1s).
    let mut decimals = (-step.log10().floor()).clamp(0.0, 6.0) as usize;
    while decimals < 6 && (format!("{v:.decimals$}").parse::<f64>().unwrap_or(v) - v).abs() > step * 1e-3 {
        decimals += 1;
    }
    format!("{v:.decimals$}")
}

/// Tick label on a log axis: "1e-8", "2e-8", "2.5e3".
fn log_tick_label(v: f64) -> String {
    trim_exponent(&format!("{v:.1e}"))
}

/// "1.0e-8" → "1e-8"; "2.5e3" unchanged.
fn trim_exponent(s: &str) -> String {
    s.replace(".0e", "e")
}

/// Series colours in drawing order.
fn series_colour(series: &Series, position: usize) -> [u8; 3] {
    palette_colour(series.colour.unwrap_or(position))
}

/// Draws the chart and returns the image with the mapping from data to pixels.
pub(crate) fn render_with_mapping(chart: &LineChart) -> anyhow::Result<(RgbImage, PlotMapping)> {
    font::ensure_registered()?;
    let (width, height) = chart.size;
    anyhow::ensure!(
        width >= 200 && height >= 150,
        "a chart needs at least 200 x 150 pixels, not {width} x {height}"
    );
    let log_y = chart.log_y;
    let all = || {
        chart
            .series
            .iter()
            .flat_map(|s| s.points.iter().copied())
            .filter(|&p| drawable(p, log_y))
    };
    let x_range = linear_range(finite_bounds(all().map(|p| p.0)), 0.0);
    let y_bounds = chart
        .y_range
        .filter(|r| r.0.is_finite() && r.1.is_finite() && r.1 > r.0)
        .or_else(|| finite_bounds(all().map(|p| p.1)));
    let entries: Vec<LegendEntry> = chart
        .series
        .iter()
        .enumerate()
        .map(|(i, s)| LegendEntry {
            label: s.name.clone(),
            swatch: Swatch::Line(series_colour(s, i), s.style),
        })
        .collect();
    let mut buffer = vec![255u8; width as usize * height as usize * 3];
    let mapping = {
        let root = BitMapBackend::with_buffer(&mut buffer, (width, height)).into_drawing_area();
        root.fill(&WHITE).map_err(draw_err)?;
        let legend_w = legend_width(&entries, width / 3)?;
        let (main, side) = root.split_horizontally(width - legend_w);
        let mapping = if log_y {
            let y_range = log_range(y_bounds);
            let fmt = |v: &f64| log_tick_label(*v);
            let spec = y_range.clone().log_scale();
            draw_plot(&main, chart, x_range, spec, y_range, &fmt)?
        } else {
            let y_range = linear_range(y_bounds, 0.05);
            let span = y_range.end - y_range.start;
            let fmt = move |v: &f64| linear_tick_label(*v, span);
            draw_plot(&main, chart, x_range, y_range.clone(), y_range, &fmt)?
        };
        draw_legend(&side, &entries, mapping.py.start)?;
        if y_bounds.is_none() {
            let note = if log_y {
                "no positive data to draw"
            } else {
                "no data to draw"
            };
            let at = (
                (mapping.px.start + mapping.px.end) / 2 - 60,
                (mapping.py.start + mapping.py.end) / 2,
            );
            root.draw(&Text::new(note, at, font::text(16.0)))
                .map_err(draw_err)?;
        }
        root.present().map_err(draw_err)?;
        mapping
    };
    let image = RgbImage::from_raw(width, height, buffer).context("chart buffer has the wrong size")?;
    Ok((image, mapping))
}

/// Turns a plotters error into an anyhow one (plotters' error types are generic over the backend).
pub(crate) fn draw_err(e: impl std::fmt::Display) -> anyhow::Error {
    anyhow::anyhow!("drawing failed: {e}")
}

/// Draws axes, ticks, labels, title and series of `chart` on `area` with the y axis `y_spec`.
fn draw_plot<DB, Y>(
    area: &DrawingArea<DB, Shift>,
    chart: &LineChart,
    x_range: Range<f64>,
    y_spec: Y,
    y_range: Range<f64>,
    y_fmt: &dyn Fn(&f64) -> String,
) -> anyhow::Result<PlotMapping>
where
    DB: DrawingBackend,
    Y: AsRangedCoord<Value = f64>,
    Y::CoordDescType: ValueFormatter<f64>,
{
    let x_span = x_range.end - x_range.start;
    let x_fmt = move |v: &f64| linear_tick_label(*v, x_span);
    let mut ctx = ChartBuilder::on(area)
        .caption(&chart.title, font::text(18.0))
        .margin(12)
        .x_label_area_size(48)
        .y_label_area_size(76)
        .build_cartesian_2d(x_range.clone(), y_spec)
        .map_err(draw_err)?;
    ctx.configure_mesh()
        .x_desc(&chart.x_label)
        .y_desc(&chart.y_label)
        .label_style(font::text(12.0))
        .axis_desc_style(font::text(14.0))
        .bold_line_style(RGBColor(225, 225, 225))
        .light_line_style(TRANSPARENT)
        .x_labels(10)
        .y_labels(8)
        .x_label_formatter(&x_fmt)
        .y_label_formatter(y_fmt)
        .draw()
        .map_err(draw_err)?;
    let plot = ctx.plotting_area();
    for (i, series) in chart.series.iter().enumerate() {
        let c = series_colour(series, i);
        let style = ShapeStyle::from(RGBColor(c[0], c[1], c[2])).stroke_width(2);
        for run in segments(&series.points, chart.log_y) {
            let result = match (run.len(), series.style.dash_pattern()) {
                // A lone sample between gaps would be invisible as a line: mark it with a dot.
                (1, _) => plot.draw(&Circle::new(run[0], 2, style.filled())),
                (_, (0, _)) => plot.draw(&PathElement::new(run, style)),
                (_, (dash, gap)) => plot.draw(&DashedPathElement::new(run, dash, gap, style)),
            };
            result.map_err(draw_err)?;
        }
    }
    let (px, py) = plot.get_pixel_range();
    Ok(PlotMapping {
        x: x_range,
        y: y_range,
        log_y: chart.log_y,
        px,
        py,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// True if and only if some pixel within `radius` of (col, row) is within 40 (per channel) of `colour`.
    fn colour_near(image: &RgbImage, (col, row): (i32, i32), radius: i32, colour: [u8; 3]) -> bool {
        (-radius..=radius).any(|dy| {
            (-radius..=radius).any(|dx| {
                let (x, y) = (col + dx, row + dy);
                x >= 0
                    && y >= 0
                    && (x as u32) < image.width()
                    && (y as u32) < image.height()
                    && image
                        .get_pixel(x as u32, y as u32)
                        .0
                        .iter()
                        .zip(colour)
                        .all(|(&a, b)| a.abs_diff(b) <= 40)
            })
        })
    }

    fn residual_chart() -> LineChart {
        let mut chart = LineChart::new("Residuals", "time (s)", "residual (px)");
        // A flat series at y = 1 with a NaN gap between t = 4 and t = 6, and a second one at y = -1 from t = 5 on.
        let mut before: Vec<(f64, f64)> = (0..=40).map(|k| (f64::from(k) * 0.25, 1.0)).collect();
        for p in before.iter_mut().filter(|p| p.0 > 4.0 && p.0 < 6.0) {
            p.1 = f64::NAN;
        }
        let after: Vec<(f64, f64)> = (20..=40).map(|k| (f64::from(k) * 0.25, -1.0)).collect();
        chart.series.push(Series::new("p0 before", before).with_colour(0));
        chart.series.push(
            Series::new("p0 after", after)
                .with_colour(1)
                .with_style(LineStyle::Dashed),
        );
        chart
    }

    #[test]
    fn chart_png_decodes_with_requested_size() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("residuals.png");
        let mut chart = residual_chart();
        chart.size = (640, 360);
        line_chart(&path, &chart).unwrap();
        let decoded = image::open(&path).unwrap();
        assert_eq!((decoded.width(), decoded.height()), (640, 360));
        // No temporary file is left beside the picture.
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
    }

    #[test]
    fn series_pixels_where_drawn_and_none_where_not() {
        let chart = residual_chart();
        let (image, map) = render_with_mapping(&chart).unwrap();
        assert_eq!(image.dimensions(), (900, 420));
        let solid = palette_colour(0);
        let dashed = palette_colour(1);
        // The plot rectangle is a sensible part of the picture (axes and labels left/below, legend right).
        assert!(
            map.px.start > 40 && map.px.end < 900 && map.py.start > 20 && map.py.end < 400,
            "{map:?}"
        );
        // The solid series is drawn where it has samples ...
        for t in [0.5, 2.0, 3.5, 7.0, 9.5] {
            assert!(
                colour_near(&image, map.to_pixel(t, 1.0), 2, solid),
                "no solid line at t = {t}"
            );
        }
        // ... and not inside its NaN gap, nor where no series goes (y = 0).
        for t in [4.75, 5.0, 5.25] {
            assert!(
                !colour_near(&image, map.to_pixel(t, 1.0), 2, solid),
                "line drawn across the gap at t = {t}"
            );
        }
        for t in [1.0, 5.0, 9.0] {
            let p = map.to_pixel(t, 0.0);
            assert!(
                !colour_near(&image, p, 3, solid) && !colour_near(&image, p, 3, dashed),
                "stray ink at t = {t}"
            );
        }
        // The dashed series starts at t = 5: nothing before it, dashes (some ink, some gaps) after it.
        assert!(!colour_near(&image, map.to_pixel(2.0, -1.0), 3, dashed));
        let row = map.to_pixel(7.0, -1.0).1;
        let (c0, c1) = (map.to_pixel(5.5, -1.0).0, map.to_pixel(9.5, -1.0).0);
        let inked = (c0..c1)
            .filter(|&c| colour_near(&image, (c, row), 1, dashed))
            .count();
        let total = (c1 - c0) as usize;
        assert!(
            inked > total / 3 && inked < total,
            "dashed line covers {inked} of {total} columns"
        );
    }

    #[test]
    fn log_axis_spans_ten_decades_and_skips_non_positive_values() {
        let mut chart = LineChart::new("Cost history", "iteration", "cost (px²)");
        chart.log_y = true;
        // 1e2 down to 1e-8 over 101 iterations, with a zero and a negative cost in the middle.
        let mut cost: Vec<(f64, f64)> = (0..=100)
            .map(|k| (f64::from(k), 10f64.powf(2.0 - 0.1 * f64::from(k))))
            .collect();
        cost[50].1 = 0.0;
        cost[51].1 = -3.0;
        chart.series.push(Series::new("cost", cost));
        let (image, map) = render_with_mapping(&chart).unwrap();
        assert!(map.log_y && map.y.start <= 1e-8 && map.y.end >= 1e2, "{map:?}");
        let c = palette_colour(0);
        // Points at both ends of the range and in the middle decade are drawn where a log axis puts them.
        for k in [2.0, 30.0, 70.0, 98.0] {
            let y = 10f64.powf(2.0 - 0.1 * k);
            assert!(
                colour_near(&image, map.to_pixel(k, y), 2, c),
                "cost {y:e} at iteration {k} not drawn"
            );
        }
        // The curve is a straight line on a log axis: halfway in iterations is halfway in pixels.
        let (_, r0) = map.to_pixel(0.0, 1e2);
        let (_, r1) = map.to_pixel(100.0, 1e-8);
        let (_, rm) = map.to_pixel(30.0, 10f64.powf(-1.0));
        assert!((f64::from(rm) - (0.7 * f64::from(r0) + 0.3 * f64::from(r1))).abs() <= 1.0);
        // The non-positive samples are skipped: the line breaks around them.
        let gap = map.to_pixel(50.5, 10f64.powf(2.0 - 5.05));
        assert!(
            !colour_near(&image, gap, 1, c),
            "the line crosses the skipped samples"
        );
    }

    #[test]
    fn all_non_positive_on_log_axis_still_draws_an_empty_chart() {
        let mut chart = LineChart::new("Cost", "iteration", "cost");
        chart.log_y = true;
        chart.series.push(Series::new(
            "cost",
            vec![(0.0, 0.0), (1.0, -1.0), (2.0, f64::NAN)],
        ));
        let image = render_line_chart(&chart).unwrap();
        assert_eq!(image.dimensions(), (900, 420));
    }

    #[test]
    fn too_small_chart_is_an_error_naming_the_size() {
        let mut chart = LineChart::new("t", "x", "y");
        chart.size = (50, 40);
        let err = render_line_chart(&chart).unwrap_err().to_string();
        assert!(err.contains("50 x 40"), "{err}");
    }

    #[test]
    fn segments_break_at_nan_and_non_positive_on_log() {
        let pts = [
            (0.0, 1.0),
            (1.0, f64::NAN),
            (2.0, 2.0),
            (3.0, 3.0),
            (4.0, -1.0),
            (5.0, 5.0),
        ];
        assert_eq!(segments(&pts, false).len(), 2);
        assert_eq!(
            segments(&pts, true),
            vec![vec![(0.0, 1.0)], vec![(2.0, 2.0), (3.0, 3.0)], vec![(5.0, 5.0)]]
        );
    }

    #[test]
    fn tick_labels_read_cleanly() {
        assert_eq!(linear_tick_label(2.5, 10.0), "2.5");
        assert_eq!(linear_tick_label(2.0, 100.0), "2");
        assert_eq!(linear_tick_label(-0.0, 1.0), "0.0");
        assert_eq!(linear_tick_label(3e-6, 1e-5), "3e-6");
        assert_eq!(log_tick_label(1e-8), "1e-8");
        assert_eq!(log_tick_label(250.0), "2.5e2");
    }
}
