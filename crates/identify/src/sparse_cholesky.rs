//! Sparse Cholesky factorisation `P A P^T = L L^T` of a symmetric positive definite matrix,
//! for the linear stage's normal equations on large structures.
//!
//! The normal matrix of a structure couples only bonds that share a particle, so it is as
//! sparse as the structure: on a lattice it is a two-dimensional grid graph. Conjugate gradients
//! on it need iterations in proportion to the lattice's side (the smooth, nearly self-stressed
//! directions are the slow ones), so their time grows as `bonds^1.5` and more. A direct
//! factorisation after a nested-dissection ordering has no such dependence on the conditioning.
//!
//! * Ordering: nested dissection by breadth-first level structures (George's automatic nested
//!   dissection): from a pseudo-peripheral vertex, the middle level of the breadth-first search
//!   separates the earlier levels from the later ones; both halves are ordered first,
//!   recursively, the separator last. Only the matrix's pattern is used, never coordinates.
//! * Factorisation: the up-looking algorithm (Davis, *Direct Methods for Sparse Linear
//!   Systems*, 2006, ch. 4): row `k` of `L` is found by a triangular solve whose pattern is the
//!   set of elimination-tree paths from the entries of `A`'s column `k` (its "reach").
//!
//! Why not faer: measured once (2026-11-26, a scratch program outside the repository, one run
//! on a shared two-core machine, best of 3-10) on normal matrices of square lattices of
//! springs with both diagonals (bonds coupled where they share a particle), faer 0.22's
//! sparse LLT (its own fill-reducing ordering, supernodal) factored and solved in 0.18 ms
//! against 0.30 here at 342 unknowns, 3.9 ms against 16.2 at 3906, 71 ms against 166 at
//! 16002: faer/ours 0.59, 0.24 and 0.43 (0.83, 0.36 and 0.54 counting the conversion to its
//! matrix type), with solutions equal to 2e-15 relative. faer is faster, but not where it
//! counts: the sparse path serves only beyond 200 unknowns, where the factorisation is a few
//! tens of ms of a linear stage that is itself about 0.1 % of the fit (1024 particles: linear
//! stage 182 ms, refinement 117 s; docs/identification.md), and faer would add about 70
//! crates (gemm, pulp, nano-gemm, pest, ...) and 6.5 minutes of release build on two cores.

/// Marker of "no vertex" in the elimination tree.
const NONE: usize = usize::MAX;

/// Subgraphs of at most this many vertices are ordered as they come.
const LEAF_SIZE: usize = 48;

/// Deepest recursion of the dissection; deeper parts are ordered as they come.
const MAX_DEPTH: usize = 64;

/// A fill-reducing ordering of the symmetric pattern `rows` (row `i` lists the columns of its
/// entries; the diagonal may or may not be listed): `order[new] = old`.
pub(crate) fn nested_dissection(rows: &[Vec<(usize, f64)>]) -> Vec<usize> {
    let n = rows.len();
    let mut dissection = Dissection {
        rows,
        stamp: vec![0; n],
        level: vec![0; n],
        next_stamp: 0,
        order: Vec::with_capacity(n),
    };
    let all: Vec<usize> = (0..n).collect();
    dissection.dissect(all, 0);
    dissection.order
}

/// Working state of [`nested_dissection`].
struct Dissection<'a> {
    rows: &'a [Vec<(usize, f64)>],
    /// `stamp[v] == s` marks `v` as a member of the set being processed under stamp `s`.
    stamp: Vec<u32>,
    /// Breadth-first level of each vertex of the current set.
    level: Vec<usize>,
    next_stamp: u32,
    order: Vec<usize>,
}

