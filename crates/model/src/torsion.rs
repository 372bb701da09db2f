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
        if a.length <= crate::spring::MIN_SEPARATION || b.length <= crate::spring::MIN_SEPARATION {
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn right_angle_forces_match_the_paper() {
        // i at the origin, j on +x at 2, k on +y at 4: c = 0. With T = 5, M = 0.5:
        // dc/dx_j = (u_ik - c u_ij) / d_ij = (0, 1/2), dc/dx_k = (1/4, 0).
        let x = [Vec2::zeros(), Vec2::new(2.0, 0.0), Vec2::new(0.0, 4.0)];
        let t = Torsion::new(ParticleId(0), ParticleId(1), ParticleId(2), 0.5, 5.0);
        let geo = t.geometry(&x);
        assert!(geo.cos.abs() < 1e-15);
        assert!((geo.dcos[1] - Vec2::new(0.0, 0.5)).norm() < 1e-15);
        assert!((geo.dcos[2] - Vec2::new(0.25, 0.0)).norm() < 1e-15);
        assert!((geo.dcos[0] + geo.dcos[1] + geo.dcos[2]).norm() < 1e-15);
        // f_p = -2 T (c - M) dc/dx_p = 5 dc/dx_p: opening the angle toward M = 0.5 means closing it.
        let f = geo.forces(5.0, 0.5);
        assert!((f[1] - Vec2::new(0.0, 2.5)).norm() < 1e-14);
        assert!((t.energy(&x) - 1.25).abs() < 1e-14, "E = T (c - M)^2, no 1/2");
    }

    #[test]
    fn degenerate_arm_gives_no_force() {
        let x = [Vec2::new(1.0, 1.0), Vec2::new(1.0, 1.0), Vec2::new(0.0, 4.0)];
        let t = Torsion::new(ParticleId(0), ParticleId(1), ParticleId(2), 0.5, 5.0);
        let mut g = [Vec2::zeros(); 3];
        t.add_gradient(&x, &mut g);
        assert!(g.iter().all(|v| v.norm() == 0.0 && v.x.is_finite()));
    }
}

#[cfg(test)]
mod proptests {
    use super::*;
    use crate::proptest_utils::*;
    use proptest::prelude::*;

    fn check(t: &Torsion, x: &[Vec2]) -> Result<f64, TestCaseError> {
        let arm = (x[1] - x[0]).norm().min((x[2] - x[0]).norm());
        let h = 1e-5 * arm;
        let floor = torsion_floor(t, x, h, coordinate_scale(x));
        check_gradient(t, x, h, &[floor; 3])
    }

    proptest! {
        #[test]
        fn gradient_matches_finite_differences((t, x) in torsion_at(AngleKind::Any)) {
            check(&t, &x)?;
        }

        #[test]
        fn near_straight_gradient_matches((t, x) in torsion_at(AngleKind::NearStraight)) {
            prop_assert!(t.geometry(&x).cos + 1.0 <= 1.0001e-6);
            check(&t, &x)?;
        }

        #[test]
        fn near_folded_gradient_matches((t, x) in torsion_at(AngleKind::NearFolded)) {
            prop_assert!(1.0 - t.geometry(&x).cos <= 1.0001e-6);
            check(&t, &x)?;
        }

        #[test]
        fn forces_sum_to_zero_with_no_torque((t, x) in torsion_at(AngleKind::Any)) {
            let g = analytic_gradient(&t, &x);
            let size: f64 = g.iter().map(|v| v.norm()).sum();
            let sum: Vec2 = g.iter().sum();
            prop_assert!(sum.norm() <= 1e-12 * size);
            // Rotation invariance: no net torque about the centre.
            let torque: f64 = (1..3).map(|p| { let r = x[p] - x[0]; r.x * g[p].y - r.y * g[p].x }).sum();
            let scale: f64 = (1..3).map(|p| (x[p] - x[0]).norm() * g[p].norm()).sum();
            prop_assert!(torque.abs() <= 1e-10 * scale);
        }
    }
}
