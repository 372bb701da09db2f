//! Real recordings (`/work/shared/real`, skipped with a message when absent): the tracker
//! must follow a ball in camera footage it was never tuned on.

use std::path::{Path, PathBuf};

use physfit_track::{PointFlag, TrackOptions, TrackOutcome, TrackTable};

use crate::common::track;
use crate::parabola::parabola;

fn real_dir(name: &str) -> Option<PathBuf> {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../../shared/real")
        .join(name);
    if dir.join("frames").is_dir() {
        Some(dir)
    } else {
        println!("skipped: real recording {} not found", dir.display());
        None
    }
}

#[test]
fn ball_toss_follows_the_hand_clicks_within_two_pixels() {
    let Some(dir) = real_dir("ball-toss") else { return };
    let out = track(
        &dir.join("frames"),
        &TrackOptions {
            named_start: Some(vec![("ball".into(), [131.3, 207.9])]),
            window: Some((2, 12)),
            ..TrackOptions::default()
        },
    );
    let clicks = std::fs::read_to_string(dir.join("human_track.csv")).expect("human_track.csv");
    println!("ball-toss: {}\nwarnings {:?}", out.stats, out.warnings);
    let by = out.table.by_particle();
    let ball = by.get("ball").expect("a ball track");
    let mut worst: f64 = 0.0;
    for line in clicks.lines().skip(1) {
        let v: Vec<f64> = line
            .split(',')
            .map(|x| x.trim().parse().expect("number"))
            .collect();
        let frame = v[0] as usize;
        let p = ball
            .iter()
            .find(|p| p.frame == frame)
            .unwrap_or_else(|| panic!("no ball point in frame {frame}"));
        let e = (p.x - v[1]).hypot(p.y - v[2]);
        println!(
            "ball-toss frame {frame}: tracked ({:.2}, {:.2}) {:?}, clicked ({:.2}, {:.2}), {e:.2} px apart",
            p.x, p.y, p.flag, v[1], v[2]
        );
        worst = worst.max(e);
    }
    assert!(
        worst < 2.0,
        "ball-toss: worst distance from the hand clicks {worst:.2} px"
    );
}

/// The bouncing-ball recording tracked with the ball named at its frame-0 position (from the
/// recording's structure file).
fn bouncing_ball_named(dir: &Path) -> TrackOutcome {
    track(
        &dir.join("frames"),
        &TrackOptions {
            named_start: Some(vec![("ball".into(), [24.0, 19.6])]),
            ..TrackOptions::default()
        },
    )
}

#[test]
fn bouncing_ball_is_followed_through_every_frame() {
    let Some(dir) = real_dir("bouncing-ball") else {
        return;
    };
    let out = bouncing_ball_named(&dir);
    println!("bouncing-ball: {}\nwarnings {:?}", out.stats, out.warnings);
    let by = out.table.by_particle();
    let ball: Vec<_> = by.get("ball").expect("a ball track").clone();
    assert_eq!(ball.len(), 87, "a point in each of the 87 frames");
    let mut biggest: f64 = 0.0;
    for w in ball.windows(2) {
        biggest = biggest.max((w[1].x - w[0].x).hypot(w[1].y - w[0].y));
    }
    let detected = ball.iter().filter(|p| p.flag == PointFlag::Detected).count();
    // Bounces: frames where the vertical motion turns from down to up.
    let lows: Vec<(usize, f64, f64)> = ball
        .windows(3)
        .filter(|w| w[1].y > w[0].y && w[1].y >= w[2].y && w[1].y - w[0].y.min(w[2].y) > 2.0)
        .map(|w| (w[1].frame, w[1].x, w[1].y))
        .collect();
    println!(
        "bouncing-ball: largest step {biggest:.1} px, {detected} of 87 detected, lowest points {lows:?}"
    );
    assert!(biggest <= 60.0, "largest step between frames {biggest:.1} px");
    assert!(detected >= 85, "the ball detected in {detected} of 87 frames");
    assert!(lows.len() >= 4, "at least four bounces: {lows:?}");
    // Between bounces the ball flies free: each arc is a parabola in time to within the
    // tracking error (a lost or swapped point would stand pixels off it), and every arc shows
    // nearly the same downward acceleration (measured 1573-1820 px/s^2: air drag slows the
    // fast early arcs least in their mean, and the last arc has only 7 points).
    let fps = 29.97;
    let mut fields = Vec::new();
    for pair in lows.windows(2) {
        let arc: Vec<_> = ball
            .iter()
            .filter(|p| p.frame > pair[0].0 && p.frame < pair[1].0)
            .collect();
        if arc.len() < 6 {
            continue;
        }
        let t: Vec<f64> = arc.iter().map(|p| p.frame as f64 / fps).collect();
        let y: Vec<f64> = arc.iter().map(|p| p.y).collect();
        let (coef, rms) = parabola(&t, &y);
        println!(
            "bouncing-ball: arc frames {}-{}: downward acceleration {:.0} px/s^2, rms off the parabola {rms:.2} px",
            arc[0].frame,
            arc[arc.len() - 1].frame,
            2.0 * coef[2]
        );
        assert!(
            rms < 1.0,
            "arc after frame {}: {rms:.2} px off a parabola",
            pair[0].0
        );
        fields.push(2.0 * coef[2]);
    }
    assert!(fields.len() >= 3, "at least three complete arcs: {fields:?}");
    let (lo, hi) = fields
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &g| {
            (a.min(g), b.max(g))
        });
    assert!(
        lo > 0.0 && hi / lo < 1.25,
        "the arcs disagree on the field: {fields:?}"
    );
    write_for_inspection(&out.table);
}

/// Leaves the track where a person can look at it when asked to (PHYSFIT_KEEP_TRACKS).
fn write_for_inspection(table: &TrackTable) {
    if let Ok(path) = std::env::var("PHYSFIT_KEEP_TRACKS") {
        table.write_csv(Path::new(&path)).expect("write tracks");
    }
}

/// Without a structure, the bouncing-ball wall's texture flickers into about 80 blobs a frame
/// as the camera's exposure shifts, and the median of all blob sizes is a speck's (radius 9.2
/// px; the ball's is 7.4). The sizes are measured on the blobs that move steadily over three
/// frames instead: the radius is the ball's, and the ball is detected in every frame.
#[test]
fn bouncing_ball_sizes_come_from_the_moving_blob_without_a_structure() {
    let Some(dir) = real_dir("bouncing-ball") else {
        return;
    };
    let named = bouncing_ball_named(&dir);
    let out = track(&dir.join("frames"), &TrackOptions::default());
    println!("bouncing-ball, no structure: {}", out.stats);
    assert!(
        (out.stats.radius - named.stats.radius).abs() < 0.3,
        "radius {:.2} px without a structure, {:.2} with",
        out.stats.radius,
        named.stats.radius
    );
    let by = named.table.by_particle();
    let ball = by.get("ball").expect("a ball track");
    let found = ball
        .iter()
        .filter(|p| {
            out.detections
                .iter()
                .find(|f| f.frame == p.frame)
                .is_some_and(|f| f.detections.iter().any(|d| (d.x - p.x).hypot(d.y - p.y) < 2.0))
        })
        .count();
    assert!(
        found >= 85,
        "the ball among the detections in {found} of {} frames",
        ball.len()
    );
}
