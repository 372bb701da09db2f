//! Crossings resolved after linking: which particle left a merge as which.
//!
//! While particles share a blob (or go unseen), their tracks are carried by prediction, and
//! the frame they separate in is assigned from predictions made before the merge: a merge
//! that lasts, starts before any velocity is known (particles that begin inside one blob),
//! or hides a change of motion, can hand the separated particles to the wrong tracks. Once
//! the whole recording is linked, each such crossing is judged again with what came after
//! it: each track's motion before the crossing and each candidate continuation's motion
//! after it are extrapolated (straight lines fitted to a few located points) to the middle of
//! the gap, and the continuations are handed out by the permutation that makes them meet
//! best. Where no order meets well that way, or another meets nearly as well, the motion may
//! have turned inside the crossing (a bounce off a wall): then a motion and a continuation
//! meet where their lines come closest within the gap, at a cost for any change of speed
//! (a bounce keeps the speed, two different particles seldom share it). A particle that starts inside the crossing has no motion before it; its named start
//! position is what the continuation is extrapolated back to. Where an order meets well,
//! each particle's path through the crossing is the cubic joining its motion before and
//! after, which the caller uses to hand out the blobs located inside the crossing and to
//! place the points it had predicted.

use crate::disjoint_sets::DisjointSets;
use crate::point_grid::PointGrid;

/// One point of a track as the crossing pass sees it.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Seen {
    /// Position, px.
    pub x: f64,
    /// Position, px.
    pub y: f64,
    /// Located from the particle's own blob, with no other detection near enough to share
    /// its light (a clean measurement of this particle alone).
    pub clean: bool,
    /// Placed from a prediction (a shared blob split, or a bridged gap): the ambiguity
    /// itself.
    pub predicted: bool,
}

/// A crossing judged: from `frame` on, track `tracks[k]` continues with what track
/// `tracks[from[k]]` held (the identity when the linker's order was right), and inside it
/// (frames `start` to `frame - 1`) each track's particle followed `bridges[k]`.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct Reassignment {
    /// First frame of the crossing (the first point placed from a prediction or located in
    /// a crowd).
    pub start: usize,
    /// First frame after the crossing: the continuations are exchanged from here on.
    pub frame: usize,
    /// The tracks of the crossing (indices into the caller's tracks).
    pub tracks: Vec<usize>,
    /// For each of `tracks`, the position in `tracks` of the track whose continuation it
    /// takes.
    pub from: Vec<usize>,
    /// For each of `tracks`, its particle's path through the crossing.
    pub bridges: Vec<Bridge>,
}

/// A particle's path through a crossing: the cubic (Hermite) that leaves the motion before
/// it and joins the motion after it with their positions and velocities.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Bridge {
    t0: f64,
    t1: f64,
    p0: [f64; 2],
    v0: [f64; 2],
    p1: [f64; 2],
    v1: [f64; 2],
}

impl Bridge {
    fn between(before: &Line, after: &Line) -> Bridge {
        // Before: from its last point (its own time when it is a single start position).
        let t0 = before.last;
        let t1 = after.first;
        let p0 = before.at(t0);
        let p1 = after.at(t1);
        let v1 = after.v.unwrap_or([0.0, 0.0]);
        let span = (t1 - t0).max(1.0);
        // A start position has no velocity: the chord's.
        let v0 = before
            .v
            .unwrap_or([(p1[0] - p0[0]) / span, (p1[1] - p0[1]) / span]);
        Bridge {
            t0,
            t1,
            p0,
            v0,
            p1,
            v1,
        }
    }

    /// Position at frame `t`, px.
    pub fn at(&self, t: f64) -> [f64; 2] {
        let h = (self.t1 - self.t0).max(1e-9);
        let s = ((t - self.t0) / h).clamp(0.0, 1.0);
        let (s2, s3) = (s * s, s * s * s);
        let (h00, h10, h01, h11) = (
            2.0 * s3 - 3.0 * s2 + 1.0,
            s3 - 2.0 * s2 + s,
            -2.0 * s3 + 3.0 * s2,
            s3 - s2,
        );
        [0, 1].map(|k| h00 * self.p0[k] + h10 * h * self.v0[k] + h01 * self.p1[k] + h11 * h * self.v1[k])
    }
}

/// Located points fitted on each side of a crossing.
const FIT_POINTS: usize = 3;
/// How far from the crossing those points may lie, frames.
const FIT_REACH: usize = 8;
/// Points fitted on one side of a crossing lie on one straight motion when none is farther
/// than this fraction of the crossing distance from their line; otherwise the farthest from
/// the crossing is dropped (the motion turned there: a bounce).
const STRAIGHT: f64 = 0.05;
/// Most tracks in one crossing judged (all orders of their continuations are tried).
const MAX_TRACKS: usize = 5;

