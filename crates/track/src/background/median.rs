//! Per-pixel medians over sample frames, and quantiles of levels.

use crate::frames::FrameView;
use rayon::prelude::*;

/// The per-pixel median over `samples` of every value of a frame (channel-interleaved).
pub(super) fn median_image(samples: &[FrameView<'_>]) -> Vec<f32> {
    median_values(samples, samples[0].len(), |v| v)
}

/// The per-pixel median over `samples` at the pixels `picked` (indices into a frame's
/// pixels), channel-interleaved like a frame's data.
pub(super) fn median_at(samples: &[FrameView<'_>], picked: &[usize]) -> Vec<f32> {
    let c = samples[0].channels();
    median_values(samples, picked.len() * c, |v| picked[v / c] * c + v % c)
}

/// `len` medians over `samples`: value `v` is the median of every sample's `data[index(v)]`.
/// 8-bit grey samples are ordered as bytes (the same median).
fn median_values(samples: &[FrameView<'_>], len: usize, index: impl Fn(usize) -> usize + Sync) -> Vec<f32> {
    const CHUNK: usize = 4096;
    let bytes: Option<Vec<&[u8]>> = samples
        .iter()
        .map(|f| match f {
            FrameView::Grey8 { samples, .. } => Some(*samples),
            FrameView::Frame(_) => None,
        })
        .collect();
    let mut out = vec![0.0f32; len];
    out.par_chunks_mut(CHUNK).enumerate().for_each(|(chunk, dst)| {
        let mut buf = vec![0.0f32; samples.len()];
        let mut byte_buf = vec![0u8; samples.len()];
        for (j, d) in dst.iter_mut().enumerate() {
            let i = index(chunk * CHUNK + j);
            *d = match &bytes {
                Some(bytes) => {
                    for (b, f) in byte_buf.iter_mut().zip(bytes) {
                        *b = f[i];
                    }
                    median_of_bytes(&mut byte_buf)
                }
                None => {
                    for (b, f) in buf.iter_mut().zip(samples) {
                        *b = f.value(i);
                    }
                    median_of(&mut buf)
                }
            };
        }
    });
    out
}

/// [`median_of`] of grey levels held as bytes (reordering them), the same value.
pub(super) fn median_of_bytes(v: &mut [u8]) -> f32 {
    let n = v.len();
    let (lower, m, _) = v.select_nth_unstable(n / 2);
    let m = f32::from(*m);
    if n % 2 == 1 {
        m
    } else {
        let lo = lower.iter().copied().max().map_or(f32::NEG_INFINITY, f32::from);
        0.5 * (lo + m)
    }
}

pub(super) fn median_of(v: &mut [f32]) -> f32 {
    let n = v.len();
    let mid = n / 2;
    let (lower, m, _) = v.select_nth_unstable_by(mid, f32::total_cmp);
    let m = *m;
    if n % 2 == 1 {
        m
    } else {
        let lo = lower.iter().copied().fold(f32::NEG_INFINITY, f32::max);
        0.5 * (lo + m)
    }
}

/// The `q` quantile (0..1) of `v`, reordering it; 0 for an empty slice.
pub(crate) fn quantile(v: &mut [f32], q: f64) -> f32 {
    if v.is_empty() {
        return 0.0;
    }
    let i = ((v.len() - 1) as f64 * q).round() as usize;
    *v.select_nth_unstable_by(i, f32::total_cmp).1
}
