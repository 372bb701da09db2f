//! `physfit bench diagnose`: the diagnosis on random recordings whose truth is known.
//!
//! Recording `i` of a run is drawn from seed `S + i` ([`draw`]), rendered to PNG frames by
//! physfit's renderer, tracked with its structure as `physfit run` tracks (named after the
//! structure's particles), and diagnosed with `physfit_identify::diagnose::diagnose` at the
//! CLI's defaults; the diagnosis is then judged against the truth ([`score`]) and the run
//! summarised as Markdown tables ([`table`]). The same seed gives the same recording and the
//! same result; `physfit bench diagnose --seed S --count 1` reproduces one.

pub mod draw;
pub mod score;
pub mod table;

use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::Context;
use physfit_identify::diagnose::{check_seeds, diagnose, DiagnoseOptions, Stability};
use physfit_track::{score_tracks, TrackOptions};
use physfit_tracks::TrackTable;
use serde::Serialize;

use super::Scratch;
use crate::cmd;
use crate::progress::Verbosity;
use draw::Regime;
use score::Judgement;

/// Recordings drawn by default.
pub const DEFAULT_COUNT: usize = 100;
/// Recordings drawn by default with `--quick` (small ones).
pub const QUICK_COUNT: usize = 12;

/// What to run.
#[derive(Clone, Debug, PartialEq)]
pub struct BenchOptions {
    /// Seed of the first recording; recording `i` uses `first_seed + i`.
    pub first_seed: u64,
    /// Recordings to draw.
    pub count: usize,
    /// At most 4 particles and 150 frames per recording.
    pub small: bool,
    /// Draw no new recording after this many minutes.
    pub minutes: Option<f64>,
    /// Keep each recording's scene, structure and tracks in `keep/seed-N`.
    pub keep: Option<PathBuf>,
    /// Seeds of the diagnosis's search run on each recording (1: the default seed only).
    pub search_seeds: usize,
}

/// Wall time of each stage of one recording, s.
#[derive(Clone, Debug, Default, Serialize)]
pub struct Times {
    /// Drawing and rendering the frames.
    pub render: f64,
    /// Tracking.
    pub track: f64,
    /// The diagnosis.
    pub diagnose: f64,
    /// Judging (the detectability simulations).
    pub judge: f64,
    /// The diagnoses with the other search seeds (0 without `--search-seeds`).
    pub other_seeds: f64,
}

/// One recording's result.
#[derive(Clone, Debug, Serialize)]
pub struct RecordingResult {
    /// Its seed.
    pub seed: u64,
    /// The concealed classes, e.g. `field + wall`.
    pub class: String,
    /// The number of concealed effects.
    pub effect_count: usize,
    /// What kind of recording it was (absent when it could not be drawn).
    pub regime: Option<Regime>,
    /// The concealed effects in words.
    pub concealed: Vec<String>,
    /// The tracks' RMS error per coordinate against the true centres, px.
    pub track_error: Option<f64>,
    /// The diagnosis judged (absent when a stage failed).
    pub judgement: Option<Judgement>,
    /// The findings of the other search seeds (with `--search-seeds`).
    pub stability: Option<Stability>,
    /// The stage that failed and why.
    pub error: Option<String>,
    /// Wall times.
    pub times: Times,
}

impl RecordingResult {
    /// Returns true if and only if the recording was diagnosed exactly right.
    pub fn exactly_right(&self) -> bool {
        self.judgement.as_ref().is_some_and(|j| j.exactly_right)
    }
}

/// Runs the benchmark: progress on stderr (unless quiet), the Markdown tables returned.
pub fn run(options: &BenchOptions, verbosity: Verbosity) -> anyhow::Result<(String, Vec<RecordingResult>)> {
    let started = Instant::now();
    let mut results = Vec::with_capacity(options.count);
    for i in 0..options.count {
        if let Some(m) = options.minutes {
            if started.elapsed().as_secs_f64() > 60.0 * m {
                if verbosity != Verbosity::Quiet {
                    eprintln!("bench diagnose: {m} minutes spent, stopping after {i} recordings");
                }
                break;
            }
        }
        let seed = options.first_seed.wrapping_add(i as u64);
        let result = run_one(seed, options);
        if verbosity != Verbosity::Quiet {
            eprintln!(
                "bench diagnose [{}/{}] {}",
                i + 1,
                options.count,
                table::progress_line(&result)
            );
        }
        results.push(result);
    }
    let elapsed = started.elapsed().as_secs_f64();
    Ok((table::markdown(options, &results, elapsed), results))
}

