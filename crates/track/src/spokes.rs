//! Lines that leave a particle: a spring drawn between two masses, a pendulum's string, a
//! rod. Where such a line crosses the rim of a particle's centroid window it adds its own
//! light to one side and pulls the centroid towards it (discs of 6 px joined by lines 2 px
//! wide, drawn as bright as the discs: 0.14-0.16 px off, where the noise allowed 0.006).
//!
//! A spoke shows in the ring just beyond the window (from its reach to a quarter of a radius
//! and two pixels farther): split into sectors of about two pixels of arc, the sectors a line
//! crosses stand above the ring's typical sector (the median of the sectors' means, which
//! holds a blurred or lit particle's own skirt) by more than the noise can put there in any
//! of the sectors (`sqrt(2 ln(n / 0.001))` standard errors of a sector's mean over `n`
//! sectors: one false spoke in a thousand rings of pure noise) and by a twentieth of the
//! particle's mean level (a fainter line moves a particle by less than a twentieth of the
//! sweep's bound). Each run of such sectors is cut out of the window by a half-plane at the
//! particle's radius, and so is the opposite side: the window's weights stay symmetric about
//! the estimate, so a particle that is symmetric about its centre (a disc, a spot, a ball, a
//! square) is located without bias, its own pixels on both sides of the cuts alike.

use std::f64::consts::TAU;

/// False spokes allowed per ring of pure noise: the sector test's threshold is that
/// many-in-one of the largest of the ring's sector means.
const FALSE_RATE: f64 = 1e-3;

/// Least excess of a spoke's sector over the ring's typical sector, as a fraction of the
/// particle's mean level: a line of a twentieth of a disc's contrast, two pixels wide,
/// crossing the window's one-and-a-half-pixel rim of a disc of 2 px moves its centroid by
/// about 0.03 px, under the sweep's least bound (0.05 px).
const LEAST_EXCESS: f64 = 0.05;

/// Arc of one sector at the ring's middle radius, px.
const SECTOR_ARC: f64 = 2.0;

/// Widest run of sectors one cut stands for, as a fraction of the angle its half-plane
/// spans in the window (a cut at `R − 1/2` removes the window's cap within
/// `acos((R − 1/2) / (R + 3/2))` of its normal, 43 degrees at 6 px, 15 at 60 px): wider runs
/// are cut in several places.
const WIDEST_CUT: f64 = 0.7;

/// Width of the shells whose median signal is the ring's radial profile, px.
const SHELL: f64 = 0.5;

/// Least pixels in a sector for it to be judged.
const LEAST_PIXELS: usize = 3;

/// The ring a particle's spokes are looked for in, px: from the centroid window's reach
/// (`window + 1/2`) to a quarter of the radius and two pixels beyond it.
fn spoke_ring(radius: f64, window: f64) -> (f64, f64) {
    let inner = window + 0.5;
    (inner, inner + 2.0 + 0.25 * radius)
}

/// The directions (unit vectors, y down) of the lines leaving the particle `image` is about,
/// a particle of radius `radius` px located in a window of radius `window` px whose mean level
/// is `level` (grey levels), under pixel noise `noise_sigma` (grey levels). A line stands out
/// in the ring just beyond the window and again, within a sector either way, in the ring of
/// the same width beyond that one: a corner of a square, a neighbour's edge or a speck ends
/// within a few pixels, a line goes on; and it is narrower than the particle's radius (or
/// three sectors) across the ring, where a reflection below a ball, a shadow or a neighbour's
/// edge is about as wide as a particle. Empty where no line is found.
pub(crate) fn spokes(
    image: &About<'_>,
    radius: f64,
    window: f64,
    level: f64,
    noise_sigma: f64,
) -> Vec<[f64; 2]> {
    let (inner, outer) = spoke_ring(radius, window);
    let middle = 0.5 * (inner + outer);
    let count = sector_count(inner, outer);
    let test = SectorTest::new(count, level, noise_sigma);
    let Some(near) = image.sector_excess((inner, outer), count, &test) else {
        return Vec::new();
    };
    if near.iter().all(|&e| e <= 0.0) {
        return Vec::new();
    }
    let Some(far) = image.sector_excess((outer, 2.0 * outer - inner), count, &test) else {
        return Vec::new();
    };
    // A line is narrower than the particle (a reflection, a shadow or a neighbour's edge is
    // as wide as a particle), and goes on beyond the ring.
    let widest_line = radius.max(3.0 * SECTOR_ARC);
    let sector_arc = TAU * middle / count as f64;
    let line = |run: &[usize]| {
        run.len() as f64 * sector_arc <= widest_line
            && run
                .iter()
                .any(|&k| far[k] > 0.0 || far[(k + 1) % count] > 0.0 || far[(k + count - 1) % count] > 0.0)
    };
    let span = 2.0 * ((radius - 0.5).max(0.0) / (window + 0.5)).acos();
    runs_to_directions(&near, WIDEST_CUT * span, &line)
}

