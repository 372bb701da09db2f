//! Trajectory plots: observed tracks with models' predicted trajectories drawn over them, in image coordinates.

use std::ops::Range;
use std::path::Path;

use anyhow::Context;
use image::RgbImage;
use plotters::chart::ChartBuilder;
use plotters::coord::ReverseCoordTranslate;
use plotters::element::{Circle, DashedPathElement, PathElement, Rectangle, Text};
use plotters::prelude::{BitMapBackend, IntoDrawingArea};
use plotters::style::text_anchor::{HPos, Pos, VPos};
use plotters::style::{Color, RGBColor, ShapeStyle, TRANSPARENT, WHITE};

use super::chart::{draw_err, finite_bounds, linear_range, linear_tick_label, segments, LineStyle};
use super::colour::{darken, palette_colour};
use super::font;
use super::legend::{draw_legend, legend_width, LegendEntry, Swatch};

/// The observed track of one particle, in image pixels (x right, y down).
#[derive(Debug, Clone, PartialEq)]
pub struct Track {
    /// The particle's name, e.g. `"p3"` (legend text).
    pub name: String,
    /// Positions frame by frame (px); a NaN position (particle not seen) breaks the line.
    pub points: Vec<(f64, f64)>,
}

/// The trajectories one model predicts, one per observed track.
#[derive(Debug, Clone, PartialEq)]
pub struct ModelPaths {
    /// The model's name, e.g. `"springs only"` (legend text).
    pub name: String,
    /// `paths[i]` is the prediction for `tracks[i]` (px, y down), drawn in a darker shade of that track's colour.
    /// Missing trailing entries draw nothing for those tracks.
    pub paths: Vec<Vec<(f64, f64)>>,
}

/// A located mismatch between model and observation: circled and labelled on the plot.
#[derive(Debug, Clone, PartialEq)]
pub struct Mismatch {
    /// Centre of the region (px, image coordinates).
    pub position: (f64, f64),
    /// Radius of the region (px, image coordinates); drawn at least 8 screen pixels wide so it stays visible.
    pub radius: f64,
    /// Short text beside the circle, e.g. `"p2: drag?"`.
    pub label: String,
}

/// A trajectory plot: what [`trajectory_plot`] draws.
#[derive(Debug, Clone, PartialEq)]
pub struct TrajectoryPlot {
    /// Title drawn above the plot.
    pub title: String,
    /// Observed tracks, solid, one palette colour per track (track `i` gets `palette_colour(i)`).
    pub tracks: Vec<Track>,
    /// Predictions of at most two models: the first dashed, the second dotted.
    pub models: Vec<ModelPaths>,
    /// Located mismatches, circled in black with their label.
    pub mismatches: Vec<Mismatch>,
    /// A frame of the recording drawn faded under everything, at its pixel positions (pixel centres at integer
    /// coordinates); the plot then shows the whole frame.
    pub background: Option<RgbImage>,
    /// Size (width, height) of the recording's frames in pixels: without a background, show the whole frame
    /// rather than just the region the tracks cover.
    pub frame_size: Option<(u32, u32)>,
    /// Picture width in pixels ([`TrajectoryPlot::new`]: 900); the height follows from the shown region so that a
    /// pixel of the recording stays square.
    pub width: u32,
    /// Show only the region the tracks, predictions and mismatches cover (with a margin), even over a background
    /// frame, instead of the whole frame: for small objects in large frames.
    pub zoom: bool,
}

impl TrajectoryPlot {
    /// An empty plot 900 pixels wide.
    pub fn new(title: impl Into<String>) -> Self {
        TrajectoryPlot {
            title: title.into(),
            tracks: Vec::new(),
            models: Vec::new(),
            mismatches: Vec::new(),
            background: None,
            frame_size: None,
            width: 900,
            zoom: false,
        }
    }
}

/// Height of the title strip (px).
const TITLE_HEIGHT: u32 = 36;
/// Blank margin around the plot (px).
const MARGIN: u32 = 12;
/// Room for the x tick labels and axis label (px).
const X_LABEL_AREA: u32 = 48;
/// Room for the y tick labels and axis label (px).
const Y_LABEL_AREA: u32 = 64;
/// Plot heights outside this range (px) are clamped, and the shown region widened to keep pixels square.
const PLOT_HEIGHT_RANGE: (f64, f64) = (240.0, 900.0);
/// How much of the background frame's contrast is kept (the rest fades to white) so that tracks stand out.
const BACKGROUND_CONTRAST: f64 = 0.45;
/// Tracks beyond this count share one legend row instead of one row each.
const MAX_TRACK_ROWS: usize = 12;

