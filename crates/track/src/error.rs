//! Errors of the tracking stage.

use std::path::PathBuf;

/// An error reading frames or track tables, or tracking them.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum TrackError {
    /// A file could not be read or written.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The cause.
        #[source]
        source: std::io::Error,
    },
    /// A track table could not be read or written (`--truth`, `--detections`, tracks.csv).
    #[error(transparent)]
    Table(#[from] physfit_tracks::TableError),
    /// A frame file could not be decoded (corrupt, truncated, empty or not an image).
    #[error("{path}: {message}")]
    Decode {
        /// The frame file.
        path: PathBuf,
        /// What is wrong.
        message: String,
    },
    /// A video could not be read: not a video, corrupt or truncated (`message` says which).
    #[error("{path}: {message}")]
    Video {
        /// The video file.
        path: PathBuf,
        /// What is wrong.
        message: String,
    },
    /// A program needed to read the recording could not be started (it is not on the `PATH`).
    #[error("reading {path} needs the {program} program of ffmpeg on the PATH; install ffmpeg (Debian/Ubuntu: apt-get install ffmpeg; Fedora: dnf install ffmpeg; macOS: brew install ffmpeg; Windows: winget install ffmpeg)")]
    MissingProgram {
        /// The recording.
        path: PathBuf,
        /// The program (`ffmpeg` or `ffprobe`).
        program: String,
    },
    /// The folder holds no PNG, JPEG or TIFF frames.
    #[error("{dir}: no frames (PNG, JPEG or TIFF files) in this folder")]
    NoFrames {
        /// The folder.
        dir: PathBuf,
    },
    /// A frame's size differs from the first frame's.
    #[error("{path}: frame is {found_width}x{found_height} px but {first} is {width}x{height} px; all frames must be the same size")]
    FrameSize {
        /// The odd frame.
        path: PathBuf,
        /// The first frame's file name.
        first: String,
        /// The first frame's width, px.
        width: usize,
        /// The first frame's height, px.
        height: usize,
        /// The odd frame's width, px.
        found_width: usize,
        /// The odd frame's height, px.
        found_height: usize,
    },
    /// The frame window `A..B` does not fit the recording.
    #[error("frame window {start}..{end} is invalid: the recording has {count} frames (indices 0..{last}), and A must not exceed B", last = count.saturating_sub(1))]
    Window {
        /// First frame requested.
        start: usize,
        /// Last frame requested (inclusive).
        end: usize,
        /// Frames in the recording.
        count: usize,
    },
    /// Named particles could not be followed: the tracks would be wrong.
    #[error("{}", .concerns.join("; "))]
    NotFollowed {
        /// What is wrong with each, a sentence each (naming the particle and frames).
        concerns: Vec<String>,
    },
    /// A frame file declares a size above a limit ([`crate::FrameLimits`]); nothing of it was
    /// allocated.
    #[error("{path}: {message}")]
    FrameLimit {
        /// The frame file.
        path: PathBuf,
        /// The limit's name: `frame-megapixels` or `decompression-ratio`.
        limit: &'static str,
        /// The value seen and the limit (named), in words.
        message: String,
    },
    /// An option is invalid (a non-finite start position, a non-positive radius, ...).
    #[error("invalid tracking option: {0}")]
    Option(String),
}
