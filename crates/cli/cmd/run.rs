//! `physfit run [SCENE] --out DIR`: the whole pipeline on a scene (default: built in):
//! render, track, fit, report. With a scene the truth is known, so the report compares.

use std::path::{Path, PathBuf};

use anyhow::Context;
use physfit_identify::FitOptions;
use physfit_model::Scene;
use physfit_track::{TrackOptions, TrackTable};
use serde::Serialize;

use crate::cli::RunArgs;
use crate::progress::{self, Verbosity};

/// The built-in default scene.
pub const DEFAULT_SCENE: &str = include_str!("../../../scenes/default.toml");

/// What `report.json` holds for a pipeline run.
#[derive(Serialize)]
struct RunReport<'a> {
    /// The scene analysed.
    scene: &'a str,
    /// Tracking figures against the truth.
    tracking: TrackingSummary,
    /// The fit (the `fit.json` content).
    fit: &'a physfit_identify::FitReport,
}

#[derive(Serialize)]
struct TrackingSummary {
    frames: usize,
    particles: usize,
    points: usize,
    interpolated: usize,
    warnings: Vec<String>,
    score: physfit_track::TrackScore,
}

/// Runs the pipeline.
pub fn run(args: &RunArgs, verbosity: Verbosity) -> anyhow::Result<()> {
    let (scene, source) = match &args.scene {
        Some(path) => (super::load_scene(path)?, path.clone()),
        None => (
            Scene::from_toml_str(DEFAULT_SCENE, "<built-in default scene>")
                .context("the built-in default scene")?,
            PathBuf::from("<built-in default scene>"),
        ),
    };
    let out = &args.out;
    let say = |msg: String| {
        if verbosity != Verbosity::Quiet {
            println!("{msg}");
        }
    };
    // A report left from an earlier run must not look like this run's.
    for stale in ["report.json", "report.md"] {
        let _ = std::fs::remove_file(out.join(stale));
    }

    let rendered = super::render::render_scene(&scene, &source, out, verbosity).context("stage render")?;
    say(format!(
        "render: {} frames of {} -> {}",
        rendered.frame_count,
        scene.name,
        rendered.frames_dir.display()
    ));

    let structure = scene.structure();
    let options = TrackOptions {
        named_start: Some(
            structure
                .particles
                .iter()
                .map(|p| (p.id.clone(), [p.position.x, p.position.y]))
                .collect(),
        ),
        ..TrackOptions::default()
    };
    let bar = progress::bar(verbosity, "track", rendered.frame_count as u64);
    let tracked = physfit_track::track_folder(&rendered.frames_dir, &options, &|done, _| {
        bar.set_position(done as u64)
    })
    .with_context(|| format!("stage track: frames in {}", rendered.frames_dir.display()))?;
    bar.finish_and_clear();
    let tracks_path = out.join("tracks.csv");
    tracked
        .table
        .write_csv(&tracks_path)
        .with_context(|| format!("stage track: writing {}", tracks_path.display()))?;
    let truth = TrackTable::read_csv(&out.join("truth.csv")).context("stage track: reading truth.csv")?;
    let score = physfit_track::score_tracks(&tracked.table, &truth, scene.render.radius);
    say(format!(
        "track: {} points, RMS error {:.4} px (x) {:.4} px (y), {} identity switches -> {}",
        tracked.table.points.len(),
        score.rms_x,
        score.rms_y,
        score.id_switches,
        tracks_path.display()
    ));

    let mut fitted = physfit_identify::fit(&structure, &tracked.table, &FitOptions::default(), &())
        .context("stage fit: tracks.csv against the scene's structure")?;
    fitted.report.compare_truth(&scene);
    fitted
        .fitted
        .save(&out.join("fitted.toml"))
        .context("stage fit: writing fitted.toml")?;
    say(super::fit::summary(&fitted.report));

    let report = RunReport {
        scene: &scene.name,
        tracking: TrackingSummary {
            frames: rendered.frame_count,
            particles: scene.particles.len(),
            points: tracked.table.points.len(),
            interpolated: tracked
                .table
                .points
                .iter()
                .filter(|p| p.flag == physfit_track::PointFlag::Interpolated)
                .count(),
            warnings: tracked.warnings.clone(),
            score,
        },
        fit: &fitted.report,
    };
    write_reports(out, &report)?;
    say(format!("report -> {}", out.join("report.md").display()));
    Ok(())
}

/// Writes `report.md` then `report.json` (last: its presence marks a complete run).
fn write_reports(out: &Path, report: &RunReport) -> anyhow::Result<()> {
    let md = markdown(report);
    physfit_model::write_atomic(&out.join("report.md"), md.as_bytes()).context("writing report.md")?;
    let json = serde_json::to_string_pretty(report).context("serialising report.json")?;
    physfit_model::write_atomic(&out.join("report.json"), json.as_bytes()).context("writing report.json")?;
    Ok(())
}

fn markdown(r: &RunReport) -> String {
    let t = &r.tracking;
    let mut s = format!("# physfit report: {}\n\n## Tracking\n\n", r.scene);
    s.push_str(&format!(
        "{} particles over {} frames: {} points ({} bridged by prediction).\n\n{}\n",
        t.particles,
        t.frames,
        t.points,
        t.interpolated,
        t.score.to_markdown()
    ));
    for w in &t.warnings {
        s.push_str(&format!("- warning: {w}\n"));
    }
    s.push_str("\n## Fit\n\n```text\n");
    s.push_str(&super::fit::summary(r.fit));
    s.push_str("```\n");
    for w in &r.fit.warnings {
        s.push_str(&format!("- warning: {w}\n"));
    }
    s
}