/// When a sector of a ring stands out (see [`spokes`]): by more than the noise can put in
/// any of the ring's `n` sectors (`sqrt(2 ln(n / FALSE_RATE))` standard errors of a sector's
/// mean) and by [`LEAST_EXCESS`] of the particle's mean level.
struct SectorTest {
    /// Standard errors of a sector's mean.
    sigmas: f64,
    /// Pixel noise, grey levels.
    noise_sigma: f64,
    /// The least deviation however many pixels, grey levels.
    floor: f64,
}

impl SectorTest {
    /// The test for a ring of `count` sectors about a particle of mean level `level` under
    /// pixel noise `noise_sigma` (grey levels).
    fn new(count: usize, level: f64, noise_sigma: f64) -> SectorTest {
        SectorTest {
            sigmas: (2.0 * (count as f64 / FALSE_RATE).ln()).sqrt(),
            noise_sigma,
            floor: LEAST_EXCESS * level.abs(),
        }
    }

    /// The deviation a sector of `pixels` pixels must pass, grey levels.
    fn threshold(&self, pixels: usize) -> f64 {
        (self.sigmas * self.noise_sigma / (pixels as f64).sqrt()).max(self.floor)
    }
}

/// Share of the exact search's threshold a sector must pass in the coarse first look of
/// [`SpokeSearch`]: about the pixel nearest the particle, up to 0.7 px from it, a line's
/// sectors hold a little less of it.
const COARSE: f64 = 0.75;

/// A coarse first look for lines about many particles of one radius: the ring of [`spokes`]
/// about the pixel nearest each particle's position, its pixels' offsets and sectors reckoned
/// once. A sector whose mean stands above the median sector by [`COARSE`] of what [`spokes`]
/// asks sends the particle to [`spokes`]; most particles have none (the N = 1000 benchmark's
/// discs: the exact search about 7 000 points added 30 % to the tracking's instructions).
pub(crate) struct SpokeSearch {
    radius: f64,
    window: f64,
    count: usize,
    /// Offsets (columns, rows) and sector of the pixels whose centres lie in the ring about
    /// a pixel centre.
    ring: Vec<(i32, i32, usize)>,
    /// Reach of the ring's offsets, px.
    reach: i32,
}

impl SpokeSearch {
    /// The search for particles of radius `radius` px located in windows of radius `window`
    /// px.
    pub(crate) fn new(radius: f64, window: f64) -> SpokeSearch {
        let (inner, outer) = spoke_ring(radius, window);
        let count = sector_count(inner, outer);
        let reach = outer.ceil() as i32;
        let mut ring = Vec::new();
        for dy in -reach..=reach {
            for dx in -reach..=reach {
                let d2 = f64::from(dx * dx + dy * dy);
                if d2 >= inner * inner && d2 <= outer * outer {
                    ring.push((dx, dy, sector_of(f64::from(dx), f64::from(dy), count)));
                }
            }
        }
        SpokeSearch {
            radius,
            window,
            count,
            ring,
            reach,
        }
    }

