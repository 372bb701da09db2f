//! Byte-identical outputs against a reference binary: ignored by default, run by hand before a
//! change that must not move any output (a refactoring, a dependency update). See
//! `docs/ARCHITECTURE.md`, "Checking a refactoring":
//!
//! ```text
//! PHYSFIT_REFERENCE_BIN=/path/to/old/physfit \
//!     cargo test --release --test integration -- --ignored byte_identical --nocapture
//! ```
//!
//! Each case runs the same commands with both binaries, each time into the same output folder
//! (so the paths written into reports agree), and then compares every file the commands wrote,
//! byte for byte, plus each command's exit status and standard error (which holds only errors
//! under `-q`). The one allowed difference is a measured duration: in JSON the value of a
//! `"seconds"` key or of a key inside a `"times"` object, in Markdown and HTML the stage-times
//! line of `run` (`render 1.0 s, track 0.2 s, ...; total 11.8 s.`) and the diagnosis's
//! summary line (`Frames 3..86 analysed; track noise 0.0709 px per coordinate; 0.7 s.`), and
//! only where the two lines are equal once their numbers are masked. Everything else (tracks.csv, fitted.toml, the pictures,
//! every other line of the reports) must be equal to the byte.
//!
//! The cases: `run` of the built-in default scene and of two canonical scenes; for each shared
//! real recording (`../shared/real/*`, skipped when absent) `track` (with `--detections`),
//! `fit`, `diagnose` and `run --frames`; `fit` of the other trackers' fixture tables
//! (`fixtures/tables/`) and of malformed tables (their errors compared).

use std::collections::BTreeMap;
use std::ffi::OsString;
use std::path::{Path, PathBuf};
use std::process::Command;

use crate::util::tempdir;

/// The placeholder for the case's output folder in a command's arguments.
const OUT: &str = "{out}";

/// One case: a name and its commands (arguments after the binary, `{out}` in them replaced by
/// the output folder), run in order.
struct Case {
    name: String,
    commands: Vec<Vec<OsString>>,
    /// Files written into the output folder before the commands run (same for both binaries).
    inputs: Vec<(&'static str, String)>,
}

fn args(list: &[&dyn AsRef<std::ffi::OsStr>]) -> Vec<OsString> {
    list.iter().map(|a| a.as_ref().to_os_string()).collect()
}

/// The cases (see the module doc).
fn cases() -> Vec<Case> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let scenes = root.join("scenes");
    let out = |rest: &str| format!("{OUT}/{rest}");
    let mut cases = vec![Case {
        name: "run default".into(),
        commands: vec![args(&[&"-q", &"run", &"--out", &out("run")])],
        inputs: Vec::new(),
    }];
    for scene in ["concealed-gravity-floor.toml", "paper3.toml"] {
        cases.push(Case {
            name: format!("run {scene}"),
            commands: vec![args(&[&"-q", &"run", &scenes.join(scene), &"--out", &out("run")])],
            inputs: Vec::new(),
        });
    }
    let real = root.join("../shared/real");
    for (name, window) in [
        ("ball-toss", Some("2..12")),
        ("bouncing-ball", None),
        ("pendulum-scale", None),
    ] {
        let dir = real.join(name);
        if !dir.is_dir() {
            println!("skipped: real recording {} not found", dir.display());
            continue;
        }
        let frames = dir.join("frames");
        let structure = dir.join("structure.toml");
        let window: Vec<&str> = window.map_or(Vec::new(), |w| vec!["--window", w]);
        let with_window = |mut a: Vec<OsString>| {
            a.extend(window.iter().map(OsString::from));
            a
        };
        let tracks = out("tracks.csv");
        cases.push(Case {
            name: format!("real {name}"),
            commands: vec![
                with_window(args(&[
                    &"-q",
                    &"track",
                    &frames,
                    &"--structure",
                    &structure,
                    &"--out",
                    &tracks,
                    &"--detections",
                    &out("detections.csv"),
                ])),
                with_window(args(&[
                    &"-q",
                    &"fit",
                    &tracks,
                    &"--structure",
                    &structure,
                    &"--out",
                    &out("fitted.toml"),
                    &"--report",
                    &out("fit.json"),
                ])),
                with_window(args(&[
                    &"-q",
                    &"diagnose",
                    &tracks,
                    &"--structure",
                    &structure,
                    &"--out",
                    &out("diagnose"),
                ])),
                with_window(args(&[
                    &"-q",
                    &"run",
                    &"--frames",
                    &frames,
                    &"--structure",
                    &structure,
                    &"--out",
                    &out("run"),
                ])),
            ],
            inputs: Vec::new(),
        });
    }
    // Other trackers' tables: the same two tracks (20 frames at 25 frames/s) written in each
    // format (generated, as the fixtures are too short to fit), the fixtures themselves (read,
    // then refused alike as too short) and malformed tables (their errors compared).
    let structure = "[recording]\nfps = 25.0\nframes = 20\n\n\
        [[particles]]\nid = \"a\"\nmass = 1.0\nposition = [100.0, 50.0]\n\n\
        [[particles]]\nid = \"b\"\nmass = 1.0\nposition = [200.0, 80.0]\n\n\
        [[springs]]\nbetween = [\"a\", \"b\"]\n";
    let mut inputs = vec![("structure.toml", structure.to_string())];
    inputs.extend(foreign_tables());
    inputs.extend([
        (
            "bad-cell.csv",
            "frame,particle,x,y\n0,a,100,50\n1,a,abc,51\n".to_string(),
        ),
        (
            "duplicate.csv",
            ",y,x,frame,particle\n0,50,100,0,1\n1,50,101,0,1\n".to_string(),
        ),
        ("unknown.csv", "a,b,c\n1,2,3\n".to_string()),
    ]);
    let tables = root.join("fixtures/tables");
    let mut commands = Vec::new();
    let inputs_named: Vec<&str> = inputs.iter().map(|(n, _)| *n).collect();
    for (file, extra) in [
        ("physfit.csv", vec![]),
        ("trackpy.csv", vec![]),
        ("trackmate.csv", vec!["--px-per-unit", "2"]),
        ("tracker.txt", vec!["--scale", "0.001"]),
        ("bad-cell.csv", vec![]),
        ("duplicate.csv", vec![]),
        ("unknown.csv", vec![]),
    ] {
        for fixture in [false, true] {
            let path = if fixture {
                if !tables.join(file).is_file() {
                    continue;
                }
                tables.join(file)
            } else {
                assert!(inputs_named.contains(&file));
                PathBuf::from(out(file))
            };
            let stem = format!(
                "{}-{}",
                file.replace('.', "-"),
                if fixture { "fixture" } else { "generated" }
            );
            let mut a = args(&[
                &"-q",
                &"fit",
                &path,
                &"--structure",
                &out("structure.toml"),
                &"--out",
                &out(&format!("{stem}.toml")),
                &"--report",
                &out(&format!("{stem}.json")),
                &"--method",
                &"lsq",
            ]);
            a.extend(extra.iter().map(OsString::from));
            commands.push(a);
        }
    }
    cases.push(Case {
        name: "tables".into(),
        commands,
        inputs,
    });
    cases
}

