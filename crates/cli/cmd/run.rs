//! `physfit run [SCENE] --out DIR`: the whole pipeline on a scene (default: built in).

use std::path::PathBuf;

use anyhow::Context;
use physfit_model::Scene;

use crate::cli::RunArgs;
use crate::progress::Verbosity;

/// The built-in default scene.
pub const DEFAULT_SCENE: &str = include_str!("../../../scenes/default.toml");

/// Runs the pipeline.
pub fn run(args: &RunArgs, verbosity: Verbosity) -> anyhow::Result<()> {
    let (scene, source) = match &args.scene {
        Some(path) => (super::load_scene(path)?, path.clone()),
        None => (
            Scene::from_toml_str(DEFAULT_SCENE, "<built-in default scene>").context("the built-in default scene")?,
            PathBuf::from("<built-in default scene>"),
        ),
    };
    let out = super::render::render_scene(&scene, &source, &args.out, verbosity)?;
    if verbosity != Verbosity::Quiet {
        println!(
            "rendered {} frames of scene {} -> {}",
            out.frame_count,
            scene.name,
            out.frames_dir.display()
        );
    }
    Ok(())
}