/// Draws `plot` and writes it to `path` as a PNG (atomically). Errors name the file.
pub fn trajectory_plot(path: &Path, plot: &TrajectoryPlot) -> anyhow::Result<()> {
    let image = render_trajectory_plot(plot)
        .with_context(|| format!("drawing trajectory plot {}", path.display()))?;
    super::write_png(path, &image)
}

/// The line style of model `index` (0: dashed, 1: dotted).
fn model_style(index: usize) -> LineStyle {
    if index == 0 {
        LineStyle::Dashed
    } else {
        LineStyle::Dotted
    }
}

/// The legend rows of a plot.
fn legend_entries(plot: &TrajectoryPlot) -> Vec<LegendEntry> {
    let mut entries = Vec::new();
    if plot.tracks.len() <= MAX_TRACK_ROWS {
        for (i, t) in plot.tracks.iter().enumerate() {
            entries.push(LegendEntry {
                label: t.name.clone(),
                swatch: Swatch::Line(palette_colour(i), LineStyle::Solid),
            });
        }
    } else {
        let label = format!("{} observed tracks", plot.tracks.len());
        entries.push(LegendEntry {
            label,
            swatch: Swatch::Line([90, 90, 90], LineStyle::Solid),
        });
    }
    if !plot.models.is_empty() {
        entries.push(LegendEntry {
            label: "observed".into(),
            swatch: Swatch::Line([60, 60, 60], LineStyle::Solid),
        });
    }
    for (m, model) in plot.models.iter().enumerate() {
        let label = format!("{} (predicted)", model.name);
        entries.push(LegendEntry {
            label,
            swatch: Swatch::Line([60, 60, 60], model_style(m)),
        });
    }
    if !plot.mismatches.is_empty() {
        entries.push(LegendEntry {
            label: "located mismatch".into(),
            swatch: Swatch::Circle([20, 20, 20]),
        });
    }
    entries
}

/// The region of the image plane shown (x range, y range in px, y down), before matching the plot's aspect.
fn shown_region(plot: &TrajectoryPlot) -> (Range<f64>, Range<f64>) {
    let frame = plot
        .background
        .as_ref()
        .map(|b| b.dimensions())
        .or(plot.frame_size);
    // Pixel centres are at integers, so the frame's edges are half a pixel outside them.
    let whole = frame.map(|(w, h)| (-0.5..f64::from(w) - 0.5, -0.5..f64::from(h) - 0.5));
    if let (Some(whole), false) = (&whole, plot.zoom) {
        return whole.clone();
    }
    let paths = plot
        .tracks
        .iter()
        .map(|t| &t.points)
        .chain(plot.models.iter().flat_map(|m| m.paths.iter()));
    let points: Vec<(f64, f64)> = paths.flat_map(|p| p.iter().copied()).collect();
    let circles = plot.mismatches.iter().flat_map(|m| {
        let (x, y, r) = (m.position.0, m.position.1, m.radius.max(0.0));
        [(x - r, y - r), (x + r, y + r)]
    });
    let all: Vec<(f64, f64)> = points
        .into_iter()
        .chain(circles)
        .filter(|p| p.0.is_finite() && p.1.is_finite())
        .collect();
    let margin = if whole.is_some() { 0.15 } else { 0.05 };
    let (xs, ys) = (
        linear_range(finite_bounds(all.iter().map(|p| p.0)), margin),
        linear_range(finite_bounds(all.iter().map(|p| p.1)), margin),
    );
    (xs, ys)
}

/// Widens `range` about its centre to `length`, if shorter.
fn widen(range: Range<f64>, length: f64) -> Range<f64> {
    let extra = (length - (range.end - range.start)).max(0.0) / 2.0;
    (range.start - extra)..(range.end + extra)
}

