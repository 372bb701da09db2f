//! Per-thread blob finding and location, with joins of close detections.

use crate::distance::closer_than;
use crate::rim::{encircled, rim_centre, rim_is_closed};
use crate::{
    find_blobs_forming, find_blobs_with_scratch, refine_centroids_with_scratch, Background, BackgroundModel,
    BlobSet, DetectParameters, Detection, Frame, FrameDecoder, FrameView, LocateScratch, Scratch,
};
use std::collections::BTreeMap;

/// One worker thread's buffers, reused from frame to frame: the decoder's and the decoded
/// frame's, and the [`Finder`]'s.
#[derive(Default)]
pub(super) struct Worker {
    pub(super) decoder: FrameDecoder,
    pub(super) frame: Frame,
    pub(super) finder: Finder,
}

/// One thread's buffers for finding and locating a frame's particles: the signal image, the
/// filters' and blob regions' buffers (a frame-sized region map among them) and the
/// centroids'.
#[derive(Default)]
pub(super) struct Finder {
    /// A frame converted to the background's channel count (a grey file among colour ones).
    converted: Frame,
    /// The last frame's signal, gain-corrected.
    pub(super) signal: Vec<f32>,
    detect: Scratch,
    pub(super) locate: LocateScratch,
}

impl Finder {
    /// The blobs of `frame` found with `params` (its signal left in `self.signal`).
    pub(super) fn blobs(
        &mut self,
        background: &Background,
        frame: FrameView<'_>,
        params: &DetectParameters,
    ) -> BlobSet {
        self.find(background, frame, params, false)
    }

    /// [`Finder::blobs`], the signal then gain-corrected when `levelled`. Against a constant
    /// background the gain is one offset, taken out of the signal as it is formed row by row
    /// for the detector's filters; against a per-pixel one a significant gain is taken out
    /// of the whole signal before the blobs are found (its offset follows the background's
    /// own unevenness, which the band-pass does not ignore); centroids are measured in the
    /// gain-corrected signal either way, since a centroid window integrates any offset left
    /// in it.
    pub(super) fn find(
        &mut self,
        background: &Background,
        frame: FrameView<'_>,
        params: &DetectParameters,
        levelled: bool,
    ) -> BlobSet {
        let frame = background.matching(frame, &mut self.converted);
        let (width, height) = frame.size();
        self.signal.resize(width * height, 0.0);
        // Against a constant level the gain is one offset over the frame, taken out before
        // the blobs are found (their noise mask assumes a background at zero); the gain is
        // measured once either way.
        let gain = (background.model == BackgroundModel::Constant).then(|| background.gain_to_remove(frame));
        let offset = gain.flatten().and_then(|g| background.uniform_gain_offset(g));
        // Against a per-pixel background a gain is `(g - 1) u . b`, as uneven as the
        // background: a dark-on-light recording whose exposure rises by a tenth under
        // vignetting loses every particle of its bright frames in the plain signal (sweep
        // style 1009: none found in 7 of 15 frames). It is taken out before the blobs are
        // found, the signal formed whole first.
        if background.model == BackgroundModel::PerPixel {
            if let Some(g) = background.gain_to_remove(frame) {
                background.signal_into(frame, &mut self.signal);
                background.apply_gain(g, &mut self.signal);
                let blobs = find_blobs_with_scratch(&self.signal, width, height, params, &mut self.detect);
                return blobs;
            }
        }
        // Two closures, not one that tests the offset: the plain one stays the one the
        // detector's row loop inlines (with the test in it, N = 10 of the speed benchmark
        // took 12 % more instructions).
        let blobs = match offset {
            None if background.blind.is_empty() => find_blobs_forming(
                &mut self.signal,
                width,
                height,
                params,
                &mut self.detect,
                |pixels, out| background.signal_range(frame, pixels, out),
            ),
            Some(o) if background.blind.is_empty() => find_blobs_forming(
                &mut self.signal,
                width,
                height,
                params,
                &mut self.detect,
                |pixels, out| {
                    background.signal_range(frame, pixels, out);
                    for v in out.iter_mut() {
                        *v -= o;
                    }
                },
            ),
            _ => {
                // Blind pixels are filled from their neighbours, so the signal is formed whole
                // first.
                background.signal_into(frame, &mut self.signal);
                find_blobs_with_scratch(&self.signal, width, height, params, &mut self.detect)
            }
        };
        if levelled && offset.is_none() {
            if let Some(g) = gain.unwrap_or_else(|| background.gain_to_remove(frame)) {
                background.apply_gain(g, &mut self.signal);
            }
        }
        blobs
    }

