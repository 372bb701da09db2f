//! Hostile and huge input (issue 24): every limit refuses before memory is taken, with an error
//! naming the file, the limit and the flag that raises it; absurd numbers are refused with their
//! key named; rows the structure does not name are reported.

use std::path::{Path, PathBuf};

use assert_cmd::assert::Assert;

use crate::util::{physfit, scenes_dir, tempdir, write};

/// The default scene's text.
fn default_scene() -> String {
    std::fs::read_to_string(scenes_dir().join("default.toml")).unwrap()
}

/// Asserts that `assert` is a failure (exit code 1, not a crash) whose stderr holds every one
/// of `needles` and no panic; returns stderr.
fn refused(assert: Assert, needles: &[&str]) -> String {
    let out = assert.get_output();
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    assert_eq!(out.status.code(), Some(1), "stderr: {stderr}");
    assert!(!stderr.contains("panicked"), "{stderr}");
    for n in needles {
        assert!(stderr.contains(n), "`{n}` is not in: {stderr}");
    }
    stderr
}

/// A PNG chunk: length, type, data, CRC.
fn chunk(kind: &[u8; 4], data: &[u8]) -> Vec<u8> {
    let mut c = (data.len() as u32).to_be_bytes().to_vec();
    c.extend_from_slice(kind);
    c.extend_from_slice(data);
    let mut h = crc32fast::Hasher::new();
    h.update(kind);
    h.update(data);
    c.extend_from_slice(&h.finalize().to_be_bytes());
    c
}

/// A PNG file of about 100 bytes whose header claims `width` x `height` px of `depth`-bit
/// samples of colour type `colour`, followed by a tiny image data chunk.
fn claimed_png(width: u32, height: u32, depth: u8, colour: u8) -> Vec<u8> {
    let mut file = vec![0x89, b'P', b'N', b'G', b'\r', b'\n', 0x1a, b'\n'];
    let mut ihdr = width.to_be_bytes().to_vec();
    ihdr.extend_from_slice(&height.to_be_bytes());
    ihdr.extend_from_slice(&[depth, colour, 0, 0, 0]);
    file.extend(chunk(b"IHDR", &ihdr));
    // A zlib stream of 100 zero bytes.
    let idat = [0x78, 0x9c, 0x63, 0x60, 0x18, 0x05, 0x00, 0x00, 0x64, 0x00, 0x01];
    file.extend(chunk(b"IDAT", &idat));
    file.extend(chunk(b"IEND", &[]));
    file
}

/// Writes three frames `f0.png`.. of `bytes` into a new folder `dir/name`.
fn frames(dir: &Path, name: &str, bytes: &[u8]) -> PathBuf {
    let d = dir.join(name);
    std::fs::create_dir(&d).unwrap();
    for k in 0..3 {
        std::fs::write(d.join(format!("f{k}.png")), bytes).unwrap();
    }
    d
}

#[test]
fn frames_claiming_60000_by_60000_px_are_refused_unread() {
    let dir = tempdir();
    // 8-bit grey (the tracker's own reader), 16-bit grey and 8-bit RGB with alpha (the general
    // decoder).
    for (depth, colour) in [(8, 0), (16, 0), (8, 6), (16, 2)] {
        let png = claimed_png(60_000, 60_000, depth, colour);
        assert!(png.len() < 120);
        let d = frames(dir.path(), &format!("big-{depth}-{colour}"), &png);
        let started = std::time::Instant::now();
        refused(
            physfit()
                .arg("track")
                .arg(&d)
                .arg("--out")
                .arg(dir.path().join("t.csv"))
                .assert(),
            &[
                "f0.png",
                "60000x60000 px = 3600 megapixels",
                "`frame-megapixels` limit of 50",
                "--limit frame-megapixels=",
            ],
        );
        // Refused from the header: no 3.6 GB of samples, no 55 s.
        assert!(started.elapsed().as_secs_f64() < 5.0);
        // With the size allowed, the file's 80 bytes still cannot hold the samples it claims.
        refused(
            physfit()
                .args(["--limit", "frame-megapixels=5000", "track"])
                .arg(&d)
                .arg("--out")
                .arg(dir.path().join("t.csv"))
                .assert(),
            &[
                "f0.png",
                "decompression ratio",
                "`decompression-ratio` limit of 2000",
                "--limit decompression-ratio=",
            ],
        );
    }
}

