//! Issue 21: twelve fixed seeds of `physfit bench diagnose --small`, seeds 1 to 12 (the first
//! twelve of the sequence, not chosen), each through the binary: draw the recording, render,
//! track, diagnose, judge (`crates/cli/bench/diagnose/`). `--small` caps a recording at 4
//! particles and 150 frames, so that each seed runs in a few seconds.
//!
//! Each asserts the recording is diagnosed exactly right: every detectable concealed effect
//! found, nothing found that was not concealed (marginal effects may be found or not), and
//! each detectable effect's found values within tolerance: magnitudes (a field as a vector, a
//! drag, a dashpot, a spring's stiffness and length, a tether's length) within 10 %, a wall's
//! line within 1 px and its restitution within 0.05, a tether's fixed point within 2 % of its
//! length.
//!
//! Five full-size recordings of the N = 100 run (seeds 20, 23, 53, 71 and 84, each a class
//! this work fixed) are judged the same way.
//!
//! Seeds the diagnosis gets wrong today are ignored, with what goes wrong; `cargo test --test
//! integration bench_seed -- --include-ignored` runs them all.

use serde_json::Value;

use crate::util::{physfit, tempdir};

/// Largest relative error of a magnitude.
const RELATIVE: f64 = 0.10;
/// Largest distance of a found wall's line from the true one, px.
const WALL_LINE_PX: f64 = 1.0;
/// Largest error of a restitution.
const RESTITUTION: f64 = 0.05;
/// Largest distance of a tether's found fixed point, as a fraction of its true length.
const FIXED_POINT_OF_LENGTH: f64 = 0.02;

/// Runs recording `seed` of `physfit bench diagnose --small` and asserts it is diagnosed
/// exactly right, its detectable values within tolerance.
fn bench_seed(seed: u64) {
    judge_seed(seed, true);
}

/// Runs recording `seed` of `physfit bench diagnose [--small] EXTRA...` and returns its
/// result from `--json`.
fn bench_result(seed: u64, small: bool, extra: &[&str]) -> Value {
    let dir = tempdir();
    let json = dir.path().join("results.json");
    let mut command = physfit();
    command.args(["-q", "bench", "diagnose", "--count", "1"]);
    if small {
        command.arg("--small");
    }
    command
        .args(extra)
        .arg("--seed")
        .arg(seed.to_string())
        .arg("--json")
        .arg(&json)
        .assert()
        .success();
    let text = std::fs::read_to_string(&json).expect("results.json");
    let mut results: Value = serde_json::from_str(&text).expect("results.json is JSON");
    results[0].take()
}

/// [`bench_seed`] for recording `seed` of the full-size benchmark (`small` false).
fn judge_seed(seed: u64, small: bool) {
    let result = bench_result(seed, small, &[]);
    let r = &result;
    let j = &r["judgement"];
    assert!(
        j.is_object(),
        "seed {seed}: the recording was not diagnosed: {}",
        r["error"]
    );
    let strings = |v: &Value| -> Vec<String> {
        v.as_array()
            .map(|a| a.iter().filter_map(|s| s.as_str().map(String::from)).collect())
            .unwrap_or_default()
    };
    let message = format!(
        "seed {seed} (`physfit bench diagnose --seed {seed} --count 1{}`): concealed [{}], found [{}]; {}",
        if small { " --small" } else { "" },
        strings(&r["concealed"]).join("; "),
        strings(&j["found"]).join(", "),
        j["verdict"]
    );
    let added = strings(&j["false_additions"]);
    assert!(added.is_empty(), "{message}: falsely added {added:?}");
    let effects = j["effects"].as_array().expect("effects");
    for e in effects {
        if e["detectability"] != "detectable" {
            continue;
        }
        let what = format!("{} ({:.1} noises)", e["concealed"]["effect"], e["ratio"]);
        assert!(e["found"].is_string(), "{message}: missed {what}");
        for x in e["errors"].as_array().expect("errors") {
            let value = x["value"].as_f64().expect("error value");
            let (limit, unit) = match (x["name"].as_str(), x["unit"].as_str()) {
                (Some("line"), _) => (WALL_LINE_PX, "px"),
                (Some("restitution"), _) => (RESTITUTION, ""),
                (Some("fixed point"), _) => {
                    let length = e["concealed"]["length"].as_f64().expect("tether length");
                    (FIXED_POINT_OF_LENGTH * length, "px")
                }
                _ => (RELATIVE, "(relative)"),
            };
            assert!(
                value <= limit,
                "{message}: {what}: {} off by {value:.4} {unit}, more than {limit:.4}",
                x["text"]
            );
        }
    }
    assert_eq!(j["exactly_right"], true, "{message}");
}

#[test]
fn bench_seed_01() {
    bench_seed(1);
}

#[test]
fn bench_seed_02() {
    bench_seed(2);
}

#[test]
fn bench_seed_03() {
    bench_seed(3);
}

#[test]
fn bench_seed_04() {
    bench_seed(4);
}

#[test]
#[ignore = "diagnosis issue 21: seed 5: tether without a field (3 particles, 130 frames): found, its fixed point 12.8 px off (4 % of its length; 2 % allowed)"]
fn bench_seed_05() {
    bench_seed(5);
}

#[test]
fn bench_seed_06() {
    bench_seed(6);
}

