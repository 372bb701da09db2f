//! The background model and the particle signal.
//!
//! A static camera sees a background that does not move and particles that do. The
//! background is estimated from a sample of frames as the per-pixel median over time
//! (moving particles cover a pixel in fewer than half of the frames, so the median is
//! the background there). When that median image is flat apart from a few compact spots
//! (rendered frames, or a particle that never moves), a single constant level per channel
//! is used instead, so that particles which stay put are not swallowed by the background
//! and the background adds no noise of its own. The choice is automatic.
//!
//! Particles may be brighter or darker than the background, or of another colour. The
//! *signal* of a pixel is the projection of its difference from the background onto the
//! particles' colour direction `u` (a unit vector over the channels), measured from the
//! pixels that differ most from the background: `s = u · (I − B)`. For grey frames `u` is
//! `+1` (bright on dark) or `−1` (dark on light). Particles have positive signal; the
//! background has signal 0 plus noise, whose standard deviation is measured from the
//! negative half of the signal distribution (particles contribute almost nothing there).

use kiddo::{ImmutableKdTree, SquaredEuclidean};
use rayon::prelude::*;

use crate::blind::BlindPixels;
use crate::cpu::with_avx2;
use crate::frames::{Frame, FrameView};

/// Which background model a recording uses.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BackgroundModel {
    /// One level per channel for the whole frame.
    Constant,
    /// The per-pixel median over time.
    PerPixel,
}

/// How the background model is chosen.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum BackgroundChoice {
    /// Constant if the median image is flat apart from compact spots, or its structure
    /// covers no more than twice the part of a frame that moves; else per-pixel.
    #[default]
    Auto,
    /// Always a constant level.
    Constant,
    /// Always the per-pixel median over time.
    PerPixel,
}

/// The estimated background of a recording and how particle signal is measured against it.
#[derive(Clone, Debug, PartialEq)]
pub struct Background {
    /// The model in use.
    pub model: BackgroundModel,
    /// Frame width, px.
    pub width: usize,
    /// Frame height, px.
    pub height: usize,
    /// Samples per pixel (1 or 3).
    pub channels: usize,
    /// Constant background level per channel, grey levels.
    pub level: Vec<f32>,
    /// Per-pixel background (`width * height * channels`, grey levels); the constant level
    /// everywhere for [`BackgroundModel::Constant`].
    pub image: Vec<f32>,
    /// Unit colour direction of particles against the background (one entry per channel);
    /// signal = direction · (pixel − background).
    pub direction: Vec<f32>,
    /// Standard deviation of the signal over background pixels, grey levels (≥ 0.3, the
    /// quantisation noise of 8-bit levels).
    pub noise_sigma: f64,
    /// Fraction of pixels where the per-pixel median differs from the constant level by
    /// more than its noise allows (what the automatic choice looked at).
    pub structured_fraction: f64,
    /// Frames the estimate was made from.
    pub sample_count: usize,
    /// The samples' mean [`Background::frame_gain`]: what a frame's own gain is compared
    /// with (about 1).
    pub reference_gain: f64,
    /// The brightest background value, grey levels: the scale against which a change of
    /// gain is judged significant (see [`Background::remove_gain`]).
    pub brightest: f64,
    /// Pixel noise measured from differences of consecutive samples, grey levels (sets the
    /// threshold of the colour direction).
    pub temporal_noise: f64,
    /// Mean of the clipped noise added to the background (along `direction`) where most of
    /// the background's noise is clipped at black or white, grey levels; 0 otherwise.
    pub clip_offset: f64,
    /// How far a pixel's per-pixel median must be from the constant level to count as
    /// structure (four standard errors of a median over the samples, at least 3), grey
    /// levels.
    pub structure_threshold: f32,
    /// Pixels where the background is as bright as a particle along its colour direction, so
    /// that a particle cannot show there, and how their signal is filled in (see
    /// [`Background::find_blind`]); none until then.
    pub blind: BlindPixels,
}

/// Quantisation noise of 8-bit levels (1/sqrt(12)), the smallest noise ever assumed.
const MIN_NOISE: f64 = 0.3;

/// Half-width, in standard deviations, of the band kept when the noise of a clipped
/// background is measured by iterated clipping.
const CLIP_SIGMAS: f64 = 5.0;

/// How [`Background::exclude_particles`] takes the samples' levels.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SampleExposure {
    /// As the frames hold them.
    AsRecorded,
    /// Each divided by its gain against the background, so that a median over a few clear
    /// samples does not carry their exposure, unlike its neighbours' over others. Only where
    /// the particles are known in every sample (from tracks): against a median that still
    /// holds particles the gains are off, and matching on them turned two refused styles of
    /// the sweep (1031, 1033) into tracks 1-18 px wrong without a word.
    Matched,
}

/// Least sample frames a background pixel's median is taken over once particles are
/// excluded ([`Background::exclude_particles`]).
pub const CLEAR_SAMPLES: usize = 3;

/// Fraction of structured pixels above which the per-pixel model is chosen.
pub(crate) const STRUCTURED_LIMIT: f64 = 0.02;

/// Pixels a frame's gain is measured on (an even sample): the median ratio is then known to
/// about 1.4 % of the pixel-to-pixel spread of the ratios, a tenth of a grey level on a
/// background of 150 under noise 5.
const GAIN_SAMPLES: usize = 8_192;

/// Pixels the background model is chosen on (an even sample of the frame): the fractions of
/// structured and moving pixels are then known to about 0.4 % of the frame (0.1 % near the
/// 2 % of [`STRUCTURED_LIMIT`]). Samples are far apart in 25 frames of a megabyte each, so
/// each costs a cache miss: four times as many took 9 ms more of a 200-frame recording.
const DECISION_PIXELS: usize = 16_384;

/// Pixel values (over all samples) the noise estimates are taken from: the median of this
/// many is within about 0.3 % of the population's (each costs a cache miss, as above).
const NOISE_SAMPLES: usize = 125_000;

