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

/// Loads and validates a scene file, naming it in any error; a file above the `scene-mb` limit
/// is refused unread.
pub fn load_scene(path: &Path) -> anyhow::Result<Scene> {
    crate::limits::check_scene_file(path)?;
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

/// Reads a track table, refused unread above the `tracks-mb` limit, and refused when its rows
/// of `structure`'s particles span more frames than the `frames-x-particles` limit allows.
pub fn read_tracks(path: &Path, structure: &Scene) -> anyhow::Result<TrackTable> {
    crate::limits::check_tracks_file(path)?;
    let tracks = TrackTable::read_csv(path).with_context(|| format!("reading tracks {}", path.display()))?;
    crate::limits::check_track_span(&tracks, structure, path)?;
    Ok(tracks)
}

/// Simulates a complete scene over its recording, naming the scene in errors; a scene above the
/// `frames-x-particles` limit is refused before anything is allocated.
pub fn simulate_scene(scene: &Scene, source: &Path) -> anyhow::Result<Recording> {
    crate::limits::check_scene(scene, source, false)?;
    let model = scene
        .model()
        .with_context(|| format!("scene {} cannot be simulated", source.display()))?;
    let recording = physfit_model::simulate(
        &model,
        &scene.initial_state(),
        &scene.integration_parameters(),
        scene.recording.frames,
    );
    if let Some((frame, k)) = recording.first_non_finite() {
        let i = frame * recording.particle_count + k;
        let (x, v) = (recording.positions[i], recording.velocities[i]);
        anyhow::bail!(
            "scene {}: the simulation diverged: particle \"{}\" at frame {frame} has position ({}, {}) px \
             and velocity ({}, {}) px/s; the scene's values make the motion unstable at this time step \
             (raise recording.substeps, or lower the stiffnesses)",
            source.display(),
            scene.particles[k].id,
            x.x,
            x.y,
            v.x,
            v.y
        );
    }
    Ok(recording)
}
