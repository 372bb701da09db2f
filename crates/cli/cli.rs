//! Command-line syntax only (clap derive types); `config.rs`-style validation lives with each
//! command in `cmd/`.

use std::path::PathBuf;

use clap::{Args, Parser, Subcommand};
use physfit_track::FrameWindow;

/// physfit: from an image sequence of a moving deformable object to a physical model of it,
/// and to the physics the model left out.
#[derive(Debug, Parser)]
#[command(name = "physfit", version, about, long_about = None)]
pub struct Cli {
    /// Print nothing but errors.
    #[arg(short, long, global = true, conflicts_with = "verbose")]
    pub quiet: bool,
    /// Explain each stage as it runs.
    #[arg(short, long, global = true)]
    pub verbose: bool,
    /// Raise (or lower) a size limit, `NAME=VALUE`; repeatable. Limits: frame-megapixels (50),
    /// decompression-ratio (2000), frames-x-particles (2000000), scene-mb (10), tracks-mb (100);
    /// see docs/limits.md.
    #[arg(long = "limit", value_name = "NAME=VALUE", global = true)]
    pub limits: Vec<String>,
    /// The stage to run.
    #[command(subcommand)]
    pub command: Command,
}

/// One subcommand per pipeline stage, plus `run` for the whole pipeline and `bench`.
#[derive(Debug, Subcommand)]
pub enum Command {
    /// Simulate a scene and rasterize it to PNG frames, with truth.csv, structure.toml and scene.toml.
    Render(RenderArgs),
    /// Simulate a scene and write the true particle centres as CSV (no images).
    Simulate(SimulateArgs),
    /// Find particles in a recording (frames, video, TIFF stack) and link them into trajectories (tracks.csv).
    Track(TrackArgs),
    /// Identify every bond's parameters from trajectories and a structure.
    Fit(FitArgs),
    /// Locate where the fitted model and the tracks disagree, name the missing physics, refit.
    Diagnose(DiagnoseArgs),
    /// The whole pipeline: render (a scene) or read frames, track, fit, diagnose, report.
    Run(RunArgs),
    /// Measure speed (`render`, `track`, `fit`, `all`) or the diagnosis's accuracy (`diagnose`).
    Bench(BenchArgs),
}

/// `physfit render`.
#[derive(Debug, Args)]
pub struct RenderArgs {
    /// The scene file (TOML).
    pub scene: PathBuf,
    /// Output folder (created if needed): frames/, truth.csv, structure.toml, scene.toml.
    #[arg(long)]
    pub out: PathBuf,
    /// Override the scene's `[render] seed`.
    #[arg(long)]
    pub seed: Option<u64>,
}

/// `physfit simulate`.
#[derive(Debug, Args)]
pub struct SimulateArgs {
    /// The scene file (TOML).
    pub scene: PathBuf,
    /// Output CSV (`frame,particle,x,y`).
    #[arg(long)]
    pub out: PathBuf,
}

/// `physfit track`.
#[derive(Debug, Args)]
pub struct TrackArgs {
    /// The recording: a folder of frames (PNG 8/16-bit grey, RGB, RGBA, JPEG or TIFF, read in
    /// natural name order), a video (.mp4, .mov, .avi, .mkv; needs ffmpeg on the PATH) or a
    /// multi-page TIFF stack (.tif, .tiff).
    pub frames: PathBuf,
    /// Output CSV: frame,particle,x,y,mass,size,ep,flag.
    #[arg(long)]
    pub out: PathBuf,
    /// Name tracks after this structure's particles, matched to their positions in the first
    /// analysed frame, and follow only those.
    #[arg(long)]
    pub structure: Option<PathBuf>,
    /// First and last frame tracked, inclusive (`A..B`), or times (`2.5s..4s`).
    #[arg(long)]
    pub window: Option<FrameWindow>,
    /// Frame rate, frames/s, for a window in seconds (a video's own rate otherwise).
    #[arg(long)]
    pub fps: Option<f64>,
    /// Disc radius, px (estimated from the frames when absent).
    #[arg(long)]
    pub radius: Option<f64>,
    /// Score the tracks against true centres (`frame,particle,x,y`) and print the figures.
    #[arg(long)]
    pub truth: Option<PathBuf>,
    /// Also write every frame's detections before linking
    /// (`frame,x,y,mass,size,ep,area,clipped` CSV).
    #[arg(long)]
    pub detections: Option<PathBuf>,
}

