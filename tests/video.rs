//! Recordings as users have them: videos (H.264 in MP4 and MOV, MJPEG in AVI) decoded
//! through ffmpeg, and multi-page TIFF stacks. Each is made here from a rendered scene's PNG
//! frames by the tools users have (the `ffmpeg` program, the `tiff` crate's encoder) and
//! tracked against the scene's `truth.csv`. These tests need ffmpeg on the PATH (`.ci/run`
//! installs it): they fail, never skip, without it.

use std::path::{Path, PathBuf};

use predicates::prelude::*;

use crate::util::{physfit, read_xy, scenes_dir, tempdir, write};

/// Renders the first `frames` frames of `scenes/paper3.toml` (three discs of radius 5 px on
/// 512x512 px, 100 frames/s) into `dir` (frames/, truth.csv, structure.toml).
fn render_paper3(dir: &Path, frames: usize) {
    let scene = std::fs::read_to_string(scenes_dir().join("paper3.toml"))
        .unwrap()
        .replacen("frames = 400", &format!("frames = {frames}"), 1);
    assert!(scene.contains(&format!("frames = {frames}")));
    let scene_path = write(dir, "input-scene.toml", &scene);
    physfit()
        .args(["-q", "render"])
        .arg(&scene_path)
        .arg("--out")
        .arg(dir)
        .assert()
        .success();
}

/// Encodes `dir/frames/%06d.png` at `fps` frames/s into `out` with the ffmpeg `codec`
/// arguments, failing the test when ffmpeg cannot.
fn encode(dir: &Path, fps: u32, codec: &[&str], out: &Path) {
    let status = std::process::Command::new("ffmpeg")
        .args([
            "-nostdin",
            "-v",
            "error",
            "-y",
            "-framerate",
            &fps.to_string(),
            "-i",
        ])
        .arg(dir.join("frames").join("%06d.png"))
        .args(codec)
        .arg(out)
        .status()
        .expect("these tests need the ffmpeg program on the PATH (apt-get install ffmpeg)");
    assert!(status.success(), "ffmpeg could not encode {}", out.display());
}

/// H.264 at libx264's default quality, in 4:2:0 (what phones and most players use).
const H264: &[&str] = &["-c:v", "libx264", "-pix_fmt", "yuv420p"];
/// Motion JPEG at ffmpeg's default quality (what many lab cameras write into AVI).
const MJPEG: &[&str] = &["-c:v", "mjpeg"];

/// Tracks `recording` with `structure` into `dir/name.csv` and returns the rows.
fn track(recording: &Path, structure: &Path, dir: &Path, name: &str) -> Vec<(usize, String, f64, f64)> {
    let out = dir.join(format!("{name}.csv"));
    physfit()
        .args(["-q", "track"])
        .arg(recording)
        .arg("--structure")
        .arg(structure)
        .arg("--out")
        .arg(&out)
        .assert()
        .success();
    read_xy(&out)
}

/// Recall (truth points with a track point of the same particle and frame) and the RMS
/// distance of those points from the truth, px.
fn recall_and_rms(got: &[(usize, String, f64, f64)], truth: &[(usize, String, f64, f64)]) -> (f64, f64) {
    let mut found = 0usize;
    let mut sum = 0.0;
    for t in truth {
        if let Some(g) = got.iter().find(|g| g.0 == t.0 && g.1 == t.1) {
            found += 1;
            sum += (g.2 - t.2).powi(2) + (g.3 - t.3).powi(2);
        }
    }
    (
        found as f64 / truth.len() as f64,
        (sum / found.max(1) as f64).sqrt(),
    )
}

#[test]
fn videos_in_mp4_avi_and_mov_track_within_a_third_of_a_pixel() {
    let dir = tempdir();
    render_paper3(dir.path(), 40);
    let truth = read_xy(&dir.path().join("truth.csv"));
    let structure = dir.path().join("structure.toml");
    for (name, codec) in [("h264.mp4", H264), ("mjpeg.avi", MJPEG), ("h264.mov", H264)] {
        let video = dir.path().join(name);
        encode(dir.path(), 30, codec, &video);
        let got = track(&video, &structure, dir.path(), name);
        let (recall, rms) = recall_and_rms(&got, &truth);
        assert!(recall > 0.9999, "{name}: recall {recall}");
        assert!(rms < 0.3, "{name}: RMS error {rms} px");
    }
}

