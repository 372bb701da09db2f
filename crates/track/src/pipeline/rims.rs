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
use super::window_frames::{ClassFrames, WindowFrames};
use crate::checks::Skirt;
use crate::rim::rim_centre;
use crate::{Background, PointFlag, TrackError, TrackPoint, TrackTable};
use physfit_tracks::stats::{median, robust_spread};
use rayon::prelude::*;
use std::collections::{BTreeMap, BTreeSet};

/// A hollow particle's rim is searched out to this many radii in use (and 2 px): the radius
/// of gyration of a thin ring is its own radius, `1 / sqrt(2)` of the radius it is
/// estimated at, and a ring estimated at a smaller size still holds its rim within reach.
const RIM_REACH: f64 = 1.5;

/// How far from a point a hollow particle's rim is searched for (and a round particle's
/// profile read), px, for particles of radius `radius` px: [`RIM_REACH`] radii and 2 px.
pub(super) fn rim_reach(radius: f64) -> f64 {
    RIM_REACH * radius + 2.0
}

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

/// A rim found about a search start of a track table's point.
#[derive(Clone, Copy, Debug)]
struct FoundRim {
    /// The point's index in the table.
    index: usize,
    /// The rim's centre, px.
    centre: [f64; 2],
    /// The centre's standard error on one axis, px.
    error: f64,
    /// The rim's mean radius about its centre, px.
    radius: f64,
}

/// A rim whose radius lies farther than this many of its particle's spread of rim radii
/// ([`robust_spread`], or the rims' median centre error where larger) from their median is
/// not the particle's (see [`consistent_rims`]).
const RIM_RADIUS_SIGMAS: f64 = 5.0;

/// Moves each detected point of the particles `hollow` in `table` to its rim's centre
/// ([`rim_centre`], searched out to [`RIM_REACH`] times `radius` px and 2 px, about the
/// point, in the frame's levelled signal against `background`); its `ep` becomes the rim
/// centre's standard error. A point whose rim is not found about it is searched for again
/// about where the motion of its rim-centred neighbours puts it ([`predict_from`]): its
/// centroid may have settled on part of the rim (seed 3005 of the ring neighbours, rings of
/// 14 px: a last point left 8.5 px off at its centroid, the ring whole and plain to see).
/// The linker's bridges over frames the particle was not seen in are searched for in the same
/// pass ([`replace_bridges`]); points whose rim is still not found are placed from that
/// motion instead ([`bridge_unrimmed`]).
pub(super) fn centre_on_rims(
    table: &mut TrackTable,
    hollow: &BTreeSet<String>,
    class: &ClassFrames<'_>,
) -> Result<RimsCentred, TrackError> {
    let ClassFrames {
        frames,
        background,
        radius,
        workers,
    } = *class;
    if hollow.is_empty() {
        return Ok(RimsCentred::default());
    }
    let reach = rim_reach(radius);
    let detected = |p: &TrackPoint| p.flag == PointFlag::Detected && hollow.contains(&p.particle);
    let searches: Vec<(usize, [f64; 2])> = (table.points.iter().enumerate())
        .filter(|(_, p)| detected(p))
        .map(|(i, p)| (i, [p.x, p.y]))
        .collect();
    let mut rimmed = vec![false; table.points.len()];
    // Each rim-centred point's distance from its centroid, px (NaN for the others).
    let mut gaps = vec![f64::NAN; table.points.len()];
    let first = rim_search(table, &searches, frames, background, reach, workers)?;
    let radii = rim_radii(table, &first);
    let mut moved = apply_rims(
        table,
        consistent_rims(table, first, &radii),
        &mut rimmed,
        &mut gaps,
    );
    // Again about the motion's prediction, where the rim was not found about a detected point,
    // and about the linker's bridges (one decoding of their frames for both).
    let anchors = rim_anchors(table, &rimmed);
    let predicted = |i: usize| Some((i, predict_from(&anchors, &table.points[i])?));
    let again: Vec<(usize, [f64; 2])> = (0..table.points.len())
        .filter(|&i| !rimmed[i] && detected(&table.points[i]))
        .filter_map(predicted)
        .collect();
    let bridges: Vec<(usize, [f64; 2])> = (0..table.points.len())
        .filter(|&i| {
            let p = &table.points[i];
            p.flag == PointFlag::Interpolated && hollow.contains(&p.particle)
        })
        .filter_map(predicted)
        .collect();
    let searches = [again.as_slice(), bridges.as_slice()].concat();
    let found = if searches.is_empty() {
        Vec::new()
    } else {
        rim_search(table, &searches, frames, background, reach, workers)?
    };
    let (found_bridges, found_again): (Vec<_>, Vec<_>) = consistent_rims(table, found, &radii)
        .into_iter()
        .partition(|f| table.points[f.index].flag == PointFlag::Interpolated);
    moved += apply_rims(table, found_again, &mut rimmed, &mut gaps);
    let unrimmed: Vec<usize> = (0..table.points.len())
        .filter(|&i| !rimmed[i] && detected(&table.points[i]))
        .collect();
    let not_found = unrimmed
        .iter()
        .map(|&i| (table.points[i].particle.clone(), table.points[i].frame))
        .collect();
    let warnings = bridge_unrimmed(table, &unrimmed, &rimmed, &gaps);
    replace_bridges(table, &bridges, &found_bridges);
    Ok(RimsCentred {
        moved,
        warnings,
        not_found,
    })
}

