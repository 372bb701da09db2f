//! Limits on a frame file's declared size, checked from its header before any of its samples
//! are allocated: a file of a few bytes can claim billions of pixels.
//!
//! A key design decision made here is that the limits are process-wide settings
//! ([`set_frame_limits`]) rather than a field of every decoder: frames are decoded in many places
//! of the pipeline (background samples, size estimates, the locate pass), and a limit that one
//! path forgot would be no limit. The binary sets them once from its command line.

use std::path::Path;
use std::sync::atomic::{AtomicU64, Ordering};

use crate::TrackError;

/// Largest frame decoded by default, megapixels (width x height / 10^6): 50 Mpx, above
/// 8K video (33 Mpx). Its samples take 200 MB as `f32` grey, 600 MB as `f32` colour.
pub const DEFAULT_MAX_MEGAPIXELS: f64 = 50.0;

/// Largest decompression ratio by default: decoded sample bytes per byte of the file. Deflate
/// (PNG) cannot exceed 1032:1 and a baseline JPEG stays below a few hundred to one, so a file
/// beyond 2000:1 declares a size its data cannot hold.
pub const DEFAULT_MAX_DECOMPRESSION_RATIO: f64 = 2000.0;

/// Limits on the frames a decoder takes on.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FrameLimits {
    /// Largest frame, megapixels (width x height / 10^6).
    pub max_megapixels: f64,
    /// Largest ratio of decoded sample bytes to file bytes.
    pub max_decompression_ratio: f64,
}

impl Default for FrameLimits {
    fn default() -> FrameLimits {
        FrameLimits {
            max_megapixels: DEFAULT_MAX_MEGAPIXELS,
            max_decompression_ratio: DEFAULT_MAX_DECOMPRESSION_RATIO,
        }
    }
}

/// The limits' bits; zero stands for "not set" (the defaults), as no limit is zero.
static MAX_MEGAPIXELS: AtomicU64 = AtomicU64::new(0);
static MAX_RATIO: AtomicU64 = AtomicU64::new(0);

/// Sets the limits every frame decoder of this process applies from now on.
pub fn set_frame_limits(limits: FrameLimits) {
    MAX_MEGAPIXELS.store(limits.max_megapixels.to_bits(), Ordering::Relaxed);
    MAX_RATIO.store(limits.max_decompression_ratio.to_bits(), Ordering::Relaxed);
}

/// The limits in force ([`FrameLimits::default`] unless [`set_frame_limits`] was called).
pub fn frame_limits() -> FrameLimits {
    let read = |a: &AtomicU64, default: f64| match a.load(Ordering::Relaxed) {
        0 => default,
        bits => f64::from_bits(bits),
    };
    FrameLimits {
        max_megapixels: read(&MAX_MEGAPIXELS, DEFAULT_MAX_MEGAPIXELS),
        max_decompression_ratio: read(&MAX_RATIO, DEFAULT_MAX_DECOMPRESSION_RATIO),
    }
}

/// Checks the size a frame file `path` of `file_bytes` bytes declares, `width` x `height` px of
/// `decoded_bytes` sample bytes, against [`frame_limits`]: [`TrackError::FrameLimit`] naming the
/// limit and the value seen when it is above.
pub(crate) fn check_frame_size(
    path: &Path,
    (width, height): (u64, u64),
    decoded_bytes: u64,
    file_bytes: u64,
) -> Result<(), TrackError> {
    let limits = frame_limits();
    let megapixels = width as f64 * height as f64 / 1e6;
    if megapixels > limits.max_megapixels {
        return Err(TrackError::FrameLimit {
            path: path.to_path_buf(),
            limit: "frame-megapixels",
            message: format!(
                "the file declares {width}x{height} px = {megapixels:.0} megapixels, above the \
                 `frame-megapixels` limit of {} megapixels",
                limits.max_megapixels
            ),
        });
    }
    let ratio = decoded_bytes as f64 / file_bytes.max(1) as f64;
    if ratio > limits.max_decompression_ratio {
        return Err(TrackError::FrameLimit {
            path: path.to_path_buf(),
            limit: "decompression-ratio",
            message: format!(
                "the file's {file_bytes} bytes declare {width}x{height} px = {decoded_bytes} bytes \
                 of samples, a decompression ratio of {ratio:.0}, above the `decompression-ratio` limit of {}",
                limits.max_decompression_ratio
            ),
        });
    }
    Ok(())
}
