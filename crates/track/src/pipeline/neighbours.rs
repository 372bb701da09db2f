//! [`Neighbours`]: one frame's estimates bucketed for the plane gate's neighbour queries.
//!
//! The plane gate ([`super::plane::planes_move_points`]) asks, for every tracked point of a
//! sample frame, which detection is its own and, for that detection, how far its nearest
//! neighbour lies and which others lie close enough to reach its ring. Asked of every
//! detection in turn, those were three scans of the whole frame per point: at N = 1000
//! (40 frames, one thread, callgrind) about 230 M of a run's 3088 M instructions. A
//! [`PointGrid`] answers them from a few cells, with the same answers to the bit: the
//! grid only proposes candidates (with a margin beyond the radius), and the tests that
//! decide are the brute-force scans' own ([`closer_than`], [`nearest_distance`]).

use crate::distance::{closer_than, nearest_distance};
use crate::point_grid::PointGrid;

/// Relative margin by which a candidate search reaches beyond its radius, so that no point
/// the exact test keeps is lost to the rounding of a squared distance (about 1e-16).
const SEARCH_MARGIN: f64 = 1e-6;

/// One frame's estimates (px) and their grid.
pub(super) struct Neighbours<'a> {
    /// The estimates, px.
    pub(super) points: &'a [[f64; 2]],
    grid: PointGrid<'a>,
}

impl<'a> Neighbours<'a> {
    /// Buckets `points` (px, finite).
    pub(super) fn new(points: &'a [[f64; 2]]) -> Neighbours<'a> {
        Neighbours {
            points,
            grid: PointGrid::new(points),
        }
    }

    /// Indices of the points other than `i` within `radius` px of point `i` (and a little
    /// beyond: [`SEARCH_MARGIN`]), in index order.
    fn candidates(&self, c: [f64; 2], skip: usize, radius: f64) -> Vec<usize> {
        let mut found = Vec::new();
        self.grid.within(&c, radius * (1.0 + SEARCH_MARGIN), |j, _| {
            if j != skip {
                found.push(j);
            }
        });
        found.sort_unstable();
        found
    }

    /// For point `i`: the distance to its nearest other point, px, and the other points
    /// closer than `radius` px (`hypot` distances), in index order. The distance is
    /// [`nearest_distance`]'s over all points to the bit wherever it is below `radius`;
    /// otherwise it is at least `radius` (infinite when no point lies near).
    pub(super) fn near(&self, i: usize, radius: f64) -> (f64, Vec<[f64; 2]>) {
        let c = self.points[i];
        let near: Vec<[f64; 2]> = self
            .candidates(c, i, radius)
            .into_iter()
            .map(|j| self.points[j])
            .collect();
        // Every point nearer than a candidate is itself a candidate, so the least distance
        // among them is the least of all.
        let nearest = nearest_distance(&near, c, usize::MAX);
        let others = near
            .into_iter()
            .filter(|p| closer_than(p[0] - c[0], p[1] - c[1], radius))
            .collect();
        (nearest, others)
    }

    /// The first point (lowest index) closer than `radius` px to `p` (`hypot` distance), as
    /// a scan of every point in order finds it.
    pub(super) fn first_within(&self, p: [f64; 2], radius: f64) -> Option<usize> {
        self.candidates(p, usize::MAX, radius).into_iter().find(|&j| {
            let q = self.points[j];
            closer_than(p[0] - q[0], p[1] - q[1], radius)
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Random point sets from fixed seeds: uniform, clustered and on a lattice (ties).
    fn point_sets() -> Vec<Vec<[f64; 2]>> {
        let mut state = 0x2545_f491_4f6c_dd1d_u64;
        let mut next = move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 11) as f64 / (1u64 << 53) as f64
        };
        let mut sets = Vec::new();
        for n in [1, 2, 5, 40, 300, 1000] {
            sets.push((0..n).map(|_| [512.0 * next(), 512.0 * next()]).collect());
            sets.push(
                (0..n)
                    .map(|_| [200.0 + 30.0 * next(), 100.0 + 30.0 * next()])
                    .collect(),
            );
        }
        sets.push(
            (0..400)
                .map(|k| [9.0 * (k % 20) as f64, 9.0 * (k / 20) as f64])
                .collect(),
        );
        sets
    }

    /// The answers of the scans of every point the grid replaced, bit for bit.
    #[test]
    fn near_and_first_within_answer_as_scans_of_every_point() {
        for points in point_sets() {
            let grid = Neighbours::new(&points);
            for radius in [0.5, 1.0, 9.0, 20.0, 37.5, 1000.0] {
                for (i, &c) in points.iter().enumerate() {
                    let (nearest, others) = grid.near(i, radius);
                    let all = nearest_distance(&points, c, i);
                    if all < radius {
                        assert_eq!(nearest.to_bits(), all.to_bits(), "point {i}, radius {radius}");
                    } else {
                        assert!(nearest >= radius, "point {i}, radius {radius}: {nearest}");
                    }
                    let scanned: Vec<[f64; 2]> = points
                        .iter()
                        .enumerate()
                        .filter(|&(j, p)| j != i && closer_than(p[0] - c[0], p[1] - c[1], radius))
                        .map(|(_, p)| *p)
                        .collect();
                    assert_eq!(others, scanned, "point {i}, radius {radius}");
                    // Queries off the points, at and near them.
                    for q in [c, [c[0] + 0.7 * radius, c[1] - 0.2], [c[0] + radius, c[1]]] {
                        let first = points
                            .iter()
                            .position(|p| closer_than(q[0] - p[0], q[1] - p[1], radius));
                        assert_eq!(
                            grid.first_within(q, radius),
                            first,
                            "query {q:?}, radius {radius}"
                        );
                    }
                }
            }
        }
    }
}
