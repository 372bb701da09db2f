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

/// Renders the scene file named in `args`.
pub fn run(args: &RenderArgs, verbosity: Verbosity) -> anyhow::Result<()> {
    let mut scene = super::load_scene(&args.scene)?;
    if let Some(seed) = args.seed {
        scene.render.seed = seed;
    }
    let out = render_scene(&scene, &args.scene, &args.out, verbosity)?;
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

/// Simulates and renders `scene` into `out`: `frames/`, `truth.csv`, `structure.toml` and
/// `scene.toml`. Everything is written into a staging folder first and moved into place at
/// the end, so a failed render never leaves outputs that look complete.
pub fn render_scene(
    scene: &Scene,
    source: &Path,
    out: &Path,
    verbosity: Verbosity,
) -> anyhow::Result<Rendered> {
    crate::limits::check_scene(scene, source, true)?;
    let recording = super::simulate_scene(scene, source)?;
    std::fs::create_dir_all(out).with_context(|| format!("creating output folder {}", out.display()))?;
    let staging = out.join(format!(".physfit-render-{}", std::process::id()));
    let result = (|| -> anyhow::Result<()> {
        let frames = staging.join("frames");
        std::fs::create_dir_all(&frames).with_context(|| format!("creating {}", frames.display()))?;
        let bar = progress::bar(verbosity, "render", recording.frame_count() as u64);
        physfit_render::render_sequence(&recording, &scene.render, &frames, &|_| bar.inc(1))
            .context("rendering frames")?;
        bar.finish_and_clear();
        super::truth_table(scene, &recording)
            .write_csv(&staging.join("truth.csv"))
            .context("writing truth.csv")?;
        scene
            .structure()
            .save(&staging.join("structure.toml"))
            .context("writing structure.toml")?;
        scene
            .save(&staging.join("scene.toml"))
            .context("writing scene.toml")?;
        Ok(())
    })();
    if let Err(e) = result {
        let _ = std::fs::remove_dir_all(&staging);
        return Err(e);
    }
    let frames_dir = out.join("frames");
    if frames_dir.exists() {
        std::fs::remove_dir_all(&frames_dir)
            .with_context(|| format!("replacing {}", frames_dir.display()))?;
    }
    for name in ["frames", "truth.csv", "structure.toml", "scene.toml"] {
        std::fs::rename(staging.join(name), out.join(name))
            .with_context(|| format!("moving {name} into {}", out.display()))?;
    }
    let _ = std::fs::remove_dir_all(&staging);
    Ok(Rendered {
        frames_dir,
        frame_count: recording.frame_count(),
    })
}
