//! Overlay frames: a frame of the input with what the pipeline saw and predicted drawn over it.

use image::{DynamicImage, RgbImage};
use tiny_skia::{IntSize, LineCap, Paint, PathBuilder, Pixmap, Stroke, Transform};

use super::colour::palette_colour;

/// One track's recent positions, drawn as a line that fades from its oldest point to its newest.
#[derive(Debug, Clone, PartialEq)]
pub struct Tail {
    /// Palette index of the track (`palette_colour`), the same as in the trajectory plot.
    pub colour: usize,
    /// The last N positions up to this frame (px, image coordinates), oldest first; NaN breaks the line.
    pub points: Vec<(f64, f64)>,
}

/// A model-predicted particle position at this frame, drawn as a "+" cross.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Prediction {
    /// Palette index of the particle's track.
    pub colour: usize,
    /// Predicted centre (px, image coordinates).
    pub position: (f64, f64),
}

/// What [`overlay_frame`] draws over a frame. All positions are image pixels: x right, y down, pixel centres at
/// integer coordinates (the pixel in column 3, row 5 is centred on (3, 5)).
#[derive(Debug, Clone, PartialEq)]
pub struct Overlay {
    /// Detected blob centres in this frame (px), drawn as yellow circles.
    pub detections: Vec<(f64, f64)>,
    /// Radius of the detection circles (px of the frame); e.g. the measured blob radius. At least 1.5 is drawn.
    pub detection_radius: f64,
    /// Track tails, drawn first (under the detections and predictions).
    pub tails: Vec<Tail>,
    /// Predicted positions, drawn last (on top).
    pub predictions: Vec<Prediction>,
    /// Half the length of a cross's arm (px of the frame).
    pub cross_half_size: f64,
    /// Integer enlargement of the frame (nearest neighbour) before drawing, so that marks stay legible on small
    /// frames; 0 is taken as 1.
    pub scale: u32,
}

impl Default for Overlay {
    /// No marks; detection circles of radius 4 px, crosses of half-size 4 px, no enlargement.
    fn default() -> Self {
        Overlay {
            detections: Vec::new(),
            detection_radius: 4.0,
            tails: Vec::new(),
            predictions: Vec::new(),
            cross_half_size: 4.0,
            scale: 1,
        }
    }
}

/// The colour of detection circles: a saturated yellow, visible on grey and coloured blobs alike.
const DETECTION_COLOUR: [u8; 3] = [255, 214, 0];
/// Opacity of the oldest segment of a tail (the newest is opaque).
const TAIL_OLDEST_OPACITY: f32 = 0.2;

/// `frame` (enlarged by `marks.scale`) with `marks` drawn anti-aliased over it: track tails fading towards the
/// past, detections as circles, predictions as crosses. Marks outside the frame are clipped. A frame of zero
/// width or height gives an empty image.
#[must_use]
pub fn overlay_frame(frame: &DynamicImage, marks: &Overlay) -> RgbImage {
    let source = frame.to_rgb8();
    let s = marks.scale.max(1);
    let (w, h) = (source.width() * s, source.height() * s);
    let mut rgba = Vec::with_capacity(w as usize * h as usize * 4);
    for y in 0..h {
        for x in 0..w {
            let p = source.get_pixel(x / s, y / s).0;
            rgba.extend_from_slice(&[p[0], p[1], p[2], 255]);
        }
    }
    // An opaque frame is its own premultiplied RGBA, so tiny-skia can draw on it directly.
    let Some(mut pixmap) = IntSize::from_wh(w, h).and_then(|size| Pixmap::from_vec(rgba, size)) else {
        return RgbImage::new(w, h);
    };
    // Image coordinate x is the centre of frame pixel x, i.e. the middle of output pixels s*x .. s*x + s.
    let sf = s as f32;
    let to_output = Transform::from_row(sf, 0.0, 0.0, sf, 0.5 * sf, 0.5 * sf);

    for tail in &marks.tails {
        draw_tail(&mut pixmap, tail, to_output);
    }
    let radius = marks.detection_radius.max(1.5) as f32;
    for &(x, y) in &marks.detections {
        if let Some(circle) = finite(x, y).and_then(|(x, y)| PathBuilder::from_circle(x, y, radius)) {
            let stroke = Stroke {
                width: 1.0,
                ..Stroke::default()
            };
            pixmap.stroke_path(&circle, &paint(DETECTION_COLOUR, 1.0), &stroke, to_output, None);
        }
    }
    let arm = marks.cross_half_size.max(1.0) as f32;
    for prediction in &marks.predictions {
        let Some((x, y)) = finite(prediction.position.0, prediction.position.1) else {
            continue;
        };
        let mut pb = PathBuilder::new();
        pb.move_to(x - arm, y);
        pb.line_to(x + arm, y);
        pb.move_to(x, y - arm);
        pb.line_to(x, y + arm);
        if let Some(cross) = pb.finish() {
            // One frame pixel wide with square caps: the arms cover whole pixels, so the cross is crisp.
            let stroke = Stroke {
                width: 1.0,
                line_cap: LineCap::Square,
                ..Stroke::default()
            };
            pixmap.stroke_path(
                &cross,
                &paint(palette_colour(prediction.colour), 1.0),
                &stroke,
                to_output,
                None,
            );
        }
    }

    let mut out = RgbImage::new(w, h);
    for (dst, src) in out.pixels_mut().zip(pixmap.pixels()) {
        // Everything drawn over an opaque frame stays opaque, so the premultiplied colour is the colour.
        let c = src.demultiply();
        dst.0 = [c.red(), c.green(), c.blue()];
    }
    out
}

