//! Filling unknown pixels of an image from the known ones around them.
//!
//! Where a particle covers the same pixels in every frame (a large ball that barely moves),
//! no frame shows the background there: the per-pixel median is the particle itself. Such
//! pixels are filled with the harmonic interpolation of the pixels around them (each filled
//! pixel the mean of its four neighbours), which reproduces any linear ramp of light exactly.
//!
//! A harmonic fill has no curvature of its own: under vignetting `B (1 - v r² / c²)` (the
//! Laplacian `-4 B v / c²`) a gap of radius `a` is filled `B v a² / c²` too bright or dark
//! at its middle, and where the gap runs into the image border (left free) the fill is flat
//! across it. Sweep style 1018 (a dark ball of 38 px hovering under vignetting 0.21, the gap
//! 72 px across its reach) had its background 4.8 grey levels too dark under the ball's
//! centre, in a dome cut by the top border, and was tracked 0.37 / 0.52 px off. So where the
//! known pixels around a gap show a curvature ([`fit_quadratic`]: a quadratic surface whose
//! second-order terms stand beyond 3 standard errors of zero), the gap is filled with that
//! surface plus the harmonic interpolation of what the surface leaves around it: the
//! known pixels still hold at the gap's edge, and a vignetting or a gradient times it is
//! reproduced across the gap (to their third-order terms).

/// Largest change (grey levels) of any filled pixel in a sweep at which the relaxation stops.
const SETTLED: f32 = 0.01;
/// Most sweeps of the relaxation (over-relaxed, it settles in a few times the gap's width).
const MAX_SWEEPS: usize = 4_000;

/// Replaces the pixels of `image` (`width * height * channels` values, row-major) where
/// `unknown` is true by the harmonic interpolation of the known pixels around them, by
/// successive over-relaxation started from the values they hold. Pixels outside the frame
/// are left out of a pixel's neighbours (the border is free). Nothing changes when no pixel
/// is known or none unknown.
pub(crate) fn harmonic_fill(
    image: &mut [f32],
    width: usize,
    height: usize,
    channels: usize,
    unknown: &[bool],
) {
    debug_assert_eq!(unknown.len(), width * height);
    debug_assert_eq!(image.len(), width * height * channels);
    let holes: Vec<usize> = (0..width * height).filter(|&i| unknown[i]).collect();
    if holes.is_empty() || holes.len() == unknown.len() {
        return;
    }
    // Over-relaxation for a gap of this many pixels across (the optimum for a square of side
    // `n` is 2 / (1 + sin(pi / n))).
    let across = (holes.len() as f64).sqrt().max(2.0);
    let omega = (2.0 / (1.0 + (std::f64::consts::PI / across).sin())) as f32;
    for _ in 0..MAX_SWEEPS {
        let mut largest = 0.0f32;
        for &i in &holes {
            let (x, y) = (i % width, i / width);
            let mut neighbours = [usize::MAX; 4];
            if x > 0 {
                neighbours[0] = i - 1;
            }
            if x + 1 < width {
                neighbours[1] = i + 1;
            }
            if y > 0 {
                neighbours[2] = i - width;
            }
            if y + 1 < height {
                neighbours[3] = i + width;
            }
            let count = neighbours.iter().filter(|&&n| n != usize::MAX).count() as f32;
            for c in 0..channels {
                let sum: f32 = neighbours
                    .iter()
                    .filter(|&&n| n != usize::MAX)
                    .map(|&n| image[n * channels + c])
                    .sum();
                let v = &mut image[i * channels + c];
                let step = omega * (sum / count - *v);
                *v += step;
                largest = largest.max(step.abs());
            }
        }
        if largest < SETTLED {
            break;
        }
    }
}

/// Standard errors a quadratic term must stand beyond zero for the gap to be filled along
/// the curved surface rather than harmonically.
const CURVED: f64 = 3.0;
/// Pixels the light's quadratic surface is fitted on, at most (an even sample).
const FIT_PIXELS: usize = 65_536;
/// Rounds of the quadratic fit with outliers (texture, clutter) left out.
const CLIP_ROUNDS: usize = 3;
/// Residuals beyond this many robust standard deviations are left out of the next round.
const CLIP_SIGMAS: f64 = 3.0;

