//! A track being linked: its points, motion anchors, predictions and bridged runs.

use super::options::{diagonal, FrameDetections, LinkOptions};
use super::{CLEAN_ANCHOR_AGE, GATE_SIGMAS, RESIDUAL_RATE};
use crate::appearance::{Appearance, AppearanceHistory, AppearanceLevels};
use crate::locate::Detection;
use crate::point_grid::PointGrid;
use crate::track_table::PointFlag;

#[derive(Clone, Debug)]
pub(super) struct Point {
    pub(super) x: f64,
    pub(super) y: f64,
    pub(super) mass: f64,
    pub(super) size: f64,
    pub(super) ep: f64,
    pub(super) flag: PointFlag,
    /// Written to the table (false while outside the image or lost).
    pub(super) emit: bool,
    /// Located from a blob with no other detection near enough to share its light.
    pub(super) clean: bool,
}

/// The indices into a track's points that its motion is extrapolated from (see
/// [`Track::anchors`]): the first `len` of `at`, newest first.
#[derive(Clone, Copy, Debug, Default)]
struct Anchors {
    pub(super) at: [usize; 3],
    pub(super) len: usize,
}

/// A track's extrapolations to the next frame (see [`Track::extrapolations`]).
#[derive(Clone, Copy, Debug)]
pub(super) struct Extrapolations {
    /// The newest anchor, an index into the track's points.
    newest: Option<usize>,
    /// Constant position, velocity and acceleration, px (`None` without enough anchors).
    orders: [Option<[f64; 2]>; 3],
}

/// Where a track's particle is expected in the next frame.
#[derive(Clone, Copy, Debug)]
pub(super) struct Prediction {
    /// The predicted position, px.
    pub(super) at: [f64; 2],
    /// The prediction's scale (one standard deviation of its error), px.
    pub(super) scale: f64,
    /// The extrapolations it was chosen from, which the observation then grades.
    pub(super) ahead: Extrapolations,
    /// Residuals the scale was learned from (0 while it is the track's first guess).
    pub(super) learned: u32,
    /// How far the particle can have gone from the prediction, px: twice the recording's
    /// step bound for each frame since the newest anchor, plus a diameter (infinite while
    /// the recording has no step bound yet).
    pub(super) reach: f64,
}

impl Prediction {
    /// A gate (px) as sure to hold the particle as [`GATE_SIGMAS`] scales would be if the
    /// scale were known, for a scale learned from [`Prediction::learned`] residuals, and no
    /// wider than [`Prediction::reach`]. The squared distance over twice the learned squared
    /// scale is F(2, ν)-distributed, ν being twice the residuals' effective number under the
    /// running mean's weights; its tail at `f` is `(1 + 2f/ν)^(−ν/2)`, equal to the known
    /// scale's `exp(−G²/2)` at `2f = ν (exp(G²/ν) − 1)`. One residual gives 77 scales, two
    /// 19, three 10, and many 5.9 (the running mean weighs about 5.7 residuals). A first
    /// guess (no residual) is left at [`GATE_SIGMAS`]: it is not learned from the track.
    pub(super) fn learned_gate(&self) -> f64 {
        if self.learned == 0 || !self.reach.is_finite() {
            return GATE_SIGMAS * self.scale;
        }
        // Σ w² of the running mean after n residuals: the first weighs (1 − a)^(n − 1), the
        // k-th from the newest a (1 − a)^k.
        // (Beyond 64 residuals the first one's weight is nil in double precision.)
        let keep = (1.0 - RESIDUAL_RATE).powi(2 * (self.learned.min(64) as i32 - 1));
        let sum_w2 =
            keep + RESIDUAL_RATE * RESIDUAL_RATE * (1.0 - keep) / (1.0 - (1.0 - RESIDUAL_RATE).powi(2));
        let nu = 2.0 / sum_w2;
        let g = (nu * (GATE_SIGMAS * GATE_SIGMAS / nu).exp_m1()).sqrt();
        (g * self.scale).min(self.reach).max(GATE_SIGMAS * self.scale)
    }
}

