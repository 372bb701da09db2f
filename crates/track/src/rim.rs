//! The centre of a hollow particle's rim: the point from which the rim lies equally far in
//! every direction.
//!
//! A ring (a bright rim, the background inside) has no mass at its centre, and an
//! intensity-weighted centroid of it is pulled by whatever makes one side of the rim
//! brighter than the other: a background left uneven round it (a ring that hovered over
//! some of the samples leaves part of itself in a per-pixel median), a gradient, a
//! neighbour's light. Where the rim *is* does not depend on how bright it is. Seen from a
//! point `δ` off the rim's centre, the rim's radius in direction `θ` is
//! `r(θ) ≈ r₀ + δx cos θ + δy sin θ`; the fit of that curve to every pixel of the rim's
//! band, each weighted by its signal, gives `δ` directly, and each direction's intensity
//! only weighs its own radius, never moves it. Iterated from the point until it moves
//! under a thousandth of a pixel, the fixed point is the rim's centre (the radial-symmetry
//! idea of Parthasarathy 2012, Nat. Methods 9:724, on the rim's position rather than the
//! intensity gradient).

use nalgebra::{Matrix3, Vector3};

/// Most rounds of [`rim_centre`]'s iteration.
const ROUNDS: usize = 20;
/// [`rim_centre`] stops when a round moves the centre by less than this, px.
const SETTLED: f64 = 1e-3;
/// A particle is hollow where the mean of its core (within half the rim's radius) stands
/// under this fraction of its rim's peak: a ring blurred by a third of its radius still
/// dips to 0.5-0.7 there; a disc, a spot, a shaded sphere or a textured ball (whose texture
/// averages out round each ring) peaks at its core.
const DEPTH: f64 = 0.8;
/// Most stages of [`rim_centre`] (the rim's band measured again about the last centre).
const STAGES: usize = 3;
/// [`rim_centre`] stops when a stage moves the centre by less than this, px.
const STAGE_SETTLED: f64 = 0.01;

/// A hollow particle's rim seen from a tracked point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Rim {
    /// The rim's centre less the point, px (x right, y down).
    pub(crate) offset: [f64; 2],
    /// Standard error of each component of `offset` from the pixel noise, px (the larger
    /// of the two).
    pub(crate) error: f64,
    /// The rim's mean radius about its centre, px.
    pub(crate) radius: f64,
}

/// Most and fewest azimuthal sectors [`rim_is_closed`] reads a rim in.
const SECTORS: [usize; 2] = [8, 32];
/// Pixels of the band each sector of [`rim_is_closed`] should hold, about.
const SECTOR_PIXELS: f64 = 12.0;
/// Least mean signal of every sector of a closed rim's band, as a fraction of the band's.
const SECTOR_SHARE: f64 = 0.25;

