//! [`PointGrid`]: points in the image plane bucketed on a grid of square cells, for the
//! neighbour queries of linking (nearest other point, points within a radius) at a few cells
//! a query and no allocation per query.
//!
//! Why not kiddo (a workspace dependency): on linking's per-frame pattern (an index over the
//! detections queried by every prediction within its gate, then two indexes asked whether
//! another point lies within reach; the ignored test `point_grid_against_kiddo` times it),
//! kiddo 4.2's `ImmutableKdTree` took 1.2 times as long at 16 particles, 3.2 times at 100
//! and 4.6 times at 1024 (2026-11-26, test profile, one run on a shared two-core machine:
//! 3.2 / 19 / 182 us per frame here against 3.7 / 61 / 844). The grid is built by one
//! counting sort, and its queries visit a few cells and never allocate, where the tree's
//! `within_unsorted` returns a vector and its any-other test needs `nearest_n`. And kiddo
//! 4.2's `ImmutableKdTree::nearest_one` answered wrong for small sets: against a search of
//! every point, 967 of 10 000 random queries over 3 points and 248 over 10 (some at a
//! distance below every point's), none over 40 to 1000 (ignored test
//! `kiddo_nearest_one_against_every_point`). The grid serves linking, the crossing pass, the
//! appearance spread and the pipeline's samples (`nearest_two`). kiddo remains in the
//! background exclusion (a pixel's nearest particle, often one or two): answered right there,
//! sweep style 1031 (one ring of 24.7 px, noise 27.6) went from refused to tracks written
//! 13 px off, so the exclusion waits until the self-checks catch that case.

use crate::group_by_key::group_by_key;

/// Points (px) bucketed by cell, cells about one mean spacing wide.
pub(crate) struct PointGrid<'a> {
    points: &'a [[f64; 2]],
    /// Lower corner of the points' bounding box, px.
    lo: [f64; 2],
    /// Cell side, px.
    cell: f64,
    /// Cells along x and y.
    dims: [usize; 2],
    /// Indices of the points sorted by cell (row-major cells).
    sorted: Vec<usize>,
    /// `sorted[start[c]..start[c + 1]]` are the points of cell `c`.
    start: Vec<usize>,
}

