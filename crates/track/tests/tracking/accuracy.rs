//! The issue's localisation benchmark: 512x512 8-bit frames of anti-aliased discs of
//! radius 4, amplitude 200 over a background of 30, random walks of up to 3 px/frame; the
//! RMS error per axis must match or beat trackpy 0.7's at every noise level, with default
//! options (no tuning).

use physfit_track::{BackgroundModel, TrackOptions, TrackOutcome, TrackTable};

use crate::common::{free_walk, grid_walk, issue_settings, names_at_head, render_to, score, track, TempDir};

/// trackpy 0.7's RMS localisation error per axis at noise 0, 5 and 20 grey levels, px.
const TRACKPY_RMS: [(f64, f64); 3] = [(0.0, 0.004), (5.0, 0.014), (20.0, 0.05)];

#[test]
fn localisation_beats_trackpy_at_every_noise_level() {
    let truth = grid_walk(8, 8, 64.0, 12.0, 3.0, 40, 7);
    for (k, &(noise, target)) in TRACKPY_RMS.iter().enumerate() {
        let dir = TempDir::new("issue-accuracy");
        render_to(
            &truth,
            &issue_settings(512, 512, noise, 100 + k as u64),
            dir.path(),
        );
        let out = track(dir.path(), &TrackOptions::default());
        let s = score(&out, &truth.table(512, 512));
        println!(
            "issue discs, noise {noise}: rms x {:.5} y {:.5} px (trackpy {target}), recall {}, precision {}, switches {}, radius {:.3}, noise {:.2}, median ep {:.4}",
            s.rms_x, s.rms_y, s.recall, s.precision, s.id_switches, out.stats.radius, out.stats.noise_sigma, out.stats.median_ep
        );
        assert_eq!(
            s.matched_count, s.truth_count,
            "noise {noise}: every particle found in every frame"
        );
        assert_eq!(
            s.track_count, s.truth_count,
            "noise {noise}: no spurious detections"
        );
        assert_eq!(s.id_switches, 0, "noise {noise}");
        assert!(
            s.rms_x < target && s.rms_y < target,
            "noise {noise}: rms {} {} px, trackpy {target}",
            s.rms_x,
            s.rms_y
        );
    }
}

/// With only a few frames, a per-pixel median background carries most of the pixel noise
/// (the median of 5 samples has 0.54 of one frame's noise): it must not be used where a
/// constant level describes the background as well, nor degrade localisation.
#[test]
fn few_noisy_frames_locate_as_well_as_many() {
    for (frames, seed) in [(5usize, 11u64), (3, 12), (5, 13)] {
        let truth = grid_walk(8, 8, 64.0, 12.0, 3.0, frames, seed);
        let dir = TempDir::new("few-frames");
        render_to(&truth, &issue_settings(512, 512, 20.0, seed), dir.path());
        let out = track(dir.path(), &TrackOptions::default());
        let s = score(&out, &truth.table(512, 512));
        println!(
            "{frames} frames, noise 20: rms x {:.4} y {:.4} px, recall {}, background {:?}, noise {:.2}, median ep {:.4}",
            s.rms_x, s.rms_y, s.recall, out.stats.background, out.stats.noise_sigma, out.stats.median_ep
        );
        assert_eq!(
            s.matched_count, s.truth_count,
            "{frames} frames: every particle found"
        );
        assert!(
            s.rms_x < 0.1 && s.rms_y < 0.1,
            "{frames} frames: rms {} {} px",
            s.rms_x,
            s.rms_y
        );
    }
}

