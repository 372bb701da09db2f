//! Drawing one frame: discs, blur, noise, quantisation.

use image::DynamicImage;
use physfit_model::{Colour, RenderSettings, Vec2};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;

use crate::blur::{blur_plane, gaussian_kernel};
use crate::coverage::add_disc;

/// Reusable buffers for [`render_frame_mut`]: a coverage plane, a blur buffer and the cached
/// blur kernel. One per thread lets frames be drawn with no allocation after the first.
#[derive(Clone, Debug, Default)]
pub struct RenderScratch {
    coverage: Vec<f32>,
    blur: Vec<f32>,
    kernel: Vec<f32>,
    kernel_sigma: f64,
}

impl RenderScratch {
    /// Empty buffers; they grow to the frame size on first use.
    pub fn new() -> Self {
        Self::default()
    }
}

/// Returns true if and only if frames drawn with `settings` are grey (both colours grey), in
/// which case they are `Luma8`; otherwise they are `Rgb8`.
pub fn is_grey(settings: &RenderSettings) -> bool {
    matches!(
        (settings.background, settings.foreground),
        (Colour::Grey(_), Colour::Grey(_))
    )
}

/// Draws one frame: a disc of radius `settings.radius` px at each position (px; pixel centres
/// at integer coordinates, x right, y down), in `settings.foreground` over
/// `settings.background`, anti-aliased by exact area coverage; then a Gaussian blur of standard
/// deviation `settings.blur` px; then additive Gaussian noise of standard deviation
/// `settings.noise` grey levels, independent per pixel and channel; rounded and clamped to
/// 0..255.
///
/// Overlapping discs combine as a union (coverage never exceeds full foreground). Discs partly
/// or wholly outside the image are clipped; non-finite positions draw nothing. The noise comes
/// from `settings.seed` and `frame_index` only (one ChaCha8 stream per frame), so frames can be
/// drawn in any order or in parallel and come out identical for a seed.
///
/// The image is `Luma8` when both colours are [`Colour::Grey`], `Rgb8` otherwise.
#[must_use]
pub fn render_frame(positions: &[Vec2], settings: &RenderSettings, frame_index: usize) -> DynamicImage {
    let mut image = DynamicImage::new_luma8(0, 0);
    render_frame_mut(
        positions,
        settings,
        frame_index,
        &mut RenderScratch::new(),
        &mut image,
    );
    image
}