    /// [`spokes`] about the point `image` is about where the coarse look finds a sector
    /// standing out; the arguments as there.
    pub(crate) fn lines(&self, image: &About<'_>, level: f64, noise_sigma: f64) -> Vec<[f64; 2]> {
        let test = SectorTest::new(self.count, level, noise_sigma);
        if !self.may_hold_lines(image, &test) {
            return Vec::new();
        }
        spokes(image, self.radius, self.window, level, noise_sigma)
    }

    /// Whether a sector of the ring about the pixel nearest the point stands out by
    /// [`COARSE`] of what `test` asks (see [`SpokeSearch`]); true where the ring leaves the
    /// frame (the exact search decides).
    fn may_hold_lines(&self, image: &About<'_>, test: &SectorTest) -> bool {
        let &About {
            signal,
            width,
            height,
            c,
            others,
        } = image;
        let (cx, cy) = (c[0].round() as i64, c[1].round() as i64);
        let reach = i64::from(self.reach);
        if cx - reach < 0 || cy - reach < 0 || cx + reach >= width as i64 || cy + reach >= height as i64 {
            return true;
        }
        // A pixel `P0 + d` is nearer `q` than `c` where `2 d . (q - c) > |q|² - |c|² - 2 P0 . (q - c)`.
        let p0 = [cx as f64, cy as f64];
        // Only a neighbour within twice the ring's outer radius is nearer some ring pixel.
        let within = 2.0 * f64::from(self.reach) + 1.0;
        let cuts: Vec<[f64; 3]> = others
            .iter()
            .filter(|q| (q[0] - c[0]).abs() < within && (q[1] - c[1]).abs() < within)
            .map(|q| {
                let a = [2.0 * (q[0] - c[0]), 2.0 * (q[1] - c[1])];
                let k = q[0] * q[0] + q[1] * q[1] - c[0] * c[0] - c[1] * c[1] - p0[0] * a[0] - p0[1] * a[1];
                [a[0], a[1], k]
            })
            .collect();
        let mut sum = vec![0.0f64; self.count];
        let mut n = vec![0usize; self.count];
        let base = (cy * width as i64 + cx) as isize;
        for &(dx, dy, k) in &self.ring {
            let (fx, fy) = (f64::from(dx), f64::from(dy));
            if cuts.iter().any(|u| fx * u[0] + fy * u[1] > u[2]) {
                continue;
            }
            let at = (base + dy as isize * width as isize + dx as isize) as usize;
            sum[k] += f64::from(signal[at]);
            n[k] += 1;
        }
        let means: Vec<(f64, usize)> = sum
            .iter()
            .zip(&n)
            .filter(|(_, &m)| m >= LEAST_PIXELS)
            .map(|(&s, &m)| (s / m as f64, m))
            .collect();
        if means.len() < self.count / 2 {
            return false;
        }
        let mut sorted: Vec<f64> = means.iter().map(|m| m.0).collect();
        sorted.sort_by(f64::total_cmp);
        let typical = sorted[sorted.len() / 2];
        means
            .iter()
            .any(|&(m, pixels)| m - typical > COARSE * test.threshold(pixels))
    }
}

/// Sectors of the ring `(inner, outer)` (px): about [`SECTOR_ARC`] of arc each at its middle,
/// 8-180.
fn sector_count(inner: f64, outer: f64) -> usize {
    let middle = 0.5 * (inner + outer);
    ((TAU * middle / SECTOR_ARC).ceil() as usize).clamp(8, 180)
}

/// The sector (of `count`, the first from the +x axis towards +y) holding the offset
/// `(dx, dy)`.
fn sector_of(dx: f64, dy: f64, count: usize) -> usize {
    let angle = dy.atan2(dx).rem_euclid(TAU);
    ((angle / TAU * count as f64) as usize).min(count - 1)
}