/// Finds the crossings whose continuations meet the tracks' earlier motion better in another
/// order. `tracks[i]` holds one point per frame from frame `first[i]`. `near` (px) is how
/// close a predicted point must come to another track's point in the same frame for the two
/// to be one crossing. `starts[i]`, when given, is track `i`'s start position (its particle
/// at frame `first[i]`), used where a track has no clean point before its crossing.
pub(crate) fn resolve(
    tracks: &[Vec<Seen>],
    first: &[usize],
    starts: Option<&[[f64; 2]]>,
    near: f64,
) -> Vec<Reassignment> {
    let n = tracks.len();
    let at = |i: usize, t: usize| -> Option<&Seen> { t.checked_sub(first[i]).and_then(|k| tracks[i].get(k)) };
    let end = (0..n).map(|i| first[i] + tracks[i].len()).max().unwrap_or(0);
    // Runs of predicted points per track: (track, first frame, last frame).
    let mut runs: Vec<(usize, usize, usize)> = Vec::new();
    for (i, pts) in tracks.iter().enumerate() {
        let mut k = 0;
        while k < pts.len() {
            if !pts[k].predicted {
                k += 1;
                continue;
            }
            let s = k;
            while k < pts.len() && pts[k].predicted {
                k += 1;
            }
            // Crowded detections next to the run belong to the crossing: a blob located
            // among others may be another particle's.
            let crowded = |p: &Seen| !p.clean && !p.predicted;
            let mut a = s;
            while a > 0 && s - a < FIT_REACH && crowded(&pts[a - 1]) {
                a -= 1;
            }
            let mut b = k;
            while b < pts.len() && b - k < FIT_REACH && crowded(&pts[b]) {
                b += 1;
            }
            runs.push((i, first[i] + a, first[i] + b - 1));
        }
    }
    // Crossings: union of runs and of the tracks that came near them while they ran.
    let mut sets = DisjointSets::new(runs.len());
    // Each run's partner tracks: (run, other track).
    let mut partners: Vec<(usize, usize)> = Vec::new();
    // The tracks' points in each frame some run covers, and the track of each.
    let mut frame_points: std::collections::HashMap<usize, (Vec<[f64; 2]>, Vec<usize>)> = Default::default();
    for &(i, s, e) in &runs {
        for t in (s..=e).filter(|&t| at(i, t).is_some()) {
            frame_points.entry(t).or_insert_with(|| {
                let owners: Vec<usize> = (0..n).filter(|&j| at(j, t).is_some()).collect();
                let pts: Vec<[f64; 2]> = owners
                    .iter()
                    .filter_map(|&j| at(j, t).map(|q| [q.x, q.y]))
                    .collect();
                (pts, owners)
            });
        }
    }
    let grids: std::collections::HashMap<usize, PointGrid> = frame_points
        .iter()
        .map(|(&t, (pts, _))| (t, PointGrid::new(pts)))
        .collect();
    for (r, &(i, s, e)) in runs.iter().enumerate() {
        for t in s..=e {
            let Some(p) = at(i, t) else { continue };
            let owners = &frame_points[&t].1;
            grids[&t].within(&[p.x, p.y], near, |k, d2| {
                // Strictly nearer than `near`, as the kd-tree this replaced counted them.
                if d2 < near * near && owners[k] != i {
                    partners.push((r, owners[k]));
                }
            });
        }
    }
    partners.sort_unstable();
    partners.dedup();
    // Two runs are one crossing when they overlap in time and one's track is the other's
    // partner.
    for &(r, j) in &partners {
        let (_, s, e) = runs[r];
        for (q, &(jj, s2, e2)) in runs.iter().enumerate() {
            if jj == j && s2 <= e + 1 && s <= e2 + 1 {
                sets.union(r, q);
            }
        }
    }
    let mut groups: std::collections::BTreeMap<usize, (Vec<usize>, usize, usize)> = Default::default();
    for (r, &(i, s, e)) in runs.iter().enumerate() {
        let g = groups.entry(sets.root(r)).or_insert((Vec::new(), usize::MAX, 0));
        g.0.push(i);
        g.1 = g.1.min(s);
        g.2 = g.2.max(e);
    }
    for &(r, j) in &partners {
        let root = sets.root(r);
        if let Some(g) = groups.get_mut(&root) {
            g.0.push(j);
        }
    }

    let mut out = Vec::new();
    for (_, (mut members, s, e)) in groups {
        members.sort_unstable();
        members.dedup();
        if members.len() < 2 || members.len() > MAX_TRACKS || e + 1 >= end {
            continue;
        }
        let swap_at = e + 1;
        // Motion before and after, per member.
        let mut before = Vec::new();
        let mut after = Vec::new();
        // The nearest clean points of track `i` over `frames`, nearest first, as many as
        // lie on one straight motion (a bounce off a wall among them would turn the line).
        let clean = |i: usize, frames: &mut dyn Iterator<Item = usize>| -> Vec<(f64, [f64; 2])> {
            let mut points: Vec<(f64, [f64; 2])> = frames
                .filter_map(|t| {
                    at(i, t)
                        .filter(|p| p.clean && !p.predicted)
                        .map(|p| (t as f64, [p.x, p.y]))
                })
                .take(FIT_POINTS)
                .collect();
            while points.len() > 2
                && Line::fit(&points).is_some_and(|l| l.largest_residual(&points) > STRAIGHT * near)
            {
                points.pop();
            }
            points
        };
        for &i in &members {
            let mut pre = clean(i, &mut (s.saturating_sub(FIT_REACH)..s).rev());
            if pre.is_empty() {
                // A particle that starts inside the crossing: its start position.
                if let Some(st) = starts.filter(|_| s <= first[i] + 1) {
                    pre.push((first[i] as f64, st[i]));
                }
            }
            let post = clean(i, &mut (swap_at..(swap_at + FIT_REACH).min(end)));
            before.push(Line::fit(&pre));
            after.push(Line::fit(&post));
        }
        let (Some(before), Some(after)) = (
            before.into_iter().collect::<Option<Vec<Line>>>(),
            after.into_iter().collect::<Option<Vec<Line>>>(),
        ) else {
            continue;
        };
        // Orders judged by how the motions meet: first as straight lines; where no order
        // meets well that way, the motion turned inside the crossing (a bounce), and the
        // lines may instead touch anywhere in the gap, provided the speed is kept.
        let good = members.len() as f64 * (0.25 * near).powi(2);
        // (cost of the linker's order, best cost, best order, second-best cost)
        let decide = |meet: &dyn Fn(&Line, &Line) -> f64| -> (f64, f64, Vec<usize>, f64) {
            let cost = |from: &[usize]| -> f64 {
                from.iter()
                    .enumerate()
                    .map(|(k, &f)| meet(&before[k], &after[f]))
                    .sum()
            };
            let identity: Vec<usize> = (0..members.len()).collect();
            let kept = cost(&identity);
            let mut best = (f64::INFINITY, identity);
            let mut second = f64::INFINITY;
            permutations(members.len(), &mut |p| {
                let c = cost(p);
                if c < best.0 {
                    second = best.0;
                    best = (c, p.to_vec());
                } else if c < second {
                    second = c;
                }
            });
            (kept, best.0, best.1, second)
        };
        // Straight lines decide when one order meets well and every other at least four
        // times worse; otherwise the motion may have turned.
        let (mut kept, mut best, mut order, second) = decide(&|a, b| a.mismatch(b));
        if best > good || second < 4.0 * best {
            (kept, best, order, _) = decide(&|a, b| a.mismatch(b).min(a.touching(b)) + a.speed_change(b));
        }
        // The best order must meet well (within a quarter of the crossing distance per track
        // on average) and, to overrule the linker, clearly better (by half, and by more than
        // a pixel). Where no order meets well nothing is known about who is who.
        let identity: Vec<usize> = (0..members.len()).collect();
        let from = if order != identity && best < 0.5 * kept && kept - best > 1.0 {
            order
        } else {
            identity
        };
        if best <= good {
            let bridges = from
                .iter()
                .enumerate()
                .map(|(k, &f)| Bridge::between(&before[k], &after[f]))
                .collect();
            out.push(Reassignment {
                start: s,
                frame: swap_at,
                tracks: members,
                from,
                bridges,
            });
        }
    }
    out
}

