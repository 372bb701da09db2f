//! Linking: detections of successive frames joined into trajectories.
//!
//! A key design decision made in this module is that identity is never guessed silently.
//! Each frame, every live track predicts where its particle is (constant position, then
//! constant velocity, then constant acceleration once the track's own history shows that
//! model predicts better), with a prediction scale learned from the track's past
//! prediction residuals. Motion is extrapolated (Lagrange polynomial through the latest two
//! or three anchors) from points located from the particle's own blob, preferring those no
//! other tracked particle was near enough to share light with (a soft Voronoi split pulls
//! touching particles' centroids), as long as the newest of them is recent. Candidate
//! detections within a gate of that scale come from a kd-tree, and tracks are assigned to
//! detections by optimal assignment over the whole frame (Hungarian method on each
//! connected group of competing tracks), never greedily.
//!
//! Appearance tells a particle from untracked objects: a track with no other track's
//! prediction within reach compares each candidate's log mass and size with its own recent
//! ones, in units of their measured frame-to-frame spreads ([`crate::TrackAppearance`]).
//! The squared standardised changes add to the cost, and a candidate whose combined change
//! (square root of their sum) exceeds [`APPEARANCE_GATE_SIGMAS`] (twice that in the second
//! chance, whose position gate is also doubled) is another object: the hand that threw the
//! ball, or the ball's reflection in the floor.
//!
//! A blob may hold several particles: its mass, compared with a single particle's, says
//! how many tracks it can take, and a track whose prediction falls inside a blob already
//! taken joins it. The particles of a merged blob are placed at the blob's centroid plus
//! their predicted offsets from the group's mean (flag `split`). A track that finds
//! nothing is bridged with its prediction (flag `interpolated`); once it is found again,
//! the bridged points are replaced by a cubic through the detected points on either side.
//! Each bridged or merged run is reported as an [`Ambiguity`] with its frames and tracks.
//!
//! With named start positions (a structure), exactly those particles are followed for the
//! whole window: unmatched detections never start tracks, and a track is never dropped
//! while it is in the image. Without them, every unmatched detection starts a track named
//! by an integer, and tracks unseen for more than `memory` frames end.

use crate::appearance::{Appearance, AppearanceHistory, AppearanceSpread, TrackAppearance};
use crate::assignment::{solve_sparse, SparseProblem};
use crate::locate::Detection;
use crate::point_grid::{nearest_other, PointGrid};
use crate::track_table::{PointFlag, TrackPoint, TrackTable};
use physfit_tracks::stats::{median_upper, robust_spread_upper};

mod settle;
mod step_bound;

use settle::settle_crossings;
use step_bound::StepBound;

/// Gate half-width in units of a track's prediction scale.
const GATE_SIGMAS: f64 = 4.0;
/// Weight of the newest residual in a track's running mean squared prediction error.
const RESIDUAL_RATE: f64 = 0.3;
/// A candidate whose log mass or size differs from the track's latest by more than this
/// many of the measured frame-to-frame spreads is another object (a hand, a reflection).
/// The spreads are robust (median-based) estimates and real features have heavier tails
/// than a normal distribution, hence one more than the position gate.
pub const APPEARANCE_GATE_SIGMAS: f64 = GATE_SIGMAS + 1.0;
/// Frames a track may rely on older uncrowded points for its motion before it falls back
/// on crowded ones (a particle that stays near another for longer moves on its own).
const CLEAN_ANCHOR_AGE: usize = 3;

/// The detections of one frame.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct FrameDetections {
    /// 0-based frame index (the file's index in natural name order).
    pub frame: usize,
    /// Detections, any order.
    pub detections: Vec<Detection>,
}

/// What linking needs to know.
#[derive(Clone, Debug, PartialEq)]
pub struct LinkOptions {
    /// Named particles and their approximate positions in the first frame, px; `None`
    /// tracks every detection under an integer name.
    pub named_start: Option<Vec<(String, [f64; 2])>>,
    /// Expected particle radius, px.
    pub radius: f64,
    /// Frame width, px.
    pub width: usize,
    /// Frame height, px.
    pub height: usize,
    /// Frames a track may go unseen before it ends (unnamed) or stops being bridged (named).
    pub memory: usize,
}

/// What kind of ambiguity a run of frames held.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum AmbiguityKind {
    /// The particles shared one blob; their positions were split from it.
    Merged,
    /// The particle was not seen; its position was bridged from its motion.
    Missing,
    /// The particle was outside the image or lost; no position was written.
    Lost,
}

/// A run of frames where tracking was ambiguous for some particles.
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
pub struct Ambiguity {
    /// What happened.
    pub kind: AmbiguityKind,
    /// The tracks involved.
    pub particles: Vec<String>,
    /// First frame of the run.
    pub first_frame: usize,
    /// Last frame of the run (inclusive).
    pub last_frame: usize,
}

