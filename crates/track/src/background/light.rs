//! The light falling on the scene, read from a background that is one even surface lit
//! unevenly, and taken out of the particles' signal.
//!
//! An illumination gradient or vignetting multiplies everything in view, the particles
//! included: a particle's image is its profile times the light, which leans its centroid
//! towards the brighter side by about `M ∇ln L` (its second moments times the light's
//! relative slope). A per-pixel background takes out the light's offset, not this lean:
//! fresh style 6081 (a Gaussian spot of 45 px under a gradient of 0.13 and vignetting of
//! 0.14, no noise) was followed 0.95 / 0.48 px off its centre, spread 0.01 px.
//!
//! Where the background's per-pixel median is a smooth surface (a cubic in `x` and `y`
//! explains it to within the median's own noise and quantisation, apart from a few
//! particles' leftovers), the surface is the light: nothing but light varies over an even
//! surface. The signal is then divided by the light relative to its dimmest point
//! (`L_min / L`, at most 1, so that no pixel's noise grows and the thresholds set by the
//! measured noise stay safe). A background with structure of its own (a wall, a grid, a
//! dial) shows its surface's reflectance as much as the light and is left as it is.
//!
//! This assumes the light multiplies what the particles send (reflecting objects, or
//! fluorescence excited by the same light). A camera's black level adds to the background
//! and not to the particles: it reads the light as more even than it is, so the lean is
//! taken out in part, never reversed.

use super::model::{Background, BackgroundModel};
use crate::frames::CLIPPED;

/// Pixels of the background image the surface is fitted on at most (an even sample).
const LIGHT_SAMPLES: usize = 16_384;
/// Terms of the surface: every monomial `x^i y^j` with `i + j <= 3`.
const TERMS: usize = 10;
/// Fraction of the sampled pixels that must lie within [`INLIER_SIGMAS`] of the surface (a
/// Gaussian spot of 45 px hovering in a frame of 478 x 414 px leaves its skirt in a fifth
/// of the median, fresh style 6081).
const MIN_INLIERS: f64 = 0.75;
/// Residuals beyond this many robust standard deviations are left out of the fit (a
/// particle's leftover in the median, a speck).
const INLIER_SIGMAS: f64 = 3.0;
/// How many times the median's expected spread the residuals may spread for the surface to
/// count as the light.
const SMOOTH_FACTOR: f64 = 2.0;
/// Dimmest fitted light, grey levels, that a relative light is read from: below it the
/// fitted surface may reach black, where its inverse has no bound. A camera's black level
/// under a dark background reads the light as more even than it is (see the module
/// documentation): it is taken out in part.
const MIN_LEVEL: f64 = 4.0;
/// Least relative range of the light (`L_max / L_min − 1`) that is taken out: below it the
/// lean is under a hundredth of a pixel for particles up to 30 px.
const MIN_RANGE: f64 = 0.005;
/// Robust fitting rounds at most.
const ROUNDS: usize = 8;

/// The light over the frame relative to its dimmest point, as the signal is divided by it.
#[derive(Clone, Debug, PartialEq)]
pub struct Light {
    /// `L_min / L(x, y)` per pixel (row-major, in `(0, 1]`): what a pixel's signal is
    /// multiplied by.
    pub inverse: Vec<f32>,
    /// The fitted background per pixel and channel (row-major, `width * height * channels`),
    /// grey levels: what the background is where a particle hides it in every sample.
    pub surface: Vec<f32>,
    /// `L_max / L_min` over the frame.
    pub range: f64,
}

impl Background {
    /// The light read from this background's per-pixel image, if it is one smooth surface
    /// (see the module documentation), the pixels `skip` marks left out (no sample showed
    /// them clear); `None` for a constant background, a structured one, one near black or
    /// saturated, or one lit evenly.
    pub(super) fn read_light(&self, skip: Option<&[bool]>) -> Option<Light> {
        if self.model != BackgroundModel::PerPixel {
            return None;
        }
        let (pixels, c) = (self.width * self.height, self.channels);
        let stride = (pixels / LIGHT_SAMPLES).max(1) | 1;
        let values: Vec<(usize, &[f32])> = (0..pixels)
            .step_by(stride)
            .filter(|&i| !skip.is_some_and(|s| s[i]))
            .map(|i| (i, &self.image[i * c..(i + 1) * c]))
            .collect();
        self.light_from(&values)
    }