/// A straight line through a few located points, `p(t) = p0 + v (t - t0)`; a single point
/// has no velocity and is compared where it was.
#[derive(Clone, Copy, Debug)]
struct Line {
    t0: f64,
    p0: [f64; 2],
    v: Option<[f64; 2]>,
    /// Earliest and latest times of the points fitted.
    first: f64,
    last: f64,
}

impl Line {
    /// Least-squares line through `points` (time, position); `None` without points.
    fn fit(points: &[(f64, [f64; 2])]) -> Option<Line> {
        let m = points.len() as f64;
        if points.is_empty() {
            return None;
        }
        let t0 = points.iter().map(|p| p.0).sum::<f64>() / m;
        let p0 = [0, 1].map(|k| points.iter().map(|p| p.1[k]).sum::<f64>() / m);
        let stt: f64 = points.iter().map(|p| (p.0 - t0).powi(2)).sum();
        let v = (stt > 0.0)
            .then(|| [0, 1].map(|k| points.iter().map(|p| (p.0 - t0) * (p.1[k] - p0[k])).sum::<f64>() / stt));
        let first = points.iter().map(|p| p.0).fold(f64::INFINITY, f64::min);
        let last = points.iter().map(|p| p.0).fold(f64::NEG_INFINITY, f64::max);
        Some(Line {
            t0,
            p0,
            v,
            first,
            last,
        })
    }