/// What [`centre_on_rims`] did.
#[derive(Debug, Default)]
pub(super) struct RimsCentred {
    /// Points moved to their rim's centre.
    pub(super) moved: usize,
    /// One warning per particle with detected points whose rim was not found, naming them.
    pub(super) warnings: Vec<String>,
    /// The particle and frame of each of those points: placed from the motion of its rim's
    /// centre (flagged interpolated), or left at its centroid, unchecked.
    pub(super) not_found: Vec<(String, usize)>,
}

/// The rims found about each search start `(point index, [x, y])` of `table` (the frame's
/// other points counted as neighbours).
fn rim_search(
    table: &TrackTable,
    searches: &[(usize, [f64; 2])],
    frames: &WindowFrames<'_>,
    background: &Background,
    reach: f64,
    workers: &Workers,
) -> Result<Vec<FoundRim>, TrackError> {
    let points = &table.points;
    // Each frame's points (all of them: a neighbour's pixels are its own), by index.
    let mut by_frame: BTreeMap<usize, Vec<usize>> = BTreeMap::new();
    for (i, p) in points.iter().enumerate() {
        by_frame.entry(p.frame).or_default().push(i);
    }
    let mut starts: BTreeMap<usize, Vec<(usize, [f64; 2])>> = BTreeMap::new();
    for &(i, at) in searches {
        starts.entry(points[i].frame).or_default().push((i, at));
    }
    let found: Vec<Vec<FoundRim>> = starts
        .into_par_iter()
        .map(|(k, wanted)| {
            frames.with_signal(k, background, workers, |signal, width, height| {
                let idx = &by_frame[&k];
                let mut out = Vec::new();
                for (i, at) in wanted {
                    let others: Vec<[f64; 2]> = idx
                        .iter()
                        .filter(|&&j| j != i)
                        .map(|&j| [points[j].x, points[j].y])
                        .filter(|q| (q[0] - at[0]).abs().max((q[1] - at[1]).abs()) < 2.0 * reach)
                        .collect();
                    if let Some(rim) =
                        rim_centre(signal, width, height, at, &others, reach, background.noise_sigma)
                    {
                        out.push(FoundRim {
                            index: i,
                            centre: [at[0] + rim.offset[0], at[1] + rim.offset[1]],
                            error: rim.error,
                            radius: rim.radius,
                        });
                    }
                }
                out
            })
        })
        .collect::<Result<_, TrackError>>()?;
    Ok(found.into_iter().flatten().collect())
}

