//! The linking loop: each frame's detections assigned to the live tracks.

use super::claimants::Claimants;
use super::options::{diagonal, FrameDetections, LinkOptions};
use super::outcome::{collect_runs, AmbiguityKind, LinkOutcome};
use super::reacquire::{reacquire, BlobColumns};
use super::settle::settle_crossings;
use super::single_particle::SingleParticle;
use super::step_bound::StepBound;
use super::track::{point_from, smooth_bridges, speed, start_tracks, Point, Prediction, Track};
use super::{APPEARANCE_GATE_SIGMAS, GATE_SIGMAS};
use crate::appearance::{Appearance, AppearanceSpread, TrackAppearance};
use crate::assignment::{solve_sparse, SparseProblem};
use crate::point_grid::{nearest_other, PointGrid};
use crate::track_table::{PointFlag, TrackPoint, TrackTable};

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
