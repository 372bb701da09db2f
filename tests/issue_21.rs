//! Issue 21: an honest verdict. Every report (`report.md`, `report.html`, `report.json`, the
//! printed summary) compares the final multi-step residual with the track noise, says
//! "not explained" with where the residual lives when it is far above the noise, never claims
//! the noise level it does not reach, and holds no NaN or inf, on inputs that once produced
//! them (exact tracks with a measured noise of 0, a particle at rest, motion no candidate
//! explains).

use std::path::Path;

use serde_json::Value;

use crate::util::{physfit, simulate, tempdir, write};

/// The tokens of `text` (runs of letters) that spell a non-finite number.
fn non_finite_tokens(text: &str) -> Vec<String> {
    text.split(|c: char| !c.is_ascii_alphabetic())
        .filter(|t| matches!(t.to_ascii_lowercase().as_str(), "nan" | "inf" | "infinity"))
        .map(str::to_string)
        .collect()
}

/// `report.html` without its inlined pictures (base64 runs could spell anything).
fn without_data_uris(html: &str) -> String {
    let mut out = String::with_capacity(html.len());
    let mut rest = html;
    while let Some(i) = rest.find("data:") {
        out.push_str(&rest[..i]);
        rest = &rest[i..];
        rest = rest.find('"').map_or("", |j| &rest[j..]);
    }
    out.push_str(rest);
    out
}

/// Diagnoses `tracks` against `structure` into a fresh folder; returns the printed summary,
/// `report.json`, and every report's text, after asserting none holds NaN or inf.
fn diagnose(tracks: &Path, structure: &Path, out: &Path) -> (String, Value) {
    let output = physfit()
        .arg("diagnose")
        .arg(tracks)
        .arg("--structure")
        .arg(structure)
        .arg("--out")
        .arg(out)
        .output()
        .expect("physfit runs");
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    // The output folder's name is the test's, not the report's: left out of the scan.
    let stdout = String::from_utf8_lossy(&output.stdout).replace(&out.display().to_string(), "OUT");
    let md = std::fs::read_to_string(out.join("report.md")).expect("report.md");
    let json_text = std::fs::read_to_string(out.join("report.json")).expect("report.json");
    let html = std::fs::read_to_string(out.join("report.html")).expect("report.html");
    for (name, text) in [
        ("summary", stdout.as_str()),
        ("report.md", md.as_str()),
        ("report.json", json_text.as_str()),
        ("report.html", without_data_uris(&html).as_str()),
    ] {
        let bad = non_finite_tokens(text);
        assert!(
            bad.is_empty(),
            "{name} of {} holds {bad:?}:\n{text}",
            tracks.display()
        );
    }
    let json: Value = serde_json::from_str(&json_text).expect("report.json is JSON");
    let verdict = &json["verdict"];
    for key in [
        "explained",
        "rms",
        "noise",
        "ratio",
        "threshold",
        "text",
        "pattern",
    ] {
        assert!(!verdict[key].is_null(), "verdict.{key} missing: {verdict}");
    }
    // The summary and report.md carry the verdict; none claims the noise level wrongly.
    let text = verdict["text"].as_str().unwrap_or_default().to_string();
    assert!(stdout.contains(&format!("verdict: {text}")), "{stdout}");
    assert!(md.to_lowercase().contains(&text.to_lowercase()), "{md}");
    let explained = verdict["explained"].as_bool().unwrap_or(false);
    if !explained {
        for (name, t) in [("summary", &stdout), ("report.md", &md)] {
            assert!(
                !t.contains("explains the tracks to the noise level")
                    && !t.contains("explained to the noise level"),
                "{name} claims the noise level for {}:\n{t}",
                tracks.display()
            );
        }
    }
    (stdout, json)
}

/// A tracks CSV of one particle `ball` at `positions` (frame k at index k).
fn ball_csv(dir: &Path, name: &str, positions: &[(f64, f64)]) -> std::path::PathBuf {
    let mut s = String::from("frame,particle,x,y\n");
    for (k, (x, y)) in positions.iter().enumerate() {
        s.push_str(&format!("{k},ball,{x},{y}\n"));
    }
    write(dir, name, &s)
}

const BALL: &str = r#"
name = "ball"
[recording]
fps = 60.0
frames = 240
[[particles]]
id = "ball"
mass = 1.0
position = [100.0, 200.0]
"#;

