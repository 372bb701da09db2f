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

use crate::cpu::{prefetch, with_avx2};

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

/// What [`find_blobs`] needs to know.
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

/// Half-width of the matched box filter for particles of radius `radius`, px: a box of
/// the disc's area.
pub fn box_half_width(radius: f64) -> usize {
    (((radius * std::f64::consts::PI.sqrt() - 1.0) / 2.0)
        .round()
        .max(1.0)) as usize
}

/// Standard deviation of the band-pass response to pixel noise of standard deviation
/// `noise_sigma` (grey levels) away from the border, at detector radius `radius` (px): the
/// small box lies inside the large one, so the variance of their difference of means is
/// `sigma^2 (1 / n_small - 1 / n_large)`. Grey levels.
pub fn band_noise(radius: f64, noise_sigma: f64) -> f64 {
    let h = box_half_width(radius);
    let big = 2 * h + 1;
    let n_small = ((2 * h + 1) * (2 * h + 1)) as f64;
    let n_large = ((2 * big + 1) * (2 * big + 1)) as f64;
    noise_sigma * (1.0 / n_small - 1.0 / n_large).sqrt()
}

/// Finds particle-like blobs in a signal image (`width * height`, row-major, grey levels,
/// particles positive). See the module doc for the method.
pub fn find_blobs(signal: &[f32], width: usize, height: usize, params: &DetectParameters) -> BlobSet {
    let mut scratch = Scratch::default();
    find_blobs_with_scratch(signal, width, height, params, &mut scratch)
}

/// Reusable buffers of [`find_blobs_with_scratch`]: the small box mean of the frame, the
/// band-pass response of three rows, the filters' running sums and the labelling's runs.
/// Holding one per worker thread means no frame allocates.
#[derive(Default, Debug)]
pub struct Scratch {
    small: Vec<f32>,
    /// The band-pass response (small minus large box mean) of the last three rows, row `y` at
    /// `(y % 3) * width`.
    band: Vec<f32>,
    /// The large box mean of the same rows, laid out alike.
    large: Vec<f32>,
    filter: FilterScratch,
    peaks: Vec<Peak>,
    kept: Vec<Peak>,
    cell_head: Vec<u32>,
    cell_next: Vec<u32>,
    labels: Labels,
    regions: Regions,
}

/// [`find_blobs`] with reusable buffers (no per-frame allocation of the filtered images).
pub fn find_blobs_with_scratch(
    signal: &[f32],
    width: usize,
    height: usize,
    params: &DetectParameters,
    scratch: &mut Scratch,
) -> BlobSet {
    if signal.len() < width * height {
        return BlobSet::default();
    }
    find_blobs_in_rows(&mut Formed { signal, width }, width, height, params, scratch)
}

/// [`find_blobs_with_scratch`] of the signal `form` writes into `signal` (`width * height`),
/// row by row as the filters reach it: `form(pixels, out)` writes the signal of the pixels
/// `pixels` (one row, row-major indices) into `out`. Each row is then filtered while it is
/// still in cache, instead of the whole image being written first and read back; on
/// return `signal` holds every row.
pub fn find_blobs_forming(
    signal: &mut [f32],
    width: usize,
    height: usize,
    params: &DetectParameters,
    scratch: &mut Scratch,
    form: impl FnMut(std::ops::Range<usize>, &mut [f32]),
) -> BlobSet {
    if signal.len() < width * height {
        return BlobSet::default();
    }
    let mut rows = Forming { signal, width, form };
    find_blobs_in_rows(&mut rows, width, height, params, scratch)
}

/// The rows of a signal image as the filters read them: each row once, in order.
trait SignalRows {
    /// Row `y` (the image's width of values).
    fn row(&mut self, y: usize) -> &[f32];
}

/// A signal image already formed.
struct Formed<'a> {
    signal: &'a [f32],
    width: usize,
}

impl SignalRows for Formed<'_> {
    fn row(&mut self, y: usize) -> &[f32] {
        &self.signal[y * self.width..(y + 1) * self.width]
    }
}

/// A signal image formed a row at a time, when the filters ask for the row.
struct Forming<'a, F> {
    signal: &'a mut [f32],
    width: usize,
    form: F,
}

impl<F: FnMut(std::ops::Range<usize>, &mut [f32])> SignalRows for Forming<'_, F> {
    fn row(&mut self, y: usize) -> &[f32] {
        let pixels = y * self.width..(y + 1) * self.width;
        (self.form)(pixels.clone(), &mut self.signal[pixels.clone()]);
        &self.signal[pixels]
    }
}

