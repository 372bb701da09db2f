//! What linking takes: the detections of each frame and the options.

use crate::locate::Detection;

/// The detections of one frame.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct FrameDetections {
    /// 0-based frame index (the file's index in natural name order).
    pub frame: usize,
    /// Detections, any order.
    pub detections: Vec<Detection>,
}

/// What linking needs to know.
#[derive(Clone, Debug, PartialEq)]
pub struct LinkOptions {
    /// Named particles and their approximate positions in the first frame, px; `None`
    /// tracks every detection under an integer name.
    pub named_start: Option<Vec<(String, [f64; 2])>>,
    /// Expected particle radius, px.
    pub radius: f64,
    /// Frame width, px.
    pub width: usize,
    /// Frame height, px.
    pub height: usize,
    /// Frames a track may go unseen before it ends (unnamed) or stops being bridged (named).
    pub memory: usize,
}
pub(super) fn diagonal(o: &LinkOptions) -> f64 {
    (o.width as f64).hypot(o.height as f64)
}
