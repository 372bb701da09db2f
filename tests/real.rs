//! The whole pipeline on a real recording (`../shared/real`, skipped with a message when
//! absent): a ball that rolls off a shelf, falls and bounces on a floor, from a one-particle
//! structure with no bonds and no physics. physfit must find gravity and the floor, and say
//! that the ball was supported before it fell.

use std::path::{Path, PathBuf};

use serde_json::Value;

use crate::util::{physfit, read_xy, tempdir};

#[path = "../crates/track/tests/tracking/parabola.rs"]
mod parabola;
use parabola::parabola;

/// The folder of real recording `name`, or `None` (with a message) when it is absent.
fn real_dir(name: &str) -> Option<PathBuf> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../shared/real")
        .join(name);
    if dir.join("frames").is_dir() && dir.join("structure.toml").is_file() {
        Some(dir)
    } else {
        println!("skipped: real recording {} not found", dir.display());
        None
    }
}

/// `physfit run` on the real recording in `real` (its frames and structure) with `extra`
/// arguments: the temporary folder (kept alive by the caller), the output folder and
/// `report.json`.
fn run_real(real: &Path, extra: &[&str]) -> (tempfile::TempDir, PathBuf, Value) {
    let dir = tempdir();
    let out = dir.path().join("out");
    physfit()
        .arg("-q")
        .arg("run")
        .arg("--frames")
        .arg(real.join("frames"))
        .arg("--structure")
        .arg(real.join("structure.toml"))
        .arg("--out")
        .arg(&out)
        .args(extra)
        .assert()
        .success();
    let report: Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).expect("report.json"))
            .expect("report.json is JSON");
    (dir, out, report)
}

/// The named parameter of a finding.
fn parameter(finding: &Value, name: &str) -> f64 {
    finding["parameters"]
        .as_array()
        .and_then(|ps| ps.iter().find(|p| p["name"] == name))
        .and_then(|p| p["value"].as_f64())
        .unwrap_or_else(|| panic!("no parameter {name} in {finding}"))
}

