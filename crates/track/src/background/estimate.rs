//! Estimating the background from sample frames: the model choice, the colour direction and the noise.

use super::gain::{dither, gain_shift, value_stride};
use super::median::{median_at, median_image, quantile};
use super::model::{Background, BackgroundChoice, BackgroundModel, STRUCTURED_LIMIT};
use crate::blind::BlindPixels;
use crate::frames::{Frame, FrameView, CLIPPED};

/// Quantisation noise of 8-bit levels (1/sqrt(12)), the smallest noise ever assumed.
const MIN_NOISE: f64 = 0.3;

/// Half-width, in standard deviations, of the band kept when the noise of a clipped
/// background is measured by iterated clipping.
const CLIP_SIGMAS: f64 = 5.0;

/// Pixels the background model is chosen on (an even sample of the frame): the fractions of
/// structured and moving pixels are then known to about 0.4 % of the frame (0.1 % near the
/// 2 % of [`STRUCTURED_LIMIT`]). Samples are far apart in 25 frames of a megabyte each, so
/// each costs a cache miss: four times as many took 9 ms more of a 200-frame recording.
pub(super) const DECISION_PIXELS: usize = 16_384;

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
        let stride = value_stride((k - 1) * n / NOISE_SAMPLES, channels);
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
        saturated_fraction: 0.0,
        blind: BlindPixels::default(),
        light: None,
        facing: None,
    };
    bg.measure_signal(samples);
    bg.measure_levels(samples);
    bg.saturated_fraction = samples
        .iter()
        .map(|&f| bg.saturated_fraction_of(f))
        .fold(0.0, f64::max);
    bg.light = bg.read_light(None);
    bg
}
impl Background {
    /// The samples' mean exposure gain against this background ([`Background::reference_gain`])
    /// and its brightest value ([`Background::brightest`]), measured again after the image
    /// changed.
    pub(super) fn measure_levels(&mut self, samples: &[FrameView<'_>]) {
        self.reference_gain =
            samples.iter().map(|&f| self.frame_gain(f)).sum::<f64>() / samples.len().max(1) as f64;
        self.brightest = f64::from(self.image.iter().fold(0.0f32, |m, &v| m.max(v)));
    }

    /// The particles' colour direction, the signal's noise and the clip offset, measured on
    /// `samples` against the current background image (`sigma_t`: the temporal noise, grey
    /// levels, which sets the colour threshold). A clip offset already added to the image is
    /// taken out first, so this may run again once the image changes
    /// ([`Background::exclude_particles`]).
    pub(super) fn measure_signal(&mut self, samples: &[FrameView<'_>]) {
        let sigma_t = self.temporal_noise;
        self.take_out_clip_offset();
        let stride = self.noise_stride(samples);
        // Where no pixel differs by 6 temporal sigmas, the threshold is halved down to 3 grey
        // levels before bright particles are assumed: an exposure drift counts in the temporal
        // noise (a light background drifting by 11 % read 12.6), and 75 grey levels were more
        // than a dark disc's contrast (taken for bright, its crescents in the per-pixel median
        // were followed 9 px off without a word).
        let mut threshold = (6.0 * sigma_t).max(3.0) as f32;
        self.direction = loop {
            match colour_direction(samples, self, threshold, stride) {
                Some(direction) => break direction,
                None if threshold > 3.0 => threshold = (0.5 * threshold).max(3.0),
                None => break vec![1.0 / (self.channels as f32).sqrt(); self.channels],
            }
        };
        if let Some(facing) = &self.facing {
            if self.direction.iter().zip(facing).map(|(a, b)| a * b).sum::<f32>() < 0.0 {
                for u in &mut self.direction {
                    *u = -*u;
                }
            }
        }
        self.measure_noise(samples);
    }

    /// Takes a clip offset added to the image (see [`Background::measure_noise`]) out again.
    pub(super) fn take_out_clip_offset(&mut self) {
        if self.clip_offset != 0.0 {
            let offset = self.clip_offset as f32;
            for (l, u) in self.level.iter_mut().zip(&self.direction) {
                *l -= offset * u;
            }
            for px in self.image.chunks_exact_mut(self.channels) {
                for (b, u) in px.iter_mut().zip(&self.direction) {
                    *b -= offset * u;
                }
            }
            self.clip_offset = 0.0;
        }
    }

    /// An even sample of the pixels the noise is measured on: every `stride`-th of each
    /// frame, an odd stride so that successive frames' samples fall on other columns.
    fn noise_stride(&self, samples: &[FrameView<'_>]) -> usize {
        (samples.len() * self.width * self.height / NOISE_SAMPLES).max(1) | 1
    }

    /// The signal's noise (grey levels) and the clip offset, measured on `samples` along the
    /// colour direction in use, against the current background image (with no clip offset
    /// in it).
    pub(super) fn measure_noise(&mut self, samples: &[FrameView<'_>]) {
        let (width, height, channels) = (self.width, self.height, self.channels);
        let stride = self.noise_stride(samples);
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
        // Each sample's own exposure, relative to their mean: a drifting exposure moves the
        // value of every background pixel in proportion to its brightness, up to the clip
        // level, which is not noise (an exposure drifting by 14 % on a light background read
        // noise 11 as 42).
        let gains: Vec<f64> = samples.iter().map(|&f| self.frame_gain(f)).collect();
        let mean_gain = gains.iter().sum::<f64>() / gains.len().max(1) as f64;
        let relative: Vec<f32> = gains.iter().map(|&g| (g / mean_gain) as f32).collect();
        for (s, f) in samples.iter().enumerate() {
            let g = relative[s];
            // 8-bit frames hold whole levels, so the signal takes values one level apart and
            // the median of its magnitude jumps by whole levels (noise 5 read as 4.45). A
            // deterministic dither spread evenly over one level makes the distribution
            // continuous again: its spread is then that of the quantised noise itself.
            for i in (s % stride..width * height).step_by(stride) {
                let p = &f.pixel(i)[..channels];
                let b = self.pixel(i);
                // A value at the clip level where the exposure drives the background there
                // holds no noise (a quarter of the samples, fresh style 6155).
                if p.iter().zip(b).any(|(&p, &b)| p >= CLIPPED && g * b >= CLIPPED) {
                    continue;
                }
                let shift = gain_shift(b, &self.direction, g);
                let (v, lo) = (
                    self.unlit_signal_at(p, i) - shift,
                    self.unlit_signal_at(&clip, i) - shift,
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
/// positive on average; `None` when no pixel differs so. Every `stride`-th pixel of each sample is looked at (an odd stride,
/// started one pixel later in each successive sample, as the noise sample is taken).
fn colour_direction(
    samples: &[FrameView<'_>],
    bg: &Background,
    threshold: f32,
    stride: usize,
) -> Option<Vec<f32>> {
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
        return None;
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
    Some((0..c).map(|i| (sign * v[i]) as f32).collect())
}
