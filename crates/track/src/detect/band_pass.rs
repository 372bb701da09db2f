//! The band-pass filter's box size and the noise of its response.

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