impl std::fmt::Display for Ambiguity {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let what = match self.kind {
            AmbiguityKind::Merged => "shared one blob (positions split from it)",
            AmbiguityKind::Missing => "not seen (bridged from its motion)",
            AmbiguityKind::Lost => "outside the image or lost (no positions written)",
        };
        let frames = if self.first_frame == self.last_frame {
            format!("frame {}", self.first_frame)
        } else {
            format!("frames {}-{}", self.first_frame, self.last_frame)
        };
        write!(f, "{frames}: {} {what}", self.particles.join(", "))
    }
}

/// The trajectories and what linking had to bridge.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct LinkOutcome {
    /// One point per track per frame it was followed.
    pub table: TrackTable,
    /// Every ambiguity bridged, in frame order.
    pub ambiguities: Vec<Ambiguity>,
    /// Human-readable warnings (unmatched named particles, particles that left the image).
    pub warnings: Vec<String>,
}

#[derive(Clone, Debug)]
struct Point {
    x: f64,
    y: f64,
    mass: f64,
    size: f64,
    ep: f64,
    flag: PointFlag,
    /// Written to the table (false while outside the image or lost).
    emit: bool,
    /// Located from a blob with no other detection near enough to share its light.
    clean: bool,
}

/// The indices into a track's points that its motion is extrapolated from (see
/// [`Track::anchors`]): the first `len` of `at`, newest first.
#[derive(Clone, Copy, Debug, Default)]
struct Anchors {
    at: [usize; 3],
    len: usize,
}

/// A track's extrapolations to the next frame (see [`Track::extrapolations`]).
#[derive(Clone, Copy, Debug)]
struct Extrapolations {
    /// The newest anchor, an index into the track's points.
    newest: Option<usize>,
    /// Constant position, velocity and acceleration, px (`None` without enough anchors).
    orders: [Option<[f64; 2]>; 3],
}

/// Where a track's particle is expected in the next frame.
#[derive(Clone, Copy, Debug)]
struct Prediction {
    /// The predicted position, px.
    at: [f64; 2],
    /// The prediction's scale (one standard deviation of its error), px.
    scale: f64,
    /// The extrapolations it was chosen from, which the observation then grades.
    ahead: Extrapolations,
}

#[derive(Clone, Debug)]
struct Track {
    name: String,
    first_frame: usize,
    /// One point per frame from `first_frame`, contiguous.
    points: Vec<Point>,
    misses: usize,
    /// Points located in frames (detected or split), not bridged.
    seen: usize,
    /// Consecutive frames, up to the last, in which the track shared a blob.
    merged: usize,
    /// Running mean squared one-frame-ahead residuals of the constant position, constant
    /// velocity and constant acceleration predictions, px².
    err_cp: Option<f64>,
    err_cv: Option<f64>,
    err_ca: Option<f64>,
    /// Prediction scale before any velocity is known, px.
    init_scale: f64,
    ended: bool,
    /// Appearance of each located point, with its frame.
    apps: AppearanceHistory,
}