/// Estimates the background of a recording from sample frames (all the same size and
/// channel count; at least one). See the module documentation for the method.
pub fn estimate_background(samples: &[FrameView<'_>], choice: BackgroundChoice) -> Background {
    let first = &samples[0];
    let ((width, height), channels) = (first.size(), first.channels());
    let k = samples.len();
    // The model is chosen on the per-pixel median of an even sample of the pixels (every
    // `pixel_stride`-th, odd so that it walks across the columns); the whole median image is
    // only needed when the per-pixel model is chosen.
    let pixels = width * height;
    let pixel_stride = (pixels / DECISION_PIXELS).max(1) | 1;
    let picked: Vec<usize> = (0..pixels).step_by(pixel_stride).collect();
    let median = median_at(samples, &picked);

    // Temporal noise from differences of consecutive samples: where nothing moves the
    // difference of two frames has sigma * sqrt(2), whatever the number of samples. (The
    // spread about the per-pixel median is biased low for few samples: with an odd count one
    // sample *is* the median at every pixel, so a third of three samples' deviations are 0.)
    let sigma_t = if k >= 2 {
        let n = first.len();
        let stride = ((k - 1) * n / NOISE_SAMPLES).max(1) | 1;
        let mut dev: Vec<f32> = Vec::with_capacity((k - 1) * n / stride + 1);
        for pair in samples.windows(2) {
            dev.extend(
                (0..n)
                    .step_by(stride)
                    .map(|i| (pair[0].value(i) - pair[1].value(i)).abs()),
            );
        }
        quantile(&mut dev, 0.5) as f64 * 1.4826 / std::f64::consts::SQRT_2
    } else {
        0.0
    }
    .max(MIN_NOISE);

    let level: Vec<f32> = (0..channels).map(|c| mode_level(&median, channels, c)).collect();
    let sigma_median = 1.2533 * sigma_t / (k as f64).sqrt();
    let tau = (4.0 * sigma_median).max(3.0) as f32;
    let structured = median
        .chunks_exact(channels)
        .filter(|px| px.iter().zip(&level).any(|(v, l)| (v - l).abs() > tau))
        .count();
    let structured_fraction = structured as f64 / picked.len().max(1) as f64;
    // The fraction of each frame that moving things cover: pixels far from the median.
    // Particles that hover (a random walk, a slow drift) leave part of themselves in the
    // median image; such structure covers no more of the frame than the particles do,
    // while a scene's static background (a wall, a shelf, a gradient) covers far more.
    let tau_frame = (5.0 * sigma_t).max(3.0) as f32;
    let moving: usize = samples
        .iter()
        .map(|f| {
            picked
                .iter()
                .zip(median.chunks_exact(channels))
                .filter(|(&i, m)| {
                    let p = f.pixel(i);
                    p.iter().zip(*m).any(|(a, b)| (a - b).abs() > tau_frame)
                })
                .count()
        })
        .sum();
    let moving_fraction = moving as f64 / (k * picked.len()).max(1) as f64;
    let model = match choice {
        BackgroundChoice::Constant => BackgroundModel::Constant,
        BackgroundChoice::PerPixel if k >= 2 => BackgroundModel::PerPixel,
        BackgroundChoice::PerPixel => BackgroundModel::Constant,
        BackgroundChoice::Auto
            if k >= 3
                && structured_fraction > STRUCTURED_LIMIT
                && structured_fraction > 2.0 * moving_fraction =>
        {
            BackgroundModel::PerPixel
        }
        BackgroundChoice::Auto => BackgroundModel::Constant,
    };
    let image = match model {
        BackgroundModel::PerPixel if pixel_stride == 1 => median,
        BackgroundModel::PerPixel => median_image(samples),
        BackgroundModel::Constant => Frame::filled(width, height, &level).data,
    };
    let mut bg = Background {
        model,
        width,
        height,
        channels,
        level,
        image,
        direction: vec![1.0; channels],
        noise_sigma: sigma_t,
        temporal_noise: sigma_t,
        structured_fraction,
        sample_count: k,
        reference_gain: 1.0,
        brightest: 0.0,
        clip_offset: 0.0,
        structure_threshold: tau,
        blind: BlindPixels::default(),
    };
    bg.measure_signal(samples);
    bg.reference_gain = samples.iter().map(|&f| bg.frame_gain(f)).sum::<f64>() / k as f64;
    bg.brightest = f64::from(bg.image.iter().fold(0.0f32, |m, &v| m.max(v)));
    bg
}

impl Background {
    /// The particles' colour direction, the signal's noise and the clip offset, measured on
    /// `samples` against the current background image (`sigma_t`: the temporal noise, grey
    /// levels, which sets the colour threshold). A clip offset already added to the image is
    /// taken out first, so this may run again once the image changes
    /// ([`Background::exclude_particles`]).
    fn measure_signal(&mut self, samples: &[FrameView<'_>]) {
        let sigma_t = self.temporal_noise;
        let (width, height, channels) = (self.width, self.height, self.channels);
        if self.clip_offset != 0.0 {
            let offset = self.clip_offset as f32;
            for (l, u) in self.level.iter_mut().zip(&self.direction) {
                *l -= offset * u;
            }
            for px in self.image.chunks_exact_mut(channels) {
                for (b, u) in px.iter_mut().zip(&self.direction) {
                    *b -= offset * u;
                }
            }
            self.clip_offset = 0.0;
        }
        // An even sample of the pixels (every `stride`-th of each frame, an odd stride so that
        // successive frames' samples fall on other columns).
        let stride = (samples.len() * width * height / NOISE_SAMPLES).max(1) | 1;
        self.direction = colour_direction(samples, self, (6.0 * sigma_t).max(3.0) as f32, stride);
        // The lowest signal a pixel can show: its value at the clip level (0 where particles
        // are brighter in a channel, 255 where darker).
        let clip: Vec<f32> = self
            .direction
            .iter()
            .map(|&u| if u >= 0.0 { 0.0 } else { 255.0 })
            .collect();
        let mut negatives: Vec<f32> = Vec::new();
        let mut sampled: Vec<f32> = Vec::new();
        let mut clipped = 0usize;
        // Each sample's own exposure, relative to their mean: a drifting exposure shifts the
        // signal of every background pixel in proportion to its brightness, which is not
        // noise (an exposure drifting by 14 % on a light background read noise 11 as 42).
        let gains: Vec<f64> = samples.iter().map(|&f| self.frame_gain(f)).collect();
        let mean_gain = gains.iter().sum::<f64>() / gains.len().max(1) as f64;
        for (s, f) in samples.iter().enumerate() {
            let shift = (gains[s] / mean_gain - 1.0) as f32;
            // 8-bit frames hold whole levels, so the signal takes values one level apart and
            // the median of its magnitude jumps by whole levels (noise 5 read as 4.45). A
            // deterministic dither spread evenly over one level makes the distribution
            // continuous again: its spread is then that of the quantised noise itself.
            for i in (s % stride..width * height).step_by(stride) {
                let level: f32 = self
                    .pixel(i)
                    .iter()
                    .zip(&self.direction)
                    .map(|(b, u)| u * b)
                    .sum();
                let (v, lo) = (
                    self.signal_at(&f.pixel(i)[..channels], i) - shift * level,
                    self.signal_at(&clip, i),
                );
                let d = v + dither(i);
                if d < 0.0 {
                    negatives.push(-d);
                    clipped += usize::from(v <= lo + 0.5);
                }
                sampled.push(d);
            }
        }
        if 2 * clipped < negatives.len() {
            self.noise_sigma = if negatives.len() >= 16 {
                (quantile(&mut negatives, 0.5) as f64 * 1.4826).max(MIN_NOISE)
            } else {
                MIN_NOISE
            };
        } else {
            // Most of the background's negative half is clipped (a black background under
            // noise): the noise the filters see is that of the clipped distribution, whose mean
            // sits above the level. Both come from the sampled signal by iterated 5-sigma
            // clipping, started from the upper quartile's spread (above the truth when
            // particles crowd the frame, so the clipping converges from above).
            let (offset, sigma) = clipped_mean_and_sigma(&mut sampled);
            self.noise_sigma = sigma.max(MIN_NOISE);
            self.clip_offset = offset;
            for (l, u) in self.level.iter_mut().zip(&self.direction) {
                *l += offset as f32 * u;
            }
            for px in self.image.chunks_exact_mut(channels) {
                for (b, u) in px.iter_mut().zip(&self.direction) {
                    *b += offset as f32 * u;
                }
            }
        }
    }

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
    /// ([`crate::inpaint::harmonic_fill`]). Elsewhere such pixels keep the median of the
    /// farthest samples: unnamed, a speck always found may be the scene's own texture.
    ///
    /// With [`SampleExposure::Matched`] each sample is first divided by its
    /// [`Background::frame_gain`] against this background.
    pub fn exclude_particles(
        &mut self,
        samples: &[FrameView<'_>],
        particles: &[Vec<[f64; 2]>],
        named: &[[f64; 2]],
        reach: f64,
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
            crate::inpaint::harmonic_fill(&mut self.image, w, h, c, &unknown);
            // A particle in the median made its colour ambiguous (dark where it arrives,
            // light where it left) and the noise look larger: both are measured again.
            self.measure_signal(samples);
        }
        self.reference_gain = samples.iter().map(|&f| self.frame_gain(f)).sum::<f64>() / samples.len() as f64;
        self.brightest = f64::from(self.image.iter().fold(0.0f32, |m, &v| m.max(v)));
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

    /// The brightness gain of `frame` against the background image: the median over a
    /// sample of pixels of `pixel / background` (each pixel dithered over one grey level, so
    /// that 8-bit frames do not make the median jump), with pixels darker than 16 levels in
    /// the background left out. Most pixels are background, so this follows a camera's
    /// automatic exposure or a flicker of the light and ignores the particles; 1 when no
    /// pixel qualifies.
    pub fn frame_gain<'a>(&self, frame: impl Into<FrameView<'a>>) -> f64 {
        match frame.into() {
            FrameView::Frame(f) => self.gain_of(&f.data, |v| v),
            FrameView::Grey8 { samples, .. }
                if self.channels == 1 && self.model == BackgroundModel::Constant =>
            {
                self.grey8_gain_on_level(samples)
            }
            FrameView::Grey8 { samples, .. } => self.gain_of(samples, f32::from),
        }
    }

    /// How many of `data`'s values the gain looks at, and how far apart: the values
    /// `0, stride, 2 stride, ...` below the returned length.
    fn gain_sampling(&self, len: usize) -> (usize, usize) {
        let n = len.min(self.image.len());
        (n, (n / GAIN_SAMPLES).max(1) | 1)
    }

    /// [`Background::frame_gain`] of the samples `data`, read as grey levels by `level`.
    fn gain_of<T: Copy>(&self, data: &[T], level: impl Fn(T) -> f32) -> f64 {
        let (n, stride) = self.gain_sampling(data.len());
        let data = &data[..n];
        let c = self.channels;
        let mut ratios: Vec<f32> = Vec::with_capacity(n / stride + 1);
        // Sample `j` is value `j * stride` (a plain loop: the iterator chain cost three times
        // as much, on every frame); a grey value is its pixel's.
        for (j, i) in (0..n.div_ceil(stride)).map(|j| (j, j * stride)) {
            let b = if c == 1 { self.pixel(i)[0] } else { self.image[i] };
            if b >= 16.0 {
                ratios.push((level(data[i]) + dither(j)) / b);
            }
        }
        if ratios.len() < 16 {
            return 1.0;
        }
        f64::from(quantile(&mut ratios, 0.5))
    }

    /// [`Background::frame_gain`] of 8-bit grey samples `data` against a constant grey
    /// level, the same value to the bit, found by counting. Every ratio is a dithered level
    /// over the same background level, and dividing by it keeps their order, so the median
    /// ratio is the median dithered level over the background. A level's dithered values
    /// all lie within half a level of it: a histogram of the levels tells which level holds
    /// the median, and only that level's values are ordered.
    fn grey8_gain_on_level(&self, data: &[u8]) -> f64 {
        let (n, stride) = self.gain_sampling(data.len());
        let count = n.div_ceil(stride);
        let b = self.level[0];
        if b < 16.0 || count < 16 {
            return 1.0;
        }
        let mut histogram = [0usize; 256];
        for &v in data[..n].iter().step_by(stride) {
            histogram[usize::from(v)] += 1;
        }
        // The rank `quantile(.., 0.5)` selects, and the level holding it.
        let rank = ((count - 1) as f64 * 0.5).round() as usize;
        let mut below = 0;
        let mut median_level = 0u8;
        for (level, &c) in (0..=u8::MAX).zip(&histogram) {
            if below + c > rank {
                median_level = level;
                break;
            }
            below += c;
        }
        let mut at_level: Vec<f32> = Vec::with_capacity(histogram[usize::from(median_level)]);
        for (j, &v) in data[..n].iter().step_by(stride).enumerate() {
            if v == median_level {
                at_level.push(f32::from(v) + dither(j));
            }
        }
        let x = *at_level.select_nth_unstable_by(rank - below, f32::total_cmp).1;
        f64::from(x / b)
    }

    /// Turns `signal` (the [`Background::signal`] of `frame`) into the signal against the
    /// background scaled by the frame's [`Background::frame_gain`] relative to the samples'
    /// [`Background::reference_gain`], in place (grey levels). Under a steady light the gain
    /// is 1 within a fraction of the noise; under automatic exposure it removes the offset,
    /// proportional to the background's brightness, that would otherwise add light to every
    /// centroid window in proportion to its area (and make the measured size grow with the
    /// window).
    pub fn remove_gain<'a>(&self, frame: impl Into<FrameView<'a>>, signal: &mut [f32]) {
        if let Some(g) = self.gain_to_remove(frame) {
            self.apply_gain(g, signal);
        }
    }

    /// The gain [`Background::remove_gain`] would remove from `frame`'s signal (its
    /// [`Background::frame_gain`] relative to the samples' [`Background::reference_gain`]),
    /// or `None` when it leaves the signal as it is: a gain whose effect stays below a tenth
    /// of the noise on the brightest background is the estimate's own scatter.
    pub fn gain_to_remove<'a>(&self, frame: impl Into<FrameView<'a>>) -> Option<f64> {
        let g = self.frame_gain(frame) / self.reference_gain;
        (((g - 1.0) * self.brightest).abs() >= 0.1 * self.noise_sigma).then_some(g)
    }

    /// Removes the gain `g` (from [`Background::gain_to_remove`]) from `signal`, in place.
    pub fn apply_gain(&self, g: f64, signal: &mut [f32]) {
        let g = g as f32;
        for (o, b) in signal.iter_mut().zip(self.image.chunks_exact(self.channels)) {
            // signal = u . (p - g b) = u . (p - b) - (g - 1) u . b
            let ub: f32 = b.iter().zip(&self.direction).map(|(b, u)| u * b).sum();
            *o -= (g - 1.0) * ub;
        }
    }

    /// The particle signal of `frame` (see the module doc), grey levels, one value per pixel.
    #[must_use]
    pub fn signal(&self, frame: &Frame) -> Vec<f32> {
        let mut out = Vec::new();
        self.signal_into(frame, &mut out);
        out
    }

    /// [`Background::signal`] into a reused buffer, of a frame or of a file's 8-bit grey
    /// samples (read as their levels, the same signal to the bit), with the blind pixels
    /// filled (see [`Background::find_blind`]). A frame with another
    /// channel count than the background's is converted first (grey repeated into red, green
    /// and blue; colour averaged into grey).
    pub fn signal_into<'a>(&self, frame: impl Into<FrameView<'a>>, out: &mut Vec<f32>) {
        let mut converted = Frame::default();
        let view = self.matching(frame.into(), &mut converted);
        let (width, height) = view.size();
        // Every value is written below: a reused buffer of the right length is not cleared.
        if out.len() != width * height {
            out.clear();
            out.resize(width * height, 0.0);
        }
        self.signal_range(view, 0..width * height, out);
        self.blind.fill(out);
    }

    /// `frame` with the background's channel count: as it is, or converted into `converted`
    /// (grey repeated into red, green and blue; colour averaged into grey) when a grey file
    /// sits among colour ones or the reverse.
    pub fn matching<'a>(&self, frame: FrameView<'a>, converted: &'a mut Frame) -> FrameView<'a> {
        let channels = match frame {
            FrameView::Grey8 { .. } => 1,
            FrameView::Frame(f) => f.channels,
        };
        if channels == self.channels {
            return frame;
        }
        *converted = frame.to_frame().with_channels(self.channels);
        FrameView::Frame(converted)
    }

    /// The particle signal of the pixels `pixels` (row-major indices) of `frame`, into `out`
    /// (as long as the range): [`Background::signal_into`] for part of a frame, the same
    /// values to the bit. `frame` must have the background's channel count
    /// ([`Background::matching`]).
    pub fn signal_range(&self, frame: FrameView<'_>, pixels: std::ops::Range<usize>, out: &mut [f32]) {
        let c = self.channels;
        let image = &self.image[pixels.start * c..pixels.end * c];
        match frame {
            FrameView::Grey8 { samples, .. } => self.grey_signal(&samples[pixels], image, f32::from, out),
            FrameView::Frame(f) if c == 1 => self.grey_signal(&f.data[pixels], image, |v| v, out),
            FrameView::Frame(f) => {
                let data = &f.data[pixels.start * c..pixels.end * c];
                for ((o, p), b) in out
                    .iter_mut()
                    .zip(data.chunks_exact(c))
                    .zip(image.chunks_exact(c))
                {
                    *o = colour_signal(p, b, &self.direction);
                }
            }
        }
    }

    /// [`Background::signal_range`] of grey samples `data` (read as grey levels by `level`)
    /// against the background pixels `image`.
    fn grey_signal<T: Copy>(&self, data: &[T], image: &[f32], level: impl Fn(T) -> f32, out: &mut [f32]) {
        let u = self.direction[0];
        // Every pixel of every frame: compiled for AVX2 where the CPU has it.
        with_avx2(|| match self.model {
            BackgroundModel::Constant => {
                let l = self.level[0];
                for (o, &v) in out.iter_mut().zip(data) {
                    *o = u * (level(v) - l);
                }
            }
            BackgroundModel::PerPixel => {
                for ((o, &v), &b) in out.iter_mut().zip(data).zip(image) {
                    *o = u * (level(v) - b);
                }
            }
        })
    }

    /// The background at pixel `p` (its channels, grey levels). A constant model's level
    /// stands for its image, which holds that level at every pixel to the bit: scattered
    /// samples then read the frames alone, not a frame-sized image as well.
    fn pixel(&self, p: usize) -> &[f32] {
        match self.model {
            BackgroundModel::Constant => &self.level,
            BackgroundModel::PerPixel => &self.image[p * self.channels..(p + 1) * self.channels],
        }
    }

    /// The particle signal of one pixel, `pixel` (its channels' values, grey levels) at
    /// pixel index `i`: the value [`Background::signal_into`] gives there, to the bit.
    pub fn signal_at(&self, pixel: &[f32], i: usize) -> f32 {
        let c = self.channels;
        match (c, self.model) {
            (1, BackgroundModel::Constant) => self.direction[0] * (pixel[0] - self.level[0]),
            (1, BackgroundModel::PerPixel) => self.direction[0] * (pixel[0] - self.image[i]),
            _ => colour_signal(pixel, &self.image[i * c..(i + 1) * c], &self.direction),
        }
    }

    /// Finds the blind pixels of a per-pixel background (see [`crate::BlindPixels`]) for
    /// particles whose signal is `contrast` (grey levels), filled from up to `reach` px away;
    /// a constant background has none.
    pub fn find_blind(&mut self, contrast: f32, reach: usize) {
        self.blind = match self.model {
            BackgroundModel::Constant => BlindPixels::default(),
            BackgroundModel::PerPixel => {
                let c = self.channels;
                let structure: Vec<f32> = self
                    .image
                    .chunks_exact(c)
                    .map(|b| colour_signal(b, &self.level, &self.direction))
                    .collect();
                BlindPixels::find(&structure, self.width, self.height, contrast, reach)
            }
        };
    }

    /// Returns true if and only if particles are darker than the background (grey frames),
    /// or darker on average over the channels (colour frames).
    pub fn is_dark_on_light(&self) -> bool {
        self.direction.iter().sum::<f32>() < 0.0
    }
}

