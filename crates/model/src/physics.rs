//! Physics beyond the paper: uniform field, linear drag, spring dashpots and walls.
//!
//! Each effect is off unless a scene turns it on, and the model can evaluate any combination.
//! The conservative field is a [`crate::Potential`] (see [`crate::Model`]); drag and dashpots
//! depend on velocities and are added as forces; walls are events applied after each
//! integration substep. A wall's Coulomb friction acts inside that event, as a tangential
//! impulse bounded by `friction` times the normal impulse: one law gives both the friction
//! of a bounce and the sliding friction `mu m g_n` of a particle resting on the wall (whose
//! normal impulse over a substep is `m g_n dt`), and a tangential speed the bound covers is
//! brought to zero exactly, so a particle stops and stays stopped (no chattering).
//!
//! A wall with a `stiffness` is a spring bumper instead: no event, but a one-sided spring
//! (energy `S s^2` for a penetration `s < 0`, once and with no 1/2 like a bond) and dashpot
//! along its normal, so the contact line moves with the impact speed. Its spring is part of
//! the model's [`crate::Potential`], its dashpot a velocity-dependent force.

use crate::{Rail, Rope, State, Vec2};

/// A straight wall: the line through `point` with unit `normal` pointing into the allowed side.
#[derive(Clone, Debug, PartialEq)]
pub struct Wall {
    /// A point on the wall line, px.
    pub point: Vec2,
    /// Unit normal pointing into the allowed half-plane.
    pub normal: Vec2,
    /// Coefficient of restitution on the normal velocity (0 = stops, 1 = elastic).
    pub restitution: f64,
    /// Coulomb friction coefficient `mu` (dimensionless, 0 = frictionless): the tangential
    /// velocity change of a contact is at most `mu` times its normal velocity change.
    pub friction: f64,
    /// Bumper stiffness `S`, energy/px² (mass/s²): 0 = a rigid wall (the event law); above
    /// 0 a one-sided spring of energy `S s^2` for a penetration `s < 0`, so force `-2 S s`
    /// along the normal (the usual spring constant is `k = 2 S`).
    pub stiffness: f64,
    /// Bumper dashpot coefficient `c`, mass/s: force `-c v_n` along the normal while the
    /// centre is beyond the line (only on a bumper, `stiffness > 0`).
    pub damping: f64,
}

impl Wall {
    /// A wall through `point` with normal `normal` (normalised here; a normal already of unit
    /// length to rounding is kept bit for bit, so that writing a scene and reading it back
    /// gives the same wall).
    ///
    /// Returns `None` if the normal has zero length or is not finite.
    pub fn new(point: Vec2, normal: Vec2, restitution: f64) -> Option<Wall> {
        let n = normal.norm();
        if n > 0.0 && n.is_finite() {
            let normal = if (n - 1.0).abs() <= 4.0 * f64::EPSILON {
                normal
            } else {
                normal / n
            };
            Some(Wall {
                point,
                normal,
                restitution,
                friction: 0.0,
                stiffness: 0.0,
                damping: 0.0,
            })
        } else {
            None
        }
    }

    /// This wall with Coulomb friction coefficient `mu` (dimensionless).
    pub fn with_friction(self, mu: f64) -> Wall {
        Wall { friction: mu, ..self }
    }

    /// This wall as a spring bumper of stiffness `stiffness` (energy/px²) and dashpot
    /// `damping` (mass/s). A mass `m` that hits it at normal speed `v` with no other force
    /// stays in contact for `pi / w_d` s and leaves at `e v`, with `w = sqrt(2 S / m)`,
    /// `zeta = c / (2 sqrt(2 S m))`, `w_d = w sqrt(1 - zeta^2)` and
    /// `e = exp(-zeta pi / sqrt(1 - zeta^2))` (light damping); it enters at most `v / w` px
    /// when `c = 0`.
    pub fn with_bumper(self, stiffness: f64, damping: f64) -> Wall {
        Wall {
            stiffness,
            damping,
            ..self
        }
    }

