//! The linking entry point: a [`Linker`] started on the first frame, stepped through the
//! others and finished.

use super::linker::Linker;
use super::options::{FrameDetections, LinkOptions};
use super::outcome::LinkOutcome;

/// Links per-frame detections into trajectories (see the module doc). `frames` must be
/// in increasing, contiguous frame order.
pub fn link_detections(frames: &[FrameDetections], options: &LinkOptions) -> LinkOutcome {
    if frames.is_empty() {
        return LinkOutcome::default();
    }
    let mut linker = Linker::new(frames, options);
    for fd in &frames[1..] {
        linker.step(fd);
    }
    linker.finish()
}
