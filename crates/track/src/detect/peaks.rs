//! Candidate peaks: the quick row tests (SSE2 where available) and the local-maximum test.

use super::find::CHUNK;

/// A local maximum of the band-pass response: where, and how strong.
#[derive(Clone, Copy, Debug)]
pub(super) struct Peak {
    /// Band-pass response (small minus large box mean), grey levels.
    pub(super) band: f32,
    /// Large box mean (the local background), grey levels.
    pub(super) large: f32,
    /// Column, px.
    pub(super) x: u32,
    /// Row, px.
    pub(super) y: u32,
}

/// The tests a pixel of a band-pass row must pass before the full local-maximum test: above
/// the peak threshold, its smoothed signal above the noise mask, and not below either row
/// neighbour (strictly above the left one, at least the right one).
pub(super) struct RowTest<'a> {
    /// The row's band-pass response, grey levels.
    pub(super) band: &'a [f32],
    /// The row's small box mean, grey levels.
    pub(super) small: &'a [f32],
    /// The row's noise-mask threshold of each column, grey levels.
    pub(super) mask: &'a [f32],
    /// The interior peak threshold, grey levels.
    pub(super) peak_min: f32,
}

impl RowTest<'_> {
    /// Bit `x - x0` set for each pixel `x` of `x0..x1` (at most 32 of them) that passes.
    pub(super) fn candidates(&self, x0: usize, x1: usize) -> u32 {
        #[cfg(target_arch = "x86_64")]
        if x1 == x0 + CHUNK && x0 > 0 && x1 < self.band.len() {
            // SAFETY: SSE2 is part of the x86_64 baseline; the chunk and both its neighbours
            // lie inside the row, as checked.
            return unsafe { self.candidates_sse2(x0) };
        }
        self.candidates_portable(x0, x1)
    }

    /// [`RowTest::candidates`] pixel by pixel.
    pub(super) fn candidates_portable(&self, x0: usize, x1: usize) -> u32 {
        let (band, width) = (self.band, self.band.len());
        (x0..x1).fold(0u32, |bits, x| {
            let v = band[x];
            let fails = v <= self.peak_min
                || self.small[x] <= self.mask[x]
                || (x > 0 && band[x - 1] >= v)
                || (x + 1 < width && band[x + 1] > v);
            let pass = !fails;
            bits | (u32::from(pass) << (x - x0))
        })
    }

    /// [`RowTest::candidates`] for the [`CHUNK`] pixels from `x0`, four at a time, with the
    /// same comparisons (each as its negation, so a NaN fails as it does pixel by pixel).
    ///
    /// # Safety
    /// The CPU must have SSE2, `x0 > 0` and `x0 + CHUNK < band.len()`, and `small` and `mask`
    /// as long as `band`.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "sse2")]
    unsafe fn candidates_sse2(&self, x0: usize) -> u32 {
        use std::arch::x86_64::{
            _mm_and_ps, _mm_cmpnge_ps, _mm_cmpngt_ps, _mm_cmpnle_ps, _mm_loadu_ps, _mm_movemask_ps,
            _mm_set1_ps,
        };
        let n = self.band.len().min(self.small.len()).min(self.mask.len());
        assert!(x0 > 0 && x0 + CHUNK < n, "chunk at {x0} of {n}");
        let mut bits = 0u32;
        // SAFETY: the loads read band[x - 1 ..= x + 4] and small, mask[x .. x + 4] for
        // x0 <= x < x0 + CHUNK, inside the slices by the assertion.
        unsafe {
            let peak_min = _mm_set1_ps(self.peak_min);
            for k in (0..CHUNK).step_by(4) {
                let at = x0 + k;
                let v = _mm_loadu_ps(self.band.as_ptr().add(at));
                let left = _mm_loadu_ps(self.band.as_ptr().add(at - 1));
                let right = _mm_loadu_ps(self.band.as_ptr().add(at + 1));
                let mask = _mm_loadu_ps(self.mask.as_ptr().add(at));
                let pass = _mm_and_ps(
                    _mm_and_ps(
                        _mm_cmpnle_ps(v, peak_min),
                        _mm_cmpnle_ps(_mm_loadu_ps(self.small.as_ptr().add(at)), mask),
                    ),
                    _mm_and_ps(_mm_cmpnge_ps(left, v), _mm_cmpngt_ps(right, v)),
                );
                bits |= (_mm_movemask_ps(pass) as u32) << k;
            }
        }
        bits
    }
}

