//! `physfit render SCENE --out DIR`.

use std::path::{Path, PathBuf};

use anyhow::Context;
use physfit_model::Scene;

use crate::cli::RenderArgs;
use crate::progress::{self, Verbosity};

/// What a render wrote.
pub struct Rendered {
    /// Folder of PNG frames.
    pub frames_dir: PathBuf,
    /// Number of frames.
    pub frame_count: usize,
}

/// The outputs a render writes into its folder.
pub const OUTPUTS: [&str; 4] = ["frames", "truth.csv", "structure.toml", "scene.toml"];

/// Renders the scene file named in `args`.
pub fn run(args: &RenderArgs, verbosity: Verbosity) -> anyhow::Result<()> {
    let mut scene = super::load_scene(&args.scene)?;
    if let Some(seed) = args.seed {
        scene.render.seed = seed;
    }
    crate::limits::check_scene(&scene, &args.scene, true)?;
    let staged = crate::output::Staged::begin(&args.out, "render", &OUTPUTS)?;
    let out = render_scene(&scene, &args.scene, staged.dir(), verbosity)?;
    staged.commit()?;
    if verbosity != Verbosity::Quiet {
        println!(
            "rendered {} frames of {} ({}x{}) -> {}",
            out.frame_count,
            scene.name,
            scene.render.width,
            scene.render.height,
            args.out.display()
        );
    }
    Ok(())
}

/// Simulates and renders `scene` into the folder `out` ([`OUTPUTS`]: `frames/`, `truth.csv`,
/// `structure.toml` and `scene.toml`). `out` is a staging folder ([`crate::output::Staged`]),
/// moved into place by the caller once everything is written, so that a failed render never
/// leaves outputs that look complete.
pub fn render_scene(
    scene: &Scene,
    source: &Path,
    out: &Path,
    verbosity: Verbosity,
) -> anyhow::Result<Rendered> {
    crate::limits::check_scene(scene, source, true)?;
    let recording = super::simulate_scene(scene, source)?;
    let frames_dir = out.join("frames");
    std::fs::create_dir_all(&frames_dir).with_context(|| format!("creating {}", frames_dir.display()))?;
    let bar = progress::bar(verbosity, "render", recording.frame_count() as u64);
    physfit_render::render_sequence(&recording, &scene.render, &frames_dir, &|_| bar.inc(1))
        .context("rendering frames")?;
    bar.finish_and_clear();
    super::truth_table(scene, &recording)
        .write_csv(&out.join("truth.csv"))
        .context("writing truth.csv")?;
    scene
        .structure()
        .save(&out.join("structure.toml"))
        .context("writing structure.toml")?;
    scene
        .save(&out.join("scene.toml"))
        .context("writing scene.toml")?;
    Ok(Rendered {
        frames_dir,
        frame_count: recording.frame_count(),
    })
}
