//! Helpers shared by the end-to-end tests.

use std::path::{Path, PathBuf};

use assert_cmd::Command;

/// The `physfit` binary under test.
pub fn physfit() -> Command {
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_physfit"));
    cmd.env_remove("RUST_LOG");
    cmd
}

/// The repository's `scenes/` folder.
pub fn scenes_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes")
}

/// A fresh temporary folder, removed when dropped.
pub fn tempdir() -> tempfile::TempDir {
    tempfile::Builder::new()
        .prefix("physfit-test-")
        .tempdir()
        .expect("temporary folder")
}

/// Runs `physfit -q simulate SCENE --out OUT` and asserts it succeeds.
pub fn simulate(scene: &Path, out: &Path) {
    physfit()
        .arg("-q")
        .arg("simulate")
        .arg(scene)
        .arg("--out")
        .arg(out)
        .assert()
        .success();
}

/// Writes `text` to `dir/name` and returns the path.
pub fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, text).expect("write test file");
    p
}

/// Reads a `frame,particle,x,y` CSV into rows.
pub fn read_xy(path: &Path) -> Vec<(usize, String, f64, f64)> {
    let mut rdr = csv::Reader::from_path(path).expect("open csv");
    let headers = rdr.headers().expect("headers").clone();
    let col = |name: &str| {
        headers
            .iter()
            .position(|h| h == name)
            .unwrap_or_else(|| panic!("no column {name}"))
    };
    let (f, p, x, y) = (col("frame"), col("particle"), col("x"), col("y"));
    rdr.records()
        .map(|r| {
            let r = r.expect("record");
            (
                r[f].parse().unwrap(),
                r[p].to_string(),
                r[x].parse().unwrap(),
                r[y].parse().unwrap(),
            )
        })
        .collect()
}

/// Asserts that no report or model physfit wrote into `dir` holds a non-finite number: no
/// `NaN`, `nan` or `inf` word in `report.json`, `report.md`, `fitted.toml`, and finite `x`, `y`
/// in `tracks.csv` (whose `mass`, `size`, `ep` are NaN by contract when unknown). Returns the
/// number of files scanned.
pub fn assert_finite_outputs(dir: &Path) -> usize {
    let mut scanned = 0;
    for name in ["report.json", "report.md", "fitted.toml"] {
        let Ok(text) = std::fs::read_to_string(dir.join(name)) else {
            continue;
        };
        scanned += 1;
        let bad = text
            .split(|c: char| !(c.is_ascii_alphanumeric() || c == '_' || c == '.'))
            .find(|w| ["nan", "inf", "infinity"].contains(&w.to_ascii_lowercase().as_str()));
        assert!(
            bad.is_none(),
            "{} holds `{}`",
            dir.join(name).display(),
            bad.unwrap_or_default()
        );
    }
    let tracks = dir.join("tracks.csv");
    if tracks.exists() {
        scanned += 1;
        for (frame, particle, x, y) in read_xy(&tracks) {
            assert!(
                x.is_finite() && y.is_finite(),
                "{}: frame {frame} {particle} at ({x}, {y})",
                tracks.display()
            );
        }
    }
    scanned
}
