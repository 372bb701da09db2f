//! The background left around a particle, taken out before it is located again: a plane
//! fitted on the ring just beyond the particle, and a window that reaches as far as the
//! particle does.
//!
//! A centroid window integrates whatever the background model left in the signal: a slope
//! `b` (grey levels per px) across a window of radius `W` moves the centroid by about
//! `b Σ w dx² / Σ w s`, which grows with the fourth power of the window. Under an
//! illumination gradient, vignetting or an exposure drift the model leaves such slopes, and
//! a halo, where it cannot see the background: under a large particle that hovers over its
//! own patch in every sample. The sweep's textured balls and discs of 12-40 px were 0.3-0.5
//! px off there, always to the same side (a bias: spread 0.02-0.1 px), and followed to
//! 0.0-0.1 px when drawn without the uneven light. Where the radius of gyration reads a
//! textured ball small (36.6 px for 38.2), the window `R + 1` also cuts its edge.
//!
//! Each estimate is therefore, when the pass is located again with this correction
//! ([`planes_move_points`] decides):
//!
//! 1. given a window reaching as far as its particle does ([`extent`]): out from `W`, one
//!    pixel ring at a time while a ring's mean stands 3 standard errors of the measured
//!    noise above the two-pixel ring beyond it (the particle's image still falls; a
//!    background, even or sloped, does not on average), at most to the radius of one
//!    particle's measured extent (its area above the noise mask) and short of neighbours;
//! 2. given the plane fitted by least squares on the ring from `reach + 1` to
//!    `1.5 reach + 2`, pixels beyond three robust standard deviations of the residuals left
//!    out (neighbours, texture), with neighbours' windows left out (the local background
//!    annulus of aperture photometry, with a plane instead of a level: Stetson 1987, PASP
//!    99:191);
//! 3. located by the centroid of the signal minus that plane, iterated to its fixed point.
//!
//! It stays where it was when nothing is to be corrected (the particle ends within `W` and
//! the ring's slope is within 3 standard errors of zero), when its window is cut by the
//! image border or shares pixels with a neighbour's (the joint Voronoi split of
//! [`crate::refine_centroids`] handles those), when the ring's pixels spread about the plane
//! more than the measured noise allows (a wall or a grid is no plane: corrected there, the
//! real pendulum's diagnosis gained a drag and the bouncing ball's lost its shelf), and
//! when the move exceeds what a background
//! as high and as steep as the ring's, wholly on one side, could cause (clutter in the ring
//! or a smear of the particle, not a background: on the real bouncing-ball video, frames
//! where the ball flies fast moved 2.3 px with no such bound).

use super::finder::Workers;
use super::neighbours::Neighbours;
use super::size_class::SizeClass;
use super::stage::Pass;
use crate::distance::closer_than;
use crate::{Background, Detection, FrameView};
use std::collections::BTreeMap;

/// A plane `a + bx (x − cx) + by (y − cy)` in grey levels, about the centre `c` (px).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct Plane {
    pub(super) c: [f64; 2],
    pub(super) a: f64,
    pub(super) b: [f64; 2],
    /// Standard error of each slope, grey levels per px, from the residuals' robust spread.
    pub(super) b_sigma: f64,
    /// Robust standard deviation of the fitted pixels about the plane, grey levels.
    pub(super) sigma: f64,
    /// Pixels the plane was fitted on.
    pub(super) count: usize,
}

impl Plane {
    fn at(&self, x: f64, y: f64) -> f64 {
        self.a + self.b[0] * (x - self.c[0]) + self.b[1] * (y - self.c[1])
    }
}

/// Rounds of refitting with outliers left out.
const CLIP_ROUNDS: usize = 3;
/// Residuals beyond this many robust standard deviations are left out of the next fit.
const CLIP_SIGMAS: f64 = 3.0;

/// Inner and outer radius of the ring a plane is fitted on around a window of radius
/// `window`, px: just beyond the window's weight ramp, and wide enough that the ring's second
/// moment is four times the window's (the slope's error then moves the centroid by about
/// half the centroid's own noise error, which adds a tenth to it).
pub(super) fn ring_radii(window: f64) -> (f64, f64) {
    let inner = window + 1.0;
    (inner, (1.5 * window + 2.0).max(inner + 3.0))
}

