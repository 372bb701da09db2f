//! Separable Gaussian blur of a plane (zero outside it).

/// Blurs the `width x height` plane in place with a Gaussian of standard deviation `sigma`
/// px (taps out to `4 sigma`, normalised to sum 1); `sigma < 0.05` leaves it unchanged.
/// Values outside the plane count as zero (particles are kept clear of the border).
pub fn blur_plane(plane: &mut [f64], width: usize, height: usize, sigma: f64) {
    if sigma.is_nan() || sigma < 0.05 || width == 0 || height == 0 {
        return;
    }
    let reach = (4.0 * sigma).ceil() as usize;
    let mut kernel: Vec<f64> = (0..=2 * reach)
        .map(|i| {
            let d = i as f64 - reach as f64;
            (-d * d / (2.0 * sigma * sigma)).exp()
        })
        .collect();
    let total: f64 = kernel.iter().sum();
    kernel.iter_mut().for_each(|k| *k /= total);
    let mut tmp = vec![0.0; plane.len()];
    for y in 0..height {
        let row = &plane[y * width..(y + 1) * width];
        for x in 0..width {
            let mut acc = 0.0;
            for (t, k) in kernel.iter().enumerate() {
                let xs = x as isize + t as isize - reach as isize;
                if xs >= 0 && (xs as usize) < width {
                    acc += k * row[xs as usize];
                }
            }
            tmp[y * width + x] = acc;
        }
    }
    for y in 0..height {
        for x in 0..width {
            let mut acc = 0.0;
            for (t, k) in kernel.iter().enumerate() {
                let ys = y as isize + t as isize - reach as isize;
                if ys >= 0 && (ys as usize) < height {
                    acc += k * tmp[ys as usize * width + x];
                }
            }
            plane[y * width + x] = acc;
        }
    }
}
