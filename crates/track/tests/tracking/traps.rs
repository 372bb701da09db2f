//! Beads jittering in traps (optical tweezers, colloids caged by their neighbours): each
//! jitters about a fixed place, so its step's change changes by as much as a track hopping
//! between objects does (the hopping check's third difference), and its displacement over a
//! few frames stops growing as a free walk's does (the check's other sign of clutter). Its
//! image keeps its mass: followed exactly, it must be neither called a hop nor refused
//! under a structure, and faint beads of one size must not be split into two sizes by the
//! noise of their measured scales.

use physfit_track::{
    score_tracks, track_folder, TrackError, TrackOptions, TrackOutcome, TrackPoint, TrackTable,
};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::common::{draw_disc, gauss, keep_for_a_look, said_to_jump_about, save_grey, TempDir};

/// Frames of each recording.
const FRAMES: usize = 40;

/// Beads of each recording.
const BEADS: usize = 16;

/// A recording of beads in traps, its truth, and what a user knows of it.
struct Traps {
    dir: TempDir,
    truth: TrackTable,
    /// Each bead's name and first-frame position, px.
    starts: Vec<(String, [f64; 2])>,
    /// The beads' radius, px.
    radius: f64,
    /// The spread of each bead about its trap centre per axis, px.
    spread: f64,
}

/// A recording drawn from `seed`: [`BEADS`] discs of radius 1.5-5 px (log-uniform) in a
/// square frame of 240 px a side or six trap spacings and the margins, 3-25 noise deviations
/// above a background of 20-60 (noise 2-15 grey levels), each jittering about its own trap
/// centre: an AR(1) offset of stationary spread 0.35-0.8 times (radius plus 1 px) per axis
/// (above the third-difference threshold of a particle's diameter and 2 px) and a correlation
/// of 0-0.5 from frame to frame. Trap centres lie 2 radii and 12 spreads apart at least
/// (which blob is whose is plain from positions). Beads are named `p0`.... Faint: radius 1.8-2.5
/// px, 2.6-3.2 noise deviations above the background (noise 10-15), a spread of 0.4-0.6
/// times (radius plus 1 px).
fn trapped_beads(seed: u64, faint: bool) -> Traps {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let radius = if faint {
        rng.gen_range(1.8..2.5)
    } else {
        (1.5f64.ln() + (5f64.ln() - 1.5f64.ln()) * rng.gen::<f64>()).exp()
    };
    let background = rng.gen_range(20.0..60.0);
    let noise = rng.gen_range(if faint { 10.0..15.0 } else { 2.0..15.0 });
    let contrast = noise * rng.gen_range(if faint { 2.6..3.2 } else { 3.0..25.0 });
    let spread = (radius + 1.0) * rng.gen_range(if faint { 0.4..0.6 } else { 0.35..0.8 });
    let correlation: f64 = rng.gen_range(0.0..0.5);
    let apart = 2.0 * radius + 12.0 * spread;
    let margin = radius + 4.0 * spread + 2.0;
    // Room for the beads at random: six trap spacings a side and more.
    let side = 240usize.max((6.0 * apart + 2.0 * margin).ceil() as usize);
    let (w, h) = (side, side);
    let mut centres: Vec<[f64; 2]> = Vec::new();
    for attempt in 0.. {
        assert!(
            attempt < 100_000,
            "seed {seed}: no room for {BEADS} traps {apart:.1} px apart"
        );
        if centres.len() == BEADS {
            break;
        }
        let p = [
            rng.gen_range(margin..w as f64 - margin),
            rng.gen_range(margin..h as f64 - margin),
        ];
        if centres.iter().all(|q| (q[0] - p[0]).hypot(q[1] - p[1]) >= apart) {
            centres.push(p);
        }
    }
    let kick = spread * (1.0 - correlation * correlation).sqrt();
    let mut offsets: Vec<[f64; 2]> = (0..BEADS)
        .map(|_| [spread * gauss(&mut rng), spread * gauss(&mut rng)])
        .collect();
    let dir = TempDir::new("traps");
    let mut truth = TrackTable::default();
    let mut starts = Vec::new();
    for k in 0..FRAMES {
        let mut image = vec![background; w * h];
        for (i, (c, o)) in centres.iter().zip(&offsets).enumerate() {
            // Held inside the margin: a bead cut by the border is not this test's subject.
            let p = [0, 1].map(|a| (c[a] + o[a]).clamp(radius + 2.0, [w, h][a] as f64 - radius - 3.0));
            draw_disc(&mut image, w, p, radius, background + contrast);
            truth.points.push(TrackPoint::new(k, format!("p{i}"), p[0], p[1]));
            if k == 0 {
                starts.push((format!("p{i}"), p));
            }
        }
        save_grey(
            &image,
            w,
            noise,
            &mut rng,
            &dir.path().join(format!("frame_{k:05}.png")),
        );
        for o in &mut offsets {
            *o = [0, 1].map(|a| correlation * o[a] + kick * gauss(&mut rng));
        }
    }
    keep_for_a_look(dir.path(), &format!("traps-{seed}"), &truth);
    Traps {
        dir,
        truth,
        starts,
        radius,
        spread,
    }
}