#[derive(Clone, Debug)]
pub(super) struct Track {
    pub(super) name: String,
    pub(super) first_frame: usize,
    /// One point per frame from `first_frame`, contiguous.
    pub(super) points: Vec<Point>,
    pub(super) misses: usize,
    /// Points located in frames (detected or split), not bridged.
    pub(super) seen: usize,
    /// Consecutive frames, up to the last, in which the track shared a blob.
    pub(super) merged: usize,
    /// Running mean squared one-frame-ahead residuals of the constant position, constant
    /// velocity and constant acceleration predictions, px².
    err_cp: Option<f64>,
    err_cv: Option<f64>,
    err_ca: Option<f64>,
    /// Residuals learned by the constant position, velocity and acceleration predictions.
    learned: [u32; 3],
    /// Prediction scale before any velocity is known, px.
    init_scale: f64,
    pub(super) ended: bool,
    /// Appearance of each located point, with its frame.
    pub(super) apps: AppearanceHistory,
}

/// Residuals of its own the constant acceleration prediction needs before a track uses it.
const CA_RESIDUALS: u32 = 2;

impl Track {
    pub(super) fn new(name: String, frame: usize, p: Point, init_scale: f64) -> Track {
        let seen = usize::from(p.flag != PointFlag::Interpolated);
        Track {
            name,
            first_frame: frame,
            points: vec![p],
            misses: 0,
            seen,
            merged: 0,
            err_cp: None,
            err_cv: None,
            err_ca: None,
            learned: [0; 3],
            init_scale,
            ended: false,
            apps: AppearanceHistory::default(),
        }
    }

    fn pos(&self, back: usize) -> [f64; 2] {
        let p = &self.points[self.points.len() - 1 - back];
        [p.x, p.y]
    }

    /// The points motion is extrapolated from: the latest located from the particle's own
    /// blob (split and bridged points are placed from predictions and carry no news),
    /// preferring those no other detection was near enough to share light with, as long as
    /// the newest of them is recent. Indices into `points`, newest first, at most three.
    fn anchors(&self) -> Anchors {
        let detected = |p: &Point| p.flag == PointFlag::Detected;
        let newest = self.points.iter().rposition(detected);
        let latest = |keep: &dyn Fn(&Point) -> bool| {
            let mut found = Anchors::default();
            for i in (0..self.points.len()).rev() {
                if found.len == found.at.len() {
                    break;
                }
                if keep(&self.points[i]) {
                    found.at[found.len] = i;
                    found.len += 1;
                }
            }
            found
        };
        let clean = latest(&|p| detected(p) && p.clean);
        match newest {
            Some(n) if clean.len >= 2 && clean.at[0] + CLEAN_ANCHOR_AGE >= n => clean,
            Some(_) => latest(&detected),
            None => Anchors::default(),
        }
    }

    pub(super) fn at(&self, i: usize) -> [f64; 2] {
        let p = &self.points[i];
        [p.x, p.y]
    }

    /// Polynomial extrapolations (Lagrange) through the first 1, 2 and 3 of the track's
    /// [`Track::anchors`] to the next frame: constant position, constant velocity and
    /// constant acceleration (`None` where there are too few anchors), px.
    fn extrapolations(&self) -> Extrapolations {
        let anchors = self.anchors();
        let knots = anchors
            .at
            .map(|i| (i as f64, self.points.get(i).map_or([0.0; 2], |p| [p.x, p.y])));
        let next = self.points.len() as f64;
        Extrapolations {
            newest: (anchors.len > 0).then_some(anchors.at[0]),
            orders: [1, 2, 3].map(|k| (anchors.len >= k).then(|| lagrange(&knots[..k], next))),
        }
    }

