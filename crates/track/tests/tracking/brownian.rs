//! Small discs in Brownian motion (colloids under a microscope): their steps are random, so
//! the change of their step changes by as much as a track hopping between objects does
//! (the hopping check's third difference), and a velocity extrapolated from them overshoots.
//! Followed exactly, they must not be called hops; crowded, they must keep their identities
//! as well as linking each to the nearest blob of the next frame would.

use physfit_track::{score_tracks, track_folder, TrackOptions, TrackPoint, TrackTable};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::common::{draw_disc, gauss, keep_for_a_look, said_to_jump_about, save_grey, TempDir};

/// Frames of each recording.
const FRAMES: usize = 30;

/// One recording: discs of radius 1.5-4 px (log-uniform), 80-200 grey levels over a
/// background of 20-60, random-walking with Gaussian steps of 0.3-1.0 times (radius + 1 px)
/// per axis, noise 0-5 grey levels, 30 frames. Apart: 25 discs in 240 x 240 px, no two
/// within 2 radii and 5 steps' spreads (which blob is whose is then plain from positions);
/// crowded: 40 in 200 x 200, no two within 2 radii and 3 px. A step that would bring two
/// nearer is drawn again, up to 20 times, else the disc stays. Returns the folder, the
/// truth, the radius and the step's spread per axis (px).
fn brownian_discs(seed: u64, crowded: bool) -> (TempDir, TrackTable, f64, f64) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let (w, h, count) = if crowded {
        (200, 200, 40)
    } else {
        (240usize, 240usize, 25)
    };
    let radius = (1.5f64.ln() + (4f64.ln() - 1.5f64.ln()) * rng.gen::<f64>()).exp();
    let background: f64 = rng.gen_range(20.0..60.0);
    let contrast: f64 = rng.gen_range(80.0..200.0);
    let noise: f64 = rng.gen_range(0.0..5.0);
    let sigma = (radius + 1.0) * rng.gen_range(0.3..1.0);
    let apart = 2.0 * radius + if crowded { 3.0 } else { 5.0 * sigma };
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
    while at.len() < count {
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
    let name = if crowded { "brownian-crowded" } else { "brownian" };
    keep_for_a_look(dir.path(), &format!("{name}-{seed}"), &truth);
    (dir, truth, radius, sigma)
}

/// Twelve recordings (seeds 7500-7511, 300 discs): every disc found in every frame (recall
/// 1, RMS error under 0.1 px per axis), and at most 1 % of the tracks said to hop (a walk's
/// displacement over 4 frames falls under twice its step's by chance: about 4 % of
/// simulated walks of 20 steps). Measured: RMS 0.012-0.026 px, 1 track of 300 said to hop (7502);
/// while the check judged by the third differences alone, 76 were (8 recordings of 12, all
/// with steps above 0.65 of (radius + 1 px)).
/// Identity switches are printed, not asserted (see the crowded test): 7500 and 7505 each
/// have one disc followed as two tracks (the second start warned of as a jump).
#[test]
fn small_discs_in_brownian_motion_are_not_taken_for_hops() {
    let mut report = String::new();
    let (mut wrong, mut said_to_hop) = (Vec::new(), 0);
    for seed in 7500..7512u64 {
        let (dir, truth, radius, sigma) = brownian_discs(seed, false);
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
        let hops = said_to_jump_about(&outcome);
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

/// How many times a disc of `truth` is not the nearest of the next frame's discs to where it
/// was: the identity errors of linking each to the nearest blob of the next frame.
fn nearest_blob_errors(truth: &TrackTable) -> usize {
    let mut frames: Vec<Vec<&TrackPoint>> = vec![Vec::new(); truth.frame_end()];
    for p in &truth.points {
        frames[p.frame].push(p);
    }
    frames
        .windows(2)
        .map(|w| {
            w[0].iter()
                .filter(|p| {
                    let nearest = w[1].iter().min_by(|a, b| {
                        let d = |q: &&TrackPoint| (q.x - p.x).hypot(q.y - p.y);
                        d(a).total_cmp(&d(b))
                    });
                    nearest.is_some_and(|q| q.particle != p.particle)
                })
                .count()
        })
        .sum()
}

/// Twelve crowded recordings (seeds 7500-7511): identity switches no more than linking each
/// disc to the nearest blob of the next frame makes, in each. Measured: 8 switches in all
/// (7500, whose discs step 4.8 px per axis) against 25 nearest-blob errors (20 in 7500, 1 in
/// 7508, 4 in 7511); while a new track's first step was gated by half the way to its
/// nearest neighbour, 199 (86, 39, 2, 37, 19 and 16 in 7500, 7502, 7506, 7508, 7510, 7511),
/// and 14 while constant acceleration was chosen on one residual.
#[test]
fn crowded_discs_in_brownian_motion_keep_their_identities() {
    let mut report = String::new();
    let mut worse = Vec::new();
    for seed in 7500..7512u64 {
        let (dir, truth, radius, sigma) = brownian_discs(seed, true);
        let options = TrackOptions {
            threads: Some(1),
            ..TrackOptions::default()
        };
        let outcome = track_folder(dir.path(), &options, &|_, _| {}).expect("tracked");
        let s = score_tracks(&outcome.table, &truth, radius);
        let nearest = nearest_blob_errors(&truth);
        report.push_str(&format!(
            "seed {seed}: R {radius:.2} px, steps {sigma:.2} px per axis: recall {:.3}, switches {}, nearest-blob errors {nearest}\n",
            s.recall, s.id_switches
        ));
        if s.id_switches > nearest {
            worse.push(seed);
        }
    }
    println!("{report}");
    assert!(worse.is_empty(), "{worse:?}\n{report}");
}
