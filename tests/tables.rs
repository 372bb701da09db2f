//! Other trackers' tables, end to end: a trackpy CSV and a TrackMate CSV of the same tracks,
//! with other track ids in another order, give the same fit as physfit's own CSV.

use std::path::{Path, PathBuf};

use serde_json::Value;

use crate::util::{physfit, scenes_dir, tempdir};

/// `physfit fit --method lsq` of `tracks` against `structure` with `extra` arguments: the
/// parameter values of fit.json.
fn fit_values(tracks: &Path, structure: &Path, out: &Path, extra: &[&str]) -> Vec<f64> {
    let report = out.with_extension("json");
    physfit()
        .arg("-q")
        .arg("fit")
        .arg(tracks)
        .arg("--structure")
        .arg(structure)
        .arg("--out")
        .arg(out)
        .arg("--report")
        .arg(&report)
        .arg("--method")
        .arg("lsq")
        .args(extra)
        .assert()
        .success();
    let json: Value = serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
    json["parameters"]
        .as_array()
        .unwrap()
        .iter()
        .map(|p| p["value"].as_f64().unwrap())
        .collect()
}

/// The rows of a physfit tracks.csv: frame, particle, x, y, ep.
fn rows(path: &Path) -> Vec<(usize, String, String, String, String)> {
    let mut rdr = csv::Reader::from_path(path).unwrap();
    let h = rdr.headers().unwrap().clone();
    let col = |n: &str| h.iter().position(|c| c == n).unwrap();
    let (f, p, x, y, ep) = (col("frame"), col("particle"), col("x"), col("y"), col("ep"));
    rdr.records()
        .map(|r| {
            let r = r.unwrap();
            (
                r[f].parse().unwrap(),
                r[p].to_string(),
                r[x].to_string(),
                r[y].to_string(),
                r[ep].to_string(),
            )
        })
        .collect()
}

/// Writes the tracks as trackpy would (`to_csv` of a linked DataFrame) and as TrackMate's
/// spot table (pixel units, rows grouped by track, one spot in no track), both with the
/// track ids in `ids`.
fn write_foreign(
    tracks: &[(usize, String, String, String, String)],
    ids: &dyn Fn(&str) -> String,
    dir: &Path,
) -> (PathBuf, PathBuf) {
    let mut tp = String::from(",y,x,mass,size,ecc,signal,raw_mass,ep,frame,particle\n");
    for (i, (f, p, x, y, ep)) in tracks.iter().enumerate() {
        // trackpy's frame and particle come out as floats after a merge with NaN.
        tp.push_str(&format!(
            "{i},{y},{x},812.5,2.9,0.01,40.0,1201.0,{ep},{f}.0,{}.0\n",
            ids(p)
        ));
    }
    let mut tm = String::from(
        "LABEL,ID,TRACK_ID,QUALITY,POSITION_X,POSITION_Y,POSITION_Z,POSITION_T,FRAME,RADIUS,VISIBILITY\n\
         Label,Spot ID,Track ID,Quality,X,Y,Z,T,Frame,Radius,Visibility\n\
         Label,Spot ID,Track ID,Quality,X,Y,Z,T,Frame,R,Visibility\n\
         ,,,(quality),(pixel),(pixel),(pixel),(frame),,(pixel),\n",
    );
    let mut by_track: Vec<&(usize, String, String, String, String)> = tracks.iter().collect();
    by_track.sort_by_key(|r| (ids(&r.1), r.0));
    for (i, (f, p, x, y, _)) in by_track.into_iter().enumerate() {
        tm.push_str(&format!("ID{i},{i},{},7.5,{x},{y},0.0,{f},{f},4.0,1\n", ids(p)));
    }
    tm.push_str("ID99999,99999,,0.3,3.0,3.0,0.0,0,0,4.0,1\n");
    let (tp_path, tm_path) = (dir.join("trackpy.csv"), dir.join("trackmate.csv"));
    std::fs::write(&tp_path, tp).unwrap();
    std::fs::write(&tm_path, tm).unwrap();
    (tp_path, tm_path)
}

