//! [`IdentifyError`]: everything that can stop an identification.

use physfit_model::SceneProblem;

/// An error of the identification stage; each message names the particle, frame or value at fault.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum IdentifyError {
    /// A free particle of the structure has no track in the track table.
    #[error("particle \"{particle}\" of the structure has no track (the track table names {available})")]
    MissingTrack {
        /// The structure's particle id.
        particle: String,
        /// The track names present, for the message.
        available: String,
    },
    /// The structure has no unknown bond value to fit.
    #[error("the structure has no unknown bond value to fit (every spring and torsion value is given, or there are no bonds)")]
    NoUnknowns,
    /// The analysed window holds fewer usable frames than the method needs.
    #[error("too few frames: {method} needs at least {need} frames with every particle tracked, the data give {have}")]
    TooFewFrames {
        /// What needs them.
        method: String,
        /// Frames needed.
        need: usize,
        /// Frames available.
        have: usize,
    },
    /// A track position is NaN or infinite.
    #[error("frame {frame}, particle \"{particle}\": position ({x}, {y}) is not finite")]
    NonFinite {
        /// Frame index.
        frame: usize,
        /// Particle id.
        particle: String,
        /// The x coordinate given.
        x: f64,
        /// The y coordinate given.
        y: f64,
    },
    /// The analysed window is empty or outside the tracked frames.
    #[error("window frames {first}..={last} is invalid: the tracks cover frames {start}..{end}")]
    BadWindow {
        /// First frame asked.
        first: usize,
        /// Last frame asked.
        last: usize,
        /// First tracked frame.
        start: usize,
        /// One past the last tracked frame.
        end: usize,
    },
    /// The structure itself is invalid for fitting (a known value out of range, ...).
    #[error("structure: {0}")]
    Structure(#[from] SceneProblem),
    /// A solver option is invalid.
    #[error("invalid option: {0}")]
    InvalidOption(String),
    /// The chosen method is not available in this build.
    #[error("method `{0}` is not available in this build")]
    MethodUnavailable(String),
    /// A solver failed to produce a finite cost (the model diverges everywhere it looked).
    #[error("{method} found no parameter set with a finite cost: {detail}")]
    NoFiniteCost {
        /// The method.
        method: String,
        /// What was tried.
        detail: String,
    },
}
