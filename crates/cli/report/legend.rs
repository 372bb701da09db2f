//! The legend panel drawn beside a plot, so it never hides data.

use plotters::coord::Shift;
use plotters::element::{Circle, DashedPathElement, PathElement, Text};
use plotters::prelude::{DrawingArea, DrawingBackend};
use plotters::style::{Color, RGBColor, ShapeStyle};

use super::chart::LineStyle;
use super::font;

/// Font size of legend text (px).
const FONT_SIZE: f64 = 13.0;
/// Height of one legend row (px).
const ROW_HEIGHT: i32 = 19;
/// Length of the line sample drawn before each label (px).
const SWATCH_LENGTH: i32 = 28;
/// Blank space left and right of the panel's content (px).
const PADDING: i32 = 10;

/// What a legend row shows before its label.
#[derive(Debug, Clone, Copy)]
pub(crate) enum Swatch {
    /// A line sample in this colour and dash style.
    Line([u8; 3], LineStyle),
    /// A hollow circle in this colour (a located mismatch).
    Circle([u8; 3]),
}

/// One legend row.
#[derive(Debug, Clone)]
pub(crate) struct LegendEntry {
    /// The text of the row.
    pub label: String,
    /// The sample drawn before the text.
    pub swatch: Swatch,
}

/// The width in pixels a legend panel needs for `entries` (0 for no entries), at most `max_width`.
pub(crate) fn legend_width(entries: &[LegendEntry], max_width: u32) -> anyhow::Result<u32> {
    if entries.is_empty() {
        return Ok(0);
    }
    let style = font::text(FONT_SIZE);
    let mut widest = 0;
    for entry in entries {
        let (w, _) = style
            .font
            .box_size(&entry.label)
            .map_err(|e| anyhow::anyhow!("measuring legend text: {e}"))?;
        widest = widest.max(w);
    }
    let needed = widest + (SWATCH_LENGTH + 3 * PADDING) as u32;
    Ok(needed.min(max_width))
}

/// Draws a styled polyline (already in `area`'s pixel coordinates) in `colour`, `width` pixels wide.
pub(crate) fn draw_polyline<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    points: Vec<(i32, i32)>,
    colour: [u8; 3],
    line: LineStyle,
    width: u32,
) -> anyhow::Result<()> {
    let style = ShapeStyle::from(RGBColor(colour[0], colour[1], colour[2])).stroke_width(width);
    let (dash, gap) = line.dash_pattern();
    let result = if dash == 0 {
        area.draw(&PathElement::new(points, style))
    } else {
        area.draw(&DashedPathElement::new(points, dash, gap, style))
    };
    result.map_err(|e| anyhow::anyhow!("drawing a legend line: {e}"))
}

/// Draws `entries` in a column on `area` (the panel right of the plot), starting `top` pixels from its top.
/// Rows that do not fit are replaced by a last row "… and N more".
pub(crate) fn draw_legend<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    entries: &[LegendEntry],
    top: i32,
) -> anyhow::Result<()> {
    let (_, height) = area.dim_in_pixel();
    let fits = ((height as i32 - top - PADDING) / ROW_HEIGHT).max(0) as usize;
    let shown = if entries.len() > fits {
        fits.saturating_sub(1)
    } else {
        entries.len()
    };
    let style = font::text(FONT_SIZE);
    let err = |e: plotters::drawing::DrawingAreaErrorKind<DB::ErrorType>| {
        anyhow::anyhow!("drawing the legend: {e}")
    };
    for (row, entry) in entries.iter().take(shown).enumerate() {
        let y = top + row as i32 * ROW_HEIGHT + ROW_HEIGHT / 2;
        let x0 = PADDING;
        match entry.swatch {
            Swatch::Line(colour, line) => {
                draw_polyline(area, vec![(x0, y), (x0 + SWATCH_LENGTH, y)], colour, line, 2)?
            }
            Swatch::Circle(colour) => {
                let style = RGBColor(colour[0], colour[1], colour[2]).stroke_width(2);
                area.draw(&Circle::new((x0 + SWATCH_LENGTH / 2, y), 6, style))
                    .map_err(err)?;
            }
        }
        let text_pos = (x0 + SWATCH_LENGTH + PADDING / 2, y - FONT_SIZE as i32 / 2);
        area.draw(&Text::new(entry.label.clone(), text_pos, style.clone()))
            .map_err(err)?;
    }
    if shown < entries.len() {
        let y = top + shown as i32 * ROW_HEIGHT;
        let more = format!("… and {} more", entries.len() - shown);
        area.draw(&Text::new(more, (PADDING, y), style.clone()))
            .map_err(err)?;
    }
    // A hairline frame so the panel reads as a key, not as more data.
    let frame = RGBColor(200, 200, 200).stroke_width(1);
    let rows = (shown + usize::from(shown < entries.len())) as i32;
    let bottom = top + rows * ROW_HEIGHT + 4;
    let (width, _) = area.dim_in_pixel();
    let right = width as i32 - PADDING / 2;
    let corners = vec![
        (2, top - 4),
        (right, top - 4),
        (right, bottom),
        (2, bottom),
        (2, top - 4),
    ];
    area.draw(&PathElement::new(corners, frame)).map_err(err)?;
    Ok(())
}
