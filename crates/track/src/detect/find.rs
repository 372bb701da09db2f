//! The blob search of a frame: band-pass rows, candidate peaks, their blobs and size tests.

use super::band_pass::{band_noise, box_half_width};
use super::blob::{
    Blob, BlobSet, DetectParameters, FLOOD_CAP_AREAS, MASK_SIGMAS, MAX_AREA_RATIO, MERGED_AREA_RATIO,
    MIN_AREA_RATIO, PEAK_SIGMAS,
};
use super::box_filter::{box_counts, box_rows, FilterScratch};
use super::labels::Labels;
use super::peaks::{any_above, is_local_max, Peak, RowTest};
use super::regions::{Fill, Regions};
use super::signal_rows::{Formed, Forming, SignalRows};
use crate::cpu::{prefetch, with_avx2};

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
    pub(super) small: Vec<f32>,
    /// The band-pass response (small minus large box mean) of the last three rows, row `y` at
    /// `(y % 3) * width`.
    pub(super) band: Vec<f32>,
    /// The large box mean of the same rows, laid out alike.
    pub(super) large: Vec<f32>,
    pub(super) filter: FilterScratch,
    peaks: Vec<Peak>,
    kept: Vec<Peak>,
    cell_head: Vec<u32>,
    cell_next: Vec<u32>,
    pub(super) labels: Labels,
    pub(super) regions: Regions,
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
        let (extent, extent_at_border, extent_own) = match label {
            Some(l) => (
                comps.area[*l] as f64 / f64::from(seeds_per_comp[*l].max(1)),
                comps.border[*l],
                seeds_per_comp[*l] == 1 && !comps.border[*l],
            ),
            None => (1.0, false, true),
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
            extent_own,
            at_border,
        });
    }
    out
}

/// The fraction of a disc of radius `r` (px) centred at `(x, y)` that lies inside a `width` x
/// `height` frame (pixel centres at integers, so the frame spans -0.5 to width - 0.5), from a
/// 16 x 16 grid of points over the disc's bounding square.
pub(super) fn visible_fraction(x: f64, y: f64, r: f64, width: usize, height: usize) -> f64 {
    const N: usize = 16;
    // Every grid point lies within the disc's bounding square: where that is in the frame,
    // so is the whole disc (the common case, the blob's extent touching the border far off).
    let (w, h) = (width as f64 - 0.5, height as f64 - 0.5);
    if x - r >= -0.5 && y - r >= -0.5 && x + r <= w && y + r <= h {
        return 1.0;
    }
    let (mut inside, mut all) = (0usize, 0usize);
    for i in 0..N {
        for j in 0..N {
            let px = x - r + (i as f64 + 0.5) * 2.0 * r / N as f64;
            let py = y - r + (j as f64 + 0.5) * 2.0 * r / N as f64;
            if (px - x).powi(2) + (py - y).powi(2) > r * r {
                continue;
            }
            all += 1;
            let within = px >= -0.5 && py >= -0.5 && px <= w && py <= h;
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
pub(super) const CHUNK: usize = 16;

/// How many candidates ahead of the one growing its blob the next blob's pixels are fetched
/// into the cache.
const PREFETCH_AHEAD: usize = 2;

/// The noise-mask thresholds on the small box mean, grey levels: one per column (the box's
/// column count), scaled in the rows near the top and bottom edges (its row count), where the
/// box holds fewer pixels and its mean is noisier.
struct MaskThresholds {
    /// Each column's threshold in a row whose box holds whole columns.
    pub(super) x: Vec<f32>,
    /// Each row's factor on them (1 away from the top and bottom edges).
    pub(super) fy: Vec<f32>,
    /// Half-width of the small box, px.
    pub(super) h: usize,
}

impl MaskThresholds {
    /// The threshold at pixel `(x, y)`.
    fn at(&self, x: usize, y: usize) -> f32 {
        self.x[x] * self.fy[y]
    }

    /// Row `y`'s thresholds: the columns' own where the row factor is 1, else written into
    /// `buf`.
    pub(super) fn row<'a>(&'a self, y: usize, buf: &'a mut Vec<f32>) -> &'a [f32] {
        if y >= self.h && y + self.h < self.fy.len() {
            return &self.x;
        }
        buf.clear();
        buf.extend(self.x.iter().map(|m| m * self.fy[y]));
        buf
    }
}