impl Track {
    fn new(name: String, frame: usize, p: Point, init_scale: f64) -> Track {
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

    fn at(&self, i: usize) -> [f64; 2] {
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
    fn predict(&self, floor: f64, step: Option<f64>, radius: f64) -> Prediction {
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
        // Constant velocity until it has a residual of its own, then the best of the three.
        let order = match (self.err_cp, self.err_cv, self.err_ca) {
            (Some(c), Some(v), a) => {
                let a = a.map_or(f64::INFINITY, |a| a * h * h);
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
        let (p, scale) = match (ahead.orders[order - 1], err) {
            (Some(p), Some(e)) => (p, e.sqrt().max(floor) * grow),
            (Some(p), None) => (p, self.init_scale.max(floor) * grow),
            _ => (self.at(newest), self.init_scale.max(floor) * grow),
        };
        let scale = match step {
            Some(step) => scale
                .min((2.0 * h * step + 2.0 * radius) / GATE_SIGMAS)
                .max(floor),
            None => scale,
        };
        Prediction { at: p, scale, ahead }
    }

    /// Updates the running prediction errors with an observation for the next frame, given
    /// the extrapolations to that frame (from its [`Track::predict`]).
    fn learn(&mut self, obs: [f64; 2], ahead: &Extrapolations) {
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
    }
}

/// Links per-frame detections into trajectories (see the module doc). `frames` must be
/// in increasing, contiguous frame order.
pub fn link_detections(frames: &[FrameDetections], options: &LinkOptions) -> LinkOutcome {
    let mut out = LinkOutcome::default();
    let Some(first) = frames.first() else {
        return out;
    };
    let r = options.radius.max(0.5);
    let floor = (0.25 * r).max(0.5);
    let one = SingleParticle::measure(frames);
    let pooled = AppearanceSpread::pooled(frames);
    // Detections closer than this share light through their centroid windows (radius
    // `r + 1` each, reaching the other's disc).
    let crowd = 2.0 * r + 2.0;
    let mut tracks: Vec<Track> = Vec::new();
    let mut steps = StepBound::default();
    let named = options.named_start.is_some();
    let mut events: Vec<(usize, AmbiguityKind, Vec<usize>)> = Vec::new();

    // Start: named particles matched to the first frame by optimal assignment.
    if let Some(starts) = &options.named_start {
        let dets = &first.detections;
        let det_nn = nearest_other(&dets.iter().map(|d| [d.x, d.y]).collect::<Vec<_>>());
        let nn = nearest_other(&starts.iter().map(|s| s.1).collect::<Vec<_>>());
        // Particles may start inside one blob.
        let cols = BlobColumns::of(dets, &one);
        let mut problem = SparseProblem {
            row_miss: Vec::new(),
            col_miss: vec![0.0; cols.count()],
            pairs: Vec::new(),
        };
        for (i, (_, p)) in starts.iter().enumerate() {
            let gate = (0.5 * nn[i]).max(3.0 * r).min(diagonal(options));
            problem.row_miss.push(1.0);
            for (j, d) in dets.iter().enumerate() {
                let d2 = (d.x - p[0]).powi(2) + (d.y - p[1]).powi(2);
                if d2 <= gate * gate {
                    cols.push_pairs(&mut problem, i, j, d2 / (gate * gate));
                }
            }
        }
        let assign: Vec<Option<usize>> = solve_sparse(&problem)
            .into_iter()
            .map(|c| c.map(|c| cols.blob[c]))
            .collect();
        // The particles that start in each blob.
        let mut sharing: Vec<Vec<usize>> = vec![Vec::new(); dets.len()];
        for (i, a) in assign.iter().enumerate() {
            if let Some(j) = a {
                sharing[*j].push(i);
            }
        }
        for (i, (name, p)) in starts.iter().enumerate() {
            let init = (0.5 * nn[i]).min(diagonal(options)) / GATE_SIGMAS;
            let point = match assign[i] {
                Some(j) if sharing[j].len() == 1 => {
                    point_from(&dets[j], PointFlag::Detected, det_nn[j] < crowd)
                }
                Some(j) => {
                    // A blob of several particles: each at the blob's centroid plus its start
                    // position's offset from the group's.
                    let group = &sharing[j];
                    let n = group.len() as f64;
                    let mean = group.iter().fold([0.0, 0.0], |m, &k| {
                        [m[0] + starts[k].1[0] / n, m[1] + starts[k].1[1] / n]
                    });
                    let d = &dets[j];
                    Point {
                        x: d.x + p[0] - mean[0],
                        y: d.y + p[1] - mean[1],
                        mass: d.mass / n,
                        size: d.size,
                        ep: d.ep.max(init),
                        flag: PointFlag::Split,
                        emit: true,
                        clean: false,
                    }
                }
                None => {
                    out.warnings.push(format!(
                        "frame {}: no blob near the start position ({:.1}, {:.1}) of particle {name}; starting from that position",
                        first.frame, p[0], p[1]
                    ));
                    events.push((first.frame, AmbiguityKind::Missing, vec![i]));
                    Point {
                        x: p[0],
                        y: p[1],
                        mass: f64::NAN,
                        size: f64::NAN,
                        ep: f64::NAN,
                        flag: PointFlag::Interpolated,
                        emit: true,
                        clean: false,
                    }
                }
            };
            let split = point.flag == PointFlag::Split;
            let mut track = Track::new(name.clone(), first.frame, point, init.max(floor));
            if split {
                track.merged = 1;
            } else if let Some(j) = assign[i].filter(|&j| !dets[j].clipped) {
                if let Some(a) = Appearance::of(&dets[j], 1) {
                    track.apps.push(first.frame, a);
                }
            }
            tracks.push(track);
        }
        for group in sharing.iter().filter(|g| g.len() > 1) {
            events.push((first.frame, AmbiguityKind::Merged, group.clone()));
        }
    } else {
        start_tracks(
            &mut tracks,
            first,
            &vec![false; first.detections.len()],
            floor,
            options,
            crowd,
        );
    }

    for fd in &frames[1..] {
        let t = fd.frame;
        let dets = &fd.detections;
        let live: Vec<usize> = (0..tracks.len()).filter(|&i| !tracks[i].ended).collect();
        let step = steps.bound();
        let preds: Vec<Prediction> = live.iter().map(|&i| tracks[i].predict(floor, step, r)).collect();
        // Each track's appearance, computed when first asked for (only lone tracks with a
        // candidate in their gate use it).
        let looks: Vec<std::cell::OnceCell<Option<TrackAppearance>>> =
            (0..live.len()).map(|_| std::cell::OnceCell::new()).collect();
        let look_of = |k: usize| {
            looks[k]
                .get_or_init(|| tracks[live[k]].apps.appearance(t, pooled, r + 1.0))
                .as_ref()
        };
        // Appearance tells a particle from untracked objects (a hand, a reflection). Among
        // tracked particles that come close, images merge and share light, so there motion
        // alone decides: only a track whose prediction has no other within reach uses it.
        let pred_points: Vec<[f64; 2]> = preds.iter().map(|p| p.at).collect();
        let pred_grid = PointGrid::new(&pred_points);
        // Lone: no other prediction within reach, allowing two scales of this track's own
        // prediction error.
        let lone: Vec<bool> = preds
            .iter()
            .map(|p| !pred_grid.any_other_within(&p.at, crowd + 2.0 * p.scale))
            .collect();
        // The appearance cost of giving track `k` detection `j` (sum of the squared
        // standardised changes of log mass and size), or `None` when its square root
        // exceeds `gate`: the image is that of another object. A lone track's blob holds no
        // other tracked particle, so it is compared whole with the track's own (a blob cut by
        // the image border on its mass alone, one-sidedly: see [`TrackAppearance::z`]).
        let look_cost = |k: usize, j: usize, gate: f64| -> Option<f64> {
            if !lone[k] {
                return Some(0.0);
            }
            let (Some(look), Some(a)) = (look_of(k), Appearance::of(&dets[j], 1)) else {
                return Some(0.0);
            };
            // Motion blur changes the size as the speed changes, but gradually enough for the
            // track's own spread to follow; a blob of the particle and its reflection is wider.
            // The two changes are judged together (their squared sum, as a chi-square).
            // A candidate that looks like the particle's usual self passes too (its image
            // coming back after a few blurred or shadowed frames).
            let d2_of = |look: &TrackAppearance| {
                let (zm, zs) = look.z(&a, true);
                zm * zm + zs * zs
            };
            let usual = TrackAppearance {
                last: look.usual,
                ..*look
            };
            let d2 = d2_of(look).min(d2_of(&usual));
            (d2 <= gate * gate).then_some(d2)
        };

        let cols = BlobColumns::of(dets, &one);
        let points: Vec<[f64; 2]> = dets.iter().map(|d| [d.x, d.y]).collect();
        let grid = PointGrid::new(&points);
        let mut problem = SparseProblem {
            pairs: Vec::new(),
            // Missing costs a full position gate plus a full appearance gate's worth.
            row_miss: vec![2.0 * GATE_SIGMAS * GATE_SIGMAS; live.len()],
            col_miss: vec![0.0; cols.count()],
        };
        // A track lost (unseen for longer than the memory) has a prediction grown wide: it
        // pays the normalisation of its likelihood, `4 ln(s / floor)` (the cost being twice
        // the negative log-likelihood, up to a constant), so that it cannot take the blob of
        // a neighbour whose tight prediction sits a few of its own widths off (paper5 under
        // a field of 60 px/s²: p4 left the view, and 15 frames later took p3's blob 37 px
        // from its prediction, 3 px from p3's). Tracks bridged through a crossing for a few
        // frames do not: there the widths are those of the motion, not of ignorance.
        for (k, &Prediction { at: p, scale: s, .. }) in preds.iter().enumerate() {
            let breadth = if tracks[live[k]].misses > options.memory {
                4.0 * (s / floor).max(1.0).ln()
            } else {
                0.0
            };
            grid.within(&p, GATE_SIGMAS * s, |j, d2| {
                if let Some(look) = look_cost(k, j, APPEARANCE_GATE_SIGMAS) {
                    cols.push_pairs(&mut problem, k, j, d2 / (s * s) + look + breadth);
                }
            });
        }
        let assign = solve_sparse(&problem);
        let mut det_tracks: Vec<Claimants> = vec![Claimants::default(); dets.len()];
        let mut unassigned: Vec<usize> = Vec::new();
        for (k, a) in assign.iter().enumerate() {
            match a {
                Some(c) => det_tracks[cols.blob[*c]].push(k),
                None => unassigned.push(k),
            }
        }
        // A track left over whose prediction falls inside a taken blob joins it, provided it
        // was located in the previous frame and has a velocity from located points: a
        // track that is itself being bridged, or has been seen once, says too little about
        // where its particle is to claim a share of another particle's blob.
        let merge_r = 1.5 * r;
        let mut still: Vec<usize> = Vec::new();
        for &k in &unassigned {
            let tr = &tracks[live[k]];
            if tr.misses > 0 || tr.seen < 2 {
                still.push(k);
                continue;
            }
            let p = preds[k].at;
            // Only a blob whose light says it holds more particles than it was given:
            // otherwise two tracks would glue onto one particle, and the other particle, left
            // unclaimed nearby, would be lost for good.
            let mut best: Option<(usize, f64)> = None;
            grid.within(&p, merge_r, |j, d2| {
                if !det_tracks[j].is_empty()
                    && one.holds_more(&dets[j], det_tracks[j].len())
                    && best.map_or(true, |b| d2 < b.1)
                {
                    best = Some((j, d2));
                }
            });
            let best = best.map(|b| b.0);
            match best {
                Some(j) => det_tracks[j].push(k),
                None => still.push(k),
            }
        }
        // Second chance for the rest: the nearest detection nobody took, within a gate
        // widened by the misses, provided no other leftover track is as close to it. Only
        // named tracks and tracks located at least twice get it: a new unnamed track (often
        // a noise speck) has no motion to extrapolate a wide gate from.
        let free: Vec<usize> = (0..dets.len()).filter(|&j| det_tracks[j].is_empty()).collect();
        let mut problem2 = SparseProblem {
            pairs: Vec::new(),
            // A full (widened) position gate plus a full appearance gate, as in the main pass.
            row_miss: vec![2.0; still.len()],
            col_miss: vec![0.0; free.len()],
        };
        for (a, &k) in still.iter().enumerate() {
            if !named && tracks[live[k]].seen < 2 {
                continue;
            }
            let Prediction { at: p, scale: s, .. } = preds[k];
            let g = (GATE_SIGMAS * s * 2.0).max(2.0 * r + speed(&tracks[live[k]]));
            for (b, &j) in free.iter().enumerate() {
                let d2 = (points[j][0] - p[0]).powi(2) + (points[j][1] - p[1]).powi(2);
                // The appearance gate widens with the position gate.
                let wide = 2.0 * APPEARANCE_GATE_SIGMAS;
                if let (true, Some(look)) = (d2 <= g * g, look_cost(k, j, wide)) {
                    problem2.pairs.push((a, b, d2 / (g * g) + look / (wide * wide)));
                }
            }
        }
        let assign2 = solve_sparse(&problem2);
        let mut missing: Vec<usize> = Vec::new();
        for (a, &k) in still.iter().enumerate() {
            match assign2[a] {
                Some(b) => det_tracks[free[b]].push(k),
                None => missing.push(k),
            }
        }
        if named && !missing.is_empty() {
            missing = reacquire(&tracks, &live, &preds, &missing, dets, &mut det_tracks, r);
        }

        // A point located in a blob near another tracked particle's shares light with it
        // (soft Voronoi split), so its position is pulled: motion is extrapolated from
        // uncrowded points while there are recent ones.
        let taken_pts: Vec<(usize, [f64; 2])> = (0..dets.len())
            .filter(|&j| !det_tracks[j].is_empty())
            .map(|j| (j, points[j]))
            .collect();
        let taken_points: Vec<[f64; 2]> = taken_pts.iter().map(|p| p.1).collect();
        let taken_grid = PointGrid::new(&taken_points);
        let mut clean = vec![true; dets.len()];
        for (j, p) in &taken_pts {
            clean[*j] = !taken_grid.any_other_within(p, crowd);
        }
        // Write this frame's points.
        for (j, group) in det_tracks.iter().enumerate() {
            if group.is_empty() {
                continue;
            }
            let d = &dets[j];
            if group.len() == 1 {
                let ti = live[group[0]];
                if let Some(last) = tracks[ti].points.last() {
                    if last.flag == PointFlag::Detected && last.clean && clean[j] {
                        steps.push((d.x - last.x).hypot(d.y - last.y));
                    }
                }
                tracks[ti].learn([d.x, d.y], &preds[group[0]].ahead);
                tracks[ti].misses = 0;
                tracks[ti].merged = 0;
                tracks[ti].seen += 1;
                tracks[ti]
                    .points
                    .push(point_from(d, PointFlag::Detected, !clean[j]));
                if let (Some(a), false) = (Appearance::of(d, 1), d.clipped) {
                    tracks[ti].apps.push(t, a);
                }
                continue;
            }
            let n = group.len() as f64;
            let mean = group.iter().fold([0.0, 0.0], |m, &k| {
                [m[0] + preds[k].at[0] / n, m[1] + preds[k].at[1] / n]
            });
            for &k in group.iter() {
                let Prediction { at: p, scale: s, .. } = preds[k];
                let ti = live[k];
                let x = d.x + p[0] - mean[0];
                let y = d.y + p[1] - mean[1];
                // A split point is placed from the prediction, so it carries no news about
                // the motion: it does not train the predictor, and the prediction grows
                // less certain with each merged frame, as with each unseen one.
                tracks[ti].misses = 0;
                tracks[ti].merged += 1;
                tracks[ti].seen += 1;
                tracks[ti].points.push(Point {
                    x,
                    y,
                    mass: d.mass / n,
                    size: d.size,
                    ep: d.ep.max(s),
                    flag: PointFlag::Split,
                    emit: true,
                    clean: false,
                });
            }
            events.push((t, AmbiguityKind::Merged, group.iter().map(|&k| live[k]).collect()));
        }
        for &k in &missing {
            let Prediction { at: p, scale: s, .. } = preds[k];
            let ti = live[k];
            let tr = &mut tracks[ti];
            tr.misses += 1;
            let inside = p[0] >= -r
                && p[1] >= -r
                && p[0] <= options.width as f64 - 1.0 + r
                && p[1] <= options.height as f64 - 1.0 + r;
            let emit = inside && tr.misses <= options.memory;
            if !named && tr.misses > options.memory {
                tr.ended = true;
                continue;
            }
            tr.points.push(Point {
                x: p[0],
                y: p[1],
                mass: f64::NAN,
                size: f64::NAN,
                ep: s,
                flag: PointFlag::Interpolated,
                emit,
                clean: false,
            });
            let kind = if emit {
                AmbiguityKind::Missing
            } else {
                AmbiguityKind::Lost
            };
            events.push((t, kind, vec![ti]));
        }
        if !named {
            let taken: Vec<bool> = det_tracks.iter().map(|g| !g.is_empty()).collect();
            start_tracks(&mut tracks, fd, &taken, floor, options, crowd);
        }
    }

    // Named tracks: crossings judged again with the motion after them (see `crossing`).
    if let Some(starts) = &options.named_start {
        let starts: Vec<[f64; 2]> = starts.iter().map(|s| s.1).collect();
        settle_crossings(&mut tracks, &mut events, &starts, crowd, &one);
    }

    // Unnamed tracks: drop trailing bridged points (the particle was never seen again).
    for tr in &mut tracks {
        if !named {
            while tr
                .points
                .last()
                .is_some_and(|p| p.flag == PointFlag::Interpolated)
            {
                tr.points.pop();
            }
        }
        smooth_bridges(tr);
    }
    let events: Vec<(usize, AmbiguityKind, Vec<usize>)> = events
        .into_iter()
        .filter(|(f, kind, ids)| {
            // Events emptied when a crossing was settled are gone.
            if ids.is_empty() {
                return false;
            }
            // Bridged points later dropped are not reported as bridged.
            *kind != AmbiguityKind::Missing
                || ids.iter().all(|&i| {
                    let tr = &tracks[i];
                    f - tr.first_frame < tr.points.len()
                })
        })
        .collect();
    out.ambiguities = collect_runs(&events, &tracks);
    for a in &out.ambiguities {
        if a.kind == AmbiguityKind::Lost {
            out.warnings
                .push(format!("particle {} {a}", a.particles.join(", ")));
        }
    }

    // The table: by frame, then by track order.
    let frame_end = frames.last().map_or(0, |f| f.frame + 1);
    let mut rows: Vec<TrackPoint> = Vec::new();
    for t in first.frame..frame_end {
        for tr in &tracks {
            if t < tr.first_frame {
                continue;
            }
            if let Some(p) = tr.points.get(t - tr.first_frame) {
                if p.emit {
                    rows.push(TrackPoint {
                        frame: t,
                        particle: tr.name.clone(),
                        x: p.x,
                        y: p.y,
                        mass: p.mass,
                        size: p.size,
                        ep: p.ep,
                        flag: p.flag,
                    });
                }
            }
        }
    }
    out.table = TrackTable { points: rows };
    out
}

/// What one particle's blob looks like in this recording: the median and robust spread
/// (1.4826 MAD) of the mass and size of all detections, most of which hold one particle.
struct SingleParticle {
    mass: f64,
    mass_spread: f64,
    size: f64,
    size_spread: f64,
}

impl SingleParticle {
    fn measure(frames: &[FrameDetections]) -> SingleParticle {
        let masses: Vec<f64> = frames
            .iter()
            .flat_map(|f| f.detections.iter().map(|d| d.mass))
            .collect();
        let sizes: Vec<f64> = frames
            .iter()
            .flat_map(|f| f.detections.iter().map(|d| d.size))
            .collect();
        let (mass, mass_spread) = median_and_spread(masses);
        let (size, size_spread) = median_and_spread(sizes);
        SingleParticle {
            mass,
            mass_spread,
            size,
            size_spread,
        }
    }

    /// Returns true if and only if blob `d`, already given to `taken` tracks, is measurably
    /// heavier or wider than `taken` particles (by more than three spreads, and by at least
    /// a tenth of a particle's mass or of its size).
    fn holds_more(&self, d: &Detection, taken: usize) -> bool {
        self.holds_more_than(d.mass, d.size, taken)
    }

    /// How many particles a blob of `mass` holds (1 to 4): its mass in single particles'.
    fn capacity(&self, mass: f64) -> usize {
        if self.mass > 0.0 && mass.is_finite() {
            (mass / self.mass).round().clamp(1.0, 4.0) as usize
        } else {
            1
        }
    }

    /// [`SingleParticle::holds_more`] for a blob of `mass` and `size`.
    fn holds_more_than(&self, mass: f64, size: f64, taken: usize) -> bool {
        if !(self.mass.is_finite() && self.size.is_finite()) {
            return false;
        }
        let heavier = mass > self.mass * taken as f64 + (3.0 * self.mass_spread).max(0.1 * self.mass);
        let wider = taken == 1 && size > self.size + (3.0 * self.size_spread).max(0.1 * self.size);
        heavier || wider
    }
}

/// The [`median_upper`] and [`robust_spread_upper`] of the finite values of `v`.
fn median_and_spread(mut v: Vec<f64>) -> (f64, f64) {
    v.retain(|x| x.is_finite());
    (median_upper(&mut v), robust_spread_upper(&mut v))
}

fn point_from(d: &Detection, flag: PointFlag, crowded: bool) -> Point {
    Point {
        x: d.x,
        y: d.y,
        mass: d.mass,
        size: d.size,
        ep: d.ep,
        flag,
        emit: true,
        clean: !crowded,
    }
}

/// Re-acquisition of named tracks that neither pass linked: a hypothesis test of each
/// free detection within the particle's physical reach, "my particle" against "clutter".
/// A real particle's image changes abruptly where the gates assume it changes smoothly (at a
/// bounce, motion blur and contact with a surface halve its mass within a frame or two, and
/// the velocity reverses); then the nearest and by far strongest blob is refused by both
/// passes and the track, bridged along its old motion, never returns. Here a free detection
/// is the track's particle if its log mass is nearer the track's recent log mass than the
/// median log mass of the frame's other detections (the clutter, measured in the frame
/// itself), and it lies within `(misses + 1) (2 r + v_max)` of the track's last located
/// point (`v_max` the track's largest frame-to-frame step). Ties between tracks are settled
/// by optimal assignment on the log-mass distance and the distance from each track's
/// prediction (`preds`, by live track) as a share of that reach: a particle lost out of
/// view for 20 frames reaches far, and must not take the blob of a neighbour missed for a
/// frame right where that neighbour's motion puts it. Returns the tracks still missing.
fn reacquire(
    tracks: &[Track],
    live: &[usize],
    preds: &[Prediction],
    missing: &[usize],
    dets: &[Detection],
    det_tracks: &mut [Claimants],
    r: f64,
) -> Vec<usize> {
    let free: Vec<usize> = (0..dets.len())
        .filter(|&j| det_tracks[j].is_empty() && dets[j].mass > 0.0 && dets[j].mass.is_finite())
        .collect();
    if free.is_empty() {
        return missing.to_vec();
    }
    let mut problem = SparseProblem {
        pairs: Vec::new(),
        row_miss: vec![1.0; missing.len()],
        col_miss: vec![0.0; free.len()],
    };
    for (a, &k) in missing.iter().enumerate() {
        let tr = &tracks[live[k]];
        // The track's recent log mass (median of its last located points) and its last
        // located position.
        let recent: Vec<f64> = tr
            .apps
            .points()
            .iter()
            .rev()
            .take(5)
            .map(|(_, a)| a.ln_mass)
            .collect();
        if recent.is_empty() {
            continue;
        }
        let own = finite_median(recent);
        let Some((last_i, last)) = tr
            .points
            .iter()
            .enumerate()
            .rev()
            .find(|(_, p)| p.flag == PointFlag::Detected)
        else {
            continue;
        };
        let v_max = tr
            .points
            .windows(2)
            .filter(|w| w[0].flag == PointFlag::Detected && w[1].flag == PointFlag::Detected)
            .map(|w| (w[1].x - w[0].x).hypot(w[1].y - w[0].y))
            .fold(0.0, f64::max);
        let since = (tr.points.len() - last_i) as f64;
        let reach = since * (2.0 * r + v_max);
        for (b, &j) in free.iter().enumerate() {
            let d = &dets[j];
            if (d.x - last.x).hypot(d.y - last.y) > reach {
                continue;
            }
            let clutter: Vec<f64> = free
                .iter()
                .filter(|&&i| i != j)
                .map(|&i| dets[i].mass.ln())
                .collect();
            let mine = (d.mass.ln() - own).abs();
            let accepted = clutter.is_empty() || mine < (d.mass.ln() - finite_median(clutter)).abs();
            if accepted {
                let off = (d.x - preds[k].at[0]).hypot(d.y - preds[k].at[1]) / reach.max(r);
                let cost = (0.5 * mine / (mine + 1.0) + 0.5 * off.min(1.0).powi(2)).min(0.999);
                problem.pairs.push((a, b, cost));
            }
        }
    }
    let assign = solve_sparse(&problem);
    let mut still = Vec::new();
    for (a, &k) in missing.iter().enumerate() {
        match assign[a] {
            Some(b) => det_tracks[free[b]].push(k),
            None => still.push(k),
        }
    }
    still
}

/// The columns of an assignment over one frame's blobs: each blob once per particle its mass
/// can hold ([`SingleParticle::capacity`]).
struct BlobColumns {
    /// The blob of each column.
    blob: Vec<usize>,
    /// `first[j]..first[j + 1]`: blob `j`'s columns.
    first: Vec<usize>,
}

impl BlobColumns {
    fn of(dets: &[Detection], one: &SingleParticle) -> BlobColumns {
        let mut blob = Vec::with_capacity(dets.len());
        let mut first = Vec::with_capacity(dets.len() + 1);
        for (j, d) in dets.iter().enumerate() {
            first.push(blob.len());
            blob.extend(std::iter::repeat(j).take(one.capacity(d.mass)));
        }
        first.push(blob.len());
        BlobColumns { blob, first }
    }

    fn count(&self) -> usize {
        self.blob.len()
    }

    /// Allows row `row` every column of blob `j` at `cost`, later copies a little dearer so
    /// that a lone row takes the first.
    fn push_pairs(&self, problem: &mut SparseProblem, row: usize, j: usize, cost: f64) {
        for (copy, c) in (self.first[j]..self.first[j + 1]).enumerate() {
            problem.pairs.push((row, c, cost + 1e-3 * copy as f64));
        }
    }
}

fn speed(tr: &Track) -> f64 {
    if tr.points.len() < 2 {
        return 0.0;
    }
    let (a, b) = (tr.pos(0), tr.pos(1));
    (a[0] - b[0]).hypot(a[1] - b[1])
}

fn diagonal(o: &LinkOptions) -> f64 {
    (o.width as f64).hypot(o.height as f64)
}

/// The [`median_upper`] of the finite values of `v`.
fn finite_median(mut v: Vec<f64>) -> f64 {
    v.retain(|x| x.is_finite());
    median_upper(&mut v)
}

/// The tracks (indices into the frame's live tracks) that claim one detection: almost always
/// none or one, which are held without allocating; more spill to a vector.
#[derive(Clone, Debug, Default)]
struct Claimants {
    /// The first claimant, while there is exactly one.
    one: [usize; 1],
    /// How many claimants there are.
    count: usize,
    /// Every claimant, once there are two or more.
    many: Vec<usize>,
}

impl Claimants {
    /// Adds track `k`.
    fn push(&mut self, k: usize) {
        match self.count {
            0 => self.one[0] = k,
            1 => self.many.extend([self.one[0], k]),
            _ => self.many.push(k),
        }
        self.count += 1;
    }
}

impl std::ops::Deref for Claimants {
    type Target = [usize];

    fn deref(&self) -> &[usize] {
        match self.count {
            0 => &[],
            1 => &self.one,
            _ => &self.many,
        }
    }
}

fn start_tracks(
    tracks: &mut Vec<Track>,
    fd: &FrameDetections,
    taken: &[bool],
    floor: f64,
    o: &LinkOptions,
    crowd: f64,
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
        let init = (0.5 * nn).min(diagonal(o)) / GATE_SIGMAS;
        let name = tracks.len().to_string();
        let mut track = Track::new(
            name,
            fd.frame,
            point_from(d, PointFlag::Detected, nn < crowd),
            init.max(floor),
        );
        if let (Some(a), false) = (Appearance::of(d, 1), d.clipped) {
            track.apps.push(fd.frame, a);
        }
        tracks.push(track);
    }
}

/// Replaces each run of bridged points that has seen points on both sides by the cubic
/// through the two seen points before and the two after (or the line, when only one is
/// available on a side).
fn smooth_bridges(tr: &mut Track) {
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

/// Groups per-frame events into runs of consecutive frames with the same kind and tracks.
fn collect_runs(events: &[(usize, AmbiguityKind, Vec<usize>)], tracks: &[Track]) -> Vec<Ambiguity> {
    let mut sorted: Vec<(AmbiguityKind, Vec<usize>, usize)> = events
        .iter()
        .map(|(f, k, ids)| {
            let mut ids = ids.clone();
            ids.sort_unstable();
            (*k, ids, *f)
        })
        .collect();
    sorted.sort();
    let mut out: Vec<Ambiguity> = Vec::new();
    let mut last: Option<(AmbiguityKind, Vec<usize>, usize, usize)> = None;
    let names = |ids: &[usize]| ids.iter().map(|&i| tracks[i].name.clone()).collect::<Vec<_>>();
    for (k, ids, f) in sorted {
        match &mut last {
            Some((lk, lids, _, lf)) if *lk == k && *lids == ids && *lf + 1 == f => *lf = f,
            _ => {
                if let Some((lk, lids, ff, lf)) = last.take() {
                    out.push(Ambiguity {
                        kind: lk,
                        particles: names(&lids),
                        first_frame: ff,
                        last_frame: lf,
                    });
                }
                last = Some((k, ids, f, f));
            }
        }
    }
    if let Some((lk, lids, ff, lf)) = last {
        out.push(Ambiguity {
            kind: lk,
            particles: names(&lids),
            first_frame: ff,
            last_frame: lf,
        });
    }
    out.sort_by(|a, b| (a.first_frame, a.kind, &a.particles).cmp(&(b.first_frame, b.kind, &b.particles)));
    out
}

#[cfg(test)]
mod tests {
    use super::Claimants;

    /// Claimants read back as the tracks pushed, in order, whether none, one or several.
    #[test]
    fn claimants_hold_what_was_pushed() {
        let mut c = Claimants::default();
        assert!(c.is_empty());
        let mut want = Vec::new();
        for k in [7, 3, 9, 3] {
            c.push(k);
            want.push(k);
            assert_eq!(&c[..], &want[..]);
        }
    }
}
