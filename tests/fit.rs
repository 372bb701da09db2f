//! `physfit fit`, end to end: the fit.json contract, accuracy against the truth, bad input.

use predicates::prelude::*;

use crate::util::{physfit, scenes_dir, tempdir, write};

/// Simulates `scenes/NAME.toml` into `dir/truth.csv` and writes its structure to
/// `dir/structure.toml` (through `physfit render`, the documented way to get one).
fn rendered(name: &str, dir: &std::path::Path) {
    physfit()
        .arg("-q")
        .arg("render")
        .arg(scenes_dir().join(format!("{name}.toml")))
        .arg("--out")
        .arg(dir)
        .assert()
        .success();
}

#[test]
fn lsq_fit_of_exact_tracks_recovers_every_parameter_and_writes_the_contract() {
    let dir = tempdir();
    rendered("paper3", dir.path());
    let fitted = dir.path().join("fitted.toml");
    let report = dir.path().join("fit.json");
    physfit()
        .arg("fit")
        .arg(dir.path().join("truth.csv"))
        .arg("--structure")
        .arg(dir.path().join("structure.toml"))
        .arg("--out")
        .arg(&fitted)
        .arg("--report")
        .arg(&report)
        .arg("--method")
        .arg("lsq")
        .arg("--truth")
        .arg(scenes_dir().join("paper3.toml"))
        .assert()
        .success();
    let json: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
    let params = json["parameters"].as_array().unwrap();
    // paper3: 2 springs x (length, stiffness) + 1 torsion x (rest_cos, stiffness).
    assert_eq!(params.len(), 6);
    for p in params {
        assert!(p["bond"]["between"].is_array(), "{p}");
        let name = p["name"].as_str().unwrap();
        assert!(["length", "stiffness", "rest_cos"].contains(&name), "{name}");
        assert!(p["value"].is_f64() && p["std_error"].is_f64(), "{p}");
        let rel = p["relative_error"].as_f64().unwrap();
        assert!(rel.abs() < 1e-3, "{p}");
    }
    let torsion = params
        .iter()
        .find(|p| p["bond"]["at"].is_string())
        .expect("a torsion parameter");
    assert_eq!(torsion["bond"]["between"].as_array().unwrap().len(), 2);
    assert!(json["costs"]["multi_step_sequence"]["rms"].as_f64().unwrap() < 1e-3);
    assert!(json["history"].is_array() && json["seconds"].is_f64() && json["settings"].is_object());

    // The fitted model is a scene that renders again.
    physfit()
        .arg("-q")
        .arg("render")
        .arg(&fitted)
        .arg("--out")
        .arg(dir.path().join("again"))
        .assert()
        .success();
}

#[test]
fn a_structure_particle_without_a_track_is_named() {
    let dir = tempdir();
    rendered("paper3", dir.path());
    let truth = std::fs::read_to_string(dir.path().join("truth.csv")).unwrap();
    let ids: Vec<String> = truth
        .lines()
        .skip(1)
        .map(|l| l.split(',').nth(1).unwrap().to_string())
        .collect();
    let dropped = ids[1].clone();
    let kept: String = truth
        .lines()
        .filter(|l| l.split(',').nth(1) != Some(dropped.as_str()))
        .map(|l| format!("{l}\n"))
        .collect();
    let tracks = write(dir.path(), "partial.csv", &kept);
    physfit()
        .arg("fit")
        .arg(&tracks)
        .arg("--structure")
        .arg(dir.path().join("structure.toml"))
        .arg("--out")
        .arg(dir.path().join("f.toml"))
        .assert()
        .failure()
        .stderr(
            predicate::str::contains(format!("\"{dropped}\""))
                .or(predicate::str::contains(format!("{dropped} "))),
        );
    assert!(!dir.path().join("f.toml").exists());
}

#[test]
fn a_malformed_track_file_is_named_with_its_line() {
    let dir = tempdir();
    rendered("paper3", dir.path());
    let tracks = write(
        dir.path(),
        "bad.csv",
        "frame,particle,x,y\n0,p0,1.0,2.0\n1,p0,oops,2.0\n",
    );
    physfit()
        .arg("fit")
        .arg(&tracks)
        .arg("--structure")
        .arg(dir.path().join("structure.toml"))
        .arg("--out")
        .arg(dir.path().join("f.toml"))
        .assert()
        .failure()
        .stderr(predicate::str::contains("bad.csv:3"));
}

/// With `--scale`, fit.json gains `units` and each parameter its SI value beside the px one
/// (keys unchanged): lengths in m, spring stiffness in N/m (masses as kg), torsion stiffness
/// in J; the console summary rounds each value to its standard error.
#[test]
fn a_scale_adds_si_values_beside_px() {
    let dir = tempdir();
    rendered("paper3", dir.path());
    let report = dir.path().join("fit.json");
    let out = physfit()
        .arg("fit")
        .arg(dir.path().join("truth.csv"))
        .arg("--structure")
        .arg(dir.path().join("structure.toml"))
        .arg("--out")
        .arg(dir.path().join("fitted.toml"))
        .arg("--report")
        .arg(&report)
        .args(["--method", "lsq", "--scale", "0.002"])
        .assert()
        .success();
    let stdout = String::from_utf8_lossy(&out.get_output().stdout).to_string();
    assert!(
        stdout.contains(" m)") && stdout.contains("masses as kg"),
        "{stdout}"
    );
    let json: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
    assert_eq!(json["units"]["mass_unit"], "kg");
    for p in json["parameters"].as_array().unwrap() {
        let v = p["value"].as_f64().unwrap();
        let torsion = p["bond"]["at"].is_string();
        let (unit, factor) = match (p["name"].as_str().unwrap(), torsion) {
            ("length", _) => ("m", 0.002),
            ("stiffness", false) => ("N/m", 1.0),
            ("stiffness", true) => ("J", 0.002 * 0.002),
            _ => {
                assert!(p.get("value_si").is_none(), "{p}");
                continue;
            }
        };
        assert_eq!(p["unit_si"], unit, "{p}");
        let si = p["value_si"].as_f64().unwrap();
        assert!((si - v * factor).abs() <= 1e-12 * (v * factor).abs(), "{p}");
    }
    physfit()
        .arg("fit")
        .arg(dir.path().join("truth.csv"))
        .arg("--structure")
        .arg(dir.path().join("structure.toml"))
        .arg("--out")
        .arg(dir.path().join("fitted.toml"))
        .args(["--scale", "0"])
        .assert()
        .failure()
        .stderr(predicate::str::contains("--scale 0"));
}
