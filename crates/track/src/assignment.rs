//! Optimal assignment (minimum total cost matching) of rows to columns.
//!
//! The dense solver is the Hungarian method with potentials in the O(n² m) shortest
//! augmenting path form (Kuhn 1955; Munkres 1957; Jonker & Volgenant 1987). Sparse
//! problems, where only gated pairs are allowed and every row and column may also stay
//! unmatched at a price, are split into connected components of the gating graph and each
//! component is solved densely, so a frame of a thousand well-separated particles costs
//! a thousand 1x1 problems.

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
    let mut parent: Vec<usize> = (0..nr + nc).collect();
    fn find(p: &mut [usize], mut a: usize) -> usize {
        while p[a] != a {
            p[a] = p[p[a]];
            a = p[a];
        }
        a
    }
    for &(r, c, _) in &problem.pairs {
        let a = find(&mut parent, r);
        let b = find(&mut parent, nr + c);
        if a != b {
            parent[a] = b;
        }
    }
    let mut groups: std::collections::HashMap<usize, (Vec<usize>, Vec<usize>)> = Default::default();
    for r in 0..nr {
        let root = find(&mut parent, r);
        groups.entry(root).or_default().0.push(r);
    }
    for c in 0..nc {
        let root = find(&mut parent, nr + c);
        groups.entry(root).or_default().1.push(c);
    }
    let mut pairs_by_root: std::collections::HashMap<usize, Vec<(usize, usize, f64)>> = Default::default();
    for &(r, c, cost) in &problem.pairs {
        let root = find(&mut parent, r);
        pairs_by_root.entry(root).or_default().push((r, c, cost));
    }
    let mut roots: Vec<usize> = groups.keys().copied().collect();
    roots.sort_unstable();
    for root in roots {
        let (rows, cols) = &groups[&root];
        let Some(pairs) = pairs_by_root.get(&root) else {
            continue;
        };
        if rows.len() == 1 && cols.len() == 1 {
            let (r, c, cost) = pairs.iter().fold(pairs[0], |a, b| if b.2 < a.2 { *b } else { a });
            if cost <= problem.row_miss[r] + problem.col_miss[c] {
                result[r] = Some(c);
            }
            continue;
        }
        // Dense augmented square matrix: rows | dummy rows (one per column),
        // columns | dummy columns (one per row).
        let (k, l) = (rows.len(), cols.len());
        let n = k + l;
        let big: f64 = 1e18;
        let mut cost = vec![big; n * n];
        let col_index: std::collections::HashMap<usize, usize> =
            cols.iter().enumerate().map(|(i, &c)| (c, i)).collect();
        let row_index: std::collections::HashMap<usize, usize> =
            rows.iter().enumerate().map(|(i, &r)| (r, i)).collect();
        for &(r, c, v) in pairs {
            let (i, j) = (row_index[&r], col_index[&c]);
            cost[i * n + j] = cost[i * n + j].min(v);
        }
        for (i, &r) in rows.iter().enumerate() {
            cost[i * n + l + i] = problem.row_miss[r];
        }
        for (j, &c) in cols.iter().enumerate() {
            cost[(k + j) * n + j] = problem.col_miss[c];
            for i in 0..k {
                // Dummy row × dummy column: free, so unused dummies pair up.
                cost[(k + j) * n + l + i] = 0.0;
            }
        }
        let assign = solve_dense(&cost, n, n);
        for (i, &r) in rows.iter().enumerate() {
            if let Some(j) = assign[i] {
                if j < l && cost[i * n + j] < big {
                    result[r] = Some(cols[j]);
                }
            }
        }
    }
    result
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
