//! Optimal assignment (minimum total cost matching) of rows to columns.
//!
//! The dense solver is the Hungarian method with potentials in the O(n² m) shortest
//! augmenting path form (Kuhn 1955; Munkres 1957; Jonker & Volgenant 1987). Sparse
//! problems, where only gated pairs are allowed and every row and column may also stay
//! unmatched at a price, are split into connected components of the gating graph and each
//! component is solved densely, so a frame of a thousand well-separated particles costs
//! a thousand 1x1 problems.

use crate::disjoint_sets::DisjointSets;
use crate::group_by_key::group_by_key;

/// A gated, sparse assignment problem: `pairs` are the allowed (row, column, cost) triples;
/// leaving row `r` unmatched costs `row_miss[r]`, column `c` costs `col_miss[c]`.
#[derive(Clone, Debug, Default)]
pub struct SparseProblem {
    /// Allowed pairs: (row, column, cost).
    pub pairs: Vec<(usize, usize, f64)>,
    /// Cost of leaving each row unmatched.
    pub row_miss: Vec<f64>,
    /// Cost of leaving each column unmatched.
    pub col_miss: Vec<f64>,
}

/// Solves a sparse problem; returns, for each row, its column or `None`. The total cost
/// (pairs plus misses) is minimal.
pub fn solve_sparse(problem: &SparseProblem) -> Vec<Option<usize>> {
    let nr = problem.row_miss.len();
    let nc = problem.col_miss.len();
    let mut result = vec![None; nr];
    // Union-find over rows (0..nr) and columns (nr..nr+nc).
    let mut sets = DisjointSets::new(nr + nc);
    for &(r, c, _) in &problem.pairs {
        sets.union(r, nr + c);
    }
    // Each component's rows, columns and pairs, gathered into flat lists by a counting sort
    // on the component (rows and columns ascending, pairs in the problem's order): a crowded
    // frame has a thousand components, mostly one track and one blob, and a map of vectors
    // allocated two thousand of them a frame.
    let mut component = vec![usize::MAX; nr + nc];
    let mut count = 0;
    let of: Vec<usize> = (0..nr + nc)
        .map(|v| {
            let root = sets.root(v);
            if component[root] == usize::MAX {
                component[root] = count;
                count += 1;
            }
            component[root]
        })
        .collect();
    let groups = count;
    let (row_start, rows) = group_by_key((0..nr).map(|r| (of[r], r)), groups);
    let (col_start, cols) = group_by_key((0..nc).map(|c| (of[nr + c], c)), groups);
    let (pair_start, pair_index) = group_by_key(
        problem.pairs.iter().enumerate().map(|(k, &(r, _, _))| (of[r], k)),
        groups,
    );
    let pairs: Vec<(usize, usize, f64)> = pair_index.iter().map(|&k| problem.pairs[k]).collect();
    let mut scratch = ComponentScratch {
        local: vec![0; nr + nc],
        ..ComponentScratch::default()
    };
    for g in 0..groups {
        let pairs = &pairs[pair_start[g]..pair_start[g + 1]];
        if pairs.is_empty() {
            continue;
        }
        let (rows, cols) = (
            &rows[row_start[g]..row_start[g + 1]],
            &cols[col_start[g]..col_start[g + 1]],
        );
        if rows.len() == 1 && cols.len() == 1 {
            let (r, c, cost) = pairs.iter().fold(pairs[0], |a, b| if b.2 < a.2 { *b } else { a });
            if cost <= problem.row_miss[r] + problem.col_miss[c] {
                result[r] = Some(c);
            }
            continue;
        }
        solve_component(rows, cols, pairs, problem, &mut scratch, |r, c| {
            result[r] = Some(c)
        });
    }
    result
}

