//! [`Model`]: particles, bonds and extra physics, with the total force and energy.

use crate::{Particle, ParticleSet, Physics, Potential, Spring, SpringGeometry, State, Torsion, Vec2};

/// A simulation-ready physical model: every parameter known.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Model {
    /// The point masses.
    pub particles: ParticleSet,
    /// Extension springs.
    pub springs: Vec<Spring>,
    /// Torsional springs.
    pub torsions: Vec<Torsion>,
    /// Physics beyond the paper (all off by default).
    pub physics: Physics,
}

/// The conservative part of a model: bonds plus the uniform field.
impl Potential for Model {
    fn energy(&self, x: &[Vec2]) -> f64 {
        let bonds: f64 = self.springs.iter().map(|s| s.energy(x)).sum::<f64>()
            + self.torsions.iter().map(|t| t.energy(x)).sum::<f64>();
        bonds + self.field_energy(x) + self.bumper_energy(x)
    }

    fn add_gradient(&self, x: &[Vec2], grad: &mut [Vec2]) {
        for s in &self.springs {
            s.add_gradient(x, grad);
        }
        for t in &self.torsions {
            t.add_gradient(x, grad);
        }
        let g = self.physics.gravity;
        if g != Vec2::zeros() {
            // Fixed particles are left out of the field energy (they never move), so they
            // are left out of its gradient too.
            for (p, gr) in self.particles.particles.iter().zip(grad.iter_mut()) {
                if !p.fixed {
                    *gr -= g * p.mass;
                }
            }
        }
        for w in self.physics.walls.iter().filter(|w| w.is_bumper()) {
            for ((p, xi), gr) in self.particles.particles.iter().zip(x).zip(grad.iter_mut()) {
                if !p.fixed {
                    *gr += w.bumper_gradient(*xi);
                }
            }
        }
    }
}

impl Model {
    /// Number of particles.
    pub fn particle_count(&self) -> usize {
        self.particles.len()
    }

    /// Potential energy of the uniform field, `-sum m g . x` (free particles only).
    fn field_energy(&self, x: &[Vec2]) -> f64 {
        let g = self.physics.gravity;
        self.particles
            .particles
            .iter()
            .zip(x)
            .filter(|(p, _)| !p.fixed)
            .map(|(p, xi)| -p.mass * g.dot(xi))
            .sum()
    }

    /// Energy of the bumper springs, `sum S s^2` over bumpers and penetrating free particles
    /// (0 without bumpers).
    fn bumper_energy(&self, x: &[Vec2]) -> f64 {
        let walls = self.physics.walls.iter().filter(|w| w.is_bumper());
        walls
            .map(|w| {
                self.particles
                    .particles
                    .iter()
                    .zip(x)
                    .filter(|(p, _)| !p.fixed)
                    .map(|(_, xi)| w.bumper_energy(*xi))
                    .sum::<f64>()
            })
            .sum()
    }

    /// Kinetic energy `sum m v^2 / 2` of the free particles.
    pub fn kinetic_energy(&self, state: &State) -> f64 {
        self.particles
            .particles
            .iter()
            .zip(&state.velocities)
            .filter(|(p, _)| !p.fixed)
            .map(|(p, v)| 0.5 * p.mass * v.norm_squared())
            .sum()
    }

    /// Total mechanical energy: kinetic plus potential.
    pub fn total_energy(&self, state: &State) -> f64 {
        self.kinetic_energy(state) + self.energy(&state.positions)
    }

    /// Returns true if and only if some force depends on velocities: linear or quadratic drag,
    /// the global spring dashpot, or a per-spring dashpot override that is not zero.
    ///
    /// Unlike [`Physics::has_dissipation`](crate::Physics::has_dissipation), this sees the
    /// per-spring `damping` overrides.
    pub fn has_velocity_dependent_forces(&self) -> bool {
        let ph = &self.physics;
        ph.drag != 0.0
            || ph.quadratic_drag != 0.0
            || self.has_body_drag()
            || ph.walls.iter().any(|w| w.is_bumper() && w.damping != 0.0)
            || self
                .springs
                .iter()
                .any(|s| s.damping.unwrap_or(ph.spring_damping) != 0.0)
    }

    /// Returns true if and only if some body drag (not scaled by mass) is on: the shared
    /// `physics.body_drag` or `body_quadratic_drag`, or a particle's own value, is not zero.
    pub fn has_body_drag(&self) -> bool {
        let ph = &self.physics;
        self.particles.particles.iter().any(|p| {
            p.body_drag.unwrap_or(ph.body_drag) != 0.0
                || p.body_quadratic_drag.unwrap_or(ph.body_quadratic_drag) != 0.0
        })
    }