/// Fills the pixels of `image` (`width * height * channels` values, row-major) where
/// `unknown` is true from the known pixels around them: each 4-connected gap whose
/// surroundings curve ([`fit_quadratic`] on the known pixels within half the gap's radius,
/// at least 3 px, of its bounding box) so much that a harmonic fill would miss by more than
/// `noise` (grey levels) at the gap's middle (`|Laplacian| a² / 4` over a disc of radius
/// `a`) with that quadratic surface plus the harmonic interpolation of its residual; the
/// other gaps by [`harmonic_fill`] as before (an image with no such gap is filled exactly as
/// that function fills it). See the module doc.
pub(crate) fn fill_from_surroundings(
    image: &mut [f32],
    width: usize,
    height: usize,
    channels: usize,
    unknown: &[bool],
    noise: f64,
) {
    debug_assert_eq!(unknown.len(), width * height);
    let whole = GapBox {
        gap: [0, 0, width.saturating_sub(1), height.saturating_sub(1)],
        centre: [(width as f64 - 1.0) / 2.0, (height as f64 - 1.0) / 2.0],
        radius: (width.max(height) as f64 / 2.0).max(1.0),
    };
    let surfaces: Option<Vec<Quadratic>> = (0..channels)
        .map(|c| fit_quadratic(image, width, channels, c, unknown, &whole))
        .collect();
    let Some(surfaces) = surfaces.filter(|s| s.iter().any(|q| q.curved)) else {
        harmonic_fill(image, width, height, channels, unknown);
        return;
    };
    let mut flat = unknown.to_vec();
    let mut curved_count = 0;
    for gap in gaps(unknown, width, height) {
        let box_ = GapBox::around(&gap, width);
        let harmonic_miss = |q: &Quadratic| q.laplacian().abs() * box_.radius * box_.radius / 4.0;
        if !surfaces.iter().any(|q| q.curved && harmonic_miss(q) > noise) {
            continue;
        }
        curved_count += 1;
        // The residual of the box's pixels (one beyond the gap on every side) from the
        // surface, the gap's started at 0, filled harmonically, and the surface added back.
        let [x0, y0, x1, y1] = [
            box_.gap[0].saturating_sub(1),
            box_.gap[1].saturating_sub(1),
            (box_.gap[2] + 1).min(width - 1),
            (box_.gap[3] + 1).min(height - 1),
        ];
        let (bw, bh) = (x1 - x0 + 1, y1 - y0 + 1);
        let mut local = vec![0.0f32; bw * bh * channels];
        let mut local_unknown = vec![false; bw * bh];
        for y in y0..=y1 {
            for x in x0..=x1 {
                let (i, j) = (y * width + x, (y - y0) * bw + (x - x0));
                local_unknown[j] = unknown[i];
                for (c, q) in surfaces.iter().enumerate() {
                    local[j * channels + c] = if unknown[i] {
                        0.0
                    } else {
                        image[i * channels + c] - q.at(x as f64, y as f64) as f32
                    };
                }
            }
        }
        harmonic_fill(&mut local, bw, bh, channels, &local_unknown);
        for &i in &gap {
            let (x, y) = (i % width, i / width);
            let j = (y - y0) * bw + (x - x0);
            for (c, q) in surfaces.iter().enumerate() {
                image[i * channels + c] = local[j * channels + c] + q.at(x as f64, y as f64) as f32;
            }
            flat[i] = false;
        }
    }
    if curved_count == 0 {
        harmonic_fill(image, width, height, channels, unknown);
    } else if flat.iter().any(|&u| u) {
        harmonic_fill(image, width, height, channels, &flat);
    }
}

/// The 4-connected groups of `unknown` pixels (pixel indices, row-major).
fn gaps(unknown: &[bool], width: usize, height: usize) -> Vec<Vec<usize>> {
    let mut seen = vec![false; unknown.len()];
    let mut out = Vec::new();
    for start in 0..unknown.len() {
        if !unknown[start] || seen[start] {
            continue;
        }
        seen[start] = true;
        let mut gap = vec![start];
        let mut k = 0;
        while k < gap.len() {
            let i = gap[k];
            k += 1;
            let (x, y) = (i % width, i / width);
            let mut visit = |n: usize| {
                if unknown[n] && !seen[n] {
                    seen[n] = true;
                    gap.push(n);
                }
            };
            if x > 0 {
                visit(i - 1);
            }
            if x + 1 < width {
                visit(i + 1);
            }
            if y > 0 {
                visit(i - width);
            }
            if y + 1 < height {
                visit(i + width);
            }
        }
        out.push(gap);
    }
    out
}

/// A gap's bounding box, inclusive pixel bounds `[x0, y0, x1, y1]`, with its centre and
/// radius (of the disc of its area), px.
struct GapBox {
    gap: [usize; 4],
    centre: [f64; 2],
    radius: f64,
}

