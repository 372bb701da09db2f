//! `physfit render` and `physfit simulate`, end to end.

use predicates::prelude::*;

use crate::util::{physfit, read_xy, simulate, tempdir, write};

const TWO_DISCS: &str = r#"
name = "two"
[recording]
fps = 50.0
frames = 5
substeps = 10
[render]
width = 64
height = 48
radius = 4.0
background = 20
foreground = 220
[[particles]]
id = "a"
mass = 1.0
position = [20.0, 24.0]
velocity = [10.0, 0.0]
[[particles]]
id = "b"
mass = 2.0
position = [44.0, 24.0]
[[springs]]
between = ["a", "b"]
length = 20.0
stiffness = 50.0
"#;

#[test]
fn render_writes_frames_truth_structure_and_scene() {
    let dir = tempdir();
    let scene = write(dir.path(), "two.toml", TWO_DISCS);
    let out = dir.path().join("out");
    physfit()
        .arg("render")
        .arg(&scene)
        .arg("--out")
        .arg(&out)
        .assert()
        .success();

    let frames: Vec<_> = std::fs::read_dir(out.join("frames"))
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert_eq!(frames.len(), 5);
    let img = image::open(out.join("frames/000000.png")).unwrap().to_luma8();
    assert_eq!(img.dimensions(), (64, 48));
    // Disc centres are foreground, a far corner is background.
    assert_eq!(img.get_pixel(20, 24)[0], 220);
    assert_eq!(img.get_pixel(44, 24)[0], 220);
    assert_eq!(img.get_pixel(0, 0)[0], 20);
    assert_eq!(img.get_pixel(32, 5)[0], 20);

    // truth.csv starts at the scene's frame-0 positions, named by id.
    let truth = read_xy(&out.join("truth.csv"));
    assert_eq!(truth.len(), 10);
    assert_eq!(truth[0], (0, "a".to_string(), 20.0, 24.0));
    assert_eq!(truth[1], (0, "b".to_string(), 44.0, 24.0));
    // Two bodies on a spring, solved analytically: the centre of mass drifts at 10/3 px/s and
    // the separation r oscillates about L = 20 with omega = sqrt(2 S / mu), mu = 2/3.
    let t = 4.0 / 50.0;
    let omega = (2.0_f64 * 50.0 / (2.0 / 3.0)).sqrt();
    let r = 20.0 + 4.0 * (omega * t).cos() - 10.0 / omega * (omega * t).sin();
    let expected_a = 36.0 + 10.0 / 3.0 * t - 2.0 / 3.0 * r;
    let last_a = truth.iter().find(|r| r.0 == 4 && r.1 == "a").unwrap();
    assert!((last_a.2 - expected_a).abs() < 1e-3, "{last_a:?} vs {expected_a}");

    // structure.toml keeps topology and positions but no values; scene.toml keeps values.
    let structure = std::fs::read_to_string(out.join("structure.toml")).unwrap();
    assert!(
        structure.contains("between = [\"a\", \"b\"]") && !structure.contains("stiffness"),
        "{structure}"
    );
    let full = std::fs::read_to_string(out.join("scene.toml")).unwrap();
    assert!(full.contains("stiffness = 50.0"), "{full}");
    // No staging leftovers, inside or beside; the list of physfit's outputs.
    for d in [&out, &dir.path().to_path_buf()] {
        let names: Vec<String> = std::fs::read_dir(d)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        assert!(
            names
                .iter()
                .all(|n| !n.starts_with('.') || n == ".physfit-outputs"),
            "{names:?}"
        );
    }
    let listed = std::fs::read_to_string(out.join(".physfit-outputs")).unwrap();
    assert!(listed.lines().any(|l| l == "frames/000004.png") && listed.contains("truth.csv\n"));
}

#[test]
fn render_is_deterministic_for_a_seed() {
    let dir = tempdir();
    let noisy = TWO_DISCS.replace("foreground = 220", "foreground = 220\nnoise = 8.0\nseed = 3");
    let scene = write(dir.path(), "noisy.toml", &noisy);
    for out in ["o1", "o2"] {
        physfit()
            .arg("render")
            .arg(&scene)
            .arg("--out")
            .arg(dir.path().join(out))
            .assert()
            .success();
    }
    let a = std::fs::read(dir.path().join("o1/frames/000003.png")).unwrap();
    let b = std::fs::read(dir.path().join("o2/frames/000003.png")).unwrap();
    assert_eq!(a, b);
    physfit()
        .arg("render")
        .arg(&scene)
        .arg("--seed")
        .arg("4")
        .arg("--out")
        .arg(dir.path().join("o3"))
        .assert()
        .success();
    let c = std::fs::read(dir.path().join("o3/frames/000003.png")).unwrap();
    assert_ne!(a, c);
}

#[test]
fn simulate_matches_render_truth() {
    let dir = tempdir();
    let scene = write(dir.path(), "two.toml", TWO_DISCS);
    simulate(&scene, &dir.path().join("t.csv"));
    physfit()
        .arg("render")
        .arg(&scene)
        .arg("--out")
        .arg(dir.path().join("r"))
        .assert()
        .success();
    assert_eq!(
        read_xy(&dir.path().join("t.csv")),
        read_xy(&dir.path().join("r/truth.csv"))
    );
}

#[test]
fn bad_scene_names_the_file_and_key_and_fails() {
    let dir = tempdir();
    let scene = write(
        dir.path(),
        "bad.toml",
        &TWO_DISCS.replace("mass = 2.0", "mass = -2.0"),
    );
    physfit()
        .arg("render")
        .arg(&scene)
        .arg("--out")
        .arg(dir.path().join("out"))
        .assert()
        .failure()
        .stderr(
            predicate::str::contains("bad.toml").and(predicate::str::contains("particle \"b\" has mass -2")),
        );
    assert!(!dir.path().join("out/frames").exists());

    let typo = write(
        dir.path(),
        "typo.toml",
        &TWO_DISCS.replace("stiffness = 50.0", "stifness = 50.0"),
    );
    physfit()
        .arg("simulate")
        .arg(&typo)
        .arg("--out")
        .arg(dir.path().join("t.csv"))
        .assert()
        .failure()
        .stderr(predicate::str::contains("typo.toml:").and(predicate::str::contains("stifness")));
    assert!(!dir.path().join("t.csv").exists());
}

#[test]
fn structure_cannot_be_rendered_and_error_names_the_bond() {
    let dir = tempdir();
    let scene = write(dir.path(), "s.toml", &TWO_DISCS.replace("stiffness = 50.0", ""));
    physfit()
        .arg("render")
        .arg(&scene)
        .arg("--out")
        .arg(dir.path().join("out"))
        .assert()
        .failure()
        .stderr(predicate::str::contains("spring a-b has no stiffness"));
}

#[test]
fn missing_scene_file_is_a_clear_error() {
    physfit()
        .args(["render", "/nonexistent/scene.toml", "--out", "/tmp/never"])
        .assert()
        .failure()
        .stderr(predicate::str::contains("/nonexistent/scene.toml"));
}