/// Each particle's rim radius among `found` (px): the median, and how far from it a rim of
/// the particle may lie ([`RIM_RADIUS_SIGMAS`] of their spread); particles with fewer than 3
/// rims found have none.
fn rim_radii(table: &TrackTable, found: &[FoundRim]) -> BTreeMap<String, (f64, f64)> {
    let mut by_particle: BTreeMap<&str, Vec<&FoundRim>> = BTreeMap::new();
    for f in found {
        by_particle
            .entry(table.points[f.index].particle.as_str())
            .or_default()
            .push(f);
    }
    by_particle
        .into_iter()
        .filter(|(_, rims)| rims.len() >= 3)
        .map(|(particle, rims)| {
            let mut radii: Vec<f64> = rims.iter().map(|f| f.radius).collect();
            let middle = median(&mut radii);
            let mut errors: Vec<f64> = rims.iter().map(|f| f.error).collect();
            let spread = robust_spread(&mut radii).max(median(&mut errors));
            (particle.to_string(), (middle, RIM_RADIUS_SIGMAS * spread))
        })
        .collect()
}

/// The rims of `found` whose radius lies within its particle's bound ([`rim_radii`]). A point
/// between two rings can hold a hollow pattern of its own: the near arcs of both, the
/// neighbour's pixels left out, read as a rim a pixel or two smaller about a centre between
/// them (ring neighbour 3009 at 10 px and noise 15: rims of 7.1-7.3 px against the ring's
/// 8.75, a point left 13 px off with an error of 0.1 px).
fn consistent_rims(
    table: &TrackTable,
    found: Vec<FoundRim>,
    radii: &BTreeMap<String, (f64, f64)>,
) -> Vec<FoundRim> {
    found
        .into_iter()
        .filter(|f| {
            radii
                .get(&table.points[f.index].particle)
                .map_or(true, |&(middle, bound)| (f.radius - middle).abs() <= bound)
        })
        .collect()
}

/// Moves the points of `found` to their rim's centre (`ep` its error), marking them
/// `rimmed`, and how far each moved in `gaps` (px); returns how many.
fn apply_rims(table: &mut TrackTable, found: Vec<FoundRim>, rimmed: &mut [bool], gaps: &mut [f64]) -> usize {
    let count = found.len();
    for f in found {
        let p = &mut table.points[f.index];
        gaps[f.index] = (f.centre[0] - p.x).hypot(f.centre[1] - p.y);
        p.x = f.centre[0];
        p.y = f.centre[1];
        p.ep = f.error;
        rimmed[f.index] = true;
    }
    count
}

/// Frames on each side of a point whose rim-centred neighbours place it.
const BRIDGE_REACH: usize = 3;