/// Least pixels a sector of the ring inside a particle holds on average for [`mark_pull`] to
/// judge it (the ring from a quarter to 0.85 of the radius holds about `1.2 R` pixels a
/// sector of two pixels' arc: particles of 5 px and more).
const LEAST_MARK_PIXELS: f64 = 6.0;

/// How far a mark inside a particle (a line drawn from its centre to its edge for its angle,
/// a texture's bump, a highlight) pulls its centroid, as the first moment of the mark's
/// signal about the point, grey levels · px³ (to be divided by the window's mass); `None`
/// where no sector of the ring from a quarter to 0.85 of the radius `radius` (px) about the
/// point `image` is about stands out from the ring's typical sector either way (as [`spokes`] judges a sector, its
/// shells' medians taken out), or where the particle is too small to judge
/// ([`LEAST_MARK_PIXELS`]). The ring leaves out the centre, where sectors hold a pixel or two,
/// and the edge, which a centroid off the centre by a little makes uneven: the moment is
/// that of the part of the mark the ring holds, about two thirds of a line from centre to
/// edge.
pub(crate) fn mark_pull(image: &About<'_>, radius: f64, level: f64, noise_sigma: f64) -> Option<[f64; 2]> {
    let (inner, outer) = (0.25 * radius, 0.85 * radius);
    let count = sector_count(inner, outer);
    let area = std::f64::consts::PI * (outer * outer - inner * inner);
    if area / (count as f64) < LEAST_MARK_PIXELS {
        return None;
    }
    let test = SectorTest::new(count, level, noise_sigma);
    let deviations = image.sector_deviations((inner, outer), count, &test)?;
    let middle = 0.5 * (inner + outer);
    let mut pull = [0.0, 0.0];
    for (k, &(d, pixels)) in deviations.iter().enumerate() {
        let a = (k as f64 + 0.5) * TAU / count as f64;
        pull[0] += d * pixels as f64 * middle * a.cos();
        pull[1] += d * pixels as f64 * middle * a.sin();
    }
    deviations.iter().any(|d| d.0.abs() > 0.0).then_some(pull)
}

/// The image about one particle, as the ring searches read it: the signal (`width * height`,
/// row-major, particles positive), the particle's position `c` and its neighbours' `others`
/// (px), whose nearer pixels are left out.
pub(crate) struct About<'a> {
    pub(crate) signal: &'a [f32],
    pub(crate) width: usize,
    pub(crate) height: usize,
    pub(crate) c: [f64; 2],
    pub(crate) others: &'a [[f64; 2]],
}