#[test]
fn trackpy_and_trackmate_tables_give_the_same_fit_as_physfits_own() {
    let dir = tempdir();
    let d = dir.path();
    physfit()
        .args(["-q", "render"])
        .arg(scenes_dir().join("paper3.toml"))
        .arg("--out")
        .arg(d)
        .assert()
        .success();
    let structure = d.join("structure.toml");
    let tracks = d.join("tracks.csv");
    physfit()
        .args(["-q", "track"])
        .arg(d.join("frames"))
        .arg("--structure")
        .arg(&structure)
        .arg("--out")
        .arg(&tracks)
        .assert()
        .success();
    let own = fit_values(&tracks, &structure, &d.join("own.toml"), &[]);
    let table = rows(&tracks);
    // Shuffled ids: the structure's ids reversed in order and renamed to numbers.
    let mut names: Vec<String> = table.iter().map(|r| r.1.clone()).collect();
    names.sort();
    names.dedup();
    let ids = |p: &str| {
        let k = names.iter().position(|n| n == p).unwrap();
        format!("{}", 10 * (names.len() - k) + 3)
    };
    let (tp, tm) = write_foreign(&table, &ids, d);
    for (path, format) in [(&tp, "trackpy"), (&tm, "trackmate")] {
        for extra in [&[][..], &["--format", format][..]] {
            let got = fit_values(path, &structure, &d.join(format!("{format}.toml")), extra);
            assert_eq!(got.len(), own.len());
            for (a, b) in got.iter().zip(&own) {
                assert!(
                    (a - b).abs() <= 1e-9 * b.abs().max(1e-300),
                    "{format} {extra:?}: {a} vs physfit's {b}"
                );
            }
        }
    }
    println!("trackpy and trackmate fits equal physfit's: {own:?}");
}

#[test]
fn bad_tables_are_named_with_file_and_line() {
    let dir = tempdir();
    let d = dir.path();
    physfit()
        .args(["-q", "render"])
        .arg(scenes_dir().join("clean-pendulum.toml"))
        .arg("--out")
        .arg(d)
        .assert()
        .success();
    let cases = [
        (
            "truncated.csv",
            ",y,x,frame,particle\n0,1,2,0,1\n1,1,2",
            "truncated.csv:3:",
        ),
        (
            "nan.csv",
            ",y,x,frame,particle\n0,NaN,2,0,1\n",
            "nan.csv:2: column `y`",
        ),
        (
            "text.csv",
            ",y,x,frame,particle\n0,1,two,0,1\n",
            "text.csv:2: column `x`",
        ),
        (
            "dup.csv",
            ",y,x,frame,particle\n0,1,2,0,1\n1,1,2,0,1\n",
            "dup.csv:3:",
        ),
        (
            "cols.csv",
            "LABEL,TRACK_ID,POSITION_X,FRAME\nID0,0,1.0,0\n",
            "missing column `POSITION_Y`",
        ),
        ("what.csv", "a,b,c\n1,2,3\n", "--format"),
    ];
    for (name, text, want) in cases {
        let path = d.join(name);
        std::fs::write(&path, text).unwrap();
        let out = physfit()
            .arg("fit")
            .arg(&path)
            .arg("--structure")
            .arg(d.join("structure.toml"))
            .arg("--out")
            .arg(d.join("fitted.toml"))
            .assert()
            .failure();
        let err = String::from_utf8_lossy(&out.get_output().stderr).to_string();
        assert!(err.contains(want), "{name}: {err}");
        assert!(!err.contains("panicked"), "{name}: {err}");
    }
}

