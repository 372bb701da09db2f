//! Unit tests of linking.

use super::claimants::Claimants;
use super::options::FrameDetections;
use crate::locate::Detection;

/// A detection of one particle's mass and size at `(x, y)`.
pub(crate) fn det(x: f64, y: f64) -> Detection {
    Detection {
        x,
        y,
        mass: 100.0,
        size: 2.0,
        ep: 0.05,
        follow: 0.0,
        area: 12.0,
        clipped: false,
    }
}

/// Frame `frame` with a detection of [`det`] at each of `at`.
pub(crate) fn frame(frame: usize, at: &[[f64; 2]]) -> FrameDetections {
    FrameDetections {
        frame,
        detections: at.iter().map(|p| det(p[0], p[1])).collect(),
    }
}

/// Claimants read back as the tracks pushed, in order, whether none, one or several.
#[test]
fn claimants_hold_what_was_pushed() {
    let mut c = Claimants::default();
    assert!(c.is_empty());
    let mut want = Vec::new();
    for k in [7, 3, 9, 3] {
        c.push(k);
        want.push(k);
        assert_eq!(&c[..], &want[..]);
    }
}