    /// Predicted position and prediction scale (px) for the next frame. With a bound on
    /// one frame's displacement (`step`, px), the gate (`GATE_SIGMAS` scales) reaches no
    /// farther than the particle can have gone since its newest anchor, twice over (its
    /// velocity may have reversed), plus a particle diameter: a track whose residuals grew
    /// from a wrong link, or over a long merge, cannot reach across the frame.
    pub(super) fn predict(&self, floor: f64, step: Option<f64>, radius: f64) -> Prediction {
        let grow = 1.0 + (self.misses + self.merged) as f64;
        let ahead = self.extrapolations();
        let n = self.points.len();
        let newest = ahead.newest.unwrap_or(n - 1);
        // The errors were learned one frame ahead. Extrapolated `h` frames, the noise of
        // the quadratic term grows by about `h²` more than that of the line, so constant
        // acceleration is used across a gap only if it was that much better. Constant
        // position wins where the track's own residuals say the motion is a random walk
        // (a velocity extrapolated from random steps overshoots by a step on average).
        let h = (n - newest) as f64;
        // Constant velocity until it has a residual of its own, then the best of the three;
        // constant acceleration only once it has [`CA_RESIDUALS`] of them (one residual is
        // no measure of a motion: a random walk's extrapolation fell 0.8 px from a step of
        // 7.6 px, and the track, gated by that, lost its next step of 13 px).
        let order = match (self.err_cp, self.err_cv, self.err_ca) {
            (Some(c), Some(v), a) => {
                let a = a
                    .filter(|_| self.learned[2] >= CA_RESIDUALS)
                    .map_or(f64::INFINITY, |a| a * h * h);
                if a < v && a < c {
                    3
                } else if c < v {
                    1
                } else {
                    2
                }
            }
            _ => 2,
        };
        let err = [self.err_cp, self.err_cv, self.err_ca][order - 1];
        let (p, scale, learned) = match (ahead.orders[order - 1], err) {
            (Some(p), Some(e)) => (p, e.sqrt().max(floor) * grow, self.learned[order - 1]),
            (Some(p), None) => (p, self.init_scale.max(floor) * grow, 0),
            _ => (self.at(newest), self.init_scale.max(floor) * grow, 0),
        };
        let reach = step.map_or(f64::INFINITY, |step| 2.0 * h * step + 2.0 * radius);
        let scale = if reach.is_finite() {
            scale.min(reach / GATE_SIGMAS).max(floor)
        } else {
            scale
        };
        Prediction {
            at: p,
            scale,
            ahead,
            learned,
            reach,
        }
    }

    /// Updates the running prediction errors with an observation for the next frame, given
    /// the extrapolations to that frame (from its [`Track::predict`]).
    pub(super) fn learn(&mut self, obs: [f64; 2], ahead: &Extrapolations) {
        let upd = |e: &mut Option<f64>, p: Option<[f64; 2]>| {
            if let Some(p) = p {
                let r2 = (obs[0] - p[0]).powi(2) + (obs[1] - p[1]).powi(2);
                *e = Some(match *e {
                    Some(old) => (1.0 - RESIDUAL_RATE) * old + RESIDUAL_RATE * r2,
                    None => r2,
                });
            }
        };
        let [cp, cv, ca] = ahead.orders;
        upd(&mut self.err_cp, cp);
        upd(&mut self.err_cv, cv);
        upd(&mut self.err_ca, ca);
        for (n, p) in self.learned.iter_mut().zip(ahead.orders) {
            *n = n.saturating_add(u32::from(p.is_some()));
        }
    }
}
pub(super) fn point_from(d: &Detection, flag: PointFlag, crowded: bool) -> Point {
    Point {
        x: d.x,
        y: d.y,
        mass: d.mass,
        size: d.size,
        ep: d.fixed_point_error(),
        flag,
        emit: true,
        clean: !crowded,
    }
}
pub(super) fn speed(tr: &Track) -> f64 {
    if tr.points.len() < 2 {
        return 0.0;
    }
    let (a, b) = (tr.pos(0), tr.pos(1));
    (a[0] - b[0]).hypot(a[1] - b[1])
}
/// Starts a track at each detection of `fd` not `taken`, its appearance relative to the
/// frame's level in `levels`.
pub(super) fn start_tracks(
    tracks: &mut Vec<Track>,
    fd: &FrameDetections,
    levels: &AppearanceLevels,
    taken: &[bool],
    floor: f64,
    o: &LinkOptions,
    shares: f64,
) {
    // Most frames start no track (every detection is taken): the neighbour search is only
    // built for the others.
    if taken.iter().all(|&t| t) {
        return;
    }
    let pts: Vec<[f64; 2]> = fd.detections.iter().map(|d| [d.x, d.y]).collect();
    let grid = PointGrid::new(&pts);
    for (j, d) in fd.detections.iter().enumerate() {
        if taken[j] {
            continue;
        }
        let nn = grid.nearest_other(&pts[j]);
        // The first step is gated by the whole way to the nearest other blob: two
        // neighbours' first steps then compete in the assignment, which gives each blob to
        // the nearer. Gated by half the way, discs in Brownian motion stepping farther lost
        // their first step, and their tracks, extrapolated, took other discs' blobs (40
        // discs of 1.5-4 px at steps of 0.3-1.0 of (R + 1) a frame per axis: 199 identity
        // switches in 12 recordings, against 25 for linking each to the nearest blob; 14 since).
        // A named track's first step is gated more narrowly (`Linker::first_step_reach`):
        // there the blobs beside it are nobody's tracks, and nothing competes for them.
        let init = nn.min(diagonal(o)) / GATE_SIGMAS;
        let name = tracks.len().to_string();
        let mut track = Track::new(
            name,
            fd.frame,
            point_from(d, PointFlag::Detected, nn < shares),
            init.max(floor),
        );
        if let (Some(a), false) = (Appearance::of(d, 1), d.clipped) {
            track.apps.push(fd.frame, levels.apply(a, fd.frame));
        }
        tracks.push(track);
    }
}

