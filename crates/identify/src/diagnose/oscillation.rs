//! The strongest oscillations of a sampled series: a least-squares (Lomb-Scargle)
//! periodogram of the series less its cubic trend, each peak refined by golden-section
//! search. A stiff tether's radial oscillation shows in its particle's distance from the
//! anchor; its angular frequency `ω` gives the stiffness `S = m ω² / 2` (energy
//! `S (l - L)²`, MODEL.md's convention), a start the multi-step fit cannot reach from a
//! soft one, since each frequency the recording holds a whole number of periods of is a
//! basin of its own.

use nalgebra::{DMatrix, DVector};

/// How many times the periodogram's median power a peak must hold to be heard: for noise
/// alone, the power at one frequency is exponentially distributed about its mean (`ln 2`
/// times the mean is the median), so a peak of 20 medians has a chance of `e^-13.9`
/// (1e-6) at each of the grid's few thousand frequencies.
pub const HEARD_OVER_MEDIAN: f64 = 20.0;

/// The power of the best sinusoid of angular frequency `omega` (rad/s) through `values`
/// sampled at `times` (s): the sum of squares it explains.
fn power(times: &[f64], values: &[f64], omega: f64) -> f64 {
    // Tau makes the sine and cosine columns orthogonal (Lomb 1976).
    let (s2, c2) = times.iter().fold((0.0, 0.0), |(s, c), t| {
        (s + (2.0 * omega * t).sin(), c + (2.0 * omega * t).cos())
    });
    let tau = s2.atan2(c2) / (2.0 * omega);
    let (mut yc, mut ys, mut cc, mut ss) = (0.0, 0.0, 0.0, 0.0);
    for (t, y) in times.iter().zip(values) {
        let (s, c) = (omega * (t - tau)).sin_cos();
        yc += y * c;
        ys += y * s;
        cc += c * c;
        ss += s * s;
    }
    let a = if cc > 0.0 { yc * yc / cc } else { 0.0 };
    let b = if ss > 0.0 { ys * ys / ss } else { 0.0 };
    a + b
}

/// The amplitudes `(a, b)` (units of `values`) of the least-squares `a cos ωt + b sin ωt`
/// through `values` (at `times`, s) less their cubic trend, at angular frequency `omega`
/// (rad/s); zeros when there are too few samples.
pub fn amplitudes(times: &[f64], values: &[f64], omega: f64) -> (f64, f64) {
    let n = times.len();
    if n < 6 || n != values.len() {
        return (0.0, 0.0);
    }
    let t0 = times[0];
    let span = (times[n - 1] - t0).max(f64::MIN_POSITIVE);
    let design = DMatrix::from_fn(n, 6, |i, j| match j {
        0 => (omega * times[i]).cos(),
        1 => (omega * times[i]).sin(),
        _ => ((times[i] - t0) / span * 2.0 - 1.0).powi(j as i32 - 2),
    });
    let y = DVector::from_column_slice(values);
    match design.svd(true, true).solve(&y, 1e-12) {
        Ok(c) => (c[0], c[1]),
        Err(_) => (0.0, 0.0),
    }
}

/// `values` less their least-squares cubic in `times`.
fn detrended(times: &[f64], values: &[f64]) -> Option<Vec<f64>> {
    let n = times.len();
    let t0 = times.first()?;
    let span = (times.last()? - t0).max(f64::MIN_POSITIVE);
    let design = DMatrix::from_fn(n, 4, |i, j| ((times[i] - t0) / span * 2.0 - 1.0).powi(j as i32));
    let y = DVector::from_column_slice(values);
    let coefficients = design.clone().svd(true, true).solve(&y, 1e-12).ok()?;
    Some((y - design * coefficients).iter().copied().collect())
}