/// Matches named start positions to points, px, by minimal total squared distance: each start
/// takes at most one point, none farther than `gate`, px (a start with no point within it
/// stays unmatched). Returns, for each start, its point's index. This is how named tracks
/// begin: structure particles matched to first-frame detections, or to the first positions
/// of another tracker's tracks.
pub fn match_to_starts(starts: &[[f64; 2]], points: &[[f64; 2]], gate: f64) -> Vec<Option<usize>> {
    let g2 = gate * gate;
    let mut problem = SparseProblem {
        row_miss: vec![1.0; starts.len()],
        col_miss: vec![0.0; points.len()],
        pairs: Vec::new(),
    };
    for (i, s) in starts.iter().enumerate() {
        for (j, p) in points.iter().enumerate() {
            let d2 = (p[0] - s[0]).powi(2) + (p[1] - s[1]).powi(2);
            if d2 <= g2 {
                problem.pairs.push((i, j, d2 / g2));
            }
        }
    }
    solve_sparse(&problem)
}

/// Solves one connected component by successive shortest augmenting paths on the sparse
/// graph (Dijkstra with potentials, the shortest-path form of the Hungarian method), so a
/// crowded frame whose gates chain a thousand particles together costs about the number of
/// gated pairs per augmentation, not the cube of the component size.
///
/// Leaving column `c` unmatched costs `col_miss[c]`, so matching row `r` to it costs
/// `cost - col_miss[c]` relative to leaving it; each row also has a private "miss" column at
/// `row_miss[r]`. Every row is then assigned exactly once, and a constant per row (its
/// cheapest option) is subtracted so that all costs are non-negative for Dijkstra.
fn solve_component(
    rows: &[usize],
    cols: &[usize],
    pairs: &[(usize, usize, f64)],
    problem: &SparseProblem,
    scratch: &mut ComponentScratch,
    mut assign: impl FnMut(usize, usize),
) {
    use std::cmp::Reverse;
    let (k, l) = (rows.len(), cols.len());
    let nr = problem.row_miss.len();
    let ComponentScratch {
        local,
        edge_start,
        edges,
        v,
        u,
        col_match,
        row_match,
        dist,
        prev_row,
        done,
        touched,
        finalized,
        heap,
    } = scratch;
    // Local indices: `local[r]` for row r, `local[nr + c]` for column c.
    for (i, &r) in rows.iter().enumerate() {
        local[r] = i;
    }
    for (j, &c) in cols.iter().enumerate() {
        local[nr + c] = j;
    }
    // Edges per local row (local column, cost), its pairs in the problem's order and then
    // its miss column l + i, as offsets `edge_start[i]..edge_start[i + 1]` into `edges`.
    edge_start.clear();
    edge_start.resize(k + 2, 0);
    for &(r, _, _) in pairs {
        edge_start[local[r] + 2] += 1;
    }
    for i in 0..k {
        edge_start[i + 2] += edge_start[i + 1] + 1;
    }
    edges.clear();
    edges.resize(pairs.len() + k, (0, 0.0));
    for &(r, c, cost) in pairs {
        let i = local[r];
        edges[edge_start[i + 1]] = (local[nr + c], cost - problem.col_miss[c]);
        edge_start[i + 1] += 1;
    }
    for (i, &r) in rows.iter().enumerate() {
        edges[edge_start[i + 1]] = (l + i, problem.row_miss[r]);
        edge_start[i + 1] += 1;
        let row = &mut edges[edge_start[i]..edge_start[i + 1]];
        let lo = row.iter().map(|e| e.1).fold(f64::INFINITY, f64::min);
        for e in row {
            e.1 -= lo;
        }
    }
    let adj = |i: usize| &edges[edge_start[i]..edge_start[i + 1]];
    let m = l + k;
    let reset = |vec: &mut Vec<_>, len, value| {
        vec.clear();
        vec.resize(len, value);
    };
    reset(v, m, 0.0);
    reset(u, k, 0.0);
    reset(dist, m, f64::INFINITY);
    col_match.clear();
    col_match.resize(m, None);
    row_match.clear();
    row_match.resize(k, None);
    prev_row.clear();
    prev_row.resize(m, usize::MAX);
    done.clear();
    done.resize(m, false);
    touched.clear();
    for s in 0..k {
        for &j in touched.iter() {
            dist[j] = f64::INFINITY;
            done[j] = false;
            prev_row[j] = usize::MAX;
        }
        touched.clear();
        heap.clear();
        for &(j, c) in adj(s) {
            let d = c - u[s] - v[j];
            if d < dist[j] {
                if dist[j].is_infinite() {
                    touched.push(j);
                }
                dist[j] = d;
                prev_row[j] = s;
                heap.push(Reverse(DistKey(d, j)));
            }
        }
        finalized.clear();
        let mut end = None;
        while let Some(Reverse(DistKey(d, j))) = heap.pop() {
            if done[j] || d > dist[j] {
                continue;
            }
            done[j] = true;
            finalized.push(j);
            match col_match[j] {
                None => {
                    end = Some((j, d));
                    break;
                }
                Some(i) => {
                    for &(j2, c) in adj(i) {
                        if done[j2] {
                            continue;
                        }
                        let nd = d + c - u[i] - v[j2];
                        if nd < dist[j2] {
                            if dist[j2].is_infinite() {
                                touched.push(j2);
                            }
                            dist[j2] = nd;
                            prev_row[j2] = i;
                            heap.push(Reverse(DistKey(nd, j2)));
                        }
                    }
                }
            }
        }
        // Every row has its own miss column, so a free column is always reached.
        let Some((jend, dend)) = end else { continue };
        for &j in finalized.iter() {
            let delta = dend - dist[j];
            if delta > 0.0 {
                v[j] -= delta;
                if let Some(i) = col_match[j] {
                    u[i] += delta;
                }
            }
        }
        u[s] += dend;
        // Augment along the path of predecessors.
        let mut j = jend;
        loop {
            let i = prev_row[j];
            let old = row_match[i];
            row_match[i] = Some(j);
            col_match[j] = Some(i);
            match old {
                Some(jo) if i != s => j = jo,
                _ => break,
            }
        }
    }
    for (j, r) in col_match.iter().enumerate().take(l) {
        if let Some(i) = r {
            assign(rows[*i], cols[j]);
        }
    }
}

