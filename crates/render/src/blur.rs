//! Separable Gaussian blur of a float plane, the optical blur of a camera.

/// Kernel half-width in standard deviations: the truncated tails hold under 1e-4 of the weight.
const KERNEL_SIGMAS: f64 = 4.0;

/// A normalised 1-D Gaussian kernel of standard deviation `sigma` px, truncated at
/// `KERNEL_SIGMAS` sigma; its taps sum to 1 so the blur preserves total intensity.
pub(crate) fn gaussian_kernel(sigma: f64) -> Vec<f32> {
    let half = (KERNEL_SIGMAS * sigma).ceil().max(1.0) as usize;
    let mut k: Vec<f64> = (0..=2 * half)
        .map(|t| {
            let d = t as f64 - half as f64;
            (-0.5 * d * d / (sigma * sigma)).exp()
        })
        .collect();
    let sum: f64 = k.iter().sum();
    k.iter_mut().for_each(|v| *v /= sum);
    k.into_iter().map(|v| v as f32).collect()
}

/// Blurs a row-major `width × height` plane in place with `kernel` (odd length) along x then y,
/// using `scratch` (resized as needed). Samples beyond the border repeat the edge pixel, so a
/// constant plane stays constant; away from the border the total is preserved exactly.
pub(crate) fn blur_plane(
    plane: &mut [f32],
    width: usize,
    height: usize,
    kernel: &[f32],
    scratch: &mut Vec<f32>,
) {
    let half = kernel.len() / 2;
    scratch.clear();
    scratch.resize(plane.len(), 0.0);
    // Along x: plane -> scratch.
    for (src, dst) in plane.chunks_exact(width).zip(scratch.chunks_exact_mut(width)) {
        for (x, out) in dst.iter_mut().enumerate() {
            let mut acc = 0.0f32;
            for (t, &w) in kernel.iter().enumerate() {
                let xs = (x + t).saturating_sub(half).min(width - 1);
                acc += w * src[xs];
            }
            *out = acc;
        }
    }
    // Along y: scratch -> plane, a whole row at a time so memory is read in order.
    for (y, dst) in plane.chunks_exact_mut(width).enumerate() {
        dst.fill(0.0);
        for (t, &w) in kernel.iter().enumerate() {
            let ys = (y + t).saturating_sub(half).min(height - 1);
            let src = &scratch[ys * width..(ys + 1) * width];
            for (o, &s) in dst.iter_mut().zip(src) {
                *o += w * s;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn kernel_is_normalised_with_the_right_spread() {
        let sigma = 1.7;
        let k = gaussian_kernel(sigma);
        let half = (k.len() / 2) as f64;
        let sum: f64 = k.iter().map(|&v| v as f64).sum();
        let var: f64 = k
            .iter()
            .enumerate()
            .map(|(t, &v)| v as f64 * (t as f64 - half).powi(2))
            .sum();
        assert!((sum - 1.0).abs() < 1e-6);
        assert!((var.sqrt() - sigma).abs() < 1e-3, "spread {}", var.sqrt());
    }

    #[test]
    fn blurred_point_has_the_kernel_variance_and_constant_stays_constant() {
        let (w, h) = (41, 41);
        let mut plane = vec![0.0f32; w * h];
        plane[20 * w + 20] = 1.0;
        let mut scratch = Vec::new();
        let sigma = 2.0;
        blur_plane(&mut plane, w, h, &gaussian_kernel(sigma), &mut scratch);
        let total: f64 = plane.iter().map(|&v| v as f64).sum();
        let var_x: f64 = plane
            .iter()
            .enumerate()
            .map(|(p, &v)| v as f64 * ((p % w) as f64 - 20.0).powi(2))
            .sum();
        assert!((total - 1.0).abs() < 1e-5);
        assert!((var_x - sigma * sigma).abs() < 1e-2, "variance {var_x}");

        let mut flat = vec![0.25f32; w * h];
        blur_plane(&mut flat, w, h, &gaussian_kernel(3.0), &mut scratch);
        assert!(flat.iter().all(|&v| (v - 0.25).abs() < 1e-6));
    }
}