/// The plane fitted on the ring around `c` (see [`ring_radii`]) of `signal`
/// (`width * height`, row-major), leaving out pixels within `keep_out` px of any point of
/// `others`; `None` when fewer than 12 pixels remain.
pub(super) fn fit_ring_plane(
    signal: &[f32],
    width: usize,
    height: usize,
    c: [f64; 2],
    window: f64,
    others: &[[f64; 2]],
    keep_out: f64,
) -> Option<Plane> {
    let (inner, outer) = ring_radii(window);
    let x0 = (c[0] - outer).floor().max(0.0) as usize;
    let y0 = (c[1] - outer).floor().max(0.0) as usize;
    let x1 = ((c[0] + outer).ceil() as usize).min(width.checked_sub(1)?);
    let y1 = ((c[1] + outer).ceil() as usize).min(height.checked_sub(1)?);
    let near: Vec<[f64; 2]> = others
        .iter()
        .copied()
        .filter(|o| closer_than(o[0] - c[0], o[1] - c[1], outer + keep_out))
        .collect();
    let keep2 = keep_out * keep_out;
    let mut pixels: Vec<[f64; 3]> = Vec::new();
    for y in y0..=y1 {
        let dy = y as f64 - c[1];
        for x in x0..=x1 {
            let dx = x as f64 - c[0];
            let r2 = dx * dx + dy * dy;
            if r2 < inner * inner || r2 > outer * outer {
                continue;
            }
            if near
                .iter()
                .any(|o| (x as f64 - o[0]).powi(2) + (y as f64 - o[1]).powi(2) < keep2)
            {
                continue;
            }
            pixels.push([dx, dy, f64::from(signal[y * width + x])]);
        }
    }
    let mut used = vec![true; pixels.len()];
    let mut plane = None;
    let mut residuals: Vec<f64> = Vec::with_capacity(pixels.len());
    for _ in 0..CLIP_ROUNDS {
        let fit = least_squares_plane(&pixels, &used)?;
        residuals.clear();
        residuals.extend(
            pixels
                .iter()
                .zip(&used)
                .filter(|(_, &u)| u)
                .map(|(p, _)| (p[2] - fit[0] - fit[1] * p[0] - fit[2] * p[1]).abs()),
        );
        let mid = residuals.len() / 2;
        let mad = *residuals.select_nth_unstable_by(mid, f64::total_cmp).1;
        let sigma = 1.4826 * mad;
        // The slope's standard error: sigma over the root of the ring's second moment about
        // the fitted pixels' mean.
        let (mut n, mut sx, mut sy, mut sxx, mut syy) = (0.0, 0.0, 0.0, 0.0, 0.0);
        for (p, &u) in pixels.iter().zip(&used) {
            if u {
                n += 1.0;
                sx += p[0];
                sy += p[1];
                sxx += p[0] * p[0];
                syy += p[1] * p[1];
            }
        }
        let spread = ((sxx - sx * sx / n) + (syy - sy * sy / n)) / 2.0;
        plane = Some(Plane {
            c,
            a: fit[0],
            b: [fit[1], fit[2]],
            b_sigma: sigma / spread.max(1.0).sqrt(),
            sigma,
            count: n as usize,
        });
        let limit = CLIP_SIGMAS * sigma;
        let mut changed = false;
        for (p, u) in pixels.iter().zip(used.iter_mut()) {
            let keep = (p[2] - fit[0] - fit[1] * p[0] - fit[2] * p[1]).abs() <= limit;
            changed |= keep != *u;
            *u = keep;
        }
        if !changed {
            break;
        }
    }
    plane
}

/// Least-squares plane `[a, bx, by]` through the `used` points `[dx, dy, value]`; `None`
/// with fewer than 12 points or a singular system.
fn least_squares_plane(points: &[[f64; 3]], used: &[bool]) -> Option<[f64; 3]> {
    let mut m = [[0.0f64; 3]; 3];
    let mut v = [0.0f64; 3];
    let mut count = 0;
    for (p, &u) in points.iter().zip(used) {
        if !u {
            continue;
        }
        count += 1;
        let f = [1.0, p[0], p[1]];
        for i in 0..3 {
            v[i] += f[i] * p[2];
            for j in 0..3 {
                m[i][j] += f[i] * f[j];
            }
        }
    }
    if count < 12 {
        return None;
    }
    solve3(m, v)
}

/// Solves the 3 x 3 system `m x = v` by Cramer's rule; `None` when it is singular.
fn solve3(m: [[f64; 3]; 3], v: [f64; 3]) -> Option<[f64; 3]> {
    let det = |m: &[[f64; 3]; 3]| {
        m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1]) - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
            + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0])
    };
    let d = det(&m);
    if d.abs() < 1e-12 {
        return None;
    }
    let mut out = [0.0; 3];
    for (k, o) in out.iter_mut().enumerate() {
        let mut mk = m;
        for i in 0..3 {
            mk[i][k] = v[i];
        }
        *o = det(&mk) / d;
    }
    Some(out)
}

/// Most centroid iterations on the plane-corrected signal.
const MAX_ITERATIONS: usize = 40;

