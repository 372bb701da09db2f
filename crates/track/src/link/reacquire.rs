//! Re-acquisition of named tracks that neither pass linked.

use super::claimants::Claimants;
use super::single_particle::{finite_median, SingleParticle};
use super::track::{Prediction, Track};
use crate::assignment::{solve_sparse, SparseProblem};
use crate::locate::Detection;
use crate::track_table::PointFlag;

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
pub(super) fn reacquire(
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
pub(super) struct BlobColumns {
    /// The blob of each column.
    pub(super) blob: Vec<usize>,
    /// `first[j]..first[j + 1]`: blob `j`'s columns.
    pub(super) first: Vec<usize>,
}

impl BlobColumns {
    pub(super) fn of(dets: &[Detection], one: &SingleParticle) -> BlobColumns {
        let capacities: Vec<usize> = dets.iter().map(|d| one.capacity(d.mass)).collect();
        BlobColumns::with(&capacities)
    }

    /// The columns of blobs that hold `capacities[j]` particles each.
    pub(super) fn with(capacities: &[usize]) -> BlobColumns {
        let mut blob = Vec::with_capacity(capacities.len());
        let mut first = Vec::with_capacity(capacities.len() + 1);
        for (j, &c) in capacities.iter().enumerate() {
            first.push(blob.len());
            blob.extend(std::iter::repeat(j).take(c));
        }
        first.push(blob.len());
        BlobColumns { blob, first }
    }

    pub(super) fn count(&self) -> usize {
        self.blob.len()
    }

    /// Allows row `row` every column of blob `j` at `cost`, later copies a little dearer so
    /// that a lone row takes the first.
    pub(super) fn push_pairs(&self, problem: &mut SparseProblem, row: usize, j: usize, cost: f64) {
        for (copy, c) in (self.first[j]..self.first[j + 1]).enumerate() {
            problem.pairs.push((row, c, cost + 1e-3 * copy as f64));
        }
    }
}