/// Two tracks, `a` from (100, 50) px and `b` from (200, 80) px, over 20 frames, as physfit,
/// trackpy (ids 4 and 11), TrackMate (in units of 0.5 px: `--px-per-unit 2`) and Tracker
/// (metres at 0.001 m/px, y up, times from 0.2 s) tables.
fn foreign_tables() -> Vec<(&'static str, String)> {
    let point = |id: usize, k: usize| {
        let k = k as f64;
        if id == 0 {
            (100.0 + 3.0 * k + 0.05 * k * k, 50.0 + 0.5 * k)
        } else {
            (200.0 - 2.0 * k, 80.0 + k - 0.02 * k * k)
        }
    };
    let mut physfit = String::from("frame,particle,x,y\n");
    let mut trackpy = String::from(",y,x,mass,size,ecc,signal,raw_mass,ep,frame,particle\n");
    let mut trackmate =
        String::from("LABEL,ID,TRACK_ID,QUALITY,POSITION_X,POSITION_Y,POSITION_Z,POSITION_T,FRAME\n");
    let mut tracker = String::from("mass A\t\t\tmass B\t\t\nt\tx\ty\tt\tx\ty\n");
    for k in 0..20 {
        let t = 0.2 + k as f64 / 25.0;
        let mut row = Vec::new();
        for (id, (name, tp_id)) in [("a", 4), ("b", 11)].into_iter().enumerate() {
            let (x, y) = point(id, k);
            let i = 2 * k + id;
            physfit.push_str(&format!("{k},{name},{x},{y}\n"));
            trackpy.push_str(&format!(
                "{i},{y},{x},812.5,2.9,0.01,40.0,1201.0,0.02,{k}.0,{tp_id}.0\n"
            ));
            trackmate.push_str(&format!(
                "ID{i},{i},{id},12.5,{},{},0.0,{t},{k}\n",
                x / 2.0,
                y / 2.0
            ));
            row.push(format!("{t}\t{}\t{}", x / 1000.0, -y / 1000.0));
        }
        tracker.push_str(&row.join("\t"));
        tracker.push('\n');
    }
    vec![
        ("physfit.csv", physfit),
        ("trackpy.csv", trackpy),
        ("trackmate.csv", trackmate),
        ("tracker.txt", tracker),
    ]
}

