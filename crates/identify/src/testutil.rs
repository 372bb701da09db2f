//! Test objects built in code: paper-like 3-, 5- and 8-particle scenes, lattices, and their
//! exact or noisy tracks.

use physfit_model::scene::{ParticleFile, RecordingFile, SceneFile, SpringFile, TorsionFile};
use physfit_model::{simulate, IntegratorKind, Recording, Scene};
use physfit_tracks::{TrackPoint, TrackTable};
use rand::SeedableRng;
use rand_distr::{Distribution, Normal};

/// A spring `(i, j, L, S)`.
pub type SpringDef = (usize, usize, f64, f64);
/// A torsion `(centre, j, k, M, T)`.
pub type TorsionDef = (usize, usize, usize, f64, f64);

/// Timing of a test recording.
#[derive(Clone, Copy, Debug)]
pub struct Timing {
    /// Frames per second.
    pub fps: f64,
    /// Frames.
    pub frames: usize,
    /// Substeps per frame.
    pub substeps: u32,
    /// Integrator.
    pub integrator: IntegratorKind,
}

impl Default for Timing {
    fn default() -> Self {
        Timing {
            fps: 100.0,
            frames: 100,
            substeps: 20,
            integrator: IntegratorKind::Verlet,
        }
    }
}

/// A scene from particle positions (with masses), springs and torsions.
pub fn scene_from(
    name: &str,
    particles: &[(f64, [f64; 2])],
    springs: &[SpringDef],
    torsions: &[TorsionDef],
    timing: Timing,
) -> Scene {
    let id = |k: usize| format!("p{k}");
    let raw = SceneFile {
        name: Some(name.into()),
        recording: RecordingFile {
            fps: timing.fps,
            frames: timing.frames,
            substeps: Some(timing.substeps),
            integrator: Some(timing.integrator),
            metres_per_px: None,
            ruler: None,
        },
        render: None,
        particles: particles
            .iter()
            .enumerate()
            .map(|(k, &(mass, position))| ParticleFile {
                id: id(k),
                mass,
                position,
                velocity: None,
                fixed: false,
                ..Default::default()
            })
            .collect(),
        springs: springs
            .iter()
            .map(|&(i, j, l, s)| SpringFile {
                between: [id(i), id(j)],
                length: Some(l),
                stiffness: Some(s),
                damping: None,
            })
            .collect(),
        torsions: torsions
            .iter()
            .map(|&(c, j, k, m, t)| TorsionFile {
                at: id(c),
                between: [id(j), id(k)],
                rest_cos: Some(m),
                stiffness: Some(t),
            })
            .collect(),
        physics: None,
    };
    Scene::from_file(raw).expect("valid test scene")
}

/// A 3-particle object: two springs and the torsion between them (6 unknowns).
pub fn paper3(timing: Timing) -> Scene {
    scene_from(
        "paper3",
        &[(1.0, [100.0, 100.0]), (1.5, [141.0, 98.0]), (1.0, [158.0, 136.0])],
        &[(0, 1, 40.0, 50.0), (1, 2, 40.0, 80.0)],
        &[(1, 0, 2, -0.5, 60000.0)],
        timing,
    )
}

/// A 5-particle chain: four springs and three torsions (14 unknowns).
pub fn paper5(timing: Timing) -> Scene {
    scene_from(
        "paper5",
        &[
            (1.0, [100.0, 100.0]),
            (1.2, [137.0, 118.0]),
            (1.0, [178.0, 105.0]),
            (0.8, [212.0, 126.0]),
            (1.0, [250.0, 110.0]),
        ],
        &[
            (0, 1, 40.0, 60.0),
            (1, 2, 42.0, 45.0),
            (2, 3, 38.0, 70.0),
            (3, 4, 40.0, 55.0),
        ],
        &[
            (1, 0, 2, -0.8, 50000.0),
            (2, 1, 3, -0.7, 70000.0),
            (3, 2, 4, -0.85, 40000.0),
        ],
        timing,
    )
}

