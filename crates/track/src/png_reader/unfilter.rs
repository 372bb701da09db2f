//! Reversing PNG's per-row filters (PNG specification, section 9) for 8-bit samples.
//!
//! Each filtered row is a filter-type byte and the row's bytes, each stored as its difference
//! from a prediction made of already decoded bytes: the byte `bpp` to the left (`a`), the
//! byte above (`b`) and the byte above that one's left (`c`), all zero outside the image.
//! Encoders pick the Average (`(a + b) / 2`) or Paeth filter for most rows of a noisy frame,
//! and with one byte per pixel each byte then waits for the one before it: decoded a row at
//! a time, a frame is a chain of 262 144 dependent additions at 512 x 512.
//!
//! Sixteen rows are therefore decoded together, as a wavefront: at step `s` row `j` of the
//! group decodes its byte `s - j`, whose left neighbour was decoded `bpp` steps earlier in
//! the same row and whose upper neighbours one step earlier in the row above. The sixteen
//! bytes of a step are one vector, so the chain is one vector operation per step for all
//! sixteen rows, whatever filter each row uses. The rows go in and out of this skewed,
//! column-major order sixteen steps at a time, by 16 x 16 byte transposes.

/// Filter types (PNG specification, section 9.2).
const NONE: u8 = 0;
const SUB: u8 = 1;
const UP: u8 = 2;
const AVERAGE: u8 = 3;
const PAETH: u8 = 4;

/// Rows decoded together by the wavefront.
const LANES: usize = 16;

/// Zero bytes kept before (and after) each padded row of the wavefront's buffers.
const PAD: usize = LANES;

/// A filtered row whose filter-type byte is not one of PNG's five: the row (0-based) and the
/// byte.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct BadFilter {
    pub row: usize,
    pub kind: u8,
}

/// Reusable buffers of [`unfilter`]: a group's rows copied between zero pads, and the row
/// above the group.
#[derive(Debug, Default)]
pub(crate) struct Scratch {
    rows_in: Vec<u8>,
    rows_out: Vec<u8>,
    above: Vec<u8>,
}

/// Decodes the filtered image `filtered` (`out.len() / row` rows, each a filter-type byte and
/// `row` bytes) into `out` (the rows' bytes, back to back), with `bpp` bytes per pixel
/// (1 to 4). Errs with the first row whose filter type is unknown.
pub(crate) fn unfilter(
    filtered: &[u8],
    row: usize,
    bpp: usize,
    out: &mut [u8],
    scratch: &mut Scratch,
) -> Result<(), BadFilter> {
    assert!((1..=4).contains(&bpp), "bytes per pixel out of range");
    if row == 0 {
        return Ok(());
    }
    let rows = out.len() / row;
    assert!(filtered.len() >= rows * (row + 1), "filtered image too short");
    if let Some(bad) = (0..rows).find(|&y| filtered[y * (row + 1)] > PAETH) {
        return Err(BadFilter {
            row: bad,
            kind: filtered[bad * (row + 1)],
        });
    }
    // SAFETY: SSE2 is part of the x86_64 baseline; the groups' rows lie within both slices
    // (checked above) and every filter type is known.
    #[cfg(target_arch = "x86_64")]
    let done = unsafe {
        let groups = rows / LANES;
        match bpp {
            1 => wavefront_sse2::<1>(filtered, row, out, groups, scratch),
            2 => wavefront_sse2::<2>(filtered, row, out, groups, scratch),
            3 => wavefront_sse2::<3>(filtered, row, out, groups, scratch),
            _ => wavefront_sse2::<4>(filtered, row, out, groups, scratch),
        }
    };
    #[cfg(not(target_arch = "x86_64"))]
    let done = {
        let _ = scratch;
        0
    };
    for y in done..rows {
        let (above, rest) = out.split_at_mut(y * row);
        let prev = (y > 0).then(|| &above[(y - 1) * row..]);
        let line = &filtered[y * (row + 1)..(y + 1) * (row + 1)];
        unfilter_row(line[0], &line[1..], prev, bpp, &mut rest[..row]);
    }
    Ok(())
}

/// One row decoded byte after byte: `kind` is its filter type (known), `raw` its filtered
/// bytes, `prev` the decoded row above (none for the first row).
fn unfilter_row(kind: u8, raw: &[u8], prev: Option<&[u8]>, bpp: usize, out: &mut [u8]) {
    let up = |x: usize| prev.map_or(0, |p| p[x]);
    for x in 0..raw.len() {
        let a = if x >= bpp { out[x - bpp] } else { 0 };
        let c = if x >= bpp { up(x - bpp) } else { 0 };
        let b = up(x);
        let prediction = match kind {
            NONE => 0,
            SUB => a,
            UP => b,
            AVERAGE => ((u16::from(a) + u16::from(b)) / 2) as u8,
            _ => paeth(a, b, c),
        };
        out[x] = raw[x].wrapping_add(prediction);
    }
}