/// `t` tracked on one thread without a structure and then with its beads named from their
/// first-frame positions: whether named, which ("unnamed", "named"), and the outcome.
fn tracked_both_ways(t: &Traps) -> [(bool, &'static str, Result<TrackOutcome, TrackError>); 2] {
    [(false, "unnamed"), (true, "named")].map(|(named, kind)| {
        let options = TrackOptions {
            threads: Some(1),
            named_start: named.then(|| t.starts.clone()),
            ..TrackOptions::default()
        };
        (named, kind, track_folder(t.dir.path(), &options, &|_, _| {}))
    })
}

/// Twelve recordings (seeds 7600-7611, 192 beads), each tracked named and unnamed: every bead
/// found in every frame under its own name, no identity switch, no track said to jump about,
/// none refused. Measured: RMS 0.024-0.134 px; before the checks asked whether a track keeps
/// its image's mass, 8 of 12 named runs were refused (their tracks called hops) and 88 of 192
/// unnamed tracks said to jump about.
#[test]
fn beads_jittering_in_traps_are_followed_and_not_taken_for_hops() {
    let mut report = String::new();
    let mut wrong = Vec::new();
    for seed in 7600..7612u64 {
        let t = trapped_beads(seed, false);
        let label = format!(
            "seed {seed}: R {:.2} px, spread {:.2} px per axis",
            t.radius, t.spread
        );
        for (named, kind, tracked) in tracked_both_ways(&t) {
            let outcome = match tracked {
                Ok(o) => o,
                Err(e) => {
                    report.push_str(&format!("{label}: {kind}: refused: {e}\n"));
                    wrong.push((seed, kind));
                    continue;
                }
            };
            let s = score_tracks(&outcome.table, &t.truth, t.radius);
            let hops = said_to_jump_about(&outcome);
            report.push_str(&format!(
                "{label}: {kind}: recall {:.3}, switches {}, wrong names {:?}, RMS {:.3}/{:.3} px, radii {:?}, {hops} said to jump about\n",
                s.recall, s.id_switches, s.name_mismatches, s.rms_x, s.rms_y, outcome.stats.radii
            ));
            let names_right = !named || s.name_mismatches == Some(0);
            if s.recall < 1.0 || s.id_switches > 0 || !names_right || hops > 0 {
                wrong.push((seed, kind));
            }
        }
    }
    println!("{report}");
    assert!(wrong.is_empty(), "{wrong:?}\n{report}");
}

/// Faint beads of one size (seeds 7620-7631, about 3 noise deviations high), named: their
/// scales in the first frame scatter with the noise, and a gap between two of them can split
/// the beads into two size classes; each class links alone and sees the other's beads as
/// free blobs (a track of one class, its bead missed for two frames, took a bead of the other
/// 55 px away, written with a warning). They must be followed as one size, every bead under
/// its own name. Measured: 12 of 12, RMS 0.18-0.24 px; while classes 1.3 apart stayed apart,
/// 7622 was split into two sizes (one measured at 2.68 px) and refused, a track having jumped
/// 23 px; before the checks asked whether a track keeps its image's mass, all 12 were refused
/// (their tracks called hops).
#[test]
fn faint_beads_of_one_size_are_followed_as_one_size() {
    let mut report = String::new();
    let (mut wrong, mut refused) = (Vec::new(), 0);
    for seed in 7620..7632u64 {
        let t = trapped_beads(seed, true);
        let options = TrackOptions {
            threads: Some(1),
            named_start: Some(t.starts),
            ..TrackOptions::default()
        };
        let label = format!(
            "seed {seed}: R {:.2} px, spread {:.2} px per axis",
            t.radius, t.spread
        );
        match track_folder(t.dir.path(), &options, &|_, _| {}) {
            Ok(outcome) => {
                let s = score_tracks(&outcome.table, &t.truth, t.radius);
                report.push_str(&format!(
                    "{label}: recall {:.3}, switches {}, wrong names {:?}, RMS {:.3}/{:.3} px, radii {:?}\n",
                    s.recall, s.id_switches, s.name_mismatches, s.rms_x, s.rms_y, outcome.stats.radii
                ));
                if outcome.stats.radii.len() != 1 || s.id_switches > 0 || s.name_mismatches != Some(0) {
                    wrong.push(seed);
                }
            }
            Err(e) => {
                report.push_str(&format!("{label}: refused: {e}\n"));
                refused += 1;
            }
        }
    }
    println!("{report}");
    assert!(
        wrong.is_empty() && refused == 0,
        "{wrong:?}, {refused} refused\n{report}"
    );
}

/// Fifty more recordings (seeds 7650-7699, 800 beads), a sweep of the same draw. Unnamed,
/// every bead is one track from the first frame to the last (unmatched only where bridged,
/// with a warning), and no track changes bead:
/// before, 6 of the 50 made a 17th track, 2 of them without a word. A track whose first 3-4
/// steps lined up by chance learned a small scale from those 2-3 residuals, and its bead's
/// next turn fell outside the gate: the track ended and a new one took the bead (7652: the
/// bead 7.46 px from a prediction of scale 0.88 px). Where a noise speck started a track,
/// the speck's track took a bead's blob 30 px away from the bead's own track (7663). Named,
/// every bead is followed under its name, or the run is refused; a step three times both
/// nearest steps and a diameter more is refused as a hop, and a bead's steps in its trap
/// are random (their squared ratio F(2, 2)), so 2 refusals in 50 are allowed (measured 2,
/// both at a track's last step after two short ones; 4 before the first step was judged
/// against the two steps after it).
#[test]
fn a_sweep_of_trapped_beads_gives_one_track_a_bead() {
    let mut report = String::new();
    let mut wrong = Vec::new();
    let mut refused = Vec::new();
    for seed in 7650..7700u64 {
        let t = trapped_beads(seed, false);
        let label = format!("seed {seed}: R {:.2} px, spread {:.2} px", t.radius, t.spread);
        for (named, kind, tracked) in tracked_both_ways(&t) {
            let outcome = match tracked {
                Ok(o) => o,
                Err(e) => {
                    report.push_str(&format!("{label}: {kind}: refused: {e}\n"));
                    if named {
                        refused.push(seed);
                    } else {
                        wrong.push((seed, kind));
                    }
                    continue;
                }
            };
            let s = score_tracks(&outcome.table, &t.truth, t.radius);
            let tracks = outcome.table.by_particle().len();
            let bridged = outcome.stats.interpolated_count;
            report.push_str(&format!(
                "{label}: {kind}: {tracks} tracks, recall {:.3} ({bridged} points bridged), switches {}, wrong names {:?}\n",
                s.recall, s.id_switches, s.name_mismatches
            ));
            let names_right = !named || s.name_mismatches == Some(0);
            // A faint bead the detector misses in a frame is bridged there with a warning, and
            // its jitter may put it farther from the bridge than a radius (unnamed 7667: 5 of
            // 8 bridged points): only bridged points may be unmatched.
            let unmatched = s.truth_count - s.matched_count;
            if tracks != BEADS || unmatched > bridged || s.id_switches > 0 || !names_right {
                wrong.push((seed, kind));
            }
        }
    }
    println!("{report}");
    assert!(wrong.is_empty(), "{wrong:?}\n{report}");
    assert!(refused.len() <= 2, "refused {refused:?}\n{report}");
}