/// [`find_blobs_with_scratch`] of the signal rows `signal` hands over.
fn find_blobs_in_rows(
    signal: &mut impl SignalRows,
    width: usize,
    height: usize,
    params: &DetectParameters,
    scratch: &mut Scratch,
) -> BlobSet {
    if width == 0 || height == 0 {
        return BlobSet::default();
    }
    let h = box_half_width(params.radius);
    let big = 2 * h + 1;
    let sigma = params.noise_sigma.max(1e-6);
    // Near the border the boxes hold fewer pixels, so their means are noisier: the noise of
    // each filtered pixel is propagated from its own pixel counts (interior counts give the
    // smallest thresholds, `peak_min` and `mask_t`), otherwise the border sprouts false peaks.
    let count_small_x = box_counts(width, h);
    let count_small_y = box_counts(height, h);
    let count_large_x = box_counts(width, big);
    let count_large_y = box_counts(height, big);
    let band_sigma_at = |x: usize, y: usize| {
        let ns = count_small_x[x] * count_small_y[y];
        let nl = count_large_x[x] * count_large_y[y];
        sigma * (1.0 / ns - 1.0 / nl).max(0.0).sqrt()
    };
    let n_small = ((2 * h + 1) * (2 * h + 1)) as f64;
    let peak_min = (PEAK_SIGMAS * band_noise(params.radius, sigma)) as f32;
    let mask_t = (MASK_SIGMAS * sigma / n_small.sqrt()) as f32;
    // Mask thresholds per column and factors per row: sqrt(full count / count) of the small
    // box.
    let full = (2 * h + 1) as f64;
    let mask = MaskThresholds {
        x: count_small_x
            .iter()
            .map(|&c| mask_t * (full / c).sqrt() as f32)
            .collect(),
        fy: count_small_y.iter().map(|&c| (full / c).sqrt() as f32).collect(),
        h,
    };
    // Pixels farther than this from every edge see full boxes (their thresholds are the
    // interior ones, already applied).
    let margin = big;

    // One pass down the frame: each row's box means are formed, the small one kept (the
    // blobs grow in it), the band-pass response kept for three rows; the row above is then
    // searched for local maxima (it has both neighbours), and the row's mask runs are
    // labelled. Everything a row needs is still in the first-level cache.
    let Scratch {
        small,
        band,
        large,
        filter,
        peaks,
        labels: comps,
        ..
    } = scratch;
    small.resize(width * height, 0.0);
    band.resize(3 * width, 0.0);
    large.resize(3 * width, 0.0);
    // Row `y`'s place in the three-row buffers.
    let ring = |y: usize| (y % 3) * width..(y % 3 + 1) * width;
    peaks.clear();
    comps.begin();
    // Local maxima of the band-pass response in row `y` (strict against earlier neighbours in
    // raster order, non-strict against later ones, so a plateau yields one maximum per row
    // run).
    let mut scan_mask: Vec<f32> = Vec::with_capacity(width);
    let mut scan = |y: usize, band: &[f32], large: &[f32], small: &[f32]| {
        let row = |yy: usize| &band[ring(yy)];
        let (brow, srow) = (row(y), &small[y * width..(y + 1) * width]);
        let row_test = RowTest {
            band: brow,
            small: srow,
            mask: mask.row(y, &mut scan_mask),
            peak_min,
        };
        for x0 in (0..width).step_by(CHUNK) {
            let x1 = (x0 + CHUNK).min(width);
            // Most of a frame is background: a whole chunk is ruled out at once (branch-free,
            // vectorised) before any pixel is looked at alone.
            if !any_above(&brow[x0..x1], peak_min) {
                continue;
            }
            // Most pixels above the threshold sit on a particle's flank: their row neighbours
            // rule them out before the full test, all the chunk's pixels at once.
            let mut bits = row_test.candidates(x0, x1);
            while bits != 0 {
                let x = x0 + bits.trailing_zeros() as usize;
                bits &= bits - 1;
                let v = brow[x];
                let at_edge = x < margin || y < margin || x + margin >= width || y + margin >= height;
                if at_edge && f64::from(v) <= PEAK_SIGMAS * band_sigma_at(x, y) {
                    continue;
                }
                if is_local_max(row, width, height, x, y, v) {
                    peaks.push(Peak {
                        band: v,
                        large: large[ring(y)][x],
                        x: x as u32,
                        y: y as u32,
                    });
                }
            }
        }
    };
    let mut row_mask: Vec<f32> = Vec::with_capacity(width);
    box_rows(
        signal,
        width,
        height,
        [h, big],
        filter,
        [small, large],
        |y, small, large| {
            let s_row = &small[y * width..(y + 1) * width];
            let l_row = &large[ring(y)];
            with_avx2(|| {
                for ((b, s), l) in band[ring(y)].iter_mut().zip(s_row).zip(l_row) {
                    *b = s - l;
                }
            });
            comps.push_row(y, s_row, mask.row(y, &mut row_mask));
            if y > 0 {
                scan(y - 1, band, large, small);
            }
        },
    );
    scan(height - 1, band, large, small);
    comps.finish(width, height);

    // Strongest first.
    peaks.sort_unstable_by(|a, b| b.band.total_cmp(&a.band).then((a.y, a.x).cmp(&(b.y, b.x))));

    // Non-maximum suppression within one radius, on a grid of cells one radius wide (each
    // cell's kept peaks as a linked list through `cell_next`).
    let r_nms = params.radius.max(1.5);
    let cell = r_nms.ceil() as usize;
    let gw = width.div_ceil(cell);
    let gh = height.div_ceil(cell);
    let head = &mut scratch.cell_head;
    head.clear();
    head.resize(gw * gh, u32::MAX);
    let next = &mut scratch.cell_next;
    next.clear();
    let kept = &mut scratch.kept;
    kept.clear();
    let r2 = r_nms * r_nms;
    for &peak in peaks.iter() {
        let (x, y) = (peak.x as usize, peak.y as usize);
        let (cx, cy) = (x / cell, y / cell);
        let mut clash = false;
        'g: for gy in cy.saturating_sub(1)..=(cy + 1).min(gh - 1) {
            for gx in cx.saturating_sub(1)..=(cx + 1).min(gw - 1) {
                let mut k = head[gy * gw + gx];
                while k != u32::MAX {
                    let other = kept[k as usize];
                    let dx = f64::from(other.x) - x as f64;
                    let dy = f64::from(other.y) - y as f64;
                    if dx * dx + dy * dy < r2 {
                        clash = true;
                        break 'g;
                    }
                    k = next[k as usize];
                }
            }
        }
        if !clash {
            let c = cy * gw + cx;
            next.push(head[c]);
            head[c] = kept.len() as u32;
            kept.push(peak);
        }
    }

    // Each candidate's extent: the component of the smoothed signal above the noise mask
    // that holds it, shared among its candidates. A noise peak or a speck of texture barely
    // rises above the mask; a particle stands out of it with its whole skirt.
    let mut seeds_per_comp: Vec<u32> = vec![0; comps.area.len()];
    let labels: Vec<Option<usize>> = kept
        .iter()
        .map(|p| comps.label_at(p.x as usize, p.y as usize))
        .collect();
    for l in labels.iter().flatten() {
        seeds_per_comp[*l] += 1;
    }

    // Each candidate's blob: the pixels connected to it where the smoothed signal is at least
    // half way from the local background (the wide box mean) to the candidate's peak. A
    // candidate already inside a stronger one's blob shares it. Measured against the
    // candidate's own contrast, the blob does not grow with an offset left in the signal (an
    // exposure change, a shadow) nor take in texture at its edge, as a noise-mask component
    // does.
    let regions = &mut scratch.regions;
    let small = &scratch.small[..];
    regions.reset(width * height);
    let cap = ((FLOOD_CAP_AREAS * params.radius * params.radius).ceil() as usize).max(64);
    let mut seeds_per: Vec<u32> = Vec::with_capacity(kept.len());
    let mut in_region: Vec<usize> = Vec::with_capacity(kept.len());
    // Candidates come strongest first, scattered over the frame, and a frame's smoothed
    // signal and region map outgrow the second-level cache: the rows a blob a few candidates
    // ahead will grow over are fetched while this one grows.
    let reach = params.radius.ceil() as usize + 2;
    let fetch_rows = |peak: &Peak, owner: &[u32]| {
        let (x, y) = (peak.x as usize, peak.y as usize);
        for yy in y.saturating_sub(reach)..=(y + reach).min(height - 1) {
            for xx in [x.saturating_sub(reach), (x + reach).min(width - 1)] {
                prefetch(small, yy * width + xx);
                prefetch(owner, yy * width + xx);
            }
        }
    };
    for (k, peak) in kept.iter().enumerate() {
        if let Some(ahead) = kept.get(k + PREFETCH_AHEAD) {
            fetch_rows(ahead, &regions.owner);
        }
        let (x, y) = (peak.x as usize, peak.y as usize);
        let i = y * width + x;
        let region = match regions.region_at(i) {
            Some(r) => r,
            None => {
                let floor = mask.at(x, y);
                let level = (peak.large + 0.5 * peak.band).max(floor);
                let fill = Fill {
                    image: small,
                    width,
                    height,
                    level,
                    cap,
                };
                regions.grow(&fill, i)
            }
        };
        if region >= seeds_per.len() {
            seeds_per.resize(region + 1, 0);
        }
        seeds_per[region] += 1;
        in_region.push(region);
    }

    let mut out = BlobSet::default();
    for ((peak, &region), label) in kept.iter().zip(&in_region).zip(&labels) {
        let seeds = seeds_per[region].max(1);
        let area = regions.area[region] as f64 / f64::from(seeds);
        let at_border = regions.border[region];
        let (extent, extent_at_border) = match label {
            Some(l) => (
                comps.area[*l] as f64 / f64::from(seeds_per_comp[*l].max(1)),
                comps.border[*l],
            ),
            None => (1.0, false),
        };
        if let Some(expected) = params.expected {
            // Judge the whole blob, not its share per seed: a large object (a hand, the
            // edge of a floor) carries several spurious peaks (its corners), which would
            // otherwise divide its area down to a particle's. Touching particles carry one
            // peak each, and their union covers less than the sum of their areas.
            let seeds = f64::from(seeds);
            let limit = if seeds > 1.0 {
                MERGED_AREA_RATIO * expected.area * seeds
            } else {
                MAX_AREA_RATIO * expected.area
            };
            if area * seeds > limit {
                out.too_large_count += 1;
                continue;
            }
            // A particle cut by the border shows the part of its extent inside the frame.
            let visible = if extent_at_border {
                visible_fraction(
                    peak.x as f64,
                    peak.y as f64,
                    (expected.extent / std::f64::consts::PI).sqrt(),
                    width,
                    height,
                )
            } else {
                1.0
            };
            if extent < MIN_AREA_RATIO * expected.extent * visible {
                out.too_small_count += 1;
                continue;
            }
        }
        out.blobs.push(Blob {
            x: peak.x as usize,
            y: peak.y as usize,
            peak: peak.band,
            area,
            extent,
            at_border,
        });
    }
    out
}