/// The centroid of `signal − plane` in the window of radius `window` (weights
/// `clamp(W + 1/2 − d, 0, 1)`, as [`crate::refine_centroids`] uses), iterated from `start`
/// until a step is below 1e-4 px; `None` when the window's corrected mass is not positive or
/// the estimate runs off by more than the window.
pub(super) fn centroid_on_plane(
    signal: &[f32],
    width: usize,
    height: usize,
    start: [f64; 2],
    window: f64,
    plane: &Plane,
) -> Option<[f64; 2]> {
    let reach = window + 0.5;
    let mut c = start;
    for _ in 0..MAX_ITERATIONS {
        let x0 = (c[0] - reach).floor().max(0.0) as usize;
        let y0 = (c[1] - reach).floor().max(0.0) as usize;
        let x1 = ((c[0] + reach).ceil().max(0.0) as usize).min(width - 1);
        let y1 = ((c[1] + reach).ceil().max(0.0) as usize).min(height - 1);
        let (mut m, mut mx, mut my) = (0.0, 0.0, 0.0);
        for y in y0..=y1 {
            let dy = y as f64 - c[1];
            for x in x0..=x1 {
                let dx = x as f64 - c[0];
                let w = (reach - (dx * dx + dy * dy).sqrt()).clamp(0.0, 1.0);
                if w == 0.0 {
                    continue;
                }
                let s = w * (f64::from(signal[y * width + x]) - plane.at(x as f64, y as f64));
                m += s;
                mx += s * dx;
                my += s * dy;
            }
        }
        if m <= 0.0 {
            return None;
        }
        let step = [mx / m, my / m];
        c = [c[0] + step[0], c[1] + step[1]];
        if (c[0] - start[0]).hypot(c[1] - start[1]) > window {
            return None;
        }
        if step[0].hypot(step[1]) < 1e-4 {
            break;
        }
    }
    Some(c)
}

/// Standard deviations of its own noise that a ring's mean signal must stand above zero for
/// the particle to reach into it, and that a fitted slope must stand above zero to be taken
/// out.
const SIGNIFICANT: f64 = 3.0;

/// How far the particle around `c` reaches, px: from `window` outwards in steps of a pixel,
/// the inner radius of the first one-pixel ring whose mean signal no longer stands
/// [`SIGNIFICANT`] standard errors above the mean of the two-pixel ring just beyond it (the
/// particle's image still falls there; a background left in the signal, even or sloped,
/// does not fall on average), pixels within `keep_out` of `others` left out; at most `limit`.
#[allow(clippy::too_many_arguments)]
fn extent(
    signal: &[f32],
    width: usize,
    height: usize,
    c: [f64; 2],
    window: f64,
    noise_sigma: f64,
    others: &[[f64; 2]],
    keep_out: f64,
    limit: f64,
) -> f64 {
    let ring = |a: f64, b: f64| ring_mean(signal, width, height, c, (a, b), others, keep_out);
    let mut r = window;
    while r < limit {
        let (inside, n1) = ring(r, r + 1.0);
        let (beyond, n2) = ring(r + 1.0, r + 3.0);
        if n1 < 8 || n2 < 8 {
            return r;
        }
        let error = noise_sigma * (1.0 / n1 as f64 + 1.0 / n2 as f64).sqrt();
        if inside - beyond < SIGNIFICANT * error {
            return r;
        }
        r += 1.0;
    }
    limit
}

/// Mean signal and pixel count of the ring from `radii.0` to `radii.1` px around `c`,
/// pixels within `keep_out` px of any of `others` left out.
fn ring_mean(
    signal: &[f32],
    width: usize,
    height: usize,
    c: [f64; 2],
    radii: (f64, f64),
    others: &[[f64; 2]],
    keep_out: f64,
) -> (f64, usize) {
    let (a, b) = radii;
    let keep2 = keep_out * keep_out;
    let x0 = (c[0] - b).floor().max(0.0) as usize;
    let y0 = (c[1] - b).floor().max(0.0) as usize;
    let x1 = ((c[0] + b).ceil().max(0.0) as usize).min(width - 1);
    let y1 = ((c[1] + b).ceil().max(0.0) as usize).min(height - 1);
    let (mut sum, mut n) = (0.0, 0usize);
    for y in y0..=y1 {
        let dy = y as f64 - c[1];
        for x in x0..=x1 {
            let dx = x as f64 - c[0];
            let d2 = dx * dx + dy * dy;
            if d2 < a * a || d2 >= b * b {
                continue;
            }
            if others
                .iter()
                .any(|o| (x as f64 - o[0]).powi(2) + (y as f64 - o[1]).powi(2) < keep2)
            {
                continue;
            }
            sum += f64::from(signal[y * width + x]);
            n += 1;
        }
    }
    (sum / (n.max(1) as f64), n)
}