/// What one command did: its exit status and standard error.
type Outcome = (Option<i32>, String);

/// Runs `case` with `binary` into `work/out`, then moves the folder to `work/<label>`.
fn run_case(binary: &Path, case: &Case, work: &Path, label: &str) -> Vec<Outcome> {
    let out = work.join("out");
    let _ = std::fs::remove_dir_all(&out);
    std::fs::create_dir_all(&out).expect("output folder");
    for (name, text) in &case.inputs {
        std::fs::write(out.join(name), text).expect("input file");
    }
    let outcomes = case
        .commands
        .iter()
        .map(|a| {
            let a: Vec<OsString> = a
                .iter()
                .map(|s| OsString::from(s.to_string_lossy().replace(OUT, &out.to_string_lossy())))
                .collect();
            let o = Command::new(binary)
                .args(&a)
                .env_remove("RUST_LOG")
                .output()
                .expect("start physfit");
            (o.status.code(), String::from_utf8_lossy(&o.stderr).into_owned())
        })
        .collect();
    std::fs::rename(&out, work.join(label)).expect("move output folder");
    outcomes
}

/// Every file under `dir`, by path relative to it.
fn files(dir: &Path) -> BTreeMap<PathBuf, Vec<u8>> {
    let mut out = BTreeMap::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).expect("read folder") {
            let p = e.expect("folder entry").path();
            if p.is_dir() {
                stack.push(p);
            } else {
                let rel = p.strip_prefix(dir).expect("inside").to_path_buf();
                out.insert(rel, std::fs::read(&p).expect("read file"));
            }
        }
    }
    out
}

/// `line` with every number replaced by `#`; with `seconds_only`, only the numbers followed by
/// ` s` (a duration in seconds: `0.7 s.`, `1.0 s,`).
fn mask_numbers(line: &str, seconds_only: bool) -> String {
    let mut out = String::new();
    let mut rest = line;
    while let Some(start) = rest.find(|c: char| c.is_ascii_digit()) {
        let len = rest[start..]
            .find(|c: char| !(c.is_ascii_digit() || c == '.'))
            .unwrap_or(rest.len() - start);
        let after = &rest[start + len..];
        let is_seconds = after
            .strip_prefix(" s")
            .is_some_and(|a| !a.starts_with(char::is_alphanumeric));
        out.push_str(&rest[..start]);
        out.push_str(if seconds_only && !is_seconds {
            &rest[start..start + len]
        } else {
            "#"
        });
        rest = after;
    }
    out.push_str(rest);
    out
}

/// `line` with its measured durations masked (the module doc); `in_times` says whether the line
/// is inside a JSON `"times"` object.
fn mask_durations(line: &str, in_times: bool) -> String {
    let t = line.trim_start();
    if t.starts_with("\"seconds\":") || in_times {
        return mask_numbers(line, false);
    }
    let stage_times = (t.starts_with("render ") || t.starts_with("<p>render ")) && t.contains("; total ");
    let diagnosis_time = t.contains(" analysed; track noise ") && t.contains(" per coordinate; ");
    if stage_times || diagnosis_time {
        mask_numbers(line, true)
    } else {
        line.to_string()
    }
}

/// Whether two lines of a report differ only in a measured duration.
fn duration_only(a: &str, b: &str, in_times: bool) -> bool {
    mask_durations(a, in_times) == mask_durations(b, in_times)
}

/// The differences between two versions of one file: `None` when identical, `Some(count)` of
/// duration-only lines when they differ only there, `Err` naming the first other difference.
fn compare(name: &Path, a: &[u8], b: &[u8]) -> Result<Option<usize>, String> {
    if a == b {
        return Ok(None);
    }
    let text = matches!(
        name.extension().and_then(|e| e.to_str()),
        Some("json" | "md" | "html")
    );
    let (Ok(ta), Ok(tb), true) = (std::str::from_utf8(a), std::str::from_utf8(b), text) else {
        return Err(format!("{}: bytes differ", name.display()));
    };
    let (la, lb): (Vec<&str>, Vec<&str>) = (ta.split('\n').collect(), tb.split('\n').collect());
    if la.len() != lb.len() {
        return Err(format!("{}: {} lines vs {}", name.display(), la.len(), lb.len()));
    }
    let mut in_times = false;
    let mut masked = 0;
    for (k, (x, y)) in la.iter().zip(&lb).enumerate() {
        if x.trim_start().starts_with("\"times\": {") {
            in_times = true;
            continue;
        }
        if in_times && x.trim_start().starts_with('}') {
            in_times = false;
        }
        if x != y {
            if !duration_only(x, y, in_times) {
                return Err(format!("{}:{}: `{x}` vs `{y}`", name.display(), k + 1));
            }
            masked += 1;
        }
    }
    Ok(Some(masked))
}