/// Up to `count` angular frequencies (rad/s) between `low` and `high` at which `values`,
/// sampled at `times` (s) and less their cubic trend, oscillate most strongly, strongest
/// first; local maxima of the periodogram holding [`HEARD_OVER_MEDIAN`] times its median
/// power only, each refined to a small fraction of the resolution `2π / T`. Empty when
/// there are fewer than 12 samples or no such maximum.
pub fn strongest_frequencies(times: &[f64], values: &[f64], low: f64, high: f64, count: usize) -> Vec<f64> {
    if times.len() < 12 || times.len() != values.len() || !(low > 0.0 && high > low) {
        return Vec::new();
    }
    let Some(y) = detrended(times, values) else {
        return Vec::new();
    };
    let span = times[times.len() - 1] - times[0];
    if span.is_nan() || span <= 0.0 {
        return Vec::new();
    }
    // Four samples per resolution step.
    let step = std::f64::consts::PI / (2.0 * span);
    let steps = ((high - low) / step).ceil() as usize;
    let grid: Vec<(f64, f64)> = (0..=steps)
        .map(|i| {
            let w = low + step * i as f64;
            (w, power(times, &y, w))
        })
        .collect();
    let mut powers: Vec<f64> = grid.iter().map(|g| g.1).collect();
    let middle = powers.len() / 2;
    let median = *powers.select_nth_unstable_by(middle, f64::total_cmp).1;
    let mut peaks: Vec<(f64, f64)> = (1..grid.len().saturating_sub(1))
        .filter(|&i| grid[i].1 > grid[i - 1].1 && grid[i].1 >= grid[i + 1].1)
        .filter(|&i| grid[i].1 > HEARD_OVER_MEDIAN * median)
        .map(|i| refine(times, &y, grid[i - 1].0, grid[i + 1].0))
        .collect();
    peaks.sort_by(|a, b| b.1.total_cmp(&a.1));
    peaks.into_iter().take(count).map(|(w, _)| w).collect()
}

/// The maximum of the periodogram between `a` and `b` (rad/s) by golden-section search, and
/// its power.
fn refine(times: &[f64], y: &[f64], mut a: f64, mut b: f64) -> (f64, f64) {
    let ratio = (5f64.sqrt() - 1.0) / 2.0;
    let mut c = b - ratio * (b - a);
    let mut d = a + ratio * (b - a);
    let (mut fc, mut fd) = (power(times, y, c), power(times, y, d));
    for _ in 0..40 {
        if fc > fd {
            b = d;
            d = c;
            fd = fc;
            c = b - ratio * (b - a);
            fc = power(times, y, c);
        } else {
            a = c;
            c = d;
            fc = fd;
            d = a + ratio * (b - a);
            fd = power(times, y, d);
        }
    }
    if fc > fd {
        (c, fc)
    } else {
        (d, fd)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    #[test]
    fn finds_a_small_oscillation_on_a_trend_under_noise() {
        let mut rng = rand::rngs::StdRng::seed_from_u64(7);
        for _ in 0..20 {
            let fps: f64 = rng.gen_range(24.0..240.0);
            let n = rng.gen_range(60..400);
            let omega = rng.gen_range(0.1..0.8) * std::f64::consts::PI * fps;
            let phase = rng.gen_range(0.0..6.3);
            let times: Vec<f64> = (0..n).map(|k| k as f64 / fps).collect();
            let values: Vec<f64> = times
                .iter()
                .map(|t| {
                    230.0 + 3.0 * t - 0.5 * t * t
                        + 0.05 * (omega * t + phase).sin()
                        + rng.gen_range(-0.01..0.01)
                })
                .collect();
            let found = strongest_frequencies(&times, &values, 0.05 * fps, std::f64::consts::PI * fps, 1);
            let span = times[n - 1];
            assert!(
                (found[0] - omega).abs() < 0.05 * std::f64::consts::TAU / span,
                "fps {fps}, n {n}: {} against {omega}",
                found[0]
            );
        }
    }

    #[test]
    fn noise_alone_is_not_heard() {
        let mut rng = rand::rngs::StdRng::seed_from_u64(11);
        let mut heard = 0;
        for _ in 0..50 {
            let n = rng.gen_range(30..600);
            let times: Vec<f64> = (0..n).map(|k| k as f64 / 100.0).collect();
            let values: Vec<f64> = times.iter().map(|t| 5.0 * t + rng.gen_range(-1.0..1.0)).collect();
            heard += strongest_frequencies(&times, &values, 1.0, 300.0, 3).len();
        }
        assert!(heard <= 1, "{heard} peaks heard in noise alone");
    }

    #[test]
    fn too_few_samples_give_nothing() {
        let times: Vec<f64> = (0..8).map(f64::from).collect();
        assert!(strongest_frequencies(&times, &times, 0.1, 3.0, 3).is_empty());
    }
}