/// Places each point `unrimmed` (indices into `table`: a hollow particle's detected points
/// whose rim was not found, so that only their centroid is known, which leans with the light
/// and the neighbours by up to the rim's width) from the motion of the same particle's
/// rim-centred points (`rimmed[i]`) within [`BRIDGE_REACH`] frames: a quadratic in time
/// through them, least squares, when it has a point on each side and three in all, else the
/// line between the nearest on each side ([`place_from`]). Each such
/// point is flagged [`PointFlag::Interpolated`] and its `ep` becomes NaN (unknown). Points
/// with too few neighbours stay as located, and are named too. So do the points of a
/// particle whose centroids lie nearer its rim's centre (`gaps`, px, where both were found)
/// than its motion places its rim-centred points when each is left out ([`motion_error`]),
/// by [`CENTROID_GAIN`]:
/// a small ring's window holds its rim, and in curved motion the motion is the worse guess
/// (sweep style 8069, rings of 3 px, noise 16: bridges 0.6-1.9 px off where the centroids
/// were 0.1-0.3). Returns one warning per particle, naming its frames.
fn bridge_unrimmed(table: &mut TrackTable, unrimmed: &[usize], rimmed: &[bool], gaps: &[f64]) -> Vec<String> {
    if unrimmed.is_empty() {
        return Vec::new();
    }
    let anchors = rim_anchors(table, rimmed);
    // Each particle's centroids' RMS distance from its rim's centre, where both are known.
    let mut centroid_sq: BTreeMap<&str, (f64, usize)> = BTreeMap::new();
    for (p, g) in table.points.iter().zip(gaps) {
        if g.is_finite() {
            let e = centroid_sq.entry(p.particle.as_str()).or_default();
            (e.0, e.1) = (e.0 + g * g, e.1 + 1);
        }
    }
    let centroid_better: BTreeMap<String, (f64, f64)> = centroid_sq
        .iter()
        .filter(|(_, (_, n))| *n >= MIN_COMPARED)
        .filter_map(|(&name, &(sq, n))| {
            let centroid = (sq / n as f64).sqrt();
            let motion = motion_error(anchors.get(name)?)?;
            (CENTROID_GAIN * centroid < motion).then(|| (name.to_string(), (centroid, motion)))
        })
        .collect();
    let placed: Vec<(usize, Option<[f64; 2]>)> = unrimmed
        .iter()
        .map(|&i| {
            let p = &table.points[i];
            let keep = centroid_better.contains_key(&p.particle);
            (i, if keep { None } else { place_from(&anchors, p) })
        })
        .collect();
    let mut by_particle: BTreeMap<String, (Vec<usize>, Vec<usize>)> = BTreeMap::new();
    for (i, at) in placed {
        let p = &mut table.points[i];
        let entry = by_particle.entry(p.particle.clone()).or_default();
        match at {
            Some(at) => {
                p.x = at[0];
                p.y = at[1];
                p.ep = f64::NAN;
                p.flag = PointFlag::Interpolated;
                entry.0.push(p.frame);
            }
            None => entry.1.push(p.frame),
        }
    }
    let list = |frames: &[usize]| frames.iter().map(usize::to_string).collect::<Vec<_>>().join(", ");
    by_particle
        .into_iter()
        .map(|(particle, (bridged, kept))| {
            let mut text = format!(
                "{particle}: a ring whose rim was not found in some frames (its centroid there leans with the light and its neighbours)"
            );
            if !bridged.is_empty() {
                text.push_str(&format!(
                    "; placed from the motion of its rim's centre in frame(s) {} (flagged interpolated)",
                    list(&bridged)
                ));
            }
            if !kept.is_empty() {
                match centroid_better.get(&particle) {
                    Some((centroid, motion)) => text.push_str(&format!(
                        "; left at its centroid, {centroid:.2} px RMS from its rim's centre where both were found \
                         (its motion placed its rim's centre {motion:.2} px off), in frame(s) {}",
                        list(&kept)
                    )),
                    None => text.push_str(&format!(
                        "; left at its centroid, unchecked (it can lie the rim's width or more off the ring's centre), in frame(s) {}",
                        list(&kept)
                    )),
                }
            }
            text
        })
        .collect()
}

/// How many times nearer its rim's centre than its motion a particle's centroids must lie
/// to be kept: both are RMS over a few frames, and the motion was the rule (fresh style 6440,
/// rings of 5 px at noise 12: 0.34 against 0.40 px, its centroid kept and its track 0.14 ->
/// 0.17 px off).
const CENTROID_GAIN: f64 = std::f64::consts::SQRT_2;

/// Least points in each of the two comparisons (centroid against rim, motion against rim)
/// for the centroids to be kept over the motion.
const MIN_COMPARED: usize = 3;

/// How far the motion of a particle's rim-centred points `anchors` (by frame, px) places
/// each of them when it is left out ([`place_in`]), RMS, px; `None` where fewer than
/// [`MIN_COMPARED`] can be placed.
fn motion_error(anchors: &BTreeMap<usize, [f64; 2]>) -> Option<f64> {
    let mut others = anchors.clone();
    let (mut sq, mut n) = (0.0, 0usize);
    for (&k, &x) in anchors {
        others.remove(&k);
        if let Some(at) = place_in(&others, k) {
            sq += (at[0] - x[0]).powi(2) + (at[1] - x[1]).powi(2);
            n += 1;
        }
        others.insert(k, x);
    }
    (n >= MIN_COMPARED).then(|| (sq / n as f64).sqrt())
}