impl Dissection<'_> {
    fn fresh_stamp(&mut self) -> u32 {
        self.next_stamp += 1;
        self.next_stamp
    }

    /// Marks `set` as the current set; returns its stamp.
    fn mark(&mut self, set: &[usize]) -> u32 {
        let s = self.fresh_stamp();
        for &v in set {
            self.stamp[v] = s;
        }
        s
    }

    /// Breadth-first search within the vertices stamped `member` from `root`, stamping the
    /// visited ones `visited`; returns the vertices in visiting order (levels in `self.level`).
    fn bfs(&mut self, root: usize, member: u32, visited: u32) -> Vec<usize> {
        let mut queue = vec![root];
        self.stamp[root] = visited;
        self.level[root] = 0;
        let mut head = 0;
        while head < queue.len() {
            let v = queue[head];
            head += 1;
            for &(u, _) in &self.rows[v] {
                if self.stamp[u] == member {
                    self.stamp[u] = visited;
                    self.level[u] = self.level[v] + 1;
                    queue.push(u);
                }
            }
        }
        queue
    }

    /// Appends an ordering of `set` to `self.order`: each connected part dissected separately.
    fn dissect(&mut self, set: Vec<usize>, depth: usize) {
        if set.len() <= LEAF_SIZE || depth >= MAX_DEPTH {
            self.order.extend(set);
            return;
        }
        // Connected parts of the set.
        let member = self.mark(&set);
        let mut parts = Vec::new();
        for &v in &set {
            if self.stamp[v] == member {
                let visited = self.fresh_stamp();
                // Each part is marked afresh when it is dissected.
                parts.push(self.bfs(v, member, visited));
            }
        }
        for part in parts {
            self.dissect_connected(part, depth);
        }
    }

    /// As [`Self::dissect`], for a connected set.
    fn dissect_connected(&mut self, set: Vec<usize>, depth: usize) {
        if set.len() <= LEAF_SIZE {
            self.order.extend(set);
            return;
        }
        // A pseudo-peripheral root: the last vertex reached from the last vertex reached.
        let mut root = set[0];
        for _ in 0..2 {
            let member = self.mark(&set);
            let visited = self.fresh_stamp();
            let reached = self.bfs(root, member, visited);
            root = *reached.last().expect("a connected set is not empty");
        }
        let member = self.mark(&set);
        let visited = self.fresh_stamp();
        let levels = self.bfs(root, member, visited);
        let depth_of_search = levels.last().map_or(0, |&v| self.level[v]);
        if depth_of_search < 2 {
            // Too dense to separate: every vertex is within two steps of the root.
            self.order.extend(set);
            return;
        }
        let middle = depth_of_search / 2;
        let (mut before, mut after, mut separator) = (Vec::new(), Vec::new(), Vec::new());
        for v in levels {
            match self.level[v].cmp(&middle) {
                std::cmp::Ordering::Less => before.push(v),
                std::cmp::Ordering::Greater => after.push(v),
                // Only the middle level's vertices with a neighbour beyond it separate; the
                // others join the earlier levels (a thinner separator, less fill).
                std::cmp::Ordering::Equal => {
                    let level = &self.level;
                    let stamp = &self.stamp;
                    let separates = self.rows[v]
                        .iter()
                        .any(|&(u, _)| stamp[u] == visited && level[u] == middle + 1);
                    if separates {
                        separator.push(v);
                    } else {
                        before.push(v);
                    }
                }
            }
        }
        self.dissect(before, depth + 1);
        self.dissect(after, depth + 1);
        self.order.extend(separator);
    }
}

/// The factor `L` of `P A P^T = L L^T`, column-compressed, with the permutation.
pub(crate) struct CholeskyFactor {
    /// `order[new] = old`.
    order: Vec<usize>,
    /// Column starts into `row_index` and `values` (`n + 1` entries); the diagonal comes first.
    column_start: Vec<usize>,
    row_index: Vec<usize>,
    values: Vec<f64>,
}

