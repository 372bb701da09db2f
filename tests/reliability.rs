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

/// The default scene cut to `frames` frames, written into `dir`.
fn short_scene(dir: &Path, frames: usize) -> PathBuf {
    let text = default_scene().replace("frames = 300", &format!("frames = {frames}"));
    assert!(text.contains(&format!("frames = {frames}")));
    write(dir, &format!("short-{frames}.toml"), &text)
}

/// `physfit -q render SCENE --out OUT`.
fn render(scene: &Path, out: &Path) -> Assert {
    physfit()
        .args(["-q", "render"])
        .arg(scene)
        .arg("--out")
        .arg(out)
        .assert()
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
                ".png: the file declares",
                "60000x60000 px = 3600 megapixels",
                "`frame-megapixels` limit of 50",
                "--limit frame-megapixels=",
            ],
        );
        // Refused from the header: no 3.6 GB of samples, no 55 s.
        assert!(started.elapsed().as_secs_f64() < 5.0);
        // With the size allowed, the file's 68 bytes still cannot hold the samples it claims.
        refused(
            physfit()
                .args(["--limit", "frame-megapixels=5000", "track"])
                .arg(&d)
                .arg("--out")
                .arg(dir.path().join("t.csv"))
                .assert(),
            &[
                ".png: the file's",
                "decompression ratio",
                "`decompression-ratio` limit of 2000",
                "--limit decompression-ratio=",
            ],
        );
    }
}

