//! One module per subcommand; each validates its arguments and calls the library crates.

pub mod diagnose;
pub mod fit;
pub mod render;
pub mod run;
pub mod simulate;
pub mod track;

use std::path::Path;

use anyhow::{bail, Context};
use physfit_model::{Recording, Scene};
use physfit_track::{FrameSource, FrameWindow};
use physfit_tracks::{TableFormat, TableOptions, TrackPoint, TrackTable};

use crate::cli::{FormatArg, TableArgs};
use crate::progress::Verbosity;

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

/// [`named_start`] less the fixed particles outside the recording's frames (a pendulum's
/// pivot out of view): a fixed particle's position is known from the structure, and one the
/// camera cannot see cannot be tracked.
pub fn named_start_in_view(
    structure: &Scene,
    source: &FrameSource,
) -> anyhow::Result<Vec<(String, [f64; 2])>> {
    let all = named_start(structure);
    if !structure.particles.iter().any(|p| p.fixed) || source.is_empty() {
        return Ok(all);
    }
    let (width, height) = {
        let f = source
            .load_frame(0)
            .with_context(|| format!("reading {}", source.path().display()))?;
        (f.width as f64, f.height as f64)
    };
    let inside = |x: [f64; 2]| x[0] >= -0.5 && x[1] >= -0.5 && x[0] <= width - 0.5 && x[1] <= height - 0.5;
    Ok(all
        .into_iter()
        .zip(&structure.particles)
        .filter(|((_, x), p)| !p.fixed || inside(*x))
        .map(|(named, _)| named)
        .collect())
}

/// A recording opened for tracking ([`open_recording`]).
pub struct OpenRecording {
    /// Its frames (of a video: those of the window only).
    pub source: FrameSource,
    /// The window's first and last frame, inclusive, when one was given.
    pub window: Option<(usize, usize)>,
    /// The frame rate, frames/s: `--fps` when given, else a video's own; `None` for frames
    /// and stacks without `--fps`.
    pub fps: Option<f64>,
}

/// Opens the recording at `path` (a folder of frames, a video, a TIFF stack) with `window`,
/// whose times (if any) are converted with `fps` (`--fps`, frames/s), else with a video's own
/// rate, else with `fallback_fps` (a structure's `[recording] fps`). Errors name the recording.
pub fn open_recording(
    path: &Path,
    window: Option<FrameWindow>,
    fps: Option<f64>,
    fallback_fps: Option<f64>,
) -> anyhow::Result<OpenRecording> {
    if let Some(fps) = fps {
        if !(fps.is_finite() && fps > 0.0) {
            bail!("--fps {fps}: the frame rate must be a positive number of frames per second");
        }
    }
    let fps = match fps {
        Some(fps) => Some(fps),
        // The errors name the recording.
        None if physfit_track::is_video_path(path) => physfit_track::probe_video(path)?.fps,
        None => None,
    };
    let window = window
        .map(|w| w.frames(fps.or(fallback_fps)))
        .transpose()
        .with_context(|| format!("the window of {}", path.display()))?;
    let source = FrameSource::open(path, window)?;
    Ok(OpenRecording { source, window, fps })
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

/// Sets the structure's scale from `--scale`, m/px, when given (it overrides the file's).
pub fn apply_scale(structure: &mut Scene, scale: Option<f64>) -> anyhow::Result<()> {
    if let Some(m) = scale {
        if !(m.is_finite() && m > 0.0) {
            bail!("--scale {m}: the scale must be a positive number of metres per px");
        }
        structure.recording.metres_per_px = Some(m);
    }
    Ok(())
}

/// Reads a tracks table in any format `table` allows, converts it to px with the structure's
/// scale, and names its tracks after the structure's particles by their position in the first
/// analysed frame (`window`'s first, else the table's) when no track name is a particle id.
/// Warnings go to stderr unless quiet.
pub fn load_tracks(
    path: &Path,
    table: &TableArgs,
    structure: &Scene,
    window: Option<(usize, usize)>,
    verbosity: Verbosity,
) -> anyhow::Result<TrackTable> {
    let options = TableOptions {
        format: table.format.map(|f| match f {
            FormatArg::Physfit => TableFormat::Physfit,
            FormatArg::Trackpy => TableFormat::Trackpy,
            FormatArg::Trackmate => TableFormat::TrackMate,
            FormatArg::Tracker => TableFormat::Tracker,
        }),
        px_per_unit: table.px_per_unit,
        metres_per_px: structure.recording.metres_per_px,
        origin_px: table.origin,
    };
    crate::limits::check_tracks_file(path)?;
    let read = physfit_tracks::read_track_table(path, &options)
        .with_context(|| format!("reading tracks {}", path.display()))?;
    let mut notes = read.warnings;
    let in_px = matches!(read.format, TableFormat::Physfit | TableFormat::Trackpy);
    if in_px && table.px_per_unit.is_some() {
        notes.push(format!("--px-per-unit ignored: a {} table is in px", read.format));
    }
    if read.format != TableFormat::Tracker && table.origin != [0.0, 0.0] {
        notes.push(format!(
            "--origin ignored: it places Tracker's origin, not a {} table's",
            read.format
        ));
    }
    if let Some(fps) = read.fps {
        let given = structure.recording.fps;
        if (fps / given - 1.0).abs() > 0.01 {
            notes.push(format!(
                "the table's times give {fps:.4} frames/s but the structure says {given} (`[recording] fps`); the structure's is used"
            ));
        }
    }
    let mut tracks = read.table;
    notes.extend(physfit_track::name_tracks_by_position(
        &mut tracks,
        &named_start(structure),
        window.map(|w| w.0),
    ));
    crate::limits::check_track_span(&tracks, structure, path)?;
    if verbosity != Verbosity::Quiet {
        if read.format != TableFormat::Physfit {
            eprintln!("physfit: read {} as a {} table", path.display(), read.format);
        }
        for n in &notes {
            eprintln!("physfit: warning: {n}");
        }
    }
    Ok(tracks)
}
