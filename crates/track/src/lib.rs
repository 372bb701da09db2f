//! Tracking: finds particles in a folder of frames, locates them to sub-pixel accuracy and
//! links them into trajectories, seeing only pixels.

mod error;
mod track_table;

pub use error::TrackError;
pub use track_table::{PointFlag, TrackPoint, TrackTable};