/// `physfit fit`.
#[derive(Debug, Args)]
pub struct FitArgs {
    /// Trajectories: physfit's `frame,particle,x,y` CSV (`particle` = a structure id), or a
    /// trackpy, TrackMate or Tracker table (see `--format`).
    pub tracks: PathBuf,
    /// How to read the tracks table.
    #[command(flatten)]
    pub table: TableArgs,
    /// The image scale, m/px (overrides the structure's `[recording] metres_per_px` or ruler):
    /// reports then give SI values beside px, with masses taken as kg.
    #[arg(long, value_name = "M_PER_PX")]
    pub scale: Option<f64>,
    /// The structure: a scene whose unknown bond values are left out.
    #[arg(long)]
    pub structure: PathBuf,
    /// Output: the fitted model (the structure with every value filled in).
    #[arg(long)]
    pub out: PathBuf,
    /// Also write the fit report (JSON).
    #[arg(long)]
    pub report: Option<PathBuf>,
    /// Solver.
    #[arg(long, value_enum, default_value = "auto")]
    pub method: MethodArg,
    /// Seed of every random choice.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// First and last frame analysed, inclusive (`A..B`).
    #[arg(long, value_parser = parse_window)]
    pub window: Option<(usize, usize)>,
    /// Compare with the true scene: each parameter's relative error goes into the report.
    #[arg(long)]
    pub truth: Option<PathBuf>,
    /// Population of the genetic algorithms.
    #[arg(long)]
    pub population: Option<usize>,
    /// Generations (GA) or iterations (annealing), at most.
    #[arg(long)]
    pub generations: Option<usize>,
}

/// `physfit diagnose`.
#[derive(Debug, Args)]
pub struct DiagnoseArgs {
    /// Trajectories: physfit's `frame,particle,x,y` CSV (`particle` = a structure id), or a
    /// trackpy, TrackMate or Tracker table (see `--format`).
    pub tracks: PathBuf,
    /// How to read the tracks table.
    #[command(flatten)]
    pub table: TableArgs,
    /// The image scale, m/px (overrides the structure's `[recording] metres_per_px` or ruler):
    /// reports then give SI values beside px, with masses taken as kg.
    #[arg(long, value_name = "M_PER_PX")]
    pub scale: Option<f64>,
    /// The structure: a scene whose unknown bond values and physics are left out.
    #[arg(long)]
    pub structure: PathBuf,
    /// Output folder: fitted.toml, report.json, report.md, report.html and figures.
    #[arg(long)]
    pub out: PathBuf,
    /// First and last frame analysed, inclusive (`A..B`).
    #[arg(long, value_parser = parse_window)]
    pub window: Option<(usize, usize)>,
    /// Seed of every random choice (which frames are held out).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Also diagnose with the `N - 1` seeds after `--seed` and report how many found each
    /// finding (the report's `stability`); N times the time.
    #[arg(long, value_name = "N", default_value_t = 1, value_parser = clap::value_parser!(u64).range(1..=100))]
    pub seeds: u64,
}

/// How `fit` and `diagnose` read their tracks table (see `docs/tables.md`).
#[derive(Debug, Args)]
pub struct TableArgs {
    /// The tracks table's format (detected from its header when absent).
    #[arg(long, value_enum)]
    pub format: Option<FormatArg>,
    /// Pixels per unit of the table's positions (TrackMate's calibrated unit, Tracker's world
    /// unit), px/unit; otherwise derived from the unit and the scale.
    #[arg(long, value_name = "PX")]
    pub px_per_unit: Option<f64>,
    /// Where Tracker's world origin is in the image, px (`X,Y`, x right, y down).
    #[arg(long, value_name = "X,Y", value_parser = parse_point, default_value = "0,0")]
    pub origin: [f64; 2],
}

/// Track table formats.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum FormatArg {
    /// physfit's own `frame,particle,x,y[,mass,size,ep,flag]`.
    Physfit,
    /// trackpy's linked DataFrame written by `to_csv`.
    Trackpy,
    /// TrackMate's spot table CSV export.
    Trackmate,
    /// Tracker's (Open Source Physics) data export: `t, x, y` per mass.
    Tracker,
}

/// Parses a point `X,Y`, px.
pub fn parse_point(s: &str) -> Result<[f64; 2], String> {
    let (a, b) = s
        .split_once(',')
        .ok_or_else(|| format!("`{s}` is not of the form X,Y"))?;
    let num = |t: &str| -> Result<f64, String> {
        t.trim()
            .parse::<f64>()
            .ok()
            .filter(|v| v.is_finite())
            .ok_or_else(|| format!("`{s}`: `{t}` is not a finite number"))
    };
    Ok([num(a)?, num(b)?])
}

/// Identification methods.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum MethodArg {
    /// Linear least squares refined on the multi-step cost, with a global search fallback.
    Auto,
    /// Linear least squares on the equations of motion, refined by Levenberg-Marquardt.
    Lsq,
    /// The paper's simulated annealing.
    Anneal,
    /// The paper's genetic algorithm (global cost).
    Ga,
    /// The paper's genetic algorithm with per-particle local costs.
    GaLocal,
}

