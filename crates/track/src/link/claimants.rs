//! The tracks that claim one detection, held without allocating.

/// The tracks (indices into the frame's live tracks) that claim one detection: almost always
/// none or one, which are held without allocating; more spill to a vector.
#[derive(Clone, Debug, Default)]
pub(super) struct Claimants {
    /// The first claimant, while there is exactly one.
    pub(super) one: [usize; 1],
    /// How many claimants there are.
    pub(super) count: usize,
    /// Every claimant, once there are two or more.
    many: Vec<usize>,
}

impl Claimants {
    /// Adds track `k`.
    pub(super) fn push(&mut self, k: usize) {
        match self.count {
            0 => self.one[0] = k,
            1 => self.many.extend([self.one[0], k]),
            _ => self.many.push(k),
        }
        self.count += 1;
    }
}

impl std::ops::Deref for Claimants {
    type Target = [usize];

    fn deref(&self) -> &[usize] {
        match self.count {
            0 => &[],
            1 => &self.one,
            _ => &self.many,
        }
    }
}
