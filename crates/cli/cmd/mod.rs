//! One module per subcommand; each validates its arguments and calls the library crates.

pub mod diagnose;
pub mod fit;
pub mod render;
pub mod run;
pub mod simulate;
pub mod track;

use std::path::Path;

use anyhow::Context;
use physfit_model::{Recording, Scene};
use physfit_track::{TrackPoint, TrackTable};

/// Loads and validates a scene file, naming it in any error.
pub fn load_scene(path: &Path) -> anyhow::Result<Scene> {
    Scene::load(path).with_context(|| format!("loading scene {}", path.display()))
}

/// The true centres of a simulated recording as a track table named after the scene's ids.
pub fn truth_table(scene: &Scene, recording: &Recording) -> TrackTable {
    let mut points = Vec::with_capacity(recording.positions.len());
    for k in 0..recording.frame_count() {
        for (p, x) in scene.particles.iter().zip(recording.frame(k)) {
            points.push(TrackPoint::new(k, p.id.clone(), x.x, x.y));
        }
    }
    TrackTable { points }
}

/// The structure's particles by id with their frame-0 positions, px: the tracker's named start
/// (tracks take these names and only these particles are followed).
pub fn named_start(structure: &Scene) -> Vec<(String, [f64; 2])> {
    structure
        .particles
        .iter()
        .map(|p| (p.id.clone(), [p.position.x, p.position.y]))
        .collect()
}

/// Simulates a complete scene over its recording, naming the scene in errors.
pub fn simulate_scene(scene: &Scene, source: &Path) -> anyhow::Result<Recording> {
    let model = scene
        .model()
        .with_context(|| format!("scene {} cannot be simulated", source.display()))?;
    Ok(physfit_model::simulate(
        &model,
        &scene.initial_state(),
        &scene.integration_parameters(),
        scene.recording.frames,
    ))
}