    /// The restitution of this bumper for a mass `mass` meeting it with no other force:
    /// `exp(-zeta pi / sqrt(1 - zeta^2))` with `zeta = c / (2 sqrt(2 S m))` while
    /// `zeta < 1`, and 0 from critical damping on (the mass creeps back without rebounding).
    /// A rigid wall's is its `restitution`.
    pub fn bumper_restitution(&self, mass: f64) -> f64 {
        if !self.is_bumper() {
            return self.restitution;
        }
        let zeta = self.damping / (2.0 * (2.0 * self.stiffness * mass).sqrt());
        if zeta < 1.0 {
            (-zeta * std::f64::consts::PI / (1.0 - zeta * zeta).sqrt()).exp()
        } else {
            0.0
        }
    }

    /// The contact time of this bumper for a mass `mass` with no other force, s:
    /// `pi / (w sqrt(1 - zeta^2))`, `w = sqrt(2 S / m)` (see [`Wall::bumper_restitution`]);
    /// `None` for a rigid wall or from critical damping on.
    pub fn bumper_contact_time(&self, mass: f64) -> Option<f64> {
        let zeta = self.damping / (2.0 * (2.0 * self.stiffness * mass).sqrt());
        (self.is_bumper() && zeta < 1.0).then(|| {
            std::f64::consts::PI / ((2.0 * self.stiffness / mass).sqrt() * (1.0 - zeta * zeta).sqrt())
        })
    }

    /// Returns true if and only if the wall is a spring bumper (`stiffness > 0`): forces,
    /// not the event law.
    #[inline]
    pub fn is_bumper(&self) -> bool {
        self.stiffness > 0.0
    }

    /// Energy of the bumper spring with a centre at `x` (px), mass·px²/s²: `S s^2` for a
    /// penetration `s < 0`, else 0.
    #[inline]
    pub fn bumper_energy(&self, x: Vec2) -> f64 {
        let s = self.signed_distance(x).min(0.0);
        self.stiffness * s * s
    }

    /// Gradient of [`Wall::bumper_energy`] at `x`, energy per px: `2 S s n` for `s < 0`.
    #[inline]
    pub fn bumper_gradient(&self, x: Vec2) -> Vec2 {
        let s = self.signed_distance(x).min(0.0);
        self.normal * (2.0 * self.stiffness * s)
    }

    /// Dashpot force of the bumper on a centre at `x` (px) moving at `v` (px/s),
    /// mass·px/s²: `-c (v . n) n` while `s < 0`, else zero.
    #[inline]
    pub fn bumper_damping_force(&self, x: Vec2, v: Vec2) -> Vec2 {
        if self.signed_distance(x) < 0.0 {
            self.normal * (-self.damping * v.dot(&self.normal))
        } else {
            Vec2::zeros()
        }
    }

    /// Signed distance of `x` from the wall line, px: positive on the allowed side.
    #[inline]
    pub fn signed_distance(&self, x: Vec2) -> f64 {
        (x - self.point).dot(&self.normal)
    }

    /// Applies the reflection law to one particle: a centre found on the wrong side is
    /// mirrored back with its penetration scaled by the restitution, and an approaching normal
    /// velocity `v_n < 0` becomes `-restitution * v_n`. Returns true if and only if it bounced
    /// (never for a bumper, whose contact is a force).
    #[inline]
    pub fn reflect(&self, x: &mut Vec2, v: &mut Vec2) -> bool {
        let s = self.signed_distance(*x);
        if s >= 0.0 || self.is_bumper() {
            return false;
        }
        *x -= self.normal * ((1.0 + self.restitution) * s);
        let vn = v.dot(&self.normal);
        if vn < 0.0 {
            *v -= self.normal * ((1.0 + self.restitution) * vn);
        }
        true
    }

