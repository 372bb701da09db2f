//! Extension springs (the paper's binary bonds): `E = S (d - L)^2`, counted once per bond.

use crate::{ParticleId, Potential, Vec2};

/// Separations below this (px) are treated as coincident particles, whose bond direction
/// is undefined: they exert no force rather than a NaN.
pub const MIN_SEPARATION: f64 = 1e-9;

/// A spring between particles `i` and `j` with rest length `L` and stiffness `S`.
#[derive(Clone, Debug, PartialEq)]
pub struct Spring {
    /// The two particles joined.
    pub ends: [ParticleId; 2],
    /// Rest length `L`, px.
    pub rest_length: f64,
    /// Stiffness `S`, energy per px² (force per px is `2 S`).
    pub stiffness: f64,
    /// Per-spring dashpot coefficient (mass/s), overriding the global `spring_damping`.
    pub damping: Option<f64>,
}

/// Geometry of a spring at given positions: length and unit direction from `i` to `j`.
#[derive(Clone, Copy, Debug)]
pub struct SpringGeometry {
    /// Current length `d = |x_j - x_i|`, px.
    pub length: f64,
    /// Unit vector `u_ij` from `i` to `j` (zero when the particles coincide).
    pub direction: Vec2,
}

impl SpringGeometry {
    /// Measures the spring between `xi` and `xj`.
    #[inline]
    pub fn new(xi: Vec2, xj: Vec2) -> Self {
        let delta = xj - xi;
        let length = delta.norm();
        let direction = if length > MIN_SEPARATION {
            delta / length
        } else {
            Vec2::zeros()
        };
        SpringGeometry { length, direction }
    }

    /// Force on particle `i` (the force on `j` is its negative) for stiffness `S` and rest
    /// length `L`: `f_i = 2 S (d - L) u_ij`.
    #[inline]
    pub fn force_on_i(&self, stiffness: f64, rest_length: f64) -> Vec2 {
        self.direction * (2.0 * stiffness * (self.length - rest_length))
    }
}

impl Spring {
    /// A spring between `i` and `j` with rest length `rest_length` (px) and stiffness `stiffness`.
    pub fn new(i: ParticleId, j: ParticleId, rest_length: f64, stiffness: f64) -> Self {
        Spring {
            ends: [i, j],
            rest_length,
            stiffness,
            damping: None,
        }
    }

    /// The spring's geometry at positions `x`.
    #[inline]
    pub fn geometry(&self, x: &[Vec2]) -> SpringGeometry {
        SpringGeometry::new(x[self.ends[0].index()], x[self.ends[1].index()])
    }
}

impl Potential for Spring {
    fn energy(&self, x: &[Vec2]) -> f64 {
        let ext = self.geometry(x).length - self.rest_length;
        self.stiffness * ext * ext
    }

    #[inline]
    fn add_gradient(&self, x: &[Vec2], grad: &mut [Vec2]) {
        let f_i = self.geometry(x).force_on_i(self.stiffness, self.rest_length);
        grad[self.ends[0].index()] -= f_i;
        grad[self.ends[1].index()] += f_i;
    }
}
