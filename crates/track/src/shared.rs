//! Particles that share a blob, placed again from the image once the tracks are linked.
//!
//! While particles touch or overlap, linking knows how many share a blob but not where each
//! lies in it: it places them from their motion (split points about the blob's centroid,
//! bridged points on their predicted paths), and a particle whose blob swallowed another's
//! keeps the centroid of both. Those points can sit a pixel or two off, nearer the other
//! particle than their own. Once the recording is linked, each frame's flagged points and
//! the points near them are fitted again, jointly, to the frame's signal: each particle is
//! the recording's own single-particle image (its radial profile, measured on isolated
//! particles), and overlapping images combine either by adding (light-emitting spots) or as
//! layers that each cover what lies below (opaque or rendered discs), whichever fits the
//! pixels better. A centroid cannot do this: with a soft split between two overlapping
//! discs each estimate takes the half of the light on its side, a pixel or more off the
//! particle (about `4R / 3π` when they coincide).
//!
//! Which particle is which stays the linker's (the fit starts from the linked positions and
//! keeps their order), then is judged once more from the motion: inside a group, the
//! positions go to the tracks whose accelerations they keep smallest.

use nalgebra::{DMatrix, DVector};
use rayon::prelude::*;

use crate::disjoint_sets::DisjointSets;
use crate::link::Ambiguity;
use crate::track_table::{PointFlag, TrackPoint};
use crate::TrackError;

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
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(crate) struct Relocated {
    /// Points moved to their fitted positions.
    pub moved: usize,
    /// Points handed to another track of their group by the motion.
    pub renamed: usize,
}

/// Isolated particles whose images make the profile.
const PROFILE_SAMPLES: usize = 32;
/// Radial bin of the profile, px.
const PROFILE_BIN: f64 = 0.25;

/// A single particle's image: its mean signal against the distance from its centre.
#[derive(Clone, Debug)]
struct Profile {
    /// Mean signal per [`PROFILE_BIN`] of distance (bin `k` at `k · PROFILE_BIN`), grey
    /// levels; zero beyond the last.
    bins: Vec<f64>,
    /// The largest bin: the level of a fully covered pixel, grey levels.
    peak: f64,
    /// Whether the profile was measured on the recording's particles (else it is a disc of
    /// the measured radius, whose level is only estimated).
    measured: bool,
}