/// Returns true if and only if some value of `line` exceeds `t`.
pub(super) fn any_above(line: &[f32], t: f32) -> bool {
    line.iter().fold(false, |any, v| any | (*v > t))
}

/// Bit `k` set if and only if `line[k]` exceeds `thresholds[k]`, for the first 64 values at
/// most (higher bits clear).
pub(super) fn above_bits(line: &[f32], thresholds: &[f32]) -> u64 {
    #[cfg(target_arch = "x86_64")]
    // SAFETY: SSE2 is part of the x86_64 baseline.
    unsafe {
        above_bits_sse2(line, thresholds)
    }
    #[cfg(not(target_arch = "x86_64"))]
    above_bits_portable(line, thresholds)
}

/// [`above_bits`] in plain Rust.
#[cfg(any(test, not(target_arch = "x86_64")))]
pub(super) fn above_bits_portable(line: &[f32], thresholds: &[f32]) -> u64 {
    line.iter()
        .zip(thresholds)
        .take(64)
        .enumerate()
        .fold(0u64, |bits, (k, (v, t))| bits | (u64::from(v > t) << k))
}

/// [`above_bits`] sixteen values at a time (four compares narrowed to one byte mask), the
/// last few one by one: as fast as the chunked test it replaced on background, and a run of pixels
/// above the mask is then two bit scans instead of a loop over its pixels.
///
/// # Safety
/// The CPU must have SSE2 (every x86_64 does).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "sse2")]
unsafe fn above_bits_sse2(line: &[f32], thresholds: &[f32]) -> u64 {
    use std::arch::x86_64::{
        __m128i, _mm_castps_si128, _mm_cmpgt_ps, _mm_loadu_ps, _mm_movemask_epi8, _mm_packs_epi16,
        _mm_packs_epi32,
    };
    let n = line.len().min(thresholds.len()).min(64);
    let whole = n / 16 * 16;
    let mut bits = 0u64;
    // SAFETY: every load reads values k .. k + 4 with k + 4 <= n, within both slices.
    unsafe {
        // All ones in each lane above its threshold, zero elsewhere.
        let above = |k: usize| -> __m128i {
            _mm_castps_si128(_mm_cmpgt_ps(
                _mm_loadu_ps(line.as_ptr().add(k)),
                _mm_loadu_ps(thresholds.as_ptr().add(k)),
            ))
        };
        for k in (0..whole).step_by(16) {
            // Sixteen lane masks narrowed to bytes (saturating packs keep 0 and -1), then
            // one bit each.
            let lo = _mm_packs_epi32(above(k), above(k + 4));
            let hi = _mm_packs_epi32(above(k + 8), above(k + 12));
            let group = _mm_movemask_epi8(_mm_packs_epi16(lo, hi)) as u32 as u64;
            bits |= group << k;
        }
    }
    for k in whole..n {
        bits |= u64::from(line[k] > thresholds[k]) << k;
    }
    bits
}

/// Returns true if and only if the band-pass response `v` at `(x, y)` is a local maximum:
/// strictly above its earlier neighbours in raster order, at least its later ones. `band(yy)`
/// is row `yy` of the response (asked for rows `y - 1` to `y + 1` within the frame).
pub(super) fn is_local_max<'a>(
    band: impl Fn(usize) -> &'a [f32],
    width: usize,
    height: usize,
    x: usize,
    y: usize,
    v: f32,
) -> bool {
    for yy in y.saturating_sub(1)..=(y + 1).min(height - 1) {
        let lo = x.saturating_sub(1);
        for (xx, &w) in band(yy)
            .iter()
            .enumerate()
            .take((x + 1).min(width - 1) + 1)
            .skip(lo)
        {
            if (yy, xx) == (y, x) {
                continue;
            }
            let earlier = yy < y || (yy == y && xx < x);
            if (earlier && w >= v) || (!earlier && w > v) {
                return false;
            }
        }
    }
    true
}