/// Draws one tail, each segment more opaque than the one before it.
fn draw_tail(pixmap: &mut Pixmap, tail: &Tail, to_output: Transform) {
    let n = tail.points.len();
    let stroke = Stroke {
        width: 1.5,
        line_cap: LineCap::Butt,
        ..Stroke::default()
    };
    for (k, pair) in tail.points.windows(2).enumerate() {
        let (Some(a), Some(b)) = (finite(pair[0].0, pair[0].1), finite(pair[1].0, pair[1].1)) else {
            continue;
        };
        let newness = (k + 1) as f32 / (n - 1) as f32;
        let opacity = TAIL_OLDEST_OPACITY + (1.0 - TAIL_OLDEST_OPACITY) * newness;
        let mut pb = PathBuilder::new();
        pb.move_to(a.0, a.1);
        pb.line_to(b.0, b.1);
        if let Some(segment) = pb.finish() {
            pixmap.stroke_path(
                &segment,
                &paint(palette_colour(tail.colour), opacity),
                &stroke,
                to_output,
                None,
            );
        }
    }
}

/// The point as f32 if both coordinates are finite.
fn finite(x: f64, y: f64) -> Option<(f32, f32)> {
    (x.is_finite() && y.is_finite()).then_some((x as f32, y as f32))
}

/// An anti-aliased solid paint of `colour` at `opacity` (0..=1).
fn paint(colour: [u8; 3], opacity: f32) -> Paint<'static> {
    let mut paint = Paint::default();
    paint.set_color_rgba8(
        colour[0],
        colour[1],
        colour[2],
        (opacity.clamp(0.0, 1.0) * 255.0).round() as u8,
    );
    paint.anti_alias = true;
    paint
}

#[cfg(test)]
mod tests {
    use super::*;

    const GREY: [u8; 3] = [50, 50, 50];

    fn grey_frame(w: u32, h: u32) -> DynamicImage {
        DynamicImage::ImageRgb8(RgbImage::from_pixel(w, h, image::Rgb(GREY)))
    }

    fn px(image: &RgbImage, x: u32, y: u32) -> [u8; 3] {
        image.get_pixel(x, y).0
    }

    fn close(a: [u8; 3], b: [u8; 3], tol: u8) -> bool {
        a.iter().zip(b).all(|(&p, q)| p.abs_diff(q) <= tol)
    }

    /// Distance of a pixel's colour from the background grey (sum over channels).
    fn ink(p: [u8; 3]) -> u32 {
        p.iter().zip(GREY).map(|(&a, b)| u32::from(a.abs_diff(b))).sum()
    }

    #[test]
    fn detection_circle_is_centred_on_the_pixel_centre_y_down() {
        let marks = Overlay {
            detections: vec![(20.0, 30.0)],
            detection_radius: 5.0,
            ..Overlay::default()
        };
        let out = overlay_frame(&grey_frame(64, 48), &marks);
        assert_eq!(out.dimensions(), (64, 48));
        // The ring passes through the four pixels 5 px from (20, 30), row 30 counted from the top.
        // (Anti-aliased: each of these pixels is mostly, not wholly, covered by the 1 px wide ring.)
        let coverage =
            |p: [u8; 3]| (f64::from(p[0]) - f64::from(GREY[0])) / f64::from(DETECTION_COLOUR[0] - GREY[0]);
        for (x, y) in [(25, 30), (15, 30), (20, 25), (20, 35)] {
            let p = px(&out, x, y);
            assert!(
                p[0] >= GREY[0] && coverage(p) > 0.6 && p[2] <= GREY[2],
                "ring missing at ({x}, {y}): {p:?}"
            );
        }
        // Inside and far outside the ring the frame is untouched; nothing at the y-flipped place (row 17).
        for (x, y) in [(20, 30), (22, 31), (20, 17), (20, 12), (40, 30)] {
            assert_eq!(px(&out, x, y), GREY, "unexpected ink at ({x}, {y})");
        }
        // Point-symmetric about the pixel centre (20, 30), up to anti-aliasing noise: not about (20.5, 30.5).
        for dy in -6i32..=6 {
            for dx in -6i32..=6 {
                let a = coverage(px(&out, (20 + dx) as u32, (30 + dy) as u32));
                let b = coverage(px(&out, (20 - dx) as u32, (30 - dy) as u32));
                assert!(
                    (a - b).abs() < 0.06,
                    "ring not symmetric at offset ({dx}, {dy}): {a} vs {b}"
                );
            }
        }
    }

