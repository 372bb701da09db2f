//! Particle sizes found in the samples, grouped into classes of one size each.

use super::finder::{locate_window, Workers};
use super::radius::{
    estimate_radius, expected_size, first_frame_scan, scale_of_each, Estimation, RADIUS_SAMPLES,
};
use crate::scale::{self, ScaleBlob};
use crate::{Background, DetectParameters, FrameView};
use physfit_tracks::stats::median;

/// The particle size the detector works with, measured on the sample frames.
pub(super) struct Sizes {
    /// Particle radius, px.
    pub(super) radius: f64,
    /// Whether `radius` was measured (not given).
    pub(super) radius_estimated: bool,
    /// Whether `radius` is the half-maximum radius of smooth spots wider than the window
    /// the radius of gyration gave (`radius::widen_to_half_maximum`): their window `R + 1`
    /// is then near the noise-optimal one, and is not widened to their skirt.
    pub(super) smooth: bool,
    /// Detection parameters at that radius, with the expected blob sizes.
    pub(super) params: DetectParameters,
}

impl Sizes {
    /// Radius (unless `given`) and expected blob sizes, from the first [`RADIUS_SAMPLES`]
    /// sample frames against `background`; measured on the blobs nearest `starts` when
    /// named particles are given.
    pub(super) fn measure(
        background: &Background,
        samples: &[FrameView<'_>],
        given: Option<f64>,
        starts: Option<&[[f64; 2]]>,
        scale: Option<f64>,
        workers: &Workers,
    ) -> Sizes {
        let estimation = Estimation {
            background,
            workers,
            frames: &samples[..samples.len().min(RADIUS_SAMPLES)],
        };
        let (radius, radius_estimated, smooth) = match given {
            Some(r) => (r, false, false),
            None => {
                let (r, smooth) = estimate_radius(&estimation, starts, scale);
                (r, true, smooth)
            }
        };
        let expected = expected_size(&estimation, radius, starts);
        Sizes {
            radius,
            radius_estimated,
            smooth,
            params: DetectParameters {
                radius,
                noise_sigma: background.noise_sigma,
                expected,
            },
        }
    }
}

/// Ratio of two size classes' measured radii below which they are one size after all (the
/// scale space split them; the measured radii are within a blurred edge of each other).
/// Faint beads of one radius (2 px, 3 noise deviations high) were split by the noise of their
/// scales into classes measured 1.30 and 1.38 apart, each linked alone, and a track of one
/// took a bead of the other 55 px away; sizes 2.5 times apart blurred by 2.5-3 px measure
/// 1.32-1.46 apart and are followed as well at one size (0.084 against 0.079 px RMS, 0.071
/// against 0.072), and unblurred ones 2.4 apart and more.
const SAME_SIZE: f64 = 1.5;

/// Particles of one size and the detector's sizes for them. Named particles whose scales
/// lie far apart (a ball 2.5 times its neighbour's size) are each found, located and linked
/// at their own size: at one radius the larger is found as parts, or the smaller drowns in
/// the noise of a window fit for the larger.
pub(super) struct SizeClass {
    /// The named particles of this size (indices into the named starts, in order); `None`:
    /// every particle (one size, named or not).
    pub(super) members: Option<Vec<usize>>,
    pub(super) sizes: Sizes,
}

impl SizeClass {
    /// The size classes of a recording: one, unless named particles' scales in the first
    /// estimation frame fall into groups far apart ([`scale::size_groups`]), each then measured
    /// on its own particles; classes whose measured radii come out within [`SAME_SIZE`] of
    /// each other are measured again as one. A `given` radius makes one class.
    ///
    /// `scan` is [`first_frame_scan`] against `background`, when already made.
    pub(super) fn measure_all(
        background: &Background,
        samples: &[FrameView<'_>],
        given: Option<f64>,
        starts: Option<&[[f64; 2]]>,
        scan: Option<&[ScaleBlob]>,
        workers: &Workers,
    ) -> Vec<SizeClass> {
        let one = |scale: Option<f64>| {
            vec![SizeClass {
                members: None,
                sizes: Sizes::measure(background, samples, given, starts, scale, workers),
            }]
        };
        let Some(starts) = starts.filter(|_| given.is_none()) else {
            return one(None);
        };
        let scales = match scan {
            Some(all) => scale_of_each(all, starts),
            None => scale_of_each(&first_frame_scan(background, samples, workers), starts),
        };
        let groups = scale::size_groups(&scales);
        let group_scale = |g: &[usize]| -> Option<f64> {
            let mut r: Vec<f64> = g.iter().filter_map(|&i| scales[i]).collect();
            (!r.is_empty()).then(|| median(&mut r))
        };
        if groups.len() < 2 {
            return one(group_scale(&groups[0]));
        }
        let mut classes: Vec<SizeClass> = groups
            .iter()
            .map(|g| {
                let own: Vec<[f64; 2]> = g.iter().map(|&i| starts[i]).collect();
                SizeClass {
                    members: Some(g.clone()),
                    sizes: Sizes::measure(background, samples, None, Some(&own), group_scale(g), workers),
                }
            })
            .collect();
        classes.sort_by(|a, b| a.sizes.radius.total_cmp(&b.sizes.radius));
        let apart = classes
            .windows(2)
            .all(|w| w[1].sizes.radius > SAME_SIZE * w[0].sizes.radius);
        if apart {
            classes
        } else {
            one(None)
        }
    }

    /// This class's entries of `all` (one per named particle, in order).
    pub(super) fn starts<T: Clone>(&self, all: &[T]) -> Vec<T> {
        match &self.members {
            None => all.to_vec(),
            Some(m) => m.iter().map(|&i| all[i].clone()).collect(),
        }
    }

    /// Centroid window radius for this class, px ([`locate_window`]).
    pub(super) fn window(&self) -> f64 {
        locate_window(self.sizes.radius)
    }

    /// The farthest this class's windows reach when located with the local background
    /// taken out ([`super::plane::most_reach`]), px: the window itself for smooth spots
    /// ([`Sizes::smooth`]). A Gaussian spot's skirt stands above the noise to twice its
    /// half-maximum radius, and a window that far takes in the light's tilt across it:
    /// sweep style 1030 (a spot of 46 px under a gradient and vignetting) went from 0.15 /
    /// 0.40 px to 0.17 / 0.47 px (its tolerance 0.23 / 0.46) with windows of 86-90 px.
    pub(super) fn plane_reach(&self) -> f64 {
        if self.sizes.smooth {
            self.window()
        } else {
            super::plane::most_reach(&self.sizes.params, self.window())
        }
    }
}
pub(super) fn largest_radius(classes: &[SizeClass]) -> f64 {
    classes.iter().map(|c| c.sizes.radius).fold(0.0, f64::max)
}

/// How far tracked particles are taken out of a per-pixel median, px: twice the radius and a
/// pixel (where a disc or a blurred spot has left less than a grey level), or the radius of
/// a blob's area above the noise mask and a pixel where that is farther (a smooth spot's
/// skirt), the largest over the classes. Two Gaussian spots of 12 px half-maximum radius
/// under vignetting and no noise (profile neighbour 4006) left their skirts in the median
/// beyond `2R + 1` and were followed 0.35 / 0.49 px off with errors of 0.002 px; now 0.08 /
/// 0.04. The sample frames' own exclusion, of every blob found, keeps `2R + 1`: with this
/// reach there, five textured balls of 7 px under a gradient (sweep style 1003) were refused.
pub(super) fn exclusion_reach(classes: &[SizeClass]) -> f64 {
    reach_over(classes, |_| 2.0)
}

/// How far tracked particles' own light reaches, px: the radius and a pixel for particles
/// sized at their edge (a disc, a ball, a ring), twice the radius and a pixel for smooth spots
/// sized at their half maximum (a Gaussian's light stands at a sixteenth of its peak there),
/// or the skirt as in [`exclusion_reach`] where farther; where the light falling on the scene
/// is read again, the pixels beyond it are clear of them.
pub(super) fn light_reach(classes: &[SizeClass]) -> f64 {
    reach_over(classes, |sizes| if sizes.smooth { 2.0 } else { 1.0 })
}

/// The largest over the classes of `radii` (of a class's sizes) radii or the skirt's radius,
/// and a pixel, px.
fn reach_over(classes: &[SizeClass], radii: impl Fn(&Sizes) -> f64) -> f64 {
    classes
        .iter()
        .map(|c| {
            let skirt = c
                .sizes
                .params
                .expected
                .map_or(0.0, |e| (e.extent / std::f64::consts::PI).sqrt());
            (radii(&c.sizes) * c.sizes.radius).max(skirt) + 1.0
        })
        .fold(0.0, f64::max)
}
