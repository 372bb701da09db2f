//! Tracking: finds particles in a recording (a folder of frames, a video, a TIFF stack),
//! locates them to sub-pixel accuracy and links them into trajectories, seeing only pixels.

mod appearance;
mod assignment;
mod background;
mod blind;
mod checks;
mod cpu;
mod crossing;
mod detect;
mod disjoint_sets;
mod error;
mod frames;
mod group_by_key;
mod inpaint;
mod limits;
mod link;
mod locate;
mod naming;
mod pipeline;
mod png_reader;
mod point_grid;
mod scale;
mod score;
mod shared_blobs;
mod source;
mod stack;
mod track_table;
mod video;

pub use appearance::*;
pub use assignment::*;
pub use background::*;
pub use blind::BlindPixels;
pub use detect::*;
pub use error::TrackError;
pub use frames::*;
pub use limits::{
    frame_limits, set_frame_limits, FrameLimits, DEFAULT_MAX_DECOMPRESSION_RATIO, DEFAULT_MAX_MEGAPIXELS,
};
pub use link::*;
pub use locate::*;
pub use naming::name_tracks_by_position;
pub use pipeline::{track_folder, track_source, TrackOptions, TrackOutcome, TrackStats};
#[doc(hidden)]
pub use png_reader::fuzz_read_png;
pub use score::*;
pub use source::{FrameSource, FrameWindow};
pub use stack::{is_tiff, TiffStack, TIFF_EXTENSIONS};
// The track table and other trackers' tables live in physfit-tracks; re-exported so the
// tracker's users keep one import path for what it returns.
pub use physfit_tracks::{
    detect_format, read_track_table, read_track_table_str, ForeignTable, PointFlag, TableError, TableFormat,
    TableOptions, TrackPoint, TrackTable,
};
pub use track_table::write_detections_csv;
pub use video::{
    is_video_path, probe_video, VideoFrames, VideoInfo, NEUTRAL_LEVELS, VIDEO_EXTENSIONS, VIDEO_MEMORY_BYTES,
};
