//! Noisy particles located by fitting their own mean profile instead of their centroid.
//!
//! A centroid weighs every pixel of its window by its distance from the centre, the
//! background inside a ring and around a small blurred spot included: where noise is high,
//! its error runs to two to four times the Cramér-Rao bound (sweep rings of 3 px at noise
//! 16-21: 0.25-0.41 px against bounds of 0.07-0.09). A least-squares fit of the particle's
//! own profile weighs each pixel by how much its level moves with the centre, which reaches
//! the bound. The profile is measured from the data: the particle's mean signal against
//! distance from its points, over sample frames ([`profile_of_halves`]). Each point is
//! then fitted ([`fit_profile`]): the profile scaled and moved, over a plane of background
//! (a gradient or vignetting under the particle is not taken for its light).
//!
//! Only where it pays and where the model holds, judged from the data, particle by particle.
//! The profile's bound ([`RadialProfile::bound`], the fit's error where the model holds) must
//! halve the variance of the particle's centroids in its sample frames ([`MIN_GAIN`]); that
//! costs no fit, and on the benchmark's discs (4 px, noise 5) it ends there. Then every point
//! is fitted, and the fits are kept where the median residual is the pixel noise's
//! ([`MAX_CHI2`]: an object that is not round about its centre, textured or shaded leaves
//! more), the fits differ from the centroids by no more than the centroids' own noise
//! ([`MAX_APART`]: else one of them follows a texture or a shading), their own errors still
//! halve the variance, and the track does not scatter more about its motion with them than
//! without ([`smoother`], [`SMOOTHER_SIGMAS`]): the data's own checks that the fit is not
//! following something the model took for the particle. A fitted point
//! farther from its centroid than the two estimates' errors allow ([`MAX_MOVE_SIGMAS`]) keeps
//! its centroid. Points with a neighbour within twice the fit's reach, bridged or placed
//! points, and hollow particles (located on their rims, see `rims`) are left as they are.

use super::finder::Workers;
use super::window_frames::{ClassFrames, WindowFrames};
use crate::point_grid::PointGrid;
use crate::{Background, PointFlag, TrackError, TrackTable};
use physfit_tracks::stats::median;
use rayon::prelude::*;
use std::collections::{BTreeMap, BTreeSet, HashMap};

/// Width of the profile's distance bins, px.
const BIN: f64 = 0.25;
/// Least pixels a bin must hold to count (fewer are merged into the next): its mean's noise
/// then adds at most 2 % to a fit's residual variance (see [`residual_on_particle`]).
const BIN_PIXELS: usize = 50;
/// Sample frames a particle's profile is measured and judged in, at most.
const PROFILE_FRAMES: usize = 24;
/// Least sample points a particle needs to be judged.
const MIN_SAMPLES: usize = 4;
/// Least ratio of a particle's median centroid error to its median fit error for its points
/// to be fitted: the fit must halve the variance at least. Below that the centroid is
/// already near the bound (discs of 4 px at noise 5: 1.37), and a change of estimator within
/// the tracks, and a second decoding of every frame, buy little.
pub(super) const MIN_GAIN: f64 = std::f64::consts::SQRT_2;
/// Largest median reduced chi-square (residual variance over the pixel noise's) of a
/// particle's sample fits for the fit to be used: a round particle's residual is the noise
/// (the profile's own noise, averaged over every sample point, adds a few percent).
pub(super) const MAX_CHI2: f64 = 1.5;
/// Largest ratio of a particle's fits' mean squared difference from its points (per axis)
/// to its points' mean variance (`ep²`) for the fits to be used. An efficient fit of the right
/// model differs from the centroid of the same image by `ep² − error²` on average (0.47-0.79
/// of `ep²` on fresh styles 8020, 8069 and 8145's rings); where the two differ by more than
/// the centroid's own noise, one of them follows something the noise does not explain, a
/// texture or a shading, and the fit's stated error is no guide (textured balls 6278, 6631,
/// 6779, 6898, 8296 and 8359: 1.2-8.1, their fits 0.01-0.13 px farther off than their
/// centroids).
pub(super) const MAX_APART: f64 = 1.0;
/// A fitted point farther from its centroid than this many standard errors of their
/// difference keeps its centroid.
pub(super) const MAX_MOVE_SIGMAS: f64 = 4.0;
/// Gauss-Newton iterations of one fit, at most.
const MAX_ITERATIONS: usize = 30;

/// A particle's mean signal against distance from its centre: piecewise linear between the
/// mean distances of its bins.
#[derive(Clone, Debug, PartialEq)]
pub(super) struct RadialProfile {
    /// Mean distance of each bin's pixels from their centres, px (increasing).
    r: Vec<f64>,
    /// Mean signal of each bin's pixels, grey levels.
    level: Vec<f64>,
}

