//! A frame's brightness gain against the background, and its removal from the signal.

use super::model::{Background, BackgroundModel};
use crate::frames::{FrameView, CLIPPED, CLIP_LEVEL};

/// Pixels a frame's gain is measured on (an even sample): the median ratio is then known to
/// about 1.4 % of the pixel-to-pixel spread of the ratios, a tenth of a grey level on a
/// background of 150 under noise 5.
const GAIN_SAMPLES: usize = 8_192;

/// Fraction of a sample's values at the clip level above which the exposure saturates the
/// background (see [`Background::uniform_gain_offset`]).
const SATURATED_LIMIT: f64 = 0.05;

impl Background {
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

    /// Whether the exposure saturates the background: more than 5 % of some sample's values
    /// at the 8-bit clip level (255 or more). Clipped pixels, and the particles' light
    /// against them, do not follow a frame's gain.
    pub fn exposure_saturates(&self) -> bool {
        self.saturated_fraction > SATURATED_LIMIT
    }

    /// The fraction of `frame`'s values at the 8-bit clip level (255 or more), over the
    /// values [`Background::frame_gain`] looks at.
    pub(super) fn saturated_fraction_of(&self, frame: FrameView<'_>) -> f64 {
        let count = |n: usize, stride: usize, at: &dyn Fn(usize) -> bool| {
            let picked = n.div_ceil(stride).max(1);
            (0..n).step_by(stride).filter(|&i| at(i)).count() as f64 / picked as f64
        };
        match frame {
            FrameView::Grey8 { samples, .. } => {
                let (n, stride) = self.gain_sampling(samples.len());
                count(n, stride, &|i| samples[i] == u8::MAX)
            }
            FrameView::Frame(f) => {
                let (n, stride) = self.gain_sampling(f.data.len());
                count(n, stride, &|i| f.data[i] >= CLIPPED)
            }
        }
    }

    /// How many of `data`'s values the gain looks at, and how far apart: the values
    /// `0, stride, 2 stride, ...` below the returned length.
    fn gain_sampling(&self, len: usize) -> (usize, usize) {
        let n = len.min(self.image.len());
        (n, value_stride(n / GAIN_SAMPLES, self.channels))
    }

    /// [`Background::frame_gain`] of the samples `data`, read as grey levels by `level`.
    fn gain_of<T: Copy>(&self, data: &[T], level: impl Fn(T) -> f32) -> f64 {
        let (n, stride) = self.gain_sampling(data.len());
        let data = &data[..n];
        let c = self.channels;
        let mut ratios: Vec<f32> = Vec::with_capacity(n / stride + 1);
        // The least ratio each clipped value may have.
        let mut bounds: Vec<f32> = Vec::new();
        // The background under value `i`, if the gain looks at it (16 levels at least).
        let under = |i: usize| {
            let b = if c == 1 { self.pixel(i)[0] } else { self.image[i] };
            (b >= 16.0).then_some(b)
        };
        // Sample `j` is value `j * stride` (a plain loop: the iterator chain cost three times
        // as much, on every frame); a grey value is its pixel's.
        for (j, i) in (0..n.div_ceil(stride)).map(|j| (j, j * stride)) {
            let Some(b) = under(i) else {
                continue;
            };
            let v = level(data[i]);
            if v < CLIPPED {
                ratios.push((v + dither(j)) / b);
            } else {
                bounds.push(CLIPPED / b);
            }
        }
        censored_median(&mut ratios, &mut bounds).unwrap_or_else(|| {
            // Most values clipped: the least gain that clips as many, from the dimmest
            // background of that many brightest (read again: rarely needed).
            let mut all: Vec<f32> = (0..n).step_by(stride).filter_map(under).collect();
            let rank = all.len() - bounds.len();
            let dimmest_clipped = *all.select_nth_unstable_by(rank, f32::total_cmp).1;
            f64::from(CLIPPED / dimmest_clipped)
        })
    }

