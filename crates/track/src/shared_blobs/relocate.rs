//! The relocation of the points that share blobs: frames loaded again, groups formed and fitted.

use super::overlap_fit::{fit_positions, Composition, Fit, Pixel};
use super::profile::{measure_profile, Profile};
use super::reorder::{rename_by_motion, Starts};
use crate::disjoint_sets::DisjointSets;
use crate::link::Ambiguity;
use crate::track_table::{PointFlag, TrackPoint};
use crate::TrackError;
use rayon::prelude::*;
use std::collections::BTreeSet;

/// What the relocation needs to know about the frames and the particles in them.
pub(crate) struct SharedBlobs<'a> {
    /// The particle signal of frame `k` (row-major, `width * height`, gain removed).
    pub signal_of: &'a (dyn Fn(usize) -> Result<Vec<f32>, TrackError> + Sync),
    /// Frame width, px.
    pub width: usize,
    /// Frame height, px.
    pub height: usize,
    /// Particle radius (at half the peak signal), px.
    pub radius: f64,
    /// Centroid window radius, px.
    pub window: f64,
}

/// Counts of a relocation.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub(crate) struct Relocated {
    /// Points moved to their fitted positions.
    pub moved: usize,
    /// Points handed to another track of their group by the motion.
    pub renamed: usize,
    /// The particle and frame of each point placed from the image by a group's fit.
    pub placed: BTreeSet<(String, usize)>,
}
/// Places the flagged (split or bridged) points of `points`, and the points that share their
/// blobs, from the image, then lets the motion judge which of a group's positions belongs to
/// which track. Frames are loaded again, in parallel; the others are untouched. A group's
/// fit is kept only if every position stays within one radius of where linking put it;
/// otherwise its linked points stand.
pub(crate) fn relocate_shared(
    points: &mut [TrackPoint],
    ambiguities: &mut [Ambiguity],
    starts: &Starts<'_>,
    blobs: &SharedBlobs<'_>,
) -> Result<Relocated, TrackError> {
    let mut by_frame: std::collections::BTreeMap<usize, Vec<usize>> = std::collections::BTreeMap::new();
    for (i, p) in points.iter().enumerate() {
        by_frame.entry(p.frame).or_default().push(i);
    }
    let overlap = 2.0 * blobs.radius;
    let work: Vec<&Vec<usize>> = by_frame
        .values()
        .filter(|idx| {
            idx.iter().any(|&i| points[i].flag != PointFlag::Detected) || has_overlap(points, idx, overlap)
        })
        .collect();
    if work.is_empty() {
        return Ok(Relocated::default());
    }
    let view: &[TrackPoint] = points;
    let profile = match measure_profile(view, &by_frame.values().collect::<Vec<_>>(), blobs)? {
        Some(p) => p,
        None => match Profile::disc(view, blobs.radius) {
            Some(p) => p,
            None => return Ok(Relocated::default()),
        },
    };
    let fitted: Vec<Vec<Group>> = work
        .par_iter()
        .map(|idx| relocate_frame(view, idx, blobs, &profile))
        .collect::<Result<_, TrackError>>()?;
    let mut counts = Relocated::default();
    let groups: Vec<Group> = fitted.into_iter().flatten().collect();
    for g in &groups {
        if let Some(fit) = &g.fit {
            counts.moved += g.members.len();
            for ((&i, p), &e) in g.members.iter().zip(&fit.positions).zip(&fit.errors) {
                points[i].x = p[0];
                points[i].y = p[1];
                points[i].ep = e;
            }
        }
    }
    counts.renamed = rename_by_motion(points, &groups, ambiguities, starts);
    counts.placed = groups
        .iter()
        .filter(|g| g.fit.is_some())
        .flat_map(|g| {
            g.members
                .iter()
                .map(|&i| (points[i].particle.clone(), points[i].frame))
        })
        .collect();
    Ok(counts)
}

/// One frame's group of particles that may share light: the points (indices) and their
/// fit (`None` where the linked points stand).
#[derive(Clone, Debug)]
pub(super) struct Group {
    pub(super) members: Vec<usize>,
    pub(super) fit: Option<Fit>,
}
/// Returns true if and only if two of the points `idx` (indices into `points`) lie closer
/// than `overlap` px.
fn has_overlap(points: &[TrackPoint], idx: &[usize], overlap: f64) -> bool {
    let mut xs: Vec<[f64; 2]> = idx.iter().map(|&i| [points[i].x, points[i].y]).collect();
    xs.sort_by(|a, b| a[0].total_cmp(&b[0]));
    xs.iter().enumerate().any(|(k, a)| {
        xs[k + 1..]
            .iter()
            .take_while(|b| b[0] - a[0] < overlap)
            .any(|b| dist2(*a, *b) < overlap * overlap)
    })
}