#[test]
fn a_video_gives_its_frame_rate_and_windows_take_seconds() {
    let dir = tempdir();
    render_paper3(dir.path(), 40);
    let video = dir.path().join("clip.mp4");
    encode(dir.path(), 30, H264, &video);
    let tracked = |window: &str, fps: Option<&str>| {
        let mut cmd = physfit();
        cmd.arg("track")
            .arg(&video)
            .args(["--window", window, "--out"])
            .arg(dir.path().join("w.csv"));
        if let Some(fps) = fps {
            cmd.args(["--fps", fps]);
        }
        cmd.assert().success()
    };
    // At the container's 30 frames/s, 0.5 s to 1 s are frames 15 to 30.
    tracked("0.5s..1s", None).stdout(predicate::str::contains("tracked frames 15..30 (16 frames)"));
    // --fps overrides the container: at 20 frames/s, 1 s to 1.5 s are frames 20 to 30.
    tracked("1s..1.5s", Some("20")).stdout(predicate::str::contains("tracked frames 20..30 (11 frames)"));
    let rows = read_xy(&dir.path().join("w.csv"));
    assert!(
        rows.iter().all(|r| (20..=30).contains(&r.0)) && rows.len() == 33,
        "{rows:?}"
    );
    // Times past the end name the recording's length.
    physfit()
        .arg("track")
        .arg(&video)
        .args(["--window", "1s..3s", "--out"])
        .arg(dir.path().join("w.csv"))
        .assert()
        .failure()
        .stderr(predicate::str::contains("30..90").and(predicate::str::contains("40 frames")));
}

#[test]
fn without_ffmpeg_the_error_says_what_to_install() {
    let dir = tempdir();
    let video = write(dir.path(), "clip.mp4", "not looked at");
    // With an empty PATH neither ffprobe nor ffmpeg can be found.
    physfit()
        .env("PATH", "")
        .arg("track")
        .arg(&video)
        .arg("--out")
        .arg(dir.path().join("t.csv"))
        .assert()
        .code(1)
        .stderr(
            predicate::str::contains("clip.mp4")
                .and(predicate::str::contains(
                    "needs the ffprobe program of ffmpeg on the PATH",
                ))
                .and(predicate::str::contains("apt-get install ffmpeg"))
                .and(predicate::str::contains("brew install ffmpeg"))
                .and(predicate::str::contains("panicked").not()),
        );
}

#[test]
fn truncated_and_corrupt_videos_are_named() {
    let dir = tempdir();
    render_paper3(dir.path(), 20);
    for (name, codec, keep) in [("cut.mp4", H264, 0.5), ("cut.avi", MJPEG, 0.5)] {
        let whole = dir.path().join(format!("whole-{name}"));
        encode(dir.path(), 30, codec, &whole);
        let bytes = std::fs::read(&whole).unwrap();
        let cut = write(dir.path(), name, "");
        std::fs::write(&cut, &bytes[..(bytes.len() as f64 * keep) as usize]).unwrap();
        physfit()
            .arg("track")
            .arg(&cut)
            .arg("--out")
            .arg(dir.path().join("t.csv"))
            .assert()
            .code(1)
            .stderr(
                predicate::str::contains(name)
                    .and(predicate::str::contains("truncated"))
                    .and(predicate::str::contains("panicked").not()),
            );
    }
    let junk = write(dir.path(), "junk.mkv", "this is not a video");
    physfit()
        .arg("track")
        .arg(&junk)
        .arg("--out")
        .arg(dir.path().join("t.csv"))
        .assert()
        .code(1)
        .stderr(predicate::str::contains("junk.mkv").and(predicate::str::contains("not a video")));
    assert!(!dir.path().join("t.csv").exists());
}

/// The sample layout of a TIFF stack written from grey PNG frames.
#[derive(Clone, Copy, Debug)]
enum Pages {
    Grey8,
    Grey16,
    Rgb8,
}

/// Writes the PNG frames of `frames` (8-bit grey) as one multi-page TIFF, one page per frame,
/// with the `tiff` crate's encoder: 16-bit pages hold each level times 257 (the same levels),
/// RGB pages the level in every channel.
fn write_stack(frames: &Path, pages: Pages, out: &Path) {
    use tiff::encoder::{colortype, TiffEncoder};
    let mut files: Vec<PathBuf> = std::fs::read_dir(frames)
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    files.sort();
    let mut encoder = TiffEncoder::new(std::fs::File::create(out).unwrap()).unwrap();
    for f in &files {
        let img = image::open(f).unwrap().to_luma8();
        let (w, h) = img.dimensions();
        let grey = img.into_raw();
        match pages {
            Pages::Grey8 => encoder.write_image::<colortype::Gray8>(w, h, &grey),
            Pages::Grey16 => {
                let wide: Vec<u16> = grey.iter().map(|&v| u16::from(v) * 257).collect();
                encoder.write_image::<colortype::Gray16>(w, h, &wide)
            }
            Pages::Rgb8 => {
                let rgb: Vec<u8> = grey.iter().flat_map(|&v| [v, v, v]).collect();
                encoder.write_image::<colortype::RGB8>(w, h, &rgb)
            }
        }
        .unwrap();
    }
}