/// The fraction of a disc of radius `r` (px) centred at `(x, y)` that lies inside a `width` x
/// `height` frame (pixel centres at integers, so the frame spans -0.5 to width - 0.5), from a
/// 16 x 16 grid of points over the disc's bounding square.
fn visible_fraction(x: f64, y: f64, r: f64, width: usize, height: usize) -> f64 {
    const N: usize = 16;
    let (mut inside, mut all) = (0usize, 0usize);
    for i in 0..N {
        for j in 0..N {
            let px = x - r + (i as f64 + 0.5) * 2.0 * r / N as f64;
            let py = y - r + (j as f64 + 0.5) * 2.0 * r / N as f64;
            if (px - x).powi(2) + (py - y).powi(2) > r * r {
                continue;
            }
            all += 1;
            let within = px >= -0.5 && py >= -0.5 && px <= width as f64 - 0.5 && py <= height as f64 - 0.5;
            inside += usize::from(within);
        }
    }
    if all == 0 {
        1.0
    } else {
        inside as f64 / all as f64
    }
}

/// Pixels tested together by the quick rejections of background.
const CHUNK: usize = 16;

/// How many candidates ahead of the one growing its blob the next blob's pixels are fetched
/// into the cache.
const PREFETCH_AHEAD: usize = 2;