impl RadialProfile {
    /// The profile of the signal about `samples` out to `reach` px (see [`accumulate`] and
    /// [`profile_of_halves`]; samples alternate between the halves).
    #[cfg(test)]
    pub(super) fn measure(samples: &[ProfileSample<'_>], reach: f64) -> Option<RadialProfile> {
        let mut halves = [
            vec![Bin::default(); bin_count(reach)],
            vec![Bin::default(); bin_count(reach)],
        ];
        for (k, sample) in samples.iter().enumerate() {
            accumulate(sample, reach, &mut halves[k % 2]);
        }
        profile_of_halves(&halves)
    }

    /// The Cramér-Rao bound of a fit's centre (on one axis, the mean of both axes' variances)
    /// under pixel noise `noise` (grey levels) over the pixels within `reach` px, the centre a
    /// third of a pixel off the grid: what [`fit_profile`] reaches where the profile is the
    /// particle's. `None` where the information is singular.
    fn bound(&self, reach: f64, noise: f64) -> Option<f64> {
        let mut information = nalgebra::Matrix6::<f64>::zeros();
        let span = reach.ceil() as i64 + 1;
        for y in -span..=span {
            for x in -span..=span {
                let (dx, dy) = (x as f64 + 1.0 / 3.0, y as f64 - 1.0 / 3.0);
                let d = (dx * dx + dy * dy).sqrt();
                if d > reach {
                    continue;
                }
                let (level, slope) = self.at(d);
                let j = nalgebra::Vector6::new(-slope * dx / d, -slope * dy / d, level, 1.0, dx, dy);
                information.ger(1.0, &j, &j, 1.0);
            }
        }
        let covariance = information.try_inverse()?;
        let variance = 0.5 * (covariance[(0, 0)] + covariance[(1, 1)]);
        (variance > 0.0).then(|| variance.sqrt() * noise)
    }

    /// The profile's level and slope at distance `d` px: a cubic through the bins' means
    /// whose slope there is the secant of its neighbours' (continuous), flat before the first
    /// bin and after the last.
    fn at(&self, d: f64) -> (f64, f64) {
        let (r, l) = (&self.r, &self.level);
        let n = r.len();
        if d <= r[0] {
            return (l[0], 0.0);
        }
        if d >= r[n - 1] {
            return (l[n - 1], 0.0);
        }
        let k = r.partition_point(|&x| x <= d) - 1;
        let tangent = |i: usize| {
            if i == 0 || i + 1 == n {
                0.0
            } else {
                (l[i + 1] - l[i - 1]) / (r[i + 1] - r[i - 1])
            }
        };
        let h = r[k + 1] - r[k];
        let t = (d - r[k]) / h;
        let (m0, m1) = (tangent(k) * h, tangent(k + 1) * h);
        let (t2, t3) = (t * t, t * t * t);
        let level = (2.0 * t3 - 3.0 * t2 + 1.0) * l[k]
            + (t3 - 2.0 * t2 + t) * m0
            + (-2.0 * t3 + 3.0 * t2) * l[k + 1]
            + (t3 - t2) * m1;
        let slope = ((6.0 * t2 - 6.0 * t) * l[k]
            + (3.0 * t2 - 4.0 * t + 1.0) * m0
            + (-6.0 * t2 + 6.0 * t) * l[k + 1]
            + (3.0 * t2 - 2.0 * t) * m1)
            / h;
        (level, slope)
    }
}

/// One point's pixels: a frame's signal (`width * height`, row-major, particles positive)
/// and the point, px.
pub(super) struct ProfileSample<'a> {
    pub(super) signal: &'a [f32],
    pub(super) width: usize,
    pub(super) height: usize,
    pub(super) centre: [f64; 2],
}

impl ProfileSample<'_> {
    /// `f(dx, dy, signal)` for each pixel within `reach` px of the centre inside the frame.
    fn for_each_pixel(&self, reach: f64, mut f: impl FnMut(f64, f64, f64)) {
        let [cx, cy] = self.centre;
        let x0 = (cx - reach).ceil().max(0.0) as usize;
        let y0 = (cy - reach).ceil().max(0.0) as usize;
        let x1 = ((cx + reach).floor() as i64).min(self.width as i64 - 1);
        let y1 = ((cy + reach).floor() as i64).min(self.height as i64 - 1);
        if x1 < 0 || y1 < 0 {
            return;
        }
        for y in y0..=y1 as usize {
            let dy = y as f64 - cy;
            let row = &self.signal[y * self.width..(y + 1) * self.width];
            for (x, &s) in row.iter().enumerate().take(x1 as usize + 1).skip(x0) {
                let dx = x as f64 - cx;
                if dx * dx + dy * dy <= reach * reach {
                    f(dx, dy, f64::from(s));
                }
            }
        }
    }
}

/// A point located by [`fit_profile`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct ProfileFit {
    /// The fitted centre, px.
    pub(super) centre: [f64; 2],
    /// Its standard error on one axis (the mean of both axes' variances), px: the bound of
    /// the pixel noise, times the square root of the residual variance on the particle's light
    /// over that around it where that exceeds 1 ([`residual_on_particle`]; about 1 where the
    /// profile holds the particle, more where it is textured, shaded or not round).
    pub(super) error: f64,
    /// Residual variance over the pixel noise's, per degree of freedom.
    pub(super) chi2: f64,
}

