//! The track table types, owned by `physfit-tracks` and used here under this path, and the
//! tracker's own detections CSV.

use std::path::Path;

pub use physfit_tracks::{PointFlag, TrackPoint, TrackTable};

use crate::TrackError;

/// Writes every frame's located detections, before linking, as CSV
/// `frame,x,y,mass,size,ep,area,clipped` (trackpy's `locate` output with physfit's extra
/// columns; units as in [`crate::Detection`]), atomically.
pub fn write_detections_csv(frames: &[crate::FrameDetections], path: &Path) -> Result<(), TrackError> {
    use std::fmt::Write as _;
    let mut text = String::from("frame,x,y,mass,size,ep,area,clipped\n");
    for f in frames {
        for d in &f.detections {
            let _ = writeln!(
                text,
                "{},{},{},{},{},{},{},{}",
                f.frame, d.x, d.y, d.mass, d.size, d.ep, d.area, d.clipped
            );
        }
    }
    physfit_tracks::write_atomic(path, text.as_bytes()).map_err(|source| {
        TrackError::from(physfit_tracks::TableError::Io {
            path: path.to_path_buf(),
            source,
        })
    })
}
