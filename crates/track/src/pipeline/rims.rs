//! Hollow particles (rings) located by their rim's centre instead of their centroid.
//!
//! A ring's intensity centroid leans with whatever makes one side of its rim brighter (a
//! gradient, vignetting, part of the particle left in a per-pixel background, a
//! neighbour's light), and its window holds the background inside the ring, whose noise
//! has a long lever arm. Its rim's position does neither ([`rim_centre`]). Particles whose
//! rim is found about their points in most of the skirt's sample frames are measured from
//! the data to be hollow; each of their detected points is then moved to its rim's centre,
//! frame by frame. Discs, spots, balls and spheres are not hollow and are left as located.

use super::finder::Workers;
use super::window_frames::WindowFrames;
use crate::checks::Skirt;
use crate::rim::rim_centre;
use crate::{Background, PointFlag, TrackError, TrackTable};
use rayon::prelude::*;
use std::collections::{BTreeMap, BTreeSet};

/// A hollow particle's rim is searched out to this many radii in use (and 2 px): the radius
/// of gyration of a thin ring is its own radius, `1 / sqrt(2)` of the radius it is
/// estimated at, and a ring estimated at a smaller size still holds its rim within reach.
pub(super) const RIM_REACH: f64 = 1.5;

/// Least sample frames in which a particle's rim must be found for it to count as hollow.
const HOLLOW_SAMPLES: usize = 3;

/// The particles of `skirts` (as [`super::skirts::sample_skirts`] measures them) whose rim
/// was found in at least half their sample frames, and in [`HOLLOW_SAMPLES`] at least.
pub(super) fn hollow_particles(skirts: &BTreeMap<String, Vec<(usize, Skirt)>>) -> BTreeSet<String> {
    skirts
        .iter()
        .filter(|(_, m)| {
            let rims = m.iter().filter(|s| s.1.rim.is_some()).count();
            rims >= HOLLOW_SAMPLES && 2 * rims >= m.len()
        })
        .map(|(p, _)| p.clone())
        .collect()
}

/// Moves each detected point of the particles `hollow` in `table` to its rim's centre
/// ([`rim_centre`], searched out to [`RIM_REACH`] times `radius` px and 2 px, about the
/// point, in the frame's levelled signal against `background`); its `ep` becomes the rim
/// centre's standard error. Points whose rim is not found stay. Returns how many moved.
pub(super) fn centre_on_rims(
    table: &mut TrackTable,
    hollow: &BTreeSet<String>,
    frames: &WindowFrames<'_>,
    background: &Background,
    radius: f64,
    workers: &Workers,
) -> Result<usize, TrackError> {
    if hollow.is_empty() {
        return Ok(0);
    }
    let first = frames.numbers.first().copied().unwrap_or(0);
    // Each frame's points (all of them: a neighbour's pixels are its own), by index.
    let mut by_frame: BTreeMap<usize, Vec<usize>> = BTreeMap::new();
    for (i, p) in table.points.iter().enumerate() {
        by_frame.entry(p.frame).or_default().push(i);
    }
    let reach = RIM_REACH * radius + 2.0;
    let points = &table.points;
    let moves: Vec<Vec<(usize, [f64; 2], f64)>> = by_frame
        .into_par_iter()
        .filter(|(_, idx)| {
            idx.iter()
                .any(|&i| points[i].flag == PointFlag::Detected && hollow.contains(&points[i].particle))
        })
        .map(|(k, idx)| {
            workers.with(|w| {
                let frame = frames.get(k - first, &mut w.decoder, &mut w.frame)?;
                let (width, height) = frame.size();
                w.finder.levelled_signal(background, frame);
                let mut out = Vec::new();
                for &i in &idx {
                    let p = &points[i];
                    if p.flag != PointFlag::Detected || !hollow.contains(&p.particle) {
                        continue;
                    }
                    let others: Vec<[f64; 2]> = idx
                        .iter()
                        .filter(|&&j| j != i)
                        .map(|&j| [points[j].x, points[j].y])
                        .filter(|q| (q[0] - p.x).abs().max((q[1] - p.y).abs()) < 2.0 * reach)
                        .collect();
                    if let Some(rim) = rim_centre(
                        &w.finder.signal,
                        width,
                        height,
                        [p.x, p.y],
                        &others,
                        reach,
                        background.noise_sigma,
                    ) {
                        out.push((i, [p.x + rim.offset[0], p.y + rim.offset[1]], rim.error));
                    }
                }
                Ok(out)
            })
        })
        .collect::<Result<_, TrackError>>()?;
    let mut moved = 0;
    for (i, at, ep) in moves.into_iter().flatten() {
        let p = &mut table.points[i];
        p.x = at[0];
        p.y = at[1];
        p.ep = ep;
        moved += 1;
    }
    Ok(moved)
}