/// Whether the rim of radius `radius` px about `centre` (px) in `signal` (`width * height`,
/// grey levels, particles positive) runs all round: in each azimuthal sector of its band
/// (`radius` ± a sixth of it and a pixel; 8-32 sectors of about [`SECTOR_PIXELS`] each) that
/// holds half its pixels in the frame or more, the mean signal is at least [`SECTOR_SHARE`] of the whole
/// band's (positive). A ring is closed, one side brighter or cut by the border; the near
/// sides of two rings side by side, seen from between them, make a hollow "rim" about their
/// midpoint as well, but one that is dark where it crosses the gap between them.
pub(crate) fn rim_is_closed(
    signal: &[f32],
    width: usize,
    height: usize,
    centre: [f64; 2],
    radius: f64,
) -> bool {
    let half = radius / 6.0 + 1.0;
    let (inner, outer) = ((radius - half).max(0.0), radius + half);
    let area = std::f64::consts::PI * (outer * outer - inner * inner);
    let sectors = ((area / SECTOR_PIXELS) as usize).clamp(SECTORS[0], SECTORS[1]);
    let mut sum = [0.0f64; SECTORS[1]];
    let mut count = [0usize; SECTORS[1]];
    let x0 = (centre[0] - outer).floor().max(0.0) as usize;
    let y0 = (centre[1] - outer).floor().max(0.0) as usize;
    let x1 = ((centre[0] + outer).ceil() as i64).min(width as i64 - 1);
    let y1 = ((centre[1] + outer).ceil() as i64).min(height as i64 - 1);
    if x1 < 0 || y1 < 0 {
        return false;
    }
    for y in y0..=y1 as usize {
        for x in x0..=x1 as usize {
            let (dx, dy) = (x as f64 - centre[0], y as f64 - centre[1]);
            let d = dx.hypot(dy);
            if d < inner || d > outer {
                continue;
            }
            let turn = (dy.atan2(dx) / std::f64::consts::TAU).rem_euclid(1.0);
            let k = ((turn * sectors as f64) as usize).min(sectors - 1);
            sum[k] += f64::from(signal[y * width + x]);
            count[k] += 1;
        }
    }
    let total: usize = count.iter().sum();
    if total == 0 {
        return false;
    }
    let band = sum.iter().sum::<f64>() / total as f64;
    // A sector the border cuts to less than half its pixels is not judged (what is left of
    // it may be the band's edge alone).
    let judged = 0.5 * area / sectors as f64;
    band > 0.0
        && (0..sectors)
            .filter(|&k| count[k] as f64 >= judged)
            .all(|k| sum[k] / count[k] as f64 >= SECTOR_SHARE * band)
}

/// Rays [`encircled`] casts from a point.
const RAYS: usize = 16;

/// Whether something bright encircles `point` (px) within `reach` px in `signal`
/// (`width * height`, grey levels, particles positive): along each of [`RAYS`] rays from it
/// (nearest pixels, 1 px apart, each the mean of three consecutive samples against the
/// noise), the brightest stands at [`SECTOR_SHARE`] of the brightest over all rays or more;
/// rays that leave the frame are not judged, and at least four must be. A cheap first test
/// before [`rim_centre`] and [`rim_is_closed`]: a point inside a ring is encircled, the
/// midpoint between two separate blobs (or clutter) only towards them.
pub(crate) fn encircled(signal: &[f32], width: usize, height: usize, point: [f64; 2], reach: f64) -> bool {
    let steps = reach.ceil() as usize;
    let mut brightest = [f64::NEG_INFINITY; RAYS];
    let mut judged = [false; RAYS];
    for (k, (b, j)) in brightest.iter_mut().zip(judged.iter_mut()).enumerate() {
        let angle = std::f64::consts::TAU * k as f64 / RAYS as f64;
        let (dx, dy) = (angle.cos(), angle.sin());
        let mut last = [0.0f64; 3];
        let mut inside = true;
        for step in 1..=steps {
            let (x, y) = (point[0] + dx * step as f64, point[1] + dy * step as f64);
            let (xi, yi) = (x.round(), y.round());
            if xi < 0.0 || yi < 0.0 || xi >= width as f64 || yi >= height as f64 {
                inside = false;
                break;
            }
            last[step % 3] = f64::from(signal[yi as usize * width + xi as usize]);
            if step >= 3 {
                *b = b.max((last[0] + last[1] + last[2]) / 3.0);
            }
        }
        *j = inside && steps >= 3;
    }
    let top = brightest.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let count = judged.iter().filter(|&&j| j).count();
    top > 0.0
        && count >= 4
        && (0..RAYS)
            .filter(|&k| judged[k])
            .all(|k| brightest[k] >= SECTOR_SHARE * top)
}