impl Profile {
    /// Signal at distance `r` (px) from the centre, and its derivative along `r`.
    fn at(&self, r: f64) -> (f64, f64) {
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
    fn disc(points: &[TrackPoint], radius: f64) -> Option<Profile> {
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
    fn clear(&self, t: f64) -> f64 {
        (1.0 - t / self.peak).clamp(0.0, 1.0)
    }

    /// Reach of the image, px.
    fn reach(&self) -> f64 {
        (self.bins.len() - 1) as f64 * PROFILE_BIN
    }
}

/// How overlapping particle images combine.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Composition {
    /// Light adds (fluorescent or glowing spots).
    Sum,
    /// Each image covers a fraction `s / peak` of what lies below (opaque objects, discs
    /// drawn one over the other).
    Cover,
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
    Ok(counts)
}

/// One frame's group of particles that may share light: the points (indices) and their
/// fit (`None` where the linked points stand).
#[derive(Clone, Debug)]
struct Group {
    members: Vec<usize>,
    fit: Option<Fit>,
}

/// The single-particle profile, measured on up to [`PROFILE_SAMPLES`] isolated located
/// particles (no other point within two windows and a radius) of the first frames of
/// `frames` (each a list of point indices) that hold some; `None` when none does.
fn measure_profile(
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

fn dist2(a: [f64; 2], b: [f64; 2]) -> f64 {
    (a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2)
}

/// Calls `f(x, y, index)` for every pixel of the `width x height` frame within `reach` of
/// some point of `centres`, once each.
fn for_pixels_near(
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

/// One pixel of a group's fit.
#[derive(Clone, Copy, Debug)]
struct Pixel {
    /// Column and row of the pixel centre, px.
    x: f64,
    y: f64,
    /// Measured signal, grey levels.
    signal: f64,
    /// Light of the particles held in place: their sum, grey levels (for [`Composition::Sum`]).
    held_sum: f64,
    /// The fraction of the pixel they leave uncovered (for [`Composition::Cover`]).
    held_clear: f64,
}

/// A group's fitted positions.
#[derive(Clone, Debug)]
struct Fit {
    /// Positions, px.
    positions: Vec<[f64; 2]>,
    /// Standard error of each position (per axis, px), from the residuals' spread: where the
    /// model misses the image (blur, a composition it does not know) the residuals grow, and
    /// so do the errors.
    errors: Vec<f64>,
    /// Sum of squared residuals, grey levels².
    sse: f64,
}

/// Fits the positions of particles seeded at `seeds` (px) to `pixels` by
/// Levenberg-Marquardt (with a brightness scale common to them when the profile is a disc).
fn fit_positions(pixels: &[Pixel], seeds: &[[f64; 2]], profile: &Profile, composition: Composition) -> Fit {
    let k = seeds.len();
    // Unknowns: each position (x, y), then, for a profile that was not measured (a disc), one
    // brightness scale for the group (its level is only estimated). A measured profile's
    // level is the recording's own: a free scale would only let overlapping particles trade
    // light for position.
    let free_scale = !profile.measured;
    let m = 2 * k + usize::from(free_scale);
    let clear = |t: f64| profile.clear(t);
    // Sum of squared residuals at `u`; with `normal`, also the Gauss-Newton normal
    // equations (JᵀJ and Jᵀr, r = measured − model).
    let evaluate = |u: &[f64], mut normal: Option<(&mut DMatrix<f64>, &mut DVector<f64>)>| -> f64 {
        let scale = if free_scale { u[2 * k] } else { 1.0 };
        let mut sse = 0.0;
        let mut grad = vec![0.0; m];
        // Each fitted particle's value and its derivatives along its own x and y.
        let mut vals = vec![(0.0, 0.0, 0.0); k];
        if let Some((a, b)) = normal.as_mut() {
            a.fill(0.0);
            b.fill(0.0);
        }
        for px in pixels {
            for (j, v) in vals.iter_mut().enumerate() {
                let (dx, dy) = (px.x - u[2 * j], px.y - u[2 * j + 1]);
                let r = dx.hypot(dy);
                let (t, dt) = profile.at(r);
                *v = if r > 1e-9 {
                    (t, -dt * dx / r, -dt * dy / r)
                } else {
                    (t, 0.0, 0.0)
                };
            }
            let shape = match composition {
                Composition::Sum => {
                    for (j, v) in vals.iter().enumerate() {
                        grad[2 * j] = scale * v.1;
                        grad[2 * j + 1] = scale * v.2;
                    }
                    px.held_sum + vals.iter().map(|v| v.0).sum::<f64>()
                }
                Composition::Cover => {
                    let all_clear = px.held_clear * vals.iter().map(|v| clear(v.0)).product::<f64>();
                    for (j, v) in vals.iter().enumerate() {
                        let rest: f64 = px.held_clear
                            * vals
                                .iter()
                                .enumerate()
                                .filter(|&(i, _)| i != j)
                                .map(|(_, w)| clear(w.0))
                                .product::<f64>();
                        grad[2 * j] = scale * rest * v.1;
                        grad[2 * j + 1] = scale * rest * v.2;
                    }
                    profile.peak * (1.0 - all_clear)
                }
            };
            if free_scale {
                grad[2 * k] = shape;
            }
            let res = px.signal - scale * shape;
            sse += res * res;
            if let Some((a, b)) = normal.as_mut() {
                for i in (0..m).filter(|&i| grad[i] != 0.0) {
                    b[i] += grad[i] * res;
                    for j in 0..m {
                        a[(i, j)] += grad[i] * grad[j];
                    }
                }
            }
        }
        sse
    };
    let mut u: Vec<f64> = seeds
        .iter()
        .flat_map(|p| [p[0], p[1]])
        .chain(free_scale.then_some(1.0))
        .collect();
    let mut a = DMatrix::zeros(m, m);
    let mut b = DVector::zeros(m);
    let mut sse = evaluate(&u, Some((&mut a, &mut b)));
    let mut lambda = 1e-3;
    for _ in 0..FIT_ITERATIONS {
        let mut damped = a.clone();
        for i in 0..m {
            damped[(i, i)] += lambda * a[(i, i)].max(1e-9);
        }
        let Some(step) = damped.cholesky().map(|c| c.solve(&b)) else {
            lambda *= 10.0;
            continue;
        };
        let trial: Vec<f64> = u.iter().zip(step.iter()).map(|(v, d)| v + d).collect();
        let trial_sse = evaluate(&trial, None);
        if trial_sse < sse {
            u = trial;
            sse = evaluate(&u, Some((&mut a, &mut b)));
            lambda = (lambda * 0.3).max(1e-9);
            if step.rows(0, 2 * k).amax() < FIT_STEP_TOLERANCE {
                break;
            }
        } else {
            lambda *= 10.0;
            if lambda > 1e9 {
                break;
            }
        }
    }
    let pos: Vec<[f64; 2]> = u[..2 * k].chunks_exact(2).map(|c| [c[0], c[1]]).collect();
    // Covariance s² (JᵀJ)⁻¹, with s² the residual variance.
    let dof = pixels.len().saturating_sub(m).max(1) as f64;
    let inverse = a.try_inverse();
    let errors = (0..k)
        .map(|j| {
            inverse.as_ref().map_or(f64::INFINITY, |c| {
                (0.5 * (c[(2 * j, 2 * j)] + c[(2 * j + 1, 2 * j + 1)]) * sse / dof)
                    .max(0.0)
                    .sqrt()
            })
        })
        .collect();
    Fit {
        positions: pos,
        errors,
        sse,
    }
}

/// Most Levenberg-Marquardt iterations of a group's fit.
const FIT_ITERATIONS: usize = 50;
/// A group's fit stops once a step moves no position more than this, px.
const FIT_STEP_TOLERANCE: f64 = 1e-3;

/// Most tracks in one crossing whose orders [`rename_by_motion`] weighs together (4! orders
/// a frame, and pairs of them as its states); a larger crossing is weighed a frame's group
/// at a time.
const MAX_CROSSING_TRACKS: usize = 4;

/// How many times the variance of one acceleration (both axes) the motion must gain before
/// a crossing's points change hands.
const ORDER_SIGNIFICANCE: f64 = 4.0;
/// Floor of the position error behind [`ORDER_SIGNIFICANCE`], px: the fit of overlapping
/// images is not as good as an isolated centroid.
const MIN_POSITION_ERROR: f64 = 0.05;

/// Hands the positions inside each crossing to the tracks whose motion they continue best,
/// and the tracks after it to the particles whose motion they continue.
///
/// A crossing is a run of groups in consecutive frames that share tracks. An order says
/// which track's point each track takes in a frame; it persists from frame to frame, may
/// change only between tracks that shared a group in that frame or the one before, and the
/// order reached in the frame after the crossing holds for the rest of the recording (the
/// continuations are renamed). Of every such sequence, the one with the smallest sum of
/// squared second differences (accelerations, px/frame²) along every track, through its
/// points in the frames before and after, plus the squared distance of each track's first
/// point from its named start where the crossing holds the start frame, is found by dynamic
/// programming over the frames (a state is the orders of two consecutive frames, since an
/// acceleration spans three). It replaces the linker's order where it gains more than the
/// position noise could ([`ORDER_SIGNIFICANCE`]) and the motion explains it. Exchanged
/// continuations take their ambiguity reports with them. Returns the points that changed
/// hands.
fn rename_by_motion(
    points: &mut [TrackPoint],
    groups: &[Group],
    ambiguities: &mut [Ambiguity],
    starts: &Starts<'_>,
) -> usize {
    let mut tracks: std::collections::HashMap<String, Vec<usize>> = std::collections::HashMap::new();
    for (i, p) in points.iter().enumerate() {
        tracks.entry(p.particle.clone()).or_default().push(i);
    }
    for v in tracks.values_mut() {
        v.sort_by_key(|&i| points[i].frame);
    }
    let mut renamed = 0;
    for crossing in crossings(points, groups) {
        match settle_order(points, &mut tracks, groups, &crossing, ambiguities, starts) {
            Some(n) => renamed += n,
            // Too many tracks to weigh every order of: each frame's group on its own.
            None => {
                for g in crossing {
                    renamed +=
                        settle_order(points, &mut tracks, groups, &[g], ambiguities, starts).unwrap_or(0);
                }
            }
        }
    }
    renamed
}

/// The named start positions of the tracks and the frame they hold for.
pub(crate) struct Starts<'a> {
    /// Start position (px) of each named track.
    pub positions: &'a [(String, [f64; 2])],
    /// The frame the start positions are of.
    pub frame: usize,
}

/// Runs of groups (indices into `groups`, in frame order) joined by a shared track in the
/// same or the next frame.
fn crossings(points: &[TrackPoint], groups: &[Group]) -> Vec<Vec<usize>> {
    let mut order: Vec<usize> = (0..groups.len()).collect();
    order.sort_by_key(|&g| points[groups[g].members[0]].frame);
    let mut sets = DisjointSets::new(groups.len());
    // The latest group of each track, by name.
    let mut latest: std::collections::HashMap<&str, usize> = std::collections::HashMap::new();
    for &g in &order {
        let frame = points[groups[g].members[0]].frame;
        for &i in &groups[g].members {
            let name = points[i].particle.as_str();
            if let Some(&h) = latest.get(name) {
                if points[groups[h].members[0]].frame + 1 >= frame {
                    sets.union(g, h);
                }
            }
            latest.insert(name, g);
        }
    }
    let mut runs: std::collections::BTreeMap<usize, Vec<usize>> = std::collections::BTreeMap::new();
    for &g in &order {
        runs.entry(sets.root(g)).or_default().push(g);
    }
    runs.into_values().collect()
}

/// [`rename_by_motion`] for one crossing (`run`: indices into `groups`, frame order);
/// `tracks` holds each track's point indices in frame order and is kept up to date. Returns
/// the points that changed hands, or `None` if the crossing holds more than
/// [`MAX_CROSSING_TRACKS`] tracks.
fn settle_order(
    points: &mut [TrackPoint],
    tracks: &mut std::collections::HashMap<String, Vec<usize>>,
    groups: &[Group],
    run: &[usize],
    ambiguities: &mut [Ambiguity],
    starts: &Starts<'_>,
) -> Option<usize> {
    let mut names: Vec<String> = run
        .iter()
        .flat_map(|&g| groups[g].members.iter().map(|&i| points[i].particle.clone()))
        .collect();
    names.sort();
    names.dedup();
    let k = names.len();
    if k > MAX_CROSSING_TRACKS {
        return None;
    }
    if k < 2 {
        return Some(0);
    }
    let frame_of = |g: usize| points[groups[g].members[0]].frame;
    let first = run.iter().map(|&g| frame_of(g)).min().unwrap_or(0);
    let last = run.iter().map(|&g| frame_of(g)).max().unwrap_or(0);
    // The orders are weighed up to the frame after the crossing (a track may hand back
    // what it took in its last frame), and hold on from there.
    let end = last + 1;
    // Point of each track from two frames before to two after (None where it has none).
    let lo = first.saturating_sub(2);
    let span = end + 2 - lo + 1;
    let at: Vec<Vec<Option<usize>>> = names
        .iter()
        .map(|n| {
            let own = &tracks[n];
            (lo..lo + span)
                .map(|t| {
                    own.binary_search_by_key(&t, |&i| points[i].frame)
                        .ok()
                        .map(|j| own[j])
                })
                .collect()
        })
        .collect();
    let pos = |a: usize, t: usize| at[a][t - lo].map(|i| [points[i].x, points[i].y]);
    // Orders: `perm[a] = b` gives track `a` the position track `b` has now.
    let mut all = Vec::new();
    permutations(k, &mut |p| all.push(p.to_vec()));
    let identity: Vec<usize> = (0..k).collect();
    let id = all.iter().position(|p| *p == identity).unwrap_or(0);
    // Which particle each track holds may change only where tracks meet: from one frame to
    // the next, track `a` may take over the points of another track only if the two shared
    // a group in one of the two frames. Between such changes the order persists, and after
    // the crossing it holds for the rest of the recording.
    let group_of = |t: usize, a: usize| {
        run.iter().copied().find(|&g| {
            groups[g]
                .members
                .iter()
                .any(|&i| points[i].frame == t && points[i].particle == names[a])
        })
    };
    let groups_at: Vec<Vec<Option<usize>>> = (first..=last)
        .map(|t| (0..k).map(|a| group_of(t, a)).collect())
        .collect();
    let meet = |t: usize, b: usize, c: usize| {
        b == c
            || [t.checked_sub(1), Some(t)].into_iter().flatten().any(|u| {
                (first..=last).contains(&u) && {
                    let g = &groups_at[u - first];
                    g[b].is_some() && g[b] == g[c]
                }
            })
    };
    // An order keeps which tracks have a point in a frame (no point is made or lost).
    let keeps_points =
        |t: usize, q: &[usize]| (0..k).all(|a| at[a][t - lo].is_some() == at[q[a]][t - lo].is_some());
    let step_ok = |t: usize, p: &[usize], q: &[usize]| (0..k).all(|a| meet(t, p[a], q[a]));
    let orders_at: Vec<Vec<usize>> = (first..=end)
        .map(|t| (0..all.len()).filter(|&q| keeps_points(t, &all[q])).collect())
        .collect();
    // The order after the crossing renames the tracks' continuations: only tracks seen just
    // after it whose ambiguity reports do not run across its end take part.
    let free_tail = |a: usize| {
        at[a][end + 1 - lo].is_some()
            && !ambiguities
                .iter()
                .any(|e| e.first_frame <= end && e.last_frame > end && e.particles.contains(&names[a]))
    };
    let tail_ok = |q: &[usize]| (0..k).all(|a| q[a] == a || (free_tail(a) && free_tail(q[a])));
    // The named start positions, where the crossing holds their frame.
    let start_of: Vec<Option<[f64; 2]>> = names
        .iter()
        .map(|n| {
            (first..=last)
                .contains(&starts.frame)
                .then(|| starts.positions.iter().find(|(s, _)| s == n).map(|(_, p)| *p))?
        })
        .collect();
    let start_cost = |q: &[usize]| -> f64 {
        (0..k)
            .filter_map(|a| {
                let s = start_of[a]?;
                let x = pos(q[a], starts.frame)?;
                Some(dist2(s, x))
            })
            .sum()
    };
    // Squared accelerations centred at `t` for orders `p`, `q`, `r` at t-1, t, t+1.
    let term = |t: usize, p: &[usize], q: &[usize], r: &[usize]| -> f64 {
        if t < lo + 1 || t + 1 >= lo + span {
            return 0.0;
        }
        let mut c = 0.0;
        for a in 0..k {
            if let (Some(x0), Some(x1), Some(x2)) = (pos(p[a], t - 1), pos(q[a], t), pos(r[a], t + 1)) {
                let (ax, ay) = (x0[0] - 2.0 * x1[0] + x2[0], x0[1] - 2.0 * x1[1] + x2[1]);
                c += ax * ax + ay * ay;
            }
        }
        c
    };
    let at_frame = |t: usize, q: usize| {
        if t == starts.frame {
            start_cost(&all[q])
        } else {
            0.0
        }
    };
    // Dynamic programming over the frames: `cost[(p, q)]` is the least cost of the terms
    // centred before frame `t` with orders p at t-1 and q at t (before the crossing, the
    // linked order).
    type States = std::collections::HashMap<(usize, usize), f64>;
    let mut cost: States = States::new();
    let mut back: Vec<std::collections::HashMap<(usize, usize), usize>> = Vec::new();
    for &q in &orders_at[0] {
        if !step_ok(first, &identity, &all[q]) {
            continue;
        }
        let before = first
            .checked_sub(1)
            .map_or(0.0, |t| term(t, &identity, &identity, &all[q]));
        cost.insert((id, q), before + at_frame(first, q));
    }
    for t in first + 1..=end {
        let mut next = States::new();
        let mut from: std::collections::HashMap<(usize, usize), usize> = std::collections::HashMap::new();
        for (&(p, q), &c) in &cost {
            let pp = if t - 1 == first { &identity } else { &all[p] };
            for &r in &orders_at[t - first] {
                if !step_ok(t, &all[q], &all[r]) {
                    continue;
                }
                let v = c + term(t - 1, pp, &all[q], &all[r]) + at_frame(t, r);
                let e = next.entry((q, r)).or_insert(f64::INFINITY);
                if v < *e {
                    *e = v;
                    from.insert((q, r), p);
                }
            }
        }
        cost = next;
        back.push(from);
    }
    // The end: the last order holds on after the crossing.
    let finish = |(p, q): (usize, usize)| {
        let pp = if end == first { &identity } else { &all[p] };
        term(end, pp, &all[q], &all[q]) + term(end + 1, &all[q], &all[q], &all[q])
    };
    let mut best = (f64::INFINITY, (id, id));
    for (&state, &c) in &cost {
        if !tail_ok(&all[state.1]) {
            continue;
        }
        let v = c + finish(state);
        if v < best.0 {
            best = (v, state);
        }
    }
    let now: f64 = (first.saturating_sub(1)..=end + 1)
        .map(|t| term(t, &identity, &identity, &identity))
        .sum::<f64>()
        + if (first..=last).contains(&starts.frame) {
            start_cost(&identity)
        } else {
            0.0
        };
    // Orders that differ by less than the position noise could make are left as linked: the
    // error of a second difference has variance 6σ² per axis.
    let mut eps: Vec<f64> = at
        .iter()
        .flatten()
        .flatten()
        .map(|&i| points[i].ep)
        .filter(|e| e.is_finite())
        .collect();
    let sigma = if eps.is_empty() {
        MIN_POSITION_ERROR
    } else {
        let mid = eps.len() / 2;
        eps.select_nth_unstable_by(mid, f64::total_cmp)
            .1
            .max(MIN_POSITION_ERROR)
    };
    // And only to an order the motion explains: accelerations within the noise but for one
    // reversal of each track's velocity (a bounce) at most. Where the fitted positions are
    // wrong, no order is smooth, and a smoother one is no evidence.
    let reversals: f64 = (0..k)
        .map(|a| {
            let mut steps: Vec<f64> = (lo..lo + span - 1)
                .filter_map(|t| Some(dist2(pos(a, t)?, pos(a, t + 1)?).sqrt()))
                .collect();
            if steps.is_empty() {
                return 0.0;
            }
            let mid = steps.len() / 2;
            let v = *steps.select_nth_unstable_by(mid, f64::total_cmp).1;
            4.0 * v * v
        })
        .sum();
    let terms = (k * (end - first + 3)) as f64;
    let explained = best.0 <= reversals + ORDER_SIGNIFICANCE * 12.0 * sigma * sigma * terms;
    if !(best.0 < now - ORDER_SIGNIFICANCE * 12.0 * sigma * sigma && explained) {
        return Some(0);
    }
    // The orders, frame by frame, back from the last.
    let (_, (mut p, mut q)) = best;
    let tail = q;
    let mut chosen = vec![id; end - first + 1];
    for t in (first..=end).rev() {
        chosen[t - first] = q;
        if t > first {
            let prev = back[t - first - 1][&(p, q)];
            q = p;
            p = prev;
        }
    }
    let mut renamed = 0;
    for t in first..=end {
        let perm = &all[chosen[t - first]];
        let moved: Vec<Option<TrackPoint>> =
            (0..k).map(|a| at[a][t - lo].map(|i| points[i].clone())).collect();
        for (a, &b) in perm.iter().enumerate() {
            let (true, Some(i), Some(from)) = (a != b, at[a][t - lo], &moved[b]) else {
                continue;
            };
            let p = &mut points[i];
            p.x = from.x;
            p.y = from.y;
            p.mass = from.mass;
            p.size = from.size;
            p.ep = from.ep;
            renamed += 1;
        }
    }
    // Continuations: track `a` takes what track `tail[a]` held after the crossing.
    let tail = &all[tail];
    if *tail != identity {
        let split: Vec<(Vec<usize>, Vec<usize>)> = names
            .iter()
            .map(|n| {
                let own = &tracks[n];
                let cut = own.partition_point(|&i| points[i].frame <= end);
                (own[..cut].to_vec(), own[cut..].to_vec())
            })
            .collect();
        for (a, &b) in tail.iter().enumerate() {
            let mut joined = split[a].0.clone();
            joined.extend(&split[b].1);
            for &i in &split[b].1 {
                points[i].particle.clone_from(&names[a]);
            }
            renamed += usize::from(a != b) * split[b].1.len();
            tracks.insert(names[a].clone(), joined);
        }
        for e in ambiguities.iter_mut().filter(|e| e.first_frame > end) {
            for name in &mut e.particles {
                if let Some(b) = names.iter().position(|n| n == name) {
                    if let Some(a) = tail.iter().position(|&x| x == b) {
                        name.clone_from(&names[a]);
                    }
                }
            }
        }
    }
    Some(renamed)
}

/// Calls `f` with every permutation of `0..k` (Heap's algorithm).
fn permutations(k: usize, f: &mut impl FnMut(&[usize])) {
    fn heap(n: usize, a: &mut [usize], f: &mut impl FnMut(&[usize])) {
        if n <= 1 {
            f(a);
            return;
        }
        for i in 0..n - 1 {
            heap(n - 1, a, f);
            if n % 2 == 0 {
                a.swap(i, n - 1);
            } else {
                a.swap(0, n - 1);
            }
        }
        heap(n - 1, a, f);
    }
    let mut a: Vec<usize> = (0..k).collect();
    heap(k, &mut a, f);
}

#[cfg(test)]
mod tests {
    use super::*;

    /// No named starts.
    const NO_STARTS: Starts<'static> = Starts {
        positions: &[],
        frame: 0,
    };

    /// Fraction of pixel `(x, y)` inside the disc of radius `r` about `c` (16 x 16 samples).
    fn coverage(x: f64, y: f64, c: [f64; 2], r: f64) -> f64 {
        let n = 16;
        let mut inside = 0;
        for i in 0..n {
            for j in 0..n {
                let sx = x - 0.5 + (i as f64 + 0.5) / n as f64;
                let sy = y - 0.5 + (j as f64 + 0.5) / n as f64;
                inside += usize::from(dist2([sx, sy], c) <= r * r);
            }
        }
        inside as f64 / (n * n) as f64
    }

    /// A 64 x 64 signal of discs of radius 4 and amplitude 200, combined by `composition`.
    fn image(discs: &[[f64; 2]], composition: Composition) -> Vec<f32> {
        let mut out = vec![0.0f32; 64 * 64];
        for y in 0..64 {
            for x in 0..64 {
                let covers: Vec<f64> = discs
                    .iter()
                    .map(|&c| coverage(x as f64, y as f64, c, 4.0))
                    .collect();
                let v = match composition {
                    Composition::Sum => covers.iter().sum::<f64>(),
                    Composition::Cover => 1.0 - covers.iter().map(|a| 1.0 - a).product::<f64>(),
                };
                out[y * 64 + x] = (200.0 * v) as f32;
            }
        }
        out
    }

    fn point(frame: usize, name: &str, p: [f64; 2], flag: PointFlag) -> TrackPoint {
        TrackPoint {
            flag,
            ep: 0.01,
            ..TrackPoint::new(frame, name, p[0], p[1])
        }
    }

    /// Two discs 3 px apart (radius 4: most of each covers the other), one particle alone
    /// for the profile; the linked points 1 px off, the second bridged. Both compositions:
    /// the fit puts each within 0.05 px of its disc, and picks the composition of the image.
    #[test]
    fn overlapping_discs_are_placed_where_they_are() {
        let lone = [50.3, 49.6];
        let pair = [[20.2, 30.1], [23.0, 31.2]];
        for composition in [Composition::Sum, Composition::Cover] {
            let signal = image(&[lone, pair[0], pair[1]], composition);
            let signal_of = |_: usize| -> Result<Vec<f32>, TrackError> { Ok(signal.clone()) };
            let blobs = SharedBlobs {
                signal_of: &signal_of,
                width: 64,
                height: 64,
                radius: 4.0,
                window: 5.0,
            };
            let mut points = vec![
                point(0, "lone", lone, PointFlag::Detected),
                point(0, "a", [pair[0][0] + 0.8, pair[0][1] + 0.6], PointFlag::Split),
                point(
                    0,
                    "b",
                    [pair[1][0] - 0.7, pair[1][1] - 0.5],
                    PointFlag::Interpolated,
                ),
            ];
            let starts = Starts {
                positions: &[],
                frame: 0,
            };
            let counts = relocate_shared(&mut points, &mut [], &starts, &blobs).expect("relocate");
            assert_eq!(counts.moved, 2, "{composition:?}");
            for (p, truth) in points[1..].iter().zip(pair) {
                let e = dist2([p.x, p.y], truth).sqrt();
                assert!(e < 0.05, "{composition:?}: {} is {e:.3} px off", p.particle);
                assert!(p.ep.is_finite() && p.ep < 0.05, "{composition:?}: ep {}", p.ep);
            }
            assert_eq!(
                (points[0].x, points[0].y),
                (lone[0], lone[1]),
                "the lone particle stays"
            );
        }
    }

    /// Two particles in straight lines crossing over frames 3-6, each at its true position
    /// but for the linker's exchange from frame 5 on (`swap_tail`) or for frames 4-5 only.
    fn crossing(swap_from: usize, swap_to: usize) -> (Vec<TrackPoint>, Vec<Group>) {
        let path = |k: usize, t: usize| {
            let t = t as f64;
            if k == 0 {
                [10.0 + 2.0 * t, 20.0 + 0.1 * t]
            } else {
                [10.0 + 2.0 * t, 25.0 - 1.2 * t]
            }
        };
        let mut points = Vec::new();
        for t in 0..10 {
            for (k, name) in ["a", "b"].iter().enumerate() {
                let who = if (swap_from..=swap_to).contains(&t) {
                    1 - k
                } else {
                    k
                };
                let flag = if (3..=6).contains(&t) {
                    PointFlag::Split
                } else {
                    PointFlag::Detected
                };
                points.push(point(t, name, path(who, t), flag));
            }
        }
        let groups = (3..=6)
            .map(|t| Group {
                members: vec![2 * t, 2 * t + 1],
                fit: None,
            })
            .collect();
        (points, groups)
    }

    fn names_follow_paths(points: &[TrackPoint]) -> bool {
        // Track "a" has y growing slowly from 20; "b" falls from 25.
        points.iter().all(|p| {
            let a = 20.0 + 0.1 * p.frame as f64;
            let b = 25.0 - 1.2 * p.frame as f64;
            let own = if p.particle == "a" { a } else { b };
            let other = if p.particle == "a" { b } else { a };
            (p.y - own).abs() <= (p.y - other).abs()
        })
    }

    /// Positions exchanged inside the crossing (frames 4-5) go back to their tracks; so do the
    /// continuations exchanged from frame 5 on, with the reports of ambiguities after it.
    #[test]
    fn the_motion_gives_each_track_its_own_positions_and_continuation() {
        let (mut points, groups) = crossing(4, 5);
        assert!(!names_follow_paths(&points));
        let renamed = rename_by_motion(&mut points, &groups, &mut [], &NO_STARTS);
        assert_eq!(renamed, 4);
        assert!(names_follow_paths(&points));

        let (mut points, groups) = crossing(5, 9);
        let mut reports = vec![Ambiguity {
            kind: crate::AmbiguityKind::Missing,
            particles: vec!["a".into()],
            first_frame: 8,
            last_frame: 8,
        }];
        rename_by_motion(&mut points, &groups, &mut reports, &NO_STARTS);
        assert!(names_follow_paths(&points));
        assert_eq!(reports[0].particles, ["b"], "the report follows the continuation");
    }

    /// An exchange smaller than the position noise is left alone.
    #[test]
    fn a_change_within_the_noise_is_not_made() {
        let (mut points, groups) = crossing(4, 5);
        for p in &mut points {
            p.ep = 5.0;
        }
        let before: Vec<(f64, f64)> = points.iter().map(|p| (p.x, p.y)).collect();
        assert_eq!(rename_by_motion(&mut points, &groups, &mut [], &NO_STARTS), 0);
        let after: Vec<(f64, f64)> = points.iter().map(|p| (p.x, p.y)).collect();
        assert_eq!(after, before);
    }

    /// A crossing at the start frame: the named start positions say who is who.
    #[test]
    fn named_starts_decide_a_crossing_at_the_first_frame() {
        // Both start in one blob and part; the linker gave each the other's start point.
        let mut points = Vec::new();
        for t in 0..6 {
            let tf = t as f64;
            let (a, b) = ([30.0 + 2.0 * tf, 30.0], [31.0 + 2.0 * tf, 32.0 + 2.0 * tf]);
            let (pa, pb) = if t == 0 { (b, a) } else { (a, b) };
            let flag = if t < 2 {
                PointFlag::Split
            } else {
                PointFlag::Detected
            };
            points.push(point(t, "a", pa, flag));
            points.push(point(t, "b", pb, flag));
        }
        let groups = (0..2)
            .map(|t| Group {
                members: vec![2 * t, 2 * t + 1],
                fit: None,
            })
            .collect::<Vec<_>>();
        let named = [("a".to_string(), [30.0, 30.0]), ("b".to_string(), [31.0, 32.0])];
        let starts = Starts {
            positions: &named,
            frame: 0,
        };
        rename_by_motion(&mut points, &groups, &mut [], &starts);
        assert_eq!((points[0].x, points[0].y), (30.0, 30.0));
        assert_eq!((points[1].x, points[1].y), (31.0, 32.0));
    }
}