    /// Adds the velocity-dependent forces (drag per mass and per body, quadratic drag,
    /// dashpots) into `force`.
    pub fn add_dissipative_forces(&self, state: &State, force: &mut [Vec2]) {
        let ph = &self.physics;
        if ph.drag != 0.0 || ph.quadratic_drag != 0.0 {
            for ((p, v), f) in self
                .particles
                .particles
                .iter()
                .zip(&state.velocities)
                .zip(force.iter_mut())
            {
                *f -= v * (p.mass * (ph.drag + ph.quadratic_drag * v.norm()));
            }
        }
        if self.has_body_drag() {
            for ((p, v), f) in self
                .particles
                .particles
                .iter()
                .zip(&state.velocities)
                .zip(force.iter_mut())
            {
                let b = p.body_drag.unwrap_or(ph.body_drag);
                let c = p.body_quadratic_drag.unwrap_or(ph.body_quadratic_drag);
                *f += body_drag_force(*v, b, c);
            }
        }
        for w in ph.walls.iter().filter(|w| w.is_bumper() && w.damping != 0.0) {
            for ((x, v), f) in state
                .positions
                .iter()
                .zip(&state.velocities)
                .zip(force.iter_mut())
            {
                *f += w.bumper_damping_force(*x, *v);
            }
        }
        for s in &self.springs {
            let c = s.damping.unwrap_or(ph.spring_damping);
            if c == 0.0 {
                continue;
            }
            let [i, j] = [s.ends[0].index(), s.ends[1].index()];
            let f = dashpot_force_on_i(
                SpringGeometry::new(state.positions[i], state.positions[j]),
                state.velocities[j] - state.velocities[i],
                c,
            );
            force[i] += f;
            force[j] -= f;
        }
    }

    /// Total force on every particle (mass·px/s²), written into `force`; fixed particles get zero.
    pub fn forces(&self, state: &State, force: &mut [Vec2]) {
        force.iter_mut().for_each(|f| *f = Vec2::zeros());
        self.add_gradient(&state.positions, force);
        force.iter_mut().for_each(|f| *f = -*f);
        self.add_dissipative_forces(state, force);
        for (p, f) in self.particles.particles.iter().zip(force.iter_mut()) {
            if p.fixed {
                *f = Vec2::zeros();
            }
        }
    }

    /// Acceleration of every particle (px/s²), written into `acc`; fixed particles get zero.
    pub fn accelerations(&self, state: &State, acc: &mut [Vec2]) {
        self.forces(state, acc);
        for (p, a) in self.particles.particles.iter().zip(acc.iter_mut()) {
            if !p.fixed {
                *a /= p.mass;
            }
        }
    }

    /// Applies every wall's reflection law ([`crate::Wall::reflect`], constant velocity) to
    /// every free particle. Returns the number of bounces (bumpers act as forces, never here).
    pub fn apply_walls(&self, state: &mut State) -> usize {
        self.apply_walls_with(state, |_| Vec2::zeros(), f64::INFINITY)
    }

    /// Applies every wall's event law at the end of a substep of `dt` s, with `acc[p]` the
    /// acceleration of particle `p` over the substep ([`crate::Wall::reflect_in_substep`]).
    /// Returns the number of bounces.
    pub fn apply_walls_in_substep(&self, state: &mut State, acc: &[Vec2], dt: f64) -> usize {
        self.apply_walls_with(state, |k| acc.get(k).copied().unwrap_or_else(Vec2::zeros), dt)
    }

    fn apply_walls_with(&self, state: &mut State, acc: impl Fn(usize) -> Vec2, dt: f64) -> usize {
        let walls = &self.physics.walls;
        if walls.is_empty() {
            return 0;
        }
        let mut bounces = 0;
        for (k, p) in self.particles.particles.iter().enumerate() {
            if p.fixed || k >= state.len() {
                continue;
            }
            let a = acc(k);
            let (x, v) = (&mut state.positions[k], &mut state.velocities[k]);
            // In a corner, a bounce off one wall can push the centre across another: repeat
            // (a few passes settle any convex corner).
            for _ in 0..=walls.len().min(8) {
                let mut bounced = false;
                for w in walls {
                    if w.reflect_in_substep(x, v, a, dt) {
                        bounced = true;
                        bounces += 1;
                    }
                }
                if !bounced {
                    break;
                }
            }
        }
        bounces
    }

    /// Moves `state`'s positions onto the ropes and rails, velocities untouched
    /// ([`crate::constraint::settle`]); returns true if and only if it moved one.
    pub fn settle_constraints(&self, state: &mut State) -> bool {
        let ph = &self.physics;
        crate::constraint::settle(&self.particles, &ph.ropes, &ph.rails, state)
    }

    /// Projects `state`, the end of a substep of `dt` s that started at positions `x_old`
    /// (px), onto the ropes and rails ([`crate::constraint`]'s RATTLE-like projection), with
    /// the rails' friction; `buffer` is reused scratch.
    pub fn apply_constraints(&self, x_old: &[Vec2], state: &mut State, dt: f64, buffer: &mut Vec<[f64; 2]>) {
        let ph = &self.physics;
        crate::constraint::project(&self.particles, &ph.ropes, &ph.rails, x_old, state, dt, buffer);
    }

