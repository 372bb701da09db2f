//! `physfit run`: the whole pipeline in one command.
//!
//! * `physfit run` (no arguments): the built-in default scene, which hides one effect;
//! * `physfit run SCENE --out DIR`: any scene; the truth is known, so the report compares;
//! * `physfit run SCENE --structure S --out DIR`: the scene rendered, then analysed knowing only
//!   the structure `S` (a subset of its particles, bonds without values, no physics): what the
//!   scene holds beyond `S` (a fixed pivot, a spring, a field) is then concealed;
//! * `physfit run --frames DIR|VIDEO|STACK --structure S --out DIR [--fps F] [--window A..B]`: a
//!   recording (a folder of frames, a video, a TIFF stack). A video's own frame rate is used
//!   unless `--fps` is given.
//!
//! Stages: render (scenes only), track, fit (the structure alone, by `lsq`), diagnose (name
//! and add the missing physics, refit), report. Each stage's failure names the stage and its
//! input. Everything is written into a staging folder beside `--out` and swapped in at the end
//! (`crate::output`), so a failed or killed run leaves the folder as it was (an earlier report
//! with its own `fitted.toml`), never a mix.

mod figures;
mod note;

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{bail, Context};
use physfit_identify::diagnose::{diagnose, DiagnoseOptions, Diagnosis};
use physfit_identify::{FitOptions, FitReport, FitResult};
use physfit_model::scene::{compare_scenes, SceneComparison};
use physfit_model::Scene;
use physfit_track::{TrackOptions, TrackScore};
use physfit_tracks::TrackTable;
use serde::Serialize;

use crate::cli::RunArgs;
use crate::progress::{self, Verbosity};

/// The built-in default scene.
pub const DEFAULT_SCENE: &str = include_str!("../../../../scenes/default.toml");

/// Name shown for the built-in default scene.
const DEFAULT_SCENE_NAME: &str = "<built-in default scene>";

/// What the run was given.
#[derive(Debug, Serialize)]
pub struct Given {
    /// `scene` (rendered here, truth known) or `recording` (frames from elsewhere).
    pub kind: &'static str,
    /// The scene file (scenes) or the structure file (recordings).
    pub source: String,
    /// The frames folder.
    pub frames: String,
    /// The structure's name.
    pub structure: String,
    /// Particles, springs and torsions of the structure.
    pub particles: usize,
    /// Springs listed in the structure.
    pub springs: usize,
    /// Torsions listed in the structure.
    pub torsions: usize,
    /// Unknown bond values.
    pub unknowns: usize,
    /// Frame rate used, frames/s.
    pub fps: f64,
    /// The image scale used, m/px (`--scale` or the structure's), when one was given.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub metres_per_px: Option<f64>,
    /// `--window`, when given.
    pub window: Option<[usize; 2]>,
    /// Seed of the random choices.
    pub seed: u64,
}

/// What tracking measured.
#[derive(Debug, Serialize)]
pub struct Tracking {
    /// Frames tracked `[first, last]`.
    pub frames: [usize; 2],
    /// Tracks written.
    pub tracks: usize,
    /// Points written.
    pub points: usize,
    /// Points bridged from the motion (`flag = interpolated`).
    pub interpolated: usize,
    /// Points split from merged blobs (`flag = split`).
    pub split: usize,
    /// Points of particles that shared a blob, placed again from the image after linking.
    pub refitted: usize,
    /// Points handed to another track of their crossing by the motion after linking.
    pub reordered: usize,
    /// Ambiguities bridged, in words.
    pub ambiguities: Vec<String>,
    /// Frames in which some structure particle has no point.
    pub frames_with_gaps: usize,
    /// Median estimated localisation error of detected points, px.
    pub median_position_error: f64,
    /// Pixel noise measured in the frames, grey levels.
    pub pixel_noise: f64,
    /// Particle radius used, px.
    pub radius: f64,
    /// True when the radius was estimated from the frames.
    pub radius_estimated: bool,
    /// `dark on light` or `bright on dark`.
    pub polarity: &'static str,
    /// Warnings of the tracker.
    pub warnings: Vec<String>,
    /// Against `truth.csv` (scenes only).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub score: Option<TrackScore>,
}

/// Wall time of each stage, s.
#[derive(Debug, Default, Serialize)]
pub struct StageTimes {
    /// Rendering (scenes only).
    pub render: f64,
    /// Tracking.
    pub track: f64,
    /// Base fit.
    pub fit: f64,
    /// Diagnosis.
    pub diagnose: f64,
    /// Pictures and reports.
    pub report: f64,
    /// The whole run.
    pub total: f64,
}

