//! A drawn recording: the style's paths and particle looks, its frames and truth.

use std::path::Path;

use image::codecs::png::{CompressionType, FilterType, PngEncoder};
use image::{DynamicImage, ImageEncoder};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

use crate::blur::blur_plane;
use crate::bound::{cramer_rao, PositionBound};
use crate::error::SynthError;
use crate::look::{add_particle, ParticleLook};
use crate::motion::{draw_paths, normal};
use crate::style::{Lines, Style};
use crate::truth::Truth;

/// The file name of frame `k`: `frame_00000.png`, `frame_00001.png`, ...
pub fn frame_file_name(k: usize) -> String {
    format!("frame_{k:05}.png")
}

/// A recording drawn from a [`Style`]: its particles' looks and paths, its truth, and its
/// frames on demand.
///
/// # Example
///
/// ```
/// use physfit_synth::{Sequence, Style};
///
/// let seq = Sequence::new(Style::random(7));
/// let frame = seq.render_frame(0);
/// assert_eq!((frame.width(), frame.height()), (seq.style.width, seq.style.height));
/// assert_eq!(seq.truth.positions.len(), seq.style.frame_count);
/// ```
#[derive(Clone, Debug)]
pub struct Sequence {
    /// The style.
    pub style: Style,
    /// Each particle's centre and intensity centroid in each frame.
    pub truth: Truth,
    looks: Vec<ParticleLook>,
}

/// Salt of the pixel noise's seed (one ChaCha8 stream per frame).
const NOISE_SALT: u64 = 0x6e01_5e5e;

impl Sequence {
    /// Draws the paths and looks of `style` and the truth (centres and the intensity
    /// centroids of the noise-free particles, lit and under even light).
    pub fn new(style: Style) -> Sequence {
        let looks: Vec<ParticleLook> = style
            .radii()
            .iter()
            .enumerate()
            .map(|(i, &r)| ParticleLook::new(&style.profile, r, style.seed.wrapping_add(i as u64)))
            .collect();
        let positions = draw_paths(&style);
        let (w, h) = (style.width as usize, style.height as usize);
        // Light on the background alone leaves the particles' images even.
        let light = |x: f64, y: f64| {
            if style.additive_light {
                1.0
            } else {
                style.light(x, y)
            }
        };
        let sums: Vec<Vec<[f64; 6]>> = positions
            .iter()
            .map(|frame| {
                frame
                    .iter()
                    .zip(&looks)
                    .map(|(&p, look)| add_particle(&mut [], w, h, look, p, &light))
                    .collect()
            })
            .collect();
        let centroid = |at: usize| -> Vec<Vec<[f64; 2]>> {
            sums.iter()
                .map(|frame| {
                    frame
                        .iter()
                        .map(|s| [s[at + 1] / s[at], s[at + 2] / s[at]])
                        .collect()
                })
                .collect()
        };
        let (centroids, even_centroids) = (centroid(0), centroid(3));
        let names = (0..style.particle_count).map(|i| format!("p{i}")).collect();
        Sequence {
            truth: Truth {
                names,
                positions,
                centroids,
                even_centroids,
            },
            style,
            looks,
        }
    }

    /// The particles' looks, in particle order.
    pub fn looks(&self) -> &[ParticleLook] {
        &self.looks
    }