#[test]
fn tiff_stacks_track_as_their_png_frames() {
    let dir = tempdir();
    render_paper3(dir.path(), 20);
    let structure = dir.path().join("structure.toml");
    let frames = dir.path().join("frames");
    let from_png = track(&frames, &structure, dir.path(), "png");
    assert_eq!(from_png.len(), 60);
    for pages in [Pages::Grey8, Pages::Grey16, Pages::Rgb8] {
        let stack = dir.path().join(format!("{pages:?}.tif"));
        write_stack(&frames, pages, &stack);
        let got = track(&stack, &structure, dir.path(), &format!("{pages:?}"));
        assert_eq!(got.len(), from_png.len(), "{pages:?}");
        for (g, p) in got.iter().zip(&from_png) {
            assert_eq!((g.0, &g.1), (p.0, &p.1), "{pages:?}");
            assert!(
                (g.2 - p.2).abs() < 1e-6 && (g.3 - p.3).abs() < 1e-6,
                "{pages:?}: frame {} {}: ({}, {}) from the stack, ({}, {}) from the PNGs",
                g.0,
                g.1,
                g.2,
                g.3,
                p.2,
                p.3
            );
        }
    }
}

#[test]
fn run_on_videos_and_a_tiff_stack_uses_their_frame_rates() {
    let dir = tempdir();
    // Three discs, 60 frames of 320x320 px: a short run.
    let scene = std::fs::read_to_string(scenes_dir().join("clean-triangle.toml")).unwrap();
    let small = scene
        .replacen("frames = 300", "frames = 60", 1)
        .replacen("width = 400", "width = 320", 1)
        .replacen("height = 400", "height = 320", 1);
    assert!(small.contains("frames = 60") && small.contains("height = 320"));
    let scene_path = write(dir.path(), "input-scene.toml", &small);
    physfit()
        .args(["-q", "render"])
        .arg(&scene_path)
        .arg("--out")
        .arg(dir.path())
        .assert()
        .success();
    let truth = read_xy(&dir.path().join("truth.csv"));
    // Each recording the issue names: mp4, mov and avi at 30 frames/s, and a TIFF stack
    // (no frame rate of its own: the structure's 100 frames/s).
    let stack = dir.path().join("triangle.tif");
    write_stack(&dir.path().join("frames"), Pages::Grey8, &stack);
    for (name, codec) in [
        ("triangle.mp4", Some(H264)),
        ("triangle.mov", Some(H264)),
        ("triangle.avi", Some(MJPEG)),
        ("triangle.tif", None),
    ] {
        let recording = dir.path().join(name);
        if let Some(codec) = codec {
            encode(dir.path(), 30, codec, &recording);
        }
        let out = dir.path().join(format!("out-{name}"));
        physfit()
            .args(["-q", "run", "--frames"])
            .arg(&recording)
            .arg("--structure")
            .arg(dir.path().join("structure.toml"))
            .arg("--out")
            .arg(&out)
            .assert()
            .success();
        let report: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).unwrap()).unwrap();
        assert_eq!(report["given"]["kind"], "recording", "{name}");
        // The structure says 100 frames/s; a container's 30 frames/s wins.
        let fps = if codec.is_some() { 30.0 } else { 100.0 };
        assert_eq!(report["given"]["fps"], fps, "{name}");
        assert_eq!(report["tracking"]["frames"], serde_json::json!([0, 59]), "{name}");
        let (recall, rms) = recall_and_rms(&read_xy(&out.join("tracks.csv")), &truth);
        assert!(
            recall > 0.9999 && rms < 0.3,
            "{name}: recall {recall}, RMS {rms} px"
        );
        assert!(out.join("report.html").is_file(), "{name}");
    }
}

/// H.264 changes a particle's mass by 1-3 % between its first frames, far beyond the 0.25 %
/// of most others: an appearance gate taken from the typical change alone refused two
/// particles of `concealed-gravity` (40 px apart, under 1 px a frame) their own blobs in
/// frames 1-2, and they swapped names for frames 2-5. Every point must be its own particle's.
#[test]
fn h264_keeps_the_names_of_slow_particles_from_the_first_frames() {
    let dir = tempdir();
    // All 300 frames: the typical change is measured over the whole recording.
    let scene = std::fs::read_to_string(scenes_dir().join("concealed-gravity.toml")).unwrap();
    let scene_path = write(dir.path(), "input-scene.toml", &scene);
    physfit()
        .args(["-q", "render"])
        .arg(&scene_path)
        .arg("--out")
        .arg(dir.path())
        .assert()
        .success();
    let video = dir.path().join("gravity.mp4");
    encode(dir.path(), 100, H264, &video);
    let got = track(&video, &dir.path().join("structure.toml"), dir.path(), "gravity");
    let truth = read_xy(&dir.path().join("truth.csv"));
    let (recall, rms) = recall_and_rms(&got, &truth);
    assert!(recall > 0.9999, "recall {recall}");
    let worst = got
        .iter()
        .filter_map(|g| {
            truth
                .iter()
                .find(|t| t.0 == g.0 && t.1 == g.1)
                .map(|t| (g.2 - t.2).hypot(g.3 - t.3))
        })
        .fold(0.0, f64::max);
    assert!(
        worst < 1.0,
        "a point {worst:.1} px from its particle (RMS {rms:.3} px)"
    );
}