/// Draws `plot` into an RGB image (what [`trajectory_plot`] writes).
pub fn render_trajectory_plot(plot: &TrajectoryPlot) -> anyhow::Result<RgbImage> {
    font::ensure_registered()?;
    anyhow::ensure!(
        plot.models.len() <= 2,
        "a trajectory plot shows at most two models, not {}",
        plot.models.len()
    );
    let width = plot.width;
    let entries = legend_entries(plot);
    let legend_w = legend_width(&entries, width / 3)?;
    let fixed_w = legend_w + 2 * MARGIN + Y_LABEL_AREA;
    anyhow::ensure!(
        width >= fixed_w + 160,
        "a trajectory plot needs at least {} pixels of width, not {width}",
        fixed_w + 160
    );
    let plot_w = f64::from(width - fixed_w);
    let (xs, ys) = shown_region(plot);
    let aspect = (ys.end - ys.start) / (xs.end - xs.start);
    let plot_h = (plot_w * aspect)
        .clamp(PLOT_HEIGHT_RANGE.0, PLOT_HEIGHT_RANGE.1)
        .round();
    // Square pixels: widen whichever range is short for the plot box.
    let (xs, ys) = (
        widen(xs.clone(), (ys.end - ys.start) * plot_w / plot_h),
        widen(ys.clone(), (xs.end - xs.start) * plot_h / plot_w),
    );
    let height = plot_h as u32 + TITLE_HEIGHT + 2 * MARGIN + X_LABEL_AREA;

    let mut buffer = vec![255u8; width as usize * height as usize * 3];
    {
        let root = BitMapBackend::with_buffer(&mut buffer, (width, height)).into_drawing_area();
        root.fill(&WHITE).map_err(draw_err)?;
        let (title_area, body) = root.split_vertically(TITLE_HEIGHT);
        let title_style = font::text(18.0).pos(Pos::new(HPos::Center, VPos::Center));
        let centre = ((width / 2) as i32, (TITLE_HEIGHT / 2) as i32 + 2);
        title_area
            .draw(&Text::new(plot.title.clone(), centre, title_style))
            .map_err(draw_err)?;
        let (main, side) = body.split_horizontally(width - legend_w);
        // The y axis shows -y so that image rows grow downwards; tick labels undo the sign.
        let mut ctx = ChartBuilder::on(&main)
            .margin(MARGIN)
            .x_label_area_size(X_LABEL_AREA)
            .y_label_area_size(Y_LABEL_AREA)
            .build_cartesian_2d(xs.clone(), -ys.end..-ys.start)
            .map_err(draw_err)?;
        let (px, py) = ctx.plotting_area().get_pixel_range();
        if let Some(frame) = &plot.background {
            let coords = ctx.as_coord_spec().clone();
            for row in py.clone() {
                for col in px.clone() {
                    let Some((x, minus_y)) = coords.reverse_translate((col, row)) else {
                        continue;
                    };
                    let (fx, fy) = (x.round(), (-minus_y).round());
                    if fx < 0.0
                        || fy < 0.0
                        || fx >= f64::from(frame.width())
                        || fy >= f64::from(frame.height())
                    {
                        continue;
                    }
                    let p = frame.get_pixel(fx as u32, fy as u32).0;
                    let faded =
                        p.map(|c| (255.0 - (255.0 - f64::from(c)) * BACKGROUND_CONTRAST).round() as u8);
                    root.draw_pixel((col, row), &RGBColor(faded[0], faded[1], faded[2]))
                        .map_err(draw_err)?;
                }
            }
        }
        let (x_span, y_span) = (xs.end - xs.start, ys.end - ys.start);
        let x_fmt = move |v: &f64| linear_tick_label(*v, x_span);
        let y_fmt = move |v: &f64| linear_tick_label(-*v, y_span);
        let grid = if plot.background.is_some() {
            TRANSPARENT
        } else {
            RGBColor(230, 230, 230).to_rgba()
        };
        ctx.configure_mesh()
            .x_desc("x (px)")
            .y_desc("y (px, down)")
            .label_style(font::text(12.0))
            .axis_desc_style(font::text(14.0))
            .bold_line_style(grid)
            .light_line_style(TRANSPARENT)
            .x_labels(10)
            .y_labels(8)
            .x_label_formatter(&x_fmt)
            .y_label_formatter(&y_fmt)
            .draw()
            .map_err(draw_err)?;
        let area = ctx.plotting_area();
        let flip = |run: Vec<(f64, f64)>| run.into_iter().map(|(x, y)| (x, -y)).collect::<Vec<_>>();
        for (i, track) in plot.tracks.iter().enumerate() {
            let c = palette_colour(i);
            let style = ShapeStyle::from(RGBColor(c[0], c[1], c[2])).stroke_width(2);
            for run in segments(&track.points, false) {
                let run = flip(run);
                let drawn = if run.len() == 1 {
                    area.draw(&Circle::new(run[0], 2, style.filled()))
                } else {
                    area.draw(&PathElement::new(run, style))
                };
                drawn.map_err(draw_err)?;
            }
        }
        for (m, model) in plot.models.iter().enumerate() {
            let (dash, gap) = model_style(m).dash_pattern();
            for (i, path) in model.paths.iter().enumerate() {
                let c = darken(palette_colour(i), 0.35);
                let style = ShapeStyle::from(RGBColor(c[0], c[1], c[2])).stroke_width(2);
                for run in segments(path, false) {
                    area.draw(&DashedPathElement::new(flip(run), dash, gap, style))
                        .map_err(draw_err)?;
                }
            }
        }
        let px_per_unit = f64::from(px.end - px.start) / x_span;
        let ink = RGBColor(20, 20, 20);
        for mismatch in &plot.mismatches {
            let (x, y) = mismatch.position;
            if !(x.is_finite() && y.is_finite()) {
                continue;
            }
            let r = (mismatch.radius * px_per_unit)
                .max(8.0)
                .min(f64::from(px.end - px.start)) as i32;
            let label_style = font::text(13.0).color(&ink);
            let (col, row) = ctx.backend_coord(&(x, -y));
            root.draw(&Circle::new((col, row), r, ink.stroke_width(2)))
                .map_err(draw_err)?;
            let label_at = (col + r * 7 / 10 + 3, row - r * 7 / 10 - 15);
            // A pale backing keeps the label legible over tracks and the background frame.
            let (tw, th) = label_style.font.box_size(&mismatch.label).map_err(draw_err)?;
            let backing = [
                (label_at.0 - 2, label_at.1 - 1),
                (label_at.0 + tw as i32 + 2, label_at.1 + th as i32 + 3),
            ];
            root.draw(&Rectangle::new(backing, WHITE.mix(0.8).filled()))
                .map_err(draw_err)?;
            root.draw(&Text::new(mismatch.label.clone(), label_at, label_style))
                .map_err(draw_err)?;
        }
        draw_legend(&side, &entries, py.start - TITLE_HEIGHT as i32)?;
        root.present().map_err(draw_err)?;
    }
    RgbImage::from_raw(width, height, buffer).context("trajectory plot buffer has the wrong size")
}

