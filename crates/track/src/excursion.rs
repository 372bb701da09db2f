//! Single-frame excursions: a point off the path its neighbours agree on.
//!
//! A track that takes a noise peak, a fragment or another image for one frame and returns
//! to its particle the next leaves one point off its path. Its residual from the midpoint of
//! its neighbours, `r_k = p_k - (p_{k-1} + p_{k+1}) / 2`, is the excursion `e`, and the
//! neighbours' residuals are each about `-e / 2` (their midpoints hold the stray point). A
//! change of velocity (a bounce, a kick) also leaves a residual at its frame, but none at its
//! neighbours, whose paths either side are straight: only a residual that its neighbours'
//! residuals each cancel by a quarter at least is an excursion. It is named where it exceeds
//! [`EXCURSION_SIGMAS`] times the track's usual residual (its median magnitude over that of a
//! two-dimensional normal) and as many times what the points' own errors allow.

use crate::track_table::{PointFlag, TrackPoint, TrackTable};

/// How many times the track's usual residual, and the one the points' errors allow, a
/// residual must exceed to be named: a two-dimensional normal residual exceeds six
/// standard deviations once in 66 million.
pub(crate) const EXCURSION_SIGMAS: f64 = 6.0;

/// Least residuals a track must have for its usual residual to be read.
const MIN_RESIDUALS: usize = 8;

/// The median magnitude of a two-dimensional standard normal vector, `sqrt(2 ln 2)`.
const RAYLEIGH_MEDIAN: f64 = 1.177_410_022_515_474_6;

/// One point off its neighbours' path.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct Excursion {
    /// The frame of the point.
    pub(crate) frame: usize,
    /// Its distance from the midpoint of its neighbours, px.
    pub(crate) off: f64,
    /// The track's usual residual (its median magnitude over [`RAYLEIGH_MEDIAN`]), px.
    pub(crate) usual: f64,
}

/// The excursions of one track's `points` (frame order): detected points whose neighbours
/// are detected in consecutive frames (and one more on one side at least), that lie farther from their
/// neighbours' midpoint than [`EXCURSION_SIGMAS`] times the track's usual residual and the
/// residual the points' errors (`ep`, px) allow, and whose neighbours' residuals each cancel
/// a quarter of it at least (where they have one).
pub(crate) fn excursions(points: &[&TrackPoint]) -> Vec<Excursion> {
    // Residuals of the points whose neighbours either side are consecutive detected frames.
    let detected = |p: &TrackPoint| p.flag == PointFlag::Detected;
    let mut residuals: Vec<Option<[f64; 2]>> = vec![None; points.len()];
    for i in 1..points.len().saturating_sub(1) {
        let (a, p, b) = (points[i - 1], points[i], points[i + 1]);
        if detected(a) && detected(p) && detected(b) && p.frame == a.frame + 1 && b.frame == p.frame + 1 {
            residuals[i] = Some([p.x - 0.5 * (a.x + b.x), p.y - 0.5 * (a.y + b.y)]);
        }
    }
    let mut magnitudes: Vec<f64> = residuals.iter().flatten().map(|r| r[0].hypot(r[1])).collect();
    if magnitudes.len() < MIN_RESIDUALS {
        return Vec::new();
    }
    let usual = physfit_tracks::stats::median(&mut magnitudes) / RAYLEIGH_MEDIAN;
    let mut out = Vec::new();
    for i in 1..points.len().saturating_sub(1) {
        let Some(r) = residuals[i] else {
            continue;
        };
        // A neighbour's residual where it has one; at the ends of a run of consecutive
        // detections, the other side alone judges.
        let (before, after) = (residuals[i - 1], residuals[i + 1]);
        if before.is_none() && after.is_none() {
            continue;
        }
        let off = r[0].hypot(r[1]);
        // The residual the points' own errors allow: the point's, and half of each neighbour's.
        let ep = |p: &TrackPoint| if p.ep.is_finite() { p.ep } else { 0.0 };
        let allowed =
            (ep(points[i]).powi(2) + 0.25 * (ep(points[i - 1]).powi(2) + ep(points[i + 1]).powi(2))).sqrt();
        if off <= EXCURSION_SIGMAS * usual.max(allowed) {
            continue;
        }
        // How much of the residual each neighbour's residual cancels, along it: a half each
        // for a stray point, none for a change of velocity, and for a neighbour of a stray
        // point twice its own from one side and none from the other.
        let cancels =
            |n: Option<[f64; 2]>| n.map_or(true, |n| -(n[0] * r[0] + n[1] * r[1]) / (off * off) >= 0.25);
        if cancels(before) && cancels(after) {
            out.push(Excursion {
                frame: points[i].frame,
                off,
                usual,
            });
        }
    }
    out
}