/// The rim of the hollow particle about `point` (px) in `signal` (`width * height`, grey
/// levels, particles positive), searched out to `reach` px, pixels nearer to any of
/// `others` (px) than to the point left out, under pixel noise `noise` (grey levels);
/// `None` where the particle is not hollow there.
///
/// The azimuthal profile about the point (one-pixel rings) must peak at some ring (the
/// rim) and stand under half that peak within half the rim's radius (hollow), the peak
/// 3 standard errors of the noise above zero. The rim's band runs from where the profile
/// falls to half its peak inside the rim to where it does outside (or `reach`), widened
/// by half its width either side so that a point off the centre still holds the rim; the
/// fit of `r₀ + δx cos θ + δy sin θ` to the radii of the band's pixels, weighted by their
/// positive signal (soft band edges, a pixel ramp, so the fit varies smoothly with the
/// point), is iterated from the point (see the module doc). `None` too where the centre
/// leaves the hollow (the rim's inner half-maximum radius), where it ends nearer to one of
/// `others` than to the point (the rim found is that neighbour's: the band follows the
/// centre, and a point between two rings can be drawn onto the other's rim), or the fit is
/// singular.
pub(crate) fn rim_centre(
    signal: &[f32],
    width: usize,
    height: usize,
    point: [f64; 2],
    others: &[[f64; 2]],
    reach: f64,
    noise: f64,
) -> Option<Rim> {
    if !(reach > 1.0 && point[0].is_finite() && point[1].is_finite()) {
        return None;
    }
    // Pixels within `r` of `c` that are nearer to `c` than to any of `others`.
    let pixels = |c: [f64; 2], r: f64, visit: &mut dyn FnMut(f64, f64, f64, f64)| {
        let x0 = (c[0] - r).floor().max(0.0) as usize;
        let y0 = (c[1] - r).floor().max(0.0) as usize;
        let x1 = ((c[0] + r).ceil().max(0.0) as usize).min(width.saturating_sub(1));
        let y1 = ((c[1] + r).ceil().max(0.0) as usize).min(height.saturating_sub(1));
        for y in y0..=y1 {
            let dy = y as f64 - c[1];
            for x in x0..=x1 {
                let dx = x as f64 - c[0];
                let d2 = dx * dx + dy * dy;
                if d2 >= r * r
                    || others
                        .iter()
                        .any(|q| (x as f64 - q[0]).powi(2) + (y as f64 - q[1]).powi(2) < d2)
                {
                    continue;
                }
                visit(dx, dy, d2.sqrt(), f64::from(signal[y * width + x]));
            }
        }
    };
    // The rim's band about `c`: from the azimuthal profile in one-pixel rings, `(lo, hi,
    // inner)` (the band's edges and the rim's inner half-maximum radius), or `None` where
    // the particle is not hollow about `c`.
    let band_about = |c: [f64; 2]| -> Option<(f64, f64, f64)> {
        let bins = reach.ceil() as usize;
        let mut sum = vec![0.0f64; bins];
        let mut count = vec![0usize; bins];
        pixels(c, reach, &mut |_, _, d, v| {
            let k = (d as usize).min(bins - 1);
            sum[k] += v;
            count[k] += 1;
        });
        let mean: Vec<f64> = sum
            .iter()
            .zip(&count)
            .map(|(&s, &n)| if n > 0 { s / n as f64 } else { f64::NAN })
            .collect();
        let (peak_at, peak) = mean
            .iter()
            .enumerate()
            .skip(1)
            .filter(|(_, m)| m.is_finite())
            .max_by(|a, b| a.1.total_cmp(b.1))
            .map(|(k, &m)| (k, m))?;
        if !(peak > 3.0 * noise / (count[peak_at] as f64).sqrt() && peak > 0.0) {
            return None;
        }
        let rim = peak_at as f64 + 0.5;
        let core_bins = ((0.5 * rim) as usize).max(1);
        let (core_sum, core_count) =
            (0..core_bins).fold((0.0, 0usize), |(s, n), k| (s + sum[k], n + count[k]));
        if core_count == 0 {
            return None;
        }
        let core = core_sum / core_count as f64;
        // Hollow: the core stands under DEPTH of the peak, by 3 standard errors of the noise
        // at least. The rim's band lies between the crossings of the level half way from the
        // core (or zero) to the peak: a thin ring's half maximum, a blurred one's mid-rim.
        let dip = 3.0 * noise * (1.0 / count[peak_at] as f64 + 1.0 / core_count as f64).sqrt();
        if core >= DEPTH * peak || peak - core <= dip {
            return None;
        }
        let half = 0.5 * (core.max(0.0) + peak);
        // Where the profile crosses half the peak, inside and outside the rim, interpolated
        // between ring centres.
        let crossing = |ks: &mut dyn Iterator<Item = usize>| -> Option<f64> {
            let mut last = (rim, peak);
            for k in ks {
                let m = mean[k];
                if !m.is_finite() {
                    continue;
                }
                let at = k as f64 + 0.5;
                if m < half {
                    return Some(last.0 + (at - last.0) * (last.1 - half) / (last.1 - m));
                }
                last = (at, m);
            }
            None
        };
        let inner = crossing(&mut (0..peak_at).rev())?;
        let outer = crossing(&mut (peak_at + 1..bins)).unwrap_or(reach);
        let margin = 0.5 * (outer - inner);
        Some(((inner - margin).max(0.5), outer + margin, inner))
    };
    let mut centre = point;
    let mut fit = Vector3::zeros();
    let mut inverse = Matrix3::zeros();
    let (mut lo, mut hi) = (0.0, 0.0);
    // The band is measured again about each stage's centre: seen from a point off the
    // centre the rim is smeared over a wider band, which is not centred on the rim, and the
    // noise's positive part pulls each direction's radius towards the band's middle, the
    // more where the rim is faint (a bias in the direction of the rim's brightness).
    for _ in 0..STAGES {
        let (stage_lo, stage_hi, inner) = band_about(centre)?;
        (lo, hi) = (stage_lo, stage_hi);
        let band = |d: f64| ((d - lo + 0.5).clamp(0.0, 1.0) * (hi + 0.5 - d).clamp(0.0, 1.0)).max(0.0);
        let start = centre;
        for _ in 0..ROUNDS {
            let mut a = Matrix3::zeros();
            let mut b = Vector3::zeros();
            pixels(centre, hi + 0.5, &mut |dx, dy, d, v| {
                let w = v.max(0.0) * band(d);
                if w <= 0.0 || d <= 0.0 {
                    return;
                }
                let x = Vector3::new(1.0, dx / d, dy / d);
                a += w * x * x.transpose();
                b += w * d * x;
            });
            inverse = a.try_inverse()?;
            fit = inverse * b;
            centre = [centre[0] + fit[1], centre[1] + fit[2]];
            let moved = (centre[0] - start[0]).hypot(centre[1] - start[1]);
            if moved.is_nan() || moved >= inner {
                return None;
            }
            if fit[1].hypot(fit[2]) < SETTLED {
                break;
            }
        }
        if (centre[0] - start[0]).hypot(centre[1] - start[1]) < STAGE_SETTLED {
            break;
        }
    }
    let band = |d: f64| ((d - lo + 0.5).clamp(0.0, 1.0) * (hi + 0.5 - d).clamp(0.0, 1.0)).max(0.0);
    // Noise in a pixel's signal moves the fit by its weight's share: the covariance of the
    // fit is `σ² A⁻¹ (Σ s² x xᵀ (d − xᵀθ)²) A⁻¹` over the pixels of positive signal (`s`
    // the band share), with θ the fit about the centre (its last step, under `SETTLED`).
    let mut spread = Matrix3::zeros();
    let last = [centre[0] - fit[1], centre[1] - fit[2]];
    pixels(last, hi + 0.5, &mut |dx, dy, d, v| {
        let s = band(d);
        if v <= 0.0 || s <= 0.0 || d <= 0.0 {
            return;
        }
        let x = Vector3::new(1.0, dx / d, dy / d);
        let r = d - fit.dot(&x);
        spread += (s * r).powi(2) * x * x.transpose();
    });
    let covariance = noise * noise * inverse * spread * inverse;
    let from_point = (centre[0] - point[0]).hypot(centre[1] - point[1]);
    if others
        .iter()
        .any(|q| (centre[0] - q[0]).hypot(centre[1] - q[1]) < from_point)
    {
        return None;
    }
    Some(Rim {
        offset: [centre[0] - point[0], centre[1] - point[1]],
        error: covariance[(1, 1)].max(covariance[(2, 2)]).max(0.0).sqrt(),
        radius: fit[0],
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// A ring of radii `inner`-`outer` (px) at `c`, contrast `amp`, its brightness
    /// `1 + tilt cos θ` round it (one side brighter), on `size x size`, 4 x 4 samples a pixel.
    fn ring(size: usize, c: [f64; 2], inner: f64, outer: f64, amp: f64, tilt: f64) -> Vec<f32> {
        (0..size * size)
            .map(|i| {
                let (px, py) = ((i % size) as f64, (i / size) as f64);
                let mut v = 0.0;
                for sy in 0..4 {
                    for sx in 0..4 {
                        let x = px - 0.375 + 0.25 * sx as f64 - c[0];
                        let y = py - 0.375 + 0.25 * sy as f64 - c[1];
                        let d = x.hypot(y);
                        if d >= inner && d <= outer {
                            v += 1.0 + tilt * x / d.max(1e-9);
                        }
                    }
                }
                (amp * v / 16.0) as f32
            })
            .collect()
    }

    /// A ring of 20 px reads closed about its centre, also when the frame's border cuts it
    /// and when one side is 60 % brighter; two such rings side by side (their rims 4 px
    /// apart) do not about the midpoint between them, though the rim fit about that point
    /// finds a hollow "rim" of 9 px through their near sides (without this test, the join of
    /// one ring's arcs joined ring neighbour 3001's two rings of 20 px: 2.5 / 3.6 px off).
    #[test]
    fn a_ring_is_closed_and_two_rings_side_by_side_are_not() {
        let size = 100;
        let c = [50.3, 49.8];
        let one = ring(size, c, 15.0, 21.0, 100.0, 0.0);
        assert!(rim_is_closed(&one, size, size, c, 18.0));
        let lopsided = ring(size, c, 15.0, 21.0, 100.0, 0.6);
        assert!(rim_is_closed(&lopsided, size, size, c, 18.0));
        let cut = ring(size, [12.4, 49.8], 15.0, 21.0, 100.0, 0.0);
        assert!(rim_is_closed(&cut, size, size, [12.4, 49.8], 18.0));
        let (wide, height) = (140, 100);
        let pair: Vec<f32> = {
            let left = ring(wide, [45.0, 50.0], 15.0, 21.0, 100.0, 0.0);
            let right = ring(wide, [91.0, 50.0], 15.0, 21.0, 100.0, 0.0);
            // `ring` draws on a square: keep the first `height` rows.
            left.iter()
                .zip(&right)
                .take(wide * height)
                .map(|(a, b)| a + b)
                .collect()
        };
        let mid = [68.0, 50.0];
        let rim =
            rim_centre(&pair, wide, height, mid, &[], 32.0, 1.0).expect("a hollow rim about the midpoint");
        let centre = [mid[0] + rim.offset[0], mid[1] + rim.offset[1]];
        assert!(
            !rim_is_closed(&pair, wide, height, centre, rim.radius),
            "rim {rim:?}"
        );
    }

    /// Points inside a ring of 20 px (its centre, and 0.4 of its radius off, where the
    /// midpoint of two of its thirds lies) are encircled, also when the border cuts the ring;
    /// the midpoint between two discs 30 px apart is not, nor a point in the background.
    #[test]
    fn a_point_inside_a_ring_is_encircled_and_one_between_blobs_is_not() {
        let size = 100;
        let c = [50.3, 49.8];
        let one = ring(size, c, 15.0, 21.0, 100.0, 0.3);
        assert!(encircled(&one, size, size, c, 32.0));
        assert!(encircled(&one, size, size, [c[0] + 7.0, c[1] - 4.0], 32.0));
        let cut = ring(size, [12.4, 49.8], 15.0, 21.0, 100.0, 0.0);
        assert!(encircled(&cut, size, size, [12.4, 49.8], 32.0));
        let two: Vec<f32> = (0..size * size)
            .map(|i| {
                let (x, y) = ((i % size) as f64, (i / size) as f64);
                let near = |cx: f64| (x - cx).hypot(y - 50.0) <= 6.0;
                if near(35.0) || near(65.0) {
                    100.0
                } else {
                    0.0
                }
            })
            .collect();
        assert!(!encircled(&two, size, size, [50.0, 50.0], 32.0));
        assert!(!encircled(&vec![0.0; size * size], size, size, c, 32.0));
    }

    /// Seen from points up to a third of the radius off, rings of 4-20 px (rims 0.2-0.35 of
    /// the radius, one side up to 60 % brighter than the other) under noise 5 give their
    /// centre within 4 standard errors (and the error within 2 to 0.5 times the spread over
    /// draws); an intensity centroid of the brighter-sided ring is off by far more.
    #[test]
    fn a_rings_centre_is_found_from_off_centre_points_whatever_its_brightness_round_it() {
        let mut rng = ChaCha8Rng::seed_from_u64(20);
        for &radius in &[4.0, 6.0, 9.0, 14.0, 20.0] {
            let size = (2.0 * radius + 24.0) as usize;
            for _ in 0..6 {
                let c = [
                    size as f64 / 2.0 + rng.gen_range(-0.5..0.5),
                    size as f64 / 2.0 + rng.gen_range(-0.5..0.5),
                ];
                let width = rng.gen_range(0.2..0.35) * radius;
                let tilt = rng.gen_range(0.0..0.6);
                let clean = ring(size, c, radius - width, radius, 120.0, tilt);
                let noisy: Vec<f32> = clean
                    .iter()
                    .map(|&v| {
                        let n: f64 = (0..12).map(|_| rng.gen::<f64>()).sum::<f64>() - 6.0;
                        v + (5.0 * n) as f32
                    })
                    .collect();
                let off = radius / 3.0 * rng.gen_range(0.0..1.0);
                let angle = rng.gen_range(0.0..std::f64::consts::TAU);
                let p = [c[0] + off * angle.cos(), c[1] + off * angle.sin()];
                let rim = rim_centre(&noisy, size, size, p, &[], 1.5 * radius + 2.0, 5.0)
                    .unwrap_or_else(|| panic!("ring of {radius} px seen from {off:.2} px off: no rim"));
                let got = [p[0] + rim.offset[0], p[1] + rim.offset[1]];
                let miss = (got[0] - c[0]).hypot(got[1] - c[1]);
                assert!(
                    miss < 4.0 * rim.error.max(0.01),
                    "ring {radius} px, rim {width:.2}, tilt {tilt:.2}, from {off:.2} px off: {miss:.3} px, error {:.3}",
                    rim.error
                );
                assert!(
                    (rim.radius - (radius - 0.5 * width)).abs() < 0.5 * width + 0.5,
                    "{rim:?}"
                );
            }
        }
    }

    /// A flat disc and a Gaussian spot are not hollow: no rim.
    #[test]
    fn discs_and_spots_have_no_rim() {
        let disc = ring(40, [20.2, 19.7], 0.0, 8.0, 100.0, 0.0);
        assert_eq!(rim_centre(&disc, 40, 40, [20.0, 20.0], &[], 14.0, 1.0), None);
        let spot: Vec<f32> = (0..1600)
            .map(|i| {
                let d2 = ((i % 40) as f64 - 20.3).powi(2) + ((i / 40) as f64 - 19.6).powi(2);
                (100.0 * (-d2 / 32.0).exp()) as f32
            })
            .collect();
        assert_eq!(rim_centre(&spot, 40, 40, [20.0, 20.0], &[], 14.0, 1.0), None);
    }
}
