//! `physfit bench track`: end-to-end tracking speed (PNG decode, detect, locate, link) and
//! localisation accuracy on the benchmark frames, next to trackpy 0.7's figures.
//!
//! Frames are 512x512 8-bit grey, anti-aliased discs of radius 4 px and amplitude 200 over
//! a background of 30, each particle stepping up to 3 px per frame in a random direction.
//! They are rendered once per case into a folder under the system temp dir (removed after).

use std::path::Path;
use std::time::Instant;

use anyhow::Context;
use physfit_model::{Colour, Recording, RenderSettings, Vec2};
use physfit_render::render_sequence;
use physfit_track::{list_frames, score_tracks, track_folder, Frame, FrameDecoder, TrackOptions};
use physfit_tracks::{TrackPoint, TrackTable};

use super::Scratch;

/// Frame size, px.
const SIZE: u32 = 512;
/// trackpy 0.7 end-to-end frames/s at 10, 100 and 1000 particles (from the issue).
const TRACKPY_FPS: [(usize, f64); 3] = [(10, 90.0), (100, 70.0), (1000, 21.0)];
/// trackpy 0.7 RMS localisation error per axis at noise 0, 5 and 20 grey levels, px.
const TRACKPY_RMS: [(f64, f64); 3] = [(0.0, 0.004), (5.0, 0.014), (20.0, 0.05)];

/// Uniform numbers in [0, 1) from splitmix64 (fixed seeds: every run draws the same frames).
struct Uniform(u64);