    /// The gain-corrected signal of `frame` alone, without finding its blobs (left in
    /// `self.signal`, as [`Finder::find`] leaves it).
    pub(super) fn levelled_signal(&mut self, background: &Background, frame: FrameView<'_>) {
        background.signal_into(frame, &mut self.signal);
        background.remove_gain(frame, &mut self.signal);
    }

    /// Centroid estimates started at `seeds` (px; `areas` their blobs' areas, px²) in the
    /// last signal [`Finder::find`] left, `size` its width and height, each in a window of
    /// radius `window` (px), pixels nearer another estimate left out of each (see
    /// [`refine_centroids_with_scratch`]), under pixel noise `noise` (grey levels).
    pub(super) fn centroids(
        &mut self,
        size: (usize, usize),
        seeds: &[[f64; 2]],
        areas: &[f64],
        window: f64,
        noise: f64,
    ) -> Vec<Detection> {
        refine_centroids_with_scratch(
            &self.signal,
            size.0,
            size.1,
            seeds,
            areas,
            window,
            noise,
            &mut self.locate,
        )
    }

    /// The particles of `frame`: its [`Finder::blobs`], each located by the centroid in a
    /// window of radius `window` (px) of the gain-corrected signal, estimates that end within
    /// a radius of each other joined as `parts` says, then, with a `plane_reach` (px), each
    /// located again with the local background taken out, its window reaching at most that
    /// far (`super::plane`; after joining, not with [`Parts::Keep`]).
    pub(super) fn locate(
        &mut self,
        background: &Background,
        frame: FrameView<'_>,
        params: &DetectParameters,
        window: f64,
        parts: Parts,
        plane_reach: Option<f64>,
    ) -> Vec<Detection> {
        let blobs = self.find(background, frame, params, true).blobs;
        let seeds: Vec<[f64; 2]> = blobs.iter().map(|b| [b.x as f64, b.y as f64]).collect();
        let areas: Vec<f64> = blobs.iter().map(|b| b.area).collect();
        let (width, height) = frame.size();
        let noise = background.noise_sigma;
        let mut found = self.centroids((width, height), &seeds, &areas, window, noise);
        if parts == Parts::Keep {
            return found;
        }

        // Joined estimates move, and may then end within a radius of another: joined again,
        // a few rounds at most (each round leaves fewer estimates). One round left a ring of
        // 9 px 0.62 / 0.98 px RMS off (test `rings_beside_neighbours_are_not_split_between_them`,
        // seed 3002; 0.09 / 0.15 with more). Each round locates every estimate of the frame
        // again: on pendulum-scale, with its dial and text, the rounds add 8 % to the
        // instructions (one round 7 %).
        // Estimates up to two radii apart are the arcs of one ring where a closed rim is found
        // about their midpoint, holding both (see [`join_close`]).
        let reach = super::rims::rim_reach(params.radius);
        for _ in 0..JOIN_ROUNDS {
            let signal = &self.signal;
            let arcs = |a: [f64; 2], b: [f64; 2]| {
                let mid = [0.5 * (a[0] + b[0]), 0.5 * (a[1] + b[1])];
                encircled(signal, width, height, mid, reach)
                    && rim_centre(signal, width, height, mid, &[], reach, noise).is_some_and(|rim| {
                        let c = [mid[0] + rim.offset[0], mid[1] + rim.offset[1]];
                        [a, b]
                            .iter()
                            .all(|p| (p[0] - c[0]).hypot(p[1] - c[1]) < rim.radius)
                            && rim_is_closed(signal, width, height, c, rim.radius)
                    })
            };
            let Some((seeds, areas)) = join_close(&found, params.radius, arcs) else {
                break;
            };
            found = self.centroids((width, height), &seeds, &areas, window, noise);
        }
        if let Some(most) = plane_reach {
            let noise = super::plane::Noise::of(background);
            super::plane::correct_for_planes(&self.signal, width, height, &mut found, window, most, noise);
        }
        found
    }
}

/// What [`Finder::locate`] does with centroid estimates that end closer than a radius to
/// each other.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Parts {
    /// Joined and located again as one ([`join_close`]): the frames of the recording.
    Join,
    /// Kept apart: the size estimate's rounds ([`estimate_radius`]). Joined there, the rim
    /// halves of a thin ring measure as one ring and the size comes out right (8.12 px for
    /// the sweep's rings of radius 6.45 px, style 1002, against 3.48 from the halves); but
    /// at that size the band-pass also answers between two rings' near rims, a centroid
    /// started there takes part of a ring and ends beyond a radius of the ring's own, and
    /// the style came out with 13 of its 140 points lost and 0.75 px RMS, tracks written.
    /// At 3.48 px the skirt check refuses it, the honest outcome until those answers are
    /// told apart.
    Keep,
}

