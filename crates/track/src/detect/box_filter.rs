//! Streaming box means in fixed point (prefix sums, SSE2 where available).

#[cfg(test)]
use super::signal_rows::Formed;
use super::signal_rows::SignalRows;
use crate::cpu::with_avx2;

/// Pixels in a box of half-width `h` about each position along an axis of `len` pixels
/// (the box clipped by the image edges).
pub(super) fn box_counts(len: usize, h: usize) -> Vec<f64> {
    (0..len)
        .map(|x| ((x + h).min(len - 1) - x.saturating_sub(h) + 1) as f64)
        .collect()
}

/// One output row of a box mean of half-width `h` at row `y`, from the prefix sums `pre` of
/// the row's column sums (fixed point, `unit` per grey level, wrapping); `inv_x` holds
/// 1 / (pixels in the box's row span) per column.
#[inline(always)]
fn box_row(out: &mut [f32], pre: &[i32], inv_x: &[f64], h: usize, y: usize, height: usize, unit: f64) {
    let width = out.len();
    let inv_y = 1.0 / (((y + h).min(height - 1) - y.saturating_sub(h) + 1) as f64 * unit);
    let edge = |x: usize| {
        let (lo, hi) = (x.saturating_sub(h), (x + h).min(width - 1));
        (f64::from(pre[hi + 1].wrapping_sub(pre[lo])) * inv_y * inv_x[x]) as f32
    };
    if 2 * h + 1 > width {
        for (x, o) in out.iter_mut().enumerate() {
            *o = edge(x);
        }
        return;
    }
    // Interior columns hold a full box: one constant factor (vectorised).
    let k = (inv_y / (2 * h + 1) as f64) as f32;
    for ((o, hi), lo) in out[h..width - h].iter_mut().zip(&pre[2 * h + 1..]).zip(pre) {
        *o = hi.wrapping_sub(*lo) as f32 * k;
    }
    for x in (0..h).chain(width - h..width) {
        out[x] = edge(x);
    }
}

/// Running sums of [`box_rows`], kept between frames.
#[derive(Default, Debug)]
pub(crate) struct FilterScratch {
    /// The rows of the image in fixed point (see [`box_rows`]) the boxes about the current
    /// row span, plus one: row `r` at `(r % ring) * width`.
    fixed: Vec<i32>,
    /// Column sums over each filter's rows (one row per filter, fixed point).
    cols: [Vec<i32>; 2],
    /// Prefix sums along the row of each filter's column sums (`width + 1`, fixed point,
    /// wrapping: a difference of two is exact whenever the box's sum fits in an `i32`).
    prefix: [Vec<i32>; 2],
}

/// A bound on a particle signal's magnitude, grey levels: a difference of two 8-bit-scale
/// values projected on a unit colour direction is at most `255 √3`, plus room for the
/// background offsets of clipped noise.
const SIGNAL_BOUND: f32 = 512.0;

/// Fixed-point units per grey level for boxes of `side` pixels square: a power of two (the
/// scaling is exact) no larger than 4096 (rounding each pixel by at most 1/8192 of a level,
/// far below any noise), small enough that no box sum of [`SIGNAL_BOUND`] values overflows
/// an `i32`.
fn fixed_unit(side: usize) -> f32 {
    let room = f64::from(1u32 << 31) / ((side.max(1) as f64).powi(2) * f64::from(SIGNAL_BOUND));
    room.log2().floor().clamp(0.0, 12.0).exp2() as f32
}

/// `image` in fixed point (`unit` per grey level, rounded to nearest, clamped to
/// [`SIGNAL_BOUND`]), into `out` (as long as `image`).
fn to_fixed(image: &[f32], unit: f32, out: &mut [i32]) {
    let bound = SIGNAL_BOUND * unit;
    #[cfg(target_arch = "x86_64")]
    {
        // SAFETY: SSE2 is part of the x86_64 baseline, and `out` is as long as `image`.
        unsafe { to_fixed_sse2(image, unit, bound, out) }
    }
    #[cfg(not(target_arch = "x86_64"))]
    for (o, &v) in out.iter_mut().zip(image) {
        *o = (v * unit).max(-bound).min(bound).round() as i32;
    }
}

