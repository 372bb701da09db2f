//! The background re-estimated without the particles, and the structure that stays.

use super::estimate::DECISION_PIXELS;
use super::median::median_of;
use super::model::{Background, BackgroundModel, SampleExposure, CLEAR_SAMPLES};
use crate::frames::FrameView;
use crate::point_grid::PointGrid;
use kiddo::{ImmutableKdTree, SquaredEuclidean};
use rayon::prelude::*;

impl Background {
    /// Re-estimates a per-pixel background without the particles: each pixel's median is
    /// taken over the sample frames in which no particle (`particles[j]`: positions found in
    /// `samples[j]`, px) lies within `reach` px of it, or, where fewer than
    /// [`CLEAR_SAMPLES`] such frames exist (a particle orbiting one spot), over the
    /// [`CLEAR_SAMPLES`] frames whose nearest particle is farthest from it. Particles that
    /// hover cover the same pixels in many frames and leave part of themselves in a plain
    /// median (17 grey levels of a 120-level spot in the gaussian-blobs fixture), which then
    /// biases every centroid near there. A constant background is left as it is.
    ///
    /// Pixels within `reach` of a `named` particle's start (px) that no sample shows clear of
    /// a particle are the particle's own (a large ball that barely moves covers them in every
    /// frame): they are filled from the clear pixels around them
    /// (`inpaint::fill_from_surroundings`). Elsewhere such pixels keep the median of the
    /// farthest samples: unnamed, a speck always found may be the scene's own texture.
    ///
    /// Where the background is an even surface lit unevenly (it has a [`Light`]), the light
    /// is read again on the pixels clear of every particle's `reach` in every sample when
    /// they are half the frame, or else on those clear of the named particles' `light_reach`
    /// (px: how far their own light reaches) when that is nearer and those are, and that
    /// surface is the background wherever a particle came.
    ///
    /// With [`SampleExposure::Matched`] each sample is first divided by its
    /// [`Background::frame_gain`] against this background.
    pub fn exclude_particles(
        &mut self,
        samples: &[FrameView<'_>],
        particles: &[Vec<[f64; 2]>],
        named: &[[f64; 2]],
        reach: f64,
        light_reach: f64,
        exposure: SampleExposure,
    ) {
        if self.model != BackgroundModel::PerPixel
            || samples.len() != particles.len()
            || samples.len() < CLEAR_SAMPLES
            || reach.is_nan()
            || reach <= 0.0
        {
            return;
        }
        let (w, h, c) = (self.width, self.height, self.channels);
        // Pixels some particle came within `reach` of, in any sample: only these change.
        let near_any = near_any_particle(particles, reach, w, h);
        // Over an even surface lit unevenly the background is the light's surface wherever a
        // particle came: read again on the pixels none came near where they are half the
        // frame at least (the first reading, on the whole median, bends towards what
        // hovering particles left in it: a Gaussian spot of 13 px under a gradient, fresh
        // style 6226, was followed 0.32 / 0.38 px off), or kept where they are fewer or do
        // not show it (a cubic fitted on the corners a ball of 38 px leaves clear, sweep
        // style 1018, bent across the middle by 10 grey levels: 0.75 px off).
        if self.light.is_some() {
            let clear = near_any.iter().filter(|&&n| !n).count();
            // Where the blobs' `reach` leaves less than half the frame (a large particle,
            // specks of noise or texture found at its scale), the particles' own light may
            // still leave half: the named particles' blobs (those within `reach` of a start),
            // or every blob without names, out to `light_reach` where that is nearer. The
            // first reading bends with a large ball that hovers (a shaded sphere of 39 px under
            // vignetting, fresh style 6653: clear of every blob's 2R + 1 stood 23 % of the
            // frame; against the first reading the sphere read 26 px and was followed 8 px
            // off, read clear of its own R + 1 (60 %), 0.36 / 1.45 px, its shaded centroid
            // 0.68 / 1.45 px off its centre). A smooth spot's light reaches `reach` itself,
            // and read clear of the named spot alone the light bent with its skirt (fresh
            // style 6054, a Gaussian spot of 30 px: 0.49 / 0.70 px -> 0.60 / 0.87).
            let light = if 2 * clear >= near_any.len() {
                self.read_light(Some(&near_any))
            } else if light_reach >= reach {
                None
            } else {
                // Every track's points are named where the tracks are taken out: a grid, not a
                // scan of all of them for each blob (nor kiddo's tree, wrong for a few points:
                // see `point_grid`).
                let starts = PointGrid::new(named);
                let theirs = |p: &[f64; 2]| {
                    let mut near = named.is_empty();
                    starts.within(p, reach, |_, _| near = true);
                    near
                };
                let own: Vec<Vec<[f64; 2]>> = particles
                    .iter()
                    .map(|found| found.iter().filter(|p| theirs(p)).copied().collect())
                    .collect();
                let near_light = near_any_particle(&own, light_reach, w, h);
                let clear = near_light.iter().filter(|&&n| !n).count();
                (2 * clear >= near_light.len())
                    .then(|| self.read_light(Some(&near_light)))
                    .flatten()
            };
            if light.is_some() {
                self.light = light;
            }
            if let Some(light) = &self.light {
                for (i, _) in near_any.iter().enumerate().filter(|(_, &n)| n) {
                    self.image[i * c..(i + 1) * c].copy_from_slice(&light.surface[i * c..(i + 1) * c]);
                }
            }
            // As after a fill below: the colour and the noise are measured again.
            self.measure_signal(samples);
            self.measure_levels(samples);
            return;
        }
        let trees: Vec<Option<ImmutableKdTree<f64, 2>>> = particles
            .iter()
            .map(|p| (!p.is_empty()).then(|| ImmutableKdTree::<f64, 2>::new_from_slice(p)))
            .collect();
        // Distance from a pixel to the nearest particle of each sample, px (infinite: none).
        let nearest = |tree: &Option<ImmutableKdTree<f64, 2>>, x: f64, y: f64| {
            tree.as_ref().map_or(f64::INFINITY, |t| {
                t.nearest_one::<SquaredEuclidean>(&[x, y]).distance.sqrt()
            })
        };
        let (clip_offset, direction) = (self.clip_offset, self.direction.clone());
        // Each sample on this background's exposure, if asked: a median over a few clear
        // samples would otherwise carry their exposure, unlike its neighbours' over others.
        let gains: Vec<f32> = samples
            .iter()
            .map(|&f| match exposure {
                SampleExposure::Matched => self.frame_gain(f) as f32,
                SampleExposure::AsRecorded => 1.0,
            })
            .collect();
        let near_named = near_any_particle(&[named.to_vec()], reach, w, h);
        // Pixels near a named start that no sample shows clear, by row.
        let covered: Vec<Vec<usize>> = self
            .image
            .par_chunks_mut(c * w)
            .zip(near_any.par_chunks(w))
            .enumerate()
            .map(|(y, (row, near_row))| {
                let mut covered = Vec::new();
                let mut order: Vec<(f64, usize)> = Vec::with_capacity(samples.len());
                let mut buf: Vec<f32> = Vec::with_capacity(samples.len());
                for (x, px) in row.chunks_exact_mut(c).enumerate().filter(|(x, _)| near_row[*x]) {
                    let pixel = y * w + x;
                    order.clear();
                    order.extend(
                        trees
                            .iter()
                            .enumerate()
                            .map(|(s, t)| (nearest(t, x as f64, y as f64), s)),
                    );
                    // The clear samples, or the farthest few when too few are clear.
                    if order.iter().filter(|o| o.0 > reach).count() < CLEAR_SAMPLES {
                        if near_named[pixel] {
                            covered.push(pixel);
                        }
                        order.sort_by(|a, b| b.0.total_cmp(&a.0));
                        order.truncate(CLEAR_SAMPLES);
                    } else {
                        order.retain(|o| o.0 > reach);
                    }
                    for (ch, v) in px.iter_mut().enumerate() {
                        buf.clear();
                        buf.extend(
                            order
                                .iter()
                                .map(|&(_, s)| samples[s].value(pixel * c + ch) / gains[s]),
                        );
                        *v = median_of(&mut buf) + clip_offset as f32 * direction[ch];
                    }
                }
                covered
            })
            .collect();
        let mut unknown = vec![false; w * h];
        for &i in covered.iter().flatten() {
            unknown[i] = true;
        }
        if covered.iter().any(|c| !c.is_empty()) {
            crate::inpaint::fill_from_surroundings(&mut self.image, w, h, c, &unknown, self.noise_sigma);
            // A particle in the median made its colour ambiguous (dark where it arrives,
            // light where it left) and the noise look larger: both are measured again.
            self.measure_signal(samples);
        }
        self.measure_levels(samples);
    }

    /// The fraction of the frame's pixels whose structure (a per-pixel median farther from
    /// the constant level than [`Background::structure_threshold`]) stays when the samples
    /// holding a particle near the pixel are left out: at each structured pixel, the median
    /// over the samples in which no particle (`particles[j]`: positions found in
    /// `samples[j]`, px) lies within `reach` px must still be structure (against a
    /// threshold grown for the fewer samples). Particles that hover over a few samples leave
    /// themselves in the median, which the automatic choice can take for a static scene;
    /// there the pixel shows the level whenever the particle is away. Structure under a
    /// speck that is always found (texture) has no clear sample and is not counted. 0 for
    /// the constant model.
    #[must_use]
    pub fn static_structure_fraction(
        &self,
        samples: &[FrameView<'_>],
        particles: &[Vec<[f64; 2]>],
        reach: f64,
    ) -> f64 {
        if self.model != BackgroundModel::PerPixel || samples.len() != particles.len() || samples.is_empty() {
            return 0.0;
        }
        let (w, h, c) = (self.width, self.height, self.channels);
        let near: Vec<Vec<bool>> = particles
            .iter()
            .map(|p| near_any_particle(std::slice::from_ref(p), reach, w, h))
            .collect();
        let k = samples.len() as f32;
        let tau = self.structure_threshold;
        let stride = ((w * h) / DECISION_PIXELS).max(1) | 1;
        let mut looked = 0usize;
        let mut stays = 0usize;
        let mut buf: Vec<f32> = Vec::with_capacity(samples.len());
        for i in (0..w * h).step_by(stride) {
            looked += 1;
            let px = &self.image[i * c..(i + 1) * c];
            if !px.iter().zip(&self.level).any(|(v, l)| (v - l).abs() > tau) {
                continue;
            }
            let clear: Vec<usize> = (0..samples.len()).filter(|&j| !near[j][i]).collect();
            if clear.is_empty() {
                continue;
            }
            let t = tau * (k / clear.len() as f32).sqrt();
            let structured = (0..c).any(|ch| {
                buf.clear();
                buf.extend(clear.iter().map(|&j| samples[j].value(i * c + ch)));
                (median_of(&mut buf) - self.level[ch]).abs() > t
            });
            stays += usize::from(structured);
        }
        stays as f64 / looked.max(1) as f64
    }
}
/// Marks the pixels (of a `width` x `height` frame) within `reach` px of some particle of
/// some sample (`particles[j]`: positions in sample `j`, px).
fn near_any_particle(particles: &[Vec<[f64; 2]>], reach: f64, width: usize, height: usize) -> Vec<bool> {
    let mut near = vec![false; width * height];
    let span = |v: f64, len: usize| {
        let lo = (v - reach).floor().max(0.0) as usize;
        let hi = ((v + reach).ceil().max(0.0) as usize).min(len.saturating_sub(1));
        lo..=hi
    };
    for p in particles.iter().flatten() {
        for y in span(p[1], height) {
            for x in span(p[0], width) {
                near[y * width + x] |= (x as f64 - p[0]).hypot(y as f64 - p[1]) <= reach;
            }
        }
    }
    near
}
