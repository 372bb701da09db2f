//! The truth's own simulation judged: stable integration, discs apart, the frame's margin
//! kept, linking unambiguous; and what kind of recording it is ([`Regime`]).

use std::path::Path;

use physfit_model::scene::{ParticleSpec, SpringSpec, TorsionSpec};
use physfit_model::{ParticleId, Recording, Scene, Vec2};
use serde::Serialize;

/// Most integration substeps per frame a drawn recording may need.
pub const MAX_SUBSTEPS: u32 = 60;
/// Largest `omega dt` per substep kept for the stiffest mode (rad).
const OMEGA_DT: f64 = 0.25;

/// What kind of recording was drawn (its regime), for the failure lines and the JSON.
#[derive(Clone, Debug, Default, Serialize)]
pub struct Regime {
    /// Particles of the structure.
    pub particles: usize,
    /// `free`, `chain`, `strip` or `graph`.
    pub topology: &'static str,
    /// Springs of the structure.
    pub springs: usize,
    /// Torsions of the structure.
    pub torsions: usize,
    /// Frame rate, frames/s.
    pub fps: f64,
    /// Frames.
    pub frames: usize,
    /// Integration substeps per frame.
    pub substeps: u32,
    /// Disc radius, px.
    pub radius: f64,
    /// Pixel noise, grey levels.
    pub noise: f64,
    /// Frame size, px.
    pub size: [u32; 2],
    /// Largest displacement of one particle between two frames, px.
    pub max_step: f64,
    /// Bounces off the wall, all particles together.
    pub bounces: usize,
    /// Fewest frames between two bounces of one particle (`None`: no particle bounced twice).
    pub frames_between_bounces: Option<usize>,
    /// Draws rejected (not physically sensible) before this one.
    pub rejected_draws: usize,
}

impl Regime {
    /// In a few words: `3 particles (chain, 2 springs, 1 torsion), 120 frames at 60 fps, ...`.
    pub fn describe(&self) -> String {
        let mut s = format!(
            "{} particle{} ({}, {} springs, {} torsions), {} frames at {} fps, r {:.1} px, noise {:.1}, {}x{} px, up to {:.1} px/frame",
            self.particles,
            if self.particles == 1 { "" } else { "s" },
            self.topology,
            self.springs,
            self.torsions,
            self.frames,
            self.fps,
            self.radius,
            self.noise,
            self.size[0],
            self.size[1],
            self.max_step
        );
        if self.bounces > 0 {
            s.push_str(&format!(", {} bounces", self.bounces));
            if let Some(f) = self.frames_between_bounces {
                s.push_str(&format!(" (at least {f} frames apart)"));
            }
        }
        s
    }
}

/// Substeps per frame that keep `omega dt` of the stiffest mode under [`OMEGA_DT`] (a
/// Gershgorin bound on the mass-weighted stiffness; torsions as springs of `T / d^2`), at
/// least 10; `None` beyond [`MAX_SUBSTEPS`].
pub fn substeps_needed(
    particles: &[ParticleSpec],
    springs: &[SpringSpec],
    torsions: &[TorsionSpec],
    fps: f64,
) -> Option<u32> {
    let inverse_mass = |p: ParticleId| {
        let q = &particles[p.index()];
        if q.fixed {
            0.0
        } else {
            1.0 / q.mass
        }
    };
    let mut row = vec![0.0; particles.len()];
    for s in springs {
        let k = 2.0 * s.stiffness.unwrap_or(0.0) * (inverse_mass(s.ends[0]) + inverse_mass(s.ends[1]));
        row[s.ends[0].index()] += k;
        row[s.ends[1].index()] += k;
    }
    for t in torsions {
        let ids = [t.center, t.ends[0], t.ends[1]];
        let d = t
            .ends
            .iter()
            .map(|e| (particles[e.index()].position - particles[t.center.index()].position).norm())
            .fold(f64::INFINITY, f64::min)
            .max(1.0);
        let k =
            8.0 * t.stiffness.unwrap_or(0.0) / (d * d) * ids.iter().map(|&p| inverse_mass(p)).sum::<f64>();
        for p in ids {
            row[p.index()] += k;
        }
    }
    let omega = row.iter().fold(0.0f64, |a, &b| a.max(b)).sqrt();
    let substeps = (omega / (OMEGA_DT * fps)).ceil().max(10.0);
    (substeps.is_finite() && substeps <= MAX_SUBSTEPS as f64).then_some(substeps as u32)
}