/// The centre of `sample`'s particle by least squares over the pixels within `reach` px of
/// its centre: `profile` scaled and moved, plus a plane of background (six parameters,
/// Gauss-Newton from the sample's centre, scale 1, plane 0), under pixel noise `noise`
/// (grey levels). `None` where the fit does not converge, its scale is not positive, or it
/// runs off by more than half the reach.
pub(super) fn fit_profile(
    sample: &ProfileSample<'_>,
    profile: &RadialProfile,
    reach: f64,
    noise: f64,
) -> Option<ProfileFit> {
    let [cx, cy] = sample.centre;
    // Inside the frame: a window the border cuts keeps the pixels it holds.
    let mut pixels: Vec<(f64, f64, f64)> = Vec::new();
    sample.for_each_pixel(reach, |dx, dy, s| pixels.push((dx, dy, s)));
    if pixels.len() < 12 {
        return None;
    }
    // Parameters: centre offset (2), scale, background level and slopes (x, y).
    let mut theta = [0.0, 0.0, 1.0, 0.0, 0.0, 0.0];
    let normal = |theta: &[f64; 6]| {
        let mut jtj = nalgebra::Matrix6::<f64>::zeros();
        let mut jte = nalgebra::Vector6::<f64>::zeros();
        let mut sse = 0.0;
        for &(dx, dy, s) in &pixels {
            let (ux, uy) = (dx - theta[0], dy - theta[1]);
            let d = (ux * ux + uy * uy).sqrt();
            let (level, slope) = profile.at(d);
            let (gx, gy) = if d > 1e-9 {
                (-theta[2] * slope * ux / d, -theta[2] * slope * uy / d)
            } else {
                (0.0, 0.0)
            };
            let j = nalgebra::Vector6::new(gx, gy, level, 1.0, dx, dy);
            let e = s - (theta[2] * level + theta[3] + theta[4] * dx + theta[5] * dy);
            jtj.ger(1.0, &j, &j, 1.0);
            jte.axpy(e, &j, 1.0);
            sse += e * e;
        }
        (jtj, jte, sse)
    };
    // Gauss-Newton, each step halved until the residual falls (the profile is piecewise
    // cubic: its slope is continuous, its curvature not).
    let (mut jtj, mut jte, mut sse) = normal(&theta);
    let mut converged = false;
    for _ in 0..MAX_ITERATIONS {
        let step = jtj.cholesky()?.solve(&jte);
        // At most a pixel at a time: the profile's slope is only known locally.
        let length = step[0].hypot(step[1]);
        let mut scale = if length > 1.0 { 1.0 / length } else { 1.0 };
        let mut next = None;
        for _ in 0..12 {
            let mut trial = theta;
            for (t, s) in trial.iter_mut().zip(step.iter()) {
                *t += s * scale;
            }
            let fitted = normal(&trial);
            if fitted.2 <= sse {
                next = Some((trial, fitted));
                break;
            }
            scale *= 0.5;
        }
        let Some((trial, fitted)) = next else {
            // No step lowers the residual: at the minimum as far as the arithmetic tells.
            converged = true;
            break;
        };
        let moved = length * scale;
        let gained = sse - fitted.2;
        theta = trial;
        (jtj, jte, sse) = fitted;
        if theta[0].hypot(theta[1]) > reach / 2.0 {
            return None;
        }
        // Converged once the centre moves by less than a fiftieth of its own error, or the
        // residual falls by less than a part in 1e8.
        let variance = jtj.try_inverse().map_or(0.0, |c| 0.5 * (c[(0, 0)] + c[(1, 1)]));
        if moved < (0.02 * variance.max(0.0).sqrt() * noise.max(1e-9)).max(1e-5) || gained < 1e-8 * sse {
            converged = true;
            break;
        }
    }
    if !converged || theta[2] <= 0.0 {
        return None;
    }
    let covariance = jtj.try_inverse()?;
    let dof = pixels.len() as f64 - 6.0;
    let noise = noise.max(1e-9);
    // The bound, with what the profile leaves on the particle's light beyond the noise counted
    // as noise: a textured ball's texture, a shaded sphere's light, a blurred streak.
    let on_particle = residual_on_particle(&pixels, &theta, profile);
    let misfit = if on_particle.is_finite() {
        on_particle.max(1.0).sqrt()
    } else {
        1.0
    };
    let error = (0.5 * (covariance[(0, 0)] + covariance[(1, 1)])).max(0.0).sqrt() * noise * misfit;
    Some(ProfileFit {
        centre: [cx + theta[0], cy + theta[1]],
        error,
        chi2: sse / dof / (noise * noise),
    })
}

/// The residual variance of a fit (`theta`, over `pixels` `(dx, dy, signal)`) on the pixels
/// of the particle's light (where `profile` stands more than a quarter of its range from its
/// last level) over that on the others; NaN where either holds fewer than 12 pixels.
fn residual_on_particle(pixels: &[(f64, f64, f64)], theta: &[f64; 6], profile: &RadialProfile) -> f64 {
    let tail = *profile.level.last().unwrap_or(&0.0);
    let range = profile.level.iter().map(|l| (l - tail).abs()).fold(0.0, f64::max);
    let (mut on, mut off) = ((0.0, 0usize), (0.0, 0usize));
    for &(dx, dy, s) in pixels {
        let d = (dx - theta[0]).hypot(dy - theta[1]);
        let level = profile.at(d).0;
        let e = s - (theta[2] * level + theta[3] + theta[4] * dx + theta[5] * dy);
        let side = if (level - tail).abs() > 0.25 * range {
            &mut on
        } else {
            &mut off
        };
        (side.0, side.1) = (side.0 + e * e, side.1 + 1);
    }
    if on.1 < 12 || off.1 < 12 {
        return f64::NAN;
    }
    (on.0 / on.1 as f64) / (off.0 / off.1 as f64)
}

/// What [`fit_profiles`] did.
#[derive(Debug, Default)]
pub(super) struct ProfilesFitted {
    /// Points moved to their fitted centre.
    pub(super) moved: usize,
}

