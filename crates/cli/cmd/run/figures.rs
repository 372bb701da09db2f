//! The run's pictures: the observed tracks with the base and diagnosed models' multi-step
//! predictions, the mismatch located on the image, residuals before and after, the base fit's
//! cost history, and overlay frames of the input.

use std::collections::BTreeMap;
use std::path::Path;

use anyhow::Context;
use physfit_identify::diagnose::Diagnosis;
use physfit_identify::FitResult;
use physfit_model::Scene;
use physfit_track::TrackTable;

use crate::cmd::diagnose::figures::{self as diagnosis_figures, Backdrop};
use crate::report::{self, LineChart, ModelPaths, Overlay, Prediction, Series, Tail, Track, TrajectoryPlot};

/// Frames of track tail drawn on an overlay.
const TAIL_FRAMES: usize = 10;

/// A model's predicted positions, px, per particle (in the diagnosis's particle order) and
/// absolute frame.
type Paths = Vec<BTreeMap<usize, (f64, f64)>>;

/// Draws every picture into `out`; returns their Markdown and the files written (relative).
pub fn figures(
    out: &Path,
    frames_dir: &Path,
    tracks: &TrackTable,
    base: Option<&FitResult>,
    d: &Diagnosis,
) -> anyhow::Result<(String, Vec<String>)> {
    let paths = physfit_track::list_frames(frames_dir)?;
    let first = paths
        .get(d.window[0])
        .or(paths.first())
        .map(|p| image::open(p).with_context(|| format!("reading {}", p.display())))
        .transpose()?;
    let ids = &d.residuals.particles;
    let base_paths = base.map(|b| predicted(&b.fitted, ids, d)).transpose()?;
    let final_paths = predicted(&d.final_scene, ids, d)?;
    let mut md = String::new();
    let mut files = Vec::new();

    let by_particle = tracks.by_particle();
    let in_window = |f: usize| f >= d.window[0] && f <= d.window[1];
    let track_lines: Vec<Track> = ids
        .iter()
        .map(|id| Track {
            name: id.clone(),
            points: by_particle
                .get(id.as_str())
                .map(|v| {
                    v.iter()
                        .filter(|q| in_window(q.frame))
                        .map(|q| (q.x, q.y))
                        .collect()
                })
                .unwrap_or_default(),
        })
        .collect();
    let model_lines = |name: &str, p: &Paths| ModelPaths {
        name: name.into(),
        paths: p.iter().map(|m| m.values().copied().collect()).collect(),
    };
    report::trajectory_plot(
        &out.join("trajectories.png"),
        &TrajectoryPlot {
            title: "observed tracks (solid), base model (dashed), diagnosed model (dotted)".into(),
            tracks: track_lines,
            models: base_paths
                .iter()
                .map(|p| model_lines("base model", p))
                .chain([model_lines("diagnosed model", &final_paths)])
                .collect(),
            background: first.as_ref().map(|f| f.to_rgb8()),
            zoom: true,
            ..TrajectoryPlot::new("")
        },
    )?;
    md.push_str(&report::markdown_image("trajectories", "trajectories.png"));
    md.push_str("\n\n");
    files.push("trajectories.png".to_string());

    let backdrop = Backdrop {
        frame: first.as_ref(),
        frame_size: None,
    };
    md.push_str(&diagnosis_figures::figures(out, d, tracks, &backdrop)?);
    files.extend(["mismatch.png", "residuals_before.png", "residuals_after.png"].map(String::from));

    let history: Vec<(f64, f64)> = base
        .map(|b| {
            b.report
                .history
                .iter()
                .enumerate()
                .map(|(i, &c)| (i as f64, c))
                .collect()
        })
        .unwrap_or_default();
    if let (Some(base), true) = (base, history.len() > 1) {
        let mut chart = LineChart::new("base fit: solver cost history", "iteration", "cost, px²");
        chart.log_y = true;
        chart.series = vec![Series::new(&base.report.method_used, history)];
        report::line_chart(&out.join("cost_history.png"), &chart)?;
        md.push_str(&report::markdown_image("cost history", "cost_history.png"));
        md.push_str("\n\n");
        files.push("cost_history.png".to_string());
    }

    // Overlay frames: first, middle and last analysed, with detections, track tails and the
    // diagnosed model's predicted positions.
    let overlay_dir = out.join("overlay");
    std::fs::create_dir_all(&overlay_dir).with_context(|| format!("creating {}", overlay_dir.display()))?;
    let (a, b) = (d.window[0], d.window[1]);
    let mut chosen = vec![a, (a + b) / 2, b];
    chosen.dedup();
    for f in chosen {
        let Some(path) = paths.get(f) else { continue };
        let frame = image::open(path).with_context(|| format!("reading {}", path.display()))?;
        let mut marks = Overlay::default();
        for (k, id) in ids.iter().enumerate() {
            let Some(obs) = by_particle.get(id.as_str()) else {
                continue;
            };
            if let Some(q) = obs.iter().find(|q| q.frame == f) {
                marks.detections.push((q.x, q.y));
            }
            marks.tails.push(Tail {
                colour: k,
                points: obs
                    .iter()
                    .filter(|q| q.frame <= f && q.frame + TAIL_FRAMES > f)
                    .map(|q| (q.x, q.y))
                    .collect(),
            });
            if let Some(&position) = final_paths.get(k).and_then(|m| m.get(&f)) {
                marks.predictions.push(Prediction { colour: k, position });
            }
        }
        let name = format!("overlay/frame_{f:06}.png");
        report::write_png(&out.join(&name), &report::overlay_frame(&frame, &marks))?;
        md.push_str(&report::markdown_image(&format!("overlay of frame {f}"), &name));
        md.push('\n');
        files.push(name);
    }
    Ok((md, files))
}

/// The positions `scene` predicts for each of `ids` over the diagnosis's analysed frames,
/// simulated from the scene's frame-0 state (the fitted motion's).
fn predicted(scene: &Scene, ids: &[String], d: &Diagnosis) -> anyhow::Result<Paths> {
    let model = scene
        .model()
        .with_context(|| format!("the model {} cannot be simulated", scene.name))?;
    let recording = physfit_model::simulate(
        &model,
        &scene.initial_state(),
        &scene.integration_parameters(),
        d.window[1] + 1,
    );
    Ok(ids
        .iter()
        .map(|id| {
            let mut m = BTreeMap::new();
            if let Some(p) = scene.particle_id(id) {
                for f in d.window[0]..=d.window[1] {
                    let x = recording.frame(f)[p.index()];
                    m.insert(f, (x.x, x.y));
                }
            }
            m
        })
        .collect())
}