/// The Paeth predictor: of `a`, `b` and `c`, the one nearest to `a + b - c` (ties to `a`,
/// then `b`).
fn paeth(a: u8, b: u8, c: u8) -> u8 {
    let (a16, b16, c16) = (i16::from(a), i16::from(b), i16::from(c));
    let pa = (b16 - c16).abs();
    let pb = (a16 - c16).abs();
    let pc = (a16 + b16 - 2 * c16).abs();
    if pa <= pb && pa <= pc {
        a
    } else if pb <= pc {
        b
    } else {
        c
    }
}

/// Decodes the first `groups` groups of [`LANES`] rows as wavefronts (see the module doc),
/// with `BPP` bytes per pixel, returning the rows done.
///
/// # Safety
/// The CPU must have SSE2 (every x86_64 does); `filtered` holds at least
/// `groups * LANES` filtered rows of `row + 1` bytes, `out` as many rows of `row` bytes, and
/// every filter type among them is at most [`PAETH`].
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "sse2")]
unsafe fn wavefront_sse2<const BPP: usize>(
    filtered: &[u8],
    row: usize,
    out: &mut [u8],
    groups: usize,
    scratch: &mut Scratch,
) -> usize {
    use std::arch::x86_64::{
        __m128i, _mm_add_epi8, _mm_and_si128, _mm_andnot_si128, _mm_avg_epu8, _mm_cmpeq_epi8,
        _mm_cvtsi32_si128, _mm_loadu_si128, _mm_or_si128, _mm_set1_epi8, _mm_setzero_si128, _mm_slli_si128,
        _mm_storeu_si128, _mm_sub_epi8, _mm_xor_si128,
    };
    if groups == 0 {
        return 0;
    }
    // Steps a group takes: row j decodes byte s - j at step s, so the last row ends at
    // step row + LANES - 2; whole blocks of LANES steps.
    let blocks = (row + LANES - 1).div_ceil(LANES);
    // Each padded row: PAD zeros, the row, then room for the last block's reach.
    let stride = PAD + blocks * LANES + PAD;
    let Scratch {
        rows_in,
        rows_out,
        above,
    } = scratch;
    rows_in.clear();
    rows_in.resize(LANES * stride, 0);
    rows_out.clear();
    rows_out.resize(LANES * stride, 0);
    above.clear();
    above.resize(stride, 0);
    let one = _mm_set1_epi8(1);
    for g in 0..groups {
        let y0 = g * LANES;
        let mut kinds = [0u8; LANES];
        for (j, kind) in kinds.iter_mut().enumerate() {
            let line = &filtered[(y0 + j) * (row + 1)..(y0 + j + 1) * (row + 1)];
            *kind = line[0];
            rows_in[j * stride + PAD..j * stride + PAD + row].copy_from_slice(&line[1..]);
        }
        // SAFETY: `kinds` holds LANES bytes.
        let kinds_v = unsafe { _mm_loadu_si128(kinds.as_ptr().cast::<__m128i>()) };
        let is = |k: u8| _mm_cmpeq_epi8(kinds_v, _mm_set1_epi8(k as i8));
        let (m_sub, m_up, m_avg, m_paeth) = (is(SUB), is(UP), is(AVERAGE), is(PAETH));
        let any_paeth = kinds.contains(&PAETH);
        // The decoded bytes of the last BPP steps, oldest first (the left neighbours of this
        // step's), and the bytes above them.
        let mut decoded = [_mm_setzero_si128(); BPP];
        let mut upper = [_mm_setzero_si128(); BPP];
        for b in 0..blocks {
            let s0 = b * LANES;
            // Row j's bytes s0 - j .. s0 - j + 16, turned into step s0 + t's bytes.
            let mut block = [_mm_setzero_si128(); LANES];
            for (j, v) in block.iter_mut().enumerate() {
                // SAFETY: PAD + s0 - j + 16 <= stride - PAD + 16 - j <= stride (j >= 0).
                *v = unsafe {
                    _mm_loadu_si128(rows_in.as_ptr().add(j * stride + PAD + s0 - j).cast::<__m128i>())
                };
            }
            transpose_16x16(&mut block);
            for (t, v) in block.iter_mut().enumerate() {
                // Row j's byte above is the byte row j - 1 decoded one step ago; the first
                // row's comes from the row above the group.
                let from_above = _mm_cvtsi32_si128(i32::from(above[PAD + s0 + t]));
                let b_above = _mm_or_si128(_mm_slli_si128::<1>(decoded[BPP - 1]), from_above);
                let (a_left, c_upper_left) = (decoded[0], upper[0]);
                let mut prediction = _mm_or_si128(_mm_and_si128(m_sub, a_left), _mm_and_si128(m_up, b_above));
                // floor((a + b) / 2): the rounded-up average less the lost half.
                let average = _mm_sub_epi8(
                    _mm_avg_epu8(a_left, b_above),
                    _mm_and_si128(_mm_xor_si128(a_left, b_above), one),
                );
                prediction = _mm_or_si128(prediction, _mm_and_si128(m_avg, average));
                if any_paeth {
                    let p = paeth_sse2(a_left, b_above, c_upper_left);
                    prediction =
                        _mm_or_si128(_mm_andnot_si128(m_paeth, prediction), _mm_and_si128(m_paeth, p));
                }
                let value = _mm_add_epi8(*v, prediction);
                decoded.copy_within(1.., 0);
                upper.copy_within(1.., 0);
                decoded[BPP - 1] = value;
                upper[BPP - 1] = b_above;
                *v = value;
            }
            transpose_16x16(&mut block);
            for (j, v) in block.iter().enumerate() {
                // SAFETY: as for the loads.
                unsafe {
                    _mm_storeu_si128(
                        rows_out
                            .as_mut_ptr()
                            .add(j * stride + PAD + s0 - j)
                            .cast::<__m128i>(),
                        *v,
                    )
                };
            }
        }
        for j in 0..LANES {
            let decoded_row = &rows_out[j * stride + PAD..j * stride + PAD + row];
            out[(y0 + j) * row..(y0 + j + 1) * row].copy_from_slice(decoded_row);
        }
        above[PAD..PAD + row].copy_from_slice(&out[(y0 + LANES - 1) * row..(y0 + LANES) * row]);
    }
    groups * LANES
}