#[test]
fn bench_seed_07() {
    bench_seed(7);
}

#[test]
#[ignore = "diagnosis issue 21: seed 8: tether without a field, one particle, 21 frames: found alone, its fixed point 7.8 px off (6 % of its length; 2 % allowed)"]
fn bench_seed_08() {
    bench_seed(8);
}

// Its wall came out with restitution 0 while the held-out block took every frame after the
// bounce; the blocks are now chosen knowing the jolts.
#[test]
fn bench_seed_09() {
    bench_seed(9);
}

#[test]
fn bench_seed_10() {
    bench_seed(10);
}

#[test]
fn bench_seed_11() {
    bench_seed(11);
}

#[test]
fn bench_seed_12() {
    bench_seed(12);
}

// Full-size recordings of the N = 100 run that this changes fixed, one per class: a
// field of 0.08 px/s^2 added beside a wall (20); a stiff tether's anchor stopped 50 px short
// along its line, a field beside it (71); an anchor run off to 26 800 px where the truth is at
// 331 px (84).

#[test]
fn bench_full_seed_20() {
    judge_seed(20, false);
}

#[test]
fn bench_full_seed_71() {
    judge_seed(71, false);
}

#[test]
fn bench_full_seed_84() {
    judge_seed(84, false);
}

// A tether of p6 added beside the concealed dashpots, kept by 87 % of resamples of the frames
// (23: now undecided); a missing spring of length 0 +- 8000 px that, refitted on every frame,
// no longer paid for its parameters (53: now taken out).

#[test]
fn bench_full_seed_23() {
    judge_seed(23, false);
}

#[test]
fn bench_full_seed_53() {
    judge_seed(53, false);
}

/// Issue 21: recording 95 (two particles, one held by a stiff tether to a point 230 px off
/// screen, a soft spring between them, 213 frames). The weak form cannot tell the soft spring's
/// stiffness, and the base fit started at its scale stopped in a minimum at 0.73 px RMS; the
/// tether's tension shows only in stretches of the track noise, so the weak form proposed a
/// near, soft anchor. Now the base fit also starts a decade and two below, and a tether is
/// proposed from the circle its particle's path follows. Its stiffness came out 420 against
/// 3291, and its faint linear drag as quadratic drag (0.08 px RMS, 9.7 noises); now the
/// tether's stiffness is also started from its radial oscillation, heard at 3294.
#[test]
fn bench_full_seed_95() {
    judge_seed(95, false);
}

// Stiff tethers out of view whose stiffness only their ring tells (S 4326 and 5075): 63 had
// its tether at S 3978 with the anchor 70 px off (1.2 px RMS, 840 noises) and missed a soft
// spring; 50 had quadratic drag alone, twice its truth (0.80 px RMS). (64, 44 frames, now finds
// its tether from the ring in its residual, S 4976.9 against 4977.6, but its anchor is 7.0 px
// off, 2.01 % of the length, with standard errors of 4 and 6 px: not a test of 2 %.)

#[test]
fn bench_full_seed_50() {
    judge_seed(50, false);
}

#[test]
fn bench_full_seed_63() {
    judge_seed(63, false);
}

#[test]
fn the_time_table_counts_every_recording_once() {
    let dir = tempdir();
    let table = dir.path().join("table.md");
    physfit()
        .args(["-q", "bench", "diagnose", "--quick", "--count", "3", "--out"])
        .arg(&table)
        .assert()
        .success();
    let text = std::fs::read_to_string(&table).expect("table.md");
    let start = text.find("Diagnosis time by recording size").expect("time table");
    let rows: Vec<&str> = text[start..]
        .lines()
        .skip(4)
        .take_while(|l| l.starts_with('|'))
        .collect();
    assert_eq!(rows.len(), 3, "{}", &text[start..]);
    // Cells read `n: median / longest; under of n`.
    let counted: usize = rows
        .iter()
        .flat_map(|r| r.split('|').skip(2))
        .filter_map(|cell| cell.trim().split(':').next()?.parse::<usize>().ok())
        .sum();
    assert_eq!(counted, 3, "{}", &text[start..]);
}

/// Issue 21, "stable": small recordings 1, 2, 8, 9 and 11 (a field with a wall, dashpots, a
/// tether, a missing spring with a wall, a field) diagnosed with the search seeds 1 to 10 give
/// the same findings for every seed, and the report says so. Recording 1 (a bounce at frame
/// 19 of 28) lost its field with seeds 2 and 4 while their held-out block took every frame
/// after the bounce.
#[test]
fn ten_search_seeds_give_the_same_findings() {
    for seed in [1u64, 2, 8, 9, 11] {
        let result = bench_result(seed, true, &["--search-seeds", "10"]);
        let st = &result["stability"];
        assert_eq!(
            st["seeds"].as_array().map(Vec::len),
            Some(10),
            "seed {seed}: {st}"
        );
        assert!(
            st["findings"].as_array().is_some_and(|f| !f.is_empty()),
            "seed {seed}: nothing found: {st}"
        );
        assert_eq!(
            st["same_findings"], true,
            "seed {seed}: findings depend on the search seed: {st}"
        );
        for f in st["findings"].as_array().expect("findings") {
            assert_eq!(f["seeds"], 10, "seed {seed}: {f}");
        }
    }
}
