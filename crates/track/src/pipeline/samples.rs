//! Sample frames: loading, size checks and the moving blobs among them.

use super::finder::{Finder, Workers};
use super::skirts::locate_unfiltered;
use crate::point_grid::PointGrid;
use crate::{Background, DecodedFrame, FrameSource, FrameView, TrackError};
use rayon::prelude::*;
use std::path::Path;

/// Loads up to `count` frames of `source` spread evenly over `numbers` (frame numbers), with
/// the `workers`' decoders; returns their indices into `numbers` and the decoded frames.
pub(super) fn load_sample(
    source: &FrameSource,
    numbers: &[usize],
    count: usize,
    workers: &Workers,
) -> Result<(Vec<usize>, Vec<DecodedFrame>), TrackError> {
    let n = numbers.len();
    let picks: Vec<usize> = if n <= count {
        (0..n).collect()
    } else {
        let mut v: Vec<usize> = (0..count).map(|i| i * (n - 1) / (count - 1)).collect();
        v.dedup();
        v
    };
    // The decoders' buffers are reused from frame to frame (a fresh decoder per rayon job
    // paged its buffers in again for every few frames).
    let frames = picks
        .par_iter()
        .map(|&i| workers.with(|w| source.load_decoded(numbers[i], &mut w.decoder)))
        .collect::<Result<Vec<_>, _>>()?;
    Ok((picks, frames))
}

/// The sample frames as the estimates read them (8-bit grey files as their bytes).
pub(super) fn views(frames: &[DecodedFrame]) -> Vec<FrameView<'_>> {
    frames.iter().map(DecodedFrame::view).collect()
}

pub(super) fn check_size<'a>(
    path: &Path,
    frame: impl Into<FrameView<'a>>,
    reference: &Path,
    size: (usize, usize),
) -> Result<(), TrackError> {
    let (found_width, found_height) = frame.into().size();
    if (found_width, found_height) == size {
        return Ok(());
    }
    Err(TrackError::FrameSize {
        path: path.to_path_buf(),
        first: reference
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default(),
        width: size.0,
        height: size.1,
        found_width,
        found_height,
    })
}

/// The blobs of the first of three consecutive `frames` that move steadily: each has a blob
/// in the next frame more than half a pixel away (a speck of static texture stays put), and
/// the frame after holds a blob within a pixel, or a tenth of the step, of where constant
/// velocity puts it (a speck flickering in and out of the band-pass does not chain over
/// three frames). Blobs are found at `radius` (px) with no size rejection and located by
/// their centroids: their peaks' whole pixels judged a slowly rolling ball static at one
/// radius and moving at the next. Positions in the first frame, px; empty when nothing
/// moves.
pub(super) fn moving_blobs(
    background: &Background,
    frames: [FrameView<'_>; 3],
    radius: f64,
    finder: &mut Finder,
) -> Vec<[f64; 2]> {
    let [a, b, c] = frames.map(|frame| -> Vec<[f64; 2]> {
        locate_unfiltered(background, frame, radius, finder)
            .iter()
            .map(|d| [d.x, d.y])
            .collect()
    });
    let later = [b, c];
    if later.iter().any(|pts| pts.is_empty()) {
        return Vec::new();
    }
    let (tb, tc) = (PointGrid::new(&later[0]), PointGrid::new(&later[1]));
    a.into_iter()
        .filter(|p| {
            let Some((j, d)) = tb.nearest_two(p)[0] else {
                return false;
            };
            let b = later[0][j];
            let step = d.sqrt();
            if step <= 0.5 {
                return false;
            }
            let predicted = [2.0 * b[0] - p[0], 2.0 * b[1] - p[1]];
            tc.nearest_two(&predicted)[0].is_some_and(|(_, d)| d.sqrt() <= (0.1 * step).max(1.0))
        })
        .collect()
}
