//! The run's pictures: the observed tracks with the base and diagnosed models' multi-step
//! predictions, the mismatch located on the image, residuals before and after, the base fit's
//! cost history, and overlay frames of the input.

use std::path::Path;

use anyhow::Context;
use physfit_identify::diagnose::Diagnosis;
use physfit_identify::FitResult;
use physfit_track::{Frame, FrameSource};
use physfit_tracks::TrackTable;

use crate::cmd::diagnose::figures::{self as diagnosis_figures, Backdrop};
use crate::report::{self, LineChart, Overlay, Prediction, Series, Tail};

/// Frames of track tail drawn on an overlay.
const TAIL_FRAMES: usize = 10;

/// Draws every picture into `out`; returns their Markdown and the files written (relative).
pub fn figures(
    out: &Path,
    frames: &FrameSource,
    tracks: &TrackTable,
    base: Option<&FitResult>,
    d: &Diagnosis,
) -> anyhow::Result<(String, Vec<String>)> {
    let picture = |k: usize| -> anyhow::Result<image::DynamicImage> {
        let frame = frames
            .load_frame(k)
            .with_context(|| format!("reading {}", frames.frame_name(k).display()))?;
        Ok(frame_picture(&frame))
    };
    let first = Some(picture(d.window[0])?);
    let ids = &d.residuals.particles;
    let by_particle = tracks.by_particle();
    let mut md = String::new();
    let mut files = Vec::new();

    let backdrop = Backdrop {
        frame: first.as_ref(),
        frame_size: None,
    };
    md.push_str(&diagnosis_figures::figures(out, d, tracks, &backdrop)?);
    files.extend(diagnosis_figures::FIGURE_FILES.map(String::from));

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
        if f >= frames.len() {
            continue;
        }
        let frame = picture(f)?;
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
            if let Some(x) = predicted_at(d, id, f) {
                marks.predictions.push(Prediction {
                    colour: k,
                    position: (x.x, x.y),
                });
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

/// A frame as an 8-bit picture (grey or RGB) to draw on.
fn frame_picture(frame: &Frame) -> image::DynamicImage {
    let bytes: Vec<u8> = frame
        .data
        .iter()
        .map(|&v| v.round().clamp(0.0, 255.0) as u8)
        .collect();
    let (w, h) = (frame.width as u32, frame.height as u32);
    let picture = if frame.channels == 1 {
        image::GrayImage::from_raw(w, h, bytes).map(image::DynamicImage::ImageLuma8)
    } else {
        image::RgbImage::from_raw(w, h, bytes).map(image::DynamicImage::ImageRgb8)
    };
    picture.expect("a frame's samples fill its size")
}

/// The diagnosed model's predicted position of particle `id` at frame `f`, px.
fn predicted_at(d: &Diagnosis, id: &str, f: usize) -> Option<physfit_model::Vec2> {
    let p = d.predictions.as_ref()?;
    let k = p.particles.iter().position(|q| q == id)?;
    let row = p.frames.iter().position(|&g| g == f)?;
    p.final_model.get(row)?.get(k).copied().flatten()
}