    /// Applies the reflection law to a particle found at `x` with velocity `v` (px/s) at the
    /// end of an integration substep of `dt` s during which its acceleration was about `a`
    /// (px/s²). Returns true if and only if it bounced.
    ///
    /// This is the event law the integrators use. It takes the normal acceleration `a_n` as
    /// constant over the substep: the centre crossed the line a time `tau = s / v_n` ago (to
    /// first order, clamped to `[0, dt]`), had normal velocity `v_n - a_n tau` there, left it
    /// with `-restitution` times that, and moved on under `a_n` for `tau`. Hence
    /// `s' = -e s + (1 + e) a_n tau^2 / 2` and `v_n' = -e v_n + (1 + e) a_n tau`, which keeps
    /// the bounce accurate to second order in `dt` (the plain mirror law of [`Wall::reflect`]
    /// is off by `(1 + e) a_n tau` in velocity, an energy gain at every bounce under gravity).
    /// When `a_n` pushes the particle back faster than it rebounds (resting contact), it is
    /// left on the line with no normal velocity: it never ends a substep on the wrong side.
    /// Without friction the tangential velocity is unchanged; with friction see
    /// [`Wall::apply_friction`]. A bumper never bounces (its contact is a force).
    #[inline]
    pub fn reflect_in_substep(&self, x: &mut Vec2, v: &mut Vec2, a: Vec2, dt: f64) -> bool {
        let s = self.signed_distance(*x);
        if s >= 0.0 || self.is_bumper() {
            return false;
        }
        let e = self.restitution;
        let vn = v.dot(&self.normal);
        if vn < 0.0 {
            let an = a.dot(&self.normal);
            let tau = (s / vn).clamp(0.0, dt.max(0.0));
            let s_new = (-e * s + (1.0 + e) * an * tau * tau * 0.5).max(0.0);
            let vn_new = (-e * vn + (1.0 + e) * an * tau).max(0.0);
            *x += self.normal * (s_new - s);
            *v += self.normal * (vn_new - vn);
            if self.friction != 0.0 {
                self.apply_friction(x, v, vn_new - vn, tau);
            }
        } else {
            // Already leaving (pushed across by another force): only the position is wrong.
            *x -= self.normal * ((1.0 + self.restitution) * s);
        }
        true
    }

    /// Coulomb friction of one contact: the tangential velocity `v_t` (px/s) loses
    /// `min(mu * dv_n, |v_t|)`, where `dv_n` (px/s, >= 0) is the contact's normal velocity
    /// change (its normal impulse per unit mass). Resting on the wall under a normal
    /// acceleration `g_n`, `dv_n = g_n dt` each substep: a sliding particle decelerates at
    /// `mu g_n` and stops after `v0^2 / (2 mu g_n)` px; once stopped it stays stopped while the
    /// tangential push is at most `mu g_n` (the static condition), since the bound then
    /// covers what the push added. The impulse is taken at the contact, `tau` s before the end
    /// of the substep, so the position moves back by the velocity change times `tau` (for a
    /// resting contact `tau = dt / 2`: the trapezoidal rule of a constant deceleration).
    #[inline]
    pub fn apply_friction(&self, x: &mut Vec2, v: &mut Vec2, dv_n: f64, tau: f64) {
        coulomb_friction(self.normal, self.friction, x, v, dv_n, tau);
    }
}