/// A Tracker data export of the same tracks: masses named `mass A`..., times from 0.5 s,
/// positions in metres (0.002 m/px) with y up around an origin at (100, 300) px, side by side
/// with a names line. Read with `--scale 0.002 --origin 100,300`, it fits like physfit's own
/// CSV, to rounding (1e-9 relative).
#[test]
fn a_tracker_export_gives_the_same_fit_as_physfits_own() {
    let dir = tempdir();
    let d = dir.path();
    physfit()
        .args(["-q", "render"])
        .arg(scenes_dir().join("paper3.toml"))
        .arg("--out")
        .arg(d)
        .assert()
        .success();
    let structure = d.join("structure.toml");
    let truth = d.join("truth.csv");
    let own = fit_values(&truth, &structure, &d.join("own.toml"), &[]);
    let fps: f64 = std::fs::read_to_string(&structure)
        .unwrap()
        .lines()
        .find_map(|l| l.strip_prefix("fps = ").map(|v| v.trim().parse().unwrap()))
        .unwrap();
    let mut rdr = csv::Reader::from_path(&truth).unwrap();
    let rows: Vec<(usize, String, f64, f64)> = rdr
        .records()
        .map(|r| {
            let r = r.unwrap();
            (
                r[0].parse().unwrap(),
                r[1].to_string(),
                r[2].parse().unwrap(),
                r[3].parse().unwrap(),
            )
        })
        .collect();
    let mut names: Vec<String> = rows.iter().map(|r| r.1.clone()).collect();
    names.dedup();
    names.sort();
    names.dedup();
    let frames = rows.iter().map(|r| r.0).max().unwrap() + 1;
    let mut text = names
        .iter()
        .enumerate()
        .map(|(k, _)| format!("mass {}\t\t", (b'A' + k as u8) as char))
        .collect::<Vec<_>>()
        .join("\t");
    text.push('\n');
    text.push_str(&vec!["t\tx\ty"; names.len()].join("\t"));
    text.push('\n');
    for f in 0..frames {
        let t = 0.5 + f as f64 / fps;
        let cells: Vec<String> = names
            .iter()
            .map(|n| {
                let r = rows.iter().find(|r| r.0 == f && &r.1 == n).unwrap();
                format!("{t}\t{}\t{}", (r.2 - 100.0) * 0.002, -(r.3 - 300.0) * 0.002)
            })
            .collect();
        text.push_str(&cells.join("\t"));
        text.push('\n');
    }
    let path = d.join("tracker.txt");
    std::fs::write(&path, text).unwrap();
    let got = fit_values(
        &path,
        &structure,
        &d.join("tracker.toml"),
        &["--scale", "0.002", "--origin", "100,300"],
    );
    for (a, b) in got.iter().zip(&own) {
        assert!((a - b).abs() <= 1e-9 * b.abs(), "tracker: {a} vs physfit's {b}");
    }
}

/// `diagnose` reads a foreign table like `fit`: the true centres of a scene with a concealed
/// field, written as a TrackMate spot table (pixel units, numbered tracks), give the same
/// findings with the same values as physfit's own CSV.
#[test]
fn diagnose_reads_a_trackmate_table_like_physfits_own() {
    let dir = tempdir();
    let d = dir.path();
    physfit()
        .args(["-q", "render"])
        .arg(scenes_dir().join("concealed-gravity.toml"))
        .arg("--out")
        .arg(d)
        .assert()
        .success();
    let truth = d.join("truth.csv");
    let mut rdr = csv::Reader::from_path(&truth).unwrap();
    let table: Vec<(usize, String, String, String, String)> = rdr
        .records()
        .map(|r| {
            let r = r.unwrap();
            (
                r[0].parse().unwrap(),
                r[1].to_string(),
                r[2].to_string(),
                r[3].to_string(),
                String::new(),
            )
        })
        .collect();
    let mut names: Vec<String> = table.iter().map(|r| r.1.clone()).collect();
    names.sort();
    names.dedup();
    let ids = |p: &str| format!("{}", 7 + names.iter().position(|n| n == p).unwrap());
    let (_, tm) = write_foreign(&table, &ids, d);
    let findings = |tracks: &Path, out: &str| -> Vec<(String, Vec<f64>)> {
        physfit()
            .args(["-q", "diagnose"])
            .arg(tracks)
            .arg("--structure")
            .arg(d.join("structure.toml"))
            .arg("--out")
            .arg(d.join(out))
            .assert()
            .success();
        let json: Value =
            serde_json::from_str(&std::fs::read_to_string(d.join(out).join("report.json")).unwrap()).unwrap();
        json["findings"]
            .as_array()
            .unwrap()
            .iter()
            .map(|f| {
                let values = f["parameters"]
                    .as_array()
                    .unwrap()
                    .iter()
                    .map(|p| p["value"].as_f64().unwrap())
                    .collect();
                (f["effect"].as_str().unwrap().to_string(), values)
            })
            .collect()
    };
    let own = findings(&truth, "own");
    let got = findings(&tm, "trackmate");
    assert!(!own.is_empty());
    assert_eq!(got.len(), own.len(), "{got:?} vs {own:?}");
    for ((e1, v1), (e2, v2)) in got.iter().zip(&own) {
        assert_eq!(e1, e2);
        for (a, b) in v1.iter().zip(v2) {
            assert!((a - b).abs() <= 1e-9 * b.abs().max(1.0), "{e1}: {a} vs {b}");
        }
    }
}
