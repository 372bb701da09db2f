//! Physics beyond the paper: uniform field, linear drag, spring dashpots and walls.
//!
//! Each effect is off unless a scene turns it on, and the model can evaluate any combination.
//! The conservative field is a [`crate::Potential`] (see [`crate::Model`]); drag and dashpots
//! depend on velocities and are added as forces; walls are events applied after each
//! integration substep.

use crate::Vec2;

/// A straight wall: the line through `point` with unit `normal` pointing into the allowed side.
#[derive(Clone, Debug, PartialEq)]
pub struct Wall {
    /// A point on the wall line, px.
    pub point: Vec2,
    /// Unit normal pointing into the allowed half-plane.
    pub normal: Vec2,
    /// Coefficient of restitution on the normal velocity (0 = stops, 1 = elastic).
    pub restitution: f64,
}

impl Wall {
    /// A wall through `point` with normal `normal` (normalised here).
    ///
    /// Returns `None` if the normal has zero length or is not finite.
    pub fn new(point: Vec2, normal: Vec2, restitution: f64) -> Option<Wall> {
        let n = normal.norm();
        if n > 0.0 && n.is_finite() {
            Some(Wall {
                point,
                normal: normal / n,
                restitution,
            })
        } else {
            None
        }
    }

    /// Signed distance of `x` from the wall line, px: positive on the allowed side.
    #[inline]
    pub fn signed_distance(&self, x: Vec2) -> f64 {
        (x - self.point).dot(&self.normal)
    }

    /// Applies the reflection law to one particle: a centre found on the wrong side is
    /// mirrored back with its penetration scaled by the restitution, and an approaching normal
    /// velocity `v_n < 0` becomes `-restitution * v_n`. Returns true if and only if it bounced.
    #[inline]
    pub fn reflect(&self, x: &mut Vec2, v: &mut Vec2) -> bool {
        let s = self.signed_distance(*x);
        if s >= 0.0 {
            return false;
        }
        *x -= self.normal * ((1.0 + self.restitution) * s);
        let vn = v.dot(&self.normal);
        if vn < 0.0 {
            *v -= self.normal * ((1.0 + self.restitution) * vn);
        }
        true
    }
}

/// The extra physics of a model. `Physics::default()` is the paper's model: nothing extra.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Physics {
    /// Uniform acceleration field `[gx, gy]`, px/s² (y down, so gravity is `[0, +g]`).
    pub gravity: Vec2,
    /// Linear drag coefficient, 1/s: `F = -drag * m * v`.
    pub drag: f64,
    /// Quadratic drag coefficient, 1/px: `F = -quadratic_drag * m * |v| v`.
    pub quadratic_drag: f64,
    /// Global spring dashpot coefficient, mass/s: `F_i = c ((v_j - v_i) . u_ij) u_ij`.
    pub spring_damping: f64,
    /// Walls the particles' centres bounce off.
    pub walls: Vec<Wall>,
}

impl Physics {
    /// Returns true if and only if any velocity-dependent force is on.
    pub fn has_dissipation(&self) -> bool {
        self.drag != 0.0 || self.quadratic_drag != 0.0 || self.spring_damping != 0.0
    }
}
