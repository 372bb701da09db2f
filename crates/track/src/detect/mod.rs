//! Blob detection: where the particles are, to the pixel.
//!
//! The particle signal (see [`crate::background`]) is band-pass filtered: a box mean of
//! side about the particle's diameter (the matched filter of a disc, which averages the
//! noise down) minus a box mean twice as wide (which removes any slowly varying residual
//! background and the interiors of large objects). Candidate particles are the local
//! maxima of that response above `PEAK_SIGMAS` times its noise, the noise being propagated
//! from the measured pixel noise, so no brightness threshold has to be chosen by hand.
//! Maxima closer than one particle radius to a stronger one are dropped (a disc has one
//! centre). Each candidate then owns a blob: the pixels connected to it where the smoothed
//! signal is at least half way from the local background to the candidate's peak (and above
//! `MASK_SIGMAS` times its noise), shared with any weaker candidate inside it. Measured
//! against each candidate's own contrast, a blob's size does not depend on the brightness
//! offsets real video leaves in the signal (exposure changes, shadows). A blob's area per
//! candidate tells a particle
//! from a large object (a hand, a floor edge) or from a speck much smaller than the
//! expected particle, and such candidates are rejected.

mod band_pass;
mod blob;
mod box_filter;
mod find;
mod labels;
mod peaks;
mod regions;
mod signal_rows;

pub use band_pass::{band_noise, box_half_width};
pub use blob::{
    Blob, BlobSet, BlobSize, DetectParameters, FLOOD_CAP_AREAS, MASK_SIGMAS, MAX_AREA_RATIO,
    MERGED_AREA_RATIO, MIN_AREA_RATIO, PEAK_SIGMAS,
};
pub use find::{find_blobs, find_blobs_forming, find_blobs_with_scratch, Scratch};

#[cfg(test)]
mod tests;
