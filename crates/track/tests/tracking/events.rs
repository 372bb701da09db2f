//! Sequences with something wrong in them: a frame file missing, a blank frame, particles
//! leaving the image. The tracker must stay on its particles and say what happened.

use physfit_model::Vec2;
use physfit_track::{AmbiguityKind, PointFlag, TrackOptions};

use crate::common::{frame_path, issue_settings, render_to, score, track, write_frame, TempDir, Truth};
use crate::crossing::ballistic;

#[test]
fn a_missing_frame_file_does_not_swap_tracks() {
    // 12 particles crossing at 4 px/frame; file 20 of 40 deleted, so file index 20 holds
    // frame 21 and every particle jumps two frames' motion at once.
    let truth = ballistic(12, 256.0, 8.0, 4.0, 40, 5);
    let dir = TempDir::new("gap");
    render_to(&truth, &issue_settings(256, 256, 5.0, 3), dir.path());
    std::fs::remove_file(frame_path(dir.path(), 20)).expect("delete frame 20");
    let out = track(
        dir.path(),
        &TrackOptions {
            named_start: Some(truth.named_start()),
            ..TrackOptions::default()
        },
    );
    let index: Vec<usize> = (0..40).filter(|&k| k != 20).collect();
    let s = score(&out, &truth.table_for(&index, 256, 256));
    println!(
        "gap: recall {}, switches {}, wrong names {:?}, warnings {:?}",
        s.recall, s.id_switches, s.name_mismatches, out.warnings
    );
    assert_eq!(
        s.name_mismatches,
        Some(0),
        "tracks stay on their particles after the gap"
    );
    assert_eq!(s.id_switches, 0);
    assert_eq!(s.matched_count, s.truth_count);
}

#[test]
fn a_blank_frame_is_named_and_bridged() {
    let truth = ballistic(6, 256.0, 8.0, 2.0, 30, 8);
    let settings = issue_settings(256, 256, 3.0, 4);
    let dir = TempDir::new("blank");
    render_to(&truth, &settings, dir.path());
    write_frame(&[], &settings, 15, &frame_path(dir.path(), 15));
    let out = track(
        dir.path(),
        &TrackOptions {
            named_start: Some(truth.named_start()),
            ..TrackOptions::default()
        },
    );
    println!("blank: warnings {:?}", out.warnings);
    assert!(
        out.warnings
            .iter()
            .any(|w| w.contains("frame 15") || w.contains("000015.png")),
        "{:?}",
        out.warnings
    );
    let mut table = truth.table(256, 256);
    table.points.retain(|p| p.frame != 15);
    let s = score(&out, &table);
    assert_eq!(s.name_mismatches, Some(0));
    assert_eq!(
        s.matched_count, s.truth_count,
        "followed before and after the blank frame"
    );
    // In the blank frame every particle is bridged, flagged and reported.
    let bridged: Vec<_> = out.table.points.iter().filter(|p| p.frame == 15).collect();
    assert_eq!(bridged.len(), 6);
    assert!(
        bridged.iter().all(|p| p.flag == PointFlag::Interpolated),
        "{bridged:?}"
    );
    for name in &truth.names {
        assert!(
            out.stats
                .ambiguities
                .iter()
                .any(|a| a.kind == AmbiguityKind::Missing
                    && a.particles.contains(name)
                    && (a.first_frame..=a.last_frame).contains(&15)),
            "{name} bridged at frame 15 but not reported: {:?}",
            out.stats.ambiguities
        );
    }
}

/// Three particles; `a` moves right at 5 px/frame and leaves the image at about frame 24.
fn leaving() -> Truth {
    let frames = (0..40)
        .map(|k| {
            let k = k as f64;
            vec![
                Vec2::new(140.0 + 5.0 * k, 60.0),
                Vec2::new(60.0 + 0.5 * k, 150.0),
                Vec2::new(120.0, 200.0 - 0.7 * k),
            ]
        })
        .collect();
    Truth {
        names: vec!["a".into(), "b".into(), "c".into()],
        frames,
    }
}

#[test]
fn a_particle_leaving_the_image_ends_with_a_warning() {
    let truth = leaving();
    let dir = TempDir::new("leave");
    render_to(&truth, &issue_settings(256, 256, 5.0, 6), dir.path());
    for named in [true, false] {
        let out = track(
            dir.path(),
            &TrackOptions {
                named_start: named.then(|| truth.named_start()),
                ..TrackOptions::default()
            },
        );
        println!("leaving (named {named}): warnings {:?}", out.warnings);
        let s = score(&out, &truth.table(256, 256));
        // Every point written is on a particle, or bridged at most a radius past the edge
        // where the particle left (no garbage after it left).
        let r = out.stats.radius;
        let stray: Vec<_> = out
            .table
            .points
            .iter()
            .filter(|p| {
                let t = truth.frames[p.frame]
                    .iter()
                    .map(|t| (t.x - p.x).hypot(t.y - p.y))
                    .fold(f64::INFINITY, f64::min);
                t > r && !(p.flag == PointFlag::Interpolated && p.x <= 255.0 + r)
            })
            .collect();
        assert!(
            stray.is_empty(),
            "named {named}: points on no particle: {stray:?}"
        );
        assert!(
            out.table.points.iter().all(|p| p.x > -r && p.x <= 255.0 + r),
            "named {named}"
        );
        assert_eq!(s.id_switches, 0, "named {named}");
        // While fully inside, `a` is followed.
        let inside_frames = (0..40).filter(|&k| truth.frames[k][0].x < 251.0).count();
        assert!(
            s.matched_count >= 80 + inside_frames,
            "named {named}: {} matched",
            s.matched_count
        );
        if named {
            assert!(
                out.warnings
                    .iter()
                    .any(|w| w.contains('a') && (w.contains("outside") || w.contains("lost"))),
                "a warning says particle a left: {:?}",
                out.warnings
            );
            // The points not written as `a` left are listed, each where its centre lay
            // within the radius (and its centroid's inward lean) of the right edge, and
            // none of them is in the table.
            let cut = &out.stats.cut_by_border;
            assert!(!cut.is_empty(), "no point listed as cut by the border");
            for (name, frame) in cut {
                let x = truth.frames[*frame][0].x;
                assert!(
                    name == "a" && x >= 255.5 - r - 1.0,
                    "{name} in frame {frame} (true x {x:.1}) listed as cut by the border"
                );
                assert!(
                    !out.table
                        .points
                        .iter()
                        .any(|p| &p.particle == name && p.frame == *frame),
                    "{name} in frame {frame} is listed as cut and written"
                );
            }
        }
    }
}
