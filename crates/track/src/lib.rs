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
mod distance;
mod error;
mod excursion;
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
mod rim;
mod scale;
mod score;
mod shared_blobs;
mod source;
mod spokes;
mod stack;
mod track_table;
mod video;
mod view;

pub use appearance::{
    Appearance, AppearanceHistory, AppearanceLevels, AppearanceSpread, TrackAppearance, HISTORY,
    OWN_SPREAD_MIN_CHANGES,
};
pub use assignment::{match_to_starts, solve_dense, solve_sparse, SparseProblem};
pub use background::{
    estimate_background, Background, BackgroundChoice, BackgroundModel, Light, SampleExposure, CLEAR_SAMPLES,
};
pub use blind::BlindPixels;
pub use detect::{
    band_noise, box_half_width, find_blobs, find_blobs_forming, find_blobs_with_scratch, Blob, BlobSet,
    BlobSize, DetectParameters, Scratch, FLOOD_CAP_AREAS, MASK_SIGMAS, MAX_AREA_RATIO, MERGED_AREA_RATIO,
    MIN_AREA_RATIO, PEAK_SIGMAS,
};
pub use error::TrackError;
pub use frames::{
    compare_natural, frame_from_image, frame_number, list_frames, load_frame, DecodedFrame, Frame,
    FrameDecoder, FrameView,
};
pub use limits::{
    frame_limits, set_frame_limits, FrameLimits, DEFAULT_MAX_DECOMPRESSION_RATIO, DEFAULT_MAX_MEGAPIXELS,
};
pub use link::{
    backward_disagreements, link_detections, Ambiguity, AmbiguityKind, Disagreement, FrameDetections,
    LinkOptions, LinkOutcome, APPEARANCE_GATE_SIGMAS,
};
pub use locate::{refine_centroids, refine_centroids_with_scratch, Detection, LocateScratch};
pub use naming::name_tracks_by_position;
pub use pipeline::{track_folder, track_source, TrackOptions, TrackOutcome, TrackStats};
#[doc(hidden)]
pub use png_reader::fuzz_read_png;
pub use score::{rms_offset, score_tracks, TrackScore};
pub use source::{FrameSource, FrameWindow};
pub use stack::{is_tiff, TiffStack, TIFF_EXTENSIONS};
pub use view::{edge_distance, in_view};
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
