//! Bad input: each gives an error naming the folder, the file or the value, never a panic.

use std::path::Path;

use physfit_track::{track_folder, TrackError, TrackOptions};

use crate::common::{frame_path, issue_settings, render_to, TempDir};
use crate::crossing::ballistic;

fn error_of(dir: &Path, options: &TrackOptions) -> TrackError {
    match track_folder(dir, options, &|_, _| {}) {
        Ok(out) => panic!("{} tracked without error: {}", dir.display(), out.stats),
        Err(e) => e,
    }
}

fn small_sequence(label: &str, frames: usize) -> TempDir {
    let dir = TempDir::new(label);
    render_to(
        &ballistic(3, 64.0, 6.0, 1.0, frames, 1),
        &issue_settings(64, 64, 2.0, 1),
        dir.path(),
    );
    dir
}

#[test]
fn an_empty_folder_is_named() {
    let dir = TempDir::new("empty");
    std::fs::write(dir.path().join("notes.txt"), "not a frame").expect("write");
    let e = error_of(dir.path(), &TrackOptions::default());
    assert!(matches!(e, TrackError::NoFrames { .. }), "{e}");
    assert!(e.to_string().contains(&dir.path().display().to_string()), "{e}");
}

#[test]
fn a_truncated_png_is_named() {
    let dir = small_sequence("truncated", 8);
    let path = frame_path(dir.path(), 5);
    let bytes = std::fs::read(&path).expect("read");
    std::fs::write(&path, &bytes[..bytes.len() / 2]).expect("truncate");
    let e = error_of(dir.path(), &TrackOptions::default()).to_string();
    assert!(e.contains("000005.png"), "{e}");
}

#[test]
fn a_non_image_png_is_named() {
    let dir = small_sequence("corrupt", 8);
    std::fs::write(frame_path(dir.path(), 3), "this is not a PNG file\n").expect("write");
    let e = error_of(dir.path(), &TrackOptions::default()).to_string();
    assert!(e.contains("000003.png"), "{e}");
}

#[test]
fn a_frame_of_another_size_is_named() {
    let dir = small_sequence("sizes", 40);
    // A frame not among the background samples, so it is met while locating.
    let odd = frame_path(dir.path(), 7);
    crate::common::write_frame(&[], &issue_settings(80, 64, 2.0, 1), 7, &odd);
    let e = error_of(dir.path(), &TrackOptions::default());
    assert!(matches!(e, TrackError::FrameSize { .. }), "{e}");
    assert!(
        e.to_string().contains("000007.png") && e.to_string().contains("80x64"),
        "{e}"
    );
}

#[test]
fn an_invalid_window_is_refused() {
    let dir = small_sequence("window", 8);
    for window in [(5, 2), (0, 8), (9, 12)] {
        let e = error_of(
            dir.path(),
            &TrackOptions {
                window: Some(window),
                ..TrackOptions::default()
            },
        );
        assert!(
            matches!(e, TrackError::Window { count: 8, .. }),
            "{window:?}: {e}"
        );
        assert!(
            e.to_string().contains(&format!("{}..{}", window.0, window.1)),
            "{e}"
        );
    }
}

#[test]
fn bad_options_are_refused() {
    let dir = small_sequence("options", 4);
    let e = error_of(
        dir.path(),
        &TrackOptions {
            radius: Some(-1.0),
            ..TrackOptions::default()
        },
    );
    assert!(
        matches!(e, TrackError::Option(_)) && e.to_string().contains("-1"),
        "{e}"
    );
    let e = error_of(
        dir.path(),
        &TrackOptions {
            named_start: Some(vec![("p".into(), [f64::NAN, 3.0])]),
            ..TrackOptions::default()
        },
    );
    assert!(
        matches!(e, TrackError::Option(_)) && e.to_string().contains('p'),
        "{e}"
    );
}