    /// Draws frame `k`: `Luma8` for a grey style, `Rgb8` for a colour one (see [`Style`] for
    /// the pixel model). The noise comes from the style's seed and `k` only.
    ///
    /// # Panics
    ///
    /// If `k` is not below the style's frame count.
    pub fn render_frame(&self, k: usize) -> DynamicImage {
        let s = &self.style;
        let (w, h) = (s.width as usize, s.height as usize);
        let mut plane = vec![0.0; w * h];
        for (&p, look) in self.truth.positions[k].iter().zip(&self.looks) {
            add_particle(&mut plane, w, h, look, p, &|_, _| 1.0);
        }
        if let Some(lines) = s.lines {
            for pair in self.truth.positions[k].windows(2) {
                add_line_beneath(&mut plane, w, h, pair[0], pair[1], lines);
            }
        }
        blur_plane(&mut plane, w, h, s.blur);
        let mut rng = ChaCha8Rng::seed_from_u64(s.seed ^ NOISE_SALT);
        rng.set_stream(k as u64);
        let gain = s.gain(k);
        let channels = if s.colour { 3 } else { 1 };
        let mut bytes = Vec::with_capacity(w * h * channels);
        for y in 0..h {
            for x in 0..w {
                let light = s.light(x as f64, y as f64);
                let lit = gain * light;
                let p = plane[y * w + x];
                for c in 0..channels {
                    let contrast = (s.foreground[c] - s.background[c]) * p;
                    let clean = if s.additive_light {
                        // The light's unevenness on the background alone.
                        lit * s.background[c] + gain * contrast
                    } else {
                        lit * (s.background[c] + contrast)
                    };
                    let noisy = if s.noise > 0.0 {
                        clean + s.noise * normal(&mut rng)
                    } else {
                        clean
                    };
                    bytes.push(noisy.round().clamp(0.0, 255.0) as u8);
                }
            }
        }
        if s.colour {
            DynamicImage::ImageRgb8(
                image::RgbImage::from_raw(s.width, s.height, bytes).expect("w * h * 3 bytes"),
            )
        } else {
            DynamicImage::ImageLuma8(
                image::GrayImage::from_raw(s.width, s.height, bytes).expect("w * h bytes"),
            )
        }
    }

    /// Writes every frame into `dir` (created if missing) as `frame_00000.png`, ... (8-bit
    /// PNG).
    pub fn write_frames(&self, dir: &Path) -> Result<(), SynthError> {
        std::fs::create_dir_all(dir).map_err(|source| SynthError::Io {
            path: dir.to_path_buf(),
            source,
        })?;
        for k in 0..self.style.frame_count {
            let path = dir.join(frame_file_name(k));
            let image = self.render_frame(k);
            let mut bytes = Vec::new();
            PngEncoder::new_with_quality(&mut bytes, CompressionType::Fast, FilterType::Adaptive)
                .write_image(
                    image.as_bytes(),
                    image.width(),
                    image.height(),
                    image.color().into(),
                )
                .map_err(|source| SynthError::Encode {
                    path: path.clone(),
                    source,
                })?;
            std::fs::write(&path, bytes).map_err(|source| SynthError::Io { path, source })?;
        }
        Ok(())
    }

    /// The Cramér-Rao bound of the per-axis position error of this recording's particles
    /// under its pixel noise (see [`PositionBound`]).
    pub fn bound(&self) -> PositionBound {
        cramer_rao(&self.style, &self.looks)
    }
}

