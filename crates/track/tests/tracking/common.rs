//! Shared helpers: temporary folders, rendering position sequences to PNG frames, truth
//! tables, and running the tracker.

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};

use physfit_model::{write_atomic, Colour, Recording, RenderSettings, Scene, Vec2};
use physfit_render::{encode_png, frame_file_name, render_frame, render_sequence};
use physfit_track::{
    score_tracks, track_folder, TrackOptions, TrackOutcome, TrackPoint, TrackScore, TrackTable,
};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// A folder under the system temp dir, removed when dropped.
pub struct TempDir(pub PathBuf);

impl TempDir {
    /// A fresh, empty folder whose name contains `label`.
    pub fn new(label: &str) -> TempDir {
        static COUNT: AtomicUsize = AtomicUsize::new(0);
        let n = COUNT.fetch_add(1, Ordering::Relaxed);
        let dir = std::env::temp_dir().join(format!("physfit-track-it-{}-{n}-{label}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).expect("create temp dir");
        TempDir(dir)
    }

    /// The folder.
    pub fn path(&self) -> &Path {
        &self.0
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// Positions per frame (frame-major), with particle names.
pub struct Truth {
    /// Particle names.
    pub names: Vec<String>,
    /// `frames[k][i]`: position of particle `i` in frame `k`, px.
    pub frames: Vec<Vec<Vec2>>,
}

impl Truth {
    /// Truth from a simulated recording, first `frames` frames.
    pub fn from_recording(names: Vec<String>, rec: &Recording, frames: usize) -> Truth {
        Truth {
            names,
            frames: (0..frames.min(rec.frame_count()))
                .map(|k| rec.frame(k).to_vec())
                .collect(),
        }
    }

    /// The recording holding these positions (velocities zero: the renderer ignores them).
    pub fn recording(&self) -> Recording {
        let n = self.names.len();
        let positions: Vec<Vec2> = self.frames.iter().flatten().copied().collect();
        Recording {
            particle_count: n,
            velocities: vec![Vec2::zeros(); positions.len()],
            positions,
        }
    }

    /// The truth as a track table; frame `k` of the table is `frames[index[k]]` (so a
    /// deleted frame file can be skipped), particles inside the image only.
    pub fn table_for(&self, index: &[usize], width: u32, height: u32) -> TrackTable {
        let mut points = Vec::new();
        for (k, &src) in index.iter().enumerate() {
            for (name, p) in self.names.iter().zip(&self.frames[src]) {
                if inside(*p, width, height, 0.0) {
                    points.push(TrackPoint::new(k, name.clone(), p.x, p.y));
                }
            }
        }
        TrackTable { points }
    }

    /// The truth of every frame as a track table.
    pub fn table(&self, width: u32, height: u32) -> TrackTable {
        let index: Vec<usize> = (0..self.frames.len()).collect();
        self.table_for(&index, width, height)
    }

    /// Named start positions: every particle at its frame-0 position.
    pub fn named_start(&self) -> Vec<(String, [f64; 2])> {
        self.names
            .iter()
            .zip(&self.frames[0])
            .map(|(n, p)| (n.clone(), [p.x, p.y]))
            .collect()
    }
}

/// Returns true if and only if `p` lies at least `margin` px inside the image.
pub fn inside(p: Vec2, width: u32, height: u32, margin: f64) -> bool {
    p.x >= margin
        && p.y >= margin
        && p.x <= f64::from(width) - 1.0 - margin
        && p.y <= f64::from(height) - 1.0 - margin
}

/// Renders `truth` into `dir` as `000000.png`, ... (in parallel).
pub fn render_to(truth: &Truth, settings: &RenderSettings, dir: &Path) {
    render_sequence(&truth.recording(), settings, dir, &|_| {}).expect("render frames");
}

/// Writes one frame with the given positions as `dir/name`.
pub fn write_frame(positions: &[Vec2], settings: &RenderSettings, frame_index: usize, path: &Path) {
    let img = render_frame(positions, settings, frame_index);
    write_atomic(path, &encode_png(&img).expect("encode")).expect("write frame");
}

/// The path of frame `k` in `dir`.
pub fn frame_path(dir: &Path, k: usize) -> PathBuf {
    dir.join(frame_file_name(k))
}

/// Tracks `dir` with `options`.
pub fn track(dir: &Path, options: &TrackOptions) -> TrackOutcome {
    track_folder(dir, options, &|_, _| {})
        .unwrap_or_else(|e| panic!("tracking {} failed: {e}", dir.display()))
}

/// How many of an outcome's warnings say a track's positions jump about (the hopping check).
pub fn said_to_jump_about(outcome: &TrackOutcome) -> usize {
    outcome
        .warnings
        .iter()
        .filter(|w| w.contains("positions jump about"))
        .count()
}

/// Scores an outcome against a truth table; a point farther than the particle radius from a
/// true centre is on another particle or none, so it never matches.
pub fn score(outcome: &TrackOutcome, truth: &TrackTable) -> TrackScore {
    score_tracks(&outcome.table, truth, outcome.stats.radius)
}

/// Loads a scene of the repository's `scenes/` folder.
pub fn load_scene(name: &str) -> Scene {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../scenes")
        .join(name);
    Scene::load(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// Render settings of the issue's benchmark discs: radius 4, amplitude 200 over 30, grey.
pub fn issue_settings(width: u32, height: u32, noise: f64, seed: u64) -> RenderSettings {
    RenderSettings {
        width,
        height,
        radius: 4.0,
        background: Colour::Grey(30),
        foreground: Colour::Grey(230),
        noise,
        blur: 0.0,
        seed,
    }
}

/// Free random walks of `count` discs of radius `radius` (px) over a `size` x `size` px frame,
/// the kind trackpy's users record: each particle keeps its own speed (0.5-3 px a frame) in a
/// fresh random direction every frame; a step that would bring two discs closer than
/// `2 radius + 1` px, or a disc within a pixel of the border, is drawn again (up to ten times,
/// then the particle stays put). Particles wander anywhere and pass close by each other.
pub fn free_walk(count: usize, size: f64, radius: f64, frames: usize, seed: u64) -> Truth {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let apart = 2.0 * radius + 1.0;
    let (lo, hi) = (radius + 1.0, size - 1.0 - radius - 1.0);
    let clear = |pos: &[Vec2], q: Vec2, skip: usize, gap: f64| {
        pos.iter()
            .enumerate()
            .all(|(j, p)| j == skip || (p - q).norm() >= gap)
    };
    let mut pos: Vec<Vec2> = Vec::with_capacity(count);
    while pos.len() < count {
        let q = Vec2::new(rng.gen_range(lo..hi), rng.gen_range(lo..hi));
        if clear(&pos, q, usize::MAX, apart + 2.0) {
            pos.push(q);
        }
    }
    let speed: Vec<f64> = (0..count).map(|_| rng.gen_range(0.5..3.0)).collect();
    let mut out = vec![pos.clone()];
    for _ in 1..frames {
        for i in 0..count {
            for _ in 0..10 {
                let a = std::f64::consts::TAU * rng.gen::<f64>();
                let q = pos[i] + speed[i] * Vec2::new(a.cos(), a.sin());
                if (lo..=hi).contains(&q.x) && (lo..=hi).contains(&q.y) && clear(&pos, q, i, apart) {
                    pos[i] = q;
                    break;
                }
            }
        }
        out.push(pos.clone());
    }
    Truth {
        names: (0..count).map(|i| format!("p{i}")).collect(),
        frames: out,
    }
}

/// Random walks of isolated particles: one per cell of a `cols x rows` grid of `cell` px
/// cells, each stepping a random distance up to `max_step` px per frame in a random
/// direction and reflected to stay within `cell / 2 - clearance` px of its cell centre,
/// so no two discs ever come closer than `2 * clearance` px.
pub fn grid_walk(
    cols: usize,
    rows: usize,
    cell: f64,
    clearance: f64,
    max_step: f64,
    frames: usize,
    seed: u64,
) -> Truth {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let half = cell / 2.0 - clearance;
    let mut centres = Vec::new();
    let mut pos = Vec::new();
    for r in 0..rows {
        for c in 0..cols {
            let centre = Vec2::new(cell * (c as f64 + 0.5), cell * (r as f64 + 0.5));
            centres.push(centre);
            pos.push(centre + Vec2::new(rng.gen_range(-half..half), rng.gen_range(-half..half)));
        }
    }
    let mut out = vec![pos.clone()];
    for _ in 1..frames {
        for (p, c) in pos.iter_mut().zip(&centres) {
            let len = max_step * rng.gen::<f64>();
            let a = std::f64::consts::TAU * rng.gen::<f64>();
            let mut q = *p + len * Vec2::new(a.cos(), a.sin());
            for k in 0..2 {
                if q[k] > c[k] + half {
                    q[k] = 2.0 * (c[k] + half) - q[k];
                }
                if q[k] < c[k] - half {
                    q[k] = 2.0 * (c[k] - half) - q[k];
                }
            }
            *p = q;
        }
        out.push(pos.clone());
    }
    Truth {
        names: (0..pos.len()).map(|i| format!("p{i}")).collect(),
        frames: out,
    }
}

/// Asserts the outcome follows every particle of `truth` in every frame with no switch and
/// returns the score.
pub fn assert_followed(label: &str, outcome: &TrackOutcome, truth: &TrackTable) -> TrackScore {
    let s = score(outcome, truth);
    assert!(
        s.matched_count == s.truth_count && s.id_switches == 0 && s.name_mismatches.unwrap_or(0) == 0,
        "{label}: {} of {} truth points matched, {} switches, {:?} wrong names\n{}\nwarnings: {:?}",
        s.matched_count,
        s.truth_count,
        s.id_switches,
        s.name_mismatches,
        outcome.stats,
        outcome.warnings
    );
    s
}

/// Returns true if and only if `warning` names `particle` at its head, before the first
/// colon: `p2: ...`, or `p2 and p6: ...`, or `p1, p2 and p6: ...`.
pub fn names_at_head(warning: &str, particle: &str) -> bool {
    warning
        .split_once(':')
        .is_some_and(|(head, _)| head.split([',', ' ']).any(|n| n == particle))
}

/// Adds a disc of radius `r` px at `c` (px) over `image` (grey levels, row-major, width
/// `w`), its area-sampled coverage (4 x 4 samples a pixel) replacing the level by `level`.
pub fn draw_disc(image: &mut [f64], w: usize, c: [f64; 2], r: f64, level: f64) {
    let h = image.len() / w;
    let x0 = (c[0] - r - 1.0).floor().max(0.0) as usize;
    let y0 = (c[1] - r - 1.0).floor().max(0.0) as usize;
    let x1 = ((c[0] + r + 1.0).ceil().max(0.0) as usize).min(w - 1);
    let y1 = ((c[1] + r + 1.0).ceil().max(0.0) as usize).min(h - 1);
    for y in y0..=y1 {
        for x in x0..=x1 {
            let mut inside = 0u32;
            for sy in 0..4 {
                for sx in 0..4 {
                    let px = x as f64 - 0.375 + 0.25 * f64::from(sx);
                    let py = y as f64 - 0.375 + 0.25 * f64::from(sy);
                    if (px - c[0]).hypot(py - c[1]) <= r {
                        inside += 1;
                    }
                }
            }
            let cover = f64::from(inside) / 16.0;
            let v = &mut image[y * w + x];
            *v = *v * (1.0 - cover) + level * cover;
        }
    }
}

/// A standard normal deviate (Box-Muller) from `rng`.
pub fn gauss(rng: &mut impl Rng) -> f64 {
    let (u1, u2): (f64, f64) = (1.0 - rng.gen::<f64>(), rng.gen());
    (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
}

/// Writes `image` (grey levels, row-major, width `w`) to `path` as an 8-bit PNG, with
/// Gaussian noise of `noise` grey levels from `rng` added and the levels rounded and clamped.
pub fn save_grey(image: &[f64], w: usize, noise: f64, rng: &mut impl Rng, path: &Path) {
    let h = image.len() / w;
    let mut out = image::GrayImage::new(w as u32, h as u32);
    for (i, v) in image.iter().enumerate() {
        let n = if noise > 0.0 { noise * gauss(rng) } else { 0.0 };
        let level = (v + n).round().clamp(0.0, 255.0) as u8;
        out.put_pixel((i % w) as u32, (i / w) as u32, image::Luma([level]));
    }
    out.save(path).expect("write frame");
}

/// With `PHYSFIT_SWEEP_KEEP=DIR` set, keeps the frames of `dir` in `DIR/name/frames` and
/// `truth` in `DIR/name/truth.csv`, for a closer look with `physfit track`.
pub fn keep_for_a_look(dir: &Path, name: &str, truth: &TrackTable) {
    let Ok(keep) = std::env::var("PHYSFIT_SWEEP_KEEP") else {
        return;
    };
    let to = Path::new(&keep).join(name);
    std::fs::create_dir_all(to.join("frames")).expect("keep folder");
    for entry in std::fs::read_dir(dir).expect("frames").flatten() {
        std::fs::copy(entry.path(), to.join("frames").join(entry.file_name())).expect("copy frame");
    }
    truth.write_csv(&to.join("truth.csv")).expect("write truth");
}
