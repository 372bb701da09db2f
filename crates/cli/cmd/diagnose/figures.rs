//! The diagnosis's pictures: residuals over time before and after, and the image with the
//! mismatch located (shared by `physfit diagnose` and `physfit run`).

use std::path::Path;

use physfit_identify::diagnose::Diagnosis;
use physfit_tracks::TrackTable;

use crate::report::{self, LineChart, LineStyle, Mismatch, ModelPaths, Series, Track, TrajectoryPlot};

/// Jolts labelled on the mismatch picture, strongest first (the rest are circled unlabelled).
const LABELLED_JOLTS: usize = 6;

/// A frame of the recording to draw under the pictures, or the frame size alone.
pub struct Backdrop<'a> {
    /// A frame of the recording (the first analysed one).
    pub frame: Option<&'a image::DynamicImage>,
    /// The recording's frame size, px, when no frame is at hand.
    pub frame_size: Option<(u32, u32)>,
}

/// The pictures [`figures`] writes, relative to the output folder.
pub const FIGURE_FILES: [&str; 4] = [
    "trajectories.png",
    "mismatch.png",
    "residuals_before.png",
    "residuals_after.png",
];

/// Draws every diagnosis picture into `out` ([`FIGURE_FILES`]) and returns their Markdown.
pub fn figures(
    out: &Path,
    d: &Diagnosis,
    tracks: &TrackTable,
    backdrop: &Backdrop,
) -> anyhow::Result<String> {
    let mut md = prediction_picture(out, d, tracks, backdrop)?;
    md.push_str(&mismatch_picture(out, d, tracks, backdrop)?);
    md.push_str(&residual_charts(out, d)?);
    Ok(md)
}

/// The observed tracks of the analysed frames, one per structure particle.
fn observed_tracks(d: &Diagnosis, tracks: &TrackTable) -> Vec<Track> {
    let by_particle = tracks.by_particle();
    let in_window = |f: usize| f >= d.window[0] && f <= d.window[1];
    d.residuals
        .particles
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
        .collect()
}

/// The observed tracks with the base model's (dashed) and the diagnosed model's (dotted)
/// multi-step predictions over the analysed frames: `trajectories.png`.
pub fn prediction_picture(
    out: &Path,
    d: &Diagnosis,
    tracks: &TrackTable,
    backdrop: &Backdrop,
) -> anyhow::Result<String> {
    let ids = &d.residuals.particles;
    let mut models = Vec::new();
    if let Some(p) = &d.predictions {
        let in_window = |f: usize| f >= d.window[0] && f <= d.window[1];
        for (name, series) in [("base model", &p.base), ("diagnosed model", &p.final_model)] {
            let paths = ids
                .iter()
                .map(|id| {
                    let Some(k) = p.particles.iter().position(|q| q == id) else {
                        return Vec::new();
                    };
                    p.frames
                        .iter()
                        .zip(series)
                        .filter(|(&f, _)| in_window(f))
                        .map(|(_, row)| row[k].map_or((f64::NAN, f64::NAN), |x| (x.x, x.y)))
                        .collect()
                })
                .collect();
            models.push(ModelPaths {
                name: name.into(),
                paths,
            });
        }
    }
    let plot = TrajectoryPlot {
        tracks: observed_tracks(d, tracks),
        models,
        background: backdrop.frame.map(|f| f.to_rgb8()),
        frame_size: backdrop.frame_size,
        zoom: true,
        ..TrajectoryPlot::new("observed tracks (solid), base model (dashed), diagnosed model (dotted)")
    };
    report::trajectory_plot(&out.join("trajectories.png"), &plot)?;
    Ok(format!(
        "{}\n\n",
        report::markdown_image("observed and predicted trajectories", "trajectories.png")
    ))
}