/// Moves the detected points of `table`'s particles (not in `hollow`) to the centre of their
/// own mean profile (see the module documentation), particles of radius `radius` px, where
/// that is judged to pay and to hold.
pub(super) fn fit_profiles(
    table: &mut TrackTable,
    hollow: &BTreeSet<String>,
    class: &ClassFrames<'_>,
) -> Result<ProfilesFitted, TrackError> {
    let ClassFrames {
        frames,
        background,
        radius,
        workers,
    } = *class;
    let reach = super::rims::rim_reach(radius);
    let eligible = eligible_points(table, hollow, reach);
    if eligible.iter().all(|&e| !e) {
        return Ok(ProfilesFitted::default());
    }
    // Sample frames (already decoded), at most PROFILE_FRAMES evenly spread.
    let chosen = frames.spread_samples(PROFILE_FRAMES);
    let in_samples: Vec<usize> = (0..table.points.len())
        .filter(|&i| eligible[i] && chosen.binary_search(&table.points[i].frame).is_ok())
        .collect();
    // Each particle's profile about its centroids; the particles whose fits the profile says
    // would pay (judged without a fit: the bound is the fit's error where the model holds).
    let centroid_at: Vec<[f64; 2]> = table.points.iter().map(|p| [p.x, p.y]).collect();
    let profiles = measure_profiles(
        table,
        &in_samples,
        &centroid_at,
        frames,
        background,
        reach,
        workers,
    )?;
    let mut sample_errors: BTreeMap<&str, Vec<f64>> = BTreeMap::new();
    for &i in &in_samples {
        let p = &table.points[i];
        sample_errors.entry(&p.particle).or_default().push(p.ep);
    }
    let promising: BTreeSet<&str> = sample_errors
        .iter_mut()
        .filter_map(|(name, errors)| {
            let bound = profiles
                .get(*name)
                .and_then(|pr| pr.bound(reach, background.noise_sigma));
            let pays = errors.len() >= MIN_SAMPLES && bound.is_some_and(|b| median(errors) >= MIN_GAIN * b);
            pays.then_some(*name)
        })
        .collect();
    if promising.is_empty() {
        return Ok(ProfilesFitted::default());
    }
    let in_samples: Vec<usize> = (in_samples.into_iter())
        .filter(|&i| promising.contains(table.points[i].particle.as_str()))
        .collect();
    // Their profiles again about their fits (once), then every point fitted.
    let mut at = centroid_at.clone();
    for (i, fit) in fit_points(
        table,
        &in_samples,
        &at,
        &profiles,
        frames,
        background,
        reach,
        workers,
    )? {
        at[i] = fit.centre;
    }
    let profiles = measure_profiles(table, &in_samples, &at, frames, background, reach, workers)?;
    let all: Vec<usize> = (0..table.points.len())
        .filter(|&i| eligible[i] && promising.contains(table.points[i].particle.as_str()))
        .collect();
    let fits = fit_points(
        table,
        &all,
        &centroid_at,
        &profiles,
        frames,
        background,
        reach,
        workers,
    )?;
    // Each point's fit, where it holds: within MAX_MOVE_SIGMAS of the point (the two errors
    // taken as independent, a bound on their difference's spread that a change of estimator
    // does not reach) and its residual within twice MAX_CHI2.
    let mut by_particle: BTreeMap<String, Vec<(usize, ProfileFit)>> = BTreeMap::new();
    let mut chi2: BTreeMap<String, Vec<f64>> = BTreeMap::new();
    for (i, fit) in fits {
        let p = &table.points[i];
        chi2.entry(p.particle.clone()).or_default().push(fit.chi2);
        let spread = (p.ep * p.ep + fit.error * fit.error).sqrt();
        let shift = (fit.centre[0] - p.x).hypot(fit.centre[1] - p.y);
        if shift <= MAX_MOVE_SIGMAS * spread && fit.chi2 <= 2.0 * MAX_CHI2 {
            by_particle.entry(p.particle.clone()).or_default().push((i, fit));
        }
    }
    // Judged particle by particle: the model must hold (the median residual that of the
    // noise), the fits must say they pay, and the fitted track must not scatter more about
    // its motion than the located one.
    let mut tracks: HashMap<&str, Vec<usize>> = HashMap::new();
    for (i, p) in table.points.iter().enumerate() {
        if by_particle.contains_key(&p.particle) {
            tracks.entry(p.particle.as_str()).or_default().push(i);
        }
    }
    let mut kept: Vec<(usize, ProfileFit)> = Vec::new();
    for (name, fits) in by_particle {
        let (Some(track), Some(c)) = (tracks.get_mut(name.as_str()), chi2.get_mut(&name)) else {
            continue;
        };
        track.sort_by_key(|&i| table.points[i].frame);
        let located: Vec<[f64; 2]> = track
            .iter()
            .map(|&i| [table.points[i].x, table.points[i].y])
            .collect();
        let mut fitted = located.clone();
        let place: HashMap<usize, usize> = track.iter().enumerate().map(|(k, &i)| (i, k)).collect();
        for (i, fit) in &fits {
            fitted[place[i]] = fit.centre;
        }
        let frames_of: Vec<usize> = track.iter().map(|&i| table.points[i].frame).collect();
        let mut ep: Vec<f64> = fits.iter().map(|(i, _)| table.points[*i].ep).collect();
        let mut errors: Vec<f64> = fits.iter().map(|(_, f)| f.error).collect();
        // Per axis, the fits' mean squared difference from the points against the points' mean
        // variance: an efficient fit of the right model differs from the centroid of the same
        // image by `ep² − error²` on average, under `ep²`.
        let (mut apart, mut variance) = (0.0, 0.0);
        for (i, f) in &fits {
            let p = &table.points[*i];
            apart += ((f.centre[0] - p.x).powi(2) + (f.centre[1] - p.y).powi(2)) / 2.0;
            variance += p.ep * p.ep;
        }
        if median(c) <= MAX_CHI2
            && apart <= MAX_APART * variance
            && median(&mut ep) >= MIN_GAIN * median(&mut errors)
            && smoother(&frames_of, &located, &fitted) > -SMOOTHER_SIGMAS
        {
            kept.extend(fits);
        }
    }
    let moved = kept.len();
    for (i, fit) in kept {
        let p = &mut table.points[i];
        (p.x, p.y, p.ep) = (fit.centre[0], fit.centre[1], fit.error);
    }
    Ok(ProfilesFitted { moved })
}