/// The signal of a colour pixel `p` against background `b`: the difference projected on the
/// particles' colour direction `u`, grey levels.
fn colour_signal(p: &[f32], b: &[f32], u: &[f32]) -> f32 {
    p.iter().zip(b).zip(u).map(|((p, b), u)| u * (p - b)).sum::<f32>()
}

/// Mean and standard deviation (grey levels) of the bulk of `values` (reordered) by iterated
/// 5-sigma clipping from the median and the upper quartile's spread. The wide cut keeps the
/// long tail of a clipped (half-normal) noise distribution, whose spread the filters see,
/// while rejecting particle pixels; it shortens a normal distribution's spread by 1e-5.
fn clipped_mean_and_sigma(values: &mut [f32]) -> (f64, f64) {
    if values.len() < 16 {
        return (0.0, MIN_NOISE);
    }
    let mut mean = f64::from(quantile(values, 0.5));
    let mut sigma = ((f64::from(quantile(values, 0.75)) - mean) / 0.6745).max(MIN_NOISE);
    for _ in 0..50 {
        let (lo, hi) = (mean - CLIP_SIGMAS * sigma, mean + CLIP_SIGMAS * sigma);
        let (mut n, mut sum, mut sum2) = (0usize, 0.0f64, 0.0f64);
        for &v in values.iter() {
            let v = f64::from(v);
            if v >= lo && v <= hi {
                n += 1;
                sum += v;
                sum2 += v * v;
            }
        }
        if n < 16 {
            break;
        }
        let m = sum / n as f64;
        let s = ((sum2 / n as f64 - m * m).max(0.0)).sqrt();
        let converged = (s - sigma).abs() <= 1e-3 * sigma && (m - mean).abs() <= 1e-3 * sigma;
        mean = m;
        sigma = s.max(MIN_NOISE);
        if converged {
            break;
        }
    }
    (mean, sigma)
}

