//! `docs/getting-started.md`, run as written: every `cargo run --release --` line in order, in
//! a scratch folder holding a copy of `scenes/`, then the properties the page promises. This
//! is also the end-to-end test of `physfit run` on the built-in default scene.

use std::path::{Path, PathBuf};

use crate::util::{physfit, tempdir};

const CARGO_RUN: &str = "cargo run --release --";
/// The page's ffmpeg lines (section 4 makes its video with them).
const FFMPEG: &str = "ffmpeg ";

/// The repository's root.
fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// The shell lines of the page's ```sh blocks, in order.
fn shell_lines(page: &str) -> Vec<String> {
    let mut lines = Vec::new();
    let mut in_block = false;
    for line in page.lines() {
        let t = line.trim();
        if t.starts_with("```") {
            in_block = !in_block && t == "```sh";
            continue;
        }
        if in_block && !t.is_empty() {
            lines.push(t.to_string());
        }
    }
    lines
}

fn json(path: &Path) -> serde_json::Value {
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    serde_json::from_str(&text).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

fn effects(report: &serde_json::Value) -> Vec<String> {
    report["findings"]
        .as_array()
        .expect("findings list")
        .iter()
        .map(|f| f["effect"].as_str().expect("effect name").to_string())
        .collect()
}

/// The value of `name` in a finding's parameter list.
fn finding_value(finding: &serde_json::Value, name: &str) -> f64 {
    finding["parameters"]
        .as_array()
        .expect("parameters")
        .iter()
        .find(|p| p["name"] == name)
        .and_then(|p| p["value"].as_f64())
        .unwrap_or_else(|| panic!("no {name} in {finding}"))
}

/// Every `<img>` of an HTML page takes its picture from a `data:` URI.
fn assert_self_contained(html: &str) {
    let mut images = 0;
    for (k, _) in html.match_indices("<img") {
        let tag = &html[k..k + html[k..].find('>').expect("closed tag")];
        let src = tag.split("src=\"").nth(1).expect("img with src");
        assert!(
            src.starts_with("data:image/png;base64,"),
            "external picture in {tag:.120}"
        );
        images += 1;
    }
    assert!(images >= 5, "only {images} pictures in report.html");
    assert!(!html.contains(".png\""), "a .png file is referenced by name");
}

#[test]
fn the_getting_started_page_runs_as_written() {
    let page = std::fs::read_to_string(root().join("docs/getting-started.md")).expect("the page");
    let lines = shell_lines(&page);
    let commands: Vec<&str> = lines.iter().filter_map(|l| l.strip_prefix(CARGO_RUN)).collect();
    assert!(commands.len() >= 6, "the page lost its commands: {lines:?}");
    // The ffmpeg lines of "From your own video" make the video; every other line is the test
    // command, which must be the README's and CI's.
    let ci = std::fs::read_to_string(root().join(".ci/run")).expect(".ci/run");
    let readme = std::fs::read_to_string(root().join("README.md")).expect("README");
    for other in lines
        .iter()
        .filter(|l| !l.starts_with(CARGO_RUN) && !l.starts_with(FFMPEG))
    {
        assert_eq!(
            other, "cargo test --workspace",
            "a command the test cannot run: {other}"
        );
        assert!(ci.contains(other.as_str()) && readme.contains(other.as_str()));
    }

    let dir = tempdir();
    let scenes = dir.path().join("scenes");
    std::fs::create_dir(&scenes).unwrap();
    for entry in std::fs::read_dir(root().join("scenes")).unwrap() {
        let path = entry.unwrap().path();
        std::fs::copy(&path, scenes.join(path.file_name().unwrap())).unwrap();
    }
    for line in &lines {
        let (program, command) = match (line.strip_prefix(CARGO_RUN), line.strip_prefix(FFMPEG)) {
            (Some(command), _) => (physfit(), command),
            (None, Some(command)) => (assert_cmd::Command::new("ffmpeg"), command),
            (None, None) => continue,
        };
        let mut program = program;
        let args: Vec<&str> = command.split_whitespace().collect();
        let output = program
            .current_dir(dir.path())
            .args(&args)
            .output()
            .expect("run the page's command");
        assert!(
            output.status.success(),
            "`{line}` failed:\n{}",
            String::from_utf8_lossy(&output.stderr)
        );
    }

    // 1. The default run: a complete report that names the concealed drag.
    let out = dir.path().join("physfit-out");
    for file in [
        "report.md",
        "report.html",
        "report.json",
        "tracks.csv",
        "fitted.toml",
        "trajectories.png",
        "mismatch.png",
        "residuals_before.png",
        "residuals_after.png",
        "cost_history.png",
    ] {
        assert!(out.join(file).is_file(), "physfit-out/{file} missing");
    }
    assert!(std::fs::read_dir(out.join("overlay")).unwrap().count() >= 2);
    let report = json(&out.join("report.json"));
    assert_eq!(effects(&report), ["drag"]);
    let truth = physfit_model::Scene::load(&root().join("scenes/default.toml")).unwrap();
    let drag = finding_value(&report["findings"][0], "drag");
    assert!(
        (drag - truth.physics.drag).abs() < 0.01 * truth.physics.drag,
        "drag {drag} against {}",
        truth.physics.drag
    );
    assert_eq!(report["truth"]["effects_concealed"], serde_json::json!(["drag"]));
    assert_eq!(report["truth"]["missed"], serde_json::json!([]));
    assert_eq!(report["truth"]["spurious"], serde_json::json!([]));
    assert_eq!(report["tracking"]["score"]["id_switches"], 0);
    let fitted = physfit_model::Scene::load(&out.join("fitted.toml")).expect("fitted.toml is a scene");
    assert!((fitted.physics.drag - drag).abs() < 1e-9);
    assert!(
        report["final"]["costs"]["multi_step"]["rms"].as_f64().unwrap()
            < 0.1 * report["base"]["costs"]["multi_step"]["rms"].as_f64().unwrap()
    );
    assert_self_contained(&std::fs::read_to_string(out.join("report.html")).unwrap());
    let md = std::fs::read_to_string(out.join("report.md")).unwrap();
    for section in [
        "## What was given",
        "## What was tracked",
        "## Base fit",
        "## Findings",
        "## Against the truth",
    ] {
        assert!(md.contains(section), "report.md lacks {section}");
    }

    // 2. The stages one at a time.
    let demo = dir.path().join("demo");
    for file in [
        "truth.csv",
        "structure.toml",
        "scene.toml",
        "tracks.csv",
        "fitted.toml",
        "fit.json",
    ] {
        assert!(demo.join(file).is_file(), "demo/{file} missing");
    }
    let diagnosis = json(&demo.join("diagnosis/report.json"));
    assert_eq!(effects(&diagnosis), ["gravity"]);
    assert!(demo.join("diagnosis/fitted.toml").is_file());

    // 3. The same frames as a recording: no truth, the same finding.
    let run = json(&demo.join("run/report.json"));
    assert_eq!(run["given"]["kind"], "recording");
    assert!(run.get("truth").is_none());
    assert_eq!(effects(&run), ["gravity"]);

    // 4. From a video: the container's frame rate, the window in seconds as frames, the field.
    assert!(demo.join("first.png").is_file());
    let video = json(&demo.join("video/report.json"));
    assert_eq!(video["given"]["kind"], "recording");
    assert!(video["given"]["frames"].as_str().unwrap().ends_with("throw.avi"));
    assert_eq!(video["given"]["fps"], 100.0);
    assert_eq!(video["given"]["window"], serde_json::json!([0, 250]));
    assert_eq!(effects(&video), ["gravity"]);
    let g = finding_value(&video["findings"][0], "gravity_y");
    assert!((g - 40.0).abs() < 0.4, "gravity_y {g} px/s^2 against 40");
}
