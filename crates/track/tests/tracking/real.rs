//! Real recordings (`/work/shared/real`, skipped with a message when absent): the tracker
//! must follow a ball in camera footage it was never tuned on.

use std::path::PathBuf;

use physfit_track::{PointFlag, TrackOptions, TrackTable};

use crate::common::track;

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

#[test]
#[ignore = "known failure (issue 3): the radius reads 9.16 px (right) but no blob is found in 19 frames (frame 0 among them) and the track is lost over frames 8-18 (76 of 87 points); with the expected area and radius weighted by light the ball is followed through every bounce (largest step 32.7 px, 79 of 87 detected, first five lows 360-368 px) but ball-toss then fails; run with --ignored"]
fn bouncing_ball_is_followed_through_every_frame() {
    let Some(dir) = real_dir("bouncing-ball") else {
        return;
    };
    let out = track(
        &dir.join("frames"),
        &TrackOptions {
            named_start: Some(vec![("ball".into(), [24.0, 19.6])]),
            ..TrackOptions::default()
        },
    );
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
    assert!(lows.len() >= 2, "at least two bounces: {lows:?}");
    // Every bounce happens on the same floor: the lowest points agree within a few pixels.
    let ys: Vec<f64> = lows.iter().map(|l| l.2).collect();
    let (lo, hi) = ys.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &y| {
        (a.min(y), b.max(y))
    });
    assert!(hi - lo < 8.0, "bounce heights {ys:?}");
    write_for_inspection(&out.table);
}

/// Leaves the track where a person can look at it when asked to (PHYSFIT_KEEP_TRACKS).
fn write_for_inspection(table: &TrackTable) {
    if let Ok(path) = std::env::var("PHYSFIT_KEEP_TRACKS") {
        table
            .write_csv(std::path::Path::new(&path))
            .expect("write tracks");
    }
}