    /// Adds a particle (convenience for building models in code) and returns its id.
    pub fn add_particle(&mut self, mass: f64, fixed: bool) -> crate::ParticleId {
        self.particles.insert(Particle::new(mass, fixed))
    }
}

/// Drag force on a body moving at `v` (px/s) through a medium, mass·px/s²: `-(b + c |v|) v`
/// with linear coefficient `b` (mass/s) and quadratic coefficient `c` (mass/px), not scaled
/// by the body's mass. A body of mass `m` alone then slows as `v0 exp(-b t / m)` (`c = 0`),
/// and falls at most at `sqrt(m g / c)` under a field `g` (`b = 0`).
#[inline]
pub fn body_drag_force(v: Vec2, b: f64, c: f64) -> Vec2 {
    -v * (b + c * v.norm())
}

/// Dashpot force on particle `i` of a spring: `c ((v_j - v_i) . u_ij) u_ij`, for relative
/// velocity `v_j - v_i` (px/s) and coefficient `c` (mass/s).
#[inline]
pub fn dashpot_force_on_i(geometry: SpringGeometry, relative_velocity: Vec2, c: f64) -> Vec2 {
    geometry.direction * (c * relative_velocity.dot(&geometry.direction))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fixed_particles_take_no_force_and_no_field_gradient() {
        let mut m = Model::default();
        let a = m.add_particle(2.0, true);
        let b = m.add_particle(3.0, false);
        m.springs.push(Spring::new(a, b, 1.0, 10.0));
        m.physics.gravity = Vec2::new(0.0, 9.0);
        let state = State::at_rest(vec![Vec2::new(0.0, 5.0), Vec2::new(3.0, 5.0)]);
        let mut f = vec![Vec2::zeros(); 2];
        m.forces(&state, &mut f);
        assert!(f[0].norm() == 0.0);
        // Spring pulls b back by 2 S (d - L) = 40, gravity adds m g = 27 down.
        assert!((f[1] - Vec2::new(-40.0, 27.0)).norm() < 1e-12);
        // The field's energy and gradient both leave the fixed particle out.
        let field = Model {
            springs: vec![],
            ..m.clone()
        };
        let mut g = vec![Vec2::zeros(); 2];
        field.add_gradient(&state.positions, &mut g);
        assert!(g[0].norm() == 0.0);
        assert!((g[1] - Vec2::new(0.0, -27.0)).norm() < 1e-12);
        assert!((field.energy(&state.positions) + 3.0 * 9.0 * 5.0).abs() < 1e-12);
    }

    #[test]
    fn per_spring_damping_counts_as_velocity_dependent() {
        let mut m = Model::default();
        let a = m.add_particle(1.0, false);
        let b = m.add_particle(1.0, false);
        m.springs.push(Spring::new(a, b, 1.0, 1.0));
        assert!(!m.has_velocity_dependent_forces());
        m.springs[0].damping = Some(0.5);
        assert!(m.has_velocity_dependent_forces());
        // An override of zero beats a global dashpot.
        m.physics.spring_damping = 2.0;
        m.springs[0].damping = Some(0.0);
        assert!(!m.has_velocity_dependent_forces());
    }

    #[test]
    fn dashpot_force_law() {
        // F_i = c ((v_j - v_i) . u_ij) u_ij: only the stretching rate counts.
        let geo = SpringGeometry::new(Vec2::zeros(), Vec2::new(0.0, 2.0));
        let f = dashpot_force_on_i(geo, Vec2::new(5.0, -3.0), 4.0);
        assert!((f - Vec2::new(0.0, -12.0)).norm() < 1e-12);
    }
}

#[cfg(test)]
mod proptests {
    use super::*;
    use crate::proptest_utils::*;
    use proptest::prelude::*;

    proptest! {
        #[test]
        fn gradient_matches_finite_differences((model, x) in model_and_positions()) {
            let h = 1e-5 * min_separation(&x);
            let floor = model_floor(&model, &x, h);
            check_gradient(&model, &x, h, &floor)?;
        }

        #[test]
        fn forces_are_minus_the_gradient_except_on_fixed_particles((model, x) in model_and_positions()) {
            let state = State::at_rest(x.clone());
            let mut f = vec![Vec2::zeros(); x.len()];
            model.forces(&state, &mut f);
            let g = analytic_gradient(&model, &x);
            for (p, particle) in model.particles.particles.iter().enumerate() {
                if particle.fixed {
                    prop_assert!(f[p].norm() == 0.0);
                } else {
                    prop_assert!((f[p] + g[p]).norm() <= 1e-12 * g[p].norm());
                }
            }
        }
    }
}
