//! The dynamic state of a model: positions and velocities.

use crate::Vec2;

/// Positions (px) and velocities (px/s) of every particle, indexed by [`crate::ParticleId`].
#[derive(Clone, Debug, Default, PartialEq)]
pub struct State {
    /// Positions, px (x right, y down, pixel centres at integer coordinates).
    pub positions: Vec<Vec2>,
    /// Velocities, px/s.
    pub velocities: Vec<Vec2>,
}

impl State {
    /// A state from positions and velocities of equal length.
    ///
    /// # Panics
    /// If the lengths differ.
    pub fn new(positions: Vec<Vec2>, velocities: Vec<Vec2>) -> Self {
        assert_eq!(positions.len(), velocities.len(), "one velocity per position");
        State {
            positions,
            velocities,
        }
    }

    /// A state at rest at `positions`.
    pub fn at_rest(positions: Vec<Vec2>) -> Self {
        let n = positions.len();
        State::new(positions, vec![Vec2::zeros(); n])
    }

    /// Number of particles.
    pub fn len(&self) -> usize {
        self.positions.len()
    }

    /// Returns true if and only if the state holds no particle.
    pub fn is_empty(&self) -> bool {
        self.positions.is_empty()
    }
}