/// A hundred particles random-walking in 51 px cells over ten frames at noise 20 (the
/// benchmark's localisation case): each hovers over a patch a few radii wide, so the
/// per-pixel median of ten samples holds every particle, and that structure, covering more
/// of the frame than the particles move over, once passed for a static scene (a per-pixel
/// background with the particles in it: 0.79 px RMS, radius 3.5 px for 4). Structure
/// that lies only where particles were found is theirs: the background is a constant level.
#[test]
fn hovering_particles_over_ten_noisy_frames_are_not_taken_for_the_background() {
    for seed in [21u64, 22] {
        let truth = grid_walk(10, 10, 51.2, 10.0, 3.0, 10, seed);
        let dir = TempDir::new("hovering");
        render_to(&truth, &issue_settings(512, 512, 20.0, seed), dir.path());
        let out = track(dir.path(), &TrackOptions::default());
        // Noise 20 gives about 0.044 px.
        followed_against_a_constant_level(seed, &out, &truth.table(512, 512), 0.06);
        assert!(
            (out.stats.radius - 4.0).abs() < 0.2,
            "seed {seed}: radius {}",
            out.stats.radius
        );
    }
}

/// Named particles that barely move (0.03 px a frame) are in the per-pixel median like static
/// objects, and seven discs in a small light frame, noise 15, covered enough of it to take the
/// per-pixel model: the discs were tracked against themselves, 1 px off with identity errors.
/// The structure's start positions say they are particles: the background is a constant level
/// and each is followed to the accuracy its noise allows.
#[test]
fn named_particles_that_barely_move_are_not_taken_for_the_background() {
    for seed in [31u64, 32] {
        let truth = grid_walk(3, 3, 30.0, 7.0, 0.03, 16, seed);
        let mut settings = issue_settings(90, 90, 15.0, seed);
        settings.background = physfit_model::Colour::Grey(240);
        settings.foreground = physfit_model::Colour::Grey(90);
        settings.radius = 4.75;
        let dir = TempDir::new("static-named");
        render_to(&truth, &settings, dir.path());
        let out = track(
            dir.path(),
            &TrackOptions {
                named_start: Some(truth.named_start()),
                ..TrackOptions::default()
            },
        );
        followed_against_a_constant_level(seed, &out, &truth.table(90, 90), 0.1);
    }
}

/// Asserts `out` measured its particles against a constant background level and followed
/// every particle of `truth` in every frame, without a switch, within `rms` px per axis.
fn followed_against_a_constant_level(seed: u64, out: &TrackOutcome, truth: &TrackTable, rms: f64) {
    let s = score(out, truth);
    println!(
        "seed {seed}: rms x {:.4} y {:.4} px, recall {}, switches {}, background {:?}, radius {:.2}",
        s.rms_x, s.rms_y, s.recall, s.id_switches, out.stats.background, out.stats.radius
    );
    assert_eq!(out.stats.background, BackgroundModel::Constant, "seed {seed}");
    assert_eq!(
        s.matched_count, s.truth_count,
        "seed {seed}: every particle found"
    );
    assert_eq!(s.id_switches, 0, "seed {seed}");
    assert!(
        s.rms_x < rms && s.rms_y < rms,
        "seed {seed}: rms {} {} px",
        s.rms_x,
        s.rms_y
    );
}

/// Unnamed linking of the movies trackpy's users make: 100 discs of radius 4 px random-walking
/// freely at 0.5-3 px a frame over 200 frames of 512 x 512 px, noise 5, without a structure:
/// exactly one track per particle, no particle claimed twice in a frame, no identity change.
/// Noise peaks used to start a 101st track: one at the frame's edge (the size test let every
/// blob touching the border through; it now expects the part of a particle inside the frame),
/// one inside (a track of a single point inside the recording is now dropped as a noise peak).
#[test]
fn unnamed_free_random_walks_give_one_track_per_particle() {
    let truth = free_walk(100, 512.0, 4.0, 200, 41);
    let dir = TempDir::new("free-walk");
    render_to(&truth, &issue_settings(512, 512, 5.0, 41), dir.path());
    let out = track(dir.path(), &TrackOptions::default());
    let s = score(&out, &truth.table(512, 512));
    let tracks = out.table.particle_ids().len();
    let mut per_frame: std::collections::BTreeMap<(usize, String), usize> = std::collections::BTreeMap::new();
    for p in &out.table.points {
        *per_frame.entry((p.frame, p.particle.clone())).or_default() += 1;
    }
    println!(
        "{tracks} tracks, recall {}, precision {}, switches {}, rms {:.4} {:.4} px",
        s.recall, s.precision, s.id_switches, s.rms_x, s.rms_y
    );
    assert_eq!(tracks, 100, "one track per particle");
    assert!(
        per_frame.values().all(|&n| n == 1),
        "a track with two points in a frame"
    );
    assert_eq!(s.matched_count, s.truth_count, "every particle in every frame");
    assert_eq!(s.track_count, s.truth_count, "no point beyond the particles'");
    assert_eq!(s.id_switches, 0);
    assert!(s.rms_x < 0.02 && s.rms_y < 0.02, "rms {} {} px", s.rms_x, s.rms_y);
}

