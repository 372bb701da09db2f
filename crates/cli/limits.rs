//! Limits on the size of what physfit reads and builds, checked before the memory is taken
//! (docs/limits.md). Each has a name, a default, and is raised with `--limit NAME=VALUE`.
//!
//! Frame limits live in the tracker (`physfit_track::FrameLimits`), which applies them inside
//! every decoder; [`install`] hands it this command line's values. The others are checked here,
//! by the commands, on the files they are given.

use std::path::Path;
use std::sync::OnceLock;

use anyhow::bail;
use physfit_model::Scene;
use physfit_track::{FrameLimits, TrackError};
use physfit_tracks::TrackTable;

/// Largest scene (or structure) file read by default, MB.
pub const DEFAULT_SCENE_MB: f64 = 10.0;
/// Largest track table read by default, MB.
pub const DEFAULT_TRACKS_MB: f64 = 100.0;
/// Most samples (frames x particles) simulated, or fitted from a track table, by default.
pub const DEFAULT_FRAMES_X_PARTICLES: f64 = 2.0e6;

/// The limits in force.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Limits {
    /// Largest frame read or rendered, megapixels.
    pub frame_megapixels: f64,
    /// Largest ratio of a frame's decoded sample bytes to its file's bytes.
    pub decompression_ratio: f64,
    /// Most frames x particles of a simulation, or of a track table's frame span x the
    /// structure's particles.
    pub frames_x_particles: f64,
    /// Largest scene file, MB.
    pub scene_mb: f64,
    /// Largest track table, MB.
    pub tracks_mb: f64,
}

impl Default for Limits {
    fn default() -> Limits {
        let frames = FrameLimits::default();
        Limits {
            frame_megapixels: frames.max_megapixels,
            decompression_ratio: frames.max_decompression_ratio,
            frames_x_particles: DEFAULT_FRAMES_X_PARTICLES,
            scene_mb: DEFAULT_SCENE_MB,
            tracks_mb: DEFAULT_TRACKS_MB,
        }
    }
}

/// The limit names `--limit` takes, in docs/limits.md's order.
pub const NAMES: [&str; 5] = [
    "frame-megapixels",
    "decompression-ratio",
    "frames-x-particles",
    "scene-mb",
    "tracks-mb",
];

impl Limits {
    /// The limit `name`'s slot.
    fn slot(&mut self, name: &str) -> Option<&mut f64> {
        Some(match name {
            "frame-megapixels" => &mut self.frame_megapixels,
            "decompression-ratio" => &mut self.decompression_ratio,
            "frames-x-particles" => &mut self.frames_x_particles,
            "scene-mb" => &mut self.scene_mb,
            "tracks-mb" => &mut self.tracks_mb,
            _ => return None,
        })
    }

    /// The defaults with each `NAME=VALUE` of `settings` applied.
    pub fn from_settings(settings: &[String]) -> anyhow::Result<Limits> {
        let mut limits = Limits::default();
        for s in settings {
            let Some((name, value)) = s.split_once('=') else {
                bail!(
                    "--limit {s}: expected NAME=VALUE, with NAME one of {}",
                    NAMES.join(", ")
                );
            };
            let name = name.trim();
            let Some(slot) = limits.slot(name) else {
                bail!(
                    "--limit {s}: unknown limit `{name}`; the limits are {}",
                    NAMES.join(", ")
                );
            };
            match value.trim().parse::<f64>() {
                Ok(v) if v.is_finite() && v > 0.0 => *slot = v,
                _ => bail!("--limit {s}: `{value}` is not a positive number"),
            }
        }
        Ok(limits)
    }
}

static LIMITS: OnceLock<Limits> = OnceLock::new();

/// Makes `limits` the process's limits, the tracker's frame limits included. Called once, by
/// `main`, before any command runs.
pub fn install(limits: Limits) {
    physfit_track::set_frame_limits(FrameLimits {
        max_megapixels: limits.frame_megapixels,
        max_decompression_ratio: limits.decompression_ratio,
    });
    let _ = LIMITS.set(limits);
}

/// The limits in force (the defaults until [`install`]).
pub fn limits() -> Limits {
    LIMITS.get().copied().unwrap_or_default()
}

/// How to raise the limit `name`, for an error message.
pub fn raise_hint(name: &str) -> String {
    format!("raise it with --limit {name}=N")
}