/// The Paeth predictor of sixteen byte triples at once (see [`paeth`]).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "sse2")]
fn paeth_sse2(
    a: std::arch::x86_64::__m128i,
    b: std::arch::x86_64::__m128i,
    c: std::arch::x86_64::__m128i,
) -> std::arch::x86_64::__m128i {
    use std::arch::x86_64::{
        __m128i, _mm_add_epi16, _mm_and_si128, _mm_andnot_si128, _mm_cmpgt_epi16, _mm_max_epi16,
        _mm_or_si128, _mm_packs_epi16, _mm_setzero_si128, _mm_sub_epi16, _mm_unpackhi_epi8,
        _mm_unpacklo_epi8,
    };
    let zero = _mm_setzero_si128();
    let abs = |x: __m128i| _mm_max_epi16(x, _mm_sub_epi16(zero, x));
    // Per half, the masks "a is chosen" and "b is chosen over c", as 16-bit lanes.
    let half = |wide: fn(__m128i, __m128i) -> __m128i| {
        let (a, b, c) = (wide(a, zero), wide(b, zero), wide(c, zero));
        let (bc, ac) = (_mm_sub_epi16(b, c), _mm_sub_epi16(a, c));
        let (pa, pb, pc) = (abs(bc), abs(ac), abs(_mm_add_epi16(bc, ac)));
        let not_a = _mm_or_si128(_mm_cmpgt_epi16(pa, pb), _mm_cmpgt_epi16(pa, pc));
        (not_a, _mm_cmpgt_epi16(pb, pc))
    };
    let (not_a_lo, c_over_b_lo) = half(_mm_unpacklo_epi8);
    let (not_a_hi, c_over_b_hi) = half(_mm_unpackhi_epi8);
    let not_a = _mm_packs_epi16(not_a_lo, not_a_hi);
    let c_over_b = _mm_packs_epi16(c_over_b_lo, c_over_b_hi);
    let b_or_c = _mm_or_si128(_mm_andnot_si128(c_over_b, b), _mm_and_si128(c_over_b, c));
    _mm_or_si128(_mm_andnot_si128(not_a, a), _mm_and_si128(not_a, b_or_c))
}

