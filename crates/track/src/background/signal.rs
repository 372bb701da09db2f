//! The particle signal of a frame against the background.

use super::model::{Background, BackgroundModel};
use crate::blind::BlindPixels;
use crate::cpu::with_avx2;
use crate::frames::{Frame, FrameView};

impl Background {
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
            FrameView::Grey8 { samples, .. } => {
                self.grey_signal(&samples[pixels.clone()], image, f32::from, out)
            }
            FrameView::Frame(f) if c == 1 => self.grey_signal(&f.data[pixels.clone()], image, |v| v, out),
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
        if let Some(light) = &self.light {
            for (o, l) in out.iter_mut().zip(&light.inverse[pixels]) {
                *o *= l;
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
    pub(super) fn pixel(&self, p: usize) -> &[f32] {
        match self.model {
            BackgroundModel::Constant => &self.level,
            BackgroundModel::PerPixel => &self.image[p * self.channels..(p + 1) * self.channels],
        }
    }

    /// The particle signal of one pixel, `pixel` (its channels' values, grey levels) at
    /// pixel index `i`: the value [`Background::signal_into`] gives there, to the bit.
    pub fn signal_at(&self, pixel: &[f32], i: usize) -> f32 {
        let s = self.unlit_signal_at(pixel, i);
        self.light.as_ref().map_or(s, |l| s * l.inverse[i])
    }

    /// [`Background::signal_at`] before the light is taken out (see
    /// [`crate::Light`]): what the pixel noise is measured on, the same at every
    /// pixel.
    pub(super) fn unlit_signal_at(&self, pixel: &[f32], i: usize) -> f32 {
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

    /// The spread of a frame's signal about this background where nothing but background
    /// is seen, grey levels: [`Background::noise_sigma`] with a per-pixel median's own error
    /// added (`1.2533 sigma / sqrt(k)` over `k` samples). The noise is measured on the
    /// samples against their own median, which each of them pulls towards itself; a frame
    /// not among them sees the median's error as well (sweep style 1018, noise 4.9 measured
    /// 4.64 over 16 samples: rings round its ball spread 4.85-4.99 about a plane).
    pub fn frame_noise(&self) -> f64 {
        let median_share = match self.model {
            super::BackgroundModel::PerPixel => std::f64::consts::FRAC_PI_2 / self.sample_count.max(1) as f64,
            super::BackgroundModel::Constant => 0.0,
        };
        self.noise_sigma * (1.0 + median_share).sqrt()
    }
}
/// The signal of a colour pixel `p` against background `b`: the difference projected on the
/// particles' colour direction `u`, grey levels.
fn colour_signal(p: &[f32], b: &[f32], u: &[f32]) -> f32 {
    p.iter().zip(b).zip(u).map(|((p, b), u)| u * (p - b)).sum::<f32>()
}