/// `physfit run`.
#[derive(Debug, Args)]
pub struct RunArgs {
    /// A scene file to render and analyse (the truth is then known and compared); the
    /// built-in default scene when neither a scene nor `--frames` is given.
    #[arg(conflicts_with = "frames")]
    pub scene: Option<PathBuf>,
    /// A recording: a folder of frames (PNG, JPEG or TIFF, natural name order), a video (.mp4,
    /// .mov, .avi, .mkv; needs ffmpeg on the PATH) or a TIFF stack: track, fit and diagnose it
    /// against `--structure`.
    #[arg(long, requires = "structure")]
    pub frames: Option<PathBuf>,
    /// The recorded object's structure (particles, masses, first positions, bonds without
    /// values); its particle positions are those of the first analysed frame. With a scene,
    /// what the analysis is told instead of the scene's own structure: a subset of the
    /// scene's particles (a pendulum's bob without its pivot, say).
    #[arg(long)]
    pub structure: Option<PathBuf>,
    /// Frame rate, frames/s (overrides a video's own rate and the structure's
    /// `[recording] fps`).
    #[arg(long, requires = "frames")]
    pub fps: Option<f64>,
    /// The image scale, m/px (overrides the structure's `[recording] metres_per_px` or ruler):
    /// reports then give SI values beside px, with masses taken as kg.
    #[arg(long, value_name = "M_PER_PX")]
    pub scale: Option<f64>,
    /// First and last frame analysed, inclusive (`A..B`), or times (`2.5s..4s`).
    #[arg(long)]
    pub window: Option<FrameWindow>,
    /// Seed of every random choice (rendering noise of a scene keeps the scene's own seed).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Output folder.
    #[arg(long, default_value = "physfit-out")]
    pub out: PathBuf,
}

/// `physfit bench`.
#[derive(Debug, Args)]
pub struct BenchArgs {
    /// What to measure.
    #[arg(value_enum, default_value = "all")]
    pub what: BenchTarget,
    /// Smaller inputs, for a quick look (seconds, not minutes).
    #[arg(long)]
    pub quick: bool,
    /// With `track`: instead of speed, the tracker's accuracy over a grid of particle radius
    /// (1.5-48 px), profile (disc, Gaussian, ring, textured, shaded sphere) and noise (0, 5,
    /// 20), drawn by physfit-synth.
    #[arg(long)]
    pub sweep: bool,
    /// Also write the tables to this Markdown file.
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// With `diagnose`: recordings to draw (default 100; 12 with `--quick`).
    #[arg(long)]
    pub count: Option<usize>,
    /// With `diagnose`: seed of the first recording; recording `i` uses `seed + i`, so
    /// `--seed S --count 1` reproduces recording S of any run.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// With `diagnose`: small recordings (at most 4 particles and 150 frames; the ones the
    /// tests run). `--quick` implies it.
    #[arg(long)]
    pub small: bool,
    /// With `diagnose`: draw no new recording after this many minutes (the table says how
    /// many ran).
    #[arg(long)]
    pub minutes: Option<f64>,
    /// With `diagnose`: also write every recording's result (truth, detectability, findings,
    /// errors, times) to this JSON file.
    #[arg(long)]
    pub json: Option<PathBuf>,
    /// With `diagnose`: keep each recording in `KEEP/seed-N` (`scene.toml`: the truth,
    /// `structure.toml`, `tracks.csv`, `truth.csv`), so that `physfit diagnose` can be run on
    /// it again.
    #[arg(long)]
    pub keep: Option<PathBuf>,
    /// With `diagnose`: also diagnose each recording with the search seeds 2..=N and count
    /// the recordings whose findings are the same for every seed (N times the time).
    #[arg(long, value_name = "N", default_value_t = 1, value_parser = clap::value_parser!(u64).range(1..=100))]
    pub search_seeds: u64,
}

/// Benchmark groups.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum BenchTarget {
    /// Rendering frames.
    Render,
    /// Tracking: decode, locate, link.
    Track,
    /// Identification: the paper's experiments and lsq scaling.
    Fit,
    /// Identification's scaling table alone (lsq and ga-local on lattices of 9 to 1024 particles).
    Scaling,
    /// The diagnosis on random recordings with known concealed effects: found, missed and
    /// falsely added rates and parameter errors (not part of `all`).
    Diagnose,
    /// Everything but `diagnose`.
    All,
}

/// Parses an inclusive frame window `A..B` (frame numbers only: times need a recording).
pub fn parse_window(s: &str) -> Result<(usize, usize), String> {
    match s.parse::<FrameWindow>()? {
        FrameWindow::Frames(a, b) => Ok((a, b)),
        FrameWindow::Seconds(..) => Err(format!("window `{s}`: give frame numbers A..B here, not times")),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::CommandFactory;

    #[test]
    fn verify_cli() {
        Cli::command().debug_assert();
    }

    #[test]
    fn windows_parse_and_reject() {
        assert_eq!(parse_window("2..12"), Ok((2, 12)));
        assert!(parse_window("12..2").unwrap_err().contains("before"));
        assert!(parse_window("a..2").unwrap_err().contains("`a`"));
        assert!(parse_window("3").unwrap_err().contains("A..B"));
    }

    #[test]
    fn points_parse_and_reject() {
        assert_eq!(parse_point("1.5, -2"), Ok([1.5, -2.0]));
        assert!(parse_point("1").unwrap_err().contains("X,Y"));
        assert!(parse_point("1,nan").unwrap_err().contains("finite"));
    }
}