impl CholeskyFactor {
    /// Factors the symmetric matrix given by its full rows (both triangles, each row's entries
    /// with distinct columns) in the ordering `order` (`order[new] = old`), with `ridge` added
    /// to the diagonal. `None` if a pivot is not positive (the matrix is not numerically
    /// positive definite).
    pub(crate) fn new(rows: &[Vec<(usize, f64)>], order: Vec<usize>, ridge: f64) -> Option<CholeskyFactor> {
        let n = rows.len();
        let mut position = vec![0; n];
        for (new, &old) in order.iter().enumerate() {
            position[old] = new;
        }
        // Upper triangle of the permuted matrix by columns: column j holds rows i <= j.
        let mut columns: Vec<Vec<(usize, f64)>> = vec![Vec::new(); n];
        for (old_r, row) in rows.iter().enumerate() {
            let r = position[old_r];
            for &(old_c, v) in row {
                let c = position[old_c];
                if r <= c {
                    columns[c].push((r, v));
                }
            }
        }
        for (j, col) in columns.iter_mut().enumerate() {
            match col.iter_mut().find(|e| e.0 == j) {
                Some(d) => d.1 += ridge,
                None => col.push((j, ridge)),
            }
        }
        let parent = elimination_tree(&columns);
        let mut reach = Reach::new(n);
        // Symbolic pass: the number of entries of each column of L.
        let mut count = vec![1usize; n];
        for k in 0..n {
            for &i in reach.of(&columns, &parent, k) {
                count[i] += 1;
            }
        }
        let mut column_start = vec![0; n + 1];
        for j in 0..n {
            column_start[j + 1] = column_start[j] + count[j];
        }
        let nnz = column_start[n];
        let mut row_index = vec![0; nnz];
        let mut values = vec![0.0; nnz];
        let mut next = column_start.clone();
        let mut x = vec![0.0; n];
        for k in 0..n {
            for &(i, v) in &columns[k] {
                x[i] += v;
            }
            let mut d = x[k];
            x[k] = 0.0;
            for &i in reach.of(&columns, &parent, k) {
                let lki = x[i] / values[column_start[i]];
                x[i] = 0.0;
                for p in column_start[i] + 1..next[i] {
                    x[row_index[p]] -= values[p] * lki;
                }
                d -= lki * lki;
                let p = next[i];
                next[i] += 1;
                row_index[p] = k;
                values[p] = lki;
            }
            if d <= 0.0 || !d.is_finite() {
                return None;
            }
            let p = next[k];
            next[k] += 1;
            row_index[p] = k;
            values[p] = d.sqrt();
        }
        Some(CholeskyFactor {
            order,
            column_start,
            row_index,
            values,
        })
    }

    /// Entries of `L` (a measure of the fill).
    #[cfg(test)]
    pub(crate) fn nonzeros(&self) -> usize {
        self.values.len()
    }

    /// Solves `A x = b`.
    pub(crate) fn solve(&self, b: &[f64]) -> Vec<f64> {
        let n = self.order.len();
        let (cs, ri, lv) = (&self.column_start, &self.row_index, &self.values);
        let mut y: Vec<f64> = self.order.iter().map(|&old| b[old]).collect();
        for j in 0..n {
            y[j] /= lv[cs[j]];
            let yj = y[j];
            for p in cs[j] + 1..cs[j + 1] {
                y[ri[p]] -= lv[p] * yj;
            }
        }
        for j in (0..n).rev() {
            let mut s = y[j];
            for p in cs[j] + 1..cs[j + 1] {
                s -= lv[p] * y[ri[p]];
            }
            y[j] = s / lv[cs[j]];
        }
        let mut x = vec![0.0; n];
        for (new, &old) in self.order.iter().enumerate() {
            x[old] = y[new];
        }
        x
    }
}

/// The elimination tree of the upper-triangular column pattern `columns` (`parent[j]`, or
/// [`NONE`] for a root).
fn elimination_tree(columns: &[Vec<(usize, f64)>]) -> Vec<usize> {
    let n = columns.len();
    let mut parent = vec![NONE; n];
    let mut ancestor = vec![NONE; n];
    for (k, col) in columns.iter().enumerate() {
        for &(i, _) in col {
            let mut i = i;
            while i != NONE && i < k {
                let next = ancestor[i];
                ancestor[i] = k;
                if next == NONE {
                    parent[i] = k;
                }
                i = next;
            }
        }
    }
    parent
}