/// Places again the points the linker bridged over frames a hollow particle was not seen in
/// (`bridges`: index and the motion's place from its rim-centred neighbours,
/// [`predict_from`]; they were placed from the motion of centroids, which lean off a ring's
/// centre by up to its rim's width): at their rim's centre where `found` holds it, or else at
/// that place. They stay flagged interpolated (the linker's warning names the frames); those
/// with too few neighbours stay as bridged. Seed 3005 of the ring neighbours: rings of 14 px,
/// a bridge 5.7 px off between rim-centred points 0.1 px off on either side; rings of 20 px,
/// a bridge over the last frame 22.8 px off.
fn replace_bridges(table: &mut TrackTable, bridges: &[(usize, [f64; 2])], found: &[FoundRim]) {
    let placed = bridges
        .iter()
        .copied()
        .chain(found.iter().map(|f| (f.index, f.centre)));
    for (i, at) in placed {
        table.points[i].x = at[0];
        table.points[i].y = at[1];
    }
}

/// Each particle's rim-centred points (`rimmed[i]`) by frame.
fn rim_anchors<'a>(table: &'a TrackTable, rimmed: &[bool]) -> BTreeMap<&'a str, BTreeMap<usize, [f64; 2]>> {
    let mut anchors: BTreeMap<&str, BTreeMap<usize, [f64; 2]>> = BTreeMap::new();
    for (i, p) in table.points.iter().enumerate() {
        if rimmed[i] {
            anchors
                .entry(p.particle.as_str())
                .or_default()
                .insert(p.frame, [p.x, p.y]);
        }
    }
    anchors
}

/// Where `p`'s particle's rim-centred points `anchors` within [`BRIDGE_REACH`] frames place
/// it: [`quadratic_at_zero`] through them, or, with only one on each side, the straight line
/// between those two (as the linker bridges a frame the particle was not seen in). A ring of
/// 24 px, its rim-centred points in frames 16 and 19 only, was left at its centroid 17 px
/// off in frame 18 (bench cell ring 24 px, noise 0).
fn place_from(anchors: &BTreeMap<&str, BTreeMap<usize, [f64; 2]>>, p: &TrackPoint) -> Option<[f64; 2]> {
    place_in(anchors.get(p.particle.as_str())?, p.frame)
}

/// Where one particle's rim-centred points `anchors` (by frame, px) place it in `frame`, as
/// [`place_from`] says.
fn place_in(anchors: &BTreeMap<usize, [f64; 2]>, frame: usize) -> Option<[f64; 2]> {
    let near: Vec<(f64, [f64; 2])> = anchors
        .range(frame.saturating_sub(BRIDGE_REACH)..=frame + BRIDGE_REACH)
        .map(|(&k, &x)| (k as f64 - frame as f64, x))
        .collect();
    quadratic_at_zero(&near).or_else(|| {
        let before = near.iter().rev().find(|q| q.0 < 0.0)?;
        let after = near.iter().find(|q| q.0 > 0.0)?;
        let t = -before.0 / (after.0 - before.0);
        Some([0, 1].map(|c| before.1[c] + t * (after.1[c] - before.1[c])))
    })
}

/// Where `p`'s particle's rim-centred points `anchors` within [`BRIDGE_REACH`] frames put it:
/// [`place_from`] between them, or on the line through the two nearest on one side, within
/// [`BRIDGE_REACH`] frames of it.
fn predict_from(anchors: &BTreeMap<&str, BTreeMap<usize, [f64; 2]>>, p: &TrackPoint) -> Option<[f64; 2]> {
    if let Some(at) = place_from(anchors, p) {
        return Some(at);
    }
    let a = anchors.get(p.particle.as_str())?;
    let window = p.frame.saturating_sub(BRIDGE_REACH)..=p.frame + BRIDGE_REACH;
    let before: Vec<(usize, [f64; 2])> = a
        .range(window.clone())
        .filter(|(&k, _)| k < p.frame)
        .map(|(&k, &x)| (k, x))
        .collect();
    let after: Vec<(usize, [f64; 2])> = a
        .range(window)
        .filter(|(&k, _)| k > p.frame)
        .map(|(&k, &x)| (k, x))
        .collect();
    let two: Vec<(usize, [f64; 2])> = if before.len() >= 2 {
        before[before.len() - 2..].to_vec()
    } else if after.len() >= 2 {
        after[..2].to_vec()
    } else {
        return None;
    };
    let ((k0, x0), (k1, x1)) = (two[0], two[1]);
    let t = (p.frame as f64 - k0 as f64) / (k1 as f64 - k0 as f64);
    Some([0, 1].map(|c| x0[c] + t * (x1[c] - x0[c])))
}