#[test]
fn the_bouncing_ball_shows_gravity_a_floor_and_the_shelf() {
    let Some(real) = real_dir("bouncing-ball") else {
        return;
    };
    let (_dir, out, report) = run_real(&real, &[]);
    let findings = report["findings"].as_array().expect("findings");
    let names: Vec<&str> = findings.iter().filter_map(|f| f["effect"].as_str()).collect();
    println!("bouncing ball: findings {names:?}");
    let find = |effect: &str| {
        findings
            .iter()
            .find(|f| f["effect"] == effect)
            .unwrap_or_else(|| panic!("no {effect} among the findings {names:?}"))
    };

    // An independent measure of the field: parabolas through the tracked free flights between
    // bounces (lows of the track), their mean downward acceleration.
    let track = read_xy(&out.join("tracks.csv"));
    assert_eq!(track.len(), 87, "a ball position in every frame");
    let fps = 29.97;
    let lows: Vec<usize> = (1..track.len() - 1)
        .filter(|&k| track[k].3 > track[k - 1].3 && track[k].3 >= track[k + 1].3)
        .collect();
    let mut arcs = Vec::new();
    for pair in lows.windows(2) {
        let (a, b) = (pair[0] + 1, pair[1] - 1);
        if b + 1 - a >= 6 {
            let t: Vec<f64> = (a..=b).map(|k| track[k].0 as f64 / fps).collect();
            let y: Vec<f64> = (a..=b).map(|k| track[k].3).collect();
            arcs.push(2.0 * parabola(&t, &y).0[2]);
        }
    }
    assert!(arcs.len() >= 3, "free-flight arcs {arcs:?} (lows at {lows:?})");
    let arc_mean = arcs.iter().sum::<f64>() / arcs.len() as f64;

    let gravity = find("gravity");
    let (gx, gy) = (parameter(gravity, "gravity_x"), parameter(gravity, "gravity_y"));
    let g = gx.hypot(gy);
    let angle = gy.atan2(gx).to_degrees();
    println!("bouncing ball: gravity {g:.0} px/s^2 towards {angle:.1} degrees; free-flight arcs {arcs:?}");
    assert!(
        (angle - 90.0).abs() < 5.0,
        "the field points down: {angle:.1} degrees"
    );
    assert!(
        (g / arc_mean - 1.0).abs() < 0.15,
        "field {g:.0} px/s^2 against {arc_mean:.0} from the free-flight arcs"
    );

    // The floor: a horizontal wall through the ball's lowest positions, losing energy.
    let wall = find("wall");
    let (nx, ny) = (parameter(wall, "normal_x"), parameter(wall, "normal_y"));
    let offset = parameter(wall, "offset");
    let restitution = parameter(wall, "restitution");
    let lowest = track.iter().map(|p| p.3).fold(f64::NEG_INFINITY, f64::max);
    let x_low = track
        .iter()
        .max_by(|a, b| a.3.total_cmp(&b.3))
        .map(|p| p.2)
        .expect("points");
    let floor_y = (offset - nx * x_low) / ny;
    println!(
        "bouncing ball: floor y = {floor_y:.1} px (lowest tracked {lowest:.1}), normal ({nx:.3}, {ny:.3}), restitution {restitution:.3}"
    );
    assert!(
        ny < -0.99,
        "a horizontal floor whose normal points up: ({nx}, {ny})"
    );
    // The floor is placed no better than the model fits: friction at the bounces, which the
    // model cannot express (issue 22), leaves a residual of several px that the wall's line
    // shares (it tilts a little to take some of the horizontal loss).
    let last = report["final"]["costs"]["multi_step"]["rms"]
        .as_f64()
        .expect("final rms");
    assert!(
        (floor_y - lowest).abs() < 3.0 + 2.0 * last,
        "floor {floor_y:.1} px, lowest point {lowest:.1} px (final RMS {last:.2} px)"
    );
    assert!(
        restitution > 0.3 && restitution < 0.95,
        "restitution {restitution}: the bounces lose height"
    );

    // The shelf: the ball is supported in the first frames, and the report says so.
    let supports = report["localisation"]["supports"].as_array().expect("supports");
    let shelf = supports
        .iter()
        .find(|s| s["particle"] == "ball")
        .unwrap_or_else(|| panic!("no support found: {supports:?}"));
    let frames = [
        shelf["frames"][0].as_u64().expect("frame"),
        shelf["frames"][1].as_u64().expect("frame"),
    ];
    assert_eq!(frames[0], 0, "supported from the first frame: {frames:?}");
    assert!(frames[1] <= 8, "released within the first frames: {frames:?}");
    let md = std::fs::read_to_string(out.join("report.md")).expect("report.md");
    for words in ["supported in frames 0-", "gravity", "wall"] {
        assert!(md.contains(words), "report.md does not mention \"{words}\"");
    }

    // The diagnosed model follows the recording far better than the bare structure.
    let base = report["base"]["costs"]["multi_step"]["rms"]
        .as_f64()
        .expect("base rms");
    println!("bouncing ball: multi-step RMS {base:.2} -> {last:.2} px");
    assert!(last < base / 5.0, "multi-step RMS {base:.2} -> {last:.2} px");

    // The field and the floor, and nothing standing in for what happens at the bounces: a
    // quadratic drag or a tether fitted there fails transfer to other observed start states.
    // Friction at the floor is a candidate (issue 22) but not proposed: Coulomb friction only
    // takes tangential speed, and this ball, spinning from its roll off the shelf, leaves 4
    // of its 5 bounces faster along the floor than it came (measured from the track: 62 to
    // 81, 47 to 37, 21 to 42, 25 to 41 and 24 to 39 px/s). A point mass cannot express the
    // spin, so the remainder is stated as not explained, against the noise.
    let gains = lows
        .iter()
        .filter(|&&k| k >= 3 && k + 4 < track.len())
        .filter(|&&k| track[k + 4].2 - track[k + 1].2 > track[k].2 - track[k - 3].2)
        .count();
    println!("bouncing ball: {gains} bounce(s) gain horizontal speed (lows at {lows:?})");
    assert!(gains >= 3, "the bounces that gain speed along the floor: {gains}");
    assert!(!names.contains(&"wall_friction"), "{names:?}");
    let mut sorted = names.clone();
    sorted.sort_unstable();
    assert_eq!(sorted, ["gravity", "wall"], "{findings:?}");
    let verdict = &report["verdict"];
    assert_eq!(verdict["explained"], Value::Bool(false), "{verdict}");
    let text = verdict["text"].as_str().unwrap_or_default();
    assert!(
        text.starts_with("not explained: ") && text.contains("px RMS against a noise of"),
        "{text}"
    );
    println!("bouncing ball: {text}");
    for r in report["rejected"].as_array().cloned().unwrap_or_default() {
        if let Some(reason) = r["reason"].as_str() {
            println!("bouncing ball: rejected {}: {reason}", r["label"]);
        }
    }
}