    /// The largest distance of `points` from the line, px.
    fn largest_residual(&self, points: &[(f64, [f64; 2])]) -> f64 {
        points
            .iter()
            .map(|(t, p)| {
                let q = self.at(*t);
                (p[0] - q[0]).hypot(p[1] - q[1])
            })
            .fold(0.0, f64::max)
    }

    fn at(&self, t: f64) -> [f64; 2] {
        match self.v {
            Some(v) => [
                self.p0[0] + v[0] * (t - self.t0),
                self.p0[1] + v[1] * (t - self.t0),
            ],
            None => self.p0,
        }
    }

    /// Squared distance of closest approach of this (earlier) motion and `later` between
    /// this one's last point and `later`'s first (where a bounce inside the gap would have
    /// turned the one into the other); infinite without both velocities.
    fn touching(&self, later: &Line) -> f64 {
        let (Some(va), Some(vb)) = (self.v, later.v) else {
            return f64::INFINITY;
        };
        let (ta, tb) = (self.last, later.first.max(self.last));
        let a = self.at(ta);
        let b = later.at(ta);
        let d0 = [a[0] - b[0], a[1] - b[1]];
        let w = [va[0] - vb[0], va[1] - vb[1]];
        let ww = w[0] * w[0] + w[1] * w[1];
        let t = if ww > 0.0 {
            (-(d0[0] * w[0] + d0[1] * w[1]) / ww).clamp(0.0, tb - ta)
        } else {
            0.0
        };
        (d0[0] + w[0] * t).powi(2) + (d0[1] + w[1] * t).powi(2)
    }

    /// Squared change of speed between this motion and `later`, times the gap's length
    /// squared: the distance it would open over the gap, px² (0 without both velocities).
    fn speed_change(&self, later: &Line) -> f64 {
        let (Some(va), Some(vb)) = (self.v, later.v) else {
            return 0.0;
        };
        let gap = (later.first - self.last).max(1.0);
        (va[0].hypot(va[1]) - vb[0].hypot(vb[1])).powi(2) * gap * gap
    }

    /// Squared distance at which this (earlier) motion and `later` meet: both extrapolated
    /// to the middle of the gap between them, or to this one's own time when it has no
    /// velocity.
    fn mismatch(&self, later: &Line) -> f64 {
        let t = if self.v.is_some() {
            0.5 * (self.t0 + later.t0)
        } else {
            self.t0
        };
        let (a, b) = (self.at(t), later.at(t));
        (a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2)
    }
}

