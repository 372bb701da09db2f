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