/// Transposes sixteen vectors of sixteen bytes in place: byte `t` of vector `j` becomes
/// byte `j` of vector `t`.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "sse2")]
fn transpose_16x16(m: &mut [std::arch::x86_64::__m128i; LANES]) {
    use std::arch::x86_64::{
        _mm_unpackhi_epi16, _mm_unpackhi_epi32, _mm_unpackhi_epi64, _mm_unpackhi_epi8, _mm_unpacklo_epi16,
        _mm_unpacklo_epi32, _mm_unpacklo_epi64, _mm_unpacklo_epi8,
    };
    // Four rounds, each interleaving vector pairs half the set apart at twice the width of
    // the last. The rounds alone leave byte j of vector t from source vector
    // `BIT_REVERSED[j]`, so the first round takes its sources in that order.
    const BIT_REVERSED: [usize; LANES] = [0, 8, 4, 12, 2, 10, 6, 14, 1, 9, 5, 13, 3, 11, 7, 15];
    macro_rules! round {
        ($from:expr, $lo:ident, $hi:ident) => {{
            let src = *m;
            for k in 0..LANES / 2 {
                let (a, b) = (src[$from(k)], src[$from(k + LANES / 2)]);
                m[2 * k] = $lo(a, b);
                m[2 * k + 1] = $hi(a, b);
            }
        }};
    }
    round!(|k: usize| BIT_REVERSED[k], _mm_unpacklo_epi8, _mm_unpackhi_epi8);
    round!(|k: usize| k, _mm_unpacklo_epi16, _mm_unpackhi_epi16);
    round!(|k: usize| k, _mm_unpacklo_epi32, _mm_unpackhi_epi32);
    round!(|k: usize| k, _mm_unpacklo_epi64, _mm_unpackhi_epi64);
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    /// The whole image decoded row by row (the reference).
    fn by_rows(filtered: &[u8], row: usize, bpp: usize, rows: usize) -> Vec<u8> {
        let mut out = vec![0u8; rows * row];
        for y in 0..rows {
            let (above, rest) = out.split_at_mut(y * row);
            let prev = (y > 0).then(|| &above[(y - 1) * row..]);
            let line = &filtered[y * (row + 1)..(y + 1) * (row + 1)];
            unfilter_row(line[0], &line[1..], prev, bpp, &mut rest[..row]);
        }
        out
    }

    /// The wavefront decodes random filtered images exactly as the row-by-row loop, for every
    /// filter type (mixed within a group and alone), every pixel size and row lengths and
    /// heights on both sides of the group size.
    #[test]
    fn wavefront_matches_row_by_row_decoding() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        let mut scratch = Scratch::default();
        for bpp in 1..=4 {
            for width in [1, 2, 3, 5, 15, 16, 17, 31, 33, 64, 100] {
                for rows in [1, 15, 16, 17, 40, 64] {
                    for only in [None, Some(AVERAGE), Some(PAETH), Some(SUB)] {
                        let row = width * bpp;
                        let filtered: Vec<u8> = (0..rows * (row + 1))
                            .map(|i| {
                                if i % (row + 1) == 0 {
                                    only.unwrap_or_else(|| rng.gen_range(0..=PAETH))
                                } else {
                                    rng.gen()
                                }
                            })
                            .collect();
                        let mut out = vec![0u8; rows * row];
                        unfilter(&filtered, row, bpp, &mut out, &mut scratch).unwrap();
                        let want = by_rows(&filtered, row, bpp, rows);
                        assert!(
                            out == want,
                            "bpp {bpp}, width {width}, rows {rows}, filter {only:?}: first difference at byte {:?}",
                            out.iter().zip(&want).position(|(a, b)| a != b)
                        );
                    }
                }
            }
        }
    }

    #[cfg(target_arch = "x86_64")]
    #[test]
    fn transpose_moves_byte_t_of_vector_j_to_byte_j_of_vector_t() {
        use std::arch::x86_64::{__m128i, _mm_loadu_si128, _mm_storeu_si128};
        let bytes: Vec<[u8; LANES]> = (0..LANES)
            .map(|j| std::array::from_fn(|t| (j * LANES + t) as u8))
            .collect();
        // SAFETY: each array holds sixteen bytes.
        let mut m: [__m128i; LANES] =
            std::array::from_fn(|j| unsafe { _mm_loadu_si128(bytes[j].as_ptr().cast::<__m128i>()) });
        // SAFETY: SSE2 is part of the x86_64 baseline.
        unsafe { transpose_16x16(&mut m) };
        for (t, v) in m.iter().enumerate() {
            let mut got = [0u8; LANES];
            // SAFETY: as above.
            unsafe { _mm_storeu_si128(got.as_mut_ptr().cast::<__m128i>(), *v) };
            let want: [u8; LANES] = std::array::from_fn(|j| (j * LANES + t) as u8);
            assert_eq!(got, want, "vector {t}");
        }
    }

    #[test]
    fn paeth_predictor_follows_the_specification() {
        // Nearest to a + b - c, ties to a then b.
        assert_eq!(paeth(10, 20, 10), 20);
        assert_eq!(paeth(20, 10, 10), 20);
        assert_eq!(paeth(10, 10, 10), 10);
        assert_eq!(paeth(0, 255, 255), 0);
        assert_eq!(paeth(100, 50, 200), 50);
    }

    #[test]
    fn an_unknown_filter_type_names_its_row() {
        let row = 4;
        let mut filtered = vec![0u8; 20 * (row + 1)];
        filtered[17 * (row + 1)] = 5;
        let mut out = vec![0u8; 20 * row];
        let e = unfilter(&filtered, row, 1, &mut out, &mut Scratch::default()).unwrap_err();
        assert_eq!(e, BadFilter { row: 17, kind: 5 });
    }
}