#[test]
fn masks_only_durations() {
    assert!(duration_only(
        "  \"seconds\": 0.19,",
        "  \"seconds\": 10.2,",
        false
    ));
    assert!(duration_only("    \"fit\": 0.19,", "    \"fit\": 0.2,", true));
    assert!(!duration_only("    \"fit\": 0.19,", "    \"fit\": 0.2,", false));
    assert!(duration_only(
        "render 1.0 s, track 0.2 s, fit 0.2 s, diagnose 10.3 s, report 0.1 s; total 11.8 s.",
        "render 0.8 s, track 0.2 s, fit 0.2 s, diagnose 11.1 s, report 0.1 s; total 12.4 s.",
        false
    ));
    assert!(duration_only(
        "<p>Frames 3..86 analysed; track noise 0.0709 px per coordinate; 0.7 s.</p>",
        "<p>Frames 3..86 analysed; track noise 0.0709 px per coordinate; 0.8 s.</p>",
        false
    ));
    assert!(!duration_only(
        "Frames 3..86 analysed; track noise 0.0709 px per coordinate; 0.7 s.",
        "Frames 3..86 analysed; track noise 0.0710 px per coordinate; 0.7 s.",
        false
    ));
    assert!(!duration_only(
        "render 1.0 s, track 0.2 s; total 11.8 s.",
        "render 1.0 s, track 0.2 s; total 11.8 s, 3 frames.",
        false
    ));
    assert!(!duration_only("  \"value\": 0.4,", "  \"value\": 0.5,", false));
    assert!(!duration_only(
        "  \"seconds\": 0.19,",
        "  \"second\": 0.19,",
        false
    ));
    let a = b"{\n  \"times\": {\n    \"fit\": 0.1\n  },\n  \"fit\": 3\n}";
    let b = b"{\n  \"times\": {\n    \"fit\": 0.2\n  },\n  \"fit\": 4\n}";
    assert!(compare(Path::new("r.json"), a, b)
        .unwrap_err()
        .contains("r.json:5"));
}

#[test]
#[ignore = "needs PHYSFIT_REFERENCE_BIN, a physfit binary built from the commit compared with"]
fn byte_identical_to_the_reference_binary() {
    let reference = PathBuf::from(
        std::env::var_os("PHYSFIT_REFERENCE_BIN")
            .expect("set PHYSFIT_REFERENCE_BIN to the reference physfit binary"),
    );
    let ours = Path::new(env!("CARGO_BIN_EXE_physfit"));
    let mut failures = Vec::new();
    let (mut identical, mut duration_only_files) = (0, 0);
    for case in cases() {
        let work = tempdir();
        let ref_outcomes = run_case(&reference, &case, work.path(), "reference");
        let our_outcomes = run_case(ours, &case, work.path(), "ours");
        for (k, (r, o)) in ref_outcomes.iter().zip(&our_outcomes).enumerate() {
            if r != o {
                failures.push(format!("{}: command {} ends {r:?} vs {o:?}", case.name, k + 1));
            }
        }
        let (rf, of) = (
            files(&work.path().join("reference")),
            files(&work.path().join("ours")),
        );
        if rf.keys().ne(of.keys()) {
            failures.push(format!(
                "{}: files {:?} vs {:?}",
                case.name,
                rf.keys().collect::<Vec<_>>(),
                of.keys().collect::<Vec<_>>()
            ));
        }
        let mut lines = 0;
        for (name, a) in &rf {
            let Some(b) = of.get(name) else { continue };
            match compare(name, a, b) {
                Ok(None) => identical += 1,
                Ok(Some(n)) => {
                    duration_only_files += 1;
                    lines += n;
                }
                Err(e) => failures.push(format!("{}: {e}", case.name)),
            }
        }
        let errors = ref_outcomes.iter().filter(|o| o.0 != Some(0)).count();
        println!(
            "{}: {} commands ({errors} failing alike), {} files compared, {lines} duration lines masked",
            case.name,
            case.commands.len(),
            rf.len()
        );
        for (k, (code, stderr)) in ref_outcomes.iter().enumerate() {
            if *code != Some(0) {
                println!(
                    "  command {} (exit {code:?}): {}",
                    k + 1,
                    stderr.lines().next().unwrap_or("")
                );
            }
        }
    }
    println!("{identical} files byte-identical, {duration_only_files} identical but for durations");
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}