/// `report.json` of a run: the diagnosis's own keys (`findings`, `rejected`, `localisation`,
/// `base`, `final`, `residuals`... as `physfit diagnose` writes them) plus what the run was
/// given, the tracking, the base fit (`fit.json`'s content), the truth comparison and the times.
#[derive(Serialize)]
pub struct RunReport<'a> {
    /// What the run was given.
    pub given: &'a Given,
    /// What tracking measured.
    pub tracking: &'a Tracking,
    /// The base fit of the structure alone (the content of `physfit fit --report`); absent
    /// when the structure has no unknown bond values.
    pub fit: Option<&'a FitReport>,
    /// The diagnosis (flattened: its keys sit at the top level).
    #[serde(flatten)]
    pub diagnosis: &'a Diagnosis,
    /// The diagnosed model against the true scene (scenes only).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub truth: Option<&'a SceneComparison>,
    /// Output files, relative to the output folder.
    pub outputs: Vec<String>,
    /// Wall time per stage.
    pub times: &'a StageTimes,
}

/// Where the frames come from.
enum Input {
    /// A scene rendered here; its truth is known. `structure` is the file of what the
    /// analysis is told (`--structure`); without it, the scene's own structure.
    Scene {
        scene: Box<Scene>,
        source: PathBuf,
        structure: Option<PathBuf>,
    },
    /// A recording's frames and its structure.
    Recording { frames: PathBuf, structure: PathBuf },
}

impl Input {
    /// The input the arguments name (the built-in default scene when none), with `--fps`
    /// checked.
    fn from_args(args: &RunArgs) -> anyhow::Result<Input> {
        let input = match (&args.scene, &args.frames, &args.structure) {
            (_, Some(frames), Some(structure)) => Input::Recording {
                frames: frames.clone(),
                structure: structure.clone(),
            },
            (Some(path), None, structure) => Input::Scene {
                scene: Box::new(super::load_scene(path)?),
                source: path.clone(),
                structure: structure.clone(),
            },
            (None, None, structure) => Input::Scene {
                scene: Box::new(
                    Scene::from_toml_str(DEFAULT_SCENE, DEFAULT_SCENE_NAME)
                        .context("the built-in default scene")?,
                ),
                source: PathBuf::from(DEFAULT_SCENE_NAME),
                structure: structure.clone(),
            },
            (_, Some(_), None) => {
                bail!("--frames needs --structure (the recorded object's particles and bonds)")
            }
        };
        if let Some(fps) = args.fps {
            if !(fps.is_finite() && fps > 0.0) {
                bail!("--fps {fps}: the frame rate must be a positive number of frames per second");
            }
        }
        Ok(input)
    }

    /// The files a run of this input writes into the output folder.
    fn output_names(&self) -> Vec<&'static str> {
        let mut names = REPORT_FILES.to_vec();
        if matches!(self, Input::Scene { .. }) {
            names.extend(super::render::OUTPUTS);
        }
        names
    }
}

/// The structure file `path` read as what the analysis of `scene` (read from `source`) is
/// told: every particle it names must be one of the scene's, and the frame rate is the
/// scene's (the frames are rendered at it).
fn told_structure(scene: &Scene, source: &Path, path: &Path) -> anyhow::Result<Scene> {
    let mut told = super::load_scene(path).context("the structure")?;
    for particle in &told.particles {
        if !scene.particles.iter().any(|q| q.id == particle.id) {
            bail!(
                "{}: particle \"{}\" is not in the scene {} (its particles: {})",
                path.display(),
                particle.id,
                source.display(),
                scene
                    .particles
                    .iter()
                    .map(|q| q.id.as_str())
                    .collect::<Vec<_>>()
                    .join(", ")
            );
        }
    }
    told.recording.fps = scene.recording.fps;
    Ok(told)
}

/// The files every run writes, in the order `report.json` lists them.
const REPORT_FILES: [&str; 5] = [
    "tracks.csv",
    "fitted.toml",
    "report.json",
    "report.md",
    "report.html",
];

/// Output of the render stage: the frames and the structure to fit them with.
struct Rendered {
    /// The frames folder (rendered here) or the recording given.
    frames_dir: PathBuf,
    /// The structure, with the recording's frame rate and `--scale` applied.
    structure: Scene,
    /// The scene rendered (scenes only).
    truth: Option<Scene>,
    /// The scene file or the structure file.
    source: PathBuf,
    /// The recording opened, with its window.
    recording: super::OpenRecording,
}

