//! The recording's single-particle image: its radial profile, measured on isolated particles.

use super::relocate::{dist2, for_pixels_near, SharedBlobs};
use crate::track_table::{PointFlag, TrackPoint};
use crate::TrackError;

/// Isolated particles whose images make the profile.
const PROFILE_SAMPLES: usize = 32;
/// Radial bin of the profile, px.
const PROFILE_BIN: f64 = 0.25;

/// A single particle's image: its mean signal against the distance from its centre.
#[derive(Clone, Debug)]
pub(super) struct Profile {
    /// Mean signal per [`PROFILE_BIN`] of distance (bin `k` at `k · PROFILE_BIN`), grey
    /// levels; zero beyond the last.
    bins: Vec<f64>,
    /// The largest bin: the level of a fully covered pixel, grey levels.
    pub(super) peak: f64,
    /// Whether the profile was measured on the recording's particles (else it is a disc of
    /// the measured radius, whose level is only estimated).
    pub(super) measured: bool,
}

impl Profile {
    /// Signal at distance `r` (px) from the centre, and its derivative along `r`.
    pub(super) fn at(&self, r: f64) -> (f64, f64) {
        let u = r / PROFILE_BIN;
        let k = u.floor() as usize;
        if k + 1 >= self.bins.len() {
            return (0.0, 0.0);
        }
        let f = u - k as f64;
        let (a, b) = (self.bins[k], self.bins[k + 1]);
        (a + f * (b - a), (b - a) / PROFILE_BIN)
    }

    /// A uniform disc of radius `radius` (px) with a half-pixel anti-aliased edge, for a
    /// recording with no isolated particle to measure (a chain of touching beads): its level
    /// is the median located mass of `points` over the disc's area. `None` without masses.
    pub(super) fn disc(points: &[TrackPoint], radius: f64) -> Option<Profile> {
        let mut masses: Vec<f64> = points
            .iter()
            .filter(|p| p.flag == PointFlag::Detected && p.mass.is_finite() && p.mass > 0.0)
            .map(|p| p.mass)
            .collect();
        if masses.is_empty() || radius.is_nan() || radius <= 0.0 {
            return None;
        }
        let mid = masses.len() / 2;
        let peak =
            *masses.select_nth_unstable_by(mid, f64::total_cmp).1 / (std::f64::consts::PI * radius * radius);
        let n_bins = ((radius + 1.0) / PROFILE_BIN).ceil() as usize + 2;
        let bins = (0..n_bins)
            .map(|k| peak * (radius + 0.5 - k as f64 * PROFILE_BIN).clamp(0.0, 1.0))
            .collect();
        Some(Profile {
            bins,
            peak,
            measured: false,
        })
    }

    /// The fraction of a pixel an image of signal `t` (grey levels) leaves uncovered, for
    /// [`Composition::Cover`].
    pub(super) fn clear(&self, t: f64) -> f64 {
        (1.0 - t / self.peak).clamp(0.0, 1.0)
    }

    /// Reach of the image, px.
    pub(super) fn reach(&self) -> f64 {
        (self.bins.len() - 1) as f64 * PROFILE_BIN
    }
}
/// The single-particle profile, measured on up to [`PROFILE_SAMPLES`] isolated located
/// particles (no other point within two windows and a radius) of the first frames of
/// `frames` (each a list of point indices) that hold some; `None` when none does.
pub(super) fn measure_profile(
    points: &[TrackPoint],
    frames: &[&Vec<usize>],
    blobs: &SharedBlobs<'_>,
) -> Result<Option<Profile>, TrackError> {
    let reach = blobs.window + 1.0;
    let apart = 2.0 * reach + blobs.radius;
    let n_bins = (reach / PROFILE_BIN).ceil() as usize + 2;
    let mut sum = vec![0.0; n_bins];
    let mut count = vec![0usize; n_bins];
    let mut taken = 0;
    for idx in frames {
        let isolated: Vec<[f64; 2]> = idx
            .iter()
            .filter(|&&i| points[i].flag == PointFlag::Detected)
            .filter(|&&i| {
                let p = [points[i].x, points[i].y];
                let inside = p[0] >= reach
                    && p[1] >= reach
                    && p[0] + reach < blobs.width as f64
                    && p[1] + reach < blobs.height as f64;
                inside
                    && idx
                        .iter()
                        .all(|&j| j == i || dist2(p, [points[j].x, points[j].y]) >= apart * apart)
            })
            .map(|&i| [points[i].x, points[i].y])
            .take(PROFILE_SAMPLES - taken)
            .collect();
        if isolated.is_empty() {
            continue;
        }
        let signal = (blobs.signal_of)(points[idx[0]].frame)?;
        for p in &isolated {
            for_pixels_near(&[*p], reach, blobs.width, blobs.height, |x, y, i| {
                let r = (x - p[0]).hypot(y - p[1]);
                let k = (r / PROFILE_BIN).round() as usize;
                if k < n_bins {
                    sum[k] += f64::from(signal[i]);
                    count[k] += 1;
                }
            });
        }
        taken += isolated.len();
        if taken >= PROFILE_SAMPLES {
            break;
        }
    }
    if taken == 0 {
        return Ok(None);
    }
    // Bins no pixel centre fell in take their neighbours' mean; the last is zero.
    let mut bins: Vec<f64> = sum
        .iter()
        .zip(&count)
        .map(|(s, &c)| if c > 0 { s / c as f64 } else { f64::NAN })
        .collect();
    for k in 0..n_bins {
        if bins[k].is_nan() {
            let before = (0..k)
                .rev()
                .find_map(|j| bins.get(j).copied().filter(|v| v.is_finite()));
            let after = (k + 1..n_bins).find_map(|j| bins.get(j).copied().filter(|v| v.is_finite()));
            bins[k] = match (before, after) {
                (Some(a), Some(b)) => 0.5 * (a + b),
                (Some(a), None) | (None, Some(a)) => a,
                (None, None) => 0.0,
            };
        }
    }
    bins.push(0.0);
    let peak = bins.iter().copied().fold(0.0, f64::max);
    if peak <= 0.0 {
        return Ok(None);
    }
    Ok(Some(Profile {
        bins,
        peak,
        measured: true,
    }))
}
