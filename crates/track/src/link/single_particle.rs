//! What one particle's blob looks like in a recording: mass and size, median and spread.

use super::options::FrameDetections;
use crate::locate::Detection;
use physfit_tracks::stats::{median_upper, robust_spread_upper};

/// What one particle's blob looks like in this recording: the median and robust spread
/// (1.4826 MAD) of the mass and size of all detections, most of which hold one particle.
pub(super) struct SingleParticle {
    pub(super) mass: f64,
    mass_spread: f64,
    pub(super) size: f64,
    size_spread: f64,
}

impl SingleParticle {
    pub(super) fn measure(frames: &[FrameDetections]) -> SingleParticle {
        let masses: Vec<f64> = frames
            .iter()
            .flat_map(|f| f.detections.iter().map(|d| d.mass))
            .collect();
        let sizes: Vec<f64> = frames
            .iter()
            .flat_map(|f| f.detections.iter().map(|d| d.size))
            .collect();
        let (mass, mass_spread) = median_and_spread(masses);
        let (size, size_spread) = median_and_spread(sizes);
        SingleParticle {
            mass,
            mass_spread,
            size,
            size_spread,
        }
    }

    /// Returns true if and only if blob `d`, already given to `taken` tracks, is measurably
    /// heavier or wider than `taken` particles (by more than three spreads, and by at least
    /// a tenth of a particle's mass or of its size).
    pub(super) fn holds_more(&self, d: &Detection, taken: usize) -> bool {
        self.holds_more_than(d.mass, d.size, taken)
    }

    /// How many particles a blob of `mass` holds (1 to 4): its mass in single particles'.
    pub(super) fn capacity(&self, mass: f64) -> usize {
        if self.mass > 0.0 && mass.is_finite() {
            (mass / self.mass).round().clamp(1.0, 4.0) as usize
        } else {
            1
        }
    }

    /// [`SingleParticle::holds_more`] for a blob of `mass` and `size`.
    pub(super) fn holds_more_than(&self, mass: f64, size: f64, taken: usize) -> bool {
        if !(self.mass.is_finite() && self.size.is_finite()) {
            return false;
        }
        let heavier = mass > self.mass * taken as f64 + (3.0 * self.mass_spread).max(0.1 * self.mass);
        let wider = taken == 1 && size > self.size + (3.0 * self.size_spread).max(0.1 * self.size);
        heavier || wider
    }
}

/// The [`median_upper`] and [`robust_spread_upper`] of the finite values of `v`.
fn median_and_spread(mut v: Vec<f64>) -> (f64, f64) {
    v.retain(|x| x.is_finite());
    (median_upper(&mut v), robust_spread_upper(&mut v))
}
/// The [`median_upper`] of the finite values of `v`.
pub(super) fn finite_median(mut v: Vec<f64>) -> f64 {
    v.retain(|x| x.is_finite());
    median_upper(&mut v)
}
