//! [`Linker`]: the linking state, advanced one frame at a time.
//!
//! As argmin keeps a solver's state apart from its `next_iter`, the linker holds what
//! linking carries from frame to frame (the tracks, the step bound, the ambiguity events)
//! and [`Linker::step`] links one more frame. A frame is linked in named sub-steps, each a
//! method tested alone: [`Linker::predict`] (each live track's prediction and whether
//! another is near it), [`Linker::assign`] (optimal assignment within the gates),
//! [`Linker::join_blobs`] (a track left over joins a blob holding more than it was given),
//! [`Linker::second_chance`] (a widened gate over the detections nobody took),
//! [`reacquire`] (named tracks only), [`Linker::uncrowded`] (which located points share
//! light with another), [`Linker::write_located`] and [`Linker::bridge_missing`] (the
//! frame's points), and new tracks from the detections left. [`Linker::finish`] settles
//! crossings, smooths bridged runs and writes the table.

use std::cell::OnceCell;

use super::claimants::Claimants;
use super::fragments::join_fragments;
use super::options::{diagonal, FrameDetections, LinkOptions};
use super::outcome::{collect_runs, AmbiguityKind, LinkOutcome};
use super::reacquire::{reacquire, BlobColumns};
use super::settle::settle_crossings;
use super::single_particle::SingleParticle;
use super::step_bound::StepBound;
use super::track::{point_from, smooth_bridges, speed, start_tracks, Point, Prediction, Track};
use super::{APPEARANCE_GATE_SIGMAS, GATE_SIGMAS};
use crate::appearance::{Appearance, AppearanceHistory, AppearanceLevels, AppearanceSpread, TrackAppearance};
use crate::assignment::{solve_sparse, SparseProblem};
use crate::locate::{locate_window, Detection};
use crate::point_grid::{nearest_other, PointGrid};
use crate::track_table::{PointFlag, TrackPoint, TrackTable};

/// An ambiguity event: frame, kind, and the tracks (indices into the linker's tracks).
type Event = (usize, AmbiguityKind, Vec<usize>);

/// The state of linking between frames (see the module doc).
pub(super) struct Linker<'o> {
    options: &'o LinkOptions,
    /// Particle radius, px (at least 0.5).
    r: f64,
    /// Smallest prediction scale, px.
    floor: f64,
    /// Detections closer than this are near enough to compete (their windows, radius
    /// `r + 1` each, reach the other's disc), px.
    crowd: f64,
    /// Detections closer than this share light, px: the soft Voronoi split leaves out of
    /// each window the pixels nearer the other estimate, so a neighbour's light enters only
    /// where its disc (with its anti-aliased edge, `r + 1/2`) crosses the bisector, `d - r -
    /// 1/2 < d / 2`: `d < 2 r + 1`. (At `2 r + 2`, the side-by-side frames' 1000 random walks
    /// made two pairs of points 9.97 px apart crowded, their tracks predicted from points
    /// three frames old, and each pair exchanged its particles.)
    shares: f64,
    /// What one particle's blob looks like in the recording.
    one: SingleParticle,
    /// Each frame's common change of appearance (exposure), taken out of every appearance
    /// compared.
    levels: AppearanceLevels,
    /// Frame-to-frame appearance spreads pooled over unambiguous links.
    pooled: Option<AppearanceSpread>,
    /// Every track started so far, ended ones included.
    tracks: Vec<Track>,
    /// Bound on a clean frame-to-frame step, learned from the located points.
    steps: StepBound,
    /// Returns true if and only if the tracks are named particles of a structure.
    named: bool,
    /// Ambiguity events in the order they happened.
    events: Vec<Event>,
    /// Warnings in the order they were raised.
    warnings: Vec<String>,
    /// First frame linked.
    first_frame: usize,
    /// One past the last frame linked.
    end_frame: usize,
}

/// One frame as the live tracks see it: their predictions and the frame's detections.
struct FrameView<'f> {
    /// Frame index.
    t: usize,
    dets: &'f [Detection],
    /// The detections' positions, px.
    points: &'f [[f64; 2]],
    /// The detections bucketed for neighbour queries.
    grid: PointGrid<'f>,
    /// The live tracks (indices into the linker's tracks); `k` below indexes this.
    live: Vec<usize>,
    /// Each live track's prediction.
    preds: Vec<Prediction>,
    /// Returns true if and only if no other prediction lies within reach of track `k`'s.
    lone: Vec<bool>,
    /// Each live track's appearance, computed when first asked for (only lone tracks with a
    /// candidate in their gate use it).
    looks: Vec<OnceCell<Option<TrackAppearance>>>,
    /// How many particles each detection holds ([`Linker::capacities`]), computed when first
    /// asked for.
    capacities: OnceCell<Vec<usize>>,
}

