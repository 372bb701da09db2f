//! Torsional springs (the paper's ternary bonds): `E = T (u_ij . u_ik - M)^2`, counted once
//! per bond.

use crate::{ParticleId, Potential, SpringGeometry, Vec2};

/// A torsional spring centred on particle `i`, between the directions to `j` and `k`.
#[derive(Clone, Debug, PartialEq)]
pub struct Torsion {
    /// The centre particle `i`.
    pub center: ParticleId,
    /// The two end particles `j` and `k`.
    pub ends: [ParticleId; 2],
    /// Rest cosine `M` of the angle j-i-k (dimensionless, in [-1, 1]).
    pub rest_cos: f64,
    /// Angular stiffness `T`, energy units (the energy of a unit change of cosine).
    pub stiffness: f64,
}

/// Geometry of a torsion at given positions: the cosine and its gradient.
#[derive(Clone, Copy, Debug)]
pub struct TorsionGeometry {
    /// `c = u_ij . u_ik`, the cosine of the angle j-i-k.
    pub cos: f64,
    /// `dc/dx_i`, `dc/dx_j`, `dc/dx_k` (per px).
    pub dcos: [Vec2; 3],
}

impl TorsionGeometry {
    /// Measures the angle at `xi` between `xj` and `xk`. When an end coincides with the
    /// centre the angle is undefined and the gradient is zero.
    #[inline]
    pub fn new(xi: Vec2, xj: Vec2, xk: Vec2) -> Self {
        let a = SpringGeometry::new(xi, xj);
        let b = SpringGeometry::new(xi, xk);
        let cos = a.direction.dot(&b.direction);
        if a.length <= crate::spring::MIN_SEPARATION || b.length <= crate::spring::MIN_SEPARATION
        {
            return TorsionGeometry {
                cos,
                dcos: [Vec2::zeros(); 3],
            };
        }
        let dj = (b.direction - a.direction * cos) / a.length;
        let dk = (a.direction - b.direction * cos) / b.length;
        TorsionGeometry {
            cos,
            dcos: [-(dj + dk), dj, dk],
        }
    }

    /// Forces on `i`, `j`, `k` for stiffness `T` and rest cosine `M`:
    /// `f_p = -2 T (c - M) dc/dx_p`.
    #[inline]
    pub fn forces(&self, stiffness: f64, rest_cos: f64) -> [Vec2; 3] {
        let s = -2.0 * stiffness * (self.cos - rest_cos);
        [self.dcos[0] * s, self.dcos[1] * s, self.dcos[2] * s]
    }
}

impl Torsion {
    /// A torsion at `center` between `j` and `k`.
    pub fn new(center: ParticleId, j: ParticleId, k: ParticleId, rest_cos: f64, stiffness: f64) -> Self {
        Torsion {
            center,
            ends: [j, k],
            rest_cos,
            stiffness,
        }
    }

    /// The three particles `[i, j, k]`.
    #[inline]
    pub fn particles(&self) -> [ParticleId; 3] {
        [self.center, self.ends[0], self.ends[1]]
    }

    /// The torsion's geometry at positions `x`.
    #[inline]
    pub fn geometry(&self, x: &[Vec2]) -> TorsionGeometry {
        TorsionGeometry::new(
            x[self.center.index()],
            x[self.ends[0].index()],
            x[self.ends[1].index()],
        )
    }
}

impl Potential for Torsion {
    fn energy(&self, x: &[Vec2]) -> f64 {
        let d = self.geometry(x).cos - self.rest_cos;
        self.stiffness * d * d
    }

    #[inline]
    fn add_gradient(&self, x: &[Vec2], grad: &mut [Vec2]) {
        let f = self.geometry(x).forces(self.stiffness, self.rest_cos);
        for (p, fp) in self.particles().iter().zip(f) {
            grad[p.index()] -= fp;
        }
    }
}
