//! Points of a named track that leave its path and come back within a frame: another object
//! taken for the particle in one frame.
//!
//! A particle's image moves with the particle: from one frame to the next its steps change
//! gradually, and even a bounce only turns the step round (the steps into and out of the
//! bounce are about as long as those before and after it). A point that lies far from both
//! its neighbours while they lie near each other, the steps around it short, is not the
//! particle: the linker took another blob (a part of a larger particle, clutter) where the
//! particle's own was missed or looked less like itself. Sweep style 1038 (dark shaded
//! spheres of 9.6 and 24 px): the small one's point in frame 2 lay on a fragment of the large
//! one, 110 px off its path, written without a word.

use std::collections::BTreeMap;

use crate::{PointFlag, TrackTable};

/// How many times the longer of the steps around it each step into and out of a spike must
/// exceed (beyond the particle's diameter): a particle's step changes by no such factor from
/// one frame to the next and back.
const SPIKE_RATIO: f64 = 4.0;

/// Moves every spike of `table`'s tracks (particles of radius `radius`, px) back onto its
/// track's path and flags it interpolated: a detected point, with points of its track in the
/// frames either side, both of whose steps (from the point before and to the point after)
/// exceed the particle's diameter plus [`SPIKE_RATIO`] times the longest of the step between
/// those two neighbours and the steps just outside them. It is placed halfway between its
/// neighbours. Returns a warning per particle naming its frames and the largest jump.
pub(super) fn bridge_spikes(table: &mut TrackTable, radius: f64) -> Vec<String> {
    // Each particle's point indices in frame order (a track holds a frame once).
    let mut tracks: BTreeMap<&str, Vec<usize>> = BTreeMap::new();
    for (i, p) in table.points.iter().enumerate() {
        tracks.entry(p.particle.as_str()).or_default().push(i);
    }
    let at = |i: usize| [table.points[i].x, table.points[i].y];
    let step = |a: usize, b: usize| {
        let (p, q) = (at(a), at(b));
        (q[0] - p[0]).hypot(q[1] - p[1])
    };
    let mut spikes: Vec<(usize, [f64; 2], f64)> = Vec::new();
    for idx in tracks.values_mut() {
        idx.sort_by_key(|&i| table.points[i].frame);
        for w in 1..idx.len().saturating_sub(1) {
            let (before, i, after) = (idx[w - 1], idx[w], idx[w + 1]);
            let frame = table.points[i].frame;
            let consecutive =
                table.points[before].frame + 1 == frame && table.points[after].frame == frame + 1;
            if !consecutive || table.points[i].flag != PointFlag::Detected {
                continue;
            }
            let mut around = step(before, after);
            if w >= 2 {
                around = around.max(step(idx[w - 2], before));
            }
            if let Some(&next) = idx.get(w + 2) {
                around = around.max(step(after, next));
            }
            let bound = 2.0 * radius + SPIKE_RATIO * around;
            let legs = step(before, i).min(step(i, after));
            if legs > bound {
                let (p, q) = (at(before), at(after));
                spikes.push((i, [0.5 * (p[0] + q[0]), 0.5 * (p[1] + q[1])], legs));
            }
        }
    }
    let mut named: BTreeMap<String, (Vec<usize>, f64)> = BTreeMap::new();
    for (i, mid, legs) in spikes {
        let p = &mut table.points[i];
        let entry = named.entry(p.particle.clone()).or_insert((Vec::new(), 0.0));
        entry.0.push(p.frame);
        entry.1 = entry.1.max(legs);
        p.x = mid[0];
        p.y = mid[1];
        p.ep = f64::NAN;
        p.flag = PointFlag::Interpolated;
    }
    named
        .into_iter()
        .map(|(particle, (frames, legs))| {
            let list: Vec<String> = frames.iter().map(usize::to_string).collect();
            format!(
                "{particle}: located up to {legs:.1} px off its path and back within a frame in frame(s) {} (another object taken for it); placed halfway between its neighbours there (flagged interpolated)",
                list.join(", ")
            )
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::TrackPoint;

    fn track(name: &str, path: &[[f64; 2]]) -> Vec<TrackPoint> {
        path.iter()
            .enumerate()
            .map(|(k, p)| TrackPoint::new(k, name.to_string(), p[0], p[1]))
            .collect()
    }

    /// A particle walking 2 px a frame with its frame 3 point on an object 110 px away is
    /// placed back halfway between frames 2 and 4 and named; a ball bouncing off a floor (its
    /// step turned round at full speed, 20 px a frame) and a particle kicked from rest are
    /// left alone.
    #[test]
    fn a_point_off_the_path_and_back_is_bridged_and_named_but_a_bounce_is_not() {
        let mut walk: Vec<[f64; 2]> = (0..8).map(|k| [10.0 + 2.0 * k as f64, 50.0]).collect();
        walk[3] = [126.0, 30.0];
        let bounce: Vec<[f64; 2]> = (0..8)
            .map(|k| [100.0 + 3.0 * k as f64, 200.0 - 20.0 * (k as f64 - 3.5).abs()])
            .collect();
        let kick: Vec<[f64; 2]> = (0..8)
            .map(|k| [300.0 + if k < 4 { 0.0 } else { 30.0 * (k - 3) as f64 }, 50.0])
            .collect();
        let mut table = TrackTable::default();
        table.points.extend(track("walk", &walk));
        table.points.extend(track("bounce", &bounce));
        table.points.extend(track("kick", &kick));
        let before = table.clone();
        let warnings = bridge_spikes(&mut table, 5.0);
        assert_eq!(warnings.len(), 1, "{warnings:?}");
        assert!(warnings[0].starts_with("walk: located up to"), "{}", warnings[0]);
        assert!(warnings[0].contains("in frame(s) 3 "), "{}", warnings[0]);
        let p = &table.points[3];
        assert_eq!((p.x, p.y, p.flag), (16.0, 50.0, PointFlag::Interpolated));
        // Positions and flags (the NaN masses compare unequal).
        let of = |t: &TrackTable, name: &str| -> Vec<(f64, f64, PointFlag)> {
            t.points
                .iter()
                .filter(|p| p.particle == name)
                .map(|p| (p.x, p.y, p.flag))
                .collect()
        };
        assert_eq!(of(&table, "bounce"), of(&before, "bounce"));
        assert_eq!(of(&table, "kick"), of(&before, "kick"));
    }
}
