//! `physfit bench render`: frames per second of the renderer, drawing only and drawing plus
//! PNG encoding, on one thread and with rayon over frames.

use std::time::{Duration, Instant};

use image::DynamicImage;
use physfit_model::{RenderSettings, Vec2};
use physfit_render::{encode_png, render_frame_mut, RenderScratch};
use rayon::prelude::*;

/// Frame size of every case, px.
const SIZE: u32 = 512;
/// Seed of the scattered positions.
const POSITION_SEED: u64 = 0x5eed;

/// Positions of `count` particles scattered uniformly over the frame (splitmix64 from a fixed
/// seed, so every run draws the same frames), with a 10 px margin.
fn scatter(count: usize) -> Vec<Vec2> {
    let mut state = POSITION_SEED;
    let mut uniform = move || {
        state = state.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = state;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^= z >> 31;
        (z >> 11) as f64 / (1u64 << 53) as f64
    };
    let span = SIZE as f64 - 20.0;
    (0..count)
        .map(|_| Vec2::new(10.0 + span * uniform(), 10.0 + span * uniform()))
        .collect()
}

/// The positions of frame `k`: the scatter drifted by a sub-pixel step per frame, so every
/// frame differs as in a real recording.
fn drifted(base: &[Vec2], k: usize, out: &mut Vec<Vec2>) {
    let shift = Vec2::new(0.37 * k as f64 % 5.0, 0.21 * k as f64 % 5.0);
    out.clear();
    out.extend(base.iter().map(|p| p + shift));
}

/// Draws (and with `encode`, PNG-encodes) frames `0..frames`; returns the total PNG bytes.
fn draw_frames(
    base: &[Vec2],
    settings: &RenderSettings,
    frames: std::ops::Range<usize>,
    encode: bool,
) -> anyhow::Result<usize> {
    let mut scratch = RenderScratch::new();
    let mut image = DynamicImage::new_luma8(0, 0);
    let mut positions = Vec::with_capacity(base.len());
    let mut bytes = 0;
    for k in frames {
        drifted(base, k, &mut positions);
        render_frame_mut(&positions, settings, k, &mut scratch, &mut image);
        if encode {
            bytes += encode_png(&image)?.len();
        }
    }
    Ok(bytes)
}

/// Times `frames` frames; with `parallel`, frames are shared out over the rayon pool in chunks
/// (each chunk reuses its buffers, as `render_sequence` does per thread).
fn time_case(
    base: &[Vec2],
    settings: &RenderSettings,
    frames: usize,
    encode: bool,
    parallel: bool,
) -> anyhow::Result<Duration> {
    // One untimed frame warms caches and sizes the buffers.
    draw_frames(base, settings, 0..1, encode)?;
    let start = Instant::now();
    if parallel {
        let chunk = frames.div_ceil(rayon::current_num_threads() * 4).max(1);
        (0..frames.div_ceil(chunk)).into_par_iter().try_for_each(|c| {
            draw_frames(base, settings, c * chunk..((c + 1) * chunk).min(frames), encode).map(|_| ())
        })?;
    } else {
        draw_frames(base, settings, 0..frames, encode)?;
    }
    Ok(start.elapsed())
}

/// Runs the renderer benchmark and returns a Markdown table of frames per second. `quick`
/// draws few frames (about a second in all); otherwise enough for stable figures.
pub fn run(quick: bool) -> anyhow::Result<String> {
    let settings = RenderSettings {
        width: SIZE,
        height: SIZE,
        radius: 4.5,
        noise: 2.0,
        ..RenderSettings::default()
    };
    let threads = rayon::current_num_threads();
    let mut out = String::new();
    out.push_str(&format!(
        "### Renderer: {SIZE}x{SIZE} grey frames, radius {} px, noise sigma {} grey levels, rayon threads {threads}\n\n",
        settings.radius, settings.noise
    ));
    out.push_str("| particles | stage | threads | frames | time (s) | frames/s |\n");
    out.push_str("|---:|---|---:|---:|---:|---:|\n");
    for count in [8usize, 1000] {
        let base = scatter(count);
        for (encode, stage) in [(false, "render"), (true, "render + PNG")] {
            for parallel in [false, true] {
                let frames = match (quick, encode) {
                    (true, false) => 40,
                    (true, true) => 20,
                    (false, false) => 200,
                    (false, true) => 100,
                };
                let elapsed = time_case(&base, &settings, frames, encode, parallel)?;
                let secs = elapsed.as_secs_f64();
                out.push_str(&format!(
                    "| {count} | {stage} | {} | {frames} | {secs:.3} | {:.1} |\n",
                    if parallel {
                        threads.to_string()
                    } else {
                        "1".to_string()
                    },
                    frames as f64 / secs.max(1e-9),
                ));
            }
        }
    }
    Ok(out)
}
