//! The object before any concealed effect: timing, look, layout, masses, bonds and start
//! velocities.

use std::f64::consts::TAU;

use physfit_model::scene::{ParticleSpec, SpringSpec, TorsionSpec};
use physfit_model::{ParticleId, Vec2};
use rand::rngs::StdRng;
use rand::seq::SliceRandom;
use rand::Rng;

use super::{log_uniform, turned, unit, Kind};

/// A drawn object with its recording's timing and look, before any concealed effect.
pub struct Object {
    /// Frame rate, frames/s.
    pub fps: f64,
    /// Frames.
    pub frames: usize,
    /// The recording's duration `(frames - 1) / fps`, s.
    pub duration: f64,
    /// Disc radius, px.
    pub radius: f64,
    /// Pixel noise, grey levels.
    pub noise: f64,
    /// `free`, `chain`, `strip` or `graph`.
    pub topology: &'static str,
    /// The structure's springs as particle index pairs.
    pub edges: Vec<[usize; 2]>,
    /// Particles (the moving ones first; a tether's fixed point joins after them).
    pub particles: Vec<ParticleSpec>,
    /// Springs (the structure's first).
    pub springs: Vec<SpringSpec>,
    /// Torsions.
    pub torsions: Vec<TorsionSpec>,
    /// The moving particles' count.
    pub moving: usize,
    /// The object's typical spring stiffness, mass/s² (defined without springs too).
    pub stiffness: f64,
    /// Mean particle mass.
    pub mass_mean: f64,
    /// Largest distance of a particle from the object's centre, px (at least half the
    /// spacing).
    pub size: f64,
    /// Start speed of the object's centre, px/s.
    pub speed: f64,
    /// The shortest oscillation period drawn (8 frames), s.
    pub shortest_period: f64,
}

impl Object {
    /// Start distance between particles `a` and `b`, px.
    pub fn distance(&self, a: usize, b: usize) -> f64 {
        (self.particles[a].position - self.particles[b].position).norm()
    }
}

/// Draws the object, its timing and look (see the module doc of `draw`); `None` when its
/// layout cannot be drawn.
pub fn draw_object(rng: &mut StdRng, kinds: &[Kind], small: bool) -> Option<Object> {
    let has = |k: Kind| kinds.contains(&k);
    let fps = log_uniform(rng, 24.0, 240.0).round();
    let frames = log_uniform(rng, 10.0, if small { 150.0 } else { 600.0 }).round() as usize;
    let duration = (frames - 1) as f64 / fps;
    let radius: f64 = rng.gen_range(3.0..20.0);
    let noise: f64 = rng.gen_range(0.0..10.0);
    let needs_two = has(Kind::SpringDamping) || has(Kind::MissingSpring);
    let n = rng.gen_range(if needs_two { 2 } else { 1 }..=if small { 4 } else { 10 });
    // Neighbours closer than about 3 radii reach into the ring where the tracker checks
    // that a track follows one particle, and it refuses them.
    let spacing = (3.2 * radius).max(2.0 * radius + 10.0).max(24.0) * rng.gen_range(1.2..2.5);
    let shape = draw_shape(rng, n, spacing, has(Kind::SpringDamping))?;
    let masses: Vec<f64> = (0..n).map(|_| rng.gen_range(0.5..2.0)).collect();
    let mass_mean = masses.iter().sum::<f64>() / n as f64;
    let distance = |a: usize, b: usize| (shape.positions[a] - shape.positions[b]).norm();

    // Springs: one oscillation period for the object, each spring within a factor of 1.6.
    let shortest = 8.0 / fps;
    let period = log_uniform(rng, shortest, (40.0 * shortest).min(duration).max(1.5 * shortest));
    let stiffness = mass_mean * (TAU / period).powi(2) / 4.0;
    let springs: Vec<SpringSpec> = shape
        .edges
        .iter()
        .map(|&[a, b]| SpringSpec {
            ends: [ParticleId(a as u32), ParticleId(b as u32)],
            rest_length: Some(distance(a, b) * (1.0 + rng.gen_range(-0.08..0.08))),
            stiffness: Some(stiffness * rng.gen_range(0.6..1.6)),
            damping: None,
        })
        .collect();
    let torsions = if rng.gen_bool(0.5) {
        draw_torsions(rng, &shape, stiffness * spacing * spacing)
    } else {
        Vec::new()
    };

    // Start velocities: a travel over the recording, a spin, and a little per particle.
    let speed = log_uniform(rng, 10.0, 300.0) / duration;
    let heading = unit(rng.gen_range(0.0..TAU));
    let size = shape
        .positions
        .iter()
        .map(|p| p.norm())
        .fold(spacing / 2.0, f64::max);
    let spin = rng.gen_range(-1.0..1.0) * speed / size;
    let particles: Vec<ParticleSpec> = (0..n)
        .map(|i| {
            let p = shape.positions[i];
            let jitter = Vec2::new(rng.gen_range(-0.2..0.2), rng.gen_range(-0.2..0.2)) * speed;
            ParticleSpec {
                id: format!("p{i}"),
                mass: masses[i],
                position: p,
                velocity: speed * heading + spin * Vec2::new(-p.y, p.x) + jitter,
                fixed: false,
                ..Default::default()
            }
        })
        .collect();
    Some(Object {
        fps,
        frames,
        duration,
        radius,
        noise,
        topology: shape.topology,
        edges: shape.edges,
        particles,
        springs,
        torsions,
        moving: n,
        stiffness,
        mass_mean,
        size,
        speed,
        shortest_period: shortest,
    })
}