/// Buffers for the pattern of a row of `L`.
struct Reach {
    mark: Vec<usize>,
    path: Vec<usize>,
    stack: Vec<usize>,
}

impl Reach {
    fn new(n: usize) -> Reach {
        Reach {
            mark: vec![NONE; n],
            path: Vec::with_capacity(n),
            stack: vec![0; n],
        }
    }

    /// The pattern of row `k` of `L` below the diagonal (columns `< k`), in an order where every
    /// column comes before its elimination-tree ancestors.
    fn of(&mut self, columns: &[Vec<(usize, f64)>], parent: &[usize], k: usize) -> &[usize] {
        let n = columns.len();
        let mut top = n;
        self.mark[k] = k;
        for &(i, _) in &columns[k] {
            let mut i = i;
            if i >= k {
                continue;
            }
            self.path.clear();
            while self.mark[i] != k {
                self.path.push(i);
                self.mark[i] = k;
                i = parent[i];
            }
            while let Some(v) = self.path.pop() {
                top -= 1;
                self.stack[top] = v;
            }
        }
        &self.stack[top..]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The 5-point Laplacian of a `side x side` grid plus `shift` on the diagonal, as full rows.
    fn grid(side: usize, shift: f64) -> Vec<Vec<(usize, f64)>> {
        let idx = |r: usize, c: usize| r * side + c;
        let mut rows = vec![Vec::new(); side * side];
        for r in 0..side {
            for c in 0..side {
                let i = idx(r, c);
                rows[i].push((i, 4.0 + shift));
                if r > 0 {
                    rows[i].push((idx(r - 1, c), -1.0));
                }
                if r + 1 < side {
                    rows[i].push((idx(r + 1, c), -1.0));
                }
                if c > 0 {
                    rows[i].push((idx(r, c - 1), -1.0));
                }
                if c + 1 < side {
                    rows[i].push((idx(r, c + 1), -1.0));
                }
            }
        }
        rows
    }

    fn multiply(rows: &[Vec<(usize, f64)>], x: &[f64]) -> Vec<f64> {
        rows.iter()
            .map(|r| r.iter().map(|&(c, v)| v * x[c]).sum())
            .collect()
    }

    #[test]
    fn the_ordering_is_a_permutation() {
        let rows = grid(23, 0.0);
        let mut order = nested_dissection(&rows);
        order.sort_unstable();
        assert_eq!(order, (0..rows.len()).collect::<Vec<_>>());
    }

    #[test]
    fn solves_a_grid_laplacian_to_rounding() {
        let rows = grid(40, 1e-3);
        let x_true: Vec<f64> = (0..rows.len())
            .map(|i| ((i * 37) % 101) as f64 / 50.0 - 1.0)
            .collect();
        let b = multiply(&rows, &x_true);
        let factor = CholeskyFactor::new(&rows, nested_dissection(&rows), 0.0).expect("positive definite");
        let x = factor.solve(&b);
        let err = x
            .iter()
            .zip(&x_true)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        assert!(err < 1e-8, "largest error {err:e}");
    }

    #[test]
    fn nested_dissection_fills_far_less_than_the_natural_order() {
        // Natural (row-by-row) order of a 60 x 60 grid: a band of width 60, so about 60 entries
        // per column of L; nested dissection: O(n log n) entries.
        let rows = grid(60, 1e-3);
        let natural = CholeskyFactor::new(&rows, (0..rows.len()).collect(), 0.0).expect("definite");
        let dissected = CholeskyFactor::new(&rows, nested_dissection(&rows), 0.0).expect("definite");
        assert!(
            2 * dissected.nonzeros() < natural.nonzeros(),
            "fill: dissected {}, natural {}",
            dissected.nonzeros(),
            natural.nonzeros()
        );
    }

    #[test]
    fn an_indefinite_matrix_is_refused() {
        let mut rows = grid(10, 0.0);
        rows[37].iter_mut().find(|e| e.0 == 37).expect("diagonal").1 = -1.0;
        assert!(CholeskyFactor::new(&rows, nested_dissection(&rows), 0.0).is_none());
    }
}