#[test]
fn a_jpeg_claiming_60000_by_60000_px_is_refused_unread() {
    let dir = tempdir();
    // A 16 x 16 grey JPEG whose frame header (SOF0) is made to claim 60000 x 60000 px.
    let mut jpeg = Vec::new();
    image::codecs::jpeg::JpegEncoder::new(&mut jpeg)
        .encode(&[128u8; 256], 16, 16, image::ExtendedColorType::L8)
        .unwrap();
    let sof = jpeg.windows(2).position(|w| w == [0xff, 0xc0]).unwrap();
    jpeg[sof + 5..sof + 9].copy_from_slice(&[0xea, 0x60, 0xea, 0x60]);
    let d = dir.path().join("jpg");
    std::fs::create_dir(&d).unwrap();
    std::fs::write(d.join("f0.jpg"), &jpeg).unwrap();
    std::fs::write(d.join("f1.jpg"), &jpeg).unwrap();
    let out = dir.path().join("t.csv");
    refused(
        physfit().arg("track").arg(&d).arg("--out").arg(&out).assert(),
        &[
            ".jpg: the file declares 60000x60000 px",
            "`frame-megapixels` limit",
            "--limit frame-megapixels=",
        ],
    );
    refused(
        physfit()
            .args(["--limit", "frame-megapixels=4000", "track"])
            .arg(&d)
            .arg("--out")
            .arg(&out)
            .assert(),
        &[
            ".jpg: the file's",
            "`decompression-ratio` limit",
            "--limit decompression-ratio=",
        ],
    );
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
    // The same limit for the truth `track` scores against.
    let fixture = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures/gaussian-blobs");
    refused(
        physfit()
            .args(["--limit", "tracks-mb=0.001", "track"])
            .arg(fixture.join("frames"))
            .arg("--truth")
            .arg(fixture.join("truth.csv"))
            .arg("--out")
            .arg(dir.path().join("tracked.csv"))
            .assert(),
        &[
            "truth.csv",
            "track table is",
            "`tracks-mb` limit of 0.001 MB",
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

/// The names in `dir` that contain `physfit-`: staging folders.
fn staging_in(dir: &Path) -> Vec<String> {
    std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.contains("physfit-") && n != ".physfit-outputs")
        .collect()
}

#[test]
fn the_users_files_are_never_replaced_or_deleted() {
    let dir = tempdir();
    let scene = short_scene(dir.path(), 4);
    let out = dir.path().join("out");
    render(&scene, &out).success();
    write(&out, "notes.txt", "the user's notes");
    write(
        &out.join("frames"),
        "keep.txt",
        "the user's file among the frames",
    );
    // The frames folder would be replaced: refused, naming the file, nothing changed.
    refused(
        render(&scene, &out),
        &["keep.txt", "not written by physfit", "nothing was changed"],
    );
    assert_eq!(
        std::fs::read_to_string(out.join("frames/keep.txt")).unwrap(),
        "the user's file among the frames"
    );
    assert_eq!(std::fs::read_dir(out.join("frames")).unwrap().count(), 5);
    // Beside the outputs, the user's file is kept through a new render.
    std::fs::remove_file(out.join("frames/keep.txt")).unwrap();
    render(&scene, &out).success();
    assert_eq!(
        std::fs::read_to_string(out.join("notes.txt")).unwrap(),
        "the user's notes"
    );
    assert_eq!(std::fs::read_dir(out.join("frames")).unwrap().count(), 4);
    // A report of the user's where diagnose writes its own: refused before the work.
    write(&out, "report.md", "the user's report");
    refused(
        physfit()
            .args(["-q", "diagnose"])
            .arg(out.join("truth.csv"))
            .arg("--structure")
            .arg(out.join("structure.toml"))
            .arg("--out")
            .arg(&out)
            .assert(),
        &["report.md", "not written by physfit"],
    );
    assert_eq!(
        std::fs::read_to_string(out.join("report.md")).unwrap(),
        "the user's report"
    );
    assert!(staging_in(dir.path()).is_empty() && staging_in(&out).is_empty());
}

#[test]
fn an_out_that_is_a_file_or_read_only_is_refused() {
    let dir = tempdir();
    let scene = short_scene(dir.path(), 2);
    let file = write(dir.path(), "plain", "a file");
    refused(
        render(&scene, &file),
        &["--out", "plain", "is a file, not a folder"],
    );
    assert_eq!(std::fs::read_to_string(&file).unwrap(), "a file");
    let ro = dir.path().join("ro");
    std::fs::create_dir(&ro).unwrap();
    let mut perms = std::fs::metadata(&ro).unwrap().permissions();
    perms.set_readonly(true);
    std::fs::set_permissions(&ro, perms.clone()).unwrap();
    refused(render(&scene, &ro), &["--out", "ro", "read-only"]);
    #[allow(clippy::permissions_set_readonly_false)]
    perms.set_readonly(false);
    std::fs::set_permissions(&ro, perms).unwrap();
    assert_eq!(std::fs::read_dir(&ro).unwrap().count(), 0);
}

#[test]
fn staging_folders_of_killed_runs_are_removed_by_the_next() {
    let dir = tempdir();
    let scene = short_scene(dir.path(), 2);
    let out = dir.path().join("out");
    // Left by processes that no longer run (no such pid), beside and (older versions) inside.
    std::fs::create_dir_all(dir.path().join(".out.physfit-run-999999999/frames")).unwrap();
    std::fs::create_dir_all(out.join(".physfit-render-999999999/frames")).unwrap();
    render(&scene, &out).success();
    assert!(staging_in(dir.path()).is_empty(), "{:?}", staging_in(dir.path()));
    assert!(staging_in(&out).is_empty(), "{:?}", staging_in(&out));
}

/// The files under `dir` (relative paths), with the content of the small text ones.
fn snapshot(dir: &Path) -> std::collections::BTreeMap<String, Option<String>> {
    let mut out = std::collections::BTreeMap::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                stack.push(p);
            } else {
                let rel = p.strip_prefix(dir).unwrap().to_string_lossy().into_owned();
                let text = (rel.ends_with(".txt") || rel.ends_with(".toml"))
                    .then(|| std::fs::read_to_string(&p).unwrap());
                out.insert(rel, text);
            }
        }
    }
    out
}