/// [`to_fixed`] four pixels at a time (the conversion rounds to nearest, ties to even).
///
/// # Safety
/// The CPU must have SSE2 (every x86_64 does), and `out.len() == image.len()`.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "sse2")]
unsafe fn to_fixed_sse2(image: &[f32], unit: f32, bound: f32, out: &mut [i32]) {
    use std::arch::x86_64::{
        __m128i, _mm_cvtps_epi32, _mm_loadu_ps, _mm_max_ps, _mm_min_ps, _mm_mul_ps, _mm_set1_ps,
        _mm_storeu_si128,
    };
    let n = image.len().min(out.len());
    let chunks = n / 4;
    let (u, hi, lo) = (_mm_set1_ps(unit), _mm_set1_ps(bound), _mm_set1_ps(-bound));
    for c in 0..chunks {
        // SAFETY: elements 4c..4c+4 lie within both slices (4c + 4 <= n).
        let v = unsafe { _mm_loadu_ps(image.as_ptr().add(4 * c)) };
        let x = _mm_min_ps(_mm_max_ps(_mm_mul_ps(v, u), lo), hi);
        unsafe { _mm_storeu_si128(out.as_mut_ptr().add(4 * c).cast::<__m128i>(), _mm_cvtps_epi32(x)) };
    }
    for i in 4 * chunks..n {
        out[i] = (image[i] * unit).max(-bound).min(bound).round() as i32;
    }
}

/// Prefix sums of `col` into `pre[1..=col.len()]`, with `pre[0] = 0`, wrapping.
pub(super) fn prefix_sums(col: &[i32], pre: &mut [i32]) {
    assert!(pre.len() > col.len(), "prefix buffer too short");
    pre[0] = 0;
    #[cfg(target_arch = "x86_64")]
    {
        // SAFETY: SSE2 is part of the x86_64 baseline, and `prefix_sums_sse2` reads `col`
        // and writes `pre[1..=col.len()]` only, within the lengths just checked.
        unsafe { prefix_sums_sse2(col, pre) }
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        let mut s = 0i32;
        for (p, c) in pre[1..].iter_mut().zip(col) {
            s = s.wrapping_add(*c);
            *p = s;
        }
    }
}

/// [`prefix_sums`] eight lanes at a time: within each vector of four by two shifted
/// additions, the second vector raised by the first's total, and across pairs by the carried
/// last sum (a serial chain of one addition and one shuffle per eight pixels).
///
/// # Safety
/// The CPU must have SSE2 (every x86_64 does), and `pre.len() > col.len()`.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "sse2")]
unsafe fn prefix_sums_sse2(col: &[i32], pre: &mut [i32]) {
    use std::arch::x86_64::{
        __m128i, _mm_add_epi32, _mm_cvtsi128_si32, _mm_loadu_si128, _mm_setzero_si128, _mm_shuffle_epi32,
        _mm_slli_si128, _mm_storeu_si128,
    };
    let n = col.len();
    let pairs = n / 8;
    let local = |v: __m128i| {
        let v = _mm_add_epi32(v, _mm_slli_si128::<4>(v));
        _mm_add_epi32(v, _mm_slli_si128::<8>(v))
    };
    let mut carry = _mm_setzero_si128();
    for c in 0..pairs {
        // SAFETY: lanes 8c..8c+8 of `col` and 8c+1..8c+9 of `pre` lie within their slices
        // (8c + 8 <= n < pre.len()).
        let (lo, hi) = unsafe {
            (
                _mm_loadu_si128(col.as_ptr().add(8 * c).cast::<__m128i>()),
                _mm_loadu_si128(col.as_ptr().add(8 * c + 4).cast::<__m128i>()),
            )
        };
        let lo = local(lo);
        let hi = _mm_add_epi32(local(hi), _mm_shuffle_epi32::<0xFF>(lo));
        let (lo, hi) = (_mm_add_epi32(lo, carry), _mm_add_epi32(hi, carry));
        unsafe {
            _mm_storeu_si128(pre.as_mut_ptr().add(1 + 8 * c).cast::<__m128i>(), lo);
            _mm_storeu_si128(pre.as_mut_ptr().add(5 + 8 * c).cast::<__m128i>(), hi);
        }
        carry = _mm_shuffle_epi32::<0xFF>(hi);
    }
    let mut s = _mm_cvtsi128_si32(carry);
    for x in 8 * pairs..n {
        s = s.wrapping_add(col[x]);
        pre[x + 1] = s;
    }
}

/// Box means of sides `2 h + 1` for two half-widths `h` (pixels outside the image are left
/// out of each mean), whole images.
#[cfg(test)]
pub(super) fn box_means(image: &[f32], width: usize, height: usize, halves: [usize; 2]) -> [Vec<f32>; 2] {
    let (mut a, mut b) = (vec![0.0; width * height], vec![0.0; width * height]);
    let mut rows = Formed { signal: image, width };
    box_rows(
        &mut rows,
        width,
        height,
        halves,
        &mut FilterScratch::default(),
        [&mut a, &mut b],
        |_, _, _| {},
    );
    [a, b]
}

