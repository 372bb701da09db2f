//! Unit tests of the relocation of particles that share blobs.

use super::overlap_fit::Composition;
use super::relocate::{dist2, relocate_shared, Group, SharedBlobs};
use super::reorder::{rename_by_motion, Starts};
use crate::link::Ambiguity;
use crate::track_table::{PointFlag, TrackPoint};
use crate::TrackError;

/// No named starts.
const NO_STARTS: Starts<'static> = Starts {
    positions: &[],
    frame: 0,
};

/// Fraction of pixel `(x, y)` inside the disc of radius `r` about `c` (16 x 16 samples).
fn coverage(x: f64, y: f64, c: [f64; 2], r: f64) -> f64 {
    let n = 16;
    let mut inside = 0;
    for i in 0..n {
        for j in 0..n {
            let sx = x - 0.5 + (i as f64 + 0.5) / n as f64;
            let sy = y - 0.5 + (j as f64 + 0.5) / n as f64;
            inside += usize::from(dist2([sx, sy], c) <= r * r);
        }
    }
    inside as f64 / (n * n) as f64
}

/// A 64 x 64 signal of discs of radius 4 and amplitude 200, combined by `composition`.
fn image(discs: &[[f64; 2]], composition: Composition) -> Vec<f32> {
    let mut out = vec![0.0f32; 64 * 64];
    for y in 0..64 {
        for x in 0..64 {
            let covers: Vec<f64> = discs
                .iter()
                .map(|&c| coverage(x as f64, y as f64, c, 4.0))
                .collect();
            let v = match composition {
                Composition::Sum => covers.iter().sum::<f64>(),
                Composition::Cover => 1.0 - covers.iter().map(|a| 1.0 - a).product::<f64>(),
            };
            out[y * 64 + x] = (200.0 * v) as f32;
        }
    }
    out
}

fn point(frame: usize, name: &str, p: [f64; 2], flag: PointFlag) -> TrackPoint {
    TrackPoint {
        flag,
        ep: 0.01,
        ..TrackPoint::new(frame, name, p[0], p[1])
    }
}

/// Two discs 3 px apart (radius 4: most of each covers the other), one particle alone
/// for the profile; the linked points 1 px off, the second bridged. Both compositions:
/// the fit puts each within 0.05 px of its disc, and picks the composition of the image.
#[test]
fn overlapping_discs_are_placed_where_they_are() {
    let lone = [50.3, 49.6];
    let pair = [[20.2, 30.1], [23.0, 31.2]];
    for composition in [Composition::Sum, Composition::Cover] {
        let signal = image(&[lone, pair[0], pair[1]], composition);
        let signal_of = |_: usize| -> Result<Vec<f32>, TrackError> { Ok(signal.clone()) };
        let blobs = SharedBlobs {
            signal_of: &signal_of,
            width: 64,
            height: 64,
            radius: 4.0,
            window: 5.0,
        };
        let mut points = vec![
            point(0, "lone", lone, PointFlag::Detected),
            point(0, "a", [pair[0][0] + 0.8, pair[0][1] + 0.6], PointFlag::Split),
            point(
                0,
                "b",
                [pair[1][0] - 0.7, pair[1][1] - 0.5],
                PointFlag::Interpolated,
            ),
        ];
        let starts = Starts {
            positions: &[],
            frame: 0,
        };
        let counts = relocate_shared(&mut points, &mut [], &starts, &blobs).expect("relocate");
        assert_eq!(counts.moved, 2, "{composition:?}");
        for (p, truth) in points[1..].iter().zip(pair) {
            let e = dist2([p.x, p.y], truth).sqrt();
            assert!(e < 0.05, "{composition:?}: {} is {e:.3} px off", p.particle);
            assert!(p.ep.is_finite() && p.ep < 0.05, "{composition:?}: ep {}", p.ep);
        }
        assert_eq!(
            (points[0].x, points[0].y),
            (lone[0], lone[1]),
            "the lone particle stays"
        );
    }
}