/// Runs `command` once to completion (it must succeed), then 20 times more, each killed with
/// SIGKILL at a seeded moment spread over the run's time (the first run's, shortened to the
/// moment of any kill that found its run already ended); after each kill the folder
/// `out` must hold the same files as after the complete run, with the same `.txt` and `.toml`
/// contents (a complete run of the same input writes the same set), and `check` must hold.
/// Returns the first run's time, s, and how many of the 20 had ended before their kill.
fn kill_at_seeded_moments(
    command: &dyn Fn() -> std::process::Command,
    out: &Path,
    check: &dyn Fn(&Path),
) -> (f64, usize) {
    let started = std::time::Instant::now();
    assert!(command().status().unwrap().success());
    let first = started.elapsed().as_secs_f64();
    // The moments are spread over the run's time as the runs show it: a run that ended
    // before its kill took at most that long, and the later moments are spread over that
    // (on a shared machine the first run, timed under another job's load, took 11.8 s and
    // half the later ones ended before their kill).
    let mut duration = first;
    write(out, "notes.txt", "the user's notes");
    let before = snapshot(out);
    // Seeded moments spread over the run's time (xorshift, seed 24).
    let mut state: u64 = 24;
    let mut completed = 0;
    for k in 0..20 {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        let at = duration * ((k as f64 + (state % 1000) as f64 / 1000.0) / 20.0);
        let mut child = command().spawn().unwrap();
        std::thread::sleep(std::time::Duration::from_secs_f64(at));
        if child.try_wait().unwrap().is_some() {
            completed += 1;
            duration = duration.min(at);
        }
        let _ = child.kill(); // SIGKILL
        child.wait().unwrap();
        // A killed single-file write may leave its hidden temporary file (`.NAME.PID.tmp`),
        // removed by the next write (`temporary_files_of_killed_writes_are_removed_by_the_next`).
        let mut now = snapshot(out);
        now.retain(|f, _| !(f.starts_with('.') && f.ends_with(".tmp")));
        assert_eq!(
            now.keys().collect::<Vec<_>>(),
            before.keys().collect::<Vec<_>>(),
            "killed at {at:.2} s (run {k})"
        );
        for (file, text) in &now {
            assert_eq!(text, &before[file], "{file}, killed at {at:.2} s (run {k})");
        }
        check(out);
    }
    (first, completed)
}

/// A command of physfit's with `args`, its output silenced.
fn quiet(args: &[&std::ffi::OsStr]) -> std::process::Command {
    let mut cmd = std::process::Command::new(env!("CARGO_BIN_EXE_physfit"));
    cmd.arg("-q").args(args);
    cmd.stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null());
    cmd
}

#[test]
fn a_run_killed_at_any_moment_leaves_the_folder_as_it_was_or_complete() {
    let dir = tempdir();
    let scene = short_scene(dir.path(), 100);
    let out = dir.path().join("out");
    let run = || {
        quiet(&[
            "run".as_ref(),
            scene.as_os_str(),
            "--out".as_ref(),
            out.as_os_str(),
        ])
    };
    let (duration, completed) = kill_at_seeded_moments(&run, &out, &|out| {
        let report: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).unwrap()).unwrap();
        assert!(report.get("findings").is_some());
    });
    assert!(crate::util::assert_finite_outputs(&out) == 4);
    eprintln!("killed 20 runs of a {duration:.1} s run; {completed} had already ended");
    assert!(
        completed < 10,
        "{completed} of 20 runs ended before their kill: the moments miss the run"
    );
    // The next run clears what the killed ones left beside the folder.
    assert!(run().status().unwrap().success());
    assert!(staging_in(dir.path()).is_empty(), "{:?}", staging_in(dir.path()));
}

/// `render`, `diagnose` and `track` killed at 20 seeded moments each: the folder as it was.
#[test]
fn render_diagnose_and_track_killed_at_any_moment_leave_the_folder_as_it_was() {
    let dir = tempdir();
    let scene = short_scene(dir.path(), 100);
    let rendered = dir.path().join("rendered");
    let render = || {
        quiet(&[
            "render".as_ref(),
            scene.as_os_str(),
            "--out".as_ref(),
            rendered.as_os_str(),
        ])
    };
    let (duration, completed) = kill_at_seeded_moments(&render, &rendered, &|out| {
        assert_eq!(std::fs::read_dir(out.join("frames")).unwrap().count(), 100);
    });
    eprintln!("render: killed 20 of a {duration:.2} s run; {completed} had already ended");
    let truth = rendered.join("truth.csv");
    let structure = rendered.join("structure.toml");
    let diagnosed = dir.path().join("diagnosed");
    let diagnose = || {
        quiet(&[
            "diagnose".as_ref(),
            truth.as_os_str(),
            "--structure".as_ref(),
            structure.as_os_str(),
            "--window".as_ref(),
            "0..40".as_ref(),
            "--out".as_ref(),
            diagnosed.as_os_str(),
        ])
    };
    let (duration, completed) = kill_at_seeded_moments(&diagnose, &diagnosed, &|out| {
        let report: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).unwrap()).unwrap();
        assert!(report.get("findings").is_some());
    });
    eprintln!("diagnose: killed 20 of a {duration:.2} s run; {completed} had already ended");
    // `track` writes one file: whole or as it was, never half.
    let tracked = dir.path().join("tracked");
    std::fs::create_dir_all(&tracked).unwrap();
    let tracks = tracked.join("tracks.csv");
    let frames = rendered.join("frames");
    let track = || {
        quiet(&[
            "track".as_ref(),
            frames.as_os_str(),
            "--structure".as_ref(),
            structure.as_os_str(),
            "--out".as_ref(),
            tracks.as_os_str(),
        ])
    };
    let whole = |out: &Path| {
        let text = std::fs::read_to_string(out.join("tracks.csv")).unwrap();
        assert_eq!(text.lines().count(), 1 + 5 * 100, "a whole tracks.csv");
    };
    let (duration, completed) = kill_at_seeded_moments(&track, &tracked, &|out| {
        whole(out);
    });
    eprintln!("track: killed 20 of a {duration:.2} s run; {completed} had already ended");
}

