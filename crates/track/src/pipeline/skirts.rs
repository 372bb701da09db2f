//! The skirt self-check's samples: signal around each tracked particle, located unfiltered.

use super::finder::{locate_window, Finder, Parts, Workers};
use super::radius::nearest_each;
use super::rims::rim_reach;
use super::size_class::Sizes;
use super::window_frames::{ClassFrames, WindowFrames};
use crate::checks::{clipped_ring, skirts, Skirt};
use crate::rim::rim_centre;
use crate::{
    Background, DetectParameters, Detection, FrameView, PointFlag, TrackError, TrackPoint, TrackTable,
};
use physfit_tracks::stats::median;
use rayon::prelude::*;
use std::collections::BTreeMap;

/// Sample frames the skirts are measured in, at most.
const SKIRT_FRAMES: usize = 8;

/// A point whose mean signal within half its radius is under this fraction of its disc's
/// ([`Skirt::inner`]) may sit inside a hollow particle: its rim is measured
/// ([`rim_centre`], which decides). A flat disc reads about 1 (particles not hollow in the
/// ring neighbours read 0.91-2.8), a spot or a sphere more, a thin ring followed at about its own
/// radius near 0, rings blurred by a third of their radius 0.5-0.8.
const HOLLOW: f64 = 0.9;

/// The skirts ([`skirts`]) of the detected points of `table` in up to
/// [`SKIRT_FRAMES`] of the sample frames of the window, by particle: frame and skirt each.
pub(super) fn sample_skirts(
    table: &TrackTable,
    class: &ClassFrames<'_>,
) -> Result<BTreeMap<String, Vec<(usize, Skirt)>>, TrackError> {
    let ClassFrames {
        frames,
        background,
        radius,
        workers,
    } = *class;
    // At most SKIRT_FRAMES of the sample frames, evenly spread: a median over them is plenty,
    // and each costs a pass over its points' rings.
    let chosen = frames.spread_samples(SKIRT_FRAMES);
    let mut by_frame: BTreeMap<usize, Vec<&TrackPoint>> = BTreeMap::new();
    for p in &table.points {
        if p.flag == PointFlag::Detected && chosen.binary_search(&p.frame).is_ok() {
            by_frame.entry(p.frame).or_default().push(p);
        }
    }
    let measured: Vec<Vec<(String, usize, Skirt)>> = by_frame
        .into_par_iter()
        .map(|(k, points)| {
            frames.with_signal(k, background, workers, |signal, width, height| {
                let at: Vec<[f64; 2]> = points.iter().map(|p| [p.x, p.y]).collect();
                let mut s = skirts(signal, width, height, &at, radius, background.noise_sigma);
                // Hollow about the point (a ring): where its rim is centred.
                let reach = rim_reach(radius);
                for (i, skirt) in s.iter_mut().enumerate() {
                    let Some(skirt) = skirt.as_mut() else {
                        continue;
                    };
                    skirt.point_error = points[i].ep;
                    if skirt.inner >= HOLLOW {
                        continue;
                    }
                    let p = at[i];
                    let others: Vec<[f64; 2]> = at
                        .iter()
                        .enumerate()
                        .filter(|&(j, q)| {
                            j != i && (q[0] - p[0]).abs().max((q[1] - p[1]).abs()) < 2.0 * reach
                        })
                        .map(|(_, q)| *q)
                        .collect();
                    skirt.rim = rim_centre(signal, width, height, p, &others, reach, background.noise_sigma);
                }
                points
                    .iter()
                    .zip(s)
                    .filter_map(|(p, s)| s.map(|s| (p.particle.clone(), k, s)))
                    .collect()
            })
        })
        .collect::<Result<_, TrackError>>()?;
    let mut out: BTreeMap<String, Vec<(usize, Skirt)>> = BTreeMap::new();
    for (particle, k, s) in measured.into_iter().flatten() {
        out.entry(particle).or_default().push((k, s));
    }
    Ok(out)
}