/// A structure naming a few of many identical discs (every tenth of 1000 free random walks
/// at 0.5-3 px a frame, 512 x 512 px, noise 5, 60 frames; seeds 43, 45, 47, `PHYSFIT_NAMED_SEEDS`
/// for others): each named particle is followed to its own disc in every frame or named in a
/// warning, or the run is refused with an error naming a particle (never tracks off without
/// a word). With only the named particles as neighbours, a track's first step was gated by
/// half the distance to the nearest *named* start (90 px here), and a track took an unnamed
/// neighbour 9.5 px off whose mass was nearer its own; the gate now stops at half the distance
/// to the nearest other blob. Later steps can still be handed a lookalike's blob (a neighbour
/// at 3.6 prediction widths whose mass is nearer by 1 %): linked again backward in time, those
/// tracks take other blobs, and the particles are named as uncertain. (The skirt check counts
/// only tracked points as neighbours: seeds 44 and 49 are refused for the light of unnamed discs in a
/// named disc's ring.)
#[test]
fn named_particles_among_unnamed_lookalikes_are_followed_or_doubted() {
    let seeds: Vec<u64> = std::env::var("PHYSFIT_NAMED_SEEDS")
        .ok()
        .map_or(vec![43, 45, 47], |v| {
            v.split(',').filter_map(|s| s.parse().ok()).collect()
        });
    let mut tracked = 0;
    for seed in seeds {
        let truth = free_walk(1000, 512.0, 4.0, 60, seed);
        let dir = TempDir::new("named-few");
        render_to(&truth, &issue_settings(512, 512, 5.0, seed), dir.path());
        let named: Vec<(String, [f64; 2])> = truth.named_start().into_iter().step_by(10).collect();
        let options = TrackOptions {
            named_start: Some(named.clone()),
            ..TrackOptions::default()
        };
        let out = match physfit_track::track_folder(dir.path(), &options, &|_, _| {}) {
            Ok(out) => out,
            Err(e) => {
                let said = e.to_string();
                println!("seed {seed}: refused: {said}");
                assert!(
                    named.iter().any(|(n, _)| said.contains(&format!("{n}: "))),
                    "seed {seed}: refused without naming a particle: {said}"
                );
                continue;
            }
        };
        let table = truth.table(512, 512);
        let mut wrong = Vec::new();
        let mut silent = Vec::new();
        for (name, _) in &named {
            let off = out.table.points.iter().filter(|p| &p.particle == name).any(|p| {
                !table
                    .points
                    .iter()
                    .any(|t| t.frame == p.frame && &t.particle == name && (t.x - p.x).hypot(t.y - p.y) < 2.0)
            });
            if off {
                wrong.push(name.clone());
                let warned = out.warnings.iter().any(|w| names_at_head(w, name));
                if !warned {
                    silent.push(name.clone());
                }
            }
        }
        println!(
            "seed {seed}: {} of {} named off their disc somewhere: {wrong:?}",
            wrong.len(),
            named.len()
        );
        assert!(
            silent.is_empty(),
            "seed {seed}: off without a word: {silent:?}; warnings {:?}",
            out.warnings
        );
        assert!(wrong.len() <= 6, "seed {seed}: {wrong:?}");
        tracked += 1;
    }
    assert!(tracked > 0, "every recording refused");
}