/// What [`Finder::locate`] does with the background left around each particle.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Surround {
    /// Nothing: the signal against the background model is taken as it is.
    Ignore,
    /// Each estimate is located again in a window reaching as far as its particle does, on
    /// the signal with a plane fitted just beyond taken out (`super::plane`).
    Plane,
}

/// Radii within which two estimates may be arcs of one ring ([`join_close`]): two disjoint
/// particles of one size lie two radii apart or more.
const ARC_SPAN: f64 = 2.0;

/// Most rounds of joining estimates that converged within a radius of each other.
const JOIN_ROUNDS: usize = 4;

/// Seeds (and blob areas) for locating `found` again with the estimates that converged
/// closer than `radius` to each other joined into one, and those closer than [`ARC_SPAN`]
/// radii that `arcs` says are arcs of one ring (a closed rim found about their midpoint,
/// holding both), each group seeded at its mass-weighted mean; `None` when no two were joined.
/// A ring wider than the radius in use is found as two or three arcs whose centroids lie
/// 1.3-1.4 of the ring's radius apart (`2 ρ / π` and `0.83 ρ` from its centre): fresh style
/// 6717, a clean ring of 33 px, was found as three arcs 40.6 px apart at a radius of 40.4
/// px, its track followed one of them and was refused. The detector keeps no two maxima closer than a radius (one
/// particle's band-pass answer); two that end that close took one particle's light between
/// them. A thin ring whose neighbour's rim lies near its own answers the band-pass between
/// the two near rims too, and the centroid started there takes half the ring while the one
/// started at its centre takes the other half: each half's centroid lies `2 r / pi` from
/// the centre (3.7 px for a ring of radius 6.45 px, 3.9 px from the truth in the sweep's
/// style 1002).
pub(super) fn join_close(
    found: &[Detection],
    radius: f64,
    arcs: impl Fn([f64; 2], [f64; 2]) -> bool,
) -> Option<(Vec<[f64; 2]>, Vec<f64>)> {
    let n = found.len();
    let mut order: Vec<usize> = (0..n).collect();
    order.sort_by(|&a, &b| found[a].x.total_cmp(&found[b].x));
    let mut sets = crate::disjoint_sets::DisjointSets::new(n);
    let mut any = false;
    for (k, &i) in order.iter().enumerate() {
        for &j in &order[k + 1..] {
            if found[j].x - found[i].x >= ARC_SPAN * radius {
                break;
            }
            let (dx, dy) = (found[j].x - found[i].x, found[j].y - found[i].y);
            // `hypot`'s answer, without the library call where it is plain (311 k calls,
            // 17 M instructions at N = 1000, 40 frames).
            let joined = if closer_than(dx, dy, radius) {
                true
            } else {
                closer_than(dx, dy, ARC_SPAN * radius)
                    && arcs([found[i].x, found[i].y], [found[j].x, found[j].y])
            };
            if joined {
                sets.union(i, j);
                any = true;
            }
        }
    }
    if !any {
        return None;
    }
    // Every located estimate has a positive mass ([`refine_centroids_with_scratch`] drops
    // the others): each group's seed is its mass-weighted mean, its blob area the sum.
    let mut groups: BTreeMap<usize, ([f64; 3], f64)> = BTreeMap::new();
    for (i, d) in found.iter().enumerate() {
        let g = groups.entry(sets.root(i)).or_insert(([0.0; 3], 0.0));
        g.0[0] += d.mass * d.x;
        g.0[1] += d.mass * d.y;
        g.0[2] += d.mass;
        g.1 += d.area;
    }
    let (seeds, areas) = groups
        .into_values()
        .map(|(sum, area)| ([sum[0] / sum[2], sum[1] / sum[2]], area))
        .unzip();
    Some((seeds, areas))
}

/// Idle workers, handed out to each frame's job and taken back after: their frame-sized
/// buffers are allocated once per thread for the whole recording, not once per stage or per
/// rayon job (a fresh megabyte is page-faulted in again, as costly as filtering a frame).
#[derive(Default)]
pub(super) struct Workers(std::sync::Mutex<Vec<Worker>>);

impl Workers {
    /// `f` run with an idle worker (a new one when none is idle).
    pub(super) fn with<R>(&self, f: impl FnOnce(&mut Worker) -> R) -> R {
        let mut w = self.idle().pop().unwrap_or_default();
        let out = f(&mut w);
        self.idle().push(w);
        out
    }

    fn idle(&self) -> std::sync::MutexGuard<'_, Vec<Worker>> {
        // A job that panicked took its worker with it; the list itself is intact.
        self.0.lock().unwrap_or_else(std::sync::PoisonError::into_inner)
    }
}
pub(super) use crate::locate::locate_window;