/// The noise-mask thresholds on the small box mean, grey levels: one per column (the box's
/// column count), scaled in the rows near the top and bottom edges (its row count), where the
/// box holds fewer pixels and its mean is noisier.
struct MaskThresholds {
    /// Each column's threshold in a row whose box holds whole columns.
    x: Vec<f32>,
    /// Each row's factor on them (1 away from the top and bottom edges).
    fy: Vec<f32>,
    /// Half-width of the small box, px.
    h: usize,
}

impl MaskThresholds {
    /// The threshold at pixel `(x, y)`.
    fn at(&self, x: usize, y: usize) -> f32 {
        self.x[x] * self.fy[y]
    }

    /// Row `y`'s thresholds: the columns' own where the row factor is 1, else written into
    /// `buf`.
    fn row<'a>(&'a self, y: usize, buf: &'a mut Vec<f32>) -> &'a [f32] {
        if y >= self.h && y + self.h < self.fy.len() {
            return &self.x;
        }
        buf.clear();
        buf.extend(self.x.iter().map(|m| m * self.fy[y]));
        buf
    }
}

/// A local maximum of the band-pass response: where, and how strong.
#[derive(Clone, Copy, Debug)]
struct Peak {
    /// Band-pass response (small minus large box mean), grey levels.
    band: f32,
    /// Large box mean (the local background), grey levels.
    large: f32,
    /// Column, px.
    x: u32,
    /// Row, px.
    y: u32,
}

/// The tests a pixel of a band-pass row must pass before the full local-maximum test: above
/// the peak threshold, its smoothed signal above the noise mask, and not below either row
/// neighbour (strictly above the left one, at least the right one).
struct RowTest<'a> {
    /// The row's band-pass response, grey levels.
    band: &'a [f32],
    /// The row's small box mean, grey levels.
    small: &'a [f32],
    /// The row's noise-mask threshold of each column, grey levels.
    mask: &'a [f32],
    /// The interior peak threshold, grey levels.
    peak_min: f32,
}

