//! Whether the light read off the background falls on the particles: once it is taken out
//! of their images, their brightness along the tracks must not follow it.
//!
//! Light that falls on the particles (reflecting objects, fluorescence excited by it,
//! vignetting by the lens) multiplies their images as it does the background, and taking it
//! out leaves each particle's integrated signal steady wherever it goes. Light that only
//! adds to the background (a haze, a lamp on the backdrop, a renderer's ramp) leaves the
//! particles as they were, and dividing their images by it makes their signal follow
//! `L_min / L`. The slope of a particle's log mass against the log of the factor its image
//! was multiplied by, pooled over the particles (each about its own mean) and over the sample
//! frames (their exposure divided out), tells the two apart: 0 when the light falls on
//! them, 1 when it does not.

use super::tracks_background::SampleGains;
use crate::background::Light;
use crate::TrackTable;
use physfit_tracks::stats::median;

/// What the tracks' brightness says of the light taken out of their images.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) enum LightVerdict {
    /// Their brightness stays steady with the light taken out (slope nearer 0 than 1): the
    /// light falls on them.
    FallsOnParticles,
    /// Their brightness follows the light taken out (slope nearer 1): it only adds to the
    /// background, and the particles' images are to be left as they are.
    AddsToBackground,
    /// The tracks cross too little of the light's range to tell (the slope's standard error
    /// is above [`UNDECIDED_ERROR`], or fewer than [`MIN_POINTS`] points).
    Undecided,
}

/// Standard error of the slope above which the two cases (slopes 0 and 1) are not told
/// apart: each then lies within two standard errors of the midpoint.
const UNDECIDED_ERROR: f64 = 0.25;
/// Least move (px) that the light taken out of an image may have made for a warning to say
/// that it is not known to be right (see [`moves`]).
pub(super) const STAKE_FLOOR: f64 = 0.05;
/// Least points (over every particle, beyond one per particle) the slope is read from.
const MIN_POINTS: usize = 6;

/// What the points of `table` in the sample frames (`gains`: their exposure) say of `light`,
/// read from the slope of their log mass against the log factor (see the module documentation)
/// (over a frame `width` px wide).
pub(super) fn check_light(
    table: &TrackTable,
    light: &Light,
    width: usize,
    gains: &SampleGains,
) -> LightVerdict {
    let height = light.inverse.len() / width.max(1);
    let (mut sab, mut sbb, mut saa, mut points, mut particles) = (0.0, 0.0, 0.0, 0usize, 0usize);
    for track in table.by_particle().values() {
        let pairs: Vec<(f64, f64)> = track
            .iter()
            .filter_map(|p| {
                let g = gains.gain(p.frame)?;
                let (x, y) = (p.x.round(), p.y.round());
                let inside = x >= 0.0 && y >= 0.0 && (x as usize) < width && (y as usize) < height;
                (inside && p.mass > 0.0 && g > 0.0).then(|| {
                    let factor = f64::from(light.inverse[y as usize * width + x as usize]);
                    ((p.mass / g).ln(), factor.ln())
                })
            })
            .collect();
        if pairs.len() < 2 {
            continue;
        }
        let pairs_len = pairs.len();
        let k = pairs_len as f64;
        let ma = pairs.iter().map(|p| p.0).sum::<f64>() / k;
        let mb = pairs.iter().map(|p| p.1).sum::<f64>() / k;
        for (a, b) in pairs {
            sab += (a - ma) * (b - mb);
            sbb += (b - mb) * (b - mb);
            saa += (a - ma) * (a - ma);
        }
        points += pairs_len;
        particles += 1;
    }
    let freedom = points.saturating_sub(particles + 1);
    if freedom < MIN_POINTS || sbb <= 0.0 {
        return LightVerdict::Undecided;
    }
    let slope = sab / sbb;
    let residual = (saa - slope * sab).max(0.0) / freedom as f64;
    let error = (residual / sbb).sqrt();
    if error > UNDECIDED_ERROR {
        LightVerdict::Undecided
    } else if slope > 0.5 {
        LightVerdict::AddsToBackground
    } else {
        LightVerdict::FallsOnParticles
    }
}

/// How far each particle of `table` moves, at most over the frames, in `other` (the frames
/// located again another way), px, with the median standard error of its points in `table`
/// (px), by particle.
pub(super) fn moves(table: &TrackTable, other: &TrackTable) -> Vec<(String, f64, f64)> {
    let elsewhere: std::collections::HashMap<(&str, usize), [f64; 2]> = other
        .points
        .iter()
        .map(|p| ((p.particle.as_str(), p.frame), [p.x, p.y]))
        .collect();
    table
        .by_particle()
        .into_iter()
        .filter_map(|(name, points)| {
            let most = points
                .iter()
                .filter_map(|p| {
                    let q = elsewhere.get(&(name, p.frame))?;
                    Some((p.x - q[0]).hypot(p.y - q[1]))
                })
                .fold(f64::NAN, f64::max);
            let mut eps: Vec<f64> = points.iter().map(|p| p.ep).filter(|e| e.is_finite()).collect();
            if eps.is_empty() || most.is_nan() {
                return None;
            }
            Some((name.to_string(), most, median(&mut eps)))
        })
        .collect()
}