/// How many standard errors a track's scatter about its motion may rise by with its fits for
/// them to be kept (see [`smoother`]).
pub(super) const SMOOTHER_SIGMAS: f64 = 2.0;

/// How much less a track scatters about its motion at the positions `fitted` than at
/// `located` (its points' frames `frames`, increasing), in standard errors: the mean over
/// runs of three consecutive frames of the drop in the squared second difference, over its
/// standard error (widened by √3, each point sitting in three runs). Positive where `fitted`
/// is smoother. 0 where fewer than 4 runs are found.
fn smoother(frames: &[usize], located: &[[f64; 2]], fitted: &[[f64; 2]]) -> f64 {
    let second = |p: &[[f64; 2]], k: usize| {
        let dx = p[k + 1][0] - 2.0 * p[k][0] + p[k - 1][0];
        let dy = p[k + 1][1] - 2.0 * p[k][1] + p[k - 1][1];
        dx * dx + dy * dy
    };
    let drops: Vec<f64> = (1..frames.len().saturating_sub(1))
        .filter(|&k| frames[k - 1] + 1 == frames[k] && frames[k] + 1 == frames[k + 1])
        .map(|k| second(located, k) - second(fitted, k))
        .collect();
    let n = drops.len() as f64;
    if drops.len() < 4 {
        return 0.0;
    }
    let mean = drops.iter().sum::<f64>() / n;
    let variance = drops.iter().map(|d| (d - mean).powi(2)).sum::<f64>() / (n - 1.0);
    let error = (3.0 * variance / n).sqrt();
    if error > 0.0 {
        mean / error
    } else {
        0.0
    }
}

/// Which points of `table` may be fitted: detected, of a particle not in `hollow`, with no
/// other point of their frame within twice `reach` px.
fn eligible_points(table: &TrackTable, hollow: &BTreeSet<String>, reach: f64) -> Vec<bool> {
    let points = &table.points;
    let mut eligible: Vec<bool> = points
        .iter()
        .map(|p| p.flag == PointFlag::Detected && !hollow.contains(&p.particle) && p.ep.is_finite())
        .collect();
    let mut by_frame: BTreeMap<usize, Vec<usize>> = BTreeMap::new();
    for (i, p) in points.iter().enumerate() {
        by_frame.entry(p.frame).or_default().push(i);
    }
    for idx in by_frame.values() {
        let at: Vec<[f64; 2]> = idx.iter().map(|&i| [points[i].x, points[i].y]).collect();
        let grid = PointGrid::new(&at);
        for (&i, p) in idx.iter().zip(&at) {
            if eligible[i] && grid.any_other_within(p, 2.0 * reach) {
                eligible[i] = false;
            }
        }
    }
    eligible
}

/// Each particle's profile about the points `which` of `table`, at the centres `at`.
fn measure_profiles(
    table: &TrackTable,
    which: &[usize],
    at: &[[f64; 2]],
    frames: &WindowFrames<'_>,
    background: &Background,
    reach: f64,
    workers: &Workers,
) -> Result<BTreeMap<String, RadialProfile>, TrackError> {
    // Frames alternate between two halves (see `profile_of_halves`).
    let by_frame: Vec<(usize, (usize, Vec<usize>))> =
        group_by_frame(table, which).into_iter().enumerate().collect();
    // Per frame, per particle: the bins' sums, merged afterwards.
    type Sums = BTreeMap<String, [Vec<Bin>; 2]>;
    let bins = bin_count(reach);
    let empty = || [vec![Bin::default(); bins], vec![Bin::default(); bins]];
    let per_frame: Vec<Sums> = by_frame
        .into_par_iter()
        .map(|(rank, (k, idx))| {
            frames.with_signal(k, background, workers, |signal, width, height| {
                let mut sums: Sums = BTreeMap::new();
                for i in idx {
                    let sample = ProfileSample {
                        signal,
                        width,
                        height,
                        centre: at[i],
                    };
                    let entry = sums.entry(table.points[i].particle.clone()).or_insert_with(empty);
                    accumulate(&sample, reach, &mut entry[rank % 2]);
                }
                sums
            })
        })
        .collect::<Result<_, TrackError>>()?;
    let mut total: Sums = BTreeMap::new();
    for sums in per_frame {
        for (name, halves) in sums {
            let t = total.entry(name).or_insert_with(empty);
            for (t, h) in t.iter_mut().zip(halves) {
                for (t, b) in t.iter_mut().zip(h) {
                    t.add(&b);
                }
            }
        }
    }
    Ok(total
        .into_iter()
        .filter_map(|(name, halves)| Some((name, profile_of_halves(&halves)?)))
        .collect())
}

/// Bins of [`BIN`] px out to `reach` px.
fn bin_count(reach: f64) -> usize {
    (reach / BIN).ceil() as usize + 1
}

/// The pixels of a distance bin: their distances' sum (px), their signal's (grey levels),
/// and their count.
#[derive(Clone, Copy, Debug, Default)]
struct Bin {
    r: f64,
    s: f64,
    n: usize,
}

impl Bin {
    fn add(&mut self, other: &Bin) {
        self.r += other.r;
        self.s += other.s;
        self.n += other.n;
    }
}