#[test]
fn a_bad_limit_setting_is_refused() {
    refused(
        physfit()
            .args(["--limit", "pixels=3", "simulate", "x.toml", "--out", "x.csv"])
            .assert(),
        &["unknown limit `pixels`", "frame-megapixels"],
    );
}

#[test]
fn a_huge_render_or_recording_is_refused_before_it_is_allocated() {
    let dir = tempdir();
    let text = default_scene();
    let wide = write(
        dir.path(),
        "wide.toml",
        &text
            .replace("width = 512", "width = 100000")
            .replace("height = 512", "height = 100000"),
    );
    refused(
        physfit()
            .arg("render")
            .arg(&wide)
            .arg("--out")
            .arg(dir.path().join("o"))
            .assert(),
        &[
            "wide.toml",
            "100000x100000 px",
            "`frame-megapixels` limit",
            "--limit frame-megapixels=",
        ],
    );
    let long = write(
        dir.path(),
        "long.toml",
        &text.replace("frames = 300", "frames = 100000000"),
    );
    for cmd in ["render", "simulate"] {
        refused(
            physfit()
                .arg(cmd)
                .arg(&long)
                .arg("--out")
                .arg(dir.path().join("o2"))
                .assert(),
            &[
                "long.toml",
                "100000000 x 5 particles",
                "`frames-x-particles` limit",
                "--limit frames-x-particles=",
            ],
        );
    }
    assert!(!dir.path().join("o").exists() && !dir.path().join("o2").exists());
}

#[test]
fn a_track_table_spanning_1e12_frames_is_refused() {
    let dir = tempdir();
    let scene = write(dir.path(), "s.toml", &default_scene());
    let truth = dir.path().join("truth.csv");
    crate::util::simulate(&scene, &truth);
    let mut text = std::fs::read_to_string(&truth).unwrap();
    text.push_str("1000000000000,p0,1.0,2.0,,,,detected\n");
    let tracks = write(dir.path(), "far.csv", &text);
    let structure = dir.path().join("structure.toml");
    std::fs::write(&structure, text_structure(&default_scene())).unwrap();
    let needles = [
        "far.csv",
        "1000000000001 frames",
        "`frames-x-particles` limit",
        "--limit frames-x-particles=",
    ];
    refused(
        physfit()
            .arg("fit")
            .arg(&tracks)
            .arg("--structure")
            .arg(&structure)
            .arg("--out")
            .arg(dir.path().join("f.toml"))
            .assert(),
        &needles,
    );
    refused(
        physfit()
            .arg("diagnose")
            .arg(&tracks)
            .arg("--structure")
            .arg(&structure)
            .arg("--out")
            .arg(dir.path().join("d"))
            .assert(),
        &needles,
    );
}

/// The default scene as a structure: bond values and `[physics]` left out.
fn text_structure(scene: &str) -> String {
    let mut out = String::new();
    let mut in_physics = false;
    for line in scene.lines() {
        if line.starts_with('[') {
            in_physics = line.starts_with("[physics");
        }
        let key = line.split('=').next().unwrap_or("").trim();
        if in_physics || ["length", "stiffness", "rest_cos"].contains(&key) {
            continue;
        }
        out.push_str(line);
        out.push('\n');
    }
    out
}

#[test]
fn files_above_the_size_limits_are_refused_unread() {
    let dir = tempdir();
    // An 11 MB scene (sparse: nothing is written), above the default 10 MB.
    let big = dir.path().join("big.toml");
    std::fs::File::create(&big).unwrap().set_len(11_000_000).unwrap();
    refused(
        physfit()
            .arg("simulate")
            .arg(&big)
            .arg("--out")
            .arg(dir.path().join("t.csv"))
            .assert(),
        &[
            "big.toml",
            "scene file is 11.0 MB",
            "`scene-mb` limit of 10 MB",
            "--limit scene-mb=",
        ],
    );
    // A track table above a lowered limit.
    let scene = write(dir.path(), "s.toml", &default_scene());
    let truth = dir.path().join("truth.csv");
    crate::util::simulate(&scene, &truth);
    refused(
        physfit()
            .args(["--limit", "tracks-mb=0.01", "fit"])
            .arg(&truth)
            .arg("--structure")
            .arg(&scene)
            .arg("--out")
            .arg(dir.path().join("f.toml"))
            .assert(),
        &[
            "truth.csv",
            "track table is",
            "`tracks-mb` limit of 0.01 MB",
            "--limit tracks-mb=",
        ],
    );
}