impl About<'_> {
    /// How far each of `count` sectors of the ring `(inner, outer)` (px) about `c` stands
    /// above the ring's typical sector (the median of the sectors' means), grey levels, where
    /// that passes `test` for the pixels the sector holds, else 0; `None` where fewer than half
    /// the sectors hold [`LEAST_PIXELS`] (the ring leaves the frame). Pixels nearer one of
    /// `others` than `c` are left out, and each half-pixel shell's median is taken out first,
    /// so the sectors compare what lies off the ring's own radial profile (a spot's skirt
    /// falls steeply across the ring, and sectors holding pixels at different radii would
    /// differ).
    fn sector_excess(&self, (inner, outer): (f64, f64), count: usize, test: &SectorTest) -> Option<Vec<f64>> {
        let deviations = self.sector_deviations((inner, outer), count, test)?;
        Some(deviations.iter().map(|d| d.0.max(0.0)).collect())
    }

    /// Each of `count` sectors' deviation from the ring's typical sector (see
    /// [`About::sector_excess`]), either way, where its size passes `test`, else 0, with the
    /// pixels the sector holds.
    fn sector_deviations(
        &self,
        (inner, outer): (f64, f64),
        count: usize,
        test: &SectorTest,
    ) -> Option<Vec<(f64, usize)>> {
        let About {
            signal,
            width,
            height,
            c,
            others,
        } = *self;
        let (x0, x1) = (
            (c[0] - outer).floor().max(0.0),
            (c[0] + outer).ceil().min(width as f64 - 1.0),
        );
        let (y0, y1) = (
            (c[1] - outer).floor().max(0.0),
            (c[1] + outer).ceil().min(height as f64 - 1.0),
        );
        if !(x0 <= x1 && y0 <= y1) {
            return None;
        }
        let (inner2, outer2) = (inner * inner, outer * outer);
        let shells = ((outer - inner) / SHELL).ceil() as usize + 1;
        // Each pixel's sector, shell and signal.
        let mut pixels: Vec<(usize, usize, f64)> = Vec::new();
        for y in y0 as usize..=y1 as usize {
            let dy = y as f64 - c[1];
            for x in x0 as usize..=x1 as usize {
                let dx = x as f64 - c[0];
                let d2 = dx * dx + dy * dy;
                if d2 < inner2 || d2 > outer2 {
                    continue;
                }
                let (px, py) = (x as f64, y as f64);
                if others
                    .iter()
                    .any(|q| (px - q[0]).powi(2) + (py - q[1]).powi(2) < d2)
                {
                    continue;
                }
                let k = sector_of(dx, dy, count);
                let shell = (((d2.sqrt() - inner) / SHELL) as usize).min(shells - 1);
                pixels.push((k, shell, f64::from(signal[y * width + x])));
            }
        }
        let mut profile = vec![0.0f64; shells];
        let mut values: Vec<f64> = Vec::new();
        for (b, level) in profile.iter_mut().enumerate() {
            values.clear();
            values.extend(pixels.iter().filter(|p| p.1 == b).map(|p| p.2));
            if !values.is_empty() {
                values.sort_by(f64::total_cmp);
                *level = values[values.len() / 2];
            }
        }
        let mut sum = vec![0.0f64; count];
        let mut n = vec![0usize; count];
        for &(k, b, v) in &pixels {
            sum[k] += v - profile[b];
            n[k] += 1;
        }
        let means: Vec<Option<f64>> = sum
            .iter()
            .zip(&n)
            .map(|(&s, &m)| (m >= LEAST_PIXELS).then(|| s / m as f64))
            .collect();
        let mut judged: Vec<f64> = means.iter().flatten().copied().collect();
        if judged.len() < count / 2 {
            return None;
        }
        judged.sort_by(f64::total_cmp);
        let typical = judged[judged.len() / 2];
        Some(
            means
                .iter()
                .zip(&n)
                .map(|(m, &pixels)| match m {
                    Some(m) if (m - typical).abs() > test.threshold(pixels) => (m - typical, pixels),
                    _ => (0.0, pixels),
                })
                .collect(),
        )
    }
}

/// The directions of the runs of positive `excess` around a ring of sectors (sector `k`
/// spans angles `[k, k + 1) · 2π / n`; a single sector between two positive ones bridges
/// them, as a thin line's pixels fall unevenly into sectors of its own width): each run's
/// excess-weighted mean direction, a run wider than `widest` (rad) split into equal parts;
/// runs (their sectors, in order) that `keep` refuses are left out.
fn runs_to_directions(excess: &[f64], widest: f64, keep: &dyn Fn(&[usize]) -> bool) -> Vec<[f64; 2]> {
    let count = excess.len();
    let on: Vec<bool> = (0..count)
        .map(|k| excess[k] > 0.0 || (excess[(k + count - 1) % count] > 0.0 && excess[(k + 1) % count] > 0.0))
        .collect();
    let Some(start) = (0..count).find(|&k| !on[k]) else {
        // Every sector: nothing stands out from a typical sector.
        return Vec::new();
    };
    let width = TAU / count as f64;
    let per_cut = ((widest / width).floor() as usize).max(1);
    let mut out = Vec::new();
    let mut run: Vec<usize> = Vec::new();
    let mut flush = |run: &mut Vec<usize>| {
        if run.is_empty() || !keep(run) {
            run.clear();
            return;
        }
        for part in run.chunks(per_cut) {
            let (mut x, mut y) = (0.0, 0.0);
            for &k in part {
                let a = (k as f64 + 0.5) * width;
                x += excess[k] * a.cos();
                y += excess[k] * a.sin();
            }
            let len = x.hypot(y);
            if len > 0.0 {
                out.push([x / len, y / len]);
            }
        }
        run.clear();
    };
    for step in 1..=count {
        let k = (start + step) % count;
        if on[k] {
            run.push(k);
        } else {
            flush(&mut run);
        }
    }
    flush(&mut run);
    out
}