/// The real pendulum (`pendulum-scale`) from its pixels, with a structure naming the bob alone:
/// a uniform field and a tether to a fixed point above the bob (a pendulum), with g/L within
/// 3 % of the reference's 9.69 s^-2, and nothing else. Before, a grid line through the bob cut
/// its track in two and the diagnosis named a field of 536 585 px/s^2 pointing up.
#[test]
fn the_real_pendulum_is_a_field_and_a_tether_above_the_bob() {
    let Some(real) = real_dir("pendulum-scale") else {
        return;
    };
    let (_dir, _, report) = run_real(&real, &[]);
    let findings = report["findings"].as_array().expect("findings");
    let mut names: Vec<&str> = findings.iter().filter_map(|f| f["effect"].as_str()).collect();
    names.sort_unstable();
    assert_eq!(names, ["gravity", "missing_spring"], "{findings:?}");
    let field = findings.iter().find(|f| f["effect"] == "gravity").expect("field");
    let tether = findings
        .iter()
        .find(|f| f["effect"] == "missing_spring")
        .expect("tether");
    let (gx, gy) = (parameter(field, "gravity_x"), parameter(field, "gravity_y"));
    let (ax, ay) = (parameter(tether, "anchor_x"), parameter(tether, "anchor_y"));
    let length = parameter(tether, "length");
    let g_over_l = gx.hypot(gy) / length;
    println!("field ({gx:.1}, {gy:.1}) px/s^2, anchor ({ax:.1}, {ay:.1}) px, length {length:.1} px, g/L {g_over_l:.3} s^-2");
    assert!(
        gy > 0.0 && gx.abs() < 0.05 * gy,
        "the field points down: ({gx}, {gy})"
    );
    assert!(
        (g_over_l / 9.69 - 1.0).abs() < 0.03,
        "g/L {g_over_l} s^-2, reference 9.69"
    );
    // Above the bob's lowest point (y about 207) by about the length, near the middle of the swing.
    assert!(
        ay < 207.0 - 0.9 * length && ay > 207.0 - 1.1 * length,
        "anchor ({ax}, {ay})"
    );
    assert!((ax - 154.0).abs() < 10.0, "anchor ({ax}, {ay})");
}