/// The buffers of [`solve_component`], reused from one component to the next.
#[derive(Default)]
struct ComponentScratch {
    /// Each global row's (then column's) index within the component being solved.
    local: Vec<usize>,
    edge_start: Vec<usize>,
    edges: Vec<(usize, f64)>,
    v: Vec<f64>,
    u: Vec<f64>,
    col_match: Vec<Option<usize>>,
    row_match: Vec<Option<usize>>,
    dist: Vec<f64>,
    prev_row: Vec<usize>,
    done: Vec<bool>,
    touched: Vec<usize>,
    finalized: Vec<usize>,
    heap: std::collections::BinaryHeap<std::cmp::Reverse<DistKey>>,
}

/// A heap key of [`solve_component`]'s Dijkstra search, a column's tentative distance and
/// the column, ordered by distance (then column).
#[derive(PartialEq)]
struct DistKey(f64, usize);

impl Eq for DistKey {}

impl PartialOrd for DistKey {
    fn partial_cmp(&self, o: &Self) -> Option<std::cmp::Ordering> {
        Some(self.cmp(o))
    }
}

impl Ord for DistKey {
    fn cmp(&self, o: &Self) -> std::cmp::Ordering {
        self.0.total_cmp(&o.0).then(self.1.cmp(&o.1))
    }
}