/// Deterministic pseudo-noise in [-a, a] (a small linear congruential sequence: seeded and
/// dependency-free).
fn jitter(seed: &mut u64, a: f64) -> f64 {
    *seed = seed
        .wrapping_mul(6364136223846793005)
        .wrapping_add(1442695040888963407);
    ((*seed >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0) * a
}

#[test]
fn motion_no_candidate_explains_is_reported_as_not_explained() {
    // A ball drifting right with a wobble no field, drag, tether or wall produces: the
    // verdict must say "not explained", with the particle and the frames, and its RMS must
    // be the final model's.
    let dir = tempdir();
    let d = dir.path();
    let mut seed = 21;
    let positions: Vec<(f64, f64)> = (0..240)
        .map(|k| {
            let t = k as f64 / 60.0;
            let w = (std::f64::consts::TAU * 1.3 * t).sin() * (1.0 + t);
            (
                100.0 + 60.0 * t + 8.0 * w + jitter(&mut seed, 0.08),
                200.0 + 5.0 * w * w + jitter(&mut seed, 0.08),
            )
        })
        .collect();
    let tracks = ball_csv(d, "wobble.csv", &positions);
    let structure = write(d, "ball.toml", BALL);
    let (stdout, json) = diagnose(&tracks, &structure, &d.join("out"));
    let v = &json["verdict"];
    assert_eq!(v["explained"], Value::Bool(false), "{stdout}");
    let text = v["text"].as_str().unwrap_or_default();
    assert!(text.starts_with("not explained: "), "{text}");
    assert!(text.contains("px RMS against a noise of"), "{text}");
    let rms = v["rms"].as_f64().unwrap_or(f64::NAN);
    let noise = v["noise"].as_f64().unwrap_or(f64::NAN);
    assert!(rms > 2.0 * noise, "rms {rms}, noise {noise}");
    let final_rms = json["final"]["costs"]["multi_step"]["rms"]
        .as_f64()
        .unwrap_or(f64::NAN);
    assert!(
        (rms - final_rms).abs() <= 1e-9 * final_rms.max(1.0),
        "{rms} vs {final_rms}"
    );
    assert_eq!(v["particles"][0]["particle"], "ball");
    assert!(!v["frames"].as_array().map_or(true, Vec::is_empty), "{v}");
    assert!(!json["search"]["stop_reason"]
        .as_str()
        .unwrap_or_default()
        .is_empty());
    // Whatever was found is honest about what the tracks determine: a magnitude whose
    // standard error exceeds it, or a tether's anchor far beyond the motion, is marked not
    // identified, with a note.
    let n = positions.len() as f64;
    let mean = (
        positions.iter().map(|p| p.0).sum::<f64>() / n,
        positions.iter().map(|p| p.1).sum::<f64>() / n,
    );
    let extent = positions
        .iter()
        .map(|p| (p.0 - mean.0).hypot(p.1 - mean.1))
        .fold(0.0, f64::max);
    for f in json["findings"].as_array().cloned().unwrap_or_default() {
        let value = |name: &str| {
            f["parameters"]
                .as_array()
                .and_then(|ps| ps.iter().find(|p| p["name"] == name))
                .and_then(|p| p["value"].as_f64())
        };
        let vague = f["parameters"].as_array().is_some_and(|ps| {
            ps.iter().any(|p| {
                let name = p["name"].as_str().unwrap_or_default();
                let magnitude = !name.ends_with("_x") && !name.ends_with("_y") && name != "offset";
                magnitude
                    && p["std_error"]
                        .as_f64()
                        .zip(p["value"].as_f64())
                        .is_some_and(|(e, v)| e > v.abs())
            })
        });
        let far = f["tether"].as_bool().unwrap_or(false)
            && value("anchor_x")
                .zip(value("anchor_y"))
                .is_some_and(|(x, y)| (x - mean.0).hypot(y - mean.1) > 10.0 * extent);
        if vague || far {
            assert_eq!(f["identified"], Value::Bool(false), "{f}");
            assert!(f["note"].as_str().is_some_and(|n| !n.is_empty()), "{f}");
        }
        if far {
            assert!(f["note"].as_str().unwrap_or_default().contains("runs off"), "{f}");
        }
    }
}

#[test]
fn exact_tracks_and_a_particle_at_rest_give_finite_reports() {
    let dir = tempdir();
    let d = dir.path();
    // Exact simulated tracks (a measured noise of 0) of a ball falling onto a floor.
    let scene = write(
        d,
        "drop.toml",
        r#"
name = "ball"
[recording]
fps = 30.0
frames = 60
[[particles]]
id = "ball"
mass = 1.0
position = [100.0, 40.0]
velocity = [20.0, 0.0]
[physics]
gravity = [0.0, 2000.0]
[[physics.walls]]
point = [0.0, 400.0]
normal = [0.0, -1.0]
restitution = 0.7
"#,
    );
    let truth = d.join("truth.csv");
    simulate(&scene, &truth);
    let structure = write(d, "ball.toml", BALL);
    let (stdout, json) = diagnose(&truth, &structure, &d.join("exact"));
    assert!(
        json["verdict"]["noise"].as_f64().is_some_and(|n| n > 0.0),
        "{}",
        json["verdict"]
    );
    let effects: Vec<&str> = json["findings"]
        .as_array()
        .map(|f| f.iter().filter_map(|f| f["effect"].as_str()).collect())
        .unwrap_or_default();
    assert!(
        effects.contains(&"gravity") && effects.contains(&"wall"),
        "{stdout}"
    );

    // A ball bouncing every few frames at 24 frames/s, with noise: no weak-form window is
    // free of bounces (the localisation once printed "against NaN from noise" here).
    let scene = write(
        d,
        "drop24.toml",
        r#"
name = "drop"
[recording]
fps = 24.0
frames = 60
substeps = 40
[[particles]]
id = "ball"
mass = 1.0
position = [483.0, 37.0]
velocity = [15.0, 100.0]
[physics]
gravity = [0.0, 5900.0]
[[physics.walls]]
point = [0.0, 476.0]
normal = [0.0, -1.0]
restitution = 0.6
"#,
    );
    let exact = d.join("drop24-exact.csv");
    simulate(&scene, &exact);
    let mut seed = 24;
    let positions: Vec<(f64, f64)> = crate::util::read_xy(&exact)
        .into_iter()
        .map(|(_, _, x, y)| (x + jitter(&mut seed, 0.08), y + jitter(&mut seed, 0.08)))
        .collect();
    let noisy = ball_csv(d, "drop24.csv", &positions);
    let (stdout, _) = diagnose(&noisy, &structure, &d.join("drop24"));
    assert!(stdout.contains("verdict: "), "{stdout}");

    // A particle that never moves, exactly.
    let still = ball_csv(d, "still.csv", &vec![(120.0, 80.0); 60]);
    let (stdout, json) = diagnose(&still, &structure, &d.join("still"));
    assert!(json["findings"].as_array().is_some_and(Vec::is_empty), "{stdout}");
    assert_eq!(json["verdict"]["explained"], Value::Bool(true), "{stdout}");
}

/// Seeded Gaussian noise of standard deviation `sigma` (Box-Muller on [`jitter`]'s sequence).
fn gaussian(seed: &mut u64, sigma: f64) -> f64 {
    let u1 = 0.5 * (jitter(seed, 1.0) + 1.0);
    let u2 = 0.5 * (jitter(seed, 1.0) + 1.0);
    sigma * (-2.0 * u1.max(1e-300).ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
}

#[test]
fn a_puck_sliding_to_rest_is_surface_friction_not_a_tether_with_quadratic_drag() {
    // Dry (Coulomb) friction with the table under a puck seen from above: a uniform
    // deceleration of 400 px/s^2 to rest after 1.28 s, then at rest, tracked at 60 frames/s.
    // A stiff tether at the stop point with strong quadratic drag once fitted it to the noise
    // level ("explained"): such a model forgets how it was launched, so it fits this one path
    // only. Before the surface's friction was a candidate, a rail along the path, pressed by
    // an invented field of 8075 px/s^2 with friction 0.025 on it, also fitted it.
    let dir = tempdir();
    let d = dir.path();
    let structure = write(d, "ball.toml", BALL);
    for (k, sigma) in [0.05, 0.01].into_iter().enumerate() {
        let mut seed = 7 + k as u64;
        let (v0, a) = ((480.0f64, 180.0f64), 400.0);
        let speed = v0.0.hypot(v0.1);
        let stop = speed / a;
        let positions: Vec<(f64, f64)> = (0..240)
            .map(|j| {
                let t = (j as f64 / 60.0).min(stop);
                let s = speed * t - 0.5 * a * t * t;
                (
                    100.0 + v0.0 / speed * s + gaussian(&mut seed, sigma),
                    200.0 + v0.1 / speed * s + gaussian(&mut seed, sigma),
                )
            })
            .collect();
        let tracks = ball_csv(d, &format!("puck{k}.csv"), &positions);
        let (stdout, json) = diagnose(&tracks, &structure, &d.join(format!("puck{k}")));
        let findings = json["findings"].as_array().cloned().unwrap_or_default();
        let tether = findings.iter().any(|f| f["tether"] == Value::Bool(true));
        let quadratic = findings.iter().any(|f| f["effect"] == "quadratic_drag");
        assert!(
            !(tether && quadratic),
            "noise {sigma}: a tether with quadratic drag explains dry friction:\n{stdout}"
        );
        let names: Vec<&str> = findings.iter().filter_map(|f| f["effect"].as_str()).collect();
        assert_eq!(names, ["surface_friction"], "noise {sigma}:\n{stdout}");
        let found = findings[0]["parameters"][0]["value"].as_f64().unwrap_or(f64::NAN);
        assert!(
            (found / a - 1.0).abs() < 0.01,
            "noise {sigma}: surface friction {found} px/s^2 against {a}:\n{stdout}"
        );
        assert_eq!(
            json["verdict"]["explained"],
            Value::Bool(true),
            "noise {sigma}:\n{stdout}"
        );
        // What is named transfers (or the segments cannot tell), with the figures.
        for f in &findings {
            let t = &f["evidence"]["transfer"];
            assert_ne!(t["transfers"], Value::Bool(false), "noise {sigma}: {f}");
        }
        for r in json["rejected"].as_array().cloned().unwrap_or_default() {
            if let Some(reason) = r["reason"].as_str() {
                assert!(reason.starts_with("fits one path only: "), "{reason}");
                assert!(reason.contains("px RMS with it"), "{reason}");
            }
        }
    }
}
