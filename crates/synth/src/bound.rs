//! The Cramér-Rao bound of a particle's position under white Gaussian pixel noise.

use crate::blur::blur_plane;
use crate::look::{add_particle, ParticleLook};
use crate::style::Style;

/// The Cramér-Rao lower bound of the variance of any unbiased estimate of a particle's
/// position on each axis, px².
///
/// For white Gaussian pixel noise of standard deviation `σ` (per pixel and channel) and a
/// noise-free particle image `I`, the Fisher information of the x position is
/// `Σ_pixels Σ_channels (∂I/∂x)² / σ²`, so `CRB_x = σ² / Σ (∂I/∂x)²` (Kay, *Fundamentals of
/// Statistical Signal Processing: Estimation Theory*, 1993, §3.9). `∂I/∂x` is taken by central
/// differences (±0.05 px) of the rendered, blurred particle with the style's contrast, at unit
/// gain and light (the frame's centre) and without quantisation or clipping. The bound of a
/// recording is the mean over its particles (the bound of the mean square error over them).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PositionBound {
    /// Variance bound on x and y, px².
    pub variance: [f64; 2],
}

impl PositionBound {
    /// The bound as a standard deviation on x and y, px.
    pub fn sigma(&self) -> [f64; 2] {
        self.variance.map(f64::sqrt)
    }
}

/// Offset of the central difference, px.
const STEP: f64 = 0.05;

/// The bound for `style`'s noise and the particles `looks` (see [`PositionBound`]).
pub fn cramer_rao(style: &Style, looks: &[ParticleLook]) -> PositionBound {
    let contrast2: f64 = (0..if style.colour { 3 } else { 1 })
        .map(|c| (style.foreground[c] - style.background[c]).powi(2))
        .sum();
    let mut variance = [0.0; 2];
    for look in looks {
        let side = (2.0 * (look.reach() + 4.0 * style.blur + 4.0)).ceil() as usize;
        let c = 0.5 * side as f64 + 0.3;
        let image = |dx: f64, dy: f64| {
            let mut plane = vec![0.0; side * side];
            add_particle(&mut plane, side, side, look, [c + dx, c + 0.2 + dy], &|_, _| 1.0);
            blur_plane(&mut plane, side, side, style.blur);
            plane
        };
        for (axis, v) in variance.iter_mut().enumerate() {
            let (d, e) = if axis == 0 { (STEP, 0.0) } else { (0.0, STEP) };
            let (plus, minus) = (image(d, e), image(-d, -e));
            let fisher: f64 = plus
                .iter()
                .zip(&minus)
                .map(|(p, m)| ((p - m) / (2.0 * STEP)).powi(2))
                .sum::<f64>()
                * contrast2;
            *v += style.noise * style.noise / fisher / looks.len() as f64;
        }
    }
    PositionBound { variance }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::style::Profile;

    fn gaussian_style(noise: f64) -> (Style, Vec<ParticleLook>) {
        let mut style = Style::random(1);
        style.profile = Profile::Gaussian;
        style.colour = false;
        style.blur = 0.0;
        style.background = [20.0; 3];
        style.foreground = [120.0; 3];
        style.noise = noise;
        let look = ParticleLook::new(&style.profile, 6.0, 0);
        (style, vec![look])
    }

    #[test]
    fn bound_scales_as_the_noise_variance() {
        let (a, looks) = gaussian_style(10.0);
        let (b, _) = gaussian_style(20.0);
        let (va, vb) = (cramer_rao(&a, &looks).variance, cramer_rao(&b, &looks).variance);
        for axis in 0..2 {
            assert!((vb[axis] / va[axis] - 4.0).abs() < 1e-9, "{va:?} {vb:?}");
        }
    }

    #[test]
    fn bound_of_a_wide_gaussian_spot_is_the_continuous_one() {
        // I = A exp(-ρ²/2s²): Σ (∂I/∂x)² -> A² π / 2 for s well above a pixel, whatever s.
        let (style, looks) = gaussian_style(10.0);
        let v = cramer_rao(&style, &looks).variance;
        let expected = 2.0 * 100.0 / (std::f64::consts::PI * 100.0 * 100.0);
        for axis in 0..2 {
            assert!(
                (v[axis] / expected - 1.0).abs() < 0.01,
                "{v:?} against {expected}"
            );
        }
    }
}
