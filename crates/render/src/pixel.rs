//! The pixel convention, in one place.
//!
//! physfit puts the centre of pixel (column `i`, row `j`) at the point `(i, j)`, x right, y down
//! (see `MODEL.md`), so pixel `(i, j)` is the unit square `[i - 0.5, i + 0.5] × [j - 0.5, j + 0.5]`.
//! tiny-skia (and most 2-D graphics libraries) put that centre at `(i + 0.5, j + 0.5)` instead:
//! [`to_tiny_skia`] is the only place that converts between the two.

/// The edges `[low, high)` of pixel column (or row) `i` along one axis, px: `[i - 0.5, i + 0.5)`.
#[inline]
pub(crate) fn pixel_span(i: usize) -> (f64, f64) {
    let c = i as f64;
    (c - 0.5, c + 0.5)
}

/// The pixel columns (or rows) whose squares meet the interval `[lo, hi]` (px), clipped to
/// `0..len`; an empty range when none does (or when the bounds are not finite).
#[inline]
pub(crate) fn pixels_touching(lo: f64, hi: f64, len: u32) -> std::ops::Range<usize> {
    if !lo.is_finite() || !hi.is_finite() {
        return 0..0;
    }
    // Pixel i spans [i - 0.5, i + 0.5): the first touched is round-half-up of lo, the last of hi.
    let first = (lo + 0.5).floor().max(0.0);
    let last = (hi + 0.5).floor().min(len as f64 - 1.0);
    if first > last {
        return 0..0;
    }
    first as usize..last as usize + 1
}

/// A point in physfit pixel coordinates, in tiny-skia's coordinates (pixel centres at `+0.5`).
#[cfg(test)]
#[inline]
pub(crate) fn to_tiny_skia(p: physfit_model::Vec2) -> (f32, f32) {
    ((p.x + 0.5) as f32, (p.y + 0.5) as f32)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pixel_span_is_centred_on_the_index() {
        let (lo, hi) = pixel_span(7);
        assert!((lo - 6.5).abs() < 1e-12 && (hi - 7.5).abs() < 1e-12);
    }

    #[test]
    fn pixels_touching_clips_and_rounds() {
        assert_eq!(pixels_touching(2.4, 5.6, 100), 2..7);
        assert_eq!(pixels_touching(-10.0, 1.2, 100), 0..2);
        assert_eq!(pixels_touching(98.0, 130.0, 100), 98..100);
        assert_eq!(pixels_touching(120.0, 130.0, 100), 0..0);
        assert_eq!(pixels_touching(f64::NAN, 3.0, 100), 0..0);
    }
}
