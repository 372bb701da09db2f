//! Particles: point masses addressed by [`ParticleId`].

/// Index of a particle in a [`ParticleSet`] (and in every per-particle slice of a model).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct ParticleId(pub u32);

impl ParticleId {
    /// The index into per-particle slices.
    #[inline]
    pub fn index(self) -> usize {
        self.0 as usize
    }
}

/// The constant properties of one point mass.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Particle {
    /// Mass (arbitrary consistent unit; forces are mass·px/s²).
    pub mass: f64,
    /// True if and only if the particle is pinned: it never moves and takes no force.
    pub fixed: bool,
    /// This body's own linear drag coefficient `b`, mass/s: `F = -b v`, not scaled by the
    /// mass. `None` takes [`crate::Physics::body_drag`].
    pub body_drag: Option<f64>,
    /// This body's own quadratic drag coefficient `c`, mass/px: `F = -c |v| v`, not scaled by
    /// the mass. `None` takes [`crate::Physics::body_quadratic_drag`].
    pub body_quadratic_drag: Option<f64>,
}

impl Particle {
    /// A particle of mass `mass` (pinned if `fixed`) with no drag of its own.
    pub fn new(mass: f64, fixed: bool) -> Particle {
        Particle {
            mass,
            fixed,
            ..Particle::default()
        }
    }
}

/// All particles of a model, in index order.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ParticleSet {
    /// The particles; `particles[id.index()]` is particle `id`.
    pub particles: Vec<Particle>,
}

impl ParticleSet {
    /// Number of particles.
    pub fn len(&self) -> usize {
        self.particles.len()
    }

    /// Returns true if and only if the set holds no particle.
    pub fn is_empty(&self) -> bool {
        self.particles.is_empty()
    }

    /// Adds a particle and returns its id.
    pub fn insert(&mut self, particle: Particle) -> ParticleId {
        self.particles.push(particle);
        ParticleId((self.particles.len() - 1) as u32)
    }

    /// The particle with this id.
    ///
    /// # Panics
    /// If `id` is not in the set.
    pub fn get(&self, id: ParticleId) -> &Particle {
        &self.particles[id.index()]
    }
}