/// Replaces each run of bridged points that has seen points on both sides by the cubic
/// through the two seen points before and the two after (or the line, when only one is
/// available on a side).
pub(super) fn smooth_bridges(tr: &mut Track) {
    let n = tr.points.len();
    let seen = |p: &Point| p.flag != PointFlag::Interpolated;
    let mut i = 0;
    while i < n {
        if seen(&tr.points[i]) {
            i += 1;
            continue;
        }
        let start = i;
        while i < n && !seen(&tr.points[i]) {
            i += 1;
        }
        if start == 0 || i == n {
            continue;
        }
        let mut knots: Vec<(f64, [f64; 2])> = Vec::new();
        for k in [start.checked_sub(2), Some(start - 1), Some(i), Some(i + 1)]
            .into_iter()
            .flatten()
        {
            if k < n && seen(&tr.points[k]) {
                knots.push((k as f64, [tr.points[k].x, tr.points[k].y]));
            }
        }
        for k in start..i {
            let v = lagrange(&knots, k as f64);
            let p = &mut tr.points[k];
            p.x = v[0];
            p.y = v[1];
        }
    }
}

fn lagrange(knots: &[(f64, [f64; 2])], t: f64) -> [f64; 2] {
    let mut out = [0.0, 0.0];
    for (a, (ta, pa)) in knots.iter().enumerate() {
        let mut w = 1.0;
        for (b, (tb, _)) in knots.iter().enumerate() {
            if a != b {
                w *= (t - tb) / (ta - tb);
            }
        }
        out[0] += w * pa[0];
        out[1] += w * pa[1];
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The gate of a scale learned from 1, 2, 3 and many residuals (77, 19, 10 and 5.9
    /// scales), never narrower than the known scale's, capped by the reach, and left at the
    /// known scale's for a first guess or without a step bound.
    #[test]
    fn a_scale_learned_from_few_residuals_gets_a_wider_gate() {
        let gate = |learned: u32, reach: f64| {
            Prediction {
                at: [0.0; 2],
                scale: 1.0,
                ahead: Extrapolations {
                    newest: None,
                    orders: [None; 3],
                },
                learned,
                reach,
            }
            .learned_gate()
        };
        for (n, expected) in [(1, 77.20), (2, 18.80), (3, 10.07), (100, 5.93)] {
            let g = gate(n, 1e9);
            assert!((g - expected).abs() < 0.01, "{n} residuals: {g}");
        }
        assert!((gate(1, 20.0) - 20.0).abs() < 1e-12, "capped by the reach");
        assert!(
            (gate(100, 1.0) - GATE_SIGMAS).abs() < 1e-12,
            "never under the known gate"
        );
        assert!((gate(0, 1e9) - GATE_SIGMAS).abs() < 1e-12, "a first guess");
        assert!(
            (gate(2, f64::INFINITY) - GATE_SIGMAS).abs() < 1e-12,
            "no step bound"
        );
    }
}
