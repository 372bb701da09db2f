//! The background model and the particle signal.
//!
//! A static camera sees a background that does not move and particles that do. The
//! background is estimated from a sample of frames as the per-pixel median over time
//! (moving particles cover a pixel in fewer than half of the frames, so the median is
//! the background there). When that median image is flat apart from a few compact spots
//! (rendered frames, or a particle that never moves), a single constant level per channel
//! is used instead, so that particles which stay put are not swallowed by the background
//! and the background adds no noise of its own. The choice is automatic.
//!
//! Particles may be brighter or darker than the background, or of another colour. The
//! *signal* of a pixel is the projection of its difference from the background onto the
//! particles' colour direction `u` (a unit vector over the channels), measured from the
//! pixels that differ most from the background: `s = u · (I − B)`. For grey frames `u` is
//! `+1` (bright on dark) or `−1` (dark on light). Particles have positive signal; the
//! background has signal 0 plus noise, whose standard deviation is measured from the
//! negative half of the signal distribution (particles contribute almost nothing there).

mod estimate;
mod exclusion;
mod facing;
mod gain;
mod light;
mod median;
mod model;
mod signal;

pub use estimate::estimate_background;
pub use light::Light;
pub(crate) use model::STRUCTURED_LIMIT;
pub use model::{Background, BackgroundChoice, BackgroundModel, SampleExposure, CLEAR_SAMPLES};

#[cfg(test)]
mod tests;