pub(super) fn dist2(a: [f64; 2], b: [f64; 2]) -> f64 {
    (a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2)
}

/// Calls `f(x, y, index)` for every pixel of the `width x height` frame within `reach` of
/// some point of `centres`, once each.
pub(super) fn for_pixels_near(
    centres: &[[f64; 2]],
    reach: f64,
    width: usize,
    height: usize,
    mut f: impl FnMut(f64, f64, usize),
) {
    // The pixels along axis `k` (of `len`) within `reach` of some centre.
    let span = |k: usize, len: usize| {
        let lo = centres
            .iter()
            .map(|c| (c[k] - reach).floor().max(0.0) as usize)
            .min();
        let hi = centres.iter().map(|c| (c[k] + reach).ceil() as usize).max();
        lo.unwrap_or(0)..=hi.unwrap_or(0).min(len.saturating_sub(1))
    };
    let xs = span(0, width);
    for y in span(1, height) {
        for x in xs.clone() {
            let (xf, yf) = (x as f64, y as f64);
            if centres.iter().any(|c| dist2(*c, [xf, yf]) <= reach * reach) {
                f(xf, yf, y * width + x);
            }
        }
    }
}

/// The groups of one frame's points (`idx`, indices into `points`, all of one frame): each
/// flagged point and the points whose images may touch it, fitted jointly.
fn relocate_frame(
    points: &[TrackPoint],
    idx: &[usize],
    blobs: &SharedBlobs<'_>,
    profile: &Profile,
) -> Result<Vec<Group>, TrackError> {
    let at = |i: usize| [points[i].x, points[i].y];
    let touch = 2.0 * blobs.radius + 2.0;
    // Groups: connected components of the touching relation, among components holding a
    // flagged point.
    let n = idx.len();
    let mut sets = DisjointSets::new(n);
    let mut order: Vec<usize> = (0..n).collect();
    order.sort_by(|&a, &b| at(idx[a])[0].total_cmp(&at(idx[b])[0]));
    for (k, &a) in order.iter().enumerate() {
        for &b in &order[k + 1..] {
            let (pa, pb) = (at(idx[a]), at(idx[b]));
            if pb[0] - pa[0] >= touch {
                break;
            }
            if dist2(pa, pb) < touch * touch {
                sets.union(a, b);
            }
        }
    }
    let mut comps: std::collections::BTreeMap<usize, Vec<usize>> = std::collections::BTreeMap::new();
    for (a, &i) in idx.iter().enumerate() {
        comps.entry(sets.root(a)).or_default().push(i);
    }
    let overlap = 2.0 * blobs.radius;
    let mut groups: Vec<Group> = comps
        .into_values()
        .filter(|g| {
            g.len() > 1
                && (g.iter().any(|&i| points[i].flag != PointFlag::Detected)
                    || has_overlap(points, g, overlap))
        })
        .map(|members| Group { members, fit: None })
        .collect();
    if groups.is_empty() {
        return Ok(groups);
    }
    let signal = (blobs.signal_of)(points[idx[0]].frame)?;
    let reach = profile.reach();
    for g in &mut groups {
        // A guessed image (a disc) places a pair; three or more particles in one blob can
        // trade light for position under it (a start blob of three at 3-4 px went 4 px off).
        if !profile.measured && g.members.len() > 2 {
            continue;
        }
        let seeds: Vec<[f64; 2]> = g.members.iter().map(|&i| at(i)).collect();
        // Light of other particles within reach of the group's pixels is part of the model
        // (fixed at their located positions).
        let others: Vec<[f64; 2]> = idx
            .iter()
            .filter(|i| !g.members.contains(i))
            .map(|&i| at(i))
            .filter(|&p| seeds.iter().any(|&s| dist2(s, p) < (2.0 * reach) * (2.0 * reach)))
            .collect();
        let mut pixels: Vec<Pixel> = Vec::new();
        for_pixels_near(&seeds, blobs.window, blobs.width, blobs.height, |x, y, i| {
            let (mut held_sum, mut held_clear) = (0.0, 1.0);
            for o in &others {
                let t = profile.at((x - o[0]).hypot(y - o[1])).0;
                held_sum += t;
                held_clear *= profile.clear(t);
            }
            pixels.push(Pixel {
                x,
                y,
                signal: f64::from(signal[i]),
                held_sum,
                held_clear,
            });
        });
        let best = [Composition::Sum, Composition::Cover]
            .into_iter()
            .map(|c| fit_positions(&pixels, &seeds, profile, c))
            .min_by(|a, b| a.sse.total_cmp(&b.sse));
        g.fit = best.filter(|fit| {
            fit.positions
                .iter()
                .zip(&seeds)
                .all(|(f, s)| dist2(*f, *s) <= blobs.radius * blobs.radius)
        });
    }
    Ok(groups)
}
