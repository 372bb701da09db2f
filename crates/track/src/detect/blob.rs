//! What a blob is: the detector's parameters, its size limits and its results.

/// Candidate peaks must exceed this many standard deviations of the band-passed noise.
pub const PEAK_SIGMAS: f64 = 5.0;
/// Blob masks are the smoothed signal above this many standard deviations of its noise.
pub const MASK_SIGMAS: f64 = 3.0;
/// A candidate whose blob area per candidate exceeds this many expected particle
/// areas is part of a large object, not a particle.
pub const MAX_AREA_RATIO: f64 = 4.0;
/// A blob holding several candidates is a large object, not touching particles, when
/// its area exceeds this many expected particle areas per candidate (touching discs cover
/// less than the sum of their areas; a lone particle may be smeared by motion blur, so it
/// gets the looser [`MAX_AREA_RATIO`]).
pub const MERGED_AREA_RATIO: f64 = 1.5;
/// A blob's flood fill stops after this many times `radius²` pixels (about 13 particle
/// areas): a blob that large is rejected as a large object whatever its exact size.
pub const FLOOD_CAP_AREAS: f64 = 40.0;
/// A candidate whose extent (not touching the image border) is smaller than this fraction
/// of the expected particle extent is a speck, not a particle.
pub const MIN_AREA_RATIO: f64 = 0.2;

/// What [`find_blobs`](crate::find_blobs) needs to know.
#[derive(Clone, Debug, PartialEq)]
pub struct DetectParameters {
    /// Expected particle radius, px (the radius at half the peak signal).
    pub radius: f64,
    /// Standard deviation of the per-pixel signal noise, grey levels.
    pub noise_sigma: f64,
    /// One particle's expected blob measures (measured from the data); `None` disables the
    /// size rejection.
    pub expected: Option<BlobSize>,
}

/// What one particle's blob measures, px²: [`Blob::area`] and [`Blob::extent`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BlobSize {
    /// Area at half contrast per candidate, px²: large objects exceed it.
    pub area: f64,
    /// Area above the noise mask per candidate, px²: noise peaks and texture specks fall short.
    pub extent: f64,
}

/// A detected blob, located to the pixel.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Blob {
    /// Column of the band-pass peak, px.
    pub x: usize,
    /// Row of the band-pass peak, px.
    pub y: usize,
    /// Band-pass response at the peak, grey levels.
    pub peak: f32,
    /// Area of the blob (its pixels at least half way from the local background to the peak)
    /// divided by the candidates it holds, px².
    pub area: f64,
    /// Area of the connected component of the smoothed signal above `MASK_SIGMAS` times its
    /// noise that holds the peak, divided by the candidates in it, px²: how far the blob
    /// stands out of the noise (a noise peak barely does; a particle's skirt does too).
    pub extent: f64,
    /// Returns true if and only if the component that gives [`Blob::extent`] holds no other
    /// candidate and stays off the image border: the extent is this blob's own. (Under an
    /// uneven light the signal against a constant level is offset over whole regions of the
    /// frame, and a blob's component there is that region, shared and cut by the border.)
    pub extent_own: bool,
    /// Returns true if and only if the blob touches the image border.
    pub at_border: bool,
}

/// Blobs found in one frame, with the ones rejected for their size counted.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct BlobSet {
    /// Accepted blobs, strongest first.
    pub blobs: Vec<Blob>,
    /// Candidates rejected as parts of objects much larger than a particle.
    pub too_large_count: usize,
    /// Candidates rejected as much smaller than a particle.
    pub too_small_count: usize,
}