/// Output of the track stage.
struct Tracked {
    /// The tracker's outcome (its table is `tracks.csv`).
    outcome: physfit_track::TrackOutcome,
    /// The figures the report shows.
    summary: Tracking,
}

/// Output of the diagnose stage.
struct Diagnosed {
    /// The diagnosis (its `final_scene` is `fitted.toml`).
    diagnosis: Diagnosis,
    /// The diagnosed model against the true scene (scenes only).
    truth: Option<SceneComparison>,
}

/// What the stages share: the arguments, the verbosity and the staging folder.
struct Stages<'a> {
    args: &'a RunArgs,
    verbosity: Verbosity,
    /// The staging folder everything is written into.
    dir: PathBuf,
}

/// Runs `stage`, adding its wall time to `seconds`.
fn timed<T>(seconds: &mut f64, stage: impl FnOnce() -> anyhow::Result<T>) -> anyhow::Result<T> {
    let t = Instant::now();
    let out = stage();
    *seconds += t.elapsed().as_secs_f64();
    out
}

/// Runs the pipeline: render -> track -> fit -> diagnose -> report, each stage a method of
/// [`Stages`] returning its typed output.
pub fn run(args: &RunArgs, verbosity: Verbosity) -> anyhow::Result<()> {
    let started = Instant::now();
    let input = Input::from_args(args)?;
    // Everything is written into a staging folder and swapped in at the end: a failed or
    // killed run leaves the folder as it was, an earlier report included.
    let staged = crate::output::Staged::begin(&args.out, "run", &input.output_names())?;
    let stages = Stages {
        args,
        verbosity,
        dir: staged.dir().to_path_buf(),
    };
    let mut times = StageTimes::default();
    let rendered = stages.render(input, &mut times.render)?;
    let tracked = timed(&mut times.track, || stages.track(&rendered))?;
    let base = timed(&mut times.fit, || stages.fit(&rendered, &tracked))?;
    let diagnosed = timed(&mut times.diagnose, || {
        stages.diagnose(&rendered, &tracked, base.as_ref())
    })?;
    stages.report(
        &rendered,
        &tracked,
        base.as_ref(),
        &diagnosed,
        &mut times,
        started,
    )?;
    staged.commit().context("stage report")?;
    stages.say(&format!(
        "report -> {} (also report.html, report.json) in {:.1} s",
        args.out.join("report.md").display(),
        started.elapsed().as_secs_f64()
    ));
    Ok(())
}