/// The excursions of every track of a table: a warning for each track with any, and the
/// particle and frame of each.
#[derive(Clone, Debug, Default, PartialEq)]
pub(crate) struct Strays {
    /// One warning a track, naming its frames and how far off each point lies.
    pub(crate) warnings: Vec<String>,
    /// The particle and frame of each excursion.
    pub(crate) points: Vec<(String, usize)>,
}

/// The excursions of every track of `table` ([`excursions`]), worded and listed.
pub(crate) fn excursion_warnings(table: &TrackTable) -> Strays {
    let mut out = Strays::default();
    for (particle, points) in table.by_particle() {
        let found = excursions(&points);
        if found.is_empty() {
            continue;
        }
        let frames: Vec<String> = found
            .iter()
            .map(|e| format!("frame {} ({:.1} px)", e.frame, e.off))
            .collect();
        out.warnings.push(format!(
            "{particle}: its point lies off the path of its neighbours in {} (against {:.2} px \
             usually), where they agree with each other: it may have followed another image or a \
             part of its particle there",
            frames.join(", "),
            found[0].usual
        ));
        out.points
            .extend(found.iter().map(|e| (particle.to_string(), e.frame)));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn point(frame: usize, x: f64, y: f64) -> TrackPoint {
        TrackPoint {
            frame,
            particle: "p".into(),
            x,
            y,
            mass: 1.0,
            size: 1.0,
            ep: 0.05,
            flag: PointFlag::Detected,
        }
    }

    /// A walk with a seeded wobble of 0.2 px: one point moved 3 px is named at its frame,
    /// and no other; a bounce (the velocity reversed at one frame) is not.
    #[test]
    fn a_stray_point_is_named_and_a_bounce_is_not() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        let mut wobble = || rng.gen_range(-0.2..0.2);
        let walk: Vec<TrackPoint> = (0..20)
            .map(|k| point(k, 1.5 * k as f64 + wobble(), 40.0 + wobble()))
            .collect();
        let mut stray = walk.clone();
        stray[9].x += 2.0;
        stray[9].y -= 2.2;
        let refs: Vec<&TrackPoint> = stray.iter().collect();
        let found = excursions(&refs);
        assert_eq!(found.len(), 1, "{found:?}");
        assert_eq!(found[0].frame, 9);
        assert!((found[0].off - 2.97).abs() < 0.5, "{found:?}");
        let plain: Vec<&TrackPoint> = walk.iter().collect();
        assert!(excursions(&plain).is_empty());
        // A ball falling 3 px a frame that bounces at frame 10.
        let bounce: Vec<TrackPoint> = (0..20)
            .map(|k| {
                let y = if k <= 10 {
                    3.0 * k as f64
                } else {
                    60.0 - 3.0 * k as f64
                };
                point(k, 20.0 + 0.05 * k as f64, y + 0.1 * wobble())
            })
            .collect();
        let refs: Vec<&TrackPoint> = bounce.iter().collect();
        assert!(excursions(&refs).is_empty(), "{:?}", excursions(&refs));
    }
}
