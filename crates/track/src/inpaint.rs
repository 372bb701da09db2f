//! Filling unknown pixels of an image from the known ones around them.
//!
//! Where a particle covers the same pixels in every frame (a large ball that barely moves),
//! no frame shows the background there: the per-pixel median is the particle itself. Such
//! pixels are filled with the harmonic interpolation of the pixels around them (each filled
//! pixel the mean of its four neighbours), which reproduces any linear ramp of light exactly
//! and a smooth vignetting to a small fraction of its curvature over the gap.

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

    #[test]
    fn nothing_known_or_nothing_unknown_changes_nothing() {
        let mut image = vec![7.0f32; 12];
        harmonic_fill(&mut image, 4, 3, 1, &[true; 12]);
        assert_eq!(image, vec![7.0f32; 12]);
        harmonic_fill(&mut image, 4, 3, 1, &[false; 12]);
        assert_eq!(image, vec![7.0f32; 12]);
    }
}