/// As [`render_frame`], drawing into `image` (replaced if its size or pixel type is wrong) with
/// the caller's `scratch`, so a loop over frames allocates nothing after the first frame.
pub fn render_frame_mut(
    positions: &[Vec2],
    settings: &RenderSettings,
    frame_index: usize,
    scratch: &mut RenderScratch,
    image: &mut DynamicImage,
) {
    let (w, h) = (settings.width, settings.height);
    let n = w as usize * h as usize;
    scratch.coverage.clear();
    scratch.coverage.resize(n, 0.0);
    for &p in positions {
        add_disc(&mut scratch.coverage, w, h, p, settings.radius);
    }
    // Blur is linear and keeps constants, so blurring the coverage plane is the same as
    // blurring the composited image, for a third of the work in colour.
    if settings.blur > 0.0 && settings.blur.is_finite() && n > 0 {
        if (scratch.kernel_sigma - settings.blur).abs() > 0.0 || scratch.kernel.is_empty() {
            scratch.kernel = gaussian_kernel(settings.blur);
            scratch.kernel_sigma = settings.blur;
        }
        blur_plane(
            &mut scratch.coverage,
            w as usize,
            h as usize,
            &scratch.kernel,
            &mut scratch.blur,
        );
    }

    let grey = is_grey(settings);
    let fits = image.width() == w
        && image.height() == h
        && matches!(
            (grey, &*image),
            (true, DynamicImage::ImageLuma8(_)) | (false, DynamicImage::ImageRgb8(_))
        );
    if !fits {
        *image = if grey {
            DynamicImage::new_luma8(w, h)
        } else {
            DynamicImage::new_rgb8(w, h)
        };
    }
    let (bytes, channels): (&mut [u8], usize) = match image {
        DynamicImage::ImageLuma8(buf) => (buf, 1),
        DynamicImage::ImageRgb8(buf) => (buf, 3),
        // `fits` above guarantees one of the two variants.
        _ => return,
    };
    let bg = settings.background.rgb().map(f32::from);
    let fg = settings.foreground.rgb().map(f32::from);
    let diff = [fg[0] - bg[0], fg[1] - bg[1], fg[2] - bg[2]];
    let quantise = |v: f32| v.round().clamp(0.0, 255.0) as u8;

    let sigma = settings.noise;
    if sigma > 0.0 && sigma.is_finite() {
        let mut rng = ChaCha8Rng::seed_from_u64(settings.seed);
        rng.set_stream(frame_index as u64);
        let sigma = sigma as f32;
        for (px, &c) in bytes.chunks_exact_mut(channels).zip(&scratch.coverage) {
            for (ch, out) in px.iter_mut().enumerate() {
                let z: f32 = rng.sample(StandardNormal);
                *out = quantise(bg[ch] + diff[ch] * c + sigma * z);
            }
        }
    } else {
        for (px, &c) in bytes.chunks_exact_mut(channels).zip(&scratch.coverage) {
            for (ch, out) in px.iter_mut().enumerate() {
                *out = quantise(bg[ch] + diff[ch] * c);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    fn settings(width: u32, height: u32) -> RenderSettings {
        RenderSettings {
            width,
            height,
            ..RenderSettings::default()
        }
    }

    /// Intensity-weighted centroid of a grey image above `background`, px.
    fn centroid(image: &DynamicImage, background: f64) -> Vec2 {
        let grey = image.as_luma8().expect("grey frame");
        let (mut sx, mut sy, mut s) = (0.0, 0.0, 0.0);
        for (x, y, p) in grey.enumerate_pixels() {
            let v = (p[0] as f64 - background).abs();
            sx += v * x as f64;
            sy += v * y as f64;
            s += v;
        }
        Vec2::new(sx / s, sy / s)
    }

    #[test]
    fn centroid_of_an_isolated_disc_is_its_position() {
        let mut rng = ChaCha8Rng::seed_from_u64(11);
        let mut worst: f64 = 0.0;
        for _ in 0..300 {
            let radius = rng.gen_range(3.0..=8.0);
            let mut s = settings(48, 40);
            s.radius = radius;
            let p = Vec2::new(rng.gen_range(18.0..30.0), rng.gen_range(16.0..24.0));
            let err = (centroid(&render_frame(&[p], &s, 0), 0.0) - p).abs().max();
            worst = worst.max(err);
            assert!(err < 0.01, "radius {radius} at {p:?}: centroid off by {err} px");
        }
        // Blur is symmetric, so it keeps the centroid too (dark on light this time).
        let mut s = settings(48, 48);
        s.blur = 1.3;
        s.background = Colour::Grey(220);
        s.foreground = Colour::Grey(30);
        let p = Vec2::new(23.37, 24.81);
        let err = (centroid(&render_frame(&[p], &s, 0), 220.0) - p).abs().max();
        assert!(
            err < 0.01,
            "blurred centroid off by {err} px (worst sharp {worst})"
        );
    }

    #[test]
    fn dark_on_light_and_colour_frames_have_the_right_values() {
        let p = [Vec2::new(30.0, 20.0)];
        let mut s = settings(64, 48);
        s.background = Colour::Grey(230);
        s.foreground = Colour::Grey(20);
        let img = render_frame(&p, &s, 0);
        let grey = img.as_luma8().expect("two greys give Luma8");
        assert_eq!(grey.get_pixel(30, 20)[0], 20);
        assert_eq!(grey.get_pixel(60, 45)[0], 230);
        // Half-covered edge pixel: the disc edge passes through its centre.
        assert!(
            (grey.get_pixel(35, 20)[0] as f64 - 125.0).abs() < 8.0,
            "edge {}",
            grey.get_pixel(35, 20)[0]
        );

        s.background = Colour::Rgb([10, 20, 30]);
        s.foreground = Colour::Rgb([200, 100, 50]);
        let img = render_frame(&p, &s, 0);
        let rgb = img.as_rgb8().expect("colour gives Rgb8");
        assert_eq!(rgb.get_pixel(30, 20).0, [200, 100, 50]);
        assert_eq!(rgb.get_pixel(2, 2).0, [10, 20, 30]);

        s.background = Colour::Grey(0);
        s.foreground = Colour::Rgb([0, 255, 0]);
        let img = render_frame(&p, &s, 0);
        let rgb = img.as_rgb8().expect("grey and colour give Rgb8");
        assert_eq!(rgb.get_pixel(30, 20).0, [0, 255, 0]);
        assert_eq!(rgb.get_pixel(2, 2).0, [0, 0, 0]);
    }

    #[test]
    fn overlapping_discs_never_exceed_the_foreground() {
        let mut s = settings(40, 40);
        s.foreground = Colour::Grey(100);
        s.radius = 6.0;
        let img = render_frame(
            &[
                Vec2::new(18.0, 20.0),
                Vec2::new(22.3, 20.4),
                Vec2::new(18.0, 20.0),
            ],
            &s,
            0,
        );
        let grey = img.as_luma8().expect("grey");
        assert_eq!(grey.pixels().map(|p| p[0]).max(), Some(100));
        assert_eq!(grey.get_pixel(20, 20)[0], 100);
    }

    #[test]
    fn discs_outside_the_frame_are_clipped() {
        let s = settings(32, 32);
        let img = render_frame(&[Vec2::new(-100.0, 5.0), Vec2::new(f64::INFINITY, 3.0)], &s, 0);
        assert!(img.as_luma8().expect("grey").pixels().all(|p| p[0] == 0));
        let img = render_frame(&[Vec2::new(0.0, 31.0)], &s, 0);
        let grey = img.as_luma8().expect("grey");
        assert_eq!(grey.get_pixel(0, 31)[0], 255);
        assert_eq!(grey.get_pixel(10, 10)[0], 0);
    }

    #[test]
    fn noise_is_seeded_per_frame() {
        let mut s = settings(64, 64);
        s.noise = 5.0;
        s.background = Colour::Grey(100);
        let p = [Vec2::new(20.5, 30.25)];
        let a = render_frame(&p, &s, 3);
        assert_eq!(a.as_bytes(), render_frame(&p, &s, 3).as_bytes());
        assert_ne!(a.as_bytes(), render_frame(&p, &s, 4).as_bytes());
        s.seed += 1;
        assert_ne!(a.as_bytes(), render_frame(&p, &s, 3).as_bytes());
        // Reused buffers give the same bytes.
        s.seed -= 1;
        let (mut scratch, mut image) = (RenderScratch::new(), DynamicImage::new_rgb8(3, 3));
        render_frame_mut(&p, &s, 9, &mut scratch, &mut image);
        render_frame_mut(&p, &s, 3, &mut scratch, &mut image);
        assert_eq!(a.as_bytes(), image.as_bytes());
    }

    #[test]
    fn noise_has_the_set_standard_deviation() {
        for (background, foreground) in [
            (Colour::Grey(128), Colour::Grey(255)),
            (Colour::Rgb([120, 128, 136]), Colour::Grey(0)),
        ] {
            let mut s = settings(256, 256);
            s.noise = 6.0;
            s.background = background;
            s.foreground = foreground;
            let img = render_frame(&[], &s, 0);
            let bg = background.rgb();
            let channels = if is_grey(&s) { 1 } else { 3 };
            let (mut sum, mut sum2, mut n) = (0.0, 0.0, 0.0);
            for (k, &b) in img.as_bytes().iter().enumerate() {
                let d = b as f64 - bg[k % channels] as f64;
                sum += d;
                sum2 += d * d;
                n += 1.0;
            }
            let mean = sum / n;
            let sd = (sum2 / n - mean * mean).sqrt();
            // Rounding to integers adds 1/12 grey level² of variance.
            let expected = (s.noise * s.noise + 1.0 / 12.0).sqrt();
            assert!(mean.abs() < 0.1, "mean offset {mean}");
            assert!(
                (sd / expected - 1.0).abs() < 0.05,
                "measured sigma {sd}, set {}",
                s.noise
            );
        }
    }

    #[test]
    fn blur_preserves_total_intensity() {
        let mut s = settings(64, 64);
        s.background = Colour::Grey(40);
        s.foreground = Colour::Grey(240);
        s.radius = 4.5;
        let p = [Vec2::new(31.2, 30.7)];
        let total = |img: &DynamicImage| img.as_bytes().iter().map(|&b| b as f64 - 40.0).sum::<f64>();
        let sharp = render_frame(&p, &s, 0);
        s.blur = 2.0;
        let blurred = render_frame(&p, &s, 0);
        let (a, b) = (total(&sharp), total(&blurred));
        assert!((b / a - 1.0).abs() < 0.01, "total {a} before blur, {b} after");
        let expected = 200.0 * std::f64::consts::PI * 4.5 * 4.5;
        assert!(
            (a / expected - 1.0).abs() < 0.01,
            "total {a}, disc area x contrast {expected}"
        );
        // And it does blur: the peak drops.
        let peak = |img: &DynamicImage| img.as_bytes().iter().copied().max().unwrap_or(0);
        assert!(peak(&blurred) < peak(&sharp));
    }

    #[test]
    fn coverage_agrees_with_tiny_skia() {
        use crate::pixel::to_tiny_skia;
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        for _ in 0..20 {
            let radius = rng.gen_range(3.0..8.0);
            let p = Vec2::new(rng.gen_range(14.0..18.0), rng.gen_range(14.0..18.0));
            let mut s = settings(32, 32);
            s.radius = radius;
            let ours = render_frame(&[p], &s, 0);
            let mut pixmap = tiny_skia::Pixmap::new(32, 32).expect("non-zero size");
            let mut paint = tiny_skia::Paint::default();
            paint.set_color_rgba8(255, 255, 255, 255);
            paint.anti_alias = true;
            let (cx, cy) = to_tiny_skia(p);
            let circle = tiny_skia::PathBuilder::from_circle(cx, cy, radius as f32).expect("valid circle");
            pixmap.fill_path(
                &circle,
                &paint,
                tiny_skia::FillRule::Winding,
                tiny_skia::Transform::identity(),
                None,
            );
            let (mut worst, mut ours_total, mut theirs_total) = (0i32, 0.0, 0.0);
            for (k, &v) in ours.as_bytes().iter().enumerate() {
                let theirs = pixmap.pixels()[k].alpha() as i32;
                worst = worst.max((v as i32 - theirs).abs());
                ours_total += v as f64;
                theirs_total += theirs as f64;
            }
            // tiny-skia's 4x supersampling quantises an edge pixel's coverage to steps of about
            // 1/16 along x and 1/4 along y: allow a quarter of full scale per pixel.
            assert!(
                worst <= 64,
                "radius {radius} at {p:?}: {worst} grey levels from tiny-skia"
            );
            // tiny-skia flattens the circle into chords, which lose up to a few percent of area
            // on small discs; ours is exact (checked in `coverage`).
            assert!(
                (ours_total / theirs_total - 1.0).abs() < 0.03,
                "{ours_total} vs {theirs_total}"
            );
        }
    }
}