/// Torsions at seven joints in ten (of those with two neighbours or more), between two of
/// the joint's neighbours not nearly in one direction; stiffness 0.05-0.3 times `scale`.
fn draw_torsions(rng: &mut StdRng, shape: &Shape, scale: f64) -> Vec<TorsionSpec> {
    let mut torsions = Vec::new();
    for i in 0..shape.positions.len() {
        let neighbours: Vec<usize> = shape
            .edges
            .iter()
            .filter_map(|e| match *e {
                [a, b] if a == i => Some(b),
                [a, b] if b == i => Some(a),
                _ => None,
            })
            .collect();
        if neighbours.len() < 2 || !rng.gen_bool(0.7) {
            continue;
        }
        let pick: Vec<usize> = neighbours.choose_multiple(rng, 2).copied().collect();
        let (j, k) = (pick[0], pick[1]);
        let u = |e: usize| (shape.positions[e] - shape.positions[i]).normalize();
        let cos = u(j).dot(&u(k));
        if cos > 0.9 {
            continue;
        }
        torsions.push(TorsionSpec {
            center: ParticleId(i as u32),
            ends: [ParticleId(j as u32), ParticleId(k as u32)],
            rest_cos: Some((cos + rng.gen_range(-0.05..0.05)).clamp(-1.0, 0.95)),
            stiffness: Some(scale * rng.gen_range(0.05..0.3)),
        });
    }
    torsions
}

/// An object's layout: start positions (centred on 0) and the structure's springs.
struct Shape {
    topology: &'static str,
    positions: Vec<Vec2>,
    edges: Vec<[usize; 2]>,
}

/// Returns true if and only if `p` is at least `gap` px from every point of `points`.
fn clear_of(points: &[Vec2], p: Vec2, gap: f64) -> bool {
    points.iter().all(|q| (q - p).norm() >= gap)
}

/// Draws `n` particles `spacing` px apart as one of the topologies allowed.
fn draw_shape(rng: &mut StdRng, n: usize, spacing: f64, needs_springs: bool) -> Option<Shape> {
    let mut topologies = Vec::new();
    if n == 1 || (n <= 3 && !needs_springs) {
        topologies.push("free");
    }
    if n >= 2 {
        topologies.push("chain");
    }
    if n >= 3 {
        topologies.extend(["strip", "graph"]);
    }
    let topology = *topologies.choose(rng)?;
    let heading = rng.gen_range(0.0..TAU);
    let mut positions: Vec<Vec2> = Vec::with_capacity(n);
    let mut edges = Vec::new();
    match topology {
        "free" => {
            let side = spacing * (1.0 + 2.0 * n as f64);
            for _ in 0..n {
                let p = (0..50)
                    .map(|_| Vec2::new(rng.gen_range(0.0..side), rng.gen_range(0.0..side)))
                    .find(|&p| clear_of(&positions, p, spacing))?;
                positions.push(p);
            }
        }
        "chain" => {
            let mut angle = heading;
            positions.push(Vec2::zeros());
            for i in 1..n {
                angle += rng.gen_range(-0.8..0.8);
                let step = spacing * rng.gen_range(0.85..1.15);
                positions.push(positions[i - 1] + step * unit(angle));
                edges.push([i - 1, i]);
            }
        }
        "strip" => {
            for i in 0..n {
                let base = Vec2::new(
                    i as f64 * spacing / 2.0,
                    if i % 2 == 1 { spacing * 0.866 } else { 0.0 },
                );
                let jitter = Vec2::new(rng.gen_range(-0.08..0.08), rng.gen_range(-0.08..0.08)) * spacing;
                positions.push(turned(base, heading) + jitter);
                edges.push([i.saturating_sub(1), i]);
                if i >= 2 {
                    edges.push([i - 2, i]);
                }
            }
            edges.retain(|e| e[0] != e[1]);
        }
        _ => {
            positions.push(Vec2::zeros());
            for i in 1..n {
                let (parent, p) = (0..50)
                    .map(|_| {
                        let parent = rng.gen_range(0..i);
                        let step = spacing * rng.gen_range(0.85..1.15);
                        (parent, positions[parent] + step * unit(rng.gen_range(0.0..TAU)))
                    })
                    .find(|&(_, p)| clear_of(&positions, p, 0.8 * spacing))?;
                positions.push(p);
                edges.push([parent, i]);
            }
            for a in 0..n {
                for b in a + 1..n {
                    let joined = edges.contains(&[a, b]);
                    if !joined && (positions[a] - positions[b]).norm() < 1.6 * spacing && rng.gen_bool(0.4) {
                        edges.push([a, b]);
                    }
                }
            }
        }
    }
    for a in 0..n {
        if !clear_of(&positions[a + 1..], positions[a], 0.8 * spacing) {
            return None;
        }
    }
    let centre = positions.iter().sum::<Vec2>() / n as f64;
    for p in &mut positions {
        *p -= centre;
    }
    Some(Shape {
        topology,
        positions,
        edges,
    })
}