/// Adds the line from `a` to `b` (px) of `lines` to `plane` (`w * h` profile values) beneath
/// what is there: a pixel gains `(1 − min(value, 1)) level f`, `f` the overlap of the
/// pixel's unit span and the line's width measured across the line at the pixel's centre.
fn add_line_beneath(plane: &mut [f64], w: usize, h: usize, a: [f64; 2], b: [f64; 2], lines: Lines) {
    let d = [b[0] - a[0], b[1] - a[1]];
    let length2 = d[0] * d[0] + d[1] * d[1];
    if length2 <= 0.0 {
        return;
    }
    let reach = 0.5 * lines.width + 1.0;
    let x0 = (a[0].min(b[0]) - reach).floor().max(0.0) as usize;
    let y0 = (a[1].min(b[1]) - reach).floor().max(0.0) as usize;
    let x1 = ((a[0].max(b[0]) + reach).ceil().max(0.0) as usize).min(w.saturating_sub(1));
    let y1 = ((a[1].max(b[1]) + reach).ceil().max(0.0) as usize).min(h.saturating_sub(1));
    let half = 0.5 * lines.width;
    for y in y0..=y1 {
        for x in x0..=x1 {
            let (px, py) = (x as f64 - a[0], y as f64 - a[1]);
            let t = ((px * d[0] + py * d[1]) / length2).clamp(0.0, 1.0);
            let across = (px - t * d[0]).hypot(py - t * d[1]);
            let cover = ((across + 0.5).min(half) - (across - 0.5).max(-half)).clamp(0.0, 1.0);
            if cover > 0.0 {
                let v = &mut plane[y * w + x];
                *v += (1.0 - v.min(1.0)) * lines.level * cover;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn same_seed_draws_the_same_bytes() {
        for seed in [4, 11] {
            let a = Sequence::new(Style::random(seed));
            let b = Sequence::new(Style::random(seed));
            assert_eq!(a.truth, b.truth);
            let k = a.style.frame_count - 1;
            assert_eq!(a.render_frame(k).as_bytes(), b.render_frame(k).as_bytes());
        }
        let (a, b) = (Sequence::new(Style::random(4)), Sequence::new(Style::random(5)));
        assert_ne!(a.render_frame(0).as_bytes(), b.render_frame(0).as_bytes());
    }

    /// A line 2 px wide at half the contrast: its middle pixel between two particles is
    /// lifted by half the contrast, a pixel 3 px beside it not at all; drawn styles have none.
    #[test]
    fn lines_join_consecutive_particles_beneath_them() {
        let mut style = Style::random(4);
        assert!(style.lines.is_none());
        style.noise = 0.0;
        style.blur = 0.0;
        style.gradient = 0.0;
        style.vignetting = 0.0;
        style.exposure = 0.0;
        style.colour = false;
        style.particle_count = 2;
        style.mixed = false;
        style.lines = Some(Lines {
            width: 2.0,
            level: 0.5,
        });
        let seq = Sequence::new(style);
        let s = &seq.style;
        let [a, b] = [seq.truth.positions[0][0], seq.truth.positions[0][1]];
        let image = seq.render_frame(0).to_luma8();
        let level = |x: f64, y: f64| f64::from(image.get_pixel(x.round() as u32, y.round() as u32)[0]);
        let (mx, my) = (0.5 * (a[0] + b[0]), 0.5 * (a[1] + b[1]));
        let contrast = s.foreground[0] - s.background[0];
        // Nearest pixel centre to the midpoint: within 0.71 px of the line's axis, so at least
        // a quarter of it covered.
        let lifted = level(mx, my) - s.background[0];
        assert!(
            lifted.abs() >= 0.125 * contrast.abs() && lifted * contrast > 0.0,
            "{lifted} of {contrast}"
        );
        // 3 px aside, across the line.
        let len = (b[0] - a[0]).hypot(b[1] - a[1]);
        let (nx, ny) = (-(b[1] - a[1]) / len, (b[0] - a[0]) / len);
        let aside = level(mx + 3.0 * nx, my + 3.0 * ny) - s.background[0];
        assert!(aside.abs() <= 1.0, "{aside}");
    }

    #[test]
    fn paths_keep_apart_inside_the_frame_and_under_the_speed() {
        for seed in 0..80 {
            let seq = Sequence::new(Style::random(seed));
            let s = &seq.style;
            let radii = s.radii();
            let (w, h) = (f64::from(s.width), f64::from(s.height));
            for (k, frame) in seq.truth.positions.iter().enumerate() {
                for (i, p) in frame.iter().enumerate() {
                    let m = s.margin(radii[i]) - 1e-9;
                    assert!(
                        p[0] >= m && p[1] >= m && p[0] <= w - 1.0 - m && p[1] <= h - 1.0 - m,
                        "{s}: frame {k} particle {i} at {p:?}"
                    );
                    for (j, q) in frame.iter().enumerate().skip(i + 1) {
                        let d = (p[0] - q[0]).hypot(p[1] - q[1]);
                        assert!(d >= s.separation(radii[i], radii[j]) - 1e-9, "{s}: {d}");
                    }
                    if k > 0 {
                        let o = seq.truth.positions[k - 1][i];
                        assert!((p[0] - o[0]).hypot(p[1] - o[1]) <= s.speed + 1e-9);
                    }
                }
            }
        }
    }
}
