//! `physfit diagnose`, end to end from pixels: render a scene, track it, diagnose it from the
//! structure alone.

use crate::util::{physfit, scenes_dir, tempdir};

/// Renders `scenes/NAME.toml`, tracks it with the structure, diagnoses it; returns report.json.
fn diagnose_from_pixels(name: &str, dir: &std::path::Path) -> serde_json::Value {
    physfit()
        .arg("-q")
        .arg("render")
        .arg(scenes_dir().join(format!("{name}.toml")))
        .arg("--out")
        .arg(dir)
        .assert()
        .success();
    physfit()
        .arg("-q")
        .arg("track")
        .arg(dir.join("frames"))
        .arg("--out")
        .arg(dir.join("tracks.csv"))
        .arg("--structure")
        .arg(dir.join("structure.toml"))
        .assert()
        .success();
    physfit()
        .arg("-q")
        .arg("diagnose")
        .arg(dir.join("tracks.csv"))
        .arg("--structure")
        .arg(dir.join("structure.toml"))
        .arg("--out")
        .arg(dir.join("diag"))
        .assert()
        .success();
    for f in [
        "fitted.toml",
        "report.md",
        "report.html",
        "residuals_before.png",
        "residuals_after.png",
    ] {
        assert!(dir.join("diag").join(f).exists(), "{f} missing");
    }
    serde_json::from_str(&std::fs::read_to_string(dir.join("diag/report.json")).unwrap()).unwrap()
}

#[test]
fn concealed_drag_is_named_with_its_value_and_the_fit_improves() {
    let dir = tempdir();
    let report = diagnose_from_pixels("concealed-drag", dir.path());
    let findings = report["findings"].as_array().unwrap();
    assert_eq!(findings.len(), 1, "{findings:#?}");
    assert_eq!(findings[0]["effect"], "drag");
    let drag = findings[0]["parameters"][0]["value"].as_f64().unwrap();
    assert!((drag - 0.3).abs() < 0.03, "drag {drag} against 0.3 /s");
    let before = report["base"]["costs"]["multi_step"]["sum_squares"]
        .as_f64()
        .unwrap();
    let after = report["final"]["costs"]["multi_step"]["sum_squares"]
        .as_f64()
        .unwrap();
    assert!(after < 0.1 * before, "multi-step cost {before} -> {after}");
    // The diagnosed model is a scene with the drag in its own key.
    let fitted = std::fs::read_to_string(dir.path().join("diag/fitted.toml")).unwrap();
    assert!(
        fitted.contains("[physics]") && fitted.contains("drag = "),
        "{fitted}"
    );
}

#[test]
fn a_clean_recording_adds_nothing() {
    let dir = tempdir();
    let report = diagnose_from_pixels("clean-triangle", dir.path());
    assert!(
        report["findings"].as_array().unwrap().is_empty(),
        "{:#}",
        report["findings"]
    );
}