/// The hint for a limit error of the tracker's found in `err`'s chain, if any.
pub fn hint_for(err: &anyhow::Error) -> Option<String> {
    err.chain().find_map(|e| match e.downcast_ref::<TrackError>() {
        Some(TrackError::FrameLimit { limit, .. }) => Some(raise_hint(limit)),
        _ => None,
    })
}

/// Refuses a file larger than the limit `name` (MB) before it is read.
fn check_file_size(path: &Path, what: &str, name: &str, max_mb: f64) -> anyhow::Result<()> {
    // A file that cannot be examined is left to the reader, whose error names it.
    let Ok(meta) = std::fs::metadata(path) else {
        return Ok(());
    };
    let mb = meta.len() as f64 / 1e6;
    if meta.is_file() && mb > max_mb {
        bail!(
            "{}: the {what} is {mb:.1} MB, above the `{name}` limit of {max_mb} MB ({})",
            path.display(),
            raise_hint(name)
        );
    }
    Ok(())
}

/// Refuses a scene file above the `scene-mb` limit.
pub fn check_scene_file(path: &Path) -> anyhow::Result<()> {
    check_file_size(path, "scene file", "scene-mb", limits().scene_mb)
}

/// Refuses a track table above the `tracks-mb` limit.
pub fn check_tracks_file(path: &Path) -> anyhow::Result<()> {
    check_file_size(path, "track table", "tracks-mb", limits().tracks_mb)
}

/// Refuses a scene whose simulation would hold more than `frames-x-particles` samples, or whose
/// frames are above `frame-megapixels` when `rendered`; `source` names the scene file.
pub fn check_scene(scene: &Scene, source: &Path, rendered: bool) -> anyhow::Result<()> {
    let l = limits();
    let (frames, particles) = (scene.recording.frames, scene.particles.len());
    let samples = frames as f64 * particles as f64;
    if samples > l.frames_x_particles {
        bail!(
            "{}: recording.frames = {frames} x {particles} particles = {samples:.0} samples, above \
             the `frames-x-particles` limit of {} ({})",
            source.display(),
            l.frames_x_particles,
            raise_hint("frames-x-particles")
        );
    }
    let (w, h) = (scene.render.width, scene.render.height);
    let megapixels = f64::from(w) * f64::from(h) / 1e6;
    if rendered && megapixels > l.frame_megapixels {
        bail!(
            "{}: render.width x render.height = {w}x{h} px = {megapixels:.0} megapixels, above the \
             `frame-megapixels` limit of {} ({})",
            source.display(),
            l.frame_megapixels,
            raise_hint("frame-megapixels")
        );
    }
    Ok(())
}

/// Refuses a track table whose rows of `structure`'s particles span more frames than
/// `frames-x-particles` allows for that many particles: the fit holds every frame of the span.
pub fn check_track_span(tracks: &TrackTable, structure: &Scene, path: &Path) -> anyhow::Result<()> {
    let named: std::collections::HashSet<&str> = structure.particles.iter().map(|p| p.id.as_str()).collect();
    let span = tracks
        .points
        .iter()
        .filter(|p| named.contains(p.particle.as_str()))
        .fold(None, |acc: Option<(usize, usize)>, p| match acc {
            None => Some((p.frame, p.frame)),
            Some((a, b)) => Some((a.min(p.frame), b.max(p.frame))),
        });
    let Some((first, last)) = span else {
        return Ok(());
    };
    let frames = (last - first) as f64 + 1.0;
    let particles = structure.particles.len();
    let samples = frames * particles as f64;
    let l = limits();
    if samples > l.frames_x_particles {
        bail!(
            "{}: frames {first} to {last} ({frames:.0} frames) x {particles} particles = {samples:.0} \
             samples, above the `frames-x-particles` limit of {} ({})",
            path.display(),
            l.frames_x_particles,
            raise_hint("frames-x-particles")
        );
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn settings_parse_and_reject() {
        let l = Limits::from_settings(&["frame-megapixels=200".into(), "tracks-mb = 5".into()]).unwrap();
        assert_eq!(l.frame_megapixels.to_bits(), 200f64.to_bits());
        assert_eq!(l.tracks_mb.to_bits(), 5f64.to_bits());
        let e = Limits::from_settings(&["pixels=3".into()])
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("unknown limit `pixels`") && e.contains("frame-megapixels"),
            "{e}"
        );
        let e = Limits::from_settings(&["scene-mb=-1".into()])
            .unwrap_err()
            .to_string();
        assert!(e.contains("not a positive number"), "{e}");
        assert!(Limits::from_settings(&["scene-mb".into()]).is_err());
    }
}