impl RowTest<'_> {
    /// Bit `x - x0` set for each pixel `x` of `x0..x1` (at most 32 of them) that passes.
    fn candidates(&self, x0: usize, x1: usize) -> u32 {
        #[cfg(target_arch = "x86_64")]
        if x1 == x0 + CHUNK && x0 > 0 && x1 < self.band.len() {
            // SAFETY: SSE2 is part of the x86_64 baseline; the chunk and both its neighbours
            // lie inside the row, as checked.
            return unsafe { self.candidates_sse2(x0) };
        }
        self.candidates_portable(x0, x1)
    }

    /// [`RowTest::candidates`] pixel by pixel.
    fn candidates_portable(&self, x0: usize, x1: usize) -> u32 {
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
fn any_above(line: &[f32], t: f32) -> bool {
    line.iter().fold(false, |any, v| any | (*v > t))
}

/// Bit `k` set if and only if `line[k]` exceeds `thresholds[k]`, for the first 64 values at
/// most (higher bits clear).
fn above_bits(line: &[f32], thresholds: &[f32]) -> u64 {
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
fn above_bits_portable(line: &[f32], thresholds: &[f32]) -> u64 {
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
fn is_local_max<'a>(
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

/// Connected components (8-connected) of `image > threshold`, stored as row runs, with
/// reusable buffers.
#[derive(Default, Debug)]
struct Labels {
    /// Runs `(x_start, x_end_exclusive, label)`, row after row.
    runs: Vec<(u32, u32, u32)>,
    /// Index of each row's first run in `runs` (`height + 1` entries).
    row_start: Vec<usize>,
    /// Union-find parents of the provisional labels.
    parent: Vec<u32>,
    /// Compact label of each provisional root.
    compact: Vec<u32>,
    /// Pixel count per label.
    area: Vec<usize>,
    /// Whether each label touches the image border.
    border: Vec<bool>,
}

impl Labels {
    fn label_at(&self, x: usize, y: usize) -> Option<usize> {
        let row = &self.runs[*self.row_start.get(y)?..*self.row_start.get(y + 1)?];
        let k = row.partition_point(|r| r.1 as usize <= x);
        row.get(k).filter(|r| r.0 as usize <= x).map(|r| r.2 as usize)
    }

    /// Starts labelling a frame (its rows follow through [`Labels::push_row`]).
    fn begin(&mut self) {
        self.runs.clear();
        self.row_start.clear();
        self.parent.clear();
    }

    /// Adds row `y` (rows come in order from 0): its runs of `line[x] > thresholds[x]`,
    /// joined to the previous row's runs they touch (8-connectivity).
    fn push_row(&mut self, y: usize, line: &[f32], thresholds: &[f32]) {
        let width = line.len();
        let prev_start = self.row_start.last().copied().unwrap_or(0);
        let start_here = self.runs.len();
        self.row_start.push(start_here);
        // The row's pixels above the mask as bits, 64 at a time; each run is then found
        // with two bit scans, not pixel by pixel.
        let mut open: Option<usize> = None;
        for x0 in (0..width).step_by(64) {
            let end = (x0 + 64).min(width);
            let bits = above_bits(&line[x0..end], &thresholds[x0..end]);
            let mut x = x0;
            while x < end {
                let rest = bits >> (x - x0);
                match open {
                    None => {
                        if rest == 0 {
                            break;
                        }
                        x += rest.trailing_zeros() as usize;
                        open = Some(x);
                    }
                    Some(s) => {
                        // Bits past the row's end are clear, so a run reaching it stops there.
                        x = (x + (!rest).trailing_zeros() as usize).min(end);
                        if x < end || end == width {
                            let label = self.parent.len() as u32;
                            self.parent.push(label);
                            self.runs.push((s as u32, x as u32, label));
                            open = None;
                        }
                    }
                }
            }
        }
        if y > 0 {
            // Runs of the previous row overlapping [start - 1, end] (8-connectivity).
            let mut k = prev_start;
            for r in start_here..self.runs.len() {
                let run = self.runs[r];
                while k < start_here && self.runs[k].1 < run.0 {
                    k += 1;
                }
                let mut j = k;
                while j < start_here && self.runs[j].0 <= run.1 {
                    let a = find(&mut self.parent, run.2);
                    let b = find(&mut self.parent, self.runs[j].2);
                    if a != b {
                        self.parent[a.max(b) as usize] = a.min(b);
                    }
                    j += 1;
                }
            }
        }
    }

    /// Ends the frame (`width` x `height`, every row pushed): compact labels, with each
    /// one's area and whether it touches the border.
    fn finish(&mut self, width: usize, height: usize) {
        self.row_start.push(self.runs.len());
        self.compact.clear();
        self.compact.resize(self.parent.len(), u32::MAX);
        self.area.clear();
        self.border.clear();
        for y in 0..height {
            for r in self.row_start[y]..self.row_start[y + 1] {
                let run = self.runs[r];
                let root = find(&mut self.parent, run.2) as usize;
                if self.compact[root] == u32::MAX {
                    self.compact[root] = self.area.len() as u32;
                    self.area.push(0);
                    self.border.push(false);
                }
                let l = self.compact[root];
                self.runs[r].2 = l;
                self.area[l as usize] += (run.1 - run.0) as usize;
                self.border[l as usize] |= run.0 == 0 || run.1 as usize == width || y == 0 || y + 1 == height;
            }
        }
    }
}

/// The root of `a` in the union-find forest `parent`, halving the path on the way.
fn find(parent: &mut [u32], mut a: u32) -> u32 {
    while parent[a as usize] != a {
        let p = parent[parent[a as usize] as usize];
        parent[a as usize] = p;
        a = p;
    }
    a
}

/// The blobs of one frame's candidates, grown by flood fill, with reusable buffers.
#[derive(Default, Debug)]
struct Regions {
    /// Region of each pixel (`u32::MAX`: none).
    owner: Vec<u32>,
    /// Pixels given a region this frame (reset by the next [`Regions::reset`]).
    claimed: Vec<u32>,
    /// Span fill work list: claimed runs (first column, last column, row), whose
    /// neighbouring rows are still to be searched.
    spans: Vec<(u32, u32, u32)>,
    /// Pixel fill work list: pixels as (column, row), so that none is divided by the width.
    stack: Vec<(u32, u32)>,
    /// Pixel count per region.
    area: Vec<usize>,
    /// Whether each region touches the image border.
    border: Vec<bool>,
}

impl Regions {
    /// Forgets every region, for a frame of `pixels` pixels.
    fn reset(&mut self, pixels: usize) {
        if self.owner.len() == pixels {
            for &p in &self.claimed {
                self.owner[p as usize] = u32::MAX;
            }
        } else {
            self.owner.clear();
            self.owner.resize(pixels, u32::MAX);
        }
        self.claimed.clear();
        self.area.clear();
        self.border.clear();
    }

    fn region_at(&self, pixel: usize) -> Option<usize> {
        let r = *self.owner.get(pixel)?;
        (r != u32::MAX).then_some(r as usize)
    }

    /// Whether pixel `q` is free for `fill` to take: unclaimed and at least its level.
    fn open(&self, fill: &Fill<'_>, q: usize) -> bool {
        self.owner[q] == u32::MAX && fill.image[q] >= fill.level
    }

    /// Gives pixel `q` to region `id`.
    fn claim(&mut self, q: usize, id: u32) {
        self.owner[q] = id;
        self.claimed.push(q as u32);
    }

    /// Grows a new region from `seed` over the 8-connected pixels open to `fill`, stopping
    /// after its cap; returns the region's index.
    ///
    /// Span by span: a row's run of such pixels is claimed whole, then the rows above and
    /// below are searched under it (one pixel wider each side, for the diagonals) for runs
    /// to claim next. Each pixel is tested about three times, not nine as when each claimed
    /// pixel tests its eight neighbours. A region that reaches the cap (a large object) is
    /// grown again pixel by pixel ([`Regions::grow_pixels`]): which of its pixels a capped
    /// region holds depends on the order of the fill, and the other candidates inside the
    /// object share it or grow their own accordingly.
    fn grow(&mut self, fill: &Fill<'_>, seed: usize) -> usize {
        let first_claim = self.claimed.len();
        if let Some(id) = self.grow_spans(fill, seed) {
            return id;
        }
        for &p in &self.claimed[first_claim..] {
            self.owner[p as usize] = u32::MAX;
        }
        self.claimed.truncate(first_claim);
        self.grow_pixels(fill, seed)
    }

    /// [`Regions::grow`] span by span, or `None` (its pixels left claimed) when the region
    /// reaches the cap.
    fn grow_spans(&mut self, fill: &Fill<'_>, seed: usize) -> Option<usize> {
        let (width, height) = (fill.width, fill.height);
        let id = self.area.len() as u32;
        let (sx, sy) = (seed % width, seed / width);
        // The seed is the region's first pixel whatever its value; its row's run extends
        // from it both ways.
        self.claim(seed, id);
        let (a, b) = self.claim_run(fill, sy, sx, id);
        let mut area = b - a + 1;
        let mut border = false;
        self.spans.clear();
        self.spans.push((a as u32, b as u32, sy as u32));
        // Every claimed run is pushed, so the cap is checked after each growth.
        while let Some((x0, x1, y)) = self.spans.pop() {
            if area >= fill.cap {
                return None;
            }
            let (x0, x1, y) = (x0 as usize, x1 as usize, y as usize);
            border |= x0 == 0 || y == 0 || x1 + 1 == width || y + 1 == height;
            for yy in [y.wrapping_sub(1), y + 1].into_iter().filter(|&yy| yy < height) {
                let mut x = x0.saturating_sub(1);
                while x <= (x1 + 1).min(width - 1) {
                    let q = yy * width + x;
                    if !self.open(fill, q) {
                        x += 1;
                        continue;
                    }
                    self.claim(q, id);
                    let (a, b) = self.claim_run(fill, yy, x, id);
                    area += b - a + 1;
                    self.spans.push((a as u32, b as u32, yy as u32));
                    x = b + 2;
                }
            }
        }
        self.area.push(area);
        self.border.push(border);
        Some(id as usize)
    }

    /// [`Regions::grow`] pixel by pixel: each claimed pixel claims its 8-neighbours open to
    /// `fill`, until the region holds its cap.
    fn grow_pixels(&mut self, fill: &Fill<'_>, seed: usize) -> usize {
        let (width, height) = (fill.width, fill.height);
        let id = self.area.len() as u32;
        let mut area = 0;
        let mut border = false;
        let mut stack = std::mem::take(&mut self.stack);
        stack.clear();
        stack.push(((seed % width) as u32, (seed / width) as u32));
        self.claim(seed, id);
        while let Some((x, y)) = stack.pop() {
            let (x, y) = (x as usize, y as usize);
            area += 1;
            border |= x == 0 || y == 0 || x + 1 == width || y + 1 == height;
            if area + stack.len() >= fill.cap {
                continue;
            }
            for yy in y.saturating_sub(1)..=(y + 1).min(height - 1) {
                for xx in x.saturating_sub(1)..=(x + 1).min(width - 1) {
                    let q = yy * width + xx;
                    if self.open(fill, q) {
                        self.claim(q, id);
                        stack.push((xx as u32, yy as u32));
                    }
                }
            }
        }
        self.stack = stack;
        self.area.push(area);
        self.border.push(border);
        id as usize
    }

    /// Extends the claimed pixel `x` of row `y` left and right over the pixels open to
    /// `fill`, claiming them for region `id`; returns the run's ends (inclusive).
    fn claim_run(&mut self, fill: &Fill<'_>, y: usize, x: usize, id: u32) -> (usize, usize) {
        let row = y * fill.width;
        let (mut x0, mut x1) = (x, x);
        while x0 > 0 && self.open(fill, row + x0 - 1) {
            x0 -= 1;
            self.claim(row + x0, id);
        }
        while x1 + 1 < fill.width && self.open(fill, row + x1 + 1) {
            x1 += 1;
            self.claim(row + x1, id);
        }
        (x0, x1)
    }
}

/// What a blob's flood fill spreads over: the pixels of `image` (`width` x `height`, the
/// small box mean, grey levels) at least `level`, until the region holds `cap` pixels.
struct Fill<'a> {
    image: &'a [f32],
    width: usize,
    height: usize,
    level: f32,
    cap: usize,
}

/// Pixels in a box of half-width `h` about each position along an axis of `len` pixels
/// (the box clipped by the image edges).
fn box_counts(len: usize, h: usize) -> Vec<f64> {
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
fn prefix_sums(col: &[i32], pre: &mut [i32]) {
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
fn box_means(image: &[f32], width: usize, height: usize, halves: [usize; 2]) -> [Vec<f32>; 2] {
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
fn box_rows(
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

#[cfg(test)]
mod tests {
    use super::*;

    fn disc_image(w: usize, h: usize, centres: &[(f64, f64)], r: f64, amp: f32) -> Vec<f32> {
        let mut img = vec![0.0f32; w * h];
        for &(cx, cy) in centres {
            for y in 0..h {
                for x in 0..w {
                    let d = ((x as f64 - cx).powi(2) + (y as f64 - cy).powi(2)).sqrt();
                    img[y * w + x] += amp * (r + 0.5 - d).clamp(0.0, 1.0) as f32;
                }
            }
        }
        img
    }

    /// The span flood fill claims what the pixel-by-pixel one does (each claimed pixel
    /// claiming its unclaimed 8-neighbours at or above the level): the same pixels, area
    /// and border flag, on random images of several densities and sizes, with regions
    /// grown one after another (each seeing the pixels the earlier ones took), seeds below
    /// the level included, and every other region capped at a few pixels.
    #[test]
    fn span_flood_fill_matches_a_pixel_flood_fill() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
        for (w, h) in [(1usize, 1usize), (1, 9), (9, 1), (17, 13), (64, 48)] {
            for density in [0.2, 0.5, 0.7, 1.0] {
                let image: Vec<f32> = (0..w * h)
                    .map(|_| if rng.gen::<f64>() < density { 1.0 } else { 0.0 })
                    .collect();
                let (mut spans, mut pixels) = (Regions::default(), Regions::default());
                spans.reset(w * h);
                pixels.reset(w * h);
                for k in 0..8 {
                    let seed = rng.gen_range(0..w * h);
                    let cap = if k % 2 == 0 { usize::MAX } else { 5 };
                    if pixels.region_at(seed).is_some() {
                        assert!(
                            spans.region_at(seed).is_some(),
                            "{w}x{h}: pixel {seed} claimed by one fill only"
                        );
                        continue;
                    }
                    let fill = Fill {
                        image: &image,
                        width: w,
                        height: h,
                        level: 0.5,
                        cap,
                    };
                    let r = spans.grow(&fill, seed);
                    let want = pixels.grow_pixels(&fill, seed);
                    let of = |regions: &Regions, r: usize| -> Vec<usize> {
                        (0..w * h).filter(|&q| regions.region_at(q) == Some(r)).collect()
                    };
                    let what = format!("{w}x{h} density {density} cap {cap}, seed {seed}");
                    assert_eq!(of(&spans, r), of(&pixels, want), "{what}: pixels");
                    assert_eq!(spans.area[r], pixels.area[want], "{what}: area");
                    assert_eq!(spans.border[r], pixels.border[want], "{what}: border flag");
                }
            }
        }
    }

    /// A row's runs above its thresholds, found from bit masks 64 pixels at a time, are the
    /// runs a pixel-by-pixel scan finds: rows shorter and longer than one mask, runs that
    /// cross a mask's edge or reach the row's end, values equal to their threshold (not
    /// above it). The SSE2 mask equals the portable one.
    #[test]
    fn row_runs_match_a_pixel_scan() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        for width in [1usize, 5, 63, 64, 65, 130, 200, 512] {
            for density in [0.05, 0.5, 0.95, 1.0] {
                let thresholds: Vec<f32> = (0..width).map(|_| rng.gen_range(1.0..2.0)).collect();
                let line: Vec<f32> = thresholds
                    .iter()
                    .map(|&t| match rng.gen::<f64>() {
                        p if p < 0.1 => t,
                        p if p < density => t + 0.5,
                        _ => t - 0.5,
                    })
                    .collect();
                let mut want = Vec::new();
                let mut x = 0;
                while x < width {
                    if line[x] > thresholds[x] {
                        let s = x;
                        while x < width && line[x] > thresholds[x] {
                            x += 1;
                        }
                        want.push((s as u32, x as u32));
                    }
                    x += 1;
                }
                let mut labels = Labels::default();
                labels.begin();
                labels.push_row(0, &line, &thresholds);
                let got: Vec<(u32, u32)> = labels.runs.iter().map(|r| (r.0, r.1)).collect();
                assert_eq!(got, want, "width {width}, density {density}");
                for x0 in (0..width).step_by(64) {
                    let end = (x0 + 64).min(width);
                    let (l, t) = (&line[x0..end], &thresholds[x0..end]);
                    assert_eq!(
                        above_bits(l, t),
                        above_bits_portable(l, t),
                        "width {width} at {x0}"
                    );
                }
            }
        }
    }

    /// The row pre-test of a chunk, four pixels at a time, passes exactly the pixels the
    /// pixel-by-pixel test passes: plateaus (equal neighbours), values equal to the peak
    /// threshold or to the mask, at every chunk of rows shorter and longer than a chunk.
    #[test]
    fn row_candidates_match_the_pixel_test() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
        for width in [1usize, 16, 17, 33, 100, 512] {
            for _ in 0..20 {
                // Few distinct levels, so that neighbours are often equal.
                let band: Vec<f32> = (0..width).map(|_| f32::from(rng.gen_range(0u8..6))).collect();
                let small: Vec<f32> = (0..width).map(|_| f32::from(rng.gen_range(0u8..4))).collect();
                let fy = 1.0 + f32::from(rng.gen_range(0u8..2));
                let mask: Vec<f32> = (0..width)
                    .map(|_| f32::from(rng.gen_range(1u8..3)) * fy)
                    .collect();
                let test = RowTest {
                    band: &band,
                    small: &small,
                    mask: &mask,
                    peak_min: 2.0,
                };
                for x0 in (0..width).step_by(CHUNK) {
                    let x1 = (x0 + CHUNK).min(width);
                    let want = test.candidates_portable(x0, x1);
                    assert_eq!(test.candidates(x0, x1), want, "width {width} at {x0}");
                    for x in x0..x1 {
                        let v = band[x];
                        let pass = v > 2.0
                            && small[x] > mask[x]
                            && (x == 0 || band[x - 1] < v)
                            && (x + 1 == width || band[x + 1] <= v);
                        assert_eq!(want >> (x - x0) & 1 == 1, pass, "width {width} at {x}");
                    }
                }
            }
        }
    }

    #[test]
    fn prefix_sums_match_a_running_sum_and_wrap() {
        for n in [0usize, 1, 3, 4, 5, 8, 9, 12, 17, 512] {
            let col: Vec<i32> = (0..n)
                .map(|i| ((i as i64 * 7_919 % 2_001) - 1_000) as i32 * 1_000_003)
                .collect();
            let mut pre = vec![7; n + 1];
            prefix_sums(&col, &mut pre);
            let mut s = 0i32;
            assert_eq!(pre[0], 0);
            for (i, c) in col.iter().enumerate() {
                s = s.wrapping_add(*c);
                assert_eq!(pre[i + 1], s, "n {n} at {i}");
            }
        }
    }

    /// The mean of `img` (`w` x `h`) over the box of half-width `half` about `(x, y)`, the
    /// pixels outside the image left out, summed in double precision.
    fn brute_box_mean(img: &[f32], w: usize, h: usize, half: usize, x: usize, y: usize) -> f64 {
        let (mut s, mut n) = (0.0f64, 0.0);
        for yy in y.saturating_sub(half)..=(y + half).min(h - 1) {
            for xx in x.saturating_sub(half)..=(x + half).min(w - 1) {
                s += f64::from(img[yy * w + xx]);
                n += 1.0;
            }
        }
        s / n
    }

    #[test]
    fn box_means_of_a_signed_fractional_signal() {
        let (w, h) = (37, 23);
        let img: Vec<f32> = (0..w * h)
            .map(|i| (((i * 7_919) % 1_000) as f32 - 500.0) * 0.417)
            .collect();
        for (out, half) in box_means(&img, w, h, [3, 7]).iter().zip([3, 7]) {
            for y in 0..h {
                for x in 0..w {
                    let want = brute_box_mean(&img, w, h, half, x, y);
                    assert!(
                        (f64::from(out[y * w + x]) - want).abs() < 1e-3,
                        "half {half} at {x},{y}"
                    );
                }
            }
        }
    }

    #[test]
    fn visible_fraction_of_a_disc_at_the_border() {
        assert!((visible_fraction(50.0, 50.0, 4.0, 100, 100) - 1.0).abs() < 1e-12);
        // Centred on the frame's edge (x = -0.5): half the disc.
        assert!((visible_fraction(-0.5, 50.0, 4.0, 100, 100) - 0.5).abs() < 0.03);
        // In a corner: a quarter.
        assert!((visible_fraction(-0.5, -0.5, 4.0, 100, 100) - 0.25).abs() < 0.03);
    }

    #[test]
    fn box_mean_matches_brute_force_at_borders() {
        let (w, h) = (9, 7);
        let img: Vec<f32> = (0..w * h).map(|i| ((i * 37) % 11) as f32).collect();
        for halves in [[2, 5], [1, 3], [4, 12]] {
            for (out, half) in box_means(&img, w, h, halves).iter().zip(halves) {
                for y in 0..h {
                    for x in 0..w {
                        let want = brute_box_mean(&img, w, h, half, x, y);
                        // Fixed point rounds each pixel to 1/8192 of a level.
                        assert!(
                            (f64::from(out[y * w + x]) - want).abs() < 2e-4,
                            "half {half} at {x},{y}"
                        );
                    }
                }
            }
        }
    }

    /// The loops compiled for AVX2 give the baseline's box means and blobs to the bit, on
    /// widths that leave every remainder of eight lanes.
    #[test]
    fn avx2_loops_give_the_baseline_values() {
        for (w, h) in [(97usize, 61usize), (64, 40), (131, 23)] {
            let mut img = disc_image(
                w,
                h,
                &[(20.0, 15.0), (26.5, 16.0), (w as f64 - 9.5, 12.25)],
                4.0,
                150.0,
            );
            for (i, v) in img.iter_mut().enumerate() {
                *v += ((i * 7_919) % 17) as f32 * 0.37 - 3.0;
            }
            let means = || box_means(&img, w, h, [3, 7]);
            let p = DetectParameters {
                radius: 4.0,
                noise_sigma: 2.5,
                expected: None,
            };
            let (wide, base) = (means(), crate::cpu::baseline_only(means));
            let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
            assert_eq!(bits(&wide[0]), bits(&base[0]), "{w}x{h}");
            assert_eq!(bits(&wide[1]), bits(&base[1]), "{w}x{h}");
            let blobs = find_blobs(&img, w, h, &p);
            assert!(blobs.blobs.len() >= 2, "{blobs:?}");
            let baseline = crate::cpu::baseline_only(|| find_blobs(&img, w, h, &p));
            assert_eq!(format!("{blobs:?}"), format!("{baseline:?}"));
        }
    }

    /// Formed row by row as the filters ask, the signal gives the blobs of the whole image
    /// formed first, and ends up whole; each row is asked for once, in order.
    #[test]
    fn a_signal_formed_row_by_row_gives_the_same_blobs() {
        let (w, h) = (97, 61);
        let mut img = disc_image(
            w,
            h,
            &[(20.0, 20.0), (27.5, 21.0), (60.5, 50.25), (3.0, 58.0)],
            4.0,
            120.0,
        );
        for (i, v) in img.iter_mut().enumerate() {
            *v += ((i * 7_919) % 13) as f32 - 6.0;
        }
        let p = DetectParameters {
            radius: 4.0,
            noise_sigma: 3.7,
            expected: None,
        };
        let want = find_blobs(&img, w, h, &p);
        assert!(want.blobs.len() >= 3, "{want:?}");
        let mut signal = vec![f32::NAN; w * h];
        let mut asked = Vec::new();
        let got = find_blobs_forming(&mut signal, w, h, &p, &mut Scratch::default(), |pixels, out| {
            asked.push(pixels.start / w);
            out.copy_from_slice(&img[pixels]);
        });
        assert_eq!(format!("{got:?}"), format!("{want:?}"));
        assert_eq!(asked, (0..h).collect::<Vec<_>>());
        assert!(signal == img);
    }

    #[test]
    fn finds_touching_discs_and_rejects_a_large_object() {
        let (w, h) = (120, 80);
        let mut img = disc_image(w, h, &[(20.0, 20.0), (28.0, 20.0), (60.5, 50.25)], 4.0, 200.0);
        for y in 40..75 {
            for x in 85..115 {
                img[y * w + x] += 150.0;
            }
        }
        let mut p = DetectParameters {
            radius: 4.0,
            noise_sigma: 1.0,
            expected: None,
        };
        let all = find_blobs(&img, w, h, &p);
        let single = all.blobs.iter().find(|b| b.x.abs_diff(60) <= 1).unwrap();
        p.expected = Some(BlobSize {
            area: single.area,
            extent: single.extent,
        });
        let set = find_blobs(&img, w, h, &p);
        let mut found: Vec<(usize, usize)> = set.blobs.iter().map(|b| (b.x, b.y)).collect();
        found.sort_unstable();
        assert_eq!(found.len(), 3, "{found:?}");
        for (f, t) in found.iter().zip([(20.0, 20.0), (28.0, 20.0), (60.5, 50.25)]) {
            assert!(
                (f.0 as f64 - t.0).abs() <= 1.0 && (f.1 as f64 - t.1).abs() <= 1.0,
                "{found:?}"
            );
        }
        assert!(set.too_large_count > 0);
    }
}
