//! Which of a crossing's positions belongs to which track, judged from the motion.

use super::relocate::{dist2, Group};
use crate::disjoint_sets::DisjointSets;
use crate::link::Ambiguity;
use crate::track_table::TrackPoint;

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
pub(super) fn rename_by_motion(
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