#[test]
fn out_as_the_working_folder_keeps_the_folder_and_the_users_files() {
    let dir = tempdir();
    let scene = short_scene(dir.path(), 3);
    let out = dir.path().join("here");
    std::fs::create_dir(&out).unwrap();
    write(&out, "notes.txt", "the user's notes");
    for _ in 0..2 {
        physfit()
            .current_dir(&out)
            .args(["-q", "render"])
            .arg(&scene)
            .args(["--out", "."])
            .assert()
            .success();
    }
    assert_eq!(
        std::fs::read_to_string(out.join("notes.txt")).unwrap(),
        "the user's notes"
    );
    assert_eq!(std::fs::read_dir(out.join("frames")).unwrap().count(), 3);
    assert!(
        out.join("truth.csv").exists() && staging_in(&out).is_empty() && staging_in(dir.path()).is_empty()
    );
}

#[test]
fn temporary_files_of_killed_writes_are_removed_by_the_next() {
    let dir = tempdir();
    let scene = short_scene(dir.path(), 3);
    let out = dir.path().join("truth.csv");
    // Left by writers killed between creating and renaming them (no such pid), and one of a
    // running process (this test's) that must stay.
    write(dir.path(), ".truth.csv.999999999.tmp", "half");
    write(dir.path(), ".truth.csv.999999999.3.tmp", "half");
    let live = format!(".truth.csv.{}.0.tmp", std::process::id());
    write(dir.path(), &live, "being written");
    physfit()
        .args(["-q", "simulate"])
        .arg(&scene)
        .arg("--out")
        .arg(&out)
        .assert()
        .success();
    let mut left: Vec<String> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.ends_with(".tmp"))
        .collect();
    left.sort();
    assert_eq!(left, [live]);
}

/// A folder written by a physfit from before the output list was kept (no `.physfit-outputs`)
/// is recognised by its `report.json` or its render outputs: its files of physfit's names
/// are replaced, the user's others kept; without those marks the same files are refused.
#[test]
fn an_earlier_physfits_output_folder_is_taken_as_physfits() {
    let dir = tempdir();
    let scene = short_scene(dir.path(), 4);
    let out = dir.path().join("out");
    render(&scene, &out).success();
    // As an earlier physfit left it: no list, an extra frame, and the user's notes.
    std::fs::remove_file(out.join(".physfit-outputs")).unwrap();
    std::fs::copy(out.join("frames/000000.png"), out.join("frames/000009.png")).unwrap();
    write(&out, "notes.txt", "the user's notes");
    render(&scene, &out).success();
    assert_eq!(std::fs::read_dir(out.join("frames")).unwrap().count(), 4);
    assert_eq!(
        std::fs::read_to_string(out.join("notes.txt")).unwrap(),
        "the user's notes"
    );
    // The same frames in a folder with no mark of physfit's are the user's.
    let other = dir.path().join("other");
    std::fs::create_dir_all(other.join("frames")).unwrap();
    std::fs::copy(out.join("frames/000000.png"), other.join("frames/000000.png")).unwrap();
    refused(render(&scene, &other), &["000000.png", "not written by physfit"]);
}
