//! How to track a recording: the options.

use crate::BackgroundChoice;

/// How to track a folder of frames. `TrackOptions::default()` derives everything from the data.
#[derive(Clone, Debug, PartialEq)]
pub struct TrackOptions {
    /// First and last frame tracked, inclusive (indices in natural name order); all when `None`.
    pub window: Option<(usize, usize)>,
    /// Named particles and their positions (px) in the first tracked frame: tracks take these
    /// names and only these particles are followed. `None` tracks every blob.
    pub named_start: Option<Vec<(String, [f64; 2])>>,
    /// Particle radius, px; estimated from the frames when `None`.
    pub radius: Option<f64>,
    /// Worker threads; rayon's default (one per core) when `None`.
    pub threads: Option<usize>,
    /// Background model; chosen automatically by default.
    pub background: BackgroundChoice,
    /// Frames a particle may go unseen and still be bridged (named) or kept (unnamed).
    pub memory: usize,
}

impl Default for TrackOptions {
    fn default() -> Self {
        TrackOptions {
            window: None,
            named_start: None,
            radius: None,
            threads: None,
            background: BackgroundChoice::Auto,
            memory: 5,
        }
    }
}