/// The value at `t = 0` of the least-squares quadratic in `t` through `points` (`(t, [x, y])`),
/// when they hold a point on each side of 0 and three in all.
fn quadratic_at_zero(points: &[(f64, [f64; 2])]) -> Option<[f64; 2]> {
    let before = points.iter().any(|p| p.0 < 0.0);
    let after = points.iter().any(|p| p.0 > 0.0);
    if !before || !after || points.len() < 3 {
        return None;
    }
    // Normal equations of x(t) = a + b t + c t^2; the value at 0 is a.
    let mut m = nalgebra::Matrix3::<f64>::zeros();
    let mut rhs = nalgebra::Matrix3x2::<f64>::zeros();
    for &(t, x) in points {
        let basis = nalgebra::Vector3::new(1.0, t, t * t);
        m += basis * basis.transpose();
        rhs += basis * nalgebra::RowVector2::new(x[0], x[1]);
    }
    let solution = m.lu().solve(&rhs)?;
    Some([solution[(0, 0)], solution[(0, 1)]])
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A ring's rims read 8.75 px give or take 0.03 in nine frames, and 7.2 px in one (the
    /// near arcs of two rings about a point between them): that one is not the ring's and
    /// is dropped, the others kept; a particle with two rims found keeps both, whatever
    /// their radii.
    #[test]
    fn a_rim_of_another_radius_is_not_the_particles() {
        let table = TrackTable {
            points: (0..10)
                .map(|k| TrackPoint::new(k, "r", 0.0, 0.0))
                .chain((0..2).map(|k| TrackPoint::new(k, "s", 50.0, 0.0)))
                .collect(),
        };
        let rim = |index: usize, radius: f64| FoundRim {
            index,
            centre: [0.0, 0.0],
            error: 0.01,
            radius,
        };
        let found: Vec<FoundRim> = (0..10)
            .map(|k| {
                rim(
                    k,
                    if k == 6 {
                        7.2
                    } else {
                        8.75 + 0.03 * ((k % 3) as f64 - 1.0)
                    },
                )
            })
            .chain([rim(10, 8.0), rim(11, 5.0)])
            .collect();
        let radii = rim_radii(&table, &found);
        let kept: Vec<usize> = consistent_rims(&table, found, &radii)
            .iter()
            .map(|f| f.index)
            .collect();
        assert_eq!(kept, [0, 1, 2, 3, 4, 5, 7, 8, 9, 10, 11]);
    }

    /// A ring falling along `x = 10 + 2k, y = 20 + k^2 / 2` over frames 0-9, its rim not found
    /// in frames 4 and 9 (located 3 px off there, as a centroid leaning on a neighbour): frame
    /// 4 is placed back on the path exactly and flagged interpolated; frame 9, with rim-centred
    /// points on one side only, stays and is named. With one rim-centred point on each side
    /// only, the points between are placed on the line through them.
    #[test]
    fn points_without_their_rim_are_placed_from_the_motion_or_named() {
        let path = |k: usize| [10.0 + 2.0 * k as f64, 20.0 + 0.5 * (k * k) as f64];
        // The ring's points in frames 0..n, those of `off_frames` located `off` px off in x.
        let along = |n: usize, off_frames: &[usize], off: f64| TrackTable {
            points: (0..n)
                .map(|k| {
                    let [x, y] = path(k);
                    let dx = if off_frames.contains(&k) { off } else { 0.0 };
                    TrackPoint::new(k, "r", x + dx, y)
                })
                .collect(),
        };
        let mut table = along(10, &[4, 9], 3.0);
        let rimmed: Vec<bool> = (0..10).map(|k| k != 4 && k != 9).collect();
        let unknown = vec![f64::NAN; 10];
        let warnings = bridge_unrimmed(&mut table, &[4, 9], &rimmed, &unknown);
        let p = &table.points[4];
        assert!(
            (p.x - path(4)[0]).abs() < 1e-9 && (p.y - path(4)[1]).abs() < 1e-9,
            "{p:?}"
        );
        assert_eq!(p.flag, PointFlag::Interpolated);
        assert!(p.ep.is_nan());
        assert_eq!(table.points[9].flag, PointFlag::Detected);
        assert!((table.points[9].x - path(9)[0] - 3.0).abs() < 1e-12);
        assert_eq!(warnings.len(), 1, "{warnings:?}");
        let w = &warnings[0];
        assert!(w.starts_with("r: a ring whose rim was not found"), "{w}");
        assert!(w.contains("in frame(s) 4 (flagged interpolated)"), "{w}");
        assert!(
            w.contains("left at its centroid") && w.ends_with("in frame(s) 9"),
            "{w}"
        );
        assert!(bridge_unrimmed(&mut table, &[], &rimmed, &unknown).is_empty());

        // Rim-centred points in frames 0 and 3 only, within reach of frames 1 and 2 (their
        // rims not found, 17 px off): each is placed on the straight line between them.
        let mut table = along(4, &[1, 2], 17.0);
        let rimmed = [true, false, false, true];
        let warnings = bridge_unrimmed(&mut table, &[1, 2], &rimmed, &[f64::NAN; 4]);
        for k in [1usize, 2] {
            let t = k as f64 / 3.0;
            let p = &table.points[k];
            let want = [0, 1].map(|c| path(0)[c] + t * (path(3)[c] - path(0)[c]));
            assert!(
                (p.x - want[0]).abs() < 1e-9 && (p.y - want[1]).abs() < 1e-9,
                "{p:?}"
            );
            assert_eq!(p.flag, PointFlag::Interpolated);
        }
        assert!(!warnings[0].contains("left at its centroid"), "{warnings:?}");
    }

    #[test]
    fn centroids_nearer_the_rim_than_the_motion_are_kept() {
        // A small ring turning fast on a circle (10 px, 0.8 rad a frame): its motion, from the
        // rim-centred points around a frame, misses by a pixel and more, where its centroids lie
        // 0.1 px from its rim's centre.
        let circle = |k: usize| {
            let a = 0.8 * k as f64;
            [50.0 + 10.0 * a.cos(), 50.0 + 10.0 * a.sin()]
        };
        let mut table = TrackTable {
            points: (0..12)
                .map(|k| {
                    let [x, y] = circle(k);
                    TrackPoint::new(k, "r", x + 0.1, y)
                })
                .collect(),
        };
        let rimmed: Vec<bool> = (0..12).map(|k| k != 5).collect();
        let gaps: Vec<f64> = (0..12).map(|k| if k == 5 { f64::NAN } else { 0.1 }).collect();
        let warnings = bridge_unrimmed(&mut table, &[5], &rimmed, &gaps);
        let p = &table.points[5];
        assert_eq!(p.flag, PointFlag::Detected);
        assert!((p.x - circle(5)[0] - 0.1).abs() < 1e-12, "{p:?}");
        let w = &warnings[0];
        assert!(
            w.contains("left at its centroid, 0.10 px RMS from its rim's centre"),
            "{w}"
        );
        assert!(w.ends_with("in frame(s) 5"), "{w}");

        // On a straight line at constant speed the motion places it exactly: bridged though its
        // centroids lie as near.
        let line = |k: usize| [10.0 + 2.0 * k as f64, 20.0 + 1.0 * k as f64];
        let mut table = TrackTable {
            points: (0..12)
                .map(|k| TrackPoint::new(k, "r", line(k)[0] + 0.1, line(k)[1]))
                .collect(),
        };
        bridge_unrimmed(&mut table, &[5], &rimmed, &gaps);
        let p = &table.points[5];
        assert_eq!(p.flag, PointFlag::Interpolated);
        assert!((p.x - line(5)[0] - 0.1).abs() < 1e-9, "{p:?}");
    }
}