impl<'o> Linker<'o> {
    /// Measures the recording's single-particle blob and appearance spreads over all
    /// `frames` (at least one) and starts the tracks on the first.
    pub(super) fn new(frames: &[FrameDetections], options: &'o LinkOptions) -> Linker<'o> {
        let first = &frames[0];
        let r = options.radius.max(0.5);
        let levels = AppearanceLevels::measure(frames);
        let mut linker = Linker {
            options,
            r,
            floor: (0.25 * r).max(0.5),
            crowd: 2.0 * r + 2.0,
            shares: 2.0 * r + 1.0,
            one: SingleParticle::measure(frames),
            pooled: AppearanceSpread::pooled(frames, &levels),
            levels,
            tracks: Vec::new(),
            steps: StepBound::default(),
            named: options.named_start.is_some(),
            events: Vec::new(),
            warnings: Vec::new(),
            first_frame: first.frame,
            end_frame: first.frame + 1,
        };
        if let Some(starts) = &options.named_start {
            linker.start_named(first, frames.get(1), starts);
        } else {
            let taken = vec![false; first.detections.len()];
            start_tracks(
                &mut linker.tracks,
                first,
                &linker.levels,
                &taken,
                linker.floor,
                options,
                linker.shares,
            );
        }
        linker
    }

    /// Starts the named particles: matched to the first frame's blobs by optimal
    /// assignment, several particles possibly in one blob; `next` (the frame after `first`)
    /// bounds their first steps (see [`Linker::first_step_reach`]).
    fn start_named(
        &mut self,
        first: &FrameDetections,
        next: Option<&FrameDetections>,
        starts: &[(String, [f64; 2])],
    ) {
        let dets = &first.detections;
        let det_points: Vec<[f64; 2]> = dets.iter().map(|d| [d.x, d.y]).collect();
        let det_grid = PointGrid::new(&det_points);
        let next_points: Vec<[f64; 2]> =
            next.map_or(Vec::new(), |f| f.detections.iter().map(|d| [d.x, d.y]).collect());
        let next_grid = PointGrid::new(&next_points);
        let det_nn: Vec<f64> = det_points.iter().map(|p| det_grid.nearest_other(p)).collect();
        let nn = nearest_other(&starts.iter().map(|s| s.1).collect::<Vec<_>>());
        let assign = self.match_starts(dets, starts, &nn);
        // The particles that start in each blob.
        let mut sharing: Vec<Claimants> = vec![Claimants::default(); dets.len()];
        for (i, a) in assign.iter().enumerate() {
            if let Some(j) = a {
                sharing[*j].push(i);
            }
        }
        // A light blob nobody took beside a light one a start took is the rest of its
        // particle (see `join_fragments`).
        let positions: Vec<[f64; 2]> = starts.iter().map(|s| s.1).collect();
        let joined = join_fragments(dets, &sharing, &positions, &self.one, self.r);
        for (i, (name, p)) in starts.iter().enumerate() {
            // The first step is not known: a gate of half the way to the nearest other
            // named particle, or to the nearest other lookalike blob (see
            // `first_step_reach`).
            let clear = assign[i].filter(|&j| sharing[j].len() == 1).map_or(nn[i], |j| {
                self.first_step_reach((first, next), (&det_grid, &next_grid), j, nn[i])
            });
            let init = (0.5 * clear).min(diagonal(self.options)) / GATE_SIGMAS;
            let point = match assign[i] {
                Some(j) if sharing[j].len() == 1 => match joined.iter().find(|f| f.0 == j) {
                    Some((_, whole)) => point_from(whole, PointFlag::Detected, true),
                    None => point_from(&dets[j], PointFlag::Detected, det_nn[j] < self.shares),
                },
                Some(j) => split_start(&dets[j], &sharing[j], starts, *p, init),
                None => {
                    self.warnings.push(format!(
                        "frame {}: no blob near the start position ({:.1}, {:.1}) of particle {name}; starting from that position",
                        first.frame, p[0], p[1]
                    ));
                    self.events.push((first.frame, AmbiguityKind::Missing, vec![i]));
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
            let mut track = Track::new(name.clone(), first.frame, point, init.max(self.floor));
            if split {
                track.merged = 1;
            } else if let Some(j) = assign[i].filter(|&j| !dets[j].clipped) {
                let seen = joined.iter().find(|f| f.0 == j).map_or(&dets[j], |f| &f.1);
                if let Some(a) = Appearance::of(seen, 1) {
                    track.apps.push(first.frame, self.levels.apply(a, first.frame));
                }
            }
            self.tracks.push(track);
        }
        for group in sharing.iter().filter(|g| g.len() > 1) {
            self.events
                .push((first.frame, AmbiguityKind::Merged, group.to_vec()));
        }
    }

    /// How far (px) the first step of the particle in blob `j` of the first frame `first`
    /// may be judged by position: half of this is its gate. Up to `reach` px (the way to the
    /// nearest other named particle), the way to the nearest other blob of `first` that
    /// looks like it (log mass and size within [`APPEARANCE_GATE_SIGMAS`] of the recording's
    /// pooled frame-to-frame spreads; every blob where the spreads are unknown) — an unnamed
    /// lookalike's blob is as likely a first step as its own, by position, and appearance
    /// would choose by its noise — provided the frame after, `next` (indexed by `grids.1`,
    /// `grids.0` indexing `first`), has a lookalike blob within that half way: where it has
    /// none, the particle moved farther than its neighbours allow for (a ball thrown out of
    /// a hand, 70 px a frame past a blob 112 px away), and appearance tells it apart.
    fn first_step_reach(
        &self,
        (first, next): (&FrameDetections, Option<&FrameDetections>),
        grids: (&PointGrid, &PointGrid),
        j: usize,
        reach: f64,
    ) -> f64 {
        let reach = reach.min(diagonal(self.options));
        let here = [first.detections[j].x, first.detections[j].y];
        let look = Appearance::of(&first.detections[j], 1).and_then(|a| {
            let mut history = AppearanceHistory::default();
            history.push(first.frame, self.levels.apply(a, first.frame));
            history.appearance(first.frame + 1, self.pooled, locate_window(self.r))
        });
        let alike = |d: &Detection, t: usize| match (look, Appearance::of(d, 1)) {
            (Some(look), Some(a)) => {
                look.distance2(&self.levels.apply(a, t)) <= APPEARANCE_GATE_SIGMAS * APPEARANCE_GATE_SIGMAS
            }
            _ => true,
        };
        let mut nearest = reach;
        grids.0.within(&here, reach, |k, d2| {
            let d = d2.sqrt();
            if k != j && d < nearest && alike(&first.detections[k], first.frame) {
                nearest = d;
            }
        });
        let Some(next) = next.filter(|_| nearest < reach) else {
            return nearest;
        };
        let mut found = false;
        grids.1.within(&here, 0.5 * nearest, |k, _| {
            found = found || alike(&next.detections[k], next.frame);
        });
        if found {
            nearest
        } else {
            reach
        }
    }

    /// The blob (index into `dets`) each named start is matched to: optimal assignment on
    /// the squared distance within a gate of half the start's nearest-neighbour distance
    /// `nn` (at least `3 r`), a blob taking as many starts as its mass says it holds.
    fn match_starts(
        &self,
        dets: &[Detection],
        starts: &[(String, [f64; 2])],
        nn: &[f64],
    ) -> Vec<Option<usize>> {
        let cols = BlobColumns::of(dets, &self.one);
        let mut problem = SparseProblem {
            row_miss: Vec::new(),
            col_miss: vec![0.0; cols.count()],
            pairs: Vec::new(),
        };
        for (i, (_, p)) in starts.iter().enumerate() {
            let gate = (0.5 * nn[i]).max(3.0 * self.r).min(diagonal(self.options));
            problem.row_miss.push(1.0);
            for (j, d) in dets.iter().enumerate() {
                let d2 = (d.x - p[0]).powi(2) + (d.y - p[1]).powi(2);
                if d2 <= gate * gate {
                    cols.push_pairs(&mut problem, i, j, d2 / (gate * gate));
                }
            }
        }
        solve_sparse(&problem)
            .into_iter()
            .map(|c| c.map(|c| cols.blob[c]))
            .collect()
    }

    /// Links frame `fd` (the frame after the last one linked).
    pub(super) fn step(&mut self, fd: &FrameDetections) {
        let points: Vec<[f64; 2]> = fd.detections.iter().map(|d| [d.x, d.y]).collect();
        let view = self.predict(fd, &points);
        let (mut claims, unassigned) = self.assign(&view);
        let still = self.join_blobs(&view, &mut claims, &unassigned);
        let mut missing = self.second_chance(&view, &mut claims, &still);
        if self.named && !missing.is_empty() {
            missing = reacquire(
                &self.tracks,
                &view.live,
                &view.preds,
                &missing,
                view.dets,
                &mut claims,
                self.r,
            );
        }
        let clean = self.uncrowded(&view, &claims);
        // Every particle is named: a light blob nobody took beside a light one taken is the
        // rest of that particle.
        let joined = if self.named {
            let predictions: Vec<[f64; 2]> = view.preds.iter().map(|p| p.at).collect();
            join_fragments(view.dets, &claims, &predictions, &self.one, self.r)
        } else {
            Vec::new()
        };
        self.write_located(&view, &claims, &clean, &joined);
        self.bridge_missing(&view, &missing);
        if !self.named {
            let taken: Vec<bool> = claims.iter().map(|g| !g.is_empty()).collect();
            start_tracks(
                &mut self.tracks,
                fd,
                &self.levels,
                &taken,
                self.floor,
                self.options,
                self.shares,
            );
        }
        self.end_frame = fd.frame + 1;
    }

    /// Predicts every live track into frame `fd` (`points`: its detections' positions) and
    /// marks the lone ones: no other prediction within reach, allowing two scales of the
    /// track's own prediction error.
    fn predict<'f>(&self, fd: &'f FrameDetections, points: &'f [[f64; 2]]) -> FrameView<'f> {
        let live: Vec<usize> = (0..self.tracks.len())
            .filter(|&i| !self.tracks[i].ended)
            .collect();
        let step = self.steps.bound();
        let preds: Vec<Prediction> = live
            .iter()
            .map(|&i| self.tracks[i].predict(self.floor, step, self.r))
            .collect();
        // Appearance tells a particle from untracked objects (a hand, a reflection). Among
        // tracked particles that come close, images merge and share light, so there motion
        // alone decides: only a track whose prediction has no other within reach uses it.
        let pred_points: Vec<[f64; 2]> = preds.iter().map(|p| p.at).collect();
        let pred_grid = PointGrid::new(&pred_points);
        let lone = preds
            .iter()
            .map(|p| !pred_grid.any_other_within(&p.at, self.crowd + 2.0 * p.scale))
            .collect();
        FrameView {
            t: fd.frame,
            dets: &fd.detections,
            points,
            grid: PointGrid::new(points),
            looks: (0..live.len()).map(|_| OnceCell::new()).collect(),
            capacities: OnceCell::new(),
            live,
            preds,
            lone,
        }
    }

    /// Live track `k`'s appearance for this frame, computed once a frame.
    fn look<'v>(&self, view: &'v FrameView, k: usize) -> Option<&'v TrackAppearance> {
        view.looks[k]
            .get_or_init(|| {
                self.tracks[view.live[k]]
                    .apps
                    .appearance(view.t, self.pooled, locate_window(self.r))
            })
            .as_ref()
    }

    /// The appearance cost of giving live track `k` detection `j` (sum of the squared
    /// standardised changes of log mass and size), or `None` when its square root exceeds
    /// `gate`: the image is that of another object. A lone track's blob holds no other
    /// tracked particle, so it is compared whole with the track's own (a blob cut by the
    /// image border on its mass alone, one-sidedly: see [`TrackAppearance::z`]); a track
    /// that is not lone pays nothing.
    fn look_cost(&self, view: &FrameView, k: usize, j: usize, gate: f64) -> Option<f64> {
        if !view.lone[k] {
            return Some(0.0);
        }
        let look = self.look(view, k);
        let a = Appearance::of(&view.dets[j], 1).map(|a| self.levels.apply(a, view.t));
        let (Some(look), Some(a)) = (look, a) else {
            return Some(0.0);
        };
        // Motion blur changes the size as the speed changes, but gradually enough for the
        // track's own spread to follow; a blob of the particle and its reflection is wider.
        // The two changes are judged together (their squared sum, as a chi-square).
        // A candidate that looks like the particle's usual self passes too (its image
        // coming back after a few blurred or shadowed frames).
        let usual = TrackAppearance {
            last: look.usual,
            ..*look
        };
        let d2 = look.distance2(&a).min(usual.distance2(&a));
        (d2 <= gate * gate).then_some(d2)
    }

    /// The main pass: live tracks assigned to detections within [`GATE_SIGMAS`] of their
    /// prediction scale by optimal assignment over the whole frame, a blob taking as many
    /// tracks as its mass says it holds. Returns each detection's claimants and the live
    /// tracks left without a detection.
    fn assign(&self, view: &FrameView) -> (Vec<Claimants>, Vec<usize>) {
        let cols = BlobColumns::with(self.capacities(view));
        let mut problem = SparseProblem {
            pairs: Vec::new(),
            // Missing costs a full position gate plus a full appearance gate's worth.
            row_miss: vec![2.0 * GATE_SIGMAS * GATE_SIGMAS; view.live.len()],
            col_miss: vec![0.0; cols.count()],
        };
        // A track lost (unseen for longer than the memory) has a prediction grown wide: it
        // pays the normalisation of its likelihood, `4 ln(s / floor)` (the cost being twice
        // the negative log-likelihood, up to a constant), so that it cannot take the blob of
        // a neighbour whose tight prediction sits a few of its own widths off (paper5 under
        // a field of 60 px/s²: p4 left the view, and 15 frames later took p3's blob 37 px
        // from its prediction, 3 px from p3's). Tracks bridged through a crossing for a few
        // frames do not: there the widths are those of the motion, not of ignorance. An
        // unnamed track seen once and then missed has learned no motion either, and may be a
        // noise speck's: its width is a first guess grown by the misses (one, unseen for two
        // frames, took a bead's blob 30 px off, 2.7 px from the bead's own track's
        // prediction, and the bead's track lost it). A named track is a particle: the first
        // frames of close pairs are not to be decided by which was seen in frame 1.
        for (
            k,
            &Prediction {
                at: p,
                scale: s,
                learned,
                ..
            },
        ) in view.preds.iter().enumerate()
        {
            let misses = self.tracks[view.live[k]].misses;
            let speck = !self.named && learned == 0 && misses > 0;
            let breadth = if misses > self.options.memory || speck {
                4.0 * (s / self.floor).max(1.0).ln()
            } else {
                0.0
            };
            view.grid.within(&p, GATE_SIGMAS * s, |j, d2| {
                if let Some(look) = self.look_cost(view, k, j, APPEARANCE_GATE_SIGMAS) {
                    cols.push_pairs(&mut problem, k, j, d2 / (s * s) + look + breadth);
                }
            });
        }
        let mut claims: Vec<Claimants> = vec![Claimants::default(); view.dets.len()];
        let mut unassigned: Vec<usize> = Vec::new();
        for (k, a) in solve_sparse(&problem).iter().enumerate() {
            match a {
                Some(c) => claims[cols.blob[*c]].push(k),
                None => unassigned.push(k),
            }
        }
        (claims, unassigned)
    }

    /// How many particles each blob of the frame holds: its mass in one particle's. Named
    /// particles may differ in size, and the recording's median mass is then the smaller
    /// ones': a large particle's blob weighed five of them and took a small neighbour's track
    /// as well as its own when the small one went unseen beside it (fresh neighbour 8767,
    /// discs of 1.7 and 4.2 px: the large one's points moved 0.4-0.8 px by the split, the
    /// small one's 6-7 px off). A blob that weighs several particles, within the gate of
    /// named tracks, holds no more than its mass in the usual mass of the heaviest of them.
    /// Computed once a frame, for the assignment and for tracks joining taken blobs.
    fn capacities<'v>(&self, view: &'v FrameView) -> &'v [usize] {
        view.capacities.get_or_init(|| self.weigh_blobs(view))
    }

    /// [`Linker::capacities`], computed.
    fn weigh_blobs(&self, view: &FrameView) -> Vec<usize> {
        let mut capacities: Vec<usize> = view.dets.iter().map(|d| self.one.capacity(d.mass)).collect();
        if !self.named || capacities.iter().all(|&c| c == 1) {
            return capacities;
        }
        let mut heaviest = vec![f64::NEG_INFINITY; view.dets.len()];
        for (k, &Prediction { at: p, scale: s, .. }) in view.preds.iter().enumerate() {
            let mut near: Vec<usize> = Vec::new();
            view.grid.within(&p, GATE_SIGMAS * s, |j, _| {
                if capacities[j] > 1 {
                    near.push(j);
                }
            });
            if near.is_empty() {
                continue;
            }
            if let Some(usual) = self
                .look(view, k)
                .map(|l| l.usual.ln_mass)
                .filter(|m| m.is_finite())
            {
                for j in near {
                    heaviest[j] = heaviest[j].max(usual);
                }
            }
        }
        for (j, d) in view.dets.iter().enumerate() {
            let a = Appearance::of(d, 1).map(|a| self.levels.apply(a, view.t));
            if let (Some(a), true) = (a, heaviest[j].is_finite()) {
                let held = (a.ln_mass - heaviest[j]).exp().round().clamp(1.0, 4.0) as usize;
                capacities[j] = capacities[j].min(held);
            }
        }
        capacities
    }

    /// A track left over (`unassigned`) whose prediction falls inside a taken blob joins
    /// it, provided it was located in the previous frame and has a velocity from located
    /// points: a track that is itself being bridged, or has been seen once, says too little
    /// about where its particle is to claim a share of another particle's blob. Returns the
    /// tracks still without a detection.
    fn join_blobs(&self, view: &FrameView, claims: &mut [Claimants], unassigned: &[usize]) -> Vec<usize> {
        let merge_r = 1.5 * self.r;
        let mut still: Vec<usize> = Vec::new();
        for &k in unassigned {
            let tr = &self.tracks[view.live[k]];
            if tr.misses > 0 || tr.seen < 2 {
                still.push(k);
                continue;
            }
            // Only a blob whose light says it holds more particles than it was given:
            // otherwise two tracks would glue onto one particle, and the other particle, left
            // unclaimed nearby, would be lost for good. Where named particles' masses say a
            // blob holds fewer than the median's does, it takes no more than that.
            let capacities = self.capacities(view);
            let mut best: Option<(usize, f64)> = None;
            view.grid.within(&view.preds[k].at, merge_r, |j, d2| {
                let d = &view.dets[j];
                let n = claims[j].len();
                let weighed = capacities[j] < self.one.capacity(d.mass);
                if n > 0
                    && self.one.holds_more(d, n)
                    && (!weighed || n < capacities[j])
                    && best.map_or(true, |b| d2 < b.1)
                {
                    best = Some((j, d2));
                }
            });
            match best {
                Some((j, _)) => claims[j].push(k),
                None => still.push(k),
            }
        }
        still
    }

    /// Second chance for the tracks `still` without a detection: the detections nobody
    /// took, within a gate widened by the misses, by optimal assignment. Only named tracks
    /// and tracks located at least twice get it: a new unnamed track (often a noise speck)
    /// has no motion to extrapolate a wide gate from. Returns the tracks still missing.
    fn second_chance(&self, view: &FrameView, claims: &mut [Claimants], still: &[usize]) -> Vec<usize> {
        let free: Vec<usize> = (0..view.dets.len()).filter(|&j| claims[j].is_empty()).collect();
        let mut problem = SparseProblem {
            pairs: Vec::new(),
            // A full (widened) position gate plus a full appearance gate, as in the main pass.
            row_miss: vec![2.0; still.len()],
            col_miss: vec![0.0; free.len()],
        };
        for (a, &k) in still.iter().enumerate() {
            let tr = &self.tracks[view.live[k]];
            if !self.named && tr.seen < 2 {
                continue;
            }
            let pred = &view.preds[k];
            let (p, s) = (pred.at, pred.scale);
            // A scale learned from a few residuals may be far too small (a jittering bead's
            // first steps lined up by chance, then it turned 7.5 px from the line: the track
            // ended and a second one took the bead), so the gate allows for its uncertainty.
            let g = (GATE_SIGMAS * s * 2.0)
                .max(2.0 * self.r + speed(tr))
                .max(pred.learned_gate());
            for (b, &j) in free.iter().enumerate() {
                let q = view.points[j];
                let d2 = (q[0] - p[0]).powi(2) + (q[1] - p[1]).powi(2);
                // The appearance gate widens with the position gate.
                let wide = 2.0 * APPEARANCE_GATE_SIGMAS;
                if let (true, Some(look)) = (d2 <= g * g, self.look_cost(view, k, j, wide)) {
                    problem.pairs.push((a, b, d2 / (g * g) + look / (wide * wide)));
                }
            }
        }
        let assign = solve_sparse(&problem);
        let mut missing: Vec<usize> = Vec::new();
        for (a, &k) in still.iter().enumerate() {
            match assign[a] {
                Some(b) => claims[free[b]].push(k),
                None => missing.push(k),
            }
        }
        missing
    }

    /// Which detections were located clear of every other taken one: a point located in a
    /// blob near another tracked particle's shares light with it (soft Voronoi split), so
    /// its position is pulled, and motion is extrapolated from uncrowded points while there
    /// are recent ones. Untaken detections read true.
    fn uncrowded(&self, view: &FrameView, claims: &[Claimants]) -> Vec<bool> {
        let taken: Vec<(usize, [f64; 2])> = (0..view.dets.len())
            .filter(|&j| !claims[j].is_empty())
            .map(|j| (j, view.points[j]))
            .collect();
        let taken_points: Vec<[f64; 2]> = taken.iter().map(|p| p.1).collect();
        let taken_grid = PointGrid::new(&taken_points);
        let mut clean = vec![true; view.dets.len()];
        for (j, p) in &taken {
            clean[*j] = !taken_grid.any_other_within(p, self.shares);
        }
        clean
    }

    /// Writes this frame's located points: a detection claimed by one track is that
    /// track's point (flag `detected`); one claimed by several is split among them.
    /// A detection in `joined` (taken detection, joined detection) is written as joined with
    /// its fragment (see [`join_fragments`]).
    fn write_located(
        &mut self,
        view: &FrameView,
        claims: &[Claimants],
        clean: &[bool],
        joined: &[(usize, Detection)],
    ) {
        for (j, group) in claims.iter().enumerate() {
            match group.len() {
                0 => {}
                1 => match joined.iter().find(|f| f.0 == j) {
                    Some((_, whole)) => self.write_detected(view, whole, group[0], false),
                    None => self.write_detected(view, &view.dets[j], group[0], clean[j]),
                },
                _ => self.write_split(view, j, group),
            }
        }
    }

    /// Gives live track `k` detection `d` whole; `clean` says it was located clear of other
    /// taken detections (only then does its step teach the step bound).
    fn write_detected(&mut self, view: &FrameView, d: &Detection, k: usize, clean: bool) {
        let tr = &mut self.tracks[view.live[k]];
        if let Some(last) = tr.points.last() {
            if last.flag == PointFlag::Detected && last.clean && clean {
                self.steps.push((d.x - last.x).hypot(d.y - last.y));
            }
        }
        tr.learn([d.x, d.y], &view.preds[k].ahead);
        tr.misses = 0;
        tr.merged = 0;
        tr.seen += 1;
        tr.points.push(point_from(d, PointFlag::Detected, !clean));
        if let (Some(a), false) = (Appearance::of(d, 1), d.clipped) {
            tr.apps.push(view.t, self.levels.apply(a, view.t));
        }
    }

    /// Splits detection `j` among the live tracks of `group`: each at the blob's centroid
    /// plus its predicted offset from the group's mean prediction (flag `split`).
    fn write_split(&mut self, view: &FrameView, j: usize, group: &[usize]) {
        let d = &view.dets[j];
        let n = group.len() as f64;
        let mean = group.iter().fold([0.0, 0.0], |m, &k| {
            [m[0] + view.preds[k].at[0] / n, m[1] + view.preds[k].at[1] / n]
        });
        for &k in group {
            let Prediction { at: p, scale: s, .. } = view.preds[k];
            let tr = &mut self.tracks[view.live[k]];
            // A split point is placed from the prediction, so it carries no news about
            // the motion: it does not train the predictor, and the prediction grows
            // less certain with each merged frame, as with each unseen one.
            tr.misses = 0;
            tr.merged += 1;
            tr.seen += 1;
            tr.points.push(Point {
                x: d.x + p[0] - mean[0],
                y: d.y + p[1] - mean[1],
                mass: d.mass / n,
                size: d.size,
                ep: d.fixed_point_error().max(s),
                flag: PointFlag::Split,
                emit: true,
                clean: false,
            });
        }
        let ids = group.iter().map(|&k| view.live[k]).collect();
        self.events.push((view.t, AmbiguityKind::Merged, ids));
    }

    /// Bridges the `missing` live tracks with their predictions (flag `interpolated`),
    /// written to the table while inside the image and within the memory; an unnamed
    /// track unseen for longer than the memory ends.
    fn bridge_missing(&mut self, view: &FrameView, missing: &[usize]) {
        let (r, o) = (self.r, self.options);
        for &k in missing {
            let Prediction { at: p, scale: s, .. } = view.preds[k];
            let ti = view.live[k];
            let tr = &mut self.tracks[ti];
            tr.misses += 1;
            let inside = p[0] >= -r
                && p[1] >= -r
                && p[0] <= o.width as f64 - 1.0 + r
                && p[1] <= o.height as f64 - 1.0 + r;
            let emit = inside && tr.misses <= o.memory;
            if !self.named && tr.misses > o.memory {
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
            self.events.push((view.t, kind, vec![ti]));
        }
    }

    /// Ends linking: named tracks' crossings judged again with the motion after them (see
    /// `crossing`), unnamed tracks' trailing bridged points dropped (the particle was never
    /// seen again), bridged runs smoothed, and the table written by frame, then by track.
    pub(super) fn finish(mut self) -> LinkOutcome {
        if let Some(starts) = &self.options.named_start {
            let starts: Vec<[f64; 2]> = starts.iter().map(|s| s.1).collect();
            settle_crossings(&mut self.tracks, &mut self.events, &starts, self.crowd, &self.one);
        }
        for tr in &mut self.tracks {
            if !self.named {
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
        let events = self.reported_events();
        let ambiguities = collect_runs(&events, &self.tracks);
        let mut warnings = std::mem::take(&mut self.warnings);
        for a in &ambiguities {
            if a.kind == AmbiguityKind::Lost {
                warnings.push(format!("particle {} {a}", a.particles.join(", ")));
            }
        }
        LinkOutcome {
            table: self.table(),
            ambiguities,
            warnings,
        }
    }

    /// The events to report: those emptied when a crossing was settled are gone, and
    /// bridged points later dropped are not reported as bridged.
    fn reported_events(&mut self) -> Vec<Event> {
        let tracks = &self.tracks;
        std::mem::take(&mut self.events)
            .into_iter()
            .filter(|(f, kind, ids)| {
                !ids.is_empty()
                    && (*kind != AmbiguityKind::Missing
                        || ids
                            .iter()
                            .all(|&i| f - tracks[i].first_frame < tracks[i].points.len()))
            })
            .collect()
    }

    /// The track table: the written points by frame, then by track order.
    fn table(&self) -> TrackTable {
        let mut rows: Vec<TrackPoint> = Vec::new();
        for t in self.first_frame..self.end_frame {
            for tr in &self.tracks {
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
        TrackTable { points: rows }
    }
}

/// The start point of a named particle that starts in blob `d` with the other starts of
/// `group` (indices into `starts`): the blob's centroid plus the start position `p`'s offset
/// from the group's mean (flag `split`), with an error of at least `init`.
fn split_start(
    d: &Detection,
    group: &[usize],
    starts: &[(String, [f64; 2])],
    p: [f64; 2],
    init: f64,
) -> Point {
    let n = group.len() as f64;
    let mean = group.iter().fold([0.0, 0.0], |m, &k| {
        [m[0] + starts[k].1[0] / n, m[1] + starts[k].1[1] / n]
    });
    Point {
        x: d.x + p[0] - mean[0],
        y: d.y + p[1] - mean[1],
        mass: d.mass / n,
        size: d.size,
        ep: d.fixed_point_error().max(init),
        flag: PointFlag::Split,
        emit: true,
        clean: false,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    use crate::link::tests::{det, frame};

    /// Unnamed tracks of radius 2 px in a 100 × 100 frame, remembered `memory` frames.
    fn options(memory: usize) -> LinkOptions {
        LinkOptions {
            named_start: None,
            radius: 2.0,
            width: 100,
            height: 100,
            memory,
        }
    }

    fn last(linker: &Linker, track: usize) -> (f64, f64, PointFlag) {
        let p = linker.tracks[track].points.last().expect("a point");
        (p.x, p.y, p.flag)
    }

    /// Every detection of one particle's mass has at most one claimant.
    fn assert_one_claimant_each(claims: &[Claimants], sub_step: &str) {
        for (j, c) in claims.iter().enumerate() {
            assert!(
                c.len() <= 1,
                "{sub_step}: detection {j} given to tracks {:?}",
                &c[..]
            );
        }
    }

    /// A particle moved 2 px is linked to its own track, not to its neighbour's.
    #[test]
    fn step_links_a_particle_moved_2px_to_its_own_track() {
        let frames = [
            frame(0, &[[20.0, 20.0], [60.0, 60.0]]),
            frame(1, &[[60.0, 62.0], [22.0, 20.0]]),
        ];
        let o = options(3);
        let mut linker = Linker::new(&frames, &o);
        assert_eq!(linker.tracks.len(), 2);
        linker.step(&frames[1]);
        assert_eq!(linker.tracks.len(), 2, "no track started");
        assert_eq!(last(&linker, 0), (22.0, 20.0, PointFlag::Detected));
        assert_eq!(last(&linker, 1), (60.0, 62.0, PointFlag::Detected));
    }

    /// A detection beyond a track's gate is refused by the main pass: the track is left
    /// unassigned and the detection unclaimed, and the step then bridges the track and
    /// starts a new one at the far detection.
    #[test]
    fn assign_refuses_a_candidate_beyond_the_gate() {
        // Neighbours 40 px apart: each start scale is 40 / GATE_SIGMAS = 10 px, a 40 px gate.
        let frames = [
            frame(0, &[[20.0, 20.0], [60.0, 20.0]]),
            frame(1, &[[20.0, 70.0], [60.0, 20.0]]),
        ];
        let o = options(3);
        let mut linker = Linker::new(&frames, &o);
        let points: Vec<[f64; 2]> = frames[1].detections.iter().map(|d| [d.x, d.y]).collect();
        let view = linker.predict(&frames[1], &points);
        assert!(
            view.preds[0].scale * GATE_SIGMAS < 50.0,
            "the gate is narrower than the jump"
        );
        let (claims, unassigned) = linker.assign(&view);
        assert_eq!(unassigned, [0]);
        assert!(claims[0].is_empty(), "the far detection is nobody's");
        assert_eq!(&claims[1][..], &[1]);
        linker.step(&frames[1]);
        assert_eq!(last(&linker, 0), (20.0, 20.0, PointFlag::Interpolated));
        assert_eq!(linker.tracks.len(), 3);
        assert_eq!(last(&linker, 2), (20.0, 70.0, PointFlag::Detected));
    }

    /// Two tracks near one blob of one particle's mass: one takes it, and the other, left
    /// over with its prediction inside the taken blob, does not join it.
    #[test]
    fn join_blobs_never_gives_one_particle_blob_to_two_tracks() {
        let frames = [
            frame(0, &[[20.0, 20.0], [24.0, 20.0]]),
            frame(1, &[[20.0, 20.0], [24.0, 20.0]]),
            frame(2, &[[21.5, 20.0]]),
        ];
        let o = options(3);
        let mut linker = Linker::new(&frames, &o);
        linker.step(&frames[1]);
        let points = [[21.5, 20.0]];
        let view = linker.predict(&frames[2], &points);
        let (mut claims, unassigned) = linker.assign(&view);
        assert_eq!(claims[0].len(), 1);
        assert_eq!(unassigned.len(), 1);
        let still = linker.join_blobs(&view, &mut claims, &unassigned);
        assert_eq!(still, unassigned, "the left-over track joins no blob");
        assert_eq!(claims[0].len(), 1);
        let missing = linker.second_chance(&view, &mut claims, &still);
        assert_eq!(missing, still, "no free detection for a second chance");
        assert_eq!(claims[0].len(), 1);
    }

    /// Particles wandering in a crowd (a fixed pseudo-random walk, neighbours 3 to 10 px
    /// apart), each a blob of one particle's mass: no sub-step of any frame gives a
    /// detection to two tracks.
    #[test]
    fn no_sub_step_gives_one_detection_to_two_tracks() {
        let mut state = 0x2545_f491_4f6c_dd1d_u64;
        let mut uniform = move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 11) as f64 / (1u64 << 53) as f64
        };
        let mut at: Vec<[f64; 2]> = (0..12)
            .map(|i| [30.0 + 6.0 * (i % 4) as f64, 30.0 + 6.0 * (i / 4) as f64])
            .collect();
        let mut frames = Vec::new();
        for t in 0..40 {
            // Now and then a particle is not detected.
            let seen: Vec<[f64; 2]> = at.iter().filter(|_| uniform() > 0.1).copied().collect();
            frames.push(frame(t, &seen));
            for p in &mut at {
                p[0] += 3.0 * (uniform() - 0.5);
                p[1] += 3.0 * (uniform() - 0.5);
            }
        }
        let o = options(2);
        let mut linker = Linker::new(&frames, &o);
        for fd in &frames[1..] {
            let points: Vec<[f64; 2]> = fd.detections.iter().map(|d| [d.x, d.y]).collect();
            let view = linker.predict(fd, &points);
            let (mut claims, unassigned) = linker.assign(&view);
            assert_one_claimant_each(&claims, "assign");
            let still = linker.join_blobs(&view, &mut claims, &unassigned);
            assert_one_claimant_each(&claims, "join_blobs");
            linker.second_chance(&view, &mut claims, &still);
            assert_one_claimant_each(&claims, "second_chance");
            linker.step(fd);
        }
        let table = linker.finish().table;
        for t in 0..40 {
            let mut xs: Vec<(u64, u64)> = table
                .points
                .iter()
                .filter(|p| p.frame == t && p.flag == PointFlag::Detected)
                .map(|p| (p.x.to_bits(), p.y.to_bits()))
                .collect();
            let n = xs.len();
            xs.sort_unstable();
            xs.dedup();
            assert_eq!(xs.len(), n, "frame {t}: a detected point written for two tracks");
        }
    }

    /// A track that finds nothing is bridged at its prediction while within the memory,
    /// then (unnamed) ends; finishing drops the trailing bridged points.
    #[test]
    fn bridge_missing_bridges_within_the_memory_then_ends_the_track() {
        let frames = [
            frame(0, &[[20.0, 20.0], [60.0, 60.0]]),
            frame(1, &[[60.0, 60.0]]),
            frame(2, &[[60.0, 60.0]]),
        ];
        let o = options(1);
        let mut linker = Linker::new(&frames, &o);
        linker.step(&frames[1]);
        assert_eq!(last(&linker, 0), (20.0, 20.0, PointFlag::Interpolated));
        assert!(linker.tracks[0].points.last().is_some_and(|p| p.emit));
        assert!(!linker.tracks[0].ended);
        assert_eq!(linker.events.last().map(|e| e.1), Some(AmbiguityKind::Missing));
        linker.step(&frames[2]);
        assert!(linker.tracks[0].ended, "unseen for longer than the memory");
        assert_eq!(linker.tracks[0].points.len(), 2, "no point once ended");
        let outcome = linker.finish();
        let rows: Vec<(usize, &str)> = outcome
            .table
            .points
            .iter()
            .map(|p| (p.frame, p.particle.as_str()))
            .collect();
        assert_eq!(rows, [(0, "0"), (0, "1"), (1, "1"), (2, "1")]);
        assert!(
            outcome.ambiguities.is_empty(),
            "the dropped bridge is not reported"
        );
    }

    /// A named particle whose start position has no blob near it starts there, bridged,
    /// with a warning.
    #[test]
    fn new_starts_a_named_particle_without_a_blob_from_its_position() {
        let frames = [frame(0, &[[20.0, 20.0]])];
        let o = LinkOptions {
            named_start: Some(vec![("a".into(), [20.5, 20.0]), ("b".into(), [80.0, 80.0])]),
            ..options(3)
        };
        let linker = Linker::new(&frames, &o);
        assert_eq!(last(&linker, 0), (20.0, 20.0, PointFlag::Detected));
        assert_eq!(last(&linker, 1), (80.0, 80.0, PointFlag::Interpolated));
        assert_eq!(linker.warnings.len(), 1);
        assert!(
            linker.warnings[0].contains("particle b"),
            "{}",
            linker.warnings[0]
        );
    }

    /// Named particles of two sizes over `count` frames, moving right by 1 px a frame: a
    /// large one of mass 500 at row 60, two small ones (mass 100 give or take 20, the
    /// recording's median) at rows 20 and 90, and a small one at `small_at(k)` (its offset
    /// from the large one's column and its row; `None` where unseen), started at
    /// `small_start`. Returns each particle's (x, y, flag) in frame `k`.
    fn two_sizes(
        count: usize,
        small_at: impl Fn(usize) -> Option<[f64; 2]>,
        small_start: [f64; 2],
    ) -> impl Fn(usize, &str) -> (f64, f64, PointFlag) {
        let blob = |x: f64, y: f64, mass: f64| Detection { mass, ..det(x, y) };
        let small = |k: usize, i: usize| 100.0 * (1.0 + 0.2 * (1.3 * k as f64 + 2.0 * i as f64).sin());
        let frames: Vec<FrameDetections> = (0..count)
            .map(|k| {
                let x = 20.0 + k as f64;
                let mut detections = vec![
                    blob(x, 60.0, 500.0),
                    blob(x, 20.0, small(k, 1)),
                    blob(x, 90.0, small(k, 2)),
                ];
                if let Some([dx, y]) = small_at(k) {
                    detections.push(blob(x + dx, y, small(k, 0)));
                }
                FrameDetections { frame: k, detections }
            })
            .collect();
        let o = LinkOptions {
            named_start: Some(vec![
                ("large".into(), [20.0, 60.0]),
                ("small".into(), small_start),
                ("a".into(), [20.0, 20.0]),
                ("b".into(), [20.0, 90.0]),
            ]),
            radius: 3.0,
            ..options(3)
        };
        let table = super::super::link_detections::link_detections(&frames, &o).table;
        move |k, name| {
            (table.points.iter())
                .find(|p| p.frame == k && p.particle == name)
                .map(|p| (p.x, p.y, p.flag))
                .expect("a point")
        }
    }

    /// A large one passes 10 px from a small one that jitters (its gate is wide) and goes
    /// unseen for two frames. The large one's blob holds one particle of its own mass, not
    /// five of the median's: the small one is bridged, not split from it, and the large one
    /// keeps its detection.
    #[test]
    fn a_large_named_particle_blob_is_weighed_in_its_own_mass() {
        let jitter = |k: usize| 2.0 * (2.7 * k as f64).sin();
        let at = two_sizes(
            10,
            |k| (!(4..6).contains(&k)).then(|| [jitter(k), 70.0 - jitter(k)]),
            [20.0, 70.0],
        );
        for k in 4..6 {
            assert_eq!(
                at(k, "large"),
                (20.0 + k as f64, 60.0, PointFlag::Detected),
                "frame {k}"
            );
            assert_eq!(at(k, "small").2, PointFlag::Interpolated, "frame {k}");
        }
    }

    /// The small one 4 px from the large one, seen until frame 4 and then hidden: its
    /// prediction lies inside the large one's blob, which outweighs the median five times but
    /// holds one particle of the large one's mass, so the small track does not join it
    /// (bridged, not split), and the large one keeps its detection.
    #[test]
    fn a_track_does_not_join_a_named_blob_of_one_large_particle() {
        let at = two_sizes(8, |k| (k < 5).then_some([0.0, 64.0]), [20.0, 64.0]);
        assert_eq!(at(5, "large"), (25.0, 60.0, PointFlag::Detected));
        assert_eq!(at(5, "small").2, PointFlag::Interpolated);
    }
}