impl Stages<'_> {
    /// Prints a stage's one-line result (not with `-q`).
    fn say(&self, msg: &str) {
        if self.verbosity != Verbosity::Quiet {
            println!("{msg}");
        }
    }

    /// Prints what a stage is about to do (with `-v` only).
    fn explain(&self, msg: &str) {
        if self.verbosity == Verbosity::Verbose {
            println!("  {msg}");
        }
    }

    /// Stage render (scenes; its time is added to `seconds`) or read the structure
    /// (recordings), then open the frames with the frame rate (`--fps`, else a video's own,
    /// else the structure's or the scene's) and apply `--scale`.
    fn render(&self, input: Input, seconds: &mut f64) -> anyhow::Result<Rendered> {
        let (frames_dir, mut structure, truth, source) = match input {
            Input::Scene {
                scene,
                source,
                structure,
            } => {
                let told = match &structure {
                    Some(path) => told_structure(&scene, &source, path)?,
                    None => scene.structure(),
                };
                self.explain("render: simulate the scene with its hidden physics and draw every frame");
                let rendered = timed(seconds, || {
                    super::render::render_scene(&scene, &source, &self.dir, self.verbosity)
                        .context("stage render")
                })?;
                self.say(&format!(
                    "render: {} frames of {} -> {}",
                    rendered.frame_count,
                    scene.name,
                    self.args.out.join("frames").display()
                ));
                (rendered.frames_dir, told, Some(*scene), source)
            }
            Input::Recording { frames, structure } => {
                let s = super::load_scene(&structure).context("stage track: the structure")?;
                (frames, s, None, structure)
            }
        };
        let recording = super::open_recording(
            &frames_dir,
            self.args.window,
            self.args.fps,
            Some(structure.recording.fps),
        )
        .context("stage track")?;
        if let Some(fps) = recording.fps {
            structure.recording.fps = fps;
        }
        super::apply_scale(&mut structure, self.args.scale)?;
        Ok(Rendered {
            frames_dir,
            structure,
            truth,
            source,
            recording,
        })
    }

    /// Stage track: the structure's particles tracked through the frames into `tracks.csv`,
    /// scored against `truth.csv` for scenes.
    fn track(&self, r: &Rendered) -> anyhow::Result<Tracked> {
        self.explain("track: find the blobs in every frame, locate them to sub-pixel accuracy, link them into tracks named after the structure's particles");
        let source = &r.recording.source;
        let options = TrackOptions {
            window: r.recording.window,
            named_start: Some(super::named_start_in_view(&r.structure, source).context("stage track")?),
            ..TrackOptions::default()
        };
        let bar = progress::bar(self.verbosity, "track", 0);
        let outcome = physfit_track::track_source(source, &options, &|done, total| {
            bar.set_length(total as u64);
            bar.set_position(done as u64);
        })
        .with_context(|| format!("stage track: frames in {}", r.frames_dir.display()))?;
        bar.finish_and_clear();
        let tracks_path = self.args.out.join("tracks.csv");
        outcome
            .table
            .write_csv(&self.dir.join("tracks.csv"))
            .with_context(|| format!("stage track: writing {}", tracks_path.display()))?;
        let score = match &r.truth {
            Some(_) => {
                let truth_tracks = TrackTable::read_csv(&self.dir.join("truth.csv"))
                    .context("stage track: reading truth.csv")?;
                Some(physfit_track::score_tracks(
                    &outcome.table,
                    &truth_tracks,
                    outcome.stats.match_radius(),
                ))
            }
            None => None,
        };
        let summary = tracking_summary(&outcome, &r.structure, score);
        self.say(&note::tracking_line(&summary, &tracks_path));
        for w in &summary.warnings {
            if self.verbosity != Verbosity::Quiet {
                eprintln!("physfit: warning: {w}");
            }
        }
        Ok(Tracked { outcome, summary })
    }

    /// Stage fit: the structure alone by `lsq`, compared with the truth for scenes; `None`
    /// when the structure has no unknown bond values.
    fn fit(&self, r: &Rendered, tracked: &Tracked) -> anyhow::Result<Option<FitResult>> {
        if r.structure.unknown_count() == 0 {
            self.say("fit: the structure has no unknown bond values; the diagnosis fits the motion alone");
            return Ok(None);
        }
        self.explain("fit: the structure's bond values by linear least squares on the equations of motion, refined on the multi-step prediction");
        let fit_options = FitOptions {
            method: physfit_identify::Method::Lsq,
            seed: self.args.seed,
            window: r.recording.window,
            ..FitOptions::default()
        };
        let spinner = progress::spinner(self.verbosity, "fit");
        let fitted = physfit_identify::fit(&r.structure, &tracked.outcome.table, &fit_options, &spinner);
        spinner.finish();
        let mut base = fitted.context("stage fit: tracks.csv against the structure")?;
        if let Some(truth) = &r.truth {
            base.report.compare_truth(truth);
        }
        self.say(&format!(
            "fit: {} values of the structure alone, multi-step RMS {:.4} px (track noise {:.4} px)",
            base.report.parameters.len(),
            base.report.costs.multi_step_sequence.rms,
            base.report.track_noise
        ));
        Ok(Some(base))
    }

    /// Stage diagnose: the missing physics named, added and refitted, compared with the
    /// truth for scenes. The diagnosis fits the structure alone again on the frames it does
    /// not hold out, multi-step, starting also from the stage fit's bond values.
    fn diagnose(
        &self,
        r: &Rendered,
        tracked: &Tracked,
        base: Option<&FitResult>,
    ) -> anyhow::Result<Diagnosed> {
        self.explain("diagnose: locate where the fitted model and the tracks disagree, try each candidate effect on held-out frames, add those that earn their place, refit");
        let spinner = progress::spinner(self.verbosity, "diagnose");
        let options = DiagnoseOptions {
            seed: self.args.seed,
            window: r.recording.window,
            base: base.map(|b| b.fitted.clone()),
            ..DiagnoseOptions::default()
        };
        let diagnosed = diagnose(&r.structure, &tracked.outcome.table, &options, &spinner);
        spinner.finish();
        let diagnosis = diagnosed.context("stage diagnose: tracks.csv against the structure")?;
        if self.verbosity != Verbosity::Quiet {
            print!("diagnose: {}", super::diagnose::sections::summary(&diagnosis));
        }
        let truth = r
            .truth
            .as_ref()
            .map(|truth| compare_scenes(&diagnosis.final_scene, truth, &r.structure));
        if let Some(c) = &truth {
            self.say(&note::truth_line(c));
        }
        Ok(Diagnosed { diagnosis, truth })
    }

    /// Stage report: `fitted.toml`, the pictures and `report.md`, `report.html`,
    /// `report.json` in the staging folder; `times` gets the report's and the total time.
    fn report(
        &self,
        r: &Rendered,
        tracked: &Tracked,
        base: Option<&FitResult>,
        diagnosed: &Diagnosed,
        times: &mut StageTimes,
        started: Instant,
    ) -> anyhow::Result<()> {
        let t = Instant::now();
        let d = &diagnosed.diagnosis;
        d.final_scene
            .save(&self.dir.join("fitted.toml"))
            .context("stage report: writing fitted.toml")?;
        let given = self.given(r);
        let (pictures, mut outputs) =
            figures::figures(&self.dir, &r.recording.source, &tracked.outcome.table, base, d)
                .context("stage report: pictures")?;
        outputs.splice(0..0, REPORT_FILES.map(String::from));
        times.report = t.elapsed().as_secs_f64();
        times.total = started.elapsed().as_secs_f64();
        let report = RunReport {
            given: &given,
            tracking: &tracked.summary,
            fit: base.map(|b| &b.report),
            diagnosis: d,
            truth: diagnosed.truth.as_ref(),
            outputs,
            times,
        };
        write_reports(&self.dir, &report, &pictures).context("stage report")
    }

    /// What the run was given, for the report.
    fn given(&self, r: &Rendered) -> Given {
        let s = &r.structure;
        let frames = if r.truth.is_some() {
            self.args.out.join("frames")
        } else {
            r.frames_dir.clone()
        };
        Given {
            kind: if r.truth.is_some() { "scene" } else { "recording" },
            source: r.source.display().to_string(),
            frames: frames.display().to_string(),
            structure: s.name.clone(),
            particles: s.particles.len(),
            springs: s.springs.len(),
            torsions: s.torsions.len(),
            unknowns: s.unknown_count(),
            fps: s.recording.fps,
            metres_per_px: s.recording.metres_per_px,
            window: r.recording.window.map(|(a, b)| [a, b]),
            seed: self.args.seed,
        }
    }
}

