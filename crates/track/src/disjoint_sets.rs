//! Disjoint sets (union-find with path halving): the groups of items joined by pairwise
//! relations (touching particles, tracks that meet, gated assignment pairs).

/// A partition of the items `0..n` into sets, refined by [`DisjointSets::union`].
#[derive(Clone, Debug)]
pub(crate) struct DisjointSets {
    parent: Vec<usize>,
}

impl DisjointSets {
    /// `n` items, each in a set of its own.
    pub(crate) fn new(n: usize) -> DisjointSets {
        DisjointSets {
            parent: (0..n).collect(),
        }
    }

    /// The representative of the set holding item `a`.
    pub(crate) fn root(&mut self, mut a: usize) -> usize {
        while self.parent[a] != a {
            self.parent[a] = self.parent[self.parent[a]];
            a = self.parent[a];
        }
        a
    }

    /// Joins the sets holding items `a` and `b` (the set of `b` gives the representative).
    pub(crate) fn union(&mut self, a: usize, b: usize) {
        let (ra, rb) = (self.root(a), self.root(b));
        self.parent[ra] = rb;
    }
}

#[cfg(test)]
mod tests {
    use super::DisjointSets;

    #[test]
    fn unions_join_sets_transitively_and_nothing_else() {
        let mut s = DisjointSets::new(6);
        s.union(0, 1);
        s.union(3, 4);
        s.union(1, 4);
        assert_eq!(s.root(0), s.root(3));
        assert_eq!(s.root(1), s.root(4));
        assert_ne!(s.root(0), s.root(2));
        assert_ne!(s.root(5), s.root(2));
    }
}
