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
    for stale in ["report.json", "report.md", "report.html"] {
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

    // In the pipeline a poor least-squares fit is evidence of physics the structure left out,
    // which a global search over bond values cannot supply: fit by `lsq` and let the report
    // (and the diagnosis) say how far the model is from the tracks.
    let options = FitOptions {
        method: physfit_identify::Method::Lsq,
        ..FitOptions::default()
    };
    let mut fitted = physfit_identify::fit(&structure, &tracked.table, &options, &())
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
    let pictures =
        figures(out, &rendered.frames_dir, &tracked.table, &fitted).context("stage report: figures")?;
    write_reports(out, &report, &pictures).context("stage report")?;
    say(format!("report -> {}", out.join("report.md").display()));
    Ok(())
}

/// Draws the run's pictures into `out` and returns their Markdown lines: the trajectories
/// observed and predicted by the fitted model, each particle's prediction error over time, the
/// solver's cost history, and overlay frames of the input.
fn figures(
    out: &Path,
    frames_dir: &Path,
    tracks: &TrackTable,
    fitted: &physfit_identify::FitResult,
) -> anyhow::Result<String> {
    use crate::report::{
        self, LineChart, ModelPaths, Overlay, Prediction, Series, Tail, Track, TrajectoryPlot,
    };
    let scene = &fitted.fitted;
    let model = scene.model().context("the fitted model")?;
    let frames = tracks.frame_end();
    let predicted = physfit_model::simulate(
        &model,
        &scene.initial_state(),
        &scene.integration_parameters(),
        frames,
    );
    let by_particle = tracks.by_particle();
    let mut md = String::new();

    // Trajectories over the first frame.
    let first_frame = physfit_track::list_frames(frames_dir)?
        .first()
        .map(|p| image::open(p).with_context(|| format!("reading {}", p.display())))
        .transpose()?;
    let mut track_lines = Vec::new();
    let mut model_paths = Vec::new();
    let mut residual_series = Vec::new();
    for (k, p) in scene.particles.iter().enumerate() {
        let obs: Vec<(usize, f64, f64)> = by_particle
            .get(p.id.as_str())
            .map(|v| v.iter().map(|q| (q.frame, q.x, q.y)).collect())
            .unwrap_or_default();
        track_lines.push(Track {
            name: p.id.clone(),
            points: obs.iter().map(|o| (o.1, o.2)).collect(),
        });
        model_paths.push(
            (0..frames)
                .map(|f| (predicted.frame(f)[k].x, predicted.frame(f)[k].y))
                .collect(),
        );
        residual_series.push(
            Series::new(
                &p.id,
                obs.iter()
                    .map(|&(f, x, y)| {
                        let q = predicted.frame(f)[k];
                        (f as f64, (q.x - x).hypot(q.y - y))
                    })
                    .collect(),
            )
            .with_colour(k),
        );
    }
    report::trajectory_plot(
        &out.join("trajectories.png"),
        &TrajectoryPlot {
            title: "observed tracks (solid) and the fitted model (dashed)".into(),
            tracks: track_lines,
            models: vec![ModelPaths {
                name: "fitted model".into(),
                paths: model_paths,
            }],
            mismatches: Vec::new(),
            background: first_frame.as_ref().map(|f| f.to_rgb8()),
            frame_size: first_frame.as_ref().map(|f| (f.width(), f.height())),
            width: 900,
        },
    )?;
    md.push_str(&report::markdown_image("trajectories", "trajectories.png"));
    md.push_str("\n\n");

    let mut chart = LineChart::new(
        "distance between the fitted model's motion and the tracks",
        "frame",
        "prediction error, px",
    );
    chart.series = residual_series;
    report::line_chart(&out.join("residuals.png"), &chart)?;
    md.push_str(&report::markdown_image("residuals", "residuals.png"));
    md.push_str("\n\n");

    let history: Vec<(f64, f64)> = fitted
        .report
        .history
        .iter()
        .enumerate()
        .map(|(i, &c)| (i as f64, c))
        .collect();
    if history.len() > 1 {
        let mut chart = LineChart::new("solver cost history", "iteration", "cost, px²");
        chart.log_y = true;
        chart.series = vec![Series::new(&fitted.report.method_used, history)];
        report::line_chart(&out.join("cost_history.png"), &chart)?;
        md.push_str(&report::markdown_image("cost history", "cost_history.png"));
        md.push_str("\n\n");
    }

    // Overlay frames: first, middle and last, with detections, 10-frame tails and predictions.
    let overlay_dir = out.join("overlay");
    std::fs::create_dir_all(&overlay_dir).with_context(|| format!("creating {}", overlay_dir.display()))?;
    let paths = physfit_track::list_frames(frames_dir)?;
    for &f in &[0, frames / 2, frames.saturating_sub(1)] {
        let Some(path) = paths.get(f) else { continue };
        let frame = image::open(path).with_context(|| format!("reading {}", path.display()))?;
        let mut marks = Overlay::default();
        for (k, p) in scene.particles.iter().enumerate() {
            let Some(obs) = by_particle.get(p.id.as_str()) else {
                continue;
            };
            if let Some(q) = obs.iter().find(|q| q.frame == f) {
                marks.detections.push((q.x, q.y));
            }
            marks.tails.push(Tail {
                colour: k,
                points: obs
                    .iter()
                    .filter(|q| q.frame <= f && q.frame + 10 > f)
                    .map(|q| (q.x, q.y))
                    .collect(),
            });
            let x = predicted.frame(f)[k];
            marks.predictions.push(Prediction {
                colour: k,
                position: (x.x, x.y),
            });
        }
        let name = format!("overlay/frame_{f:06}.png");
        report::write_png(&out.join(&name), &report::overlay_frame(&frame, &marks))?;
        md.push_str(&report::markdown_image(&format!("overlay of frame {f}"), &name));
        md.push('\n');
    }
    Ok(md)
}

/// Writes `report.md`, `report.html` and `report.json` (prepared together; the JSON last).
fn write_reports(out: &Path, report: &RunReport, pictures: &str) -> anyhow::Result<()> {
    use crate::report::{HtmlExporter, JsonExporter, MarkdownExporter, ReportDocument};
    let doc = ReportDocument {
        title: format!("physfit report: {}", report.scene),
        markdown: markdown(report, pictures),
        json: serde_json::to_value(report).context("serialising report.json")?,
        dir: out.to_path_buf(),
    };
    crate::report::write_reports(&doc, &[&MarkdownExporter, &HtmlExporter, &JsonExporter])?;
    Ok(())
}

fn markdown(r: &RunReport, pictures: &str) -> String {
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
    s.push_str("```\n\n");
    for w in &r.fit.warnings {
        s.push_str(&format!("- warning: {w}\n"));
    }
    s.push_str("\n## Pictures\n\n");
    s.push_str(pictures);
    s
}