    #[test]
    fn prediction_cross_covers_whole_pixels_at_integer_positions() {
        let marks = Overlay {
            predictions: vec![Prediction {
                colour: 2,
                position: (40.0, 20.0),
            }],
            cross_half_size: 4.0,
            ..Overlay::default()
        };
        let out = overlay_frame(&grey_frame(64, 48), &marks);
        let c = palette_colour(2);
        for (x, y) in [
            (40, 20),
            (36, 20),
            (44, 20),
            (40, 16),
            (40, 24),
            (38, 20),
            (40, 23),
        ] {
            assert!(
                close(px(&out, x, y), c, 2),
                "cross missing at ({x}, {y}): {:?}",
                px(&out, x, y)
            );
        }
        for (x, y) in [
            (45, 20),
            (35, 20),
            (40, 25),
            (40, 15),
            (41, 21),
            (39, 19),
            (43, 17),
        ] {
            assert_eq!(px(&out, x, y), GREY, "cross bleeds into ({x}, {y})");
        }
    }

    #[test]
    fn enlarged_frame_keeps_marks_on_their_pixels() {
        let marks = Overlay {
            predictions: vec![Prediction {
                colour: 2,
                position: (40.0, 20.0),
            }],
            cross_half_size: 4.0,
            scale: 3,
            ..Overlay::default()
        };
        let out = overlay_frame(&grey_frame(64, 48), &marks);
        assert_eq!(out.dimensions(), (192, 144));
        let c = palette_colour(2);
        // Frame pixel (40, 20) is output pixels 120..123 x 60..63; the arm to x = 44 ends at output column 134.
        for (x, y) in [
            (120, 60),
            (122, 62),
            (121, 61),
            (134, 61),
            (108, 61),
            (121, 48),
            (121, 74),
        ] {
            assert!(
                close(px(&out, x, y), c, 2),
                "cross missing at ({x}, {y}): {:?}",
                px(&out, x, y)
            );
        }
        for (x, y) in [(119, 58), (123, 58), (135, 61), (107, 61), (121, 47), (121, 75)] {
            assert_eq!(px(&out, x, y), GREY, "cross bleeds into ({x}, {y})");
        }
    }

    #[test]
    fn tail_fades_towards_its_oldest_point() {
        let tail = Tail {
            colour: 0,
            points: vec![(5.0, 10.0), (15.0, 10.0), (25.0, 10.0), (35.0, 10.0)],
        };
        let marks = Overlay {
            tails: vec![tail],
            ..Overlay::default()
        };
        let out = overlay_frame(&grey_frame(64, 48), &marks);
        let (old, mid, new) = (
            ink(px(&out, 10, 10)),
            ink(px(&out, 20, 10)),
            ink(px(&out, 30, 10)),
        );
        assert!(
            old > 0 && old < mid && mid < new,
            "tail ink old {old}, middle {mid}, newest {new}"
        );
        assert_eq!(px(&out, 20, 14), GREY);
    }

    #[test]
    fn non_finite_marks_are_skipped_and_empty_frames_give_empty_images() {
        let marks = Overlay {
            detections: vec![(f64::NAN, 3.0)],
            predictions: vec![Prediction {
                colour: 0,
                position: (f64::INFINITY, 1.0),
            }],
            tails: vec![Tail {
                colour: 0,
                points: vec![(1.0, 1.0), (f64::NAN, 2.0), (3.0, 3.0)],
            }],
            ..Overlay::default()
        };
        let out = overlay_frame(&grey_frame(8, 8), &marks);
        assert!(out.pixels().all(|p| p.0 == GREY));
        let empty = overlay_frame(&grey_frame(0, 0), &Overlay::default());
        assert_eq!(empty.dimensions(), (0, 0));
    }
}
