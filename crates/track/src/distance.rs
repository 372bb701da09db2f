//! Distance tests that give `hypot`'s answers without calling it away from the boundary.
//!
//! `f64::hypot` (glibc's, correctly rounded to within an ulp) costs about 100 instructions;
//! the plane gate compares every tracked point with every detection of a sample frame, and
//! at N = 1000 those calls were 13 % of a 40-frame run's instructions (441 M of 3334 M,
//! callgrind). A squared distance compared with a squared radius decides the same wherever
//! the two differ by more than a relative 1e-9 (both are exact to a few ulps, 1e-16); only
//! there is `hypot` called, so every answer is the one `hypot` gives.

/// Relative margin beyond which a squared distance decides a comparison without `hypot`.
const MARGIN: f64 = 1e-9;

/// Returns true if and only if `dx.hypot(dy) < r`.
pub(crate) fn closer_than(dx: f64, dy: f64, r: f64) -> bool {
    let d2 = dx * dx + dy * dy;
    let r2 = r * r;
    if r > 0.0 && d2 < r2 * (1.0 - MARGIN) {
        true
    } else if r > 0.0 && d2 > r2 * (1.0 + MARGIN) {
        false
    } else {
        dx.hypot(dy) < r
    }
}

/// The least `hypot` distance from `c` to the points of `points` other than `skip` (px),
/// infinite when there is none: `hypot` is called only on the points whose squared distance
/// lies within a relative [`MARGIN`] of the least.
pub(crate) fn nearest_distance(points: &[[f64; 2]], c: [f64; 2], skip: usize) -> f64 {
    let squared = |p: &[f64; 2]| (p[0] - c[0]) * (p[0] - c[0]) + (p[1] - c[1]) * (p[1] - c[1]);
    let least = points
        .iter()
        .enumerate()
        .filter(|&(j, _)| j != skip)
        .map(|(_, p)| squared(p))
        .fold(f64::INFINITY, f64::min);
    points
        .iter()
        .enumerate()
        .filter(|&(j, p)| {
            // Not beyond the margin (a NaN distance stays in, as it does for `hypot`).
            j != skip
                && squared(p).partial_cmp(&(least * (1.0 + MARGIN))) != Some(std::cmp::Ordering::Greater)
        })
        .map(|(_, p)| (p[0] - c[0]).hypot(p[1] - c[1]))
        .fold(f64::INFINITY, f64::min)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every answer is `hypot`'s, at the boundary too, and for non-finite input.
    #[test]
    fn closer_than_answers_as_hypot_does() {
        let cases = [
            (3.0, 4.0, 5.0),
            (3.0, 4.0, 5.000_000_000_1),
            (3.0, 4.0, 4.999_999_999_9),
            (0.6, 0.8, 1.0),
            (1e-200, 1e-200, 1e-199),
            (1e200, 1e200, 1e201),
            (f64::NAN, 0.0, 1.0),
            (f64::INFINITY, 0.0, 1.0),
            (0.0, 0.0, 0.0),
            (0.1, 0.0, -1.0),
        ];
        for (dx, dy, r) in cases {
            assert_eq!(closer_than(dx, dy, r), dx.hypot(dy) < r, "{dx} {dy} {r}");
        }
        let mut x = 0.123_456_789f64;
        for _ in 0..10_000 {
            x = (x * 9301.0 + 49297.0) % 233_280.0;
            let (dx, dy) = (x / 1000.0 - 100.0, (x * 7.0) % 200.0 - 100.0);
            let r = dx.hypot(dy) * (1.0 + (x % 3.0 - 1.0) * 1e-15);
            assert_eq!(closer_than(dx, dy, r), dx.hypot(dy) < r, "{dx} {dy} {r}");
        }
    }

    /// The least distance is `hypot`'s least, bit for bit.
    #[test]
    fn nearest_distance_is_the_least_hypot() {
        let points = [[0.0, 0.0], [3.0, 4.0], [4.0, 3.0], [-5.0, 0.0], [10.0, 10.0]];
        let plain = |skip: usize, c: [f64; 2]| {
            points
                .iter()
                .enumerate()
                .filter(|&(j, _)| j != skip)
                .map(|(_, p)| (p[0] - c[0]).hypot(p[1] - c[1]))
                .fold(f64::INFINITY, f64::min)
        };
        for skip in 0..points.len() {
            for c in [[0.0, 0.0], [0.1, 0.2], [7.0, -3.0]] {
                assert_eq!(
                    nearest_distance(&points, c, skip).to_bits(),
                    plain(skip, c).to_bits()
                );
            }
        }
        assert!(nearest_distance(&[[1.0, 1.0]], [0.0, 0.0], 0).is_infinite());
    }
}