    /// The light read from the background values `values` (pixel index, its channels'
    /// levels), if they are one smooth surface, as [`Background::read_light`].
    fn light_from(&self, values: &[(usize, &[f32])]) -> Option<Light> {
        let (w, h, c) = (self.width, self.height, self.channels);
        if w < 8 || h < 8 {
            return None;
        }
        let pixels = w * h;
        let half = [0.5 * (w - 1) as f64, 0.5 * (h - 1) as f64];
        let mut points: Vec<([f64; TERMS], f64)> = Vec::with_capacity(values.len());
        let mut picked: Vec<&[f32]> = Vec::with_capacity(values.len());
        let mut clipped = 0usize;
        for &(i, px) in values {
            if px.iter().any(|&v| v >= CLIPPED) {
                clipped += 1;
                continue;
            }
            let level = px.iter().map(|&v| f64::from(v)).sum::<f64>() / c as f64;
            let (x, y) = unit(i, w, half);
            points.push((terms(x, y), level));
            picked.push(px);
        }
        let sampled = points.len() + clipped;
        if (points.len() as f64) < MIN_INLIERS * sampled as f64 || points.len() < 4 * TERMS {
            return None;
        }
        let (coefficients, spread, used) = robust_fit(&points)?;
        let inliers = used.iter().filter(|&&u| u).count();
        // The median's own noise over the samples, and the quantisation of 8-bit levels.
        let k = self.sample_count.max(1) as f64;
        let median_noise = 1.2533 * self.temporal_noise / k.sqrt();
        let expected = (median_noise * median_noise + 1.0 / 12.0).sqrt();
        if (inliers as f64) < MIN_INLIERS * sampled as f64 || spread > SMOOTH_FACTOR * expected {
            return None;
        }
        let mut light = vec![0.0f32; pixels];
        let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
        for (i, l) in light.iter_mut().enumerate() {
            let (x, y) = unit(i, w, half);
            let v = evaluate(&coefficients, x, y);
            lo = lo.min(v);
            hi = hi.max(v);
            *l = v as f32;
        }
        // The range must stand clear of the fit's own error (its values are known to about
        // `spread sqrt(TERMS / n)`).
        let fit_error = spread * (TERMS as f64 / inliers as f64).sqrt();
        if lo < MIN_LEVEL || hi / lo - 1.0 < MIN_RANGE || hi - lo < 10.0 * fit_error {
            return None;
        }
        // Each channel's surface, fitted on the same pixels: the light itself for grey frames.
        let surface = if c == 1 {
            light.clone()
        } else {
            let mut surface = vec![0.0f32; pixels * c];
            for ch in 0..c {
                let channel: Vec<([f64; TERMS], f64)> = points
                    .iter()
                    .zip(&picked)
                    .map(|((t, _), px)| (*t, f64::from(px[ch])))
                    .collect();
                let a = least_squares(&channel, &used)?;
                for (i, v) in surface.iter_mut().skip(ch).step_by(c).enumerate() {
                    let (x, y) = unit(i, w, half);
                    *v = evaluate(&a, x, y) as f32;
                }
            }
            surface
        };
        let lo32 = lo as f32;
        for l in &mut light {
            *l = lo32 / *l;
        }
        Some(Light {
            inverse: light,
            surface,
            range: hi / lo,
        })
    }
}

/// Pixel `i`'s coordinates in a frame `w` px wide, scaled to `[-1, 1]` by the half-extents
/// `half = [(w - 1) / 2, (h - 1) / 2]`.
fn unit(i: usize, w: usize, half: [f64; 2]) -> (f64, f64) {
    ((i % w) as f64 / half[0] - 1.0, (i / w) as f64 / half[1] - 1.0)
}

/// The surface with `coefficients` at `(x, y)` (scaled to `[-1, 1]`).
fn evaluate(coefficients: &[f64; TERMS], x: f64, y: f64) -> f64 {
    terms(x, y).iter().zip(coefficients).map(|(t, a)| t * a).sum()
}

/// The monomials `x^i y^j`, `i + j <= 3`, at `(x, y)` (coordinates scaled to `[-1, 1]`).
fn terms(x: f64, y: f64) -> [f64; TERMS] {
    [
        1.0,
        x,
        y,
        x * x,
        x * y,
        y * y,
        x * x * x,
        x * x * y,
        x * y * y,
        y * y * y,
    ]
}

/// Least squares fit of `points` (terms, value) over those `used`: the coefficients, or
/// `None` where they are not determined.
fn least_squares(points: &[([f64; TERMS], f64)], used: &[bool]) -> Option<[f64; TERMS]> {
    let mut m = nalgebra::SMatrix::<f64, TERMS, TERMS>::zeros();
    let mut v = nalgebra::SVector::<f64, TERMS>::zeros();
    for ((t, value), _) in points.iter().zip(used).filter(|(_, &u)| u) {
        let t = nalgebra::SVector::<f64, TERMS>::from_column_slice(t);
        m += t * t.transpose();
        v += t * *value;
    }
    let a = m.cholesky()?.solve(&v);
    let mut coefficients = [0.0; TERMS];
    coefficients.copy_from_slice(a.as_slice());
    Some(coefficients)
}

/// [`least_squares`] with residuals beyond [`INLIER_SIGMAS`] robust standard deviations
/// left out, iterated: the coefficients, the robust spread of the inliers' residuals (grey
/// levels) and which points are inliers.
fn robust_fit(points: &[([f64; TERMS], f64)]) -> Option<([f64; TERMS], f64, Vec<bool>)> {
    let mut used = vec![true; points.len()];
    let mut result = None;
    for _ in 0..ROUNDS {
        let a = least_squares(points, &used)?;
        let residual =
            |(t, value): &([f64; TERMS], f64)| value - t.iter().zip(&a).map(|(t, a)| t * a).sum::<f64>();
        let mut magnitudes: Vec<f64> = points
            .iter()
            .zip(&used)
            .filter(|(_, &u)| u)
            .map(|(p, _)| residual(p).abs())
            .collect();
        let mid = magnitudes.len() / 2;
        let spread = 1.4826 * *magnitudes.select_nth_unstable_by(mid, f64::total_cmp).1;
        // Whole grey levels: a spread under the quantisation's would leave out good pixels.
        let cut = INLIER_SIGMAS * spread.max(0.3);
        let next: Vec<bool> = points.iter().map(|p| residual(p).abs() <= cut).collect();
        let settled = next == used;
        let inliers = next.iter().filter(|&&u| u).count();
        result = Some((a, spread, next.clone()));
        if settled || inliers < 4 * TERMS {
            break;
        }
        used = next;
    }
    result
}