/// Moves each of `found` to its [`corrected_position`].
pub(super) fn correct_for_planes(
    signal: &[f32],
    width: usize,
    height: usize,
    found: &mut [Detection],
    window: f64,
    most: f64,
    noise: Noise,
) {
    let points: Vec<[f64; 2]> = found.iter().map(|d| [d.x, d.y]).collect();
    let points = Neighbours::new(&points);
    for (i, d) in found.iter_mut().enumerate() {
        let image = Signal {
            signal,
            width,
            height,
        };
        if let Some(Ok(p)) = corrected_position(&image, &points, i, window, most, noise, Spread::Checked) {
            d.x = p[0];
            d.y = p[1];
        }
    }
}

/// The noise a particle's surroundings are judged against, grey levels.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct Noise {
    /// The signal's pixel noise ([`Background::noise_sigma`]): what a ring's mean must stand
    /// above to hold part of the particle.
    pub(super) pixel: f64,
    /// The spread of a frame's signal about the background ([`Background::frame_noise`]):
    /// what a ring's pixels about its plane may spread to be background.
    pub(super) frame: f64,
}

impl Noise {
    /// The noise of `background`.
    pub(super) fn of(background: &Background) -> Noise {
        Noise {
            pixel: background.noise_sigma,
            frame: background.frame_noise(),
        }
    }
}

/// Whether [`corrected_position`] holds the ring's spread about its plane to the noise.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Spread {
    /// An estimate whose ring spreads more than the noise allows stays.
    Checked,
    /// The spread is not looked at: where the plane would move the estimate, whatever the
    /// ring holds (what an uneven surrounding may do to it).
    Ignored,
}

/// A ring round an estimate that spreads about its plane more than the noise allows.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) struct UnevenRing;

/// A frame's signal image, row-major, grey levels.
pub(super) struct Signal<'a> {
    pub(super) signal: &'a [f32],
    pub(super) width: usize,
    pub(super) height: usize,
}