impl Uniform {
    fn next(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^= z >> 31;
        (z >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// Random walks: `start` positions stepping up to 3 px per frame, reflected to stay within
/// `[lo, hi]` on each axis (per particle), for `frames` frames.
fn walk(start: Vec<Vec2>, bounds: &[(Vec2, Vec2)], frames: usize, seed: u64) -> Recording {
    let mut rng = Uniform(seed);
    let n = start.len();
    let mut pos = start;
    let mut positions = Vec::with_capacity(n * frames);
    positions.extend_from_slice(&pos);
    for _ in 1..frames {
        for (p, (lo, hi)) in pos.iter_mut().zip(bounds) {
            let len = 3.0 * rng.next();
            let a = std::f64::consts::TAU * rng.next();
            let mut q = *p + len * Vec2::new(a.cos(), a.sin());
            for k in 0..2 {
                if q[k] < lo[k] {
                    q[k] = 2.0 * lo[k] - q[k];
                }
                if q[k] > hi[k] {
                    q[k] = 2.0 * hi[k] - q[k];
                }
            }
            *p = q;
        }
        positions.extend_from_slice(&pos);
    }
    Recording {
        particle_count: n,
        velocities: vec![Vec2::zeros(); positions.len()],
        positions,
    }
}

/// `count` particles anywhere in the frame (they may overlap), 8 px from the edges.
fn scattered(count: usize, frames: usize) -> Recording {
    let mut rng = Uniform(0x5eed + count as u64);
    let (lo, hi) = (8.0, SIZE as f64 - 9.0);
    let start: Vec<Vec2> = (0..count)
        .map(|_| Vec2::new(lo + (hi - lo) * rng.next(), lo + (hi - lo) * rng.next()))
        .collect();
    let bounds = vec![(Vec2::new(lo, lo), Vec2::new(hi, hi)); count];
    walk(start, &bounds, frames, 7 + count as u64)
}

/// 100 isolated particles, one per cell of a 10x10 grid, each kept 10 px inside its cell.
fn isolated(frames: usize) -> Recording {
    caged(100, frames, 0xacc)
}

/// `count` particles, one per cell of the smallest square grid that holds them (filled row
/// by row), each kept inside its cell by 10 px or, in cells under 26 px, by 3 px less than
/// half the cell: discs of radius 4 px in neighbouring cells stay 2 px apart at least, so
/// that every particle can be followed under its own name.
fn caged(count: usize, frames: usize, seed: u64) -> Recording {
    let side = (count as f64).sqrt().ceil().max(1.0) as usize;
    let cell = SIZE as f64 / side as f64;
    let inset = (0.5 * cell - 3.0).min(10.0);
    let mut rng = Uniform(seed);
    let mut start = Vec::new();
    let mut bounds = Vec::new();
    for i in 0..count {
        let (r, c) = (i / side, i % side);
        let lo = Vec2::new(c as f64 * cell + inset, r as f64 * cell + inset);
        let hi = lo + Vec2::new(cell - 2.0 * inset, cell - 2.0 * inset);
        start.push(lo + Vec2::new((hi.x - lo.x) * rng.next(), (hi.y - lo.y) * rng.next()));
        bounds.push((lo, hi));
    }
    walk(start, &bounds, frames, seed)
}

fn settings(noise: f64) -> RenderSettings {
    RenderSettings {
        width: SIZE,
        height: SIZE,
        radius: 4.0,
        background: Colour::Grey(30),
        foreground: Colour::Grey(230),
        noise,
        blur: 0.0,
        seed: 1,
    }
}

fn render(rec: &Recording, noise: f64, dir: &Path) -> anyhow::Result<()> {
    render_sequence(rec, &settings(noise), dir, &|_| {})
        .with_context(|| format!("rendering into {}", dir.display()))
}

fn truth_table(rec: &Recording) -> TrackTable {
    let mut points = Vec::new();
    for k in 0..rec.frame_count() {
        for (i, p) in rec.frame(k).iter().enumerate() {
            points.push(TrackPoint::new(k, format!("p{i}"), p.x, p.y));
        }
    }
    TrackTable { points }
}

/// Seconds to decode every frame of `dir` on one thread (read, PNG decode, to f32).
fn decode_seconds(dir: &Path) -> anyhow::Result<f64> {
    let files = list_frames(dir)?;
    // With reused buffers, as the tracker decodes.
    let (mut decoder, mut frame) = (FrameDecoder::default(), Frame::default());
    let start = Instant::now();
    for f in &files {
        decoder.load_into(f, &mut frame)?;
        std::hint::black_box(&frame);
    }
    Ok(start.elapsed().as_secs_f64())
}

/// Seconds to track `dir` end to end with `threads` worker threads, following only the
/// `named` particles (name and position in the first frame, px) when given.
fn track_seconds(
    dir: &Path,
    threads: usize,
    named: Option<&[(String, [f64; 2])]>,
) -> anyhow::Result<(f64, usize)> {
    let options = TrackOptions {
        threads: Some(threads),
        named_start: named.map(<[_]>::to_vec),
        ..TrackOptions::default()
    };
    let start = Instant::now();
    let out = track_folder(dir, &options, &|_, _| {})?;
    Ok((start.elapsed().as_secs_f64(), out.table.points.len()))
}

/// Timed runs per figure of the speed table (the fastest counts).
const REPEATS: usize = 3;

/// The fastest of [`REPEATS`] runs of `seconds`: on a shared machine a run is only ever
/// slowed by the others' work, so the fastest of a few is the closest to the code's own
/// speed.
fn best_of(seconds: &dyn Fn() -> anyhow::Result<f64>) -> anyhow::Result<f64> {
    (0..REPEATS).try_fold(f64::INFINITY, |b, _| Ok(b.min(seconds()?)))
}

/// Runs the tracking benchmark and returns Markdown tables: frames/s for 10, 100 and 1000
/// particles (decode only, end to end on one and two threads) and RMS error per axis at
/// noise 0, 5 and 20, each beside trackpy 0.7's figure. `quick` uses few frames.
pub fn run(quick: bool) -> anyhow::Result<String> {
    let frames = if quick { 30 } else { 200 };
    let fps = |s: f64| frames as f64 / s.max(1e-9);
    let mut out = String::new();
    out.push_str(&format!(
        "### Tracker: {SIZE}x{SIZE} 8-bit PNG frames, discs of radius 4 px, amplitude 200 over 30, random walks up to 3 px/frame, noise sigma 5\n\n"
    ));
    out.push_str(&format!("Each time is the best of {REPEATS} runs.\n\n"));
    out.push_str("| particles | frames | decode only (frames/s, 1 thread) | physfit end to end, 1 thread | physfit, 2 threads | trackpy 0.7 | physfit / trackpy (1 thread) | decode share (1 thread) |\n");
    out.push_str("|---:|---:|---:|---:|---:|---:|---:|---:|\n");
    for (count, trackpy) in TRACKPY_FPS {
        let dir = Scratch::new(&format!("track-n{count}"))?;
        render(&scattered(count, frames), 5.0, &dir.0)?;
        // One untimed run warms the file cache, then the timed runs, each the best of
        // REPEATS.
        track_seconds(&dir.0, 1, None)?;
        let decode = best_of(&|| decode_seconds(&dir.0))?;
        let one = best_of(&|| Ok(track_seconds(&dir.0, 1, None)?.0))?;
        let two = best_of(&|| Ok(track_seconds(&dir.0, 2, None)?.0))?;
        out.push_str(&format!(
            "| {count} | {frames} | {:.0} | {:.0} | {:.0} | {trackpy:.0} | {:.1}x | {:.0} % |\n",
            fps(decode),
            fps(one),
            fps(two),
            fps(one) / trackpy,
            100.0 * decode / one
        ));
    }
    out.push_str(
        "\n### Named tracking: every particle named from its first position (as `--structure` does), walks kept apart in a grid of cells, noise sigma 5, one thread\n\n",
    );
    out.push_str("| particles | frames | unnamed (frames/s) | named (frames/s) | named / unnamed time |\n");
    out.push_str("|---:|---:|---:|---:|---:|\n");
    for (count, _) in TRACKPY_FPS {
        let dir = Scratch::new(&format!("track-named{count}"))?;
        let rec = caged(count, frames, 0xca6e + count as u64);
        render(&rec, 5.0, &dir.0)?;
        let named: Vec<(String, [f64; 2])> = rec
            .frame(0)
            .iter()
            .enumerate()
            .map(|(i, p)| (format!("p{i}"), [p.x, p.y]))
            .collect();
        track_seconds(&dir.0, 1, Some(&named))?;
        let unnamed = best_of(&|| Ok(track_seconds(&dir.0, 1, None)?.0))?;
        let with_names = best_of(&|| Ok(track_seconds(&dir.0, 1, Some(&named))?.0))?;
        out.push_str(&format!(
            "| {count} | {frames} | {:.0} | {:.0} | {:.2} |\n",
            fps(unnamed),
            fps(with_names),
            with_names / unnamed
        ));
    }
    let acc_frames = if quick { 10 } else { 40 };
    out.push_str(&format!(
        "\n### Localisation: 100 isolated discs (radius 4 px, amplitude 200 over 30), {acc_frames} frames, default options\n\n"
    ));
    out.push_str("| noise sigma (grey levels) | RMS x (px) | RMS y (px) | median ep (px) | trackpy 0.7 RMS (px) | recall | identity switches |\n");
    out.push_str("|---:|---:|---:|---:|---:|---:|---:|\n");
    let rec = isolated(acc_frames);
    let truth = truth_table(&rec);
    for (noise, trackpy) in TRACKPY_RMS {
        let dir = Scratch::new(&format!("track-rms{noise}"))?;
        render(&rec, noise, &dir.0)?;
        let t = track_folder(&dir.0, &TrackOptions::default(), &|_, _| {})?;
        let s = score_tracks(&t.table, &truth, t.stats.radius);
        out.push_str(&format!(
            "| {noise} | {:.4} | {:.4} | {:.4} | {trackpy} | {:.4} | {} |\n",
            s.rms_x, s.rms_y, t.stats.median_ep, s.recall, s.id_switches
        ));
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The named-tracking frames keep discs of radius 4 px 2 px apart at least in every frame,
    /// inside the frame, at every count the bench draws.
    #[test]
    fn caged_walks_keep_apart() {
        for (count, _) in TRACKPY_FPS {
            let rec = caged(count, 30, 0xca6e + count as u64);
            for k in 0..rec.frame_count() {
                let at = rec.frame(k);
                assert_eq!(at.len(), count);
                for (i, p) in at.iter().enumerate() {
                    assert!(
                        (4.0..=SIZE as f64 - 5.0).contains(&p.x) && (4.0..=SIZE as f64 - 5.0).contains(&p.y),
                        "count {count}, frame {k}: particle {i} at {p:?}"
                    );
                    for q in &at[i + 1..] {
                        assert!(
                            (p - q).norm() >= 10.0,
                            "count {count}, frame {k}: {p:?} and {q:?}"
                        );
                    }
                }
            }
        }
    }
}