/// The tracking figures of a run.
fn tracking_summary(
    tracked: &physfit_track::TrackOutcome,
    structure: &Scene,
    score: Option<TrackScore>,
) -> Tracking {
    let s = &tracked.stats;
    let mut per_frame = std::collections::BTreeMap::<usize, usize>::new();
    for p in &tracked.table.points {
        if structure.particle_id(&p.particle).is_some() {
            *per_frame.entry(p.frame).or_default() += 1;
        }
    }
    let frames_with_gaps = (s.frames.0..=s.frames.1)
        .filter(|f| per_frame.get(f).copied().unwrap_or(0) < structure.particles.len())
        .count();
    Tracking {
        frames: [s.frames.0, s.frames.1],
        tracks: s.track_count,
        points: s.point_count,
        interpolated: s.interpolated_count,
        split: s.split_count,
        refitted: s.refitted_count,
        reordered: s.reordered_count,
        ambiguities: s.ambiguities.iter().map(ToString::to_string).collect(),
        frames_with_gaps,
        median_position_error: s.median_ep,
        pixel_noise: s.noise_sigma,
        radius: s.radius,
        radius_estimated: s.radius_estimated,
        polarity: if s.dark_on_light {
            "dark on light"
        } else {
            "bright on dark"
        },
        warnings: tracked.warnings.clone(),
        score,
    }
}

/// Writes `report.md`, `report.html` and `report.json` (prepared together; the JSON last).
fn write_reports(out: &Path, report: &RunReport, pictures: &str) -> anyhow::Result<()> {
    use crate::report::{HtmlExporter, JsonExporter, MarkdownExporter, ReportDocument};
    let doc = ReportDocument {
        title: format!("physfit report: {}", report.given.structure),
        markdown: note::lab_note(report, pictures),
        json: serde_json::to_value(report).context("serialising report.json")?,
        dir: out.to_path_buf(),
    };
    crate::report::write_reports(&doc, &[&MarkdownExporter, &HtmlExporter, &JsonExporter])?;
    Ok(())
}
