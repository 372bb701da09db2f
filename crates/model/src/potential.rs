//! The [`Potential`] trait: every conservative force in physfit derives from an energy.
//!
//! A key design decision made in this crate is that a force is never written by hand: each
//! conservative term (spring, torsion, uniform field) implements [`Potential`], and the force
//! on a particle is minus the gradient it adds. The renderer's simulator and the identifier's
//! cost functions both call these implementations, so the force law lives in one place.

use crate::Vec2;

/// A conservative interaction with an energy (in mass·px²/s²) that depends on positions only.
pub trait Potential {
    /// Energy of the configuration `x` (positions in px, indexed by particle).
    fn energy(&self, x: &[Vec2]) -> f64;

    /// Adds the gradient of [`Potential::energy`] with respect to each position into `grad`
    /// (energy per px). The force on particle `p` is `-grad[p]`.
    fn add_gradient(&self, x: &[Vec2], grad: &mut [Vec2]);
}