    /// [`Background::frame_gain`] of 8-bit grey samples `data` against a constant grey
    /// level, the same value to the bit, found by counting. Every ratio is a dithered level
    /// over the same background level, and dividing by it keeps their order, so the median
    /// ratio is the median dithered level over the background. A level's dithered values
    /// all lie within half a level of it: a histogram of the levels tells which level holds
    /// the median, and only that level's values are ordered.
    fn grey8_gain_on_level(&self, data: &[u8]) -> f64 {
        let (n, stride) = self.gain_sampling(data.len());
        let b = self.level[0];
        let mut histogram = [0usize; 256];
        for &v in data[..n].iter().step_by(stride) {
            histogram[usize::from(v)] += 1;
        }
        // Clipped values count above every ratio read: on a constant level every bound lies
        // above every ratio read, and `censored_median` comes to the same.
        let clipped = histogram[usize::from(u8::MAX)];
        let used = n.div_ceil(stride);
        if b < 16.0 || used < 16 {
            return 1.0;
        }
        // The rank `quantile(.., 0.5)` selects over every value, and the level holding it.
        let rank = ((used - 1) as f64 * 0.5).round() as usize;
        if rank >= used - clipped {
            // Most of the frame is clipped: the least gain that clips a background this bright.
            return f64::from(CLIPPED / b);
        }
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

    /// The offset (grey levels) that the gain `g` (from [`Background::gain_to_remove`]) adds
    /// to the signal of every pixel against a [`BackgroundModel::Constant`] background, to be
    /// subtracted from it; `None` for a per-pixel background (where the offset follows the
    /// background's own brightness, and uneven light may be taken out). On a flat background
    /// a gain is one offset over the whole frame, so it can be taken out of the signal the
    /// blobs are found in: their noise mask assumes a background at zero, and an exposure
    /// drift of 9 % on a background of 181 levels (sweep style 1026) shifts it by 16 levels,
    /// four standard deviations of the smoothed noise, which floods the mask with background
    /// where the frame is dark (and the particles' measured extent with it) and shrinks it
    /// where the frame is bright. Where the gain drives the background to the clip level the
    /// offset stops there ([`gain_shift`]): left in, it made every particle's extent the
    /// frame's wherever the exposure was low, and the particles of the clipped frames specks
    /// against it (fresh style 6784: none found in 6 of 17 frames).
    #[must_use]
    pub fn uniform_gain_offset(&self, g: f64) -> Option<f32> {
        (self.model == BackgroundModel::Constant).then(|| gain_shift(&self.level, &self.direction, g as f32))
    }

    /// Removes the gain `g` (from [`Background::gain_to_remove`]) from `signal`, in place. The
    /// background a frame shows is `g b` up to the clip level (255): where the gain drives it
    /// beyond, the frame holds 255, and so is the background taken there (a light background
    /// saturating with the exposure, sweep style 6137: beyond, the clipped background read
    /// as lighter than the model all round the particles in it, and their skirts as dark
    /// rings).
    pub fn apply_gain(&self, g: f64, signal: &mut [f32]) {
        let g = g as f32;
        // The signal is divided by the light where one is read: so is the offset.
        let lit = |i: usize| self.light.as_ref().map_or(1.0, |l| l.inverse[i]);
        if f64::from(g) * self.brightest < f64::from(CLIPPED) {
            for (i, (o, b)) in signal
                .iter_mut()
                .zip(self.image.chunks_exact(self.channels))
                .enumerate()
            {
                // signal = u . (p - g b) = u . (p - b) - (g - 1) u . b
                let ub: f32 = b.iter().zip(&self.direction).map(|(b, u)| u * b).sum();
                *o -= (g - 1.0) * ub * lit(i);
            }
            return;
        }
        for (i, (o, b)) in signal
            .iter_mut()
            .zip(self.image.chunks_exact(self.channels))
            .enumerate()
        {
            // signal = u . (p - min(g b, 255)) = u . (p - b) - u . (min(g b, 255) - b)
            *o -= gain_shift(b, &self.direction, g) * lit(i);
        }
    }
}
/// How much the exposure `g` (relative to the background's) moves the signal of a pixel over
/// the background `b` (its channels), along the colour `direction`: `u . (min(g b, 255) - b)`,
/// grey levels.
pub(super) fn gain_shift(b: &[f32], direction: &[f32], g: f32) -> f32 {
    b.iter()
        .zip(direction)
        .map(|(b, u)| u * ((g * b).min(CLIP_LEVEL) - b))
        .sum()
}

/// The median ratio of a frame's values to the background under them: `ratios` holds the
/// unclipped ones (dithered) and `bounds` the least ratio each clipped value may have (a
/// clipped value says only that its pixel is at least as bright as the clip level), both
/// reordered; 1 when fewer than 16 values were looked at; `None` where most values are
/// clipped and the estimate has no median.
///
/// Left out, the clipped values pulled the median down where noise clipped the brightest
/// of a flat light background (noise 27 on a background of 230 clips one value in five);
/// counted above every ratio, they pull it up where a brighter part of the background
/// clips at any noise (vignetting). So the median is the Kaplan-Meier estimate's, each
/// clipped value censored at its bound, wherever a bound lies below the plain count's
/// median (on a flat background, and where only particles clip, none does).
///
/// Where the estimate has no median (a light background driven into saturation by the
/// exposure, whose unclipped rest is mostly the particles), [`Background::frame_gain`]
/// takes the least gain that clips as many values: the clip level over the background of
/// the dimmest of that many brightest (on a flat background, the least gain that clips it).
/// The median of the unclipped rest read the particles: 0.5 to 0.7 in the clipped frames of
/// fresh style 6374, 0.97 to 1.0 in those of 6155, whose exposures drift by 14 and 15 %.
fn censored_median(ratios: &mut [f32], bounds: &mut [f32]) -> Option<f64> {
    let used = ratios.len() + bounds.len();
    if used < 16 {
        return Some(1.0);
    }
    let rank = ((used - 1) as f64 * 0.5).round() as usize;
    let lowest_bound = bounds.iter().fold(f32::INFINITY, |m, &l| m.min(l));
    if rank < ratios.len() {
        let m = *ratios.select_nth_unstable_by(rank, f32::total_cmp).1;
        if lowest_bound >= m {
            return Some(f64::from(m));
        }
    }
    // Where every bound lies above every ratio read (a flat background, as
    // `grey8_gain_on_level` counts, to the bit), the clipped values count above them all and
    // most are clipped here; else the Kaplan-Meier estimate.
    let highest_ratio = ratios.iter().fold(f32::NEG_INFINITY, |m, &r| m.max(r));
    if lowest_bound < highest_ratio {
        return kaplan_meier_median(ratios, bounds).map(f64::from);
    }
    None
}

/// The median of the Kaplan-Meier estimate of a distribution from the values `events` and
/// the right-censored values `censored` (each known only to be at least that), or `None`
/// where the estimate stays above one half (too much is censored below its median).
fn kaplan_meier_median(events: &[f32], censored: &[f32]) -> Option<f32> {
    let mut all: Vec<(f32, bool)> = events
        .iter()
        .map(|&v| (v, true))
        .chain(censored.iter().map(|&v| (v, false)))
        .collect();
    // At a tie an event comes first: a value censored there was still at risk.
    all.sort_unstable_by(|a, b| a.0.total_cmp(&b.0).then(b.1.cmp(&a.1)));
    let mut at_risk = all.len() as f64;
    let mut survival = 1.0f64;
    for (v, event) in all {
        if event {
            survival *= 1.0 - 1.0 / at_risk;
            if survival <= 0.5 {
                return Some(v);
            }
        }
        at_risk -= 1.0;
    }
    None
}

/// A stride through channel-interleaved values near `approx` (at least 1) that visits every
/// channel: odd, so that it walks across the columns, and prime to the channel count (a
/// stride of 3, 9 or 15 read one channel of an RGB frame alone: a 1080p frame's gain was
/// read on its red values, and a light background saturating in red alone, fresh style
/// 6484, made the gain that of the particles).
pub(super) fn value_stride(approx: usize, channels: usize) -> usize {
    let mut stride = approx.max(1) | 1;
    while channels > 1 && gcd(stride, channels) != 1 {
        stride += 2;
    }
    stride
}

fn gcd(a: usize, b: usize) -> usize {
    if b == 0 {
        a
    } else {
        gcd(b, a % b)
    }
}

/// A deterministic dither over one grey level, `frac(i φ) − ½` (the golden-ratio sequence
/// spreads any run of consecutive indices evenly over the level), in 64-bit fixed point.
pub(super) fn dither(i: usize) -> f32 {
    /// The fractional part of the golden ratio, `0.618…`, times 2⁶⁴.
    const PHI_FRAC_FIXED: u64 = 0x9E37_79B9_7F4A_7C15;
    let frac = (i as u64).wrapping_mul(PHI_FRAC_FIXED) >> 40;
    frac as f32 * (1.0 / (1u64 << 24) as f32) - 0.5
}
