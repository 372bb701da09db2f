//! The signal's sign from named particles.
//!
//! The colour direction is signed so that the pixels which differ most from the background
//! project positive on average ([`Background::measure_signal`]). Where the particles are
//! faint and few, light that the background model leaves out outweighs them: a textured
//! ball of 3 px, 30 grey levels dark at noise 11 under 6 % vignetting in a frame of 58 × 62
//! px, was read bright on dark, and the bright middle of the frame was followed (fresh style
//! 8350). A structure says where each particle is in the first frame, and two references
//! there say which way it faces: the other samples (a particle that moves changes the
//! pixels of its start by the sign of its signal, whatever the light), and the background's
//! level, or the light's surface where one was read (which light that the model leaves out
//! shifts, but which, unlike a median of the samples, holds no particle: rings of 11 px
//! that drift by their radius put their rim in the median where their middle is in the
//! first frame). Against each, the change summed over a Gaussian window about each start,
//! at the width that shows it best, is the particle's vote, and the votes summed as
//! standard scores say which way the particles face. Only where both say the particles face
//! against the sign in use is it turned. A particle that hovers, or a ring wider than the
//! windows (its middle is background), casts no vote against it, and the sign is left as
//! the pixels gave it; so is the sign of a background with structure of its own (neither a
//! level nor a smooth light), against which no level says anything.

use super::gain::gain_shift;
use super::model::{Background, BackgroundModel};
use crate::frames::FrameView;

/// Widths of the Gaussian weights the change about a start is summed with, px: matched to
/// the centre of a particle of radius 1.5 px, up to that of a large one (a larger one
/// changes the same pixels).
const WIDTHS: [f64; 6] = [0.8, 1.1, 1.6, 2.2, 3.2, 4.5];

/// Standard score the summed votes must reach against the sign in use before it is turned.
/// Under noise alone the best of the six (strongly correlated) weightings of a start's
/// window spreads by 1.38 and exceeds 4 in magnitude once in 5 400 starts, 5 once in
/// 200 000 (simulated: independent unit noise over the window of 13.5 px).
const TURN_SCORE: f64 = 5.0;