/// Solves a dense `n x m` problem (`n <= m`, row-major costs); returns each row's column.
pub fn solve_dense(cost: &[f64], n: usize, m: usize) -> Vec<Option<usize>> {
    if n == 0 {
        return Vec::new();
    }
    debug_assert!(n <= m);
    let inf = f64::INFINITY;
    let mut u = vec![0.0; n + 1];
    let mut v = vec![0.0; m + 1];
    let mut p = vec![0usize; m + 1];
    let mut way = vec![0usize; m + 1];
    for i in 1..=n {
        p[0] = i;
        let mut j0 = 0;
        let mut minv = vec![inf; m + 1];
        let mut used = vec![false; m + 1];
        loop {
            used[j0] = true;
            let i0 = p[j0];
            let mut delta = inf;
            let mut j1 = 0;
            for j in 1..=m {
                if !used[j] {
                    let cur = cost[(i0 - 1) * m + (j - 1)] - u[i0] - v[j];
                    if cur < minv[j] {
                        minv[j] = cur;
                        way[j] = j0;
                    }
                    if minv[j] < delta {
                        delta = minv[j];
                        j1 = j;
                    }
                }
            }
            if j1 == 0 {
                break;
            }
            for j in 0..=m {
                if used[j] {
                    u[p[j]] += delta;
                    v[j] -= delta;
                } else {
                    minv[j] -= delta;
                }
            }
            j0 = j1;
            if p[j0] == 0 {
                break;
            }
        }
        loop {
            let j1 = way[j0];
            p[j0] = p[j1];
            j0 = j1;
            if j0 == 0 {
                break;
            }
        }
    }
    let mut out = vec![None; n];
    for j in 1..=m {
        if p[j] != 0 {
            out[p[j] - 1] = Some(j - 1);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dense_beats_greedy() {
        // Greedy takes (0,0)=1 then (1,1)=10: 11; optimal is (0,1)+(1,0) = 2+2 = 4.
        let cost = [1.0, 2.0, 2.0, 10.0];
        assert_eq!(solve_dense(&cost, 2, 2), vec![Some(1), Some(0)]);
    }

    #[test]
    fn sparse_matches_dense_on_random_problems() {
        // Brute force over the dense augmented form for small random problems.
        let mut state = 12345u64;
        let mut rnd = move || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (state >> 33) as f64 / (1u64 << 31) as f64
        };
        for _ in 0..300 {
            let (nr, nc) = (1 + (rnd() * 5.0) as usize, 1 + (rnd() * 5.0) as usize);
            let mut p = SparseProblem::default();
            for r in 0..nr {
                for c in 0..nc {
                    if rnd() < 0.6 {
                        p.pairs.push((r, c, rnd() * 4.0));
                    }
                }
            }
            p.row_miss = (0..nr).map(|_| rnd() * 3.0).collect();
            p.col_miss = (0..nc).map(|_| rnd()).collect();
            let total = |a: &[Option<usize>]| {
                let mut t = 0.0;
                let mut used = vec![false; nc];
                for (r, m) in a.iter().enumerate() {
                    match m {
                        Some(c) => {
                            used[*c] = true;
                            t += p
                                .pairs
                                .iter()
                                .filter(|q| q.0 == r && q.1 == *c)
                                .map(|q| q.2)
                                .fold(f64::INFINITY, f64::min);
                        }
                        None => t += p.row_miss[r],
                    }
                }
                t + (0..nc).filter(|&c| !used[c]).map(|c| p.col_miss[c]).sum::<f64>()
            };
            // Best by exhaustive search over partial injections.
            fn search(
                r: usize,
                nr: usize,
                nc: usize,
                cur: &mut Vec<Option<usize>>,
                best: &mut f64,
                f: &dyn Fn(&[Option<usize>]) -> f64,
                allowed: &dyn Fn(usize, usize) -> bool,
            ) {
                if r == nr {
                    *best = best.min(f(cur));
                    return;
                }
                cur.push(None);
                search(r + 1, nr, nc, cur, best, f, allowed);
                cur.pop();
                for c in 0..nc {
                    if allowed(r, c) && !cur.contains(&Some(c)) {
                        cur.push(Some(c));
                        search(r + 1, nr, nc, cur, best, f, allowed);
                        cur.pop();
                    }
                }
            }
            let mut best = f64::INFINITY;
            let allowed = |r: usize, c: usize| p.pairs.iter().any(|q| q.0 == r && q.1 == c);
            search(0, nr, nc, &mut Vec::new(), &mut best, &total, &allowed);
            let got = total(&solve_sparse(&p));
            assert!((got - best).abs() < 1e-9, "sparse {got} vs best {best} on {p:?}");
        }
    }

    #[test]
    fn sparse_respects_miss_costs() {
        let p = SparseProblem {
            pairs: vec![(0, 0, 1.0), (1, 0, 0.5), (1, 1, 5.0), (2, 2, 3.0)],
            row_miss: vec![4.0, 4.0, 1.0],
            col_miss: vec![0.0, 0.0, 1.0],
        };
        // Row 1 takes col 0 (0.5) and row 0 misses (4) = 4.5, versus row 0 col 0 (1) +
        // row 1 col 1 (5) = 6, or row 0 col 0 + row 1 miss = 5. Row 2: pair 3 > 1 + 1.
        assert_eq!(solve_sparse(&p), vec![None, Some(0), None]);
    }
}
