//! The fuzz targets' properties (`fuzz/checks/`, see `docs/fuzzing.md`) on stable, on every
//! input kept: the crashes found and fixed (`fuzz/regressions/<target>/`) and the corpus
//! (`fuzz/corpus/<target>/`).

use std::path::{Path, PathBuf};

#[path = "../fuzz/checks/png_reader.rs"]
mod png_reader;
#[path = "../fuzz/checks/scene.rs"]
mod scene;
#[path = "../fuzz/checks/track_table.rs"]
mod track_table;

/// Every file kept for `target`, sorted by path.
fn inputs(target: &str) -> Vec<PathBuf> {
    let fuzz = Path::new(env!("CARGO_MANIFEST_DIR")).join("fuzz");
    let mut files: Vec<PathBuf> = ["regressions", "corpus"]
        .iter()
        .filter_map(|dir| std::fs::read_dir(fuzz.join(dir).join(target)).ok())
        .flatten()
        .map(|entry| entry.unwrap().path())
        .filter(|p| p.is_file())
        .collect();
    files.sort();
    files
}

/// Runs `check` on every input of `target`, naming each one that breaks it.
fn check_all(target: &str, check: fn(&[u8])) {
    let files = inputs(target);
    assert!(!files.is_empty(), "no inputs kept for {target}");
    let failed: Vec<String> = files
        .iter()
        .filter(|path| {
            let bytes = std::fs::read(path).unwrap();
            std::panic::catch_unwind(|| check(&bytes)).is_err()
        })
        .map(|path| path.display().to_string())
        .collect();
    assert!(
        failed.is_empty(),
        "{target}: {} input(s) fail: {failed:?}",
        failed.len()
    );
}

#[test]
fn png_reader_inputs_decode_as_the_png_crate_or_both_refuse() {
    check_all("png_reader", png_reader::check);
}

#[test]
fn scene_inputs_validate_save_and_simulate_without_panic() {
    check_all("scene", scene::check);
}

#[test]
fn track_table_inputs_read_and_match_without_panic() {
    check_all("track_table", track_table::check);
}