impl<'a> PointGrid<'a> {
    /// Buckets `points` (at least one; finite) by a counting sort on cells about one mean
    /// spacing wide (at least 1/1024 of the larger extent, so a line of points does not
    /// make the grid huge).
    pub(crate) fn new(points: &'a [[f64; 2]]) -> PointGrid<'a> {
        let n = points.len();
        let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
        for p in points {
            for k in 0..2 {
                lo[k] = lo[k].min(p[k]);
                hi[k] = hi[k].max(p[k]);
            }
        }
        if n == 0 {
            (lo, hi) = ([0.0; 2], [0.0; 2]);
        }
        let extent = [(hi[0] - lo[0]).max(1e-9), (hi[1] - lo[1]).max(1e-9)];
        let cell = (extent[0] * extent[1] / n.max(1) as f64)
            .sqrt()
            .max(extent[0].max(extent[1]) / 1024.0);
        let dims = [0, 1].map(|k| (extent[k] / cell) as usize + 1);
        let mut grid = PointGrid {
            points,
            lo,
            cell,
            dims,
            sorted: Vec::new(),
            start: Vec::new(),
        };
        let cells = points.iter().enumerate().map(|(i, p)| {
            let (cx, cy) = grid.cell_of(p);
            (cy * dims[0] + cx, i)
        });
        (grid.start, grid.sorted) = group_by_key(cells, dims[0] * dims[1]);
        grid
    }

    /// The cell holding `p` (clamped to the grid).
    fn cell_of(&self, p: &[f64; 2]) -> (usize, usize) {
        let c = |k: usize| {
            let v = ((p[k] - self.lo[k]) / self.cell).floor();
            if v.is_nan() || v <= 0.0 {
                0
            } else {
                (v as usize).min(self.dims[k] - 1)
            }
        };
        (c(0), c(1))
    }

    /// The points of cell `(gx, gy)`.
    fn in_cell(&self, gx: usize, gy: usize) -> &[usize] {
        let c = gy * self.dims[0] + gx;
        &self.sorted[self.start[c]..self.start[c + 1]]
    }

    /// Distance from `p` to the nearest point at a distance above zero, px; infinite when
    /// there is none. Rings of cells are searched outward until the nearest point found is
    /// no farther than the edge of the block of cells searched (beyond which every point
    /// left lies): with cells one mean spacing wide, usually after the first ring.
    pub(crate) fn nearest_other(&self, p: &[f64; 2]) -> f64 {
        let mut best = f64::INFINITY;
        self.search_rings(
            p,
            &mut best,
            |best, _, d| {
                if d > 0.0 && d < *best {
                    *best = d;
                }
            },
            |best| *best,
        );
        best.sqrt()
    }

    /// The two points nearest `p` (a distance of zero included), nearest first, as `(index,
    /// squared distance, px²)`; `None` where there are fewer points. Of points at equal
    /// distances, the first met in cell order comes first.
    pub(crate) fn nearest_two(&self, p: &[f64; 2]) -> [Option<(usize, f64)>; 2] {
        let mut best: [Option<(usize, f64)>; 2] = [None, None];
        let far = |b: &Option<(usize, f64)>| b.map_or(f64::INFINITY, |(_, d)| d);
        self.search_rings(
            p,
            &mut best,
            |best, j, d| {
                if d < far(&best[0]) {
                    best[1] = best[0];
                    best[0] = Some((j, d));
                } else if d < far(&best[1]) {
                    best[1] = Some((j, d));
                }
            },
            |best| far(&best[1]),
        );
        best
    }

    /// Calls `visit(state, index, squared distance)` for the points of rings of cells
    /// around `p`, outward, until `bound(state)` (a squared distance, px²) is no farther
    /// than the edge of the block of cells searched or every cell is seen.
    fn search_rings<S>(
        &self,
        p: &[f64; 2],
        state: &mut S,
        visit: impl Fn(&mut S, usize, f64),
        bound: impl Fn(&S) -> f64,
    ) {
        if self.points.is_empty() {
            return;
        }
        let (cx, cy) = self.cell_of(p);
        let [w, h] = self.dims;
        let scan = |gx: usize, gy: usize, state: &mut S| {
            for &j in self.in_cell(gx, gy) {
                let q = &self.points[j];
                visit(state, j, (q[0] - p[0]).powi(2) + (q[1] - p[1]).powi(2));
            }
        };
        for ring in 0..w.max(h) {
            let (x0, x1) = (cx.saturating_sub(ring), (cx + ring).min(w - 1));
            let (y0, y1) = (cy.saturating_sub(ring), (cy + ring).min(h - 1));
            // The ring's cells: whole rows at its top and bottom, its two ends between.
            for gy in y0..=y1 {
                if gy.abs_diff(cy) == ring {
                    (x0..=x1).for_each(|gx| scan(gx, gy, state));
                } else {
                    if cx >= ring {
                        scan(cx - ring, gy, state);
                    }
                    if cx + ring < w {
                        scan(cx + ring, gy, state);
                    }
                }
            }
            // Every point not yet seen lies outside the block searched: at least as far from
            // `p` as the block's nearest side that has cells beyond it.
            let side = |inside: bool, d: f64| if inside { d } else { f64::INFINITY };
            let margin = [
                side(x0 > 0, p[0] - (self.lo[0] + x0 as f64 * self.cell)),
                side(x1 + 1 < w, self.lo[0] + (x1 + 1) as f64 * self.cell - p[0]),
                side(y0 > 0, p[1] - (self.lo[1] + y0 as f64 * self.cell)),
                side(y1 + 1 < h, self.lo[1] + (y1 + 1) as f64 * self.cell - p[1]),
            ]
            .into_iter()
            .fold(f64::INFINITY, f64::min);
            if margin == f64::INFINITY || (margin > 0.0 && bound(state) <= margin * margin) {
                break;
            }
        }
    }

    /// Returns true if and only if some point lies closer to `p` than `radius` px and at a
    /// distance above zero: whether [`PointGrid::nearest_other`] would be below `radius`
    /// (the same distances, compared alike), found by looking only as far as `radius` and
    /// stopping at the first such point.
    pub(crate) fn any_other_within(&self, p: &[f64; 2], radius: f64) -> bool {
        if self.points.is_empty() || radius.is_nan() || radius <= 0.0 {
            return false;
        }
        let (x0, y0) = self.cell_of(&[p[0] - radius, p[1] - radius]);
        let (x1, y1) = self.cell_of(&[p[0] + radius, p[1] + radius]);
        (y0..=y1).any(|gy| {
            (x0..=x1).any(|gx| {
                self.in_cell(gx, gy).iter().any(|&j| {
                    let q = &self.points[j];
                    let d = (q[0] - p[0]).powi(2) + (q[1] - p[1]).powi(2);
                    d > 0.0 && d.sqrt() < radius
                })
            })
        })
    }

    /// Calls `f(index, squared distance)` for every point within `radius` px of `p`
    /// (boundary included), in cell order.
    pub(crate) fn within(&self, p: &[f64; 2], radius: f64, mut f: impl FnMut(usize, f64)) {
        if self.points.is_empty() || radius.is_nan() || radius < 0.0 {
            return;
        }
        let r2 = radius * radius;
        let (x0, y0) = self.cell_of(&[p[0] - radius, p[1] - radius]);
        let (x1, y1) = self.cell_of(&[p[0] + radius, p[1] + radius]);
        for gy in y0..=y1 {
            for gx in x0..=x1 {
                for &j in self.in_cell(gx, gy) {
                    let q = &self.points[j];
                    let d = (q[0] - p[0]).powi(2) + (q[1] - p[1]).powi(2);
                    if d <= r2 {
                        f(j, d);
                    }
                }
            }
        }
    }
}

/// Distance from each point to its nearest other point (at a distance above zero), px;
/// infinite where there is none.
pub(crate) fn nearest_other(points: &[[f64; 2]]) -> Vec<f64> {
    if points.len() < 2 {
        return vec![f64::INFINITY; points.len()];
    }
    let grid = PointGrid::new(points);
    points.iter().map(|p| grid.nearest_other(p)).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Spread, clustered and collinear point sets, a pair, and a cluster with an outlier (the
    /// first set with a duplicate point).
    fn point_sets() -> Vec<Vec<[f64; 2]>> {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(12345);
        let mut next = || rng.gen::<f64>();
        let mut sets: Vec<Vec<[f64; 2]>> = vec![
            (0..500).map(|_| [512.0 * next(), 512.0 * next()]).collect(),
            (0..300)
                .map(|i| [(i % 3) as f64 * 400.0 + 5.0 * next(), 3.0 * next()])
                .collect(),
            (0..50).map(|i| [i as f64 * 1.5, 7.0]).collect(),
            vec![[3.0, 4.0], [500.0, 9.0]],
        ];
        // A dense cluster with one far outlier: cells much smaller than the outlier's gap.
        let mut cluster: Vec<[f64; 2]> = (0..200).map(|_| [20.0 * next(), 20.0 * next()]).collect();
        cluster.push([480.0, 300.0]);
        sets.push(cluster);
        let dup = sets[0][3];
        sets[0].push(dup);
        sets
    }

    /// The grid search agrees with a brute-force search (a duplicate is no neighbour).
    #[test]
    fn nearest_other_matches_brute_force() {
        for pts in &point_sets() {
            let got = nearest_other(pts);
            for (i, p) in pts.iter().enumerate() {
                let want = pts
                    .iter()
                    .map(|q| (q[0] - p[0]).hypot(q[1] - p[1]))
                    .filter(|&d| d > 0.0)
                    .fold(f64::INFINITY, f64::min);
                assert!((got[i] - want).abs() < 1e-9, "point {i}: {} vs {want}", got[i]);
            }
        }
        assert_eq!(nearest_other(&[[1.0, 2.0]]), [f64::INFINITY]);
    }

    /// `any_other_within` says whether `nearest_other` is below the radius, for radii about
    /// each point's own nearest distance (just under, equal, just over) and far beyond.
    #[test]
    fn any_other_within_agrees_with_nearest_other() {
        for pts in &point_sets() {
            let grid = PointGrid::new(pts);
            for p in pts {
                let nn = grid.nearest_other(p);
                for radius in [nn * 0.999, nn, nn * 1.001, 0.0, 1e4] {
                    assert_eq!(
                        grid.any_other_within(p, radius),
                        nn < radius,
                        "{p:?} radius {radius}"
                    );
                }
            }
        }
    }

    /// `within` finds exactly the points a brute-force search finds, for query points
    /// inside and outside the points' box and radii from zero to beyond the box.
    #[test]
    fn within_matches_brute_force() {
        for pts in &point_sets() {
            let grid = PointGrid::new(pts);
            let queries = [
                pts[0],
                pts[pts.len() - 1],
                [-30.0, -30.0],
                [600.0, 1.0],
                [250.0, 250.0],
            ];
            for q in queries {
                for radius in [0.0, 0.7, 3.0, 25.0, 2000.0] {
                    let mut got: Vec<(usize, f64)> = Vec::new();
                    grid.within(&q, radius, |j, d| got.push((j, d)));
                    got.sort_by_key(|g| g.0);
                    let want: Vec<(usize, f64)> = pts
                        .iter()
                        .enumerate()
                        .map(|(j, p)| (j, (p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2)))
                        .filter(|&(_, d)| d <= radius * radius)
                        .collect();
                    assert_eq!(got, want, "query {q:?} radius {radius}");
                }
            }
        }
        let none: [[f64; 2]; 0] = [];
        PointGrid::new(&none).within(&[0.0, 0.0], 5.0, |_, _| panic!("no points"));
    }

    /// Timing harness, run by hand (`cargo test --workspace --lib point_grid_against_kiddo --
    /// --ignored --nocapture`): PointGrid against kiddo's `ImmutableKdTree` on linking's
    /// per-frame pattern. Each frame builds an index over the detections and asks each
    /// prediction for the detections within its gate (`within`), builds one over the
    /// predictions and asks each whether another lies within reach (`any_other_within`), and
    /// builds one over the taken detections and asks the same (the crowding test); kiddo's
    /// side uses `within_unsorted` and `nearest_n(2)`. Particles on a jittered lattice 12 px
    /// apart, predictions 1 px off, a 8 px gate, a 10 px reach.
    #[test]
    #[ignore]
    fn point_grid_against_kiddo() {
        use kiddo::{ImmutableKdTree, SquaredEuclidean};
        use rand::{Rng, SeedableRng};
        use std::time::Instant;
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        let (gate, reach) = (8.0_f64, 10.0_f64);
        for (side, frame_count) in [(4usize, 20_000usize), (10, 2_000), (32, 200)] {
            // Each frame's detections and predictions.
            type Frame = (Vec<[f64; 2]>, Vec<[f64; 2]>);
            let frames: Vec<Frame> = (0..frame_count)
                .map(|_| {
                    let dets: Vec<[f64; 2]> = (0..side * side)
                        .map(|i| {
                            let (x, y) = ((i % side) as f64, (i / side) as f64);
                            [
                                20.0 + 12.0 * x + 3.0 * rng.gen::<f64>(),
                                20.0 + 12.0 * y + 3.0 * rng.gen::<f64>(),
                            ]
                        })
                        .collect();
                    let preds = dets
                        .iter()
                        .map(|d| [d[0] + rng.gen::<f64>() - 0.5, d[1] + rng.gen::<f64>() - 0.5])
                        .collect();
                    (dets, preds)
                })
                .collect();
            let t = Instant::now();
            let mut grid_hits = 0usize;
            for (dets, preds) in &frames {
                let g = PointGrid::new(dets);
                for p in preds {
                    g.within(p, gate, |_, _| grid_hits += 1);
                }
                for pts in [preds, dets] {
                    let g = PointGrid::new(pts);
                    grid_hits += pts.iter().filter(|p| g.any_other_within(p, reach)).count();
                }
            }
            let grid_time = t.elapsed().as_secs_f64();
            let t = Instant::now();
            let mut tree_hits = 0usize;
            for (dets, preds) in &frames {
                let tree = ImmutableKdTree::<f64, 2>::new_from_slice(dets);
                for p in preds {
                    tree_hits += tree.within_unsorted::<SquaredEuclidean>(p, gate * gate).len();
                }
                for pts in [preds, dets] {
                    let tree = ImmutableKdTree::<f64, 2>::new_from_slice(pts);
                    tree_hits += pts
                        .iter()
                        .filter(|p| {
                            tree.nearest_n::<SquaredEuclidean>(p, 2)
                                .iter()
                                .any(|n| n.distance > 0.0 && n.distance.sqrt() < reach)
                        })
                        .count();
                }
            }
            let tree_time = t.elapsed().as_secs_f64();
            assert_eq!(grid_hits, tree_hits, "both indexes find the same neighbours");
            let per_frame = |s: f64| s / frame_count as f64 * 1e6;
            println!(
                "{} particles: PointGrid {:.1} us/frame, kiddo {:.1} us/frame, kiddo/PointGrid {:.2}",
                side * side,
                per_frame(grid_time),
                per_frame(tree_time),
                tree_time / grid_time
            );
        }
    }

    #[test]
    #[allow(clippy::float_cmp)] // the same arithmetic: equal to the bit
    fn nearest_two_agrees_with_a_search_of_every_point() {
        // Spread, clustered and collinear sets; queries on points, between them and far
        // outside their bounding box.
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        let mut next = || rng.gen::<f64>();
        let sets: Vec<Vec<[f64; 2]>> = vec![
            (0..300).map(|_| [500.0 * next(), 400.0 * next()]).collect(),
            (0..200)
                .map(|_| [100.0 + 3.0 * next(), 50.0 + 3.0 * next()])
                .collect(),
            (0..50).map(|k| [k as f64 * 7.5, 20.0]).collect(),
            vec![[3.0, 4.0]],
        ];
        for points in &sets {
            let grid = PointGrid::new(points);
            let mut queries: Vec<[f64; 2]> = points.iter().take(40).copied().collect();
            queries.extend((0..40).map(|_| [700.0 * next() - 100.0, 600.0 * next() - 100.0]));
            queries.push([-5000.0, 9000.0]);
            for q in &queries {
                let mut all: Vec<f64> = points
                    .iter()
                    .map(|p| (p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2))
                    .collect();
                all.sort_by(f64::total_cmp);
                let [a, b] = grid.nearest_two(q);
                assert_eq!(a.map(|(_, d)| d), all.first().copied(), "{q:?}");
                assert_eq!(b.map(|(_, d)| d), all.get(1).copied(), "{q:?}");
                if let Some((j, d)) = a {
                    let p = points[j];
                    assert_eq!((p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2), d);
                }
            }
        }
    }

    #[test]
    #[ignore = "exploration: kiddo's nearest_one against a search of every point"]
    #[allow(clippy::float_cmp)] // the same arithmetic: equal to the bit
    fn kiddo_nearest_one_against_every_point() {
        use kiddo::{ImmutableKdTree, SquaredEuclidean};
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
        let mut next = || rng.gen::<f64>();
        let mut wrong = 0;
        let mut asked = 0;
        for n in [3usize, 10, 40, 200, 1000] {
            let before = wrong;
            for _ in 0..20 {
                let points: Vec<[f64; 2]> = (0..n).map(|_| [640.0 * next(), 480.0 * next()]).collect();
                let tree = ImmutableKdTree::<f64, 2>::new_from_slice(&points);
                for _ in 0..500 {
                    let q = [640.0 * next(), 480.0 * next()];
                    let best = points
                        .iter()
                        .map(|p| (p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2))
                        .fold(f64::INFINITY, f64::min);
                    let k = tree.nearest_one::<SquaredEuclidean>(&q).distance;
                    asked += 1;
                    if k != best {
                        wrong += 1;
                        if wrong < 5 {
                            eprintln!("n {n}: kiddo {k} against {best}");
                        }
                    }
                }
            }
            eprintln!("{n} points: {} of 10000 differ", wrong - before);
        }
        eprintln!("{wrong} of {asked} differ");
    }
}