/// Calls `f` with every permutation of `0..n` (Heap's algorithm).
pub(crate) fn permutations(n: usize, f: &mut dyn FnMut(&[usize])) {
    let mut p: Vec<usize> = (0..n).collect();
    let mut c = vec![0usize; n];
    f(&p);
    let mut i = 0;
    while i < n {
        if c[i] < i {
            if i % 2 == 0 {
                p.swap(0, i);
            } else {
                p.swap(c[i], i);
            }
            f(&p);
            c[i] += 1;
            i = 0;
        } else {
            c[i] = 0;
            i += 1;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn seen(x: f64, y: f64) -> Seen {
        Seen {
            x,
            y,
            clean: true,
            predicted: false,
        }
    }

    /// A particle bounces off a wall (its x velocity reverses) while another passes it, and
    /// the linker handed each the other's continuation. Straight lines do not meet across
    /// the bounce; the motions touching in the gap at an unchanged speed do.
    #[test]
    fn a_swap_across_a_bounce_is_undone() {
        let a = |t: usize| {
            let t = t as f64;
            let x = if t <= 3.0 {
                10.0 + 2.0 * t
            } else {
                16.0 - 2.0 * (t - 3.0)
            };
            [x, 50.0 + t]
        };
        let b = |t: usize| [19.0 - t as f64, 57.0 - t as f64];
        let track = |own: &dyn Fn(usize) -> [f64; 2], other: &dyn Fn(usize) -> [f64; 2]| -> Vec<Seen> {
            (0..12)
                .map(|t| {
                    let p = if t >= 6 { other(t) } else { own(t) };
                    Seen {
                        predicted: (3..=5).contains(&t),
                        ..seen(p[0], p[1])
                    }
                })
                .collect()
        };
        let tracks = vec![track(&a, &b), track(&b, &a)];
        let r = resolve(&tracks, &[0, 0], None, 10.0);
        assert_eq!(r.len(), 1, "{r:?}");
        assert_eq!((r[0].frame, &r[0].from), (6, &vec![1, 0]));
    }

    /// A particle that bounced off a wall between the located points before a crossing:
    /// its motion before the crossing is the one after the bounce, so its path through the
    /// crossing stays on it (a line fitted over the bounce would bend it toward the wall).
    #[test]
    fn a_bounce_just_before_a_crossing_does_not_bend_the_path() {
        // a: up at 2 px/frame until t = 5.5 (y = 3), then down; b passes it at frame 8.
        let a = |t: usize| {
            let t = t as f64;
            let y = if t <= 5.5 {
                14.0 - 2.0 * t
            } else {
                3.0 + 2.0 * (t - 5.5)
            };
            [30.0 + 0.5 * t, y]
        };
        let b = |t: usize| [40.0 - t as f64, 8.0 + 0.5 * t as f64];
        let track = |own: &dyn Fn(usize) -> [f64; 2]| -> Vec<Seen> {
            (0..16)
                .map(|t| {
                    let p = own(t);
                    Seen {
                        predicted: t == 8,
                        ..seen(p[0], p[1])
                    }
                })
                .collect()
        };
        let r = resolve(&[track(&a), track(&b)], &[0, 0], None, 10.0);
        assert_eq!(r.len(), 1, "{r:?}");
        let q = r[0].bridges[0].at(8.0);
        let truth = a(8);
        let e = (q[0] - truth[0]).hypot(q[1] - truth[1]);
        assert!(
            e < 0.1,
            "a's path at frame 8: {q:?}, truth {truth:?} ({e:.2} px off)"
        );
    }

    #[test]
    fn every_permutation_once() {
        let mut all = Vec::new();
        permutations(4, &mut |p| all.push(p.to_vec()));
        assert_eq!(all.len(), 24);
        all.sort();
        all.dedup();
        assert_eq!(all.len(), 24);
    }

    /// Two particles cross head on at frame 5; the linker (here, by construction) handed
    /// each the other's continuation. The pass gives them back.
    #[test]
    fn a_swapped_crossing_is_undone_and_a_kept_one_left() {
        let a: Vec<[f64; 2]> = (0..12).map(|t| [10.0 + 2.0 * t as f64, 50.0]).collect();
        let b: Vec<[f64; 2]> = (0..12)
            .map(|t| [30.0 - 2.0 * t as f64 + 0.0, 51.0 + 0.5 * t as f64])
            .collect();
        let track = |own: &[[f64; 2]], other: &[[f64; 2]], swap: bool| -> Vec<Seen> {
            (0..12)
                .map(|t| {
                    let p = if swap && t >= 7 { other[t] } else { own[t] };
                    Seen {
                        predicted: (4..=6).contains(&t),
                        ..seen(p[0], p[1])
                    }
                })
                .collect()
        };
        for swap in [true, false] {
            let tracks = vec![track(&a, &b, swap), track(&b, &a, swap)];
            let r = resolve(&tracks, &[0, 0], None, 10.0);
            assert_eq!(r.len(), 1, "{r:?}");
            assert_eq!((r[0].start, r[0].frame, &r[0].tracks), (4, 7, &vec![0, 1]));
            assert_eq!(r[0].from, if swap { vec![1, 0] } else { vec![0, 1] });
            // The bridges follow the particles through the crossing.
            for (k, truth) in [&a, &b].iter().enumerate() {
                for t in 4..7 {
                    let p = r[0].bridges[k].at(t as f64);
                    let e = (p[0] - truth[t][0]).hypot(p[1] - truth[t][1]);
                    assert!(e < 1e-6, "track {k} frame {t}: {p:?} for {:?}", truth[t]);
                }
            }
        }
    }
}