impl GapBox {
    fn around(gap: &[usize], width: usize) -> GapBox {
        let mut b = [usize::MAX, usize::MAX, 0, 0];
        let (mut sx, mut sy) = (0.0, 0.0);
        for &i in gap {
            let (x, y) = (i % width, i / width);
            b = [b[0].min(x), b[1].min(y), b[2].max(x), b[3].max(y)];
            sx += x as f64;
            sy += y as f64;
        }
        let n = gap.len() as f64;
        GapBox {
            gap: b,
            centre: [sx / n, sy / n],
            radius: (n / std::f64::consts::PI).sqrt().max(1.0),
        }
    }
}

/// A quadratic surface in grey levels over `u = (x − cx) / s`, `v = (y − cy) / s`:
/// `k0 + k1 u + k2 v + k3 u² + k4 u v + k5 v²`.
#[derive(Clone, Copy, Debug)]
struct Quadratic {
    centre: [f64; 2],
    scale: f64,
    k: [f64; 6],
    /// Returns true if and only if a second-order term stands beyond [`CURVED`] standard
    /// errors of zero.
    curved: bool,
}

impl Quadratic {
    fn terms(u: f64, v: f64) -> [f64; 6] {
        [1.0, u, v, u * u, u * v, v * v]
    }

    /// The surface's Laplacian, grey levels per px².
    fn laplacian(&self) -> f64 {
        2.0 * (self.k[3] + self.k[5]) / (self.scale * self.scale)
    }

    fn at(&self, x: f64, y: f64) -> f64 {
        let t = Self::terms(
            (x - self.centre[0]) / self.scale,
            (y - self.centre[1]) / self.scale,
        );
        t.iter().zip(&self.k).map(|(a, b)| a * b).sum()
    }
}