/// The real pendulum with its scale. The picture's own ruler (the lines marked 0, 60, 80 and
/// 100 cm on the right, at rows 33.5, 136.5, 171 and 205.5 px in every frame) gives 172 px a
/// metre (0.6 m = 103 px, 0.4 m = 69 px): `--scale 1/172` m/px. (The 1/182 first proposed
/// for this recording gave g = 9.10 m/s^2 from the same fit.) Every fitted value gets its SI
/// value (the field in m/s^2, positions and the tether's length in m) and the report says
/// masses are taken as kg. The field strength in m/s^2 is the px field times the scale
/// exactly; physically it must be the Earth's, and the tether the 1 m string ("length: 1 m"
/// in the picture).
#[test]
fn the_real_pendulum_reports_g_in_metres_per_second_squared() {
    let Some(real) = real_dir("pendulum-scale") else {
        return;
    };
    let scale = 1.0 / 172.0;
    let (_dir, out, report) = run_real(&real, &["--scale", &format!("{scale}")]);
    assert!((report["units"]["metres_per_px"].as_f64().unwrap() - scale).abs() < 1e-15);
    assert_eq!(report["units"]["mass_unit"], "kg");
    let findings = report["findings"].as_array().expect("findings");
    let field = findings.iter().find(|f| f["effect"] == "gravity").expect("field");
    let value = |f: &Value, name: &str, key: &str| {
        f["parameters"]
            .as_array()
            .and_then(|ps| ps.iter().find(|p| p["name"] == name))
            .and_then(|p| p[key].as_f64())
            .unwrap_or_else(|| panic!("no {key} of {name} in {f}"))
    };
    for axis in ["gravity_x", "gravity_y"] {
        let px = value(field, axis, "value");
        let si = value(field, axis, "value_si");
        assert!(
            (si - px * scale).abs() <= 1e-12 * px.abs(),
            "{axis}: {si} vs {px} px/s^2"
        );
        assert!((value(field, axis, "std_error_si") - value(field, axis, "std_error") * scale).abs() < 1e-12);
    }
    let g = value(field, "gravity_x", "value_si").hypot(value(field, "gravity_y", "value_si"));
    let tether = findings
        .iter()
        .find(|f| f["effect"] == "missing_spring")
        .expect("tether");
    let length_m = value(tether, "length", "value_si");
    println!(
        "pendulum at 1/172 m/px: g = {g:.3} m/s^2, tether {length_m:.3} m, g/L = {:.3} s^-2",
        g / length_m
    );
    assert!((g / 9.81 - 1.0).abs() < 0.03, "g = {g} m/s^2");
    assert!((length_m - 1.0).abs() < 0.05, "tether {length_m} m");
    let md = std::fs::read_to_string(out.join("report.md")).unwrap();
    assert!(md.contains("m/s^2") && md.contains("masses as kg"), "{md}");
    assert!(md.contains("; g = "), "{md}");
}

/// Ball-toss (13 frames, the ball in the hand in frames 0-1, analysed over 2-12): 11 frames
/// of flight carry a field and nothing more. The tracks' slow bias (about 0.66 px RMS off
/// any parabola, against 0.053 px of jitter) once let a far tether in; not identified, and
/// no better than a smooth track bias of its size, it is now reported as "not enough data".
/// The hand clicks' parabola gives about (0, 4100) px/s^2.
#[test]
fn the_ball_toss_is_a_field_and_nothing_else() {
    let Some(real) = real_dir("ball-toss") else {
        return;
    };
    let (_dir, _, report) = run_real(&real, &["--window", "2..12"]);
    let findings = report["findings"].as_array().expect("findings");
    let names: Vec<&str> = findings.iter().filter_map(|f| f["effect"].as_str()).collect();
    assert_eq!(names, ["gravity"], "{findings:?}");
    let (gx, gy) = (
        parameter(&findings[0], "gravity_x"),
        parameter(&findings[0], "gravity_y"),
    );
    println!(
        "ball-toss: field ({gx:.1}, {gy:.1}) px/s^2; undecided {}",
        report["undecided"]
    );
    let off = gx.hypot(gy - 4100.0) / 4100.0;
    assert!(
        off < 0.10,
        "field ({gx}, {gy}) is {:.1} % from (0, 4100)",
        100.0 * off
    );
}
