//! `physfit run` on a folder of frames: windows, frame rates, and failures that name their
//! stage. (The default run is checked end to end by `getting_started`.)

use predicates::prelude::*;

use crate::util::{physfit, read_xy, scenes_dir, tempdir, write};

#[test]
fn a_window_and_a_frame_rate_are_honoured_on_a_folder_of_frames() {
    let dir = tempdir();
    let rendered = dir.path().join("r");
    physfit()
        .args(["-q", "render"])
        .arg(scenes_dir().join("concealed-gravity.toml"))
        .arg("--out")
        .arg(&rendered)
        .assert()
        .success();
    // The structure of a window starting at frame 60: positions of frame 60.
    let (a, b) = (60usize, 259usize);
    let truth = read_xy(&rendered.join("truth.csv"));
    let mut structure = physfit_model::Scene::load(&rendered.join("structure.toml")).unwrap();
    for p in &mut structure.particles {
        let &(_, _, x, y) = truth
            .iter()
            .find(|t| t.0 == a && t.1 == p.id)
            .expect("truth at frame a");
        p.position = physfit_model::Vec2::new(x, y);
    }
    let structure_path = dir.path().join("structure-60.toml");
    structure.save(&structure_path).unwrap();
    // Claim twice the true frame rate: time halves, so accelerations read four times larger.
    let fps = 2.0 * structure.recording.fps;
    let out = dir.path().join("out");
    physfit()
        .args(["-q", "run", "--frames"])
        .arg(rendered.join("frames"))
        .arg("--structure")
        .arg(&structure_path)
        .args([
            "--fps",
            &fps.to_string(),
            "--window",
            &format!("{a}..{b}"),
            "--out",
        ])
        .arg(&out)
        .assert()
        .success()
        .stdout(predicate::str::is_empty());
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).unwrap()).unwrap();
    assert_eq!(crate::util::assert_finite_outputs(&out), 4);
    assert_eq!(report["given"]["kind"], "recording");
    assert_eq!(report["tracking"]["frames"], serde_json::json!([a, b]));
    assert_eq!(report["window"], serde_json::json!([a, b]));
    let findings = report["findings"].as_array().unwrap();
    assert_eq!(findings.len(), 1, "{findings:?}");
    assert_eq!(findings[0]["effect"], "gravity");
    let scene = physfit_model::Scene::load(&scenes_dir().join("concealed-gravity.toml")).unwrap();
    let g = |name: &str| {
        findings[0]["parameters"]
            .as_array()
            .unwrap()
            .iter()
            .find(|p| p["name"] == name)
            .and_then(|p| p["value"].as_f64())
            .unwrap()
    };
    let (gx, gy) = (g("gravity_x"), g("gravity_y"));
    let expected = 4.0 * scene.physics.gravity;
    assert!(
        (gx - expected.x).hypot(gy - expected.y) < 0.02 * expected.norm(),
        "gravity ({gx}, {gy}) against 4 x the truth {expected:?}"
    );
    let tracks = read_xy(&out.join("tracks.csv"));
    assert!(tracks.iter().all(|t| (a..=b).contains(&t.0)));
}

#[test]
fn a_failed_stage_is_named_and_leaves_the_folder_as_it_was() {
    let dir = tempdir();
    let out = dir.path().join("out");
    std::fs::create_dir(&out).unwrap();
    // An earlier run's outputs, listed as physfit's.
    write(&out, "report.md", "an earlier run's report");
    write(&out, "fitted.toml", "an earlier run's model");
    write(&out, ".physfit-outputs", "fitted.toml\nreport.md\n");
    let structure = write(
        dir.path(),
        "s.toml",
        "name = \"s\"\n[recording]\nfps = 30\nframes = 2\n[[particles]]\nid = \"a\"\nmass = 1\nposition = [5, 5]\n",
    );
    let missing = dir.path().join("no-such-frames");
    physfit()
        .args(["run", "--frames"])
        .arg(&missing)
        .arg("--structure")
        .arg(&structure)
        .arg("--out")
        .arg(&out)
        .assert()
        .failure()
        .stderr(predicate::str::contains("stage track").and(predicate::str::contains("no-such-frames")));
    for (name, text) in [
        ("report.md", "an earlier run's report"),
        ("fitted.toml", "an earlier run's model"),
    ] {
        assert_eq!(
            std::fs::read_to_string(out.join(name)).unwrap(),
            text,
            "{name} changed"
        );
    }
    let left: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.contains("physfit-"))
        .collect();
    assert!(left.is_empty(), "staging left behind: {left:?}");

    physfit()
        .args(["run", "--frames"])
        .arg(&missing)
        .assert()
        .failure()
        .stderr(predicate::str::contains("--structure"));
    physfit()
        .args(["run", "--frames"])
        .arg(&missing)
        .arg("--structure")
        .arg(&structure)
        .arg("--fps=-3")
        .assert()
        .failure()
        .stderr(predicate::str::contains("--fps -3").and(predicate::str::contains("frame rate")));
}

#[test]
fn a_fixed_pivot_out_of_view_is_not_tracked() {
    // A pendulum whose pivot lies 200 px above the frame: the camera sees the bob alone. The
    // pivot's position is in the scene; tracking it was refused ("detected in 0 frames").
    let dir = tempdir();
    let scene = write(
        dir.path(),
        "pendulum.toml",
        r#"
        name = "pendulum-out-of-view"
        [recording]
        fps = 60.0
        frames = 60
        substeps = 10
        [render]
        width = 200
        height = 200
        radius = 5.0
        [[particles]]
        id = "bob"
        mass = 1.0
        position = [100.0, 150.0]
        velocity = [60.0, 0.0]
        [[particles]]
        id = "pivot"
        mass = 1.0
        position = [100.0, -200.0]
        fixed = true
        [[springs]]
        between = ["bob", "pivot"]
        length = 349.0
        stiffness = 3000.0
        [physics]
        gravity = [0.0, 600.0]
    "#,
    );
    let out = dir.path().join("out");
    physfit()
        .args(["-q", "run"])
        .arg(&scene)
        .arg("--out")
        .arg(&out)
        .assert()
        .success();
    let tracks = std::fs::read_to_string(out.join("tracks.csv")).expect("tracks.csv");
    let rows: Vec<&str> = tracks.lines().skip(1).collect();
    assert_eq!(rows.len(), 60, "one bob point per frame: {tracks}");
    assert!(
        rows.iter().all(|r| r.split(',').nth(1) == Some("bob")),
        "{tracks}"
    );
}