/// The quadratic surface fitted by least squares to channel `c` of the known pixels of
/// `image` in `box_.fit`, pixels beyond [`CLIP_SIGMAS`] robust standard deviations of the
/// residuals left out ([`CLIP_ROUNDS`] rounds); `None` with fewer than 24 known pixels or a
/// singular system. Its second-order terms are `curved` when one stands beyond [`CURVED`]
/// standard errors (from the residuals' robust spread) of zero.
fn fit_quadratic(
    image: &[f32],
    width: usize,
    channels: usize,
    c: usize,
    unknown: &[bool],
    box_: &GapBox,
) -> Option<Quadratic> {
    use nalgebra::{SMatrix, SVector};
    let [x0, y0, x1, y1] = box_.gap;
    let (centre, scale) = (box_.centre, box_.radius);
    let mut points: Vec<([f64; 6], f64)> = Vec::new();
    // An even sample of the box's pixels (every `stride`-th, odd so that it walks across
    // the columns): the surface's six terms are known to a small fraction of the noise.
    let stride = ((x1 - x0 + 1) * (y1 - y0 + 1) / FIT_PIXELS).max(1) | 1;
    for i in (0..(x1 - x0 + 1) * (y1 - y0 + 1)).step_by(stride) {
        let (x, y) = (x0 + i % (x1 - x0 + 1), y0 + i / (x1 - x0 + 1));
        {
            let i = y * width + x;
            if !unknown[i] {
                let t = Quadratic::terms((x as f64 - centre[0]) / scale, (y as f64 - centre[1]) / scale);
                points.push((t, f64::from(image[i * channels + c])));
            }
        }
    }
    let mut used = vec![true; points.len()];
    let mut out = None;
    let mut residuals: Vec<f64> = Vec::with_capacity(points.len());
    for _ in 0..CLIP_ROUNDS {
        let mut m = SMatrix::<f64, 6, 6>::zeros();
        let mut r = SVector::<f64, 6>::zeros();
        let mut n = 0usize;
        for ((t, v), _) in points.iter().zip(&used).filter(|(_, &u)| u) {
            let t = SVector::<f64, 6>::from_column_slice(t);
            m += t * t.transpose();
            r += t * *v;
            n += 1;
        }
        if n < 24 {
            return None;
        }
        let inverse = m.try_inverse()?;
        let k = inverse * r;
        let k = [k[0], k[1], k[2], k[3], k[4], k[5]];
        let q = Quadratic {
            centre,
            scale,
            k,
            curved: false,
        };
        let value = |t: &[f64; 6]| t.iter().zip(&k).map(|(a, b)| a * b).sum::<f64>();
        residuals.clear();
        residuals.extend(
            points
                .iter()
                .zip(&used)
                .filter(|(_, &u)| u)
                .map(|((t, v), _)| (v - value(t)).abs()),
        );
        let mid = residuals.len() / 2;
        let sigma = 1.4826 * *residuals.select_nth_unstable_by(mid, f64::total_cmp).1;
        let curved = (3..6).any(|j| k[j].abs() > CURVED * sigma * inverse[(j, j)].sqrt());
        out = Some(Quadratic { curved, ..q });
        let limit = CLIP_SIGMAS * sigma;
        let mut changed = false;
        for ((t, v), u) in points.iter().zip(used.iter_mut()) {
            let keep = (v - value(t)).abs() <= limit;
            changed |= keep != *u;
            *u = keep;
        }
        if !changed {
            break;
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_ramp_is_filled_exactly_under_a_disc() {
        // A linear ramp of light with a disc of radius 12 px set to 255 and marked unknown:
        // the fill gives the ramp back (to the relaxation's tolerance); fails if the disc's
        // values leak into the fill or the border is held fixed at 0.
        let (w, h) = (60usize, 50usize);
        let ramp = |x: usize, y: usize| 40.0 + 1.5 * x as f32 - 0.7 * y as f32;
        let mut image: Vec<f32> = (0..w * h).map(|i| ramp(i % w, i / w)).collect();
        let mut unknown = vec![false; w * h];
        for i in 0..w * h {
            let (x, y) = ((i % w) as f64, (i / w) as f64);
            if (x - 25.0).hypot(y - 30.0) <= 12.0 {
                unknown[i] = true;
                image[i] = 255.0;
            }
        }
        harmonic_fill(&mut image, w, h, 1, &unknown);
        let worst = (0..w * h)
            .map(|i| (image[i] - ramp(i % w, i / w)).abs())
            .fold(0.0f32, f32::max);
        assert!(worst < 0.2, "largest error {worst} grey levels");
    }

    /// Vignetting `180 (1 - 0.2 r² / c²)` about the frame's centre, with a disc of radius 50
    /// px marked unknown that runs off the top border: the harmonic fill misses by several
    /// grey levels (a dome, flat across the border), the fill along the surroundings'
    /// quadratic surface by a fraction of one.
    #[test]
    fn vignetting_is_filled_along_its_curvature_up_to_the_border() {
        let (w, h) = (200usize, 160usize);
        let light = |x: usize, y: usize| {
            let (dx, dy) = (x as f32 - 99.5, y as f32 - 79.5);
            180.0 * (1.0 - 0.2 * (dx * dx + dy * dy) / (99.5f32.powi(2) + 79.5f32.powi(2)))
        };
        let truth: Vec<f32> = (0..w * h).map(|i| light(i % w, i / w)).collect();
        let unknown: Vec<bool> = (0..w * h)
            .map(|i| ((i % w) as f64 - 80.0).hypot((i / w) as f64 - 30.0) <= 50.0)
            .collect();
        let worst = |image: &[f32]| {
            (0..w * h)
                .map(|i| (image[i] - truth[i]).abs())
                .fold(0.0f32, f32::max)
        };
        let holding = |v: f32| -> Vec<f32> {
            truth
                .iter()
                .zip(&unknown)
                .map(|(&t, &u)| if u { v } else { t })
                .collect()
        };
        let mut harmonic = holding(40.0);
        harmonic_fill(&mut harmonic, w, h, 1, &unknown);
        let mut curved = holding(40.0);
        fill_from_surroundings(&mut curved, w, h, 1, &unknown, 1.0);
        assert!(
            worst(&harmonic) > 2.0,
            "harmonic fill off by {}",
            worst(&harmonic)
        );
        assert!(worst(&curved) < 0.3, "curved fill off by {}", worst(&curved));
    }

    /// Surroundings with no curvature (a ramp) are filled exactly as [`harmonic_fill`]
    /// fills them, to the bit.
    #[test]
    fn a_ramp_is_filled_as_the_harmonic_fill_does() {
        let (w, h) = (60usize, 50usize);
        let mut image: Vec<f32> = (0..w * h)
            .map(|i| 40.0 + 1.5 * (i % w) as f32 - 0.7 * (i / w) as f32)
            .collect();
        let unknown: Vec<bool> = (0..w * h)
            .map(|i| ((i % w) as f64 - 25.0).hypot((i / w) as f64 - 30.0) <= 12.0)
            .collect();
        for (v, &u) in image.iter_mut().zip(&unknown) {
            if u {
                *v = 255.0;
            }
        }
        let mut plain = image.clone();
        harmonic_fill(&mut plain, w, h, 1, &unknown);
        fill_from_surroundings(&mut image, w, h, 1, &unknown, 1.0);
        assert!(image.iter().zip(&plain).all(|(a, b)| a.to_bits() == b.to_bits()));
    }

    #[test]
    fn nothing_known_or_nothing_unknown_changes_nothing() {
        let mut image = vec![7.0f32; 12];
        harmonic_fill(&mut image, 4, 3, 1, &[true; 12]);
        assert_eq!(image, vec![7.0f32; 12]);
        harmonic_fill(&mut image, 4, 3, 1, &[false; 12]);
        assert_eq!(image, vec![7.0f32; 12]);
    }
}