/// An 8-particle ring: eight springs and ten torsions (36 unknowns, 13 degrees of freedom).
pub fn paper8(timing: Timing) -> Scene {
    let r = 50.0;
    let mut particles = Vec::new();
    for k in 0..8 {
        let a = std::f64::consts::TAU * k as f64 / 8.0;
        let wobble = [3.0, -2.0, 1.5, 0.0, -2.5, 2.0, -1.0, 1.0][k];
        particles.push((
            1.0 + 0.1 * (k % 3) as f64,
            [200.0 + (r + wobble) * a.cos(), 200.0 + (r - wobble) * a.sin()],
        ));
    }
    let side = 2.0 * r * (std::f64::consts::PI / 8.0).sin();
    let mut springs = Vec::new();
    for k in 0..8 {
        springs.push((
            k,
            (k + 1) % 8,
            side * (1.0 + 0.02 * (k % 3) as f64),
            40.0 + 5.0 * k as f64,
        ));
    }
    let interior = (135.0f64).to_radians().cos();
    let mut torsions = Vec::new();
    for k in 0..8 {
        torsions.push((
            k,
            (k + 7) % 8,
            (k + 1) % 8,
            interior + 0.01 * (k % 2) as f64,
            30000.0 + 4000.0 * k as f64,
        ));
    }
    torsions.push((0, 2, 6, 0.05, 20000.0));
    torsions.push((4, 2, 6, -0.05, 25000.0));
    scene_from("paper8", &particles, &springs, &torsions, timing)
}

/// A square lattice of `side x side` particles, springs to right and lower neighbours, a
/// torsion at each particle between its right and lower neighbours.
pub fn lattice(side: usize, timing: Timing) -> Scene {
    let spacing = 30.0;
    let idx = |r: usize, c: usize| r * side + c;
    let mut particles = Vec::new();
    for r in 0..side {
        for c in 0..side {
            let jitter = (((r * 7 + c * 13) % 11) as f64 - 5.0) * 0.4;
            particles.push((
                1.0,
                [
                    50.0 + spacing * c as f64 + jitter,
                    50.0 + spacing * r as f64 - 0.5 * jitter,
                ],
            ));
        }
    }
    let mut springs = Vec::new();
    let mut torsions = Vec::new();
    for r in 0..side {
        for c in 0..side {
            if c + 1 < side {
                springs.push((
                    idx(r, c),
                    idx(r, c + 1),
                    spacing,
                    50.0 + ((r + c) % 5) as f64 * 5.0,
                ));
            }
            if r + 1 < side {
                springs.push((
                    idx(r, c),
                    idx(r + 1, c),
                    spacing,
                    60.0 + ((r * c) % 4) as f64 * 5.0,
                ));
            }
            if c + 1 < side && r + 1 < side {
                torsions.push((
                    idx(r, c),
                    idx(r, c + 1),
                    idx(r + 1, c),
                    0.0,
                    20000.0 + ((r + 2 * c) % 3) as f64 * 3000.0,
                ));
            }
        }
    }
    scene_from("lattice", &particles, &springs, &torsions, timing)
}

/// Simulates a scene over its recording.
pub fn record(scene: &Scene) -> Recording {
    let model = scene.model().expect("complete scene");
    simulate(
        &model,
        &scene.initial_state(),
        &scene.integration_parameters(),
        scene.recording.frames,
    )
}

/// The recording as a track table, with Gaussian position noise `sigma` (px) if positive.
pub fn tracks(scene: &Scene, sigma: f64, seed: u64) -> TrackTable {
    let rec = record(scene);
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let normal = Normal::new(0.0, sigma.max(1e-300)).expect("valid sigma");
    let mut points = Vec::new();
    for k in 0..rec.frame_count() {
        for (p, x) in rec.frame(k).iter().enumerate() {
            let (dx, dy) = if sigma > 0.0 {
                (normal.sample(&mut rng), normal.sample(&mut rng))
            } else {
                (0.0, 0.0)
            };
            points.push(TrackPoint::new(
                k,
                scene.particles[p].id.clone(),
                x.x + dx,
                x.y + dy,
            ));
        }
    }
    TrackTable { points }
}

/// Largest relative error of `fitted` against `truth`, and its index.
pub fn max_relative_error(fitted: &[f64], truth: &[f64]) -> (f64, usize) {
    fitted
        .iter()
        .zip(truth)
        .map(|(f, t)| ((f - t) / t.abs().max(1e-12)).abs())
        .enumerate()
        .fold((0.0, 0), |(m, i), (k, e)| if e > m { (e, k) } else { (m, i) })
}