/// Two particles in straight lines crossing over frames 3-6, each at its true position
/// but for the linker's exchange from frame 5 on (`swap_tail`) or for frames 4-5 only.
fn crossing(swap_from: usize, swap_to: usize) -> (Vec<TrackPoint>, Vec<Group>) {
    let path = |k: usize, t: usize| {
        let t = t as f64;
        if k == 0 {
            [10.0 + 2.0 * t, 20.0 + 0.1 * t]
        } else {
            [10.0 + 2.0 * t, 25.0 - 1.2 * t]
        }
    };
    let mut points = Vec::new();
    for t in 0..10 {
        for (k, name) in ["a", "b"].iter().enumerate() {
            let who = if (swap_from..=swap_to).contains(&t) {
                1 - k
            } else {
                k
            };
            let flag = if (3..=6).contains(&t) {
                PointFlag::Split
            } else {
                PointFlag::Detected
            };
            points.push(point(t, name, path(who, t), flag));
        }
    }
    let groups = (3..=6)
        .map(|t| Group {
            members: vec![2 * t, 2 * t + 1],
            fit: None,
        })
        .collect();
    (points, groups)
}

fn names_follow_paths(points: &[TrackPoint]) -> bool {
    // Track "a" has y growing slowly from 20; "b" falls from 25.
    points.iter().all(|p| {
        let a = 20.0 + 0.1 * p.frame as f64;
        let b = 25.0 - 1.2 * p.frame as f64;
        let own = if p.particle == "a" { a } else { b };
        let other = if p.particle == "a" { b } else { a };
        (p.y - own).abs() <= (p.y - other).abs()
    })
}

/// Positions exchanged inside the crossing (frames 4-5) go back to their tracks; so do the
/// continuations exchanged from frame 5 on, with the reports of ambiguities after it.
#[test]
fn the_motion_gives_each_track_its_own_positions_and_continuation() {
    let (mut points, groups) = crossing(4, 5);
    assert!(!names_follow_paths(&points));
    let renamed = rename_by_motion(&mut points, &groups, &mut [], &NO_STARTS);
    assert_eq!(renamed, 4);
    assert!(names_follow_paths(&points));

    let (mut points, groups) = crossing(5, 9);
    let mut reports = vec![Ambiguity {
        kind: crate::AmbiguityKind::Missing,
        particles: vec!["a".into()],
        first_frame: 8,
        last_frame: 8,
    }];
    rename_by_motion(&mut points, &groups, &mut reports, &NO_STARTS);
    assert!(names_follow_paths(&points));
    assert_eq!(reports[0].particles, ["b"], "the report follows the continuation");
}

/// An exchange smaller than the position noise is left alone.
#[test]
fn a_change_within_the_noise_is_not_made() {
    let (mut points, groups) = crossing(4, 5);
    for p in &mut points {
        p.ep = 5.0;
    }
    let before: Vec<(f64, f64)> = points.iter().map(|p| (p.x, p.y)).collect();
    assert_eq!(rename_by_motion(&mut points, &groups, &mut [], &NO_STARTS), 0);
    let after: Vec<(f64, f64)> = points.iter().map(|p| (p.x, p.y)).collect();
    assert_eq!(after, before);
}

/// A crossing at the start frame: the named start positions say who is who.
#[test]
fn named_starts_decide_a_crossing_at_the_first_frame() {
    // Both start in one blob and part; the linker gave each the other's start point.
    let mut points = Vec::new();
    for t in 0..6 {
        let tf = t as f64;
        let (a, b) = ([30.0 + 2.0 * tf, 30.0], [31.0 + 2.0 * tf, 32.0 + 2.0 * tf]);
        let (pa, pb) = if t == 0 { (b, a) } else { (a, b) };
        let flag = if t < 2 {
            PointFlag::Split
        } else {
            PointFlag::Detected
        };
        points.push(point(t, "a", pa, flag));
        points.push(point(t, "b", pb, flag));
    }
    let groups = (0..2)
        .map(|t| Group {
            members: vec![2 * t, 2 * t + 1],
            fit: None,
        })
        .collect::<Vec<_>>();
    let named = [("a".to_string(), [30.0, 30.0]), ("b".to_string(), [31.0, 32.0])];
    let starts = Starts {
        positions: &named,
        frame: 0,
    };
    rename_by_motion(&mut points, &groups, &mut [], &starts);
    assert_eq!((points[0].x, points[0].y), (30.0, 30.0));
    assert_eq!((points[1].x, points[1].y), (31.0, 32.0));
}