#[cfg(test)]
mod tests {
    use super::*;

    fn is_colour(p: [u8; 3], c: [u8; 3], tol: u8) -> bool {
        p.iter().zip(c).all(|(&a, b)| a.abs_diff(b) <= tol)
    }

    /// Number of pixels in the box around (col, row) within `tol` of colour `c`.
    fn count_near(image: &RgbImage, (col, row): (i32, i32), radius: i32, c: [u8; 3], tol: u8) -> usize {
        let mut n = 0;
        for y in row - radius..=row + radius {
            for x in col - radius..=col + radius {
                if x >= 0 && y >= 0 && (x as u32) < image.width() && (y as u32) < image.height() {
                    n += usize::from(is_colour(image.get_pixel(x as u32, y as u32).0, c, tol));
                }
            }
        }
        n
    }

    /// The plot rectangle: the image region right of the y labels and above the x labels, found from the layout
    /// constants (the plot is built on fixed-size areas, so this is exact up to plotters' rounding).
    fn plot_box(plot: &TrajectoryPlot, image: &RgbImage) -> (Range<i32>, Range<i32>) {
        let legend_w = legend_width(&legend_entries(plot), plot.width / 3).unwrap();
        let x0 = (MARGIN + Y_LABEL_AREA) as i32;
        let x1 = (plot.width - legend_w - MARGIN) as i32;
        let y0 = (TITLE_HEIGHT + MARGIN) as i32;
        let y1 = image.height() as i32 - (MARGIN + X_LABEL_AREA) as i32;
        (x0..x1, y0..y1)
    }

    fn to_pixel(b: &(Range<i32>, Range<i32>), frame: (u32, u32), (x, y): (f64, f64)) -> (i32, i32) {
        let fx = (x + 0.5) / f64::from(frame.0);
        let fy = (y + 0.5) / f64::from(frame.1);
        let col = f64::from(b.0.start) + fx * f64::from(b.0.end - b.0.start);
        let row = f64::from(b.1.start) + fy * f64::from(b.1.end - b.1.start);
        (col.round() as i32, row.round() as i32)
    }

