//! [`track_folder`]: the whole tracking stage, from a recording (a folder of frames, a video,
//! a TIFF stack: a [`FrameSource`]) to a track table.
//!
//! Every threshold is measured from the frames themselves: the background model and pixel
//! noise from a sample of frames ([`crate::estimate_background`]), the particle radius from
//! the radius of gyration of the blobs found (unless given), and the expected blob area
//! from the components at that radius. Frames are decoded, filtered and located in
//! parallel; linking is sequential.

mod border;
mod finder;
mod guided;
mod light_check;
mod neighbours;
mod options;
mod outcome;
mod plane;
mod profiles;
mod radius;
mod rims;
mod samples;
mod size_class;
mod skirts;
mod spikes;
mod spokes;
mod stage;
mod start_offsets;
mod track_frames;
mod tracks_background;
mod window_frames;

pub use options::TrackOptions;
pub use outcome::{TrackOutcome, TrackStats};
pub use track_frames::{track_folder, track_source};

#[cfg(test)]
mod tests;
