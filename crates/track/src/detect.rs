//! Blob detection: where the particles are, to the pixel.
//!
//! The particle signal (see [`crate::background`]) is band-pass filtered: a box mean of
//! side about the particle's diameter (the matched filter of a disc, which averages the
//! noise down) minus a box mean twice as wide (which removes any slowly varying residual
//! background and the interiors of large objects). Candidate particles are the local
//! maxima of that response above `PEAK_SIGMAS` times its noise, the noise being propagated
//! from the measured pixel noise, so no brightness threshold has to be chosen by hand.
//! Maxima closer than one particle radius to a stronger one are dropped (a disc has one
//! centre). Each candidate then belongs to a connected component of the smoothed signal
//! above `MASK_SIGMAS` times its noise; a component's area per candidate tells a particle
//! from a large object (a hand, a floor edge) or from a speck much smaller than the
//! expected particle, and such candidates are rejected.

/// Candidate peaks must exceed this many standard deviations of the band-passed noise.
pub const PEAK_SIGMAS: f64 = 5.0;
/// Blob masks are the smoothed signal above this many standard deviations of its noise.
pub const MASK_SIGMAS: f64 = 3.0;
/// A candidate whose component area per candidate exceeds this many expected particle
/// areas is part of a large object, not a particle.
pub const MAX_AREA_RATIO: f64 = 4.0;
/// A component holding several candidates is a large object, not touching particles, when
/// its area exceeds this many expected particle areas per candidate (touching discs cover
/// less than the sum of their areas; a lone particle may be smeared by motion blur, so it
/// gets the looser [`MAX_AREA_RATIO`]).
pub const MERGED_AREA_RATIO: f64 = 1.5;
/// A candidate whose component (not touching the image border) is smaller than this
/// fraction of the expected particle area is a speck, not a particle.
pub const MIN_AREA_RATIO: f64 = 0.2;

/// What [`find_blobs`] needs to know.
#[derive(Clone, Debug, PartialEq)]
pub struct DetectParameters {
    /// Expected particle radius, px (the radius at half the peak signal).
    pub radius: f64,
    /// Standard deviation of the per-pixel signal noise, grey levels.
    pub noise_sigma: f64,
    /// Expected component area of one particle, px² (measured from the data); `None`
    /// disables the size rejection.
    pub expected_area: Option<f64>,
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
    /// Area of the blob's connected component divided by the candidates it holds, px².
    pub area: f64,
    /// Returns true if and only if the blob's component touches the image border.
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

/// Finds particle-like blobs in a signal image (`width * height`, row-major, grey levels,
/// particles positive). See the module doc for the method.
pub fn find_blobs(signal: &[f32], width: usize, height: usize, params: &DetectParameters) -> BlobSet {
    let mut scratch = Scratch::default();
    find_blobs_with_scratch(signal, width, height, params, &mut scratch)
}

/// Reusable buffers of [`find_blobs_with_scratch`].
#[derive(Default, Debug)]
pub struct Scratch {
    small: Vec<f32>,
    large: Vec<f32>,
    tmp: Vec<f64>,
    col: Vec<f64>,
}

/// [`find_blobs`] with reusable buffers (no per-frame allocation of the filtered images).
pub fn find_blobs_with_scratch(
    signal: &[f32],
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
    box_mean(
        signal,
        width,
        height,
        h,
        &mut scratch.small,
        &mut scratch.tmp,
        &mut scratch.col,
    );
    box_mean(
        signal,
        width,
        height,
        big,
        &mut scratch.large,
        &mut scratch.tmp,
        &mut scratch.col,
    );
    let (small, large) = (&scratch.small, &scratch.large);
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
    let n_large = ((2 * big + 1) * (2 * big + 1)) as f64;
    let peak_min = (PEAK_SIGMAS * sigma * (1.0 / n_small - 1.0 / n_large).sqrt()) as f32;
    let mask_t = (MASK_SIGMAS * sigma / n_small.sqrt()) as f32;
    // Mask threshold factors per column and row: sqrt(full count / count) of the small box.
    let full = (2 * h + 1) as f64;
    let mask_fx: Vec<f32> = count_small_x.iter().map(|&c| (full / c).sqrt() as f32).collect();
    let mask_fy: Vec<f32> = count_small_y.iter().map(|&c| (full / c).sqrt() as f32).collect();

    // Local maxima of the band-pass response (strict against earlier neighbours in raster
    // order, non-strict against later ones, so a plateau yields one maximum per row run).
    let band = |i: usize| small[i] - large[i];
    let mut peaks: Vec<(f32, usize, usize)> = Vec::new();
    for (y, &fy) in mask_fy.iter().enumerate().take(height) {
        let row = y * width;
        for (x, &fx) in mask_fx.iter().enumerate().take(width) {
            let i = row + x;
            let v = band(i);
            if v <= peak_min || small[i] <= mask_t * fx * fy {
                continue;
            }
            if f64::from(v) <= PEAK_SIGMAS * band_sigma_at(x, y) {
                continue;
            }
            let mut is_max = true;
            'n: for dy in -1i64..=1 {
                let yy = y as i64 + dy;
                if yy < 0 || yy >= height as i64 {
                    continue;
                }
                for dx in -1i64..=1 {
                    let xx = x as i64 + dx;
                    if (dx == 0 && dy == 0) || xx < 0 || xx >= width as i64 {
                        continue;
                    }
                    let j = yy as usize * width + xx as usize;
                    let w = band(j);
                    let earlier = j < i;
                    if (earlier && w >= v) || (!earlier && w > v) {
                        is_max = false;
                        break 'n;
                    }
                }
            }
            if is_max {
                peaks.push((v, x, y));
            }
        }
    }
    peaks.sort_by(|a, b| b.0.total_cmp(&a.0).then((a.2, a.1).cmp(&(b.2, b.1))));