/// Draws, renders, tracks, diagnoses and judges recording `seed`; a failed stage (or a
/// panic in one) is recorded in the result, never raised.
pub fn run_one(seed: u64, options: &BenchOptions) -> RecordingResult {
    let mut result = RecordingResult {
        seed,
        class: String::new(),
        effect_count: 0,
        regime: None,
        concealed: Vec::new(),
        track_error: None,
        judgement: None,
        stability: None,
        error: None,
        times: Times::default(),
    };
    let outcome = catch_unwind(AssertUnwindSafe(|| pipeline(seed, options, &mut result)));
    let failure = match outcome {
        Ok(Ok(())) => None,
        Ok(Err(e)) => Some(format!("{e:#}")),
        Err(panic) => Some(format!(
            "panicked: {}",
            panic
                .downcast_ref::<String>()
                .map(String::as_str)
                .or_else(|| panic.downcast_ref::<&str>().copied())
                .unwrap_or("(no message)")
        )),
    };
    result.error = failure;
    result
}

/// The stages of [`run_one`], filling `result` as they go.
fn pipeline(seed: u64, bench: &BenchOptions, result: &mut RecordingResult) -> anyhow::Result<()> {
    let (small, keep) = (bench.small, bench.keep.as_deref());
    let t = Instant::now();
    let drawn = draw::draw(seed, small).context("drawing the recording")?;
    result.class = draw::class_label(&drawn.kinds());
    result.effect_count = drawn.concealed.len();
    result.concealed = drawn.concealed.iter().map(|c| c.describe()).collect();
    result.regime = Some(drawn.regime.clone());
    let dir = Scratch::new(&format!("diagnose-{seed}"))?;
    let rendered = cmd::render::render_scene(
        &drawn.truth,
        Path::new(&drawn.truth.name),
        &dir.0,
        Verbosity::Quiet,
    )
    .context("stage render")?;
    result.times.render = t.elapsed().as_secs_f64();

    let t = Instant::now();
    let options = TrackOptions {
        named_start: Some(cmd::named_start(&drawn.structure)),
        ..TrackOptions::default()
    };
    let tracked =
        physfit_track::track_folder(&rendered.frames_dir, &options, &|_, _| {}).context("stage track")?;
    let mut truth =
        TrackTable::read_csv(&dir.0.join("truth.csv")).context("stage track: reading truth.csv")?;
    truth
        .points
        .retain(|p| drawn.structure.particle_id(&p.particle).is_some());
    let score = score_tracks(&tracked.table, &truth, tracked.stats.match_radius());
    let track_error = ((score.rms_x.powi(2) + score.rms_y.powi(2)) / 2.0).sqrt();
    result.track_error = Some(track_error);
    result.times.track = t.elapsed().as_secs_f64();
    if let Some(keep) = keep {
        keep_recording(&keep.join(format!("seed-{seed}")), &drawn, &tracked.table, &dir.0)?;
    }

    let t = Instant::now();
    let mut diagnosis = diagnose(&drawn.structure, &tracked.table, &DiagnoseOptions::default(), &())
        .context("stage diagnose")?;
    result.times.diagnose = t.elapsed().as_secs_f64();
    if bench.search_seeds > 1 {
        let t = Instant::now();
        check_seeds(
            &drawn.structure,
            &tracked.table,
            &DiagnoseOptions::default(),
            bench.search_seeds,
            &mut diagnosis,
        )
        .context("stage diagnose: other search seeds")?;
        result.stability = diagnosis.stability.clone();
        result.times.other_seeds = t.elapsed().as_secs_f64();
    }

    let t = Instant::now();
    result.judgement = Some(score::judge(&drawn, &diagnosis, &truth, track_error));
    result.times.judge = t.elapsed().as_secs_f64();
    Ok(())
}

/// Writes the recording's truth scene, structure, tracks and true centres to `dir`.
fn keep_recording(
    dir: &Path,
    drawn: &draw::Drawn,
    tracks: &TrackTable,
    scratch: &Path,
) -> anyhow::Result<()> {
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    drawn.truth.save(&dir.join("scene.toml"))?;
    drawn.structure.save(&dir.join("structure.toml"))?;
    tracks.write_csv(&dir.join("tracks.csv"))?;
    let from = scratch.join("truth.csv");
    std::fs::copy(&from, dir.join("truth.csv"))
        .with_context(|| format!("copying {} to {}", from.display(), dir.display()))?;
    Ok(())
}