/// Residual magnitude per particle over time, before and after the diagnosis (one chart each,
/// on the same axes).
pub fn residual_charts(out: &Path, d: &Diagnosis) -> anyhow::Result<String> {
    let r = &d.residuals;
    let mut md = String::new();
    let y_max = r
        .before
        .iter()
        .chain(&r.after)
        .flatten()
        .flatten()
        .map(|v| v[0].hypot(v[1]))
        .fold(0.0, f64::max);
    for (name, rows, title) in [
        (
            "residuals_before.png",
            &r.before,
            "base model: observed minus predicted position",
        ),
        (
            "residuals_after.png",
            &r.after,
            "diagnosed model: observed minus predicted position",
        ),
    ] {
        let mut chart = LineChart::new(title, "frame", "|residual|, px");
        if y_max > 0.0 {
            chart.y_range = Some((0.0, 1.05 * y_max));
        }
        chart.series = r
            .particles
            .iter()
            .enumerate()
            .map(|(p, id)| {
                let pts = r
                    .frames
                    .iter()
                    .zip(rows.iter())
                    .map(|(&f, row)| (f as f64, row[p].map_or(f64::NAN, |v| v[0].hypot(v[1]))))
                    .collect();
                Series::new(id, pts).with_colour(p)
            })
            .collect();
        // A residual's magnitude from track noise alone has RMS sqrt(2) sigma.
        if let (Some(&f0), Some(&f1)) = (r.frames.first(), r.frames.last()) {
            let level = std::f64::consts::SQRT_2 * d.track_noise;
            chart.series.push(
                Series::new("track noise (RMS)", vec![(f0 as f64, level), (f1 as f64, level)])
                    .with_style(LineStyle::Dashed),
            );
        }
        report::line_chart(&out.join(name), &chart)?;
        md.push_str(&report::markdown_image(title, name));
        md.push_str("\n\n");
    }
    Ok(md)
}

/// The observed tracks over the recording, with every place the base model disagreed
/// circled: significant particles' regions (with their pattern and direction), the jolts, and
/// each finding's region. Written as `mismatch.png`.
pub fn mismatch_picture(
    out: &Path,
    d: &Diagnosis,
    tracks: &TrackTable,
    backdrop: &Backdrop,
) -> anyhow::Result<String> {
    let ids = &d.residuals.particles;
    let tracks_drawn = observed_tracks(d, tracks);
    let mut mismatches = Vec::new();
    let circle = |region: &[f64; 4], label: String| Mismatch {
        position: (0.5 * (region[0] + region[2]), 0.5 * (region[1] + region[3])),
        radius: 0.5 * (region[2] - region[0]).hypot(region[3] - region[1]),
        label,
    };
    for p in d.localisation.particles.iter().filter(|p| p.significant) {
        if let Some(region) = &p.region {
            mismatches.push(circle(
                region,
                format!("{}: {}, {:.0}°", p.particle, p.pattern, p.direction_deg),
            ));
        }
    }
    let mut jolts: Vec<_> = d.localisation.jolts.iter().collect();
    jolts.sort_by(|a, b| b.significance.total_cmp(&a.significance));
    for (k, j) in jolts.iter().enumerate() {
        let id = ids.get(j.particle).map_or("?", String::as_str);
        mismatches.push(Mismatch {
            position: (j.position[0], j.position[1]),
            radius: 0.0,
            label: if k < LABELLED_JOLTS {
                format!("{id} jolt, frame {}", j.frame)
            } else {
                String::new()
            },
        });
    }
    for f in &d.findings {
        if let Some(region) = &f.seen.region {
            if f.effect != "wall" {
                mismatches.push(circle(region, f.label.clone()));
            }
        }
    }
    let title = if mismatches.is_empty() {
        "where the base model disagreed: nowhere beyond the track noise".to_string()
    } else {
        "where the base model disagreed with the tracks".to_string()
    };
    let plot = TrajectoryPlot {
        tracks: tracks_drawn,
        mismatches,
        background: backdrop.frame.map(|f| f.to_rgb8()),
        frame_size: backdrop.frame_size,
        zoom: true,
        ..TrajectoryPlot::new(title)
    };
    report::trajectory_plot(&out.join("mismatch.png"), &plot)?;
    Ok(format!(
        "{}\n\n",
        report::markdown_image("where the mismatch lives", "mismatch.png")
    ))
}
