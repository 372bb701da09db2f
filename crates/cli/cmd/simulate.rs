//! `physfit simulate SCENE --out truth.csv`.

use anyhow::Context;

use crate::cli::SimulateArgs;
use crate::progress::Verbosity;

/// Simulates the scene and writes the true centres.
pub fn run(args: &SimulateArgs, verbosity: Verbosity) -> anyhow::Result<()> {
    let scene = super::load_scene(&args.scene)?;
    let recording = super::simulate_scene(&scene, &args.scene)?;
    crate::output::clean_stale_temps(&args.out);
    super::truth_table(&scene, &recording)
        .write_csv(&args.out)
        .with_context(|| format!("writing {}", args.out.display()))?;
    if verbosity != Verbosity::Quiet {
        println!(
            "simulated {} particles over {} frames -> {}",
            scene.particles.len(),
            recording.frame_count(),
            args.out.display()
        );
    }
    Ok(())
}