/// Adds `sample`'s pixels within `reach` px of its centre to `bins` (by distance, [`BIN`] px
/// each).
fn accumulate(sample: &ProfileSample<'_>, reach: f64, bins: &mut [Bin]) {
    sample.for_each_pixel(reach, |dx, dy, s| {
        let r = (dx * dx + dy * dy).sqrt();
        let b = &mut bins[(r / BIN) as usize];
        b.r += r;
        b.s += s;
        b.n += 1;
    });
}

/// Widths of the profile's bins tried, in [`BIN`]s.
const WIDTHS: [usize; 7] = [1, 2, 4, 8, 16, 32, 64];

/// The profile of two halves of a particle's samples (bins of [`BIN`] px), its bins as wide
/// as predicts each half best from the other. Bins too narrow hold the samples' noise,
/// whose slopes the fit would follow (a spot of 19 px at noise 18, 17 samples, bins of
/// 0.25 px: fits 0.20 px off where the centroid was 0.16); bins too wide flatten the
/// particle's edge. Each half's bins are scored against the other half's profile: `Σ n T² −
/// 2 T Σ s` per bin, the sum of squared residuals less the part that no profile changes.
fn profile_of_halves(halves: &[Vec<Bin>; 2]) -> Option<RadialProfile> {
    let merged = |bins: &[Bin], k: usize| -> Vec<Bin> {
        bins.chunks(k)
            .map(|c| {
                let mut m = Bin::default();
                c.iter().for_each(|b| m.add(b));
                m
            })
            .collect()
    };
    let score = |bins: &[Bin], profile: &RadialProfile| -> f64 {
        (bins.iter().filter(|b| b.n > 0))
            .map(|b| {
                let t = profile.at(b.r / b.n as f64).0;
                b.n as f64 * t * t - 2.0 * t * b.s
            })
            .sum()
    };
    let mut best: Option<(f64, usize)> = None;
    for k in WIDTHS {
        let (Some(a), Some(b)) = (
            profile_of_bins(&merged(&halves[0], k)),
            profile_of_bins(&merged(&halves[1], k)),
        ) else {
            continue;
        };
        let cv = score(&halves[1], &a) + score(&halves[0], &b);
        if best.map_or(true, |(s, _)| cv < s) {
            best = Some((cv, k));
        }
    }
    let (_, k) = best?;
    let mut all = halves[0].clone();
    for (a, b) in all.iter_mut().zip(&halves[1]) {
        a.add(b);
    }
    profile_of_bins(&merged(&all, k))
}

/// The profile of `bins`, bins of fewer than [`BIN_PIXELS`] merged into the next.
fn profile_of_bins(bins: &[Bin]) -> Option<RadialProfile> {
    let (mut r, mut level) = (Vec::new(), Vec::new());
    let mut acc = Bin::default();
    for b in bins {
        acc.add(b);
        if acc.n >= BIN_PIXELS {
            r.push(acc.r / acc.n as f64);
            level.push(acc.s / acc.n as f64);
            acc = Bin::default();
        }
    }
    (r.len() >= 3).then_some(RadialProfile { r, level })
}

/// The fits of the points `which` of `table` started at `at`, each with its particle's
/// profile (points of particles without one are not fitted).
#[allow(clippy::too_many_arguments)]
fn fit_points(
    table: &TrackTable,
    which: &[usize],
    at: &[[f64; 2]],
    profiles: &BTreeMap<String, RadialProfile>,
    frames: &WindowFrames<'_>,
    background: &Background,
    reach: f64,
    workers: &Workers,
) -> Result<Vec<(usize, ProfileFit)>, TrackError> {
    let by_frame = group_by_frame(table, which);
    let fits: Vec<Vec<(usize, ProfileFit)>> = by_frame
        .into_par_iter()
        .map(|(k, idx)| {
            frames.with_signal(k, background, workers, |signal, width, height| {
                let mut out = Vec::new();
                for i in idx {
                    let Some(profile) = profiles.get(&table.points[i].particle) else {
                        continue;
                    };
                    let sample = ProfileSample {
                        signal,
                        width,
                        height,
                        centre: at[i],
                    };
                    if let Some(fit) = fit_profile(&sample, profile, reach, background.noise_sigma) {
                        out.push((i, fit));
                    }
                }
                out
            })
        })
        .collect::<Result<_, TrackError>>()?;
    Ok(fits.into_iter().flatten().collect())
}