/// The fraction of the ring round each detected point of `table` at the clip level
/// ([`clipped_ring`], for particles of radius `radius` px) in every sample frame of the
/// window that clips anywhere, by particle: frame and fraction each. The skirts are
/// measured in a few of the samples, and the light may saturate in others only (fresh style
/// 6171: dark Gaussian spots of 16.6 px under an exposure drift, the light saturating round
/// them in frames 10 and 11 alone, 6-10 % of each ring; their positions there 0.5 px off,
/// 1.3 times the tolerance, and no warning, since the skirts were measured in frames 0, 3,
/// 6, 9, 12 and 15).
pub(super) fn sample_clipping(
    table: &TrackTable,
    frames: &WindowFrames<'_>,
    radius: f64,
) -> BTreeMap<String, Vec<(usize, f64)>> {
    let first = frames.numbers.first().copied().unwrap_or(0);
    // Each sample frame's detected points, by frame and place among the samples.
    let mut by_frame: BTreeMap<(usize, usize), Vec<&TrackPoint>> = BTreeMap::new();
    for p in &table.points {
        let sample = p
            .frame
            .checked_sub(first)
            .and_then(|i| frames.sample_of.get(i).copied().flatten());
        if let (Some(j), PointFlag::Detected) = (sample, p.flag) {
            by_frame.entry((p.frame, j)).or_default().push(p);
        }
    }
    let measured: Vec<Vec<(String, usize, f64)>> = by_frame
        .into_par_iter()
        .map(|((k, j), points)| {
            let frame = frames.samples[j].view();
            if !frame.any_clipped() {
                return Vec::new();
            }
            points
                .iter()
                .map(|p| (p.particle.clone(), k, clipped_ring(&frame, [p.x, p.y], radius)))
                .collect()
        })
        .collect();
    let mut out: BTreeMap<String, Vec<(usize, f64)>> = BTreeMap::new();
    for (particle, k, c) in measured.into_iter().flatten() {
        out.entry(particle).or_default().push((k, c));
    }
    out
}

/// The particles' signal, grey levels: the median over the particles of `frame` (those
/// nearest `starts` when given) of the largest signal within a radius of each; `None` when no
/// particle is found.
pub(super) fn particle_contrast(
    background: &Background,
    frame: FrameView<'_>,
    sizes: &Sizes,
    starts: Option<&[[f64; 2]]>,
    workers: &Workers,
) -> Option<f32> {
    let (width, height) = frame.size();
    let mut peaks: Vec<f64> = workers.with(|w| {
        let found = w.finder.locate(
            background,
            frame,
            &sizes.params,
            locate_window(sizes.radius),
            Parts::Join,
            None,
        );
        let particles: Vec<&Detection> = match starts {
            Some(starts) => nearest_each(&found, starts, |d| [d.x, d.y]),
            None => found.iter().collect(),
        };
        let r = sizes.radius;
        particles
            .iter()
            .map(|d| {
                let (x0, x1) = (
                    (d.x - r).floor().max(0.0) as usize,
                    ((d.x + r).ceil() as usize).min(width - 1),
                );
                let (y0, y1) = (
                    (d.y - r).floor().max(0.0) as usize,
                    ((d.y + r).ceil() as usize).min(height - 1),
                );
                (y0..=y1)
                    .flat_map(|y| (x0..=x1).map(move |x| (x, y)))
                    .filter(|&(x, y)| (x as f64 - d.x).hypot(y as f64 - d.y) <= r)
                    .map(|(x, y)| f64::from(w.finder.signal[y * width + x]))
                    .fold(f64::NEG_INFINITY, f64::max)
            })
            .filter(|v| v.is_finite())
            .collect()
    });
    (!peaks.is_empty()).then(|| median(&mut peaks) as f32)
}

/// Every blob of one estimation frame at `radius`, with no size rejection, located in the
/// gain-corrected signal.
pub(super) fn locate_unfiltered(
    background: &Background,
    frame: FrameView<'_>,
    radius: f64,
    finder: &mut Finder,
) -> Vec<Detection> {
    finder.locate(
        background,
        frame,
        &unfiltered(background, radius),
        locate_window(radius),
        Parts::Keep,
        None,
    )
}

/// Detection at `radius` with no size rejection.
pub(super) fn unfiltered(background: &Background, radius: f64) -> DetectParameters {
    DetectParameters {
        radius,
        noise_sigma: background.noise_sigma,
        expected: None,
    }
}