/// Coulomb friction of a contact with unit `normal` and coefficient `mu`: the velocity `v`'s
/// part across the normal (px/s) loses `min(mu * dv_n, |v_t|)`, `dv_n` (px/s, >= 0) the
/// contact's normal velocity change; the position `x` moves by the change times `tau` (s),
/// the time since the contact. The one law of walls ([`Wall::apply_friction`]), rails and
/// the surface ([`Physics::surface_friction`], with a zero `normal`).
#[inline]
pub(crate) fn coulomb_friction(normal: Vec2, mu: f64, x: &mut Vec2, v: &mut Vec2, dv_n: f64, tau: f64) {
    let vt = *v - normal * v.dot(&normal);
    let speed = vt.norm();
    if speed > 0.0 && dv_n > 0.0 {
        let change = vt * -((mu * dv_n).min(speed) / speed);
        *v += change;
        *x += change * tau;
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
    /// Linear drag coefficient `b` of every body without its own, mass/s: `F = -b v`, not
    /// scaled by the mass (bodies of one shape and different masses share one medium).
    pub body_drag: f64,
    /// Quadratic drag coefficient `c` of every body without its own, mass/px:
    /// `F = -c |v| v`, not scaled by the mass.
    pub body_quadratic_drag: f64,
    /// Dry friction of the surface the motion lies on (a table or an air-less floor seen
    /// from above), px/s²: the deceleration `mu g` of every free particle while it slides,
    /// `F = -surface_friction * m * v / |v|`; a particle at rest stays at rest while the
    /// other forces on it are below `m * surface_friction` (Coulomb's law with the normal
    /// force out of the image plane, so only the product `mu g` shows).
    pub surface_friction: f64,
    /// Walls the particles' centres bounce off.
    pub walls: Vec<Wall>,
    /// Ropes and rods: distance constraints between particles.
    pub ropes: Vec<Rope>,
    /// Rails: particles held on lines.
    pub rails: Vec<Rail>,
}

impl Physics {
    /// Applies the surface's dry friction ([`Physics::surface_friction`]) over a substep of
    /// `dt` s to the free particles of `state` (`fixed[k]` is true for a fixed particle):
    /// each velocity loses `min(surface_friction dt, |v|)` along itself, and its position
    /// that change times `tau` s, the time over which the substep's update moved it with
    /// that velocity (`dt / 2` for velocity Verlet, the trapezoidal rule of a uniform
    /// deceleration; `dt` for semi-implicit Euler), so that a particle the other forces
    /// cannot start stays where it is.
    pub fn apply_surface_friction(
        &self,
        fixed: impl Iterator<Item = bool>,
        state: &mut State,
        dt: f64,
        tau: f64,
    ) {
        let push = self.surface_friction * dt;
        for ((x, v), fixed) in state
            .positions
            .iter_mut()
            .zip(state.velocities.iter_mut())
            .zip(fixed)
        {
            if !fixed {
                coulomb_friction(Vec2::zeros(), 1.0, x, v, push, tau);
            }
        }
    }

    /// Returns true if and only if some rope or rail constrains the motion.
    pub fn has_constraints(&self) -> bool {
        !self.ropes.is_empty() || !self.rails.is_empty()
    }

    /// Returns true if and only if a global velocity-dependent force is on (linear or quadratic
    /// drag per mass or per body, global spring dashpot). Per-spring dashpot and per-particle
    /// drag overrides live on the springs and particles: ask
    /// [`crate::Model::has_velocity_dependent_forces`] for the whole model.
    pub fn has_dissipation(&self) -> bool {
        self.drag != 0.0
            || self.quadratic_drag != 0.0
            || self.spring_damping != 0.0
            || self.body_drag != 0.0
            || self.body_quadratic_drag != 0.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_unit_normal_is_kept_bit_for_bit() {
        let once = Wall::new(Vec2::zeros(), Vec2::new(1.0, 1.0), 0.5).unwrap();
        let twice = Wall::new(Vec2::zeros(), once.normal, 0.5).unwrap();
        assert_eq!(once.normal.map(f64::to_bits), twice.normal.map(f64::to_bits));
        assert!((once.normal.norm() - 1.0).abs() < 1e-15);
        assert!(Wall::new(Vec2::zeros(), Vec2::zeros(), 0.5).is_none());
        assert!(Wall::new(Vec2::zeros(), Vec2::new(f64::NAN, 1.0), 0.5).is_none());
    }

    #[test]
    fn the_event_law_undoes_the_substep_after_the_crossing() {
        // Floor at y = 0 facing up (-y, y down); a centre 0.02 px below after a substep of
        // 1 ms, moving down at 40 px/s under 1000 px/s² down: it crossed tau = 0.5 ms ago.
        let wall = Wall::new(Vec2::zeros(), Vec2::new(0.0, -1.0), 0.5).unwrap();
        let (mut x, mut v) = (Vec2::new(3.0, 0.02), Vec2::new(7.0, 40.0));
        assert!(wall.reflect_in_substep(&mut x, &mut v, Vec2::new(0.0, 1000.0), 1e-3));
        let tau = 0.5e-3;
        // v_n = -40, a_n = -1000: v_n' = 0.5 * 40 - 1.5 * 1000 tau; s' = 0.5 * 0.02 - 1.5 * 1000 tau^2 / 2.
        assert!((v.y + (20.0 - 1.5 * 1000.0 * tau)).abs() < 1e-12, "{v:?}");
        assert!((x.y + (0.01 - 0.75 * 1000.0 * tau * tau)).abs() < 1e-12, "{x:?}");
        assert!((v.x - 7.0).abs() < 1e-15 && (x.x - 3.0).abs() < 1e-15);
        // With no acceleration it is the mirror law of `reflect`.
        let (mut x1, mut v1) = (Vec2::new(3.0, 0.02), Vec2::new(7.0, 40.0));
        let (mut x2, mut v2) = (x1, v1);
        wall.reflect_in_substep(&mut x1, &mut v1, Vec2::zeros(), 1e-3);
        wall.reflect(&mut x2, &mut v2);
        assert!((x1 - x2).norm() < 1e-15 && (v1 - v2).norm() < 1e-15);
    }

    #[test]
    fn the_bumper_force_is_minus_the_gradient_of_its_energy() {
        // Central differences of S s^2 against 2 S s n, inside and outside the line.
        let wall = Wall::new(Vec2::new(1.0, 2.0), Vec2::new(3.0, -4.0), 0.0)
            .unwrap()
            .with_bumper(7.5, 0.0);
        let h = 1e-6;
        for x in [Vec2::new(0.3, 4.1), Vec2::new(-2.0, 5.5), Vec2::new(4.0, -1.0)] {
            let g = wall.bumper_gradient(x);
            let fd = Vec2::new(
                wall.bumper_energy(x + Vec2::new(h, 0.0)) - wall.bumper_energy(x - Vec2::new(h, 0.0)),
                wall.bumper_energy(x + Vec2::new(0.0, h)) - wall.bumper_energy(x - Vec2::new(0.0, h)),
            ) / (2.0 * h);
            assert!(
                (g - fd).norm() <= 1e-6 * (1.0 + g.norm()),
                "{x:?}: {g:?} vs {fd:?}"
            );
        }
        // Beyond the line only; a bumper never takes the event law.
        assert!(wall.bumper_gradient(Vec2::new(4.0, -1.0)).norm() == 0.0);
        let (mut x, mut v) = (Vec2::new(0.3, 4.1), Vec2::new(-1.0, 1.0));
        assert!(
            wall.signed_distance(x) < 0.0 && !wall.reflect_in_substep(&mut x, &mut v, Vec2::zeros(), 1e-3)
        );
    }

    #[test]
    fn resting_contact_leaves_the_particle_on_the_line() {
        // Inelastic, slow, strongly pushed into the wall: it stays on the line, at rest in n.
        let wall = Wall::new(Vec2::new(0.0, 10.0), Vec2::new(0.0, -1.0), 0.0).unwrap();
        let (mut x, mut v) = (Vec2::new(0.0, 10.001), Vec2::new(1.0, 2.0));
        assert!(wall.reflect_in_substep(&mut x, &mut v, Vec2::new(0.0, 5000.0), 1e-3));
        assert!(wall.signed_distance(x).abs() < 1e-12 && v.y.abs() < 1e-12 && (v.x - 1.0).abs() < 1e-15);
        // A centre on the allowed side is left alone.
        let (mut x, mut v) = (Vec2::new(0.0, 9.0), Vec2::new(0.0, 50.0));
        assert!(!wall.reflect_in_substep(&mut x, &mut v, Vec2::zeros(), 1e-3));
        assert!((x.y - 9.0).abs() < 1e-15 && (v.y - 50.0).abs() < 1e-15);
    }
}