/// Where estimate `i` of `points` (px, with their grid) moves when located in a window
/// reaching as far as its particle does ([`extent`], at least `window`), on the signal with the plane fitted on the
/// ring just beyond taken out; `None` where it stays: an estimate whose window another's
/// reaches (their pixels are split between them by [`crate::refine_centroids`]), one with
/// a neighbour nearer than twice that reach and a pixel (its light, as far-reaching, would
/// lie in the window), one whose
/// particle ends within `window` and whose ring shows no slope beyond [`SIGNIFICANT`]
/// standard errors, or one whose corrected centroid has no positive mass; `Some(Err(UnevenRing))`
/// where it stays only because its ring spreads about the plane more than the noise allows
/// (with [`Spread::Checked`]).
#[allow(clippy::too_many_arguments)]
pub(super) fn corrected_position(
    image: &Signal<'_>,
    points: &Neighbours<'_>,
    i: usize,
    window: f64,
    most: f64,
    noise: Noise,
    spread: Spread,
) -> Option<Result<[f64; 2], UnevenRing>> {
    let noise_sigma = noise.pixel;
    let Signal {
        signal,
        width,
        height,
    } = *image;
    if width == 0 || height == 0 {
        return None;
    }
    let c = points.points[i];
    let keep_out = window + 1.0;
    // Only points whose keep-out disc can reach the widest ring matter. The nearest
    // distance is exact below `matters`, which exceeds both bounds it is compared with
    // (`2 window + 2` and `most + keep_out`): beyond it, what follows is the same.
    let matters = 1.5 * most.max(window) + 3.0 + 2.0 * keep_out;
    let (nearest, others) = points.near(i, matters);
    if nearest < 2.0 * window + 2.0 {
        return None;
    }
    let limit = most.min(nearest - keep_out);
    let reach = extent(
        signal,
        width,
        height,
        c,
        window,
        noise_sigma,
        &others,
        keep_out,
        limit,
    )
    .max(window);
    // A neighbour whose light reaches as far as this particle's (both measured to where
    // it falls into the noise) lies in the wide window and the ring, and its light would
    // pull the centroid towards it: the estimate stays. The keep-out disc of `window + 1`
    // round each neighbour leaves out its core, not its skirt: three Gaussian spots of
    // 4.5 px 20 px apart (fresh style 6381, no noise), reaching 12.4 px, were moved 0.15 px
    // towards each other, where the window alone found them to 0.003 px.
    if nearest < 2.0 * reach + 1.0 {
        return None;
    }
    // A window cut by the image border has lost part of its particle, and the ring around it
    // extrapolates a plane from one side: left as it is.
    let edge = reach + 0.5;
    if c[0] < edge || c[1] < edge || c[0] + edge > (width - 1) as f64 || c[1] + edge > (height - 1) as f64 {
        return None;
    }
    let plane = fit_ring_plane(signal, width, height, c, reach, &others, keep_out)?;
    // The ring must look like background: its pixels about the plane no more spread than
    // a frame's noise about the background, within 3 standard errors of a robust spread estimate
    // (1.16 / sqrt(n) of it, the median absolute deviation's efficiency being 37 %). Clutter
    // or structure in the ring (a wall, a grid, a dial on real video) is not a background a
    // plane describes, and the estimate stays: the bouncing ball's and the pendulum's rings
    // read 1.3-3 times their noise.
    let spread_limit = noise.frame * (1.0 + SIGNIFICANT * 1.16 / (plane.count.max(1) as f64).sqrt());
    if plane.sigma > spread_limit && spread == Spread::Checked {
        return Some(Err(UnevenRing));
    }
    let sloped = plane.b.iter().any(|b| b.abs() > SIGNIFICANT * plane.b_sigma);
    if reach <= window && !sloped {
        return None;
    }
    let moved = centroid_on_plane(signal, width, height, c, reach, &plane)?;
    // The move has two parts: the window's reach over the particle's signal beyond `window`
    // (a window cut short of a blurred or textured ball's edge integrates a lopsided part of
    // it), and the plane taken out. Each is bounded by what it could cause at most, all on
    // one side: the signal between `window` and `reach` (sweep style 1018, a ball of 38 px
    // whose window of 37.5 px moved 0.5 px out to 44.5 px), and a background as high and as
    // steep as the ring's, (level + slope x reach) x window area x reach / mass. A move
    // beyond those is neither (clutter in the ring, a smear of the particle), and the
    // estimate stays.
    let flat = Plane {
        a: 0.0,
        b: [0.0; 2],
        ..plane
    };
    let wide = if reach > window {
        centroid_on_plane(signal, width, height, c, reach, &flat)?
    } else {
        c
    };
    let (mean, _) = ring_mean(signal, width, height, c, (0.0, reach), &others, keep_out);
    let mass = mean * std::f64::consts::PI * reach * reach;
    let (beyond, beyond_count) = ring_mean(signal, width, height, c, (window, reach), &others, keep_out);
    let widening_most = beyond.max(0.0) * beyond_count as f64 * reach / mass.max(f64::MIN_POSITIVE);
    let area = std::f64::consts::PI * reach * reach;
    let level = plane.a.abs() + plane.b[0].hypot(plane.b[1]) * reach;
    let plane_most = level * area * reach / mass.max(f64::MIN_POSITIVE);
    ((wide[0] - c[0]).hypot(wide[1] - c[1]) <= widening_most
        && (moved[0] - wide[0]).hypot(moved[1] - wide[1]) <= plane_most)
        .then_some(Ok(moved))
}

/// Sample frames [`planes_move_points`] reads at most (spread evenly over the samples).
const GATE_SAMPLES: usize = 8;
/// Samples in which a track must move for [`planes_move_points`] (and in more than half of
/// those where it has a detection): at N = 1000 two tracks seen in two or three samples
/// moved in two by chance.
const GATE_SAMPLES_MOVED: usize = 3;

/// What the samples say of the background left around the tracks of a pass.
#[derive(Clone, Debug, Default, PartialEq)]
pub(super) struct SurroundReading {
    /// Returns true if and only if correcting for the local background moves some track
    /// (see [`planes_move_points`]).
    pub(super) moves: bool,
    /// One warning per track whose surroundings are uneven where it matters (see
    /// [`planes_move_points`]).
    pub(super) uneven: Vec<String>,
    /// One warning per other track that the plane around it would move by more than
    /// [`UNEVEN_MOVE`] standard errors in most samples, one way: what to say where the
    /// frames are not located again with the plane (see [`planes_move_points`]).
    pub(super) unmoved: Vec<String>,
}

/// Standard errors (`ep`) by which the plane around a point whose ring is too uneven to be
/// taken out must move it for the unevenness to matter.
const UNEVEN_MOVE: f64 = 3.0;

