//! Bodies drawn as a physics engine's debug view draws them: a filled disc with a line from
//! its centre to its edge marking the body's angle. The line pulls the intensity centroid off
//! the disc's centre; the tracker must say so, naming the particle and how far.

use image::{GrayImage, Luma};
use physfit_track::{score_tracks, track_folder, TrackOptions, TrackPoint, TrackTable};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::common::{gauss, TempDir};

/// One style: discs of radius 6-20 px (log-uniform), fill 120-220 over a background of
/// 20-60, a line 1-3 px wide from each disc's centre to its edge at 0-0.5 of the fill's
/// contrast (dark on the fill) or 1.2 times it, turning by up to 0.3 rad a frame, noise 0-6,
/// three discs walking up to 2 px a frame, 12 frames of 200 x 150, area-sampled 4 x 4.
/// Returns the folder and the truth table.
fn marked_discs(seed: u64) -> (TempDir, TrackTable, f64) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let radius = (6f64.ln() + (20f64.ln() - 6f64.ln()) * rng.gen::<f64>()).exp();
    let background: f64 = rng.gen_range(20.0..60.0);
    let fill: f64 = rng.gen_range(120.0..220.0);
    let contrast = fill - background;
    let line = if rng.gen_bool(0.7) {
        background + rng.gen_range(0.0..0.5) * contrast
    } else {
        (background + 1.2 * contrast).min(255.0)
    };
    let half_width = 0.5 * rng.gen_range(1.0..3.0);
    let noise = rng.gen_range(0.0..6.0);
    let (w, h) = (200usize, 150usize);
    let mut at: Vec<[f64; 2]> = (0..3)
        .map(|i| [40.0 + 60.0 * i as f64, 75.0 + rng.gen_range(-10.0..10.0)])
        .collect();
    let mut angle: Vec<f64> = (0..3)
        .map(|_| rng.gen_range(0.0..std::f64::consts::TAU))
        .collect();
    let spin: Vec<f64> = (0..3).map(|_| rng.gen_range(-0.3..0.3)).collect();
    let step: Vec<[f64; 2]> = (0..3)
        .map(|_| [rng.gen_range(-2.0..2.0), rng.gen_range(-1.0..1.0)])
        .collect();
    let dir = TempDir::new("marks");
    let mut truth = TrackTable::default();
    for k in 0..12 {
        let mut image = GrayImage::new(w as u32, h as u32);
        for y in 0..h {
            for x in 0..w {
                let mut v = 0.0;
                for sy in 0..4 {
                    for sx in 0..4 {
                        let px = x as f64 - 0.375 + 0.25 * f64::from(sx);
                        let py = y as f64 - 0.375 + 0.25 * f64::from(sy);
                        let mut level = background;
                        for (c, a) in at.iter().zip(&angle) {
                            let (dx, dy) = (px - c[0], py - c[1]);
                            if dx.hypot(dy) <= radius {
                                let along = dx * a.cos() + dy * a.sin();
                                let across = (-dx * a.sin() + dy * a.cos()).abs();
                                level = if along >= 0.0 && across <= half_width {
                                    line
                                } else {
                                    fill
                                };
                            }
                        }
                        v += level / 16.0;
                    }
                }
                let n = if noise > 0.0 { noise * gauss(&mut rng) } else { 0.0 };
                image.put_pixel(
                    x as u32,
                    y as u32,
                    Luma([(v + n).round().clamp(0.0, 255.0) as u8]),
                );
            }
        }
        image
            .save(dir.path().join(format!("frame_{k:05}.png")))
            .expect("write frame");
        for (i, c) in at.iter().enumerate() {
            truth.points.push(TrackPoint {
                frame: k,
                particle: format!("p{i}"),
                x: c[0],
                y: c[1],
                mass: f64::NAN,
                size: f64::NAN,
                ep: f64::NAN,
                flag: Default::default(),
            });
        }
        for i in 0..3 {
            at[i] = [at[i][0] + step[i][0], at[i][1] + step[i][1]];
            angle[i] += spin[i];
        }
    }
    (dir, truth, noise)
}

/// Eight styles of marked discs (seeds 7300-7307): every particle followed beyond the
/// sweep's bound (`0.05 px + 0.01 σ` per axis) is named in a warning of a mark inside it,
/// and the pull a warning gives lies within a factor of two of the particle's error (of the
/// bound, where the error is within it): no mark said to pull where none does. Measured: 18
/// particles 0.16-0.50 px off, each named with 0.61-0.67 of its error (the ring the pull is
/// read in leaves out a line's inner and outer parts), 3 at 0.04 px named with 0.55-0.58,
/// 3 within the bound unnamed.
#[test]
fn marks_inside_discs_are_named_with_their_pull() {
    let mut report = String::new();
    let mut wrong = Vec::new();
    for seed in 7300..7308u64 {
        let (dir, truth, noise) = marked_discs(seed);
        let start: Vec<(String, [f64; 2])> = truth
            .points
            .iter()
            .filter(|p| p.frame == 0)
            .map(|p| (p.particle.clone(), [p.x, p.y]))
            .collect();
        let options = TrackOptions {
            named_start: Some(start),
            threads: Some(1),
            ..TrackOptions::default()
        };
        let outcome = track_folder(dir.path(), &options, &|_, _| {}).expect("tracked");
        let bound = 0.05 + 0.01 * noise;
        for name in ["p0", "p1", "p2"] {
            let own = |t: &TrackTable| TrackTable {
                points: t.points.iter().filter(|p| p.particle == name).cloned().collect(),
            };
            let s = score_tracks(&own(&outcome.table), &own(&truth), 5.0);
            let error = s.rms_x.hypot(s.rms_y);
            let said: Option<f64> = outcome
                .warnings
                .iter()
                .filter(|w| w.starts_with(&format!("{name}: a mark inside it")))
                .find_map(|w| {
                    let tail = w.split("pulls its centroid about ").nth(1)?;
                    tail.split(' ').next()?.parse().ok()
                });
            report.push_str(&format!(
                "seed {seed} {name}: error {error:.3} px, said {said:?}\n"
            ));
            let beyond = s.rms_x > bound || s.rms_y > bound;
            let ok = match said {
                Some(p) => p > 0.5 * error && p < 2.0 * error.max(bound),
                None => !beyond,
            };
            if !ok {
                wrong.push(format!("{seed} {name}"));
            }
        }
    }
    println!("{report}");
    assert!(wrong.is_empty(), "{wrong:?}:\n{report}");
}
