//! Crossings settled after linking: the judgement of [`crate::crossing`] applied to the
//! linked tracks, their points and the ambiguity events that describe them.

use super::outcome::AmbiguityKind;
use super::single_particle::SingleParticle;
use super::track::{Point, Track};
use crate::crossing::{self, Seen};
use crate::track_table::PointFlag;

/// Settles the crossings [`crossing::resolve`] judges: inside each, the blobs located there
/// are handed to the particles whose paths they lie on and the predicted points are placed on
/// those paths (a split blob's particles about its centroid); after it, the tracks take the
/// continuations in the order their motion says. `events` (frame, kind, tracks) follow the
/// points they describe. `starts[i]` is track `i`'s start position.
pub(super) fn settle_crossings(
    tracks: &mut [Track],
    events: &mut Vec<(usize, AmbiguityKind, Vec<usize>)>,
    starts: &[[f64; 2]],
    near: f64,
    one: &SingleParticle,
) {
    let views: Vec<Vec<Seen>> = tracks
        .iter()
        .map(|tr| {
            tr.points
                .iter()
                .map(|p| Seen {
                    x: p.x,
                    y: p.y,
                    clean: p.clean && p.flag == PointFlag::Detected,
                    predicted: p.flag != PointFlag::Detected,
                })
                .collect()
        })
        .collect();
    let first: Vec<usize> = tracks.iter().map(|t| t.first_frame).collect();
    let mut found = crossing::resolve(&views, &first, Some(starts), near);
    found.sort_by_key(|r| r.frame);
    // Crossings are judged on the tracks as linked. `holder[o]`: the track now holding what
    // track `o` held from `settled[o]` on (a crossing that starts before an exchange already
    // made for one of its tracks is left as it is).
    let mut holder: Vec<usize> = (0..tracks.len()).collect();
    let mut settled: Vec<usize> = vec![0; tracks.len()];
    let index = |tr: &Track, t: usize| t.checked_sub(tr.first_frame).filter(|&k| k < tr.points.len());
    for r in found {
        if r.tracks.iter().any(|&o| settled[o] > r.start) {
            continue;
        }
        let now: Vec<usize> = r.tracks.iter().map(|&o| holder[o]).collect();
        let m = now.len();
        for t in r.start..r.frame {
            let Some(ks) = now
                .iter()
                .map(|&i| index(&tracks[i], t))
                .collect::<Option<Vec<usize>>>()
            else {
                continue;
            };
            let path: Vec<[f64; 2]> = r.bridges.iter().map(|b| b.at(t as f64)).collect();
            // The located blobs to the particles whose paths they lie on (moving as few
            // points as that allows).
            let located: Vec<Option<[f64; 2]>> = (0..m)
                .map(|a| {
                    let p = &tracks[now[a]].points[ks[a]];
                    (p.flag == PointFlag::Detected).then_some([p.x, p.y])
                })
                .collect();
            let mut best: (f64, Vec<usize>) = (f64::INFINITY, (0..m).collect());
            crossing::permutations(m, &mut |sigma| {
                let cost: f64 = (0..m)
                    .map(|a| {
                        let moved = if sigma[a] == a { 0.0 } else { 1e-6 };
                        moved
                            + located[a].map_or(0.0, |p| {
                                let q = path[sigma[a]];
                                (p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2)
                            })
                    })
                    .sum();
                if cost < best.0 {
                    best = (cost, sigma.to_vec());
                }
            });
            let sigma = best.1;
            if sigma.iter().enumerate().any(|(a, &b)| a != b) {
                let old: Vec<Point> = (0..m).map(|a| tracks[now[a]].points[ks[a]].clone()).collect();
                for (a, p) in old.into_iter().enumerate() {
                    let b = sigma[a];
                    tracks[now[b]].points[ks[b]] = p;
                }
                relabel_events(events, t..t + 1, &now, &sigma);
            }
            // A located blob measurably heavier or wider than one particle, with the path of
            // a particle that was bridged here running through it: both were in it (a
            // merged blob the linker gave to one of them). Both are placed about its
            // centroid, flagged as split.
            for a in 0..m {
                let p = tracks[now[a]].points[ks[a]].clone();
                if p.flag != PointFlag::Detected || !one.holds_more_than(p.mass, p.size, 1) {
                    continue;
                }
                let cap = one.capacity(p.mass).max(2);
                let mut others: Vec<(f64, usize)> = (0..m)
                    .filter(|&b| b != a && tracks[now[b]].points[ks[b]].flag == PointFlag::Interpolated)
                    .map(|b| ((path[b][0] - p.x).hypot(path[b][1] - p.y), b))
                    .filter(|&(d, _)| d <= 0.5 * near)
                    .collect();
                others.sort_by(|x, y| x.0.total_cmp(&y.0));
                others.truncate(cap - 1);
                if others.is_empty() {
                    continue;
                }
                let group: Vec<usize> = std::iter::once(a).chain(others.iter().map(|o| o.1)).collect();
                let g = group.len() as f64;
                let middle = group
                    .iter()
                    .fold([0.0, 0.0], |s, &b| [s[0] + path[b][0] / g, s[1] + path[b][1] / g]);
                for &b in &group {
                    let q = &mut tracks[now[b]].points[ks[b]];
                    *q = Point {
                        x: p.x + path[b][0] - middle[0],
                        y: p.y + path[b][1] - middle[1],
                        mass: p.mass / g,
                        size: p.size,
                        ep: p
                            .ep
                            .max((path[b][0] - q.x).hypot(path[b][1] - q.y).min(0.5 * near)),
                        flag: PointFlag::Split,
                        emit: true,
                        clean: false,
                    };
                }
                let ids: Vec<usize> = group.iter().map(|&b| now[b]).collect();
                for (f, kind, e) in events.iter_mut() {
                    if *f == t && *kind == AmbiguityKind::Missing && e.iter().all(|i| ids.contains(i)) {
                        e.clear();
                    }
                }
                events.push((t, AmbiguityKind::Merged, ids));
            }
            // Predicted points on the paths: bridged ones on their own, split ones about
            // their shared blob's centroid (the points of one blob carry its size and share
            // of mass).
            let key = |p: &Point| (p.mass.to_bits(), p.size.to_bits());
            let pts: Vec<Point> = (0..m).map(|a| tracks[now[a]].points[ks[a]].clone()).collect();
            for a in 0..m {
                let p = &pts[a];
                let place = match p.flag {
                    PointFlag::Detected => continue,
                    PointFlag::Interpolated => path[a],
                    PointFlag::Split => {
                        let group: Vec<usize> = (0..m)
                            .filter(|&b| pts[b].flag == PointFlag::Split && key(&pts[b]) == key(p))
                            .collect();
                        let g = group.len() as f64;
                        let mean = |v: &dyn Fn(usize) -> [f64; 2]| {
                            group
                                .iter()
                                .fold([0.0, 0.0], |s, &b| [s[0] + v(b)[0] / g, s[1] + v(b)[1] / g])
                        };
                        let centroid = mean(&|b| [pts[b].x, pts[b].y]);
                        let middle = mean(&|b| path[b]);
                        [
                            centroid[0] + path[a][0] - middle[0],
                            centroid[1] + path[a][1] - middle[1],
                        ]
                    }
                };
                let q = &mut tracks[now[a]].points[ks[a]];
                q.x = place[0];
                q.y = place[1];
            }
        }
        // After the crossing: the continuations in the order the motion says.
        if r.from.iter().enumerate().any(|(k, &f)| k != f) {
            let tails: Vec<Vec<Point>> = now
                .iter()
                .map(|&i| {
                    let cut = (r.frame - tracks[i].first_frame).min(tracks[i].points.len());
                    tracks[i].points.split_off(cut)
                })
                .collect();
            let mut tails: Vec<Option<Vec<Point>>> = tails.into_iter().map(Some).collect();
            for (k, &f) in r.from.iter().enumerate() {
                if let Some(tail) = tails[f].take() {
                    tracks[now[k]].points.extend(tail);
                }
            }
            // What track `now[f]` held moves to `now[k]`.
            let mut sigma = vec![0; m];
            for (k, &f) in r.from.iter().enumerate() {
                sigma[f] = k;
            }
            relabel_events(events, r.frame..usize::MAX, &now, &sigma);
            let old = holder.clone();
            for (k, &f) in r.from.iter().enumerate() {
                holder[r.tracks[f]] = old[r.tracks[k]];
            }
        }
        for &o in &r.tracks {
            settled[o] = r.frame;
        }
    }
}

/// Renames the tracks of the events in `frames`: `now[a]` becomes `now[sigma[a]]`.
fn relabel_events(
    events: &mut [(usize, AmbiguityKind, Vec<usize>)],
    frames: std::ops::Range<usize>,
    now: &[usize],
    sigma: &[usize],
) {
    for (_, _, ids) in events.iter_mut().filter(|e| frames.contains(&e.0)) {
        for id in ids.iter_mut() {
            if let Some(a) = now.iter().position(|&i| i == *id) {
                *id = now[sigma[a]];
            }
        }
    }
}