/// An offset in `[-0.5, 0.5)` grey levels for sample `i`, evenly spread over that range along
/// any run of consecutive samples (the golden-ratio sequence).
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

/// A deterministic dither over one grey level, `frac(i φ) − ½` (the golden-ratio sequence
/// spreads any run of consecutive indices evenly over the level), in 64-bit fixed point.
fn dither(i: usize) -> f32 {
    /// The fractional part of the golden ratio, `0.618…`, times 2⁶⁴.
    const PHI_FRAC_FIXED: u64 = 0x9E37_79B9_7F4A_7C15;
    let frac = (i as u64).wrapping_mul(PHI_FRAC_FIXED) >> 40;
    frac as f32 * (1.0 / (1u64 << 24) as f32) - 0.5
}

/// The per-pixel median over `samples` of every value of a frame (channel-interleaved).
fn median_image(samples: &[FrameView<'_>]) -> Vec<f32> {
    median_values(samples, samples[0].len(), |v| v)
}

/// The per-pixel median over `samples` at the pixels `picked` (indices into a frame's
/// pixels), channel-interleaved like a frame's data.
fn median_at(samples: &[FrameView<'_>], picked: &[usize]) -> Vec<f32> {
    let c = samples[0].channels();
    median_values(samples, picked.len() * c, |v| picked[v / c] * c + v % c)
}

/// `len` medians over `samples`: value `v` is the median of every sample's `data[index(v)]`.
/// 8-bit grey samples are ordered as bytes (the same median).
fn median_values(samples: &[FrameView<'_>], len: usize, index: impl Fn(usize) -> usize + Sync) -> Vec<f32> {
    const CHUNK: usize = 4096;
    let bytes: Option<Vec<&[u8]>> = samples
        .iter()
        .map(|f| match f {
            FrameView::Grey8 { samples, .. } => Some(*samples),
            FrameView::Frame(_) => None,
        })
        .collect();
    let mut out = vec![0.0f32; len];
    out.par_chunks_mut(CHUNK).enumerate().for_each(|(chunk, dst)| {
        let mut buf = vec![0.0f32; samples.len()];
        let mut byte_buf = vec![0u8; samples.len()];
        for (j, d) in dst.iter_mut().enumerate() {
            let i = index(chunk * CHUNK + j);
            *d = match &bytes {
                Some(bytes) => {
                    for (b, f) in byte_buf.iter_mut().zip(bytes) {
                        *b = f[i];
                    }
                    median_of_bytes(&mut byte_buf)
                }
                None => {
                    for (b, f) in buf.iter_mut().zip(samples) {
                        *b = f.value(i);
                    }
                    median_of(&mut buf)
                }
            };
        }
    });
    out
}

/// [`median_of`] of grey levels held as bytes (reordering them), the same value.
fn median_of_bytes(v: &mut [u8]) -> f32 {
    let n = v.len();
    let (lower, m, _) = v.select_nth_unstable(n / 2);
    let m = f32::from(*m);
    if n % 2 == 1 {
        m
    } else {
        let lo = lower.iter().copied().max().map_or(f32::NEG_INFINITY, f32::from);
        0.5 * (lo + m)
    }
}

fn median_of(v: &mut [f32]) -> f32 {
    let n = v.len();
    let mid = n / 2;
    let (lower, m, _) = v.select_nth_unstable_by(mid, f32::total_cmp);
    let m = *m;
    if n % 2 == 1 {
        m
    } else {
        let lo = lower.iter().copied().fold(f32::NEG_INFINITY, f32::max);
        0.5 * (lo + m)
    }
}

/// The `q` quantile (0..1) of `v`, reordering it; 0 for an empty slice.
pub(crate) fn quantile(v: &mut [f32], q: f64) -> f32 {
    if v.is_empty() {
        return 0.0;
    }
    let i = ((v.len() - 1) as f64 * q).round() as usize;
    *v.select_nth_unstable_by(i, f32::total_cmp).1
}

/// The most common level of channel `c`: the mode of a one-level histogram, refined as the
/// mean of the values within two levels of it.
fn mode_level(image: &[f32], channels: usize, c: usize) -> f32 {
    let mut hist = [0u32; 256];
    for v in image.iter().skip(c).step_by(channels) {
        hist[v.round().clamp(0.0, 255.0) as usize] += 1;
    }
    let (mode, _) = hist
        .iter()
        .enumerate()
        .max_by_key(|(i, &n)| (n, usize::MAX - i))
        .unwrap_or((0, &0));
    let lo = mode as f32 - 2.5;
    let hi = mode as f32 + 2.5;
    let (mut sum, mut count) = (0.0f64, 0usize);
    for &v in image.iter().skip(c).step_by(channels) {
        if v >= lo && v <= hi {
            sum += f64::from(v);
            count += 1;
        }
    }
    if count == 0 {
        mode as f32
    } else {
        (sum / count as f64) as f32
    }
}

/// The principal direction of the differences from the background over the pixels that
/// differ by more than `threshold` in some channel, signed so that particles project
/// positive on average. Every `stride`-th pixel of each sample is looked at (an odd stride,
/// started one pixel later in each successive sample, as the noise sample is taken).
fn colour_direction(samples: &[FrameView<'_>], bg: &Background, threshold: f32, stride: usize) -> Vec<f32> {
    let c = bg.channels;
    let mut cov = [[0.0f64; 3]; 3];
    let mut mean = [0.0f64; 3];
    let mut count = 0usize;
    for (s, f) in samples.iter().enumerate() {
        let pixels = (f.len() / c).min(bg.image.len() / c);
        for i in (s % stride..pixels).step_by(stride) {
            let (p, b) = (f.pixel(i), bg.pixel(i));
            let mut d = [0.0f64; 3];
            let mut big = false;
            for ch in 0..c {
                d[ch] = f64::from(p[ch] - b[ch]);
                big |= d[ch].abs() > f64::from(threshold);
            }
            if big {
                count += 1;
                for i in 0..c {
                    mean[i] += d[i];
                    for j in 0..c {
                        cov[i][j] += d[i] * d[j];
                    }
                }
            }
        }
    }
    if count == 0 {
        return vec![1.0 / (c as f32).sqrt(); c];
    }
    // Power iteration from the mean difference (or the grey axis when it cancels).
    let mut v = [0.0f64; 3];
    let norm = mean[..c].iter().map(|m| m * m).sum::<f64>().sqrt();
    for i in 0..c {
        v[i] = if norm > 0.0 { mean[i] / norm } else { 1.0 };
    }
    for _ in 0..100 {
        let mut w = [0.0f64; 3];
        for i in 0..c {
            for j in 0..c {
                w[i] += cov[i][j] * v[j];
            }
        }
        let n = w[..c].iter().map(|x| x * x).sum::<f64>().sqrt();
        if n <= 0.0 {
            break;
        }
        for i in 0..c {
            v[i] = w[i] / n;
        }
    }
    let proj: f64 = (0..c).map(|i| v[i] * mean[i]).sum();
    let sign = if proj < 0.0 { -1.0 } else { 1.0 };
    (0..c).map(|i| (sign * v[i]) as f32).collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::DecodedFrame;

    /// The frames' views, as the estimates take them.
    fn views(frames: &[Frame]) -> Vec<FrameView<'_>> {
        frames.iter().map(FrameView::from).collect()
    }

    fn frame_with_spot(level: f32, spot: f32, at: (usize, usize)) -> Frame {
        let mut f = Frame::filled(40, 30, &[level]);
        for y in at.1 - 2..=at.1 + 2 {
            for x in at.0 - 2..=at.0 + 2 {
                f.data[y * 40 + x] = spot;
            }
        }
        f
    }

    /// An 8-bit grey file's samples, handed over as they are, give the signal and the frame
    /// gain of the same frame converted to floating point, to the bit, against constant and
    /// per-pixel backgrounds (and the gain moves with the exposure); other layouts come as
    /// frames.
    #[test]
    fn grey_samples_give_the_frame_signal_and_gain_to_the_bit() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
        let dir = std::env::temp_dir().join(format!("physfit-view-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let (w, h) = (48u32, 40u32);
        let frames: Vec<Frame> = (0..5)
            .map(|k| {
                let img = image::GrayImage::from_fn(w, h, |x, _| {
                    image::Luma([(40 + x + k * 3 + rng.gen_range(0..9)) as u8])
                });
                let path = dir.join(format!("grey_{k}.png"));
                img.save(&path).unwrap();
                crate::load_frame(&path).unwrap()
            })
            .collect();
        let mut decoder = crate::FrameDecoder::default();
        let mut buf = Frame::default();
        // The files kept as their bytes give the same estimates to the bit.
        let kept: Vec<DecodedFrame> = (0..5)
            .map(|k| decoder.load_decoded(&dir.join(format!("grey_{k}.png"))).unwrap())
            .collect();
        let bytes: Vec<FrameView> = kept.iter().map(DecodedFrame::view).collect();
        assert!(bytes.iter().all(|v| matches!(v, FrameView::Grey8 { .. })));
        let found: Vec<Vec<[f64; 2]>> = (0..5).map(|k| vec![[10.0 + 5.0 * k as f64, 20.0]]).collect();
        for choice in [BackgroundChoice::Constant, BackgroundChoice::PerPixel] {
            let mut bg = estimate_background(&views(&frames), choice);
            let mut from_bytes = estimate_background(&bytes, choice);
            assert_eq!(from_bytes, bg, "{choice:?}");
            assert_eq!(
                from_bytes
                    .static_structure_fraction(&bytes, &found, 3.0)
                    .to_bits(),
                bg.static_structure_fraction(&views(&frames), &found, 3.0)
                    .to_bits()
            );
            from_bytes.exclude_particles(&bytes, &found, &[], 3.0, SampleExposure::AsRecorded);
            bg.exclude_particles(&views(&frames), &found, &[], 3.0, SampleExposure::AsRecorded);
            assert_eq!(from_bytes, bg, "{choice:?}");
            for (k, frame) in frames.iter().enumerate() {
                let view = decoder
                    .load_view(&dir.join(format!("grey_{k}.png")), &mut buf)
                    .unwrap();
                assert!(matches!(view, FrameView::Grey8 { .. }), "{view:?}");
                let (mut a, mut b) = (Vec::new(), Vec::new());
                bg.signal_into(view, &mut a);
                bg.signal_into(frame, &mut b);
                assert!(a.len() == b.len() && a.iter().zip(&b).all(|(x, y)| x.to_bits() == y.to_bits()));
                // Row by row, as the detector forms it.
                let mut rows = vec![f32::NAN; a.len()];
                for (y, out) in rows.chunks_exact_mut(w as usize).enumerate() {
                    bg.signal_range(view, y * w as usize..(y + 1) * w as usize, out);
                }
                assert!(rows.iter().zip(&a).all(|(x, y)| x.to_bits() == y.to_bits()));
                assert_eq!(bg.frame_gain(view).to_bits(), bg.frame_gain(frame).to_bits());
                assert!(
                    (bg.frame_gain(view) - bg.reference_gain).abs() < 0.2,
                    "{choice:?}"
                );
            }
        }
        let rgb = dir.join("rgb.png");
        image::RgbImage::from_pixel(w, h, image::Rgb([10, 20, 30]))
            .save(&rgb)
            .unwrap();
        let view = decoder.load_view(&rgb, &mut buf).unwrap();
        assert!(matches!(view, FrameView::Frame(f) if f.channels == 3 && f.data[..3] == [10.0, 20.0, 30.0]));
        std::fs::remove_dir_all(&dir).unwrap();
    }

    /// The gain of 8-bit grey bytes against a constant level, found by counting, is the
    /// general median of the ratios to the bit: flat, noisy and saturated frames with
    /// spots, levels below and above the 16 the gain needs, frames of fewer samples than
    /// the 16 it needs, of every pixel and of a strided sample.
    #[test]
    fn grey_gain_on_a_level_is_counted_to_the_bit() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
        for (w, h) in [(3usize, 2usize), (7, 5), (64, 48), (300, 200)] {
            for level in [10.0f32, 16.0, 30.0, 149.6, 240.0] {
                for sigma in [0.0f32, 0.4, 5.0, 40.0] {
                    let bytes: Vec<u8> = (0..w * h)
                        .map(|i| {
                            let noise: f32 =
                                (0..4).map(|_| rng.gen_range(-0.5f32..0.5)).sum::<f32>() * 1.73 * sigma;
                            let spot = if i % 97 < 6 { 120.0 } else { 0.0 };
                            (level + noise + spot).round().clamp(0.0, 255.0) as u8
                        })
                        .collect();
                    let frame = Frame {
                        width: w,
                        height: h,
                        channels: 1,
                        data: bytes.iter().map(|&v| f32::from(v)).collect(),
                    };
                    let mut bg = estimate_background(&[FrameView::Frame(&frame)], BackgroundChoice::Constant);
                    bg.level = vec![level];
                    bg.image = vec![level; w * h];
                    let view = FrameView::Grey8 {
                        samples: &bytes,
                        width: w,
                        height: h,
                    };
                    assert_eq!(
                        bg.frame_gain(view).to_bits(),
                        bg.frame_gain(&frame).to_bits(),
                        "{w}x{h}, level {level}, noise {sigma}"
                    );
                }
            }
        }
    }

    /// The signal formed by the loop compiled for AVX2 is the baseline's to the bit, from
    /// bytes and from `f32` frames, against constant and per-pixel backgrounds.
    #[test]
    fn avx2_signal_is_the_baseline_signal() {
        let (w, h) = (37usize, 11usize);
        let frames: Vec<Frame> = (0..5)
            .map(|k| Frame {
                width: w,
                height: h,
                channels: 1,
                data: (0..w * h).map(|i| ((i * 31 + k * 17) % 200) as f32).collect(),
            })
            .collect();
        let bytes: Vec<u8> = frames[2].data.iter().map(|&v| v as u8).collect();
        let view = FrameView::Grey8 {
            samples: &bytes,
            width: w,
            height: h,
        };
        for choice in [BackgroundChoice::Constant, BackgroundChoice::PerPixel] {
            let bg = estimate_background(&views(&frames), choice);
            for frame in [view, FrameView::Frame(&frames[2])] {
                let signal = || {
                    let mut out = Vec::new();
                    bg.signal_into(frame, &mut out);
                    out.iter().map(|v| v.to_bits()).collect::<Vec<_>>()
                };
                assert_eq!(signal(), crate::cpu::baseline_only(signal), "{choice:?}");
            }
        }
    }

    /// The median of bytes is the median of the same levels as `f32`, to the bit, for odd
    /// and even counts.
    #[test]
    fn median_of_bytes_is_the_median_of_the_levels() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        for n in 1..=30 {
            for _ in 0..20 {
                let spread = rng.gen_range(1u32..=256);
                let mut bytes: Vec<u8> = (0..n).map(|_| rng.gen_range(0..spread) as u8).collect();
                let mut levels: Vec<f32> = bytes.iter().map(|&b| f32::from(b)).collect();
                assert_eq!(
                    median_of_bytes(&mut bytes).to_bits(),
                    median_of(&mut levels).to_bits(),
                    "{n} values"
                );
            }
        }
    }

    /// A frame of another channel count than the background's is read as converted: a grey
    /// frame among colour ones as its grey repeated into red, green and blue, a colour frame
    /// among grey ones as the mean of its channels.
    #[test]
    fn a_frame_of_another_channel_count_is_converted_first() {
        let colour: Vec<Frame> = (0..3)
            .map(|k| Frame {
                width: 6,
                height: 4,
                channels: 3,
                data: (0..72).map(|i| (40 + (i * 7 + k * 5) % 50) as f32).collect(),
            })
            .collect();
        let grey = Frame {
            width: 6,
            height: 4,
            channels: 1,
            data: (0..24).map(|i| (60 + i * 3) as f32).collect(),
        };
        for (samples, odd) in [
            (colour.clone(), grey.clone()),
            (vec![grey.clone(); 3], colour[1].clone()),
        ] {
            let bg = estimate_background(&views(&samples), BackgroundChoice::PerPixel);
            let (mut got, mut want) = (Vec::new(), Vec::new());
            bg.signal_into(&odd, &mut got);
            bg.signal_into(&odd.clone().with_channels(bg.channels), &mut want);
            assert_eq!(got.len(), 24);
            assert!(got.iter().zip(&want).all(|(a, b)| a.to_bits() == b.to_bits()));
            let mut converted = Frame::default();
            let view = bg.matching(FrameView::Frame(&odd), &mut converted);
            assert!(matches!(view, FrameView::Frame(f) if f.channels == bg.channels));
        }
    }

    /// `signal_at` gives `signal_into`'s value to the bit, for grey and colour frames
    /// against constant and per-pixel backgrounds.
    #[test]
    fn signal_at_equals_the_whole_frame_signal() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        for channels in [1usize, 3] {
            let frames: Vec<Frame> = (0..5)
                .map(|_| Frame {
                    width: 9,
                    height: 7,
                    channels,
                    data: (0..9 * 7 * channels).map(|_| rng.gen_range(0.0..255.0)).collect(),
                })
                .collect();
            for choice in [BackgroundChoice::Constant, BackgroundChoice::PerPixel] {
                let bg = estimate_background(&views(&frames), choice);
                let whole = bg.signal(&frames[2]);
                for (i, v) in whole.iter().enumerate() {
                    let pixel = &frames[2].data[i * channels..(i + 1) * channels];
                    assert_eq!(
                        bg.signal_at(pixel, i).to_bits(),
                        v.to_bits(),
                        "{channels} channels, {choice:?}, pixel {i}"
                    );
                }
            }
        }
    }

    #[test]
    fn dark_on_light_gets_negative_direction_and_positive_signal() {
        let samples: Vec<Frame> = (0..5)
            .map(|k| frame_with_spot(200.0, 50.0, (5 + 6 * k, 10)))
            .collect();
        let bg = estimate_background(&views(&samples), BackgroundChoice::Auto);
        assert_eq!(bg.model, BackgroundModel::Constant);
        assert!((bg.level[0] - 200.0).abs() < 1e-3);
        assert!(bg.is_dark_on_light());
        let s = bg.signal(&samples[0]);
        assert!((s[10 * 40 + 5] - 150.0).abs() < 1e-3);
        assert!(s[0].abs() < 1e-3);
    }

    #[test]
    fn a_gradient_background_is_modelled_per_pixel() {
        let samples: Vec<Frame> = (0..7)
            .map(|k| {
                let mut f = frame_with_spot(0.0, 255.0, (5 + 4 * k, 15));
                for (i, v) in f.data.iter_mut().enumerate() {
                    if *v < 1.0 {
                        *v = (i % 40) as f32 * 4.0;
                    }
                }
                f
            })
            .collect();
        let bg = estimate_background(&views(&samples), BackgroundChoice::Auto);
        assert_eq!(bg.model, BackgroundModel::PerPixel);
        let s = bg.signal(&samples[3]);
        assert!(
            s[3 * 40 + 30].abs() < 1e-3,
            "background pixel signal {}",
            s[3 * 40 + 30]
        );
        assert!(s[15 * 40 + 17] > 100.0);
    }

    #[test]
    fn a_hovering_spot_is_taken_out_of_the_per_pixel_median() {
        // A gradient (so the per-pixel model is used) and a bright spot that sits at (20, 15)
        // in five of seven frames: the plain median there is the spot's level.
        let at = |k: usize| if k < 5 { (20, 15) } else { (8 + 20 * (k - 5), 6) };
        let gradient = |i: usize| (i % 40) as f32 * 4.0;
        let samples: Vec<Frame> = (0..7)
            .map(|k| {
                let mut f = frame_with_spot(0.0, 255.0, at(k));
                for (i, v) in f.data.iter_mut().enumerate() {
                    if *v < 1.0 {
                        *v = gradient(i);
                    }
                }
                f
            })
            .collect();
        let mut bg = estimate_background(&views(&samples), BackgroundChoice::PerPixel);
        let centre = 15 * 40 + 20;
        assert!(
            (bg.image[centre] - 255.0).abs() < 1e-3,
            "the plain median keeps the spot"
        );
        let found: Vec<Vec<[f64; 2]>> = (0..7).map(|k| vec![[at(k).0 as f64, at(k).1 as f64]]).collect();
        bg.exclude_particles(&views(&samples), &found, &[], 5.0, SampleExposure::AsRecorded);
        assert!(
            (bg.image[centre] - gradient(centre)).abs() < 1e-3,
            "the median of the three frames whose spot is farthest: {}",
            bg.image[centre]
        );
        // Far from every particle, nothing changes.
        assert!((bg.image[28 * 40 + 2] - gradient(28 * 40 + 2)).abs() < 1e-3);
    }

    #[test]
    fn colour_direction_points_to_the_particle_colour() {
        let samples: Vec<Frame> = (0..5)
            .map(|k| {
                let mut f = Frame::filled(30, 20, &[240.0, 240.0, 240.0]);
                for y in 8..12 {
                    for x in 3 + 5 * k..7 + 5 * k {
                        let i = (y * 30 + x) * 3;
                        f.data[i..i + 3].copy_from_slice(&[40.0, 140.0, 160.0]);
                    }
                }
                f
            })
            .collect();
        let bg = estimate_background(&views(&samples), BackgroundChoice::Auto);
        let d = &bg.direction;
        // The particle is (-200, -100, -80) from the background.
        let expect = [-200.0f32, -100.0, -80.0];
        let n = expect.iter().map(|v| v * v).sum::<f32>().sqrt();
        for i in 0..3 {
            assert!((d[i] - expect[i] / n).abs() < 1e-3, "{d:?}");
        }
        let s = bg.signal(&samples[0]);
        assert!((s[9 * 30 + 4] - n).abs() < 0.5);
    }
}