/// The cuts' own error, px per axis: a cut crosses the particle's edge, whose pixels sample it
/// coarsely, and a disc of radius `radius` px cut along `pairs` lines and their opposites
/// moves by about `0.06 / radius` px for each pair (measured 0.057-0.063 over 2-20 px, test
/// `the_cuts_own_error_falls_as_one_over_the_radius`), the pairs' errors independent.
pub(crate) fn cut_sampling_error(radius: f64, pairs: usize) -> f64 {
    CUT_SAMPLING / radius.max(1.0) * (pairs as f64).sqrt()
}

/// The cuts' own error times the radius, px² per axis (see [`cut_sampling_error`]).
const CUT_SAMPLING: f64 = 0.06;

/// The window cuts (see [`crate::locate`]) that leave `spokes` out of a particle of radius
/// `radius` px: a half-plane along each spoke and along its opposite, its ramp of one pixel
/// ending at the radius. Ending there, the cut leaves none of the line beyond the particle's
/// edge in the window; it crosses the particle's own edge, whose pixels it weighs alike on
/// both sides, at a cost of about 0.01 px RMS (0.03 px at most) from the sampling of the edge
/// (24 discs of 6 px at random sub-pixel places, test
/// `lines_cut_out_with_their_opposites_leave_the_centroid_on_the_centre`; a pixel farther
/// out, 0.025 px from the line's light, a pixel farther in, 0.015 px).
pub(crate) fn spoke_cuts(spokes: &[[f64; 2]], radius: f64) -> Vec<([f64; 2], f64)> {
    let at = radius - 0.5;
    spokes
        .iter()
        .flat_map(|&u| [(u, at), ([-u[0], -u[1]], at)])
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The view of `img` (`w` x `h`) about `c`, no neighbours.
    fn about(img: &[f32], w: usize, h: usize, c: [f64; 2]) -> About<'_> {
        About {
            signal: img,
            width: w,
            height: h,
            c,
            others: &[],
        }
    }

    /// A `w` x `h` image whose pixels hold the mean of `level(dx, dy)` over 8 x 8 points
    /// spread over each, `(dx, dy)` the point's offset from `c` (px).
    fn area_sampled(w: usize, h: usize, c: [f64; 2], level: impl Fn(f64, f64) -> f32) -> Vec<f32> {
        let mut img = vec![0.0f32; w * h];
        for y in 0..h {
            for x in 0..w {
                let mut v = 0.0;
                for sy in 0..8 {
                    for sx in 0..8 {
                        let px = x as f64 - 0.4375 + 0.125 * sx as f64 - c[0];
                        let py = y as f64 - 0.4375 + 0.125 * sy as f64 - c[1];
                        v += level(px, py) / 64.0;
                    }
                }
                img[y * w + x] = v;
            }
        }
        img
    }

    /// A disc of radius `r` and level `amp` at `c`, with lines of half-width `hw` and the
    /// same level from it along `dirs`.
    fn disc_with_lines(
        w: usize,
        h: usize,
        c: [f64; 2],
        r: f64,
        amp: f32,
        dirs: &[[f64; 2]],
        hw: f64,
    ) -> Vec<f32> {
        area_sampled(w, h, c, |px, py| {
            let on_line = dirs
                .iter()
                .any(|u| px * u[0] + py * u[1] > 0.0 && (px * u[1] - py * u[0]).abs() <= hw);
            if px.hypot(py) <= r || on_line {
                amp
            } else {
                0.0
            }
        })
    }

    /// A disc of radius `r` and level `amp` at `c` with a line of half-width `hw` and level
    /// `line` drawn over it from its centre to its edge along `u` (a physics engine's mark of
    /// a body's angle).
    #[allow(clippy::too_many_arguments)]
    fn disc_with_radius_line(
        w: usize,
        h: usize,
        c: [f64; 2],
        r: f64,
        amp: f32,
        u: [f64; 2],
        hw: f64,
        line: f32,
    ) -> Vec<f32> {
        area_sampled(w, h, c, |px, py| {
            if px.hypot(py) > r {
                0.0
            } else if px * u[0] + py * u[1] >= 0.0 && (px * u[1] - py * u[0]).abs() <= hw {
                line
            } else {
                amp
            }
        })
    }

    #[test]
    fn a_line_leaving_a_disc_is_found_along_its_direction() {
        let u = [0.6f64, 0.8];
        let img = disc_with_lines(64, 64, [31.3, 30.7], 6.0, 200.0, &[u], 1.0);
        let found = spokes(&about(&img, 64, 64, [31.3, 30.7]), 6.0, 7.0, 200.0, 1.0);
        assert_eq!(found.len(), 1, "{found:?}");
        let cos = found[0][0] * u[0] + found[0][1] * u[1];
        assert!(cos > 0.99, "found {found:?} for {u:?}");
    }

    #[test]
    fn a_plain_disc_or_a_blurred_skirt_has_no_spokes() {
        let img = disc_with_lines(64, 64, [31.3, 30.7], 6.0, 200.0, &[], 1.0);
        assert!(spokes(&about(&img, 64, 64, [31.3, 30.7]), 6.0, 7.0, 200.0, 1.0).is_empty());
        // A wide Gaussian spot: its skirt fills the ring evenly.
        let mut spot = vec![0.0f32; 64 * 64];
        for y in 0..64 {
            for x in 0..64 {
                let d2 = (x as f64 - 31.3).powi(2) + (y as f64 - 30.7).powi(2);
                spot[y * 64 + x] = (200.0 * (-d2 / (2.0 * 36.0)).exp()) as f32;
            }
        }
        assert!(spokes(&about(&spot, 64, 64, [31.3, 30.7]), 6.0, 7.0, 100.0, 0.5).is_empty());
    }

    /// A dark line from the centre of a disc of 12 px to its edge, 2 px wide: the plain
    /// centroid moves 0.3 px away from it; [`mark_pull`] points away from the line and says
    /// how far within a factor of two (measured 0.65 of it: the ring leaves out the line's
    /// inner and outer parts); a plain disc has no mark.
    #[test]
    fn a_mark_inside_a_disc_is_measured_by_its_pull() {
        let c = [40.3, 39.6];
        let plain = disc_with_radius_line(80, 80, c, 12.0, 200.0, [1.0, 0.0], 1.0, 200.0);
        assert!(mark_pull(&about(&plain, 80, 80, c), 12.0, 200.0, 1.0).is_none());
        for a in [0.3f64, 2.0, 4.4] {
            let u = [a.cos(), a.sin()];
            let img = disc_with_radius_line(80, 80, c, 12.0, 200.0, u, 1.0, 20.0);
            let found = crate::refine_centroids(&img, 80, 80, &[[40.0, 40.0]], &[0.0], 13.0, 1.0)[0];
            let off = [found.x - c[0], found.y - c[1]];
            let moved = off[0].hypot(off[1]);
            assert!(
                moved > 0.2 && off[0] * u[0] + off[1] * u[1] < 0.0,
                "{off:?} for {u:?}"
            );
            let pull = mark_pull(&about(&img, 80, 80, [found.x, found.y]), 12.0, 200.0, 1.0).expect("a mark");
            let said = pull[0].hypot(pull[1]) / found.mass;
            assert!(pull[0] * u[0] + pull[1] * u[1] < 0.0, "{pull:?} for {u:?}");
            assert!(
                said > 0.5 * moved && said < 2.0 * moved,
                "said {said:.3} px for {moved:.3}"
            );
        }
    }

    /// The cuts' own error: discs of 2-20 px with no line, cut along a random direction and
    /// its opposite, at 24 sub-pixel places each: measured 0.080-0.089 px² over the radius
    /// (RMS of the distance), so [`cut_sampling_error`] per axis within 25 % of it.
    #[test]
    fn the_cuts_own_error_falls_as_one_over_the_radius() {
        for r in [2.0, 3.0, 4.5, 6.0, 9.0, 14.0, 20.0] {
            let mut sq = 0.0;
            for k in 0..24 {
                let c = [41.0 + (0.137 * k as f64) % 1.0, 40.5 + (0.291 * k as f64) % 1.0];
                let a = 0.7 * k as f64;
                let img = disc_with_lines(84, 84, c, r, 200.0, &[], 1.0);
                let mut scratch = crate::LocateScratch::default();
                let cuts = [spoke_cuts(&[[a.cos(), a.sin()]], r)];
                let cut = crate::locate::refine_centroids_with_cuts(
                    &img,
                    84,
                    84,
                    &[[41.0, 41.0]],
                    &[0.0],
                    r + 1.0,
                    1.0,
                    &cuts,
                    &mut scratch,
                );
                let cut = cut[0].expect("located");
                sq += (cut.x - c[0]).powi(2) + (cut.y - c[1]).powi(2);
            }
            // Per axis, from the distance's mean square over both axes.
            let per_axis = (sq / 48.0).sqrt();
            let stated = cut_sampling_error(r, 1);
            assert!(
                (per_axis / stated - 1.0).abs() < 0.25,
                "radius {r}: {per_axis:.4} px per axis, stated {stated:.4}"
            );
        }
    }

    /// One line, then two at right angles, from discs of 6 px at 24 sub-pixel places and
    /// directions: the plain centroid is pulled 0.13 px (RMS) towards the lines; with the
    /// lines found and cut out with their opposites, 0.011 px RMS, 0.033 at most.
    #[test]
    fn lines_cut_out_with_their_opposites_leave_the_centroid_on_the_centre() {
        for lines in 1..=2 {
            let (mut plain_sq, mut cut_sq, mut worst) = (0.0, 0.0, 0.0f64);
            for k in 0..24 {
                let c = [31.0 + (0.137 * k as f64) % 1.0, 30.5 + (0.291 * k as f64) % 1.0];
                let a = 0.7 * k as f64;
                let dirs: Vec<[f64; 2]> = [[a.cos(), a.sin()], [-a.sin(), a.cos()]][..lines].to_vec();
                let img = disc_with_lines(64, 64, c, 6.0, 200.0, &dirs, 1.0);
                let plain = crate::refine_centroids(&img, 64, 64, &[[31.0, 31.0]], &[0.0], 7.0, 1.0);
                let at = [plain[0].x, plain[0].y];
                plain_sq += (at[0] - c[0]).powi(2) + (at[1] - c[1]).powi(2);
                let found = spokes(&about(&img, 64, 64, at), 6.0, 7.0, 200.0, 1.0);
                assert_eq!(found.len(), lines, "{k}: {found:?} for {dirs:?}");
                let mut scratch = crate::LocateScratch::default();
                let cut = crate::locate::refine_centroids_with_cuts(
                    &img,
                    64,
                    64,
                    &[at],
                    &[0.0],
                    7.0,
                    1.0,
                    &[spoke_cuts(&found, 6.0)],
                    &mut scratch,
                );
                let cut = cut[0].expect("located");
                let off = (cut.x - c[0]).hypot(cut.y - c[1]);
                cut_sq += off * off;
                worst = worst.max(off);
            }
            let (plain, cut) = ((plain_sq / 24.0).sqrt(), (cut_sq / 24.0).sqrt());
            assert!(plain > 0.1, "{lines} line(s) pull the plain centroid {plain} px");
            assert!(
                cut < 0.02 && worst < 0.045,
                "{lines} line(s) cut out: {cut} px RMS, {worst} at most"
            );
        }
    }
}
