//! The concealed effects put into a drawn object, magnitudes log-uniform over two decades
//! relative to the recording (see the module doc of `draw`).

use std::f64::consts::TAU;

use physfit_model::scene::{ParticleSpec, SpringSpec};
use physfit_model::{ParticleId, Physics, Scene, Vec2, Wall};
use rand::rngs::StdRng;
use rand::seq::SliceRandom;
use rand::Rng;

use super::motion::simulate;
use super::object::Object;
use super::{log_uniform, turned, unit, Kind, PIVOT};

/// The smooth effects put in, and who carries the placed ones.
pub struct Hidden {
    /// The truth's `[physics]` (walls come later, placed on the motion).
    pub physics: Physics,
    /// The missing spring's two particles.
    pub missing: Option<[String; 2]>,
    /// The tethered particle.
    pub tethered: Option<String>,
}

/// Puts every class of `kinds` but the wall into `object` (a missing spring and a tether's
/// spring and fixed point are appended to its bonds and particles); `None` when the object
/// has no pair left for a missing spring.
pub fn conceal(rng: &mut StdRng, kinds: &[Kind], object: &mut Object) -> Option<Hidden> {
    let has = |k: Kind| kinds.contains(&k);
    let (n, duration) = (object.moving, object.duration);
    let mut physics = Physics::default();
    if has(Kind::Field) {
        let displacement = log_uniform(rng, 3.0, 300.0);
        physics.gravity = 2.0 * displacement / duration.powi(2) * unit(rng.gen_range(0.0..TAU));
    }
    let field = physics.gravity.norm();
    if has(Kind::Drag) {
        physics.drag = log_uniform(rng, 0.02, 2.0) / duration;
    }
    if has(Kind::QuadraticDrag) {
        let typical = object.speed.hypot(field * duration / 2.0).max(1.0);
        physics.quadratic_drag = log_uniform(rng, 0.02, 2.0) / (duration * typical);
    }
    if has(Kind::SpringDamping) {
        let ratio = log_uniform(rng, 0.005, 0.5);
        physics.spring_damping = 2.0 * ratio * (object.stiffness * object.mass_mean).sqrt();
    }
    let mut missing = None;
    if has(Kind::MissingSpring) {
        let free_pairs: Vec<[usize; 2]> = (0..n)
            .flat_map(|a| (a + 1..n).map(move |b| [a, b]))
            .filter(|pair| !object.edges.contains(pair))
            .collect();
        let [a, b] = *free_pairs.choose(rng)?;
        missing = Some([format!("p{a}"), format!("p{b}")]);
        let spring = SpringSpec {
            ends: [ParticleId(a as u32), ParticleId(b as u32)],
            rest_length: Some(object.distance(a, b) * (1.0 + rng.gen_range(-0.1..0.1))),
            stiffness: Some(object.stiffness * log_uniform(rng, 0.01, 1.0)),
            damping: None,
        };
        object.springs.push(spring);
    }
    let mut tethered = None;
    if has(Kind::Tether) {
        let p = rng.gen_range(0..n);
        let carried = if object.edges.is_empty() {
            object.particles[p].mass
        } else {
            object.particles[..n].iter().map(|q| q.mass).sum()
        };
        let length = (2.0 * object.size).max(4.0 * object.radius + 20.0) * rng.gen_range(1.5..5.0);
        let (direction, rest, stiffness) = if field > 0.0 {
            // A pendulum: hanging against the field, stretched by the object's weight.
            let up = -physics.gravity / field;
            let stretch = log_uniform(rng, 0.05, 5.0);
            (
                turned(up, rng.gen_range(-0.6..0.6)),
                length - stretch,
                carried * field / (2.0 * stretch),
            )
        } else {
            let shortest = object.shortest_period;
            let radial = log_uniform(rng, shortest, duration.max(2.0 * shortest));
            (
                unit(rng.gen_range(0.0..TAU)),
                length * (1.0 + rng.gen_range(-0.05..0.05)),
                carried * (TAU / radial).powi(2) / 2.0,
            )
        };
        tethered = Some(format!("p{p}"));
        let anchor = object.particles[p].position + length * direction;
        object.particles.push(ParticleSpec {
            id: PIVOT.into(),
            mass: 1.0,
            position: anchor,
            velocity: Vec2::zeros(),
            fixed: true,
            ..Default::default()
        });
        object.springs.push(SpringSpec {
            ends: [ParticleId(p as u32), ParticleId(n as u32)],
            rest_length: Some(rest),
            stiffness: Some(stiffness),
            damping: None,
        });
    }
    Some(Hidden {
        physics,
        missing,
        tethered,
    })
}

/// A wall the motion of `scene` (without it) reaches part of its way towards; `None` when no
/// direction tried sees the object approach by 2 px.
pub fn place_wall(rng: &mut StdRng, scene: &Scene, n: usize) -> Option<Wall> {
    let free = simulate(scene)?;
    let g = scene.physics.gravity;
    let mut normals = Vec::new();
    if g.norm() > 0.0 && rng.gen_bool(0.75) {
        normals.push(turned(-g.normalize(), rng.gen_range(-0.3..0.3)));
    }
    normals.extend((0..8).map(|_| unit(rng.gen_range(0.0..TAU))));
    let fraction = rng.gen_range(0.3..0.9);
    let restitution = rng.gen_range(0.5..0.95);
    for normal in normals {
        let level = |k: usize| {
            free.frame(k)[..n]
                .iter()
                .map(|x| normal.dot(x))
                .fold(f64::INFINITY, f64::min)
        };
        let start = level(0);
        let lowest = (0..free.frame_count()).map(level).fold(f64::INFINITY, f64::min);
        if start - lowest >= 2.0 {
            let offset = start - fraction * (start - lowest);
            return Wall::new(offset * normal, normal, restitution);
        }
    }
    None
}
