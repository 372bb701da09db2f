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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn force_law_matches_the_paper() {
        // Stretched by 2 px along +x with S = 3: f_i = 2 S (d - L) u_ij = (12, 0) toward j.
        let x = [Vec2::new(1.0, 2.0), Vec2::new(6.0, 2.0)];
        let s = Spring::new(ParticleId(0), ParticleId(1), 3.0, 3.0);
        let f = s.geometry(&x).force_on_i(3.0, 3.0);
        assert!((f - Vec2::new(12.0, 0.0)).norm() < 1e-12);
        assert!((s.energy(&x) - 12.0).abs() < 1e-12, "E = S (d - L)^2, no 1/2");
        let mut g = [Vec2::zeros(); 2];
        s.add_gradient(&x, &mut g);
        assert!((g[0] + f).norm() < 1e-12 && (g[1] - f).norm() < 1e-12);
    }

    #[test]
    fn coincident_particles_give_no_force() {
        let x = [Vec2::new(4.0, 4.0); 2];
        let s = Spring::new(ParticleId(0), ParticleId(1), 3.0, 3.0);
        let mut g = [Vec2::zeros(); 2];
        s.add_gradient(&x, &mut g);
        assert!(g.iter().all(|v| v.norm() == 0.0));
        assert!((s.energy(&x) - 27.0).abs() < 1e-12);
    }
}

#[cfg(test)]
mod proptests {
    use super::*;
    use crate::proptest_utils::*;
    use proptest::prelude::*;

    fn check(spring: &Spring, x: &[Vec2]) -> Result<f64, TestCaseError> {
        let d = spring.geometry(x).length;
        // Step: small against the length (truncation ~ (h/d)^2), large against the
        // coordinates' rounding.
        let h = 1e-4 * d;
        let floor = spring_floor(spring, x, h, coordinate_scale(x));
        check_gradient(spring, x, h, &[floor, floor])
    }

    proptest! {
        #[test]
        fn gradient_matches_finite_differences((spring, x) in spring_with_length(log_uniform(1.0, 1000.0))) {
            check(&spring, &x)?;
        }

        #[test]
        fn very_short_spring_gradient_matches((spring, x) in spring_with_length(log_uniform(1e-2, 1.0))) {
            check(&spring, &x)?;
        }

        #[test]
        fn very_long_spring_gradient_matches((spring, x) in spring_with_length(log_uniform(1e3, 1e5))) {
            check(&spring, &x)?;
        }

        #[test]
        fn forces_are_equal_and_opposite((spring, x) in spring_with_length(log_uniform(1e-2, 1e5))) {
            let g = analytic_gradient(&spring, &x);
            prop_assert!((g[0] + g[1]).norm() <= 1e-12 * g[0].norm());
            // And along the bond: no torque.
            let u = spring.geometry(&x).direction;
            prop_assert!((g[0].x * u.y - g[0].y * u.x).abs() <= 1e-12 * g[0].norm());
        }
    }
}