/// The points `which` of `table` by frame.
fn group_by_frame(table: &TrackTable, which: &[usize]) -> BTreeMap<usize, Vec<usize>> {
    let mut by_frame: BTreeMap<usize, Vec<usize>> = BTreeMap::new();
    for &i in which {
        by_frame.entry(table.points[i].frame).or_default().push(i);
    }
    by_frame
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;
    use rand_distr::{Distribution, Normal};

    const SIZE: usize = 48;

    /// A frame of `SIZE` px square: `shape(dx, dy)` about `c`, plus `plane(x, y)` and white
    /// noise of `noise` grey levels.
    fn frame(
        c: [f64; 2],
        shape: &dyn Fn(f64, f64) -> f64,
        plane: &dyn Fn(f64, f64) -> f64,
        noise: f64,
        rng: &mut ChaCha8Rng,
    ) -> Vec<f32> {
        let normal = Normal::new(0.0, noise.max(1e-12)).unwrap();
        let mut out = vec![0.0f32; SIZE * SIZE];
        for y in 0..SIZE {
            for x in 0..SIZE {
                let (fx, fy) = (x as f64, y as f64);
                let n = if noise > 0.0 { normal.sample(rng) } else { 0.0 };
                out[y * SIZE + x] = (shape(fx - c[0], fy - c[1]) + plane(fx, fy) + n) as f32;
            }
        }
        out
    }

    /// The Cramér-Rao bound of `shape`'s centre on x at noise `noise` (the particle's scale
    /// and a plane of background estimated with it), px.
    fn bound(shape: &dyn Fn(f64, f64) -> f64, reach: f64, noise: f64) -> f64 {
        let mut fisher = nalgebra::Matrix6::<f64>::zeros();
        let h = 1e-4;
        for y in -(reach as i64)..=(reach as i64) {
            for x in -(reach as i64)..=(reach as i64) {
                let (dx, dy) = (x as f64 + 0.3, y as f64 - 0.2);
                if dx * dx + dy * dy > reach * reach {
                    continue;
                }
                let gx = -(shape(dx + h, dy) - shape(dx - h, dy)) / (2.0 * h);
                let gy = -(shape(dx, dy + h) - shape(dx, dy - h)) / (2.0 * h);
                let j = nalgebra::Vector6::new(gx, gy, shape(dx, dy), 1.0, dx, dy);
                fisher.ger(1.0, &j, &j, 1.0);
            }
        }
        noise * fisher.try_inverse().unwrap()[(0, 0)].sqrt()
    }

    /// Centroid of the positive signal within `reach` px of `start`, iterated 10 times.
    fn centroid(signal: &[f32], start: [f64; 2], reach: f64) -> [f64; 2] {
        let mut c = start;
        for _ in 0..10 {
            let (mut sx, mut sy, mut s) = (0.0, 0.0, 0.0);
            let sample = ProfileSample {
                signal,
                width: SIZE,
                height: SIZE,
                centre: c,
            };
            sample.for_each_pixel(reach, |dx, dy, v| {
                sx += v * dx;
                sy += v * dy;
                s += v;
            });
            c = [c[0] + sx / s, c[1] + sy / s];
        }
        c
    }

    /// Fits of `n` frames of `shape` at random centres: started at their centroids, the
    /// profile measured about them and again about the first fits. Returns each frame's
    /// truth, centroid and fit.
    fn fits_of(
        shape: &dyn Fn(f64, f64) -> f64,
        plane: &dyn Fn(f64, f64) -> f64,
        noise: f64,
        reach: f64,
        seed: u64,
    ) -> Vec<([f64; 2], [f64; 2], Option<ProfileFit>)> {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let mid = SIZE as f64 / 2.0;
        let frames: Vec<([f64; 2], Vec<f32>)> = (0..40)
            .map(|_| {
                let c = [mid + rng.gen_range(-1.5..1.5), mid + rng.gen_range(-1.5..1.5)];
                let f = frame(c, shape, plane, noise, &mut rng);
                (c, f)
            })
            .collect();
        let starts: Vec<[f64; 2]> = frames
            .iter()
            .map(|(_, f)| centroid(f, [mid, mid], reach))
            .collect();
        let samples = |at: &[[f64; 2]]| -> Vec<ProfileSample<'_>> {
            frames
                .iter()
                .zip(at)
                .map(|((_, f), &c)| ProfileSample {
                    signal: f,
                    width: SIZE,
                    height: SIZE,
                    centre: c,
                })
                .collect()
        };
        let fit_all = |profile: &RadialProfile| -> Vec<Option<ProfileFit>> {
            samples(&starts)
                .iter()
                .map(|s| fit_profile(s, profile, reach, noise.max(0.3)))
                .collect()
        };
        let profile = RadialProfile::measure(&samples(&starts), reach).unwrap();
        let first: Vec<[f64; 2]> = fit_all(&profile)
            .iter()
            .zip(&starts)
            .map(|(f, s)| f.map_or(*s, |f| f.centre))
            .collect();
        let profile = RadialProfile::measure(&samples(&first), reach).unwrap();
        let fits = fit_all(&profile);
        frames
            .iter()
            .zip(starts)
            .zip(fits)
            .map(|(((c, _), s), f)| (*c, s, f))
            .collect()
    }

    fn rms_x(pairs: impl Iterator<Item = ([f64; 2], [f64; 2])>) -> f64 {
        let d: Vec<f64> = pairs.map(|(a, b)| (a[0] - b[0]).powi(2)).collect();
        (d.iter().sum::<f64>() / d.len() as f64).sqrt()
    }

    #[test]
    fn a_noisy_ring_is_fitted_near_its_bound_and_far_inside_its_centroid() {
        // A blurred ring of 3 px (rim 0.9 px wide, 60 grey levels high) at noise 16.
        let ring = |dx: f64, dy: f64| {
            let r = (dx * dx + dy * dy).sqrt();
            60.0 * (-(r - 3.0).powi(2) / (2.0 * 0.9 * 0.9)).exp()
        };
        let reach = 1.5 * 3.5 + 2.0;
        let crb = bound(&ring, reach, 16.0);
        for seed in 0..3 {
            let fits = fits_of(&ring, &|_, _| 0.0, 16.0, reach, seed);
            // A fit that does not converge leaves its point at its centroid: rare.
            let failed = fits.iter().filter(|f| f.2.is_none()).count();
            assert!(failed <= 2, "seed {seed}: {failed} of 40 fits failed");
            let fits: Vec<_> = fits.into_iter().filter(|f| f.2.is_some()).collect();
            let fitted = rms_x(fits.iter().map(|f| (f.0, f.2.unwrap().centre)));
            let centroid = rms_x(fits.iter().map(|f| (f.0, f.1)));
            let said = median(&mut fits.iter().map(|f| f.2.unwrap().error).collect::<Vec<_>>());
            let chi2 = median(&mut fits.iter().map(|f| f.2.unwrap().chi2).collect::<Vec<_>>());
            println!("seed {seed}: fit {fitted:.4} px, centroid {centroid:.4}, bound {crb:.4}, said {said:.4}, chi2 {chi2:.3}");
            // 40 frames: an RMS within about 25 % of its expectation.
            assert!(
                fitted < 1.4 * crb,
                "seed {seed}: fit {fitted:.4} px against a bound of {crb:.4}"
            );
            assert!(
                fitted < 0.6 * centroid,
                "seed {seed}: fit {fitted:.4} against centroid {centroid:.4}"
            );
            assert!(
                (0.7..1.4).contains(&(said / crb)),
                "seed {seed}: said {said:.4}, bound {crb:.4}"
            );
            assert!(chi2 < MAX_CHI2, "seed {seed}: chi2 {chi2:.3}");
        }
    }

    #[test]
    fn a_plane_of_light_under_a_spot_does_not_move_its_fit() {
        // A Gaussian spot (sigma 3 px, 100 high) on a slope of half a grey level a pixel: its
        // centroid leans by tenths of a pixel, its fit does not.
        let spot = |dx: f64, dy: f64| 100.0 * (-(dx * dx + dy * dy) / 18.0).exp();
        let plane = |x: f64, y: f64| 0.5 * (x - 24.0) + 0.25 * (y - 24.0);
        let reach = 12.0;
        let fits = fits_of(&spot, &plane, 0.0, reach, 7);
        let fitted = rms_x(fits.iter().map(|f| (f.0, f.2.unwrap().centre)));
        let centroid = rms_x(fits.iter().map(|f| (f.0, f.1)));
        assert!(centroid > 0.1, "centroid {centroid:.4}");
        assert!(fitted < 0.01, "fit {fitted:.4} px off");
    }

    #[test]
    fn a_particle_that_is_not_round_leaves_more_than_noise() {
        // An ellipse of 4 by 2 px (sigmas) at noise 4: the radial profile cannot hold it.
        let ellipse = |dx: f64, dy: f64| 80.0 * (-(dx * dx / 32.0 + dy * dy / 8.0)).exp();
        let round = |dx: f64, dy: f64| 80.0 * (-(dx * dx + dy * dy) / 16.0).exp();
        let chi2 = |shape: &dyn Fn(f64, f64) -> f64| {
            let fits = fits_of(shape, &|_, _| 0.0, 4.0, 10.0, 3);
            median(&mut fits.iter().filter_map(|f| Some(f.2?.chi2)).collect::<Vec<_>>())
        };
        let (elongated, circular) = (chi2(&ellipse), chi2(&round));
        assert!(elongated > 2.0 * MAX_CHI2, "ellipse chi2 {elongated:.3}");
        assert!(circular < MAX_CHI2, "round chi2 {circular:.3}");
    }

    #[test]
    fn a_track_scatters_less_about_its_motion_with_the_better_estimates() {
        // A parabola over 30 frames, located with errors of 0.3 px and fitted with 0.1 px.
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        let (wide, narrow) = (Normal::new(0.0, 0.3).unwrap(), Normal::new(0.0, 0.1).unwrap());
        let truth = |k: usize| [2.0 * k as f64, 0.05 * (k * k) as f64];
        let frames: Vec<usize> = (0..30).collect();
        let noisy = |n: &Normal<f64>, rng: &mut ChaCha8Rng| -> Vec<[f64; 2]> {
            (0..30).map(|k| truth(k).map(|c| c + n.sample(rng))).collect()
        };
        let located = noisy(&wide, &mut rng);
        let fitted = noisy(&narrow, &mut rng);
        let better = smoother(&frames, &located, &fitted);
        assert!(better > SMOOTHER_SIGMAS, "{better:.2}");
        let worse = smoother(&frames, &fitted, &located);
        assert!(worse < -SMOOTHER_SIGMAS, "{worse:.2}");
        // Runs of three consecutive frames only: frames 0, 2, 4, ... hold none.
        let even: Vec<usize> = (0..30).map(|k| 2 * k).collect();
        assert!(smoother(&even, &located, &fitted).abs() < 1e-300);
    }

    #[test]
    fn the_profile_is_the_mean_signal_at_each_distance() {
        // A cone, 10 - r, in 8 frames: the profile reads it back within the bins' spread.
        let cone = |dx: f64, dy: f64| (10.0 - (dx * dx + dy * dy).sqrt()).max(0.0);
        let mut rng = ChaCha8Rng::seed_from_u64(1);
        let centres: Vec<[f64; 2]> = (0..8)
            .map(|k| [23.5 + 0.13 * k as f64, 24.2 - 0.11 * k as f64])
            .collect();
        let frames: Vec<Vec<f32>> = centres
            .iter()
            .map(|&c| frame(c, &cone, &|_, _| 0.0, 0.0, &mut rng))
            .collect();
        let samples: Vec<ProfileSample<'_>> = (frames.iter().zip(centres.iter().copied()))
            .map(|(f, centre)| ProfileSample {
                signal: f,
                width: SIZE,
                height: SIZE,
                centre,
            })
            .collect();
        let profile = RadialProfile::measure(&samples, 8.0).unwrap();
        for d in [2.0, 3.5, 5.0, 6.0, 7.5] {
            let (level, slope) = profile.at(d);
            assert!((level - (10.0 - d)).abs() < 0.05, "{d}: {level}");
            assert!((slope + 1.0).abs() < 0.1, "{d}: slope {slope}");
        }
    }
}
