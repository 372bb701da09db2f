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
        bonds + self.field_energy(x)
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
            for (p, gr) in self.particles.particles.iter().zip(grad.iter_mut()) {
                *gr -= g * p.mass;
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

    /// Adds the velocity-dependent forces (drag, quadratic drag, dashpots) into `force`.
    pub fn add_dissipative_forces(&self, state: &State, force: &mut [Vec2]) {
        let ph = &self.physics;
        if ph.drag != 0.0 || ph.quadratic_drag != 0.0 {
            for ((p, v), f) in self.particles.particles.iter().zip(&state.velocities).zip(force.iter_mut()) {
                *f -= v * (p.mass * (ph.drag + ph.quadratic_drag * v.norm()));
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

    /// Applies every wall's reflection law to every free particle. Returns the number of bounces.
    pub fn apply_walls(&self, state: &mut State) -> usize {
        let mut bounces = 0;
        if self.physics.walls.is_empty() {
            return 0;
        }
        for (k, p) in self.particles.particles.iter().enumerate() {
            if p.fixed {
                continue;
            }
            for w in &self.physics.walls {
                if w.reflect(&mut state.positions[k], &mut state.velocities[k]) {
                    bounces += 1;
                }
            }
        }
        bounces
    }

    /// Adds a particle (convenience for building models in code) and returns its id.
    pub fn add_particle(&mut self, mass: f64, fixed: bool) -> crate::ParticleId {
        self.particles.insert(Particle { mass, fixed })
    }
}

/// Dashpot force on particle `i` of a spring: `c ((v_j - v_i) . u_ij) u_ij`, for relative
/// velocity `v_j - v_i` (px/s) and coefficient `c` (mass/s).
#[inline]
pub fn dashpot_force_on_i(geometry: SpringGeometry, relative_velocity: Vec2, c: f64) -> Vec2 {
    geometry.direction * (c * relative_velocity.dot(&geometry.direction))
}