/// The scene's recording (simulated as `physfit render` simulates it); `None` when it cannot
/// be simulated or leaves finite numbers.
pub fn simulate(scene: &Scene) -> Option<Recording> {
    let rec = crate::cmd::simulate_scene(scene, Path::new(&scene.name)).ok()?;
    rec.positions
        .iter()
        .all(|p| p.x.is_finite() && p.y.is_finite())
        .then_some(rec)
}

/// The corners of the box holding the first `n` (moving) particles over the recording, px.
pub fn extent(rec: &Recording, n: usize) -> Option<(Vec2, Vec2)> {
    let mut points = (0..rec.frame_count()).flat_map(|k| rec.frame(k)[..n].iter().copied());
    let first = points.next()?;
    Some(points.fold((first, first), |(lo, hi), p| (lo.inf(&p), hi.sup(&p))))
}

/// Judges the rendered motion (the first `n` particles move; the rest are fixed points):
/// `None` when two discs come within `2 r + 2` px, a particle leaves the frame's margin, or
/// (with two particles or more) one moves more than half their smallest distance in a frame.
pub fn judge_motion(scene: &Scene, rec: &Recording, n: usize) -> Option<Regime> {
    let r = scene.render.radius;
    let (w, h) = (scene.render.width as f64, scene.render.height as f64);
    let all = scene.particles.len();
    let mut closest = f64::INFINITY;
    let mut max_step: f64 = 0.0;
    for k in 0..rec.frame_count() {
        let x = rec.frame(k);
        for a in 0..n {
            let p = x[a];
            if p.x < r + 2.0 || p.y < r + 2.0 || p.x > w - r - 2.0 || p.y > h - r - 2.0 {
                return None;
            }
            for q in &x[a + 1..all] {
                closest = closest.min((q - p).norm());
            }
            if k > 0 {
                max_step = max_step.max((p - rec.frame(k - 1)[a]).norm());
            }
        }
    }
    if closest < 2.0 * r + 2.0 || (n >= 2 && max_step > 0.5 * closest) {
        return None;
    }
    let (bounces, frames_between_bounces) = bounces(scene, rec, n);
    Some(Regime {
        particles: n,
        fps: scene.recording.fps,
        frames: scene.recording.frames,
        substeps: scene.recording.substeps,
        radius: r,
        noise: scene.render.noise,
        size: [scene.render.width, scene.render.height],
        max_step,
        bounces,
        frames_between_bounces,
        ..Regime::default()
    })
}

/// Bounces off the scene's wall (a particle's normal velocity turning from towards the wall
/// to away within a frame's travel of it) and the fewest frames between two of one particle.
fn bounces(scene: &Scene, rec: &Recording, n: usize) -> (usize, Option<usize>) {
    let Some(wall) = scene.physics.walls.first() else {
        return (0, None);
    };
    let dt = 1.0 / scene.recording.fps;
    let (mut count, mut fewest) = (0, None::<usize>);
    for i in 0..n {
        let mut last = None;
        for k in 1..rec.frame_count() {
            let at = |k: usize| rec.particle_count * k + i;
            let (v0, v1) = (rec.velocities[at(k - 1)], rec.velocities[at(k)]);
            let (n0, n1) = (wall.normal.dot(&v0), wall.normal.dot(&v1));
            let reach = 1.5 * dt * n0.abs().max(n1.abs()) + 1.0;
            let near = wall
                .signed_distance(rec.positions[at(k - 1)])
                .min(wall.signed_distance(rec.positions[at(k)]));
            if n0 < 0.0 && n1 > 0.0 && near <= reach {
                count += 1;
                if let Some(l) = last {
                    fewest = Some(fewest.map_or(k - l, |f: usize| f.min(k - l)));
                }
                last = Some(k);
            }
        }
    }
    (count, fewest)
}