impl Background {
    /// Turns the signal's sign where the named particles' starts (`starts`, px, in the first
    /// of `samples`) say they face the other way (see the module documentation); returns
    /// true if it turned. The noise, levels and light are measured again after a turn.
    pub fn face_starts(&mut self, samples: &[FrameView<'_>], starts: &[[f64; 2]]) -> bool {
        // Against a background with structure of its own, the level says nothing.
        let even = self.model == BackgroundModel::Constant || self.light.is_some();
        if samples.len() < 3 || starts.is_empty() || !even {
            return false;
        }
        // The level's vote first: it needs no median over the samples, and where the
        // particles face the sign in use (nearly always) the samples' is not wanted.
        // Each sample's exposure against the background: a drifting exposure moves every
        // background pixel by its share of the brightness, which is no particle's signal.
        let gains: Vec<f64> = samples.iter().map(|&f| self.frame_gain(f)).collect();
        if self.start_score(samples, &gains, starts, Against::Level) > -TURN_SCORE
            || self.start_score(samples, &gains, starts, Against::Samples) > -TURN_SCORE
        {
            return false;
        }
        self.take_out_clip_offset();
        for u in &mut self.direction {
            *u = -*u;
        }
        self.facing = Some(self.direction.clone());
        self.measure_noise(samples);
        self.measure_levels(samples);
        self.light = self.read_light(None);
        true
    }

    /// The summed standard score of the named particles' votes (positive where they agree
    /// with the sign in use) against `against`; `gains` are the samples' exposures
    /// ([`Background::frame_gain`]).
    fn start_score(
        &self,
        samples: &[FrameView<'_>],
        gains: &[f64],
        starts: &[[f64; 2]],
        against: Against,
    ) -> f64 {
        let (width, height) = (self.width as i64, self.height as i64);
        let k = samples.len() as f64;
        // The change of one pixel against the median of the samples: the noise of a pixel
        // and of a median of `k` (sqrt(pi / 2) sigma / sqrt(k)); against the level, a pixel's.
        let sigma = match against {
            Against::Samples => self.noise_sigma * (1.0 + std::f64::consts::FRAC_PI_2 / k).sqrt(),
            Against::Level => self.noise_sigma,
        };
        // Each sample's exposure against the samples' mean, for the median of the samples.
        let mean_gain = gains.iter().sum::<f64>() / k;
        let relative: Vec<f32> = gains.iter().map(|&g| (g / mean_gain) as f32).collect();
        // The first sample's own exposure against the background.
        let first_gain = gains[0] as f32;
        let reach = 3.0 * WIDTHS[WIDTHS.len() - 1];
        let mut sum = 0.0;
        let mut values = Vec::with_capacity(samples.len());
        let mut changes: Vec<(f64, f64)> = Vec::new();
        for &[x, y] in starts {
            // Each pixel's squared distance from the start and its change.
            changes.clear();
            let (cx, cy) = (x.round() as i64, y.round() as i64);
            let r = reach.ceil() as i64;
            for py in (cy - r).max(0)..=(cy + r).min(height - 1) {
                for px in (cx - r).max(0)..=(cx + r).min(width - 1) {
                    let d2 = (px as f64 - x).powi(2) + (py as f64 - y).powi(2);
                    if d2 > reach * reach {
                        continue;
                    }
                    let i = (py * width + px) as usize;
                    let change = match against {
                        Against::Samples => {
                            values.clear();
                            let b = self.pixel(i);
                            values.extend(samples.iter().zip(&relative).map(|(f, &g)| {
                                self.unlit_signal_at(&f.pixel(i), i) - gain_shift(b, &self.direction, g)
                            }));
                            let first = values[0];
                            let middle = values.len() / 2;
                            let median = *values.select_nth_unstable_by(middle, f32::total_cmp).1;
                            first - median
                        }
                        Against::Level => {
                            let p = samples[0].pixel(i);
                            let reference = match &self.light {
                                Some(light) => &light.surface[i * self.channels..(i + 1) * self.channels],
                                None => &self.level[..],
                            };
                            (reference.iter().zip(&self.direction).zip(p))
                                .map(|((l, u), p)| u * (p - l))
                                .sum::<f32>()
                                - gain_shift(reference, &self.direction, first_gain)
                        }
                    };
                    changes.push((d2, f64::from(change)));
                }
            }
            sum += best_score(&changes, sigma);
        }
        sum / (starts.len() as f64).sqrt()
    }
}

/// What a start's change is measured against.
#[derive(Clone, Copy, Debug)]
enum Against {
    /// The median of the samples at the same pixel.
    Samples,
    /// The background's level, or the light's surface where one was read: a per-pixel image
    /// is the median of the samples, which holds particles that hover about their own size
    /// (rings of 11 px drifting by their radius have their rim there, their middle in the
    /// first frame).
    Level,
}

/// The matched sum of the `changes` (each pixel's squared distance from the start, px², and
/// change, grey levels) over its noise `sigma`, `sum w c / (sigma sqrt(sum w^2))`, at the
/// width of [`WIDTHS`] that gives it the largest magnitude; 0 without pixels.
fn best_score(changes: &[(f64, f64)], sigma: f64) -> f64 {
    WIDTHS
        .iter()
        .filter_map(|&width| {
            let (total, weight2) = changes.iter().fold((0.0, 0.0), |(t, w2), &(d2, change)| {
                let w = (-0.5 * d2 / (width * width)).exp();
                (t + w * change, w2 + w * w)
            });
            (weight2 > 0.0).then(|| total / (sigma * weight2.sqrt()))
        })
        .max_by(|a, b| a.abs().total_cmp(&b.abs()))
        .unwrap_or(0.0)
}
