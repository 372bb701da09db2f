//! Small discs in Brownian motion (colloids under a microscope): their steps are random, so
//! the change of their step changes by as much as a track hopping between objects does
//! (the hopping check's third difference). Followed exactly, they must not be called hops.

use physfit_track::{score_tracks, track_folder, TrackOptions, TrackPoint, TrackTable};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::common::{draw_disc, gauss, keep_for_a_look, save_grey, TempDir};

/// Frames of each recording.
const FRAMES: usize = 30;

/// One recording: 25 discs of radius 1.5-4 px (log-uniform), 80-200 grey levels over a
/// background of 20-60, random-walking with Gaussian steps of 0.3-1.0 times (radius + 1 px)
/// per axis, noise 0-5 grey levels, 30 frames of 240 x 240. No two come within 2 radii and 5
/// steps' spreads (a step that would bring them nearer is drawn again, up to 20 times, else
/// the disc stays): which blob is whose is then plain from positions, and only the hopping
/// check is tried. Returns the folder, the truth, the radius and the step's spread per
/// axis (px).
fn brownian_discs(seed: u64) -> (TempDir, TrackTable, f64, f64) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let (w, h) = (240usize, 240usize);
    let radius = (1.5f64.ln() + (4f64.ln() - 1.5f64.ln()) * rng.gen::<f64>()).exp();
    let background: f64 = rng.gen_range(20.0..60.0);
    let contrast: f64 = rng.gen_range(80.0..200.0);
    let noise: f64 = rng.gen_range(0.0..5.0);
    let sigma = (radius + 1.0) * rng.gen_range(0.3..1.0);
    let apart = 2.0 * radius + 5.0 * sigma;
    let margin = radius + 2.0;
    let inside = |p: [f64; 2]| {
        p.iter()
            .all(|&c| c >= margin && c <= w.min(h) as f64 - 1.0 - margin)
    };
    let clear = |at: &[[f64; 2]], i: usize, p: [f64; 2]| {
        at.iter()
            .enumerate()
            .all(|(j, q)| j == i || (q[0] - p[0]).hypot(q[1] - p[1]) >= apart)
    };
    let mut at: Vec<[f64; 2]> = Vec::new();
    while at.len() < 25 {
        let p = [
            rng.gen_range(margin..w as f64 - margin),
            rng.gen_range(margin..h as f64 - margin),
        ];
        if clear(&at, usize::MAX, p) {
            at.push(p);
        }
    }
    let dir = TempDir::new("brownian");
    let mut truth = TrackTable::default();
    for k in 0..FRAMES {
        let mut image = vec![background; w * h];
        for (i, p) in at.iter().enumerate() {
            draw_disc(&mut image, w, *p, radius, background + contrast);
            truth.points.push(TrackPoint::new(k, format!("p{i}"), p[0], p[1]));
        }
        save_grey(
            &image,
            w,
            noise,
            &mut rng,
            &dir.path().join(format!("frame_{k:05}.png")),
        );
        for i in 0..at.len() {
            for _ in 0..20 {
                let p = [
                    at[i][0] + sigma * gauss(&mut rng),
                    at[i][1] + sigma * gauss(&mut rng),
                ];
                if inside(p) && clear(&at, i, p) {
                    at[i] = p;
                    break;
                }
            }
        }
    }
    keep_for_a_look(dir.path(), &format!("brownian-{seed}"), &truth);
    (dir, truth, radius, sigma)
}

/// Twelve recordings (seeds 7500-7511, 300 discs): every disc found in every frame (recall
/// 1, RMS error under 0.1 px per axis), and at most 1 % of the tracks said to hop (a walk's
/// displacement over 4 frames falls under twice its step's by chance: 3 % of simulated
/// walks of 20 steps). Measured: RMS 0.012-0.026 px, 1 track of 300 said to hop (7502);
/// while the check judged by the third differences alone, 76 were (8 recordings of 12, all
/// with steps above 0.65 of (radius + 1 px)).
/// Identity switches are printed, not asserted: at steps of 4.8 px per axis, seed 7500 has
/// one (a track that followed its disc's constant-velocity extrapolation past a large step,
/// missed it, and took another disc two frames later; left, see the tracking docs).
#[test]
fn small_discs_in_brownian_motion_are_not_taken_for_hops() {
    let mut report = String::new();
    let (mut wrong, mut said_to_hop) = (Vec::new(), 0);
    for seed in 7500..7512u64 {
        let (dir, truth, radius, sigma) = brownian_discs(seed);
        let options = TrackOptions {
            threads: Some(1),
            ..TrackOptions::default()
        };
        let outcome = match track_folder(dir.path(), &options, &|_, _| {}) {
            Ok(o) => o,
            Err(e) => {
                report.push_str(&format!("seed {seed}: R {radius:.2} px: refused: {e}\n"));
                wrong.push(seed);
                continue;
            }
        };
        let s = score_tracks(&outcome.table, &truth, radius);
        if std::env::var("PHYSFIT_SWEEP_DEBUG").is_ok() {
            report.push_str(&format!("  {:?}\n", outcome.warnings));
        }
        let hops = outcome
            .warnings
            .iter()
            .filter(|w| w.contains("positions jump about"))
            .count();
        report.push_str(&format!(
            "seed {seed}: R {radius:.2} px, steps {sigma:.2} px per axis: recall {:.3}, switches {}, RMS {:.3}/{:.3} px, {hops} said to hop\n",
            s.recall, s.id_switches, s.rms_x, s.rms_y
        ));
        said_to_hop += hops;
        if s.recall < 1.0 || s.rms_x.max(s.rms_y) > 0.1 {
            wrong.push(seed);
        }
    }
    println!("{report}");
    assert!(wrong.is_empty(), "{wrong:?}\n{report}");
    assert!(
        said_to_hop <= 3,
        "{said_to_hop} of 300 tracks said to hop\n{report}"
    );
}