#[test]
fn absurd_numbers_are_refused_naming_the_key_and_file() {
    let dir = tempdir();
    let text = default_scene();
    let cases = [
        ("fps = 100.0", "fps = 0.0", "recording.fps is 0"),
        ("fps = 100.0", "fps = -5.0", "recording.fps is -5"),
        ("fps = 100.0", "fps = nan", "recording.fps is NaN"),
        ("fps = 100.0", "fps = inf", "recording.fps is inf"),
        ("fps = 100.0", "fps = 1e308", "recording.fps is 1e308"),
        ("substeps = 20", "substeps = 0", "recording.substeps is 0"),
        ("substeps = 20", "substeps = 1000000000000", "substeps"),
        (
            "substeps = 20",
            "substeps = 4000000000",
            "recording.substeps is 4000000000",
        ),
        ("mass = 1.0", "mass = 0.0", "particle \"p0\" has mass 0"),
        ("mass = 1.0", "mass = -1.0", "particle \"p0\" has mass -1"),
        ("mass = 1.0", "mass = nan", "particle \"p0\" mass is NaN"),
        ("mass = 1.0", "mass = 1e300", "particle \"p0\" mass is 1e300"),
        (
            "position = [176.0, 250.0]",
            "position = [1e308, 250.0]",
            "particle \"p0\" position is 1e308",
        ),
        (
            "velocity = [0.0, -60.0]",
            "velocity = [0.0, -1e300]",
            "particle \"p0\" velocity is -1e300",
        ),
    ];
    for (k, (from, to, key)) in cases.iter().enumerate() {
        assert!(text.contains(from));
        let name = format!("absurd{k}.toml");
        let scene = write(dir.path(), &name, &text.replacen(from, to, 1));
        refused(
            physfit()
                .arg("simulate")
                .arg(&scene)
                .arg("--out")
                .arg(dir.path().join("t.csv"))
                .assert(),
            &[name.as_str(), key],
        );
    }
    assert!(!dir.path().join("t.csv").exists());
}

#[test]
fn a_simulation_that_diverges_names_the_frame_and_particle() {
    let dir = tempdir();
    // Valid values, but a spring far too stiff for the time step: the motion explodes.
    let text = default_scene().replacen("stiffness = 300.0", "stiffness = 1e12", 1);
    let scene = write(dir.path(), "stiff.toml", &text);
    let out = dir.path().join("t.csv");
    let stderr = refused(
        physfit()
            .arg("simulate")
            .arg(&scene)
            .arg("--out")
            .arg(&out)
            .assert(),
        &[
            "stiff.toml",
            "the simulation diverged",
            "at frame",
            "recording.substeps",
        ],
    );
    assert!(stderr.contains("particle \"p"), "{stderr}");
    assert!(
        !out.exists(),
        "a truth table with non-finite positions was written"
    );
}

#[test]
fn rows_of_tracks_the_structure_does_not_name_are_reported() {
    let dir = tempdir();
    let scene = write(dir.path(), "s.toml", &default_scene());
    let truth = dir.path().join("truth.csv");
    crate::util::simulate(&scene, &truth);
    let mut text = std::fs::read_to_string(&truth).unwrap();
    for k in 0..10 {
        text.push_str(&format!("{k},ghost,1.0,2.0,,,,detected\n"));
    }
    text.push_str("3,q9,1.0,1.0,,,,detected\n");
    let tracks = write(dir.path(), "extra.csv", &text);
    let structure = write(dir.path(), "structure.toml", &text_structure(&default_scene()));
    let out = physfit()
        .args(["fit", "--method", "lsq"])
        .arg(&tracks)
        .arg("--structure")
        .arg(&structure)
        .arg("--out")
        .arg(dir.path().join("f.toml"))
        .assert()
        .success();
    let stderr = String::from_utf8_lossy(&out.get_output().stderr).into_owned();
    assert!(
        stderr.contains("11 rows of 2 tracks the structure does not name were left out")
            && stderr.contains("\"ghost\" (10 rows)")
            && stderr.contains("\"q9\" (1 row)"),
        "{stderr}"
    );
}