    // Non-maximum suppression within one radius, on a grid of cells one radius wide.
    let r_nms = params.radius.max(1.5);
    let cell = r_nms.ceil() as usize;
    let gw = width.div_ceil(cell);
    let gh = height.div_ceil(cell);
    let mut grid: Vec<Vec<(usize, usize)>> = vec![Vec::new(); gw * gh];
    let mut kept: Vec<(f32, usize, usize)> = Vec::new();
    let r2 = r_nms * r_nms;
    for &(v, x, y) in &peaks {
        let (cx, cy) = (x / cell, y / cell);
        let mut clash = false;
        'g: for gy in cy.saturating_sub(1)..=(cy + 1).min(gh - 1) {
            for gx in cx.saturating_sub(1)..=(cx + 1).min(gw - 1) {
                for &(ox, oy) in &grid[gy * gw + gx] {
                    let dx = ox as f64 - x as f64;
                    let dy = oy as f64 - y as f64;
                    if dx * dx + dy * dy < r2 {
                        clash = true;
                        break 'g;
                    }
                }
            }
        }
        if !clash {
            grid[cy * gw + cx].push((x, y));
            kept.push((v, x, y));
        }
    }

    // Components of the smoothed signal above the mask threshold, as row runs.
    let comps = label_runs(small, width, height, mask_t, &mask_fx, &mask_fy);
    let mut seeds_per: Vec<u32> = vec![0; comps.area.len()];
    let labels: Vec<Option<usize>> = kept.iter().map(|&(_, x, y)| comps.label_at(x, y)).collect();
    for l in labels.iter().flatten() {
        seeds_per[*l] += 1;
    }
    let mut out = BlobSet::default();
    for (&(v, x, y), label) in kept.iter().zip(&labels) {
        let (area, at_border) = match label {
            Some(l) => (
                comps.area[*l] as f64 / f64::from(seeds_per[*l].max(1)),
                comps.border[*l],
            ),
            None => (1.0, false),
        };
        if let Some(expected) = params.expected_area {
            // Judge the whole component, not its share per seed: a large object (a hand, the
            // edge of a floor) carries several spurious peaks (its corners), which would
            // otherwise divide its area down to a particle's. Touching particles carry one
            // peak each, and their union covers less than the sum of their areas.
            let seeds = label.map_or(1, |l| seeds_per[l].max(1)) as f64;
            let limit = if seeds > 1.0 {
                MERGED_AREA_RATIO * expected * seeds
            } else {
                MAX_AREA_RATIO * expected
            };
            if area * seeds > limit {
                out.too_large_count += 1;
                continue;
            }
            if !at_border && area < MIN_AREA_RATIO * expected {
                out.too_small_count += 1;
                continue;
            }
        }
        out.blobs.push(Blob {
            x,
            y,
            peak: v,
            area,
            at_border,
        });
    }
    out
}

/// Connected components (8-connected) of `image > threshold`, stored as row runs.
struct Components {
    /// Per row, the runs `(x_start, x_end_exclusive, label)` in order.
    rows: Vec<Vec<(usize, usize, usize)>>,
    /// Pixel count per label.
    area: Vec<usize>,
    /// Whether each label touches the image border.
    border: Vec<bool>,
}

impl Components {
    fn label_at(&self, x: usize, y: usize) -> Option<usize> {
        let row = self.rows.get(y)?;
        let k = row.partition_point(|r| r.1 <= x);
        row.get(k).filter(|r| r.0 <= x).map(|r| r.2)
    }
}

/// Pixels in a box of half-width `h` about each position along an axis of `len` pixels
/// (the box clipped by the image edges).
fn box_counts(len: usize, h: usize) -> Vec<f64> {
    (0..len)
        .map(|x| ((x + h).min(len - 1) - x.saturating_sub(h) + 1) as f64)
        .collect()
}