/// Whether correcting for the local background ([`corrected_position`]) moves some track of
/// `pass`, in most of the sample frames where it has a detection and in
/// [`GATE_SAMPLES_MOVED`] at least, by more than half its standard error (`ep`): then the
/// frames are worth locating again with the correction. A slope that noise alone shows
/// beyond 3 standard errors around one point does not repeat on the same track. Read on up
/// to [`GATE_SAMPLES`] samples (each point's detection within a pixel of it, at its class's
/// window).
///
/// Also a warning for each track whose ring spreads about its plane more than the noise
/// allows (so the correction is not made) where the plane would move it by more than
/// [`UNEVEN_MOVE`] standard errors, in most samples and [`GATE_SAMPLES_MOVED`] at least:
/// the background left around it is uneven, and the centroid integrates it. Sweep style
/// 1019 (a dark textured ball of 30 px hovering under a saturating exposure drift, the
/// median over differently exposed samples leaving arcs round it; ring spread 1.4-2.3 times
/// the noise) was written 0.10 / 0.24 px off (tolerance 0.12 / 0.13) without a word.
///
/// And a warning for each other track that the plane would move by more than
/// [`UNEVEN_MOVE`] standard errors in most samples and [`GATE_SAMPLES_MOVED`] at least, one
/// way, whether its ring was even there or not: should the frames not be located again,
/// its positions are off by about that much. Fresh style 6646 (a textured ball of 39.5 px
/// under noise 30, a gradient and vignetting) was written 2.9 / 2.7 px off without a word:
/// the plane moved it 1.1-2.5 px in 5 of 6 samples, but its ring read even in 3 of them and
/// uneven (the vignetting curves it) in the other 2, so neither count was a majority.
pub(super) fn planes_move_points(
    background: &Background,
    samples: &[FrameView<'_>],
    sample_of: &[Option<usize>],
    pass: &Pass,
    classes: &[SizeClass],
    workers: &Workers,
) -> SurroundReading {
    let mut tracked: BTreeMap<usize, Vec<(&str, [f64; 2])>> = BTreeMap::new();
    for p in &pass.table.points {
        if p.ep.is_finite() {
            tracked
                .entry(p.frame)
                .or_default()
                .push((p.particle.as_str(), [p.x, p.y]));
        }
    }
    let mut read_of: BTreeMap<&str, TrackSurround> = BTreeMap::new();
    let read: Vec<(usize, usize)> = sample_of
        .iter()
        .enumerate()
        .filter_map(|(i, j)| j.map(|j| (i, j)))
        .collect();
    let step = read.len().div_ceil(GATE_SAMPLES).max(1);
    let read_count = read.len().div_ceil(step);
    workers.with(|w| {
        for &(i, j) in read.iter().step_by(step) {
            let Some(&frame) = samples.get(j) else {
                continue;
            };
            let mut levelled = false;
            for (class, located) in classes.iter().zip(&pass.located) {
                let Some(f) = located.get(i) else {
                    continue;
                };
                let Some(points) = tracked.get(&f.frame) else {
                    continue;
                };
                if !levelled {
                    w.finder.levelled_signal(background, frame);
                    levelled = true;
                }
                let (width, height) = frame.size();
                let image = Signal {
                    signal: &w.finder.signal,
                    width,
                    height,
                };
                let at: Vec<[f64; 2]> = f.detections.iter().map(|d| [d.x, d.y]).collect();
                let at = Neighbours::new(&at);
                let (window, most) = (class.window(), class.plane_reach());
                for &(name, p) in points {
                    let Some(k) = at.first_within(p, 1.0) else {
                        continue;
                    };
                    let track = read_of.entry(name).or_default();
                    if track.settled(read_count) {
                        continue;
                    }
                    let d = &f.detections[k];
                    let noise = Noise::of(background);
                    let assessed = corrected_position(&image, &at, k, window, most, noise, Spread::Checked);
                    let moved =
                        matches!(assessed, Some(Ok(c)) if (c[0] - d.x).hypot(c[1] - d.y) > 0.5 * d.ep);
                    track.seen += 1;
                    track.moved += usize::from(moved);
                    let far = |c: [f64; 2]| {
                        Some([c[0] - d.x, c[1] - d.y]).filter(|m| m[0].hypot(m[1]) > UNEVEN_MOVE * d.ep)
                    };
                    let shift = match assessed {
                        Some(Err(UnevenRing)) => {
                            let shift =
                                corrected_position(&image, &at, k, window, most, noise, Spread::Ignored)
                                    .and_then(Result::ok)
                                    .and_then(far);
                            if let Some(shift) = shift {
                                track.uneven.push((f.frame, shift));
                            }
                            shift
                        }
                        Some(Ok(c)) => far(c),
                        None => None,
                    };
                    if let Some(shift) = shift {
                        track.far.push((f.frame, shift));
                    }
                }
            }
        }
    });
    let uneven = read_of
        .iter()
        .filter(|(_, track)| track.is_uneven())
        .map(|(name, track)| {
            let (frames, least, most) = frames_and_range(&track.uneven);
            format!(
                "{name}: the background left around it is uneven in frames {frames} (more than a \
                 plane and the noise), and it would move {least:.2}-{most:.2} px, over {UNEVEN_MOVE} \
                 standard errors, with the plane fitted around it taken out: its positions may be \
                 off by as much"
            )
        })
        .collect();
    let unmoved = read_of
        .iter()
        .filter(|(_, track)| !track.is_uneven() && track.in_most(track.far.len()) && one_way(&track.far))
        .map(|(name, track)| {
            let (frames, least, most) = frames_and_range(&track.far);
            format!(
                "{name}: the background around it is not the one the model took out (a slope or \
                 curve of uneven light, or the particle held in the background) in frames {frames}, \
                 and it would move {least:.2}-{most:.2} px, over {UNEVEN_MOVE} standard errors, with \
                 the plane fitted around it taken out; the frames were not located again so: its \
                 positions may be off by as much"
            )
        })
        .collect();
    SurroundReading {
        moves: read_of.values().any(|track| track.in_most(track.moved)),
        uneven,
        unmoved,
    }
}

/// What the samples read of one track's surroundings ([`planes_move_points`]).
#[derive(Debug, Default)]
struct TrackSurround {
    /// Samples where its detection was measured.
    seen: usize,
    /// Samples where the plane around it, its ring even, moved it by half its `ep` or more.
    moved: usize,
    /// Frame and move, px, where its ring was uneven and the plane would move it beyond
    /// [`UNEVEN_MOVE`] standard errors.
    uneven: Vec<(usize, [f64; 2])>,
    /// Frame and move, px, where the plane would move it beyond [`UNEVEN_MOVE`] standard
    /// errors, its ring even or not (`uneven` among them).
    far: Vec<(usize, [f64; 2])>,
}

impl TrackSurround {
    /// Returns true if and only if `n` samples are most of those seen, and
    /// [`GATE_SAMPLES_MOVED`] at least.
    fn in_most(&self, n: usize) -> bool {
        n >= GATE_SAMPLES_MOVED && 2 * n > self.seen
    }

    /// Returns true if and only if the track stayed, with an even ring, in half of the
    /// `read` samples: it can then neither move nor be uneven nor far in most.
    fn settled(&self, read: usize) -> bool {
        [self.moved, self.uneven.len(), self.far.len()]
            .iter()
            .all(|&n| 2 * (self.seen - n) >= read)
    }

    /// Returns true if and only if its uneven ring would move it in most samples, one way.
    fn is_uneven(&self) -> bool {
        self.in_most(self.uneven.len()) && one_way(&self.uneven)
    }
}

/// The frames of `shifts` (px, one per sample frame read) as a list, and the least and
/// largest shift, px.
fn frames_and_range(shifts: &[(usize, [f64; 2])]) -> (String, f64, f64) {
    // A track of mixed sizes is read in each class that detected its particle, so a frame
    // can come twice (counted so in the gate above, whose limits were measured that way:
    // counted once, style 6095's large spots took the plane pass and came out 0.2 px off,
    // against 0.004).
    let mut frames: Vec<usize> = shifts.iter().map(|(k, _)| *k).collect();
    frames.dedup();
    let frames: Vec<String> = frames.iter().map(usize::to_string).collect();
    let (least, most) = shifts.iter().fold((f64::INFINITY, 0.0f64), |(a, b), &(_, m)| {
        let m = m[0].hypot(m[1]);
        (a.min(m), b.max(m))
    });
    (frames.join(", "), least, most)
}

/// Returns true if and only if the `shifts` (px, one per sample frame) lean one way: their
/// mean stands beyond [`UNEVEN_MOVE`] standard errors (from their spread about it) of
/// zero. An uneven background fixed in the scene moves a track the same way from frame to
/// frame (style 1019's ball, 0.33-0.51 px); noise in a ring that only just fails the spread
/// test moves it every which way (style 1012's spots, 0.11-0.27 px, tracked 0.08 px RMS).
fn one_way(shifts: &[(usize, [f64; 2])]) -> bool {
    let n = shifts.len() as f64;
    if shifts.len() < 2 {
        return false;
    }
    let mean = [0, 1].map(|a| shifts.iter().map(|(_, s)| s[a]).sum::<f64>() / n);
    let var: f64 = shifts
        .iter()
        .map(|(_, s)| (s[0] - mean[0]).powi(2) + (s[1] - mean[1]).powi(2))
        .sum::<f64>()
        / (n - 1.0);
    mean[0].hypot(mean[1]) > UNEVEN_MOVE * (var / n).sqrt()
}

/// The farthest a particle's window may reach when located with the local background taken
/// out, px: the radius of the disc of one particle's measured extent (its area above the
/// noise mask, [`crate::BlobSize::extent`]), at least `window`; `window` when no extent was
/// measured.
pub(super) fn most_reach(params: &crate::DetectParameters, window: f64) -> f64 {
    params
        .expected
        .map_or(window, |e| (e.extent / std::f64::consts::PI).sqrt())
        .max(window)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A pixel noise of one grey level.
    const UNIT: Noise = Noise {
        pixel: 1.0,
        frame: 1.0,
    };

    /// A disc of radius `r` and amplitude `amp` at `c` on `width x height`, exact area
    /// coverage (the project's renderer), plus `background(x, y)`.
    fn disc_on(
        width: usize,
        height: usize,
        c: [f64; 2],
        r: f64,
        amp: f32,
        background: impl Fn(f64, f64) -> f64,
    ) -> Vec<f32> {
        let mut img: Vec<f32> = (0..width * height)
            .map(|i| background((i % width) as f64, (i / width) as f64) as f32)
            .collect();
        crate::locate::tests::render_disc(&mut img, width, height, c, r, amp);
        img
    }

    /// A disc of 20 px on a background rising 0.3 grey levels per px: the plain centroid is
    /// pulled 0.2 px up the slope, the corrected one lies on the centre.
    #[test]
    fn a_slope_left_in_the_signal_is_taken_out() {
        let (w, h, c) = (128, 128, [60.3, 58.7]);
        let signal = disc_on(w, h, c, 20.0, 100.0, |x, _| 5.0 + 0.3 * (x - 64.0));
        let window = 21.0;
        let plain = crate::refine_centroids(&signal, w, h, &[[60.0, 59.0]], &[0.0], window, 1.0);
        assert!(plain[0].x - c[0] > 0.1, "plain centroid {:?}", plain[0]);
        let image = Signal {
            signal: &signal,
            width: w,
            height: h,
        };
        let p = corrected_position(
            &image,
            &Neighbours::new(&[[plain[0].x, plain[0].y]]),
            0,
            window,
            30.0,
            UNIT,
            Spread::Checked,
        )
        .and_then(Result::ok)
        .expect("a slope to take out");
        assert!(
            (p[0] - c[0]).abs() < 0.01 && (p[1] - c[1]).abs() < 0.01,
            "{p:?} vs {c:?}"
        );
    }

    /// On a flat background a disc that ends within its window is left where it is.
    #[test]
    fn a_disc_on_a_flat_background_stays() {
        let (w, h, c) = (96, 96, [47.6, 48.2]);
        let signal = disc_on(w, h, c, 12.0, 100.0, |_, _| 0.0);
        let image = Signal {
            signal: &signal,
            width: w,
            height: h,
        };
        assert_eq!(
            corrected_position(
                &image,
                &Neighbours::new(&[c]),
                0,
                13.0,
                20.0,
                UNIT,
                Spread::Checked
            ),
            None
        );
    }

    /// A window cut by the image border, or one that a neighbour's reaches, is left alone.
    #[test]
    fn windows_at_the_border_or_beside_a_neighbour_stay() {
        let (w, h) = (96, 96);
        let signal = disc_on(w, h, [12.0, 48.0], 12.0, 100.0, |x, _| 0.3 * x);
        let image = Signal {
            signal: &signal,
            width: w,
            height: h,
        };
        assert_eq!(
            corrected_position(
                &image,
                &Neighbours::new(&[[12.0, 48.0]]),
                0,
                13.0,
                20.0,
                UNIT,
                Spread::Checked
            ),
            None
        );
        let points = [[48.0, 48.0], [70.0, 48.0]];
        assert_eq!(
            corrected_position(
                &image,
                &Neighbours::new(&points),
                0,
                13.0,
                20.0,
                UNIT,
                Spread::Checked
            ),
            None
        );
    }

    /// The plane fitted on a ring of a noise-free plane is that plane, with one pixel of
    /// clutter in the ring left out.
    #[test]
    fn the_ring_plane_ignores_clutter() {
        let (w, h, c) = (64, 64, [31.5, 32.25]);
        let mut signal: Vec<f32> = (0..w * h)
            .map(|i| (2.0 + 0.1 * (i % w) as f64 - 0.05 * (i / w) as f64) as f32)
            .collect();
        signal[32 * w + 46] += 500.0;
        let plane = fit_ring_plane(&signal, w, h, c, 10.0, &[], 0.0).expect("a plane");
        assert!(
            (plane.b[0] - 0.1).abs() < 1e-6 && (plane.b[1] + 0.05).abs() < 1e-6,
            "{plane:?}"
        );
        assert!((plane.at(c[0], c[1]) - (2.0 + 0.1 * c[0] - 0.05 * c[1])).abs() < 1e-6);
    }
}