/// Box means of sides `2 h + 1` for two half-widths `h` (pixels outside the image are left
/// out of each mean), row after row: the first written into `out_a` (`width * height`), the
/// second into `out_b` as a ring of its `out_b.len() / width` rows (row `y` at
/// `y % rows`; the whole image when it holds `height` rows). After each row `y`,
/// `emit(y, a, b)` with `a` the rows of `out_a` written so far (up to row `y`) and `b` the
/// ring.
///
/// Separable and streaming: each output row adds the entering image row to a running column
/// sum and subtracts the leaving one (vectorised across the row), then takes differences of
/// a prefix sum along the row. The sums are exact integers on the image rounded to fixed
/// point ([`fixed_unit`]), so the running column sums never drift and the prefix sums may
/// wrap (their differences, the box sums, fit); the prefix sums are formed four lanes at a
/// time, carried once per eight ([`prefix_sums`]). Only the rows the boxes span are held in
/// fixed point, so the whole pass stays in cache; the image's rows are asked of `image` as
/// the boxes reach them.
pub(super) fn box_rows(
    image: &mut impl SignalRows,
    width: usize,
    height: usize,
    halves: [usize; 2],
    scratch: &mut FilterScratch,
    outs: [&mut [f32]; 2],
    mut emit: impl FnMut(usize, &[f32], &[f32]),
) {
    let [out_a, out_b] = outs;
    let rows_b = (out_b.len() / width.max(1)).max(1);
    let reach = halves[0].max(halves[1]);
    let unit = fixed_unit(2 * reach + 1);
    // Rows y - reach - 1 to y + reach are needed at row y.
    let ring = 2 * reach + 2;
    let FilterScratch {
        fixed,
        cols: [col_a, col_b],
        prefix: [pre_a, pre_b],
    } = scratch;
    // Every element is written before it is read: the buffers are only sized.
    fixed.resize(ring * width, 0);
    let mut convert = |fixed: &mut [i32], r: usize| {
        let slot = (r % ring) * width;
        to_fixed(image.row(r), unit, &mut fixed[slot..slot + width]);
    };
    for r in 0..reach.min(height) {
        convert(fixed, r);
    }
    for (col, pre, &h) in [
        (&mut *col_a, &mut *pre_a, &halves[0]),
        (&mut *col_b, &mut *pre_b, &halves[1]),
    ] {
        col.clear();
        col.resize(width, 0);
        pre.clear();
        pre.resize(width + 1, 0);
        for r in 0..h.min(height) {
            for (c, v) in col.iter_mut().zip(&fixed[(r % ring) * width..]) {
                *c = c.wrapping_add(*v);
            }
        }
    }
    let inv_x: [Vec<f64>; 2] = halves.map(|h| box_counts(width, h).iter().map(|c| 1.0 / c).collect());
    let fixed_row = |r: usize| (r % ring) * width..(r % ring + 1) * width;
    let unit = f64::from(unit);
    for y in 0..height {
        if y + reach < height {
            convert(fixed, y + reach);
        }
        // The running sums and the rows' box means, compiled for AVX2 where the CPU has it.
        with_avx2(|| {
            for (col, &h) in [(&mut *col_a, &halves[0]), (&mut *col_b, &halves[1])] {
                if y + h < height {
                    let add = &fixed[fixed_row(y + h)];
                    if y > h {
                        let sub = &fixed[fixed_row(y - h - 1)];
                        for ((c, a), s) in col.iter_mut().zip(add).zip(sub) {
                            *c = c.wrapping_add(a.wrapping_sub(*s));
                        }
                    } else {
                        for (c, a) in col.iter_mut().zip(add) {
                            *c = c.wrapping_add(*a);
                        }
                    }
                } else if y > h {
                    let sub = &fixed[fixed_row(y - h - 1)];
                    for (c, s) in col.iter_mut().zip(sub) {
                        *c = c.wrapping_sub(*s);
                    }
                }
            }
            prefix_sums(col_a, pre_a);
            prefix_sums(col_b, pre_b);
            box_row(
                &mut out_a[y * width..(y + 1) * width],
                pre_a,
                &inv_x[0],
                halves[0],
                y,
                height,
                unit,
            );
            let slot = (y % rows_b) * width;
            box_row(
                &mut out_b[slot..slot + width],
                pre_b,
                &inv_x[1],
                halves[1],
                y,
                height,
                unit,
            );
        });
        emit(y, &out_a[..(y + 1) * width], out_b);
    }
}