    #[test]
    fn image_coordinates_are_y_down_over_a_faded_background() {
        // A 160 x 120 frame, dark except a bright square near the top-left corner (rows 10..30).
        let mut frame = RgbImage::from_pixel(160, 120, image::Rgb([0, 0, 0]));
        for y in 10..30 {
            for x in 10..30 {
                frame.put_pixel(x, y, image::Rgb([255, 255, 255]));
            }
        }
        let mut plot = TrajectoryPlot::new("Trajectories");
        plot.background = Some(frame);
        // Track 0 runs along row y = 100 (near the bottom of the frame), left to right.
        plot.tracks.push(Track {
            name: "p0".into(),
            points: (20..=140).map(|x| (f64::from(x), 100.0)).collect(),
        });
        plot.models.push(ModelPaths {
            name: "springs".into(),
            paths: vec![(20..=140).map(|x| (f64::from(x), 60.0)).collect()],
        });
        let image = render_trajectory_plot(&plot).unwrap();
        assert_eq!(image.width(), 900);
        let b = plot_box(&plot, &image);
        // Square pixels: the plot box has the frame's aspect ratio.
        let aspect = f64::from(b.1.end - b.1.start) / f64::from(b.0.end - b.0.start);
        assert!((aspect - 0.75).abs() < 0.02, "plot box aspect {aspect}");
        let track = palette_colour(0);
        // The track is near the bottom of the plot, not the top: y grows downwards.
        assert!(count_near(&image, to_pixel(&b, (160, 120), (80.0, 100.0)), 3, track, 30) > 0);
        assert_eq!(
            count_near(&image, to_pixel(&b, (160, 120), (80.0, 20.0)), 3, track, 30),
            0
        );
        // The model's path is drawn dashed in a darker shade along y = 60.
        let model = darken(track, 0.35);
        let row = to_pixel(&b, (160, 120), (0.0, 60.0)).1;
        let (c0, c1) = (
            to_pixel(&b, (160, 120), (30.0, 0.0)).0,
            to_pixel(&b, (160, 120), (130.0, 0.0)).0,
        );
        let inked = (c0..c1)
            .filter(|&c| count_near(&image, (c, row), 1, model, 30) > 0)
            .count();
        assert!(
            inked > (c1 - c0) as usize / 3 && inked < (c1 - c0) as usize,
            "dashes cover {inked} columns"
        );
        // The background: the bright square shows white at its place (top left), the dark frame shows faded grey.
        let (col, row) = to_pixel(&b, (160, 120), (20.0, 20.0));
        assert!(is_colour(
            image.get_pixel(col as u32, row as u32).0,
            [255, 255, 255],
            2
        ));
        let (col, row) = to_pixel(&b, (160, 120), (80.0, 30.0));
        let grey = (255.0 * (1.0 - BACKGROUND_CONTRAST)).round() as u8;
        assert!(
            is_colour(image.get_pixel(col as u32, row as u32).0, [grey; 3], 2),
            "{:?}",
            image.get_pixel(col as u32, row as u32)
        );
    }

    #[test]
    fn mismatch_circle_is_drawn_around_its_position() {
        let mut plot = TrajectoryPlot::new("Mismatch");
        plot.frame_size = Some((200, 150));
        plot.tracks.push(Track {
            name: "p0".into(),
            points: vec![(10.0, 10.0), (20.0, 10.0)],
        });
        plot.mismatches.push(Mismatch {
            position: (100.0, 75.0),
            radius: 20.0,
            label: "p1: drag?".into(),
        });
        let image = render_trajectory_plot(&plot).unwrap();
        let b = plot_box(&plot, &image);
        let ink = [20, 20, 20];
        let centre = to_pixel(&b, (200, 150), (100.0, 75.0));
        let edge = to_pixel(&b, (200, 150), (80.0, 75.0));
        assert!(
            count_near(&image, edge, 2, ink, 40) > 0,
            "no circle at the mismatch's radius"
        );
        assert_eq!(count_near(&image, centre, 3, ink, 40), 0, "the circle is filled");
    }

    #[test]
    fn more_than_two_models_is_an_error() {
        let mut plot = TrajectoryPlot::new("t");
        for name in ["a", "b", "c"] {
            plot.models.push(ModelPaths {
                name: name.into(),
                paths: Vec::new(),
            });
        }
        let err = render_trajectory_plot(&plot).unwrap_err().to_string();
        assert!(err.contains("at most two models"), "{err}");
    }

    #[test]
    fn plot_without_frame_fits_the_data_and_writes_a_png() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("trajectories.png");
        let mut plot = TrajectoryPlot::new("Trajectories");
        plot.tracks.push(Track {
            name: "p0".into(),
            points: vec![
                (300.0, 200.0),
                (310.0, 240.0),
                (f64::NAN, f64::NAN),
                (330.0, 260.0),
            ],
        });
        trajectory_plot(&path, &plot).unwrap();
        let decoded = image::open(&path).unwrap();
        assert_eq!(decoded.width(), 900);
    }
}
