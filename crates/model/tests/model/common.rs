//! Models shared by the tests.

use physfit_model::{IntegrationParameters, IntegratorKind, Model, ParticleId, Spring, State, Torsion, Vec2};

/// A paper-like 8-particle object: a ring of 8 unit masses of radius 60 px around
/// (256, 256) with 8 springs round the ring (rest lengths 10 % longer than drawn), 10
/// torsions (one at each particle between its ring neighbours, two across) whose rest
/// cosines differ from the drawn ones, and initial velocities with zero net momentum.
/// No physics beyond the paper.
pub fn paper8() -> (Model, State) {
    let n = 8;
    let mut model = Model::default();
    let mut x = Vec::new();
    let mut v = Vec::new();
    for k in 0..n {
        model.add_particle(1.0 + 0.1 * k as f64, false);
        let a = std::f64::consts::TAU * k as f64 / n as f64;
        x.push(Vec2::new(256.0 + 60.0 * a.cos(), 256.0 + 60.0 * a.sin()));
        // A spin plus a wobble.
        v.push(Vec2::new(
            -30.0 * a.sin() + 15.0 * (3.0 * a).cos(),
            30.0 * a.cos() + 10.0 * (2.0 * a).sin(),
        ));
    }
    let id = |k: usize| ParticleId((k % n) as u32);
    for k in 0..n {
        let d = (x[(k + 1) % n] - x[k]).norm();
        model
            .springs
            .push(Spring::new(id(k), id(k + 1), 1.1 * d, 40.0 + 5.0 * k as f64));
    }
    let cos_at = |i: usize, j: usize, k: usize| {
        let a = (x[j] - x[i]).normalize();
        let b = (x[k] - x[i]).normalize();
        a.dot(&b)
    };
    for k in 0..n {
        let (j, l) = ((k + n - 1) % n, (k + 1) % n);
        let m = (cos_at(k, j, l) + 0.05).clamp(-1.0, 1.0);
        model.torsions.push(Torsion::new(id(k), id(j), id(l), m, 2.0e4));
    }
    for (i, j, l) in [(0, 1, 4), (4, 5, 0)] {
        let m = (cos_at(i, j, l) - 0.05).clamp(-1.0, 1.0);
        model.torsions.push(Torsion::new(id(i), id(j), id(l), m, 1.0e4));
    }
    // Remove the net momentum so that a free object stays in view.
    let total_mass: f64 = model.particles.particles.iter().map(|p| p.mass).sum();
    let p: Vec2 = model
        .particles
        .particles
        .iter()
        .zip(&v)
        .map(|(q, v)| v * q.mass)
        .sum();
    for vk in &mut v {
        *vk -= p / total_mass;
    }
    (model, State::new(x, v))
}

/// Total momentum `sum m v` of the free particles.
pub fn momentum(model: &Model, state: &State) -> Vec2 {
    model
        .particles
        .particles
        .iter()
        .zip(&state.velocities)
        .filter(|(p, _)| !p.fixed)
        .map(|(p, v)| v * p.mass)
        .sum()
}

/// One free particle of mass `mass` with no bonds.
pub fn single(mass: f64) -> Model {
    let mut m = Model::default();
    m.add_particle(mass, false);
    m
}

/// The largest distance between corresponding positions of two states, px.
pub fn max_distance(a: &[Vec2], b: &[Vec2]) -> f64 {
    a.iter().zip(b).map(|(p, q)| (p - q).norm()).fold(0.0, f64::max)
}

/// Frame rate of the closed-form tests, frames/s.
pub const FPS: f64 = 100.0;

/// Integration at [`FPS`] with 20 substeps a frame (0.5 ms) and the scheme `kind`.
pub fn params(kind: IntegratorKind) -> IntegrationParameters {
    IntegrationParameters {
        frame_dt: 1.0 / FPS,
        substeps: 20,
        integrator: kind,
    }
}