/// Components of `image > threshold * fx[x] * fy[y]`.
fn label_runs(
    image: &[f32],
    width: usize,
    height: usize,
    threshold: f32,
    fx: &[f32],
    fy: &[f32],
) -> Components {
    let mut rows: Vec<Vec<(usize, usize, usize)>> = Vec::with_capacity(height);
    let mut parent: Vec<usize> = Vec::new();
    fn find(parent: &mut [usize], mut a: usize) -> usize {
        while parent[a] != a {
            parent[a] = parent[parent[a]];
            a = parent[a];
        }
        a
    }
    for y in 0..height {
        let line = &image[y * width..(y + 1) * width];
        let ty = threshold * fy[y];
        let above = |x: usize| line[x] > ty * fx[x];
        let mut runs = Vec::new();
        let mut x = 0;
        while x < width {
            if above(x) {
                let start = x;
                while x < width && above(x) {
                    x += 1;
                }
                let label = parent.len();
                parent.push(label);
                runs.push((start, x, label));
            } else {
                x += 1;
            }
        }
        if let Some(prev) = rows.last() {
            let mut k = 0;
            for run in &runs {
                // Runs of the previous row overlapping [start-1, end] (8-connectivity).
                while k < prev.len() && prev[k].1 < run.0 {
                    k += 1;
                }
                let mut j = k;
                while j < prev.len() && prev[j].0 <= run.1 {
                    let a = find(&mut parent, run.2);
                    let b = find(&mut parent, prev[j].2);
                    if a != b {
                        parent[a.max(b)] = a.min(b);
                    }
                    j += 1;
                }
            }
        }
        rows.push(runs);
    }
    // Compact labels.
    let mut compact = vec![usize::MAX; parent.len()];
    let mut area = Vec::new();
    let mut border = Vec::new();
    for (y, runs) in rows.iter_mut().enumerate() {
        for run in runs.iter_mut() {
            let root = find(&mut parent, run.2);
            if compact[root] == usize::MAX {
                compact[root] = area.len();
                area.push(0);
                border.push(false);
            }
            let l = compact[root];
            run.2 = l;
            area[l] += run.1 - run.0;
            border[l] |= run.0 == 0 || run.1 == width || y == 0 || y + 1 == height;
        }
    }
    Components { rows, area, border }
}

/// Box mean of side `2h+1` (pixels outside the image are left out of the mean), into `out`.
pub(crate) fn box_mean(
    image: &[f32],
    width: usize,
    height: usize,
    h: usize,
    out: &mut Vec<f32>,
    tmp: &mut Vec<f64>,
    col: &mut Vec<f64>,
) {
    // Horizontal running sums, divided by the count of in-image columns.
    tmp.clear();
    tmp.resize(width * height, 0.0);
    for y in 0..height {
        let src = &image[y * width..(y + 1) * width];
        let dst = &mut tmp[y * width..(y + 1) * width];
        let mut sum = 0.0f64;
        for v in src.iter().take(h.min(width)) {
            sum += f64::from(*v);
        }
        for x in 0..width {
            if x + h < width {
                sum += f64::from(src[x + h]);
            }
            if x > h {
                sum -= f64::from(src[x - h - 1]);
            }
            let lo = x.saturating_sub(h);
            let hi = (x + h).min(width - 1);
            dst[x] = sum / (hi - lo + 1) as f64;
        }
    }
    // Vertical running sums over whole rows (cache friendly).
    out.clear();
    out.resize(width * height, 0.0);
    col.clear();
    col.resize(width, 0.0);
    for row in tmp.chunks_exact(width).take(h.min(height)) {
        for (c, v) in col.iter_mut().zip(row) {
            *c += v;
        }
    }
    for y in 0..height {
        if y + h < height {
            for (c, v) in col.iter_mut().zip(&tmp[(y + h) * width..(y + h + 1) * width]) {
                *c += v;
            }
        }
        if y > h {
            for (c, v) in col.iter_mut().zip(&tmp[(y - h - 1) * width..(y - h) * width]) {
                *c -= v;
            }
        }
        let lo = y.saturating_sub(h);
        let hi = (y + h).min(height - 1);
        let inv = 1.0 / (hi - lo + 1) as f64;
        for (o, c) in out[y * width..(y + 1) * width].iter_mut().zip(col.iter()) {
            *o = (c * inv) as f32;
        }
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

    #[test]
    fn box_mean_matches_brute_force_at_borders() {
        let (w, h) = (9, 7);
        let img: Vec<f32> = (0..w * h).map(|i| ((i * 37) % 11) as f32).collect();
        let (mut out, mut tmp, mut col) = (Vec::new(), Vec::new(), Vec::new());
        box_mean(&img, w, h, 2, &mut out, &mut tmp, &mut col);
        for y in 0..h {
            for x in 0..w {
                let (mut s, mut n) = (0.0, 0.0);
                for yy in y.saturating_sub(2)..=(y + 2).min(h - 1) {
                    for xx in x.saturating_sub(2)..=(x + 2).min(w - 1) {
                        s += img[yy * w + xx];
                        n += 1.0;
                    }
                }
                assert!((out[y * w + x] - s / n).abs() < 1e-4);
            }
        }
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
            expected_area: None,
        };
        let all = find_blobs(&img, w, h, &p);
        let single = all.blobs.iter().find(|b| b.x.abs_diff(60) <= 1).unwrap();
        p.expected_area = Some(single.area);
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
