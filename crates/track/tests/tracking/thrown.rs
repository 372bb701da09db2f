//! A named ball thrown across a wall of marks (the real `ball-toss` recording's class): it
//! moves several times farther per frame than the nearest mark lies from it, and the marks
//! look nothing like it (a fraction of its light). The first step of a named track is not
//! known; the marks must not narrow its gate to where the ball cannot be found.

use physfit_track::{track_folder, TrackOptions, TrackPoint, TrackTable};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::common::{draw_disc, keep_for_a_look, names_at_head, save_grey, TempDir};

/// Frames of each recording.
const FRAMES: usize = 12;

/// One recording: a ball of radius 3-9 px (log-uniform), 100-200 grey levels over a
/// background of 20-60, thrown on a parabola at 4-10 of its radii a frame along x (at most
/// 34.5 px) under a field of 1-4 px/frame² down, its top after 5.5-8 frames (in view
/// throughout), across 30-60 static marks of radius 1-4 px at 5-25 % of its contrast, one of
/// them beside its start (1.5-4 of its radii beyond touching it), none on its path; noise
/// 0-4 grey levels; 12 frames of 480 x 320. Returns the folder, the ball's true positions
/// per frame and its radius.
fn thrown_ball(seed: u64) -> (TempDir, Vec<[f64; 2]>, f64) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let (w, h) = (480usize, 320usize);
    let radius = (3f64.ln() + (9f64.ln() - 3f64.ln()) * rng.gen::<f64>()).exp();
    let background: f64 = rng.gen_range(20.0..60.0);
    let contrast: f64 = rng.gen_range(100.0..200.0);
    let noise: f64 = rng.gen_range(0.0..4.0);
    let vx = radius * rng.gen_range(4.0..10.0);
    let vx = vx.min(380.0 / (FRAMES - 1) as f64);
    let g: f64 = rng.gen_range(1.0..4.0);
    let t_top = rng.gen_range(5.5..8.0);
    let vy = -g * t_top;
    let start = [50.0, 270.0 - rng.gen_range(0.0..60.0)];
    let ball: Vec<[f64; 2]> = (0..FRAMES)
        .map(|k| {
            let t = k as f64;
            [start[0] + vx * t, start[1] + vy * t + 0.5 * g * t * t]
        })
        .collect();
    let clear_of_path = |c: [f64; 2], r: f64| {
        ball.iter()
            .all(|b| (b[0] - c[0]).hypot(b[1] - c[1]) > radius + r + 3.0)
    };
    let mut marks: Vec<([f64; 2], f64, f64)> = Vec::new();
    let beside_r: f64 = rng.gen_range(1.0..4.0);
    loop {
        let a: f64 = rng.gen_range(0.0..std::f64::consts::TAU);
        let d = radius + beside_r + radius * rng.gen_range(1.5..4.0);
        let c = [start[0] + d * a.cos(), start[1] + d * a.sin()];
        if clear_of_path(c, beside_r) && c[1] < h as f64 - 10.0 {
            marks.push((c, beside_r, contrast * rng.gen_range(0.05..0.25)));
            break;
        }
    }
    let count = rng.gen_range(30..60);
    while marks.len() < count {
        let r: f64 = rng.gen_range(1.0..4.0);
        let c = [
            rng.gen_range(10.0..w as f64 - 10.0),
            rng.gen_range(10.0..h as f64 - 10.0),
        ];
        let apart = marks
            .iter()
            .all(|(m, mr, _)| (m[0] - c[0]).hypot(m[1] - c[1]) > r + mr + 4.0);
        if apart && clear_of_path(c, r) {
            marks.push((c, r, contrast * rng.gen_range(0.05..0.25)));
        }
    }
    let dir = TempDir::new("thrown");
    for (k, b) in ball.iter().enumerate() {
        let mut image = vec![background; w * h];
        for (c, r, level) in &marks {
            draw_disc(&mut image, w, *c, *r, background + level);
        }
        draw_disc(&mut image, w, *b, radius, background + contrast);
        let path = dir.path().join(format!("frame_{k:05}.png"));
        save_grey(&image, w, noise, &mut rng, &path);
    }
    let truth = TrackTable {
        points: (ball.iter().enumerate())
            .map(|(k, b)| TrackPoint::new(k, "ball", b[0], b[1]))
            .collect(),
    };
    keep_for_a_look(dir.path(), &format!("thrown-{seed}"), &truth);
    (dir, ball, radius)
}

/// Sixteen thrown balls (seeds 7400-7415), each named at its start: every one followed in
/// every frame within a tenth of its radius, or refused or warned of by name (never a track
/// on the marks without a word). Measured: 16 of 16 followed, worst points 0.009-0.036 px
/// off. While every blob narrowed the first step's gate to half the way to it, 4 were
/// followed, 10 refused, 1 warned and 1 wrong without a word (7404: the track took a mark
/// 55 px off the ball in frame 4, the frames before bridged to it).
#[test]
fn a_ball_thrown_past_marks_that_look_otherwise_is_followed() {
    let mut report = String::new();
    let (mut followed, mut silent) = (0, Vec::new());
    for seed in 7400..7416u64 {
        let (dir, ball, radius) = thrown_ball(seed);
        let options = TrackOptions {
            named_start: Some(vec![("ball".into(), ball[0])]),
            threads: Some(1),
            ..TrackOptions::default()
        };
        let step = ball[1][0] - ball[0][0];
        let outcome = match track_folder(dir.path(), &options, &|_, _| {}) {
            Ok(o) => o,
            Err(e) => {
                let named = e.to_string().contains("ball");
                report.push_str(&format!(
                    "seed {seed}: R {radius:.1} px, step {step:.1} px: refused ({named}): {e}\n"
                ));
                if !named {
                    silent.push(seed);
                }
                continue;
            }
        };
        let worst = ball
            .iter()
            .enumerate()
            .map(|(k, b)| {
                outcome
                    .table
                    .points
                    .iter()
                    .find(|p| p.frame == k && p.particle == "ball")
                    .map_or(f64::INFINITY, |p| (p.x - b[0]).hypot(p.y - b[1]))
            })
            .fold(0.0, f64::max);
        let warned = outcome.warnings.iter().any(|w| names_at_head(w, "ball"));
        report.push_str(&format!(
            "seed {seed}: R {radius:.1} px, step {step:.1} px: worst {worst:.3} px, warned {warned}\n"
        ));
        if worst > 0.1 * radius {
            report.push_str(&format!("  warnings: {:?}\n", outcome.warnings));
        }
        if worst <= 0.1 * radius {
            followed += 1;
        } else if !warned {
            silent.push(seed);
        }
    }
    println!("{report}");
    assert!(
        silent.is_empty(),
        "off the ball without a word: {silent:?}\n{report}"
    );
    assert_eq!(followed, 16, "{report}");
}
