//! `physfit track RECORDING --out tracks.csv [--structure S] [--window A..B|2.5s..4s] [--fps F]
//! [--truth T]`: RECORDING is a folder of frames, a video or a TIFF stack.

use anyhow::Context;
use physfit_track::TrackOptions;
use physfit_tracks::TrackTable;

use crate::cli::TrackArgs;
use crate::progress::{self, Verbosity};

/// Tracks a recording.
pub fn run(args: &TrackArgs, verbosity: Verbosity) -> anyhow::Result<()> {
    let recording = super::open_recording(&args.frames, args.window, args.fps, None)?;
    let named_start = match &args.structure {
        Some(path) => Some(super::named_start_in_view(
            &super::load_scene(path)?,
            &recording.source,
        )?),
        None => None,
    };
    let options = TrackOptions {
        window: recording.window,
        named_start,
        radius: args.radius,
        ..TrackOptions::default()
    };
    let bar = progress::bar(verbosity, "track", 0);
    let outcome = physfit_track::track_source(&recording.source, &options, &|done, total| {
        bar.set_length(total as u64);
        bar.set_position(done as u64);
    })
    .with_context(|| format!("tracking {}", args.frames.display()))?;
    bar.finish_and_clear();
    if verbosity != Verbosity::Quiet {
        for w in &outcome.warnings {
            eprintln!("physfit: warning: {w}");
        }
    }
    crate::output::clean_stale_temps(&args.out);
    outcome
        .table
        .write_csv(&args.out)
        .with_context(|| format!("writing {}", args.out.display()))?;
    if let Some(path) = &args.detections {
        physfit_track::write_detections_csv(&outcome.detections, path)
            .with_context(|| format!("writing {}", path.display()))?;
    }
    if verbosity != Verbosity::Quiet {
        println!("{}", outcome.stats);
        let amb = &outcome.stats.ambiguities;
        if !amb.is_empty() {
            let count = |k: physfit_track::AmbiguityKind| amb.iter().filter(|a| a.kind == k).count();
            let faint = count(physfit_track::AmbiguityKind::Faint);
            println!(
                "ambiguities bridged: {} runs ({} merged, {} missing, {} lost{})",
                amb.len(),
                count(physfit_track::AmbiguityKind::Merged),
                count(physfit_track::AmbiguityKind::Missing),
                count(physfit_track::AmbiguityKind::Lost),
                if faint > 0 {
                    format!(", {faint} found faint")
                } else {
                    String::new()
                }
            );
        }
        let s = &outcome.stats;
        if s.refitted_count > 0 {
            println!(
                "shared blobs: {} points placed again from the image, {} handed to another track by the motion",
                s.refitted_count, s.reordered_count
            );
        }
        println!("tracks -> {}", args.out.display());
    }
    if let Some(truth_path) = &args.truth {
        crate::limits::check_tracks_file(truth_path)?;
        let truth = TrackTable::read_csv(truth_path)
            .with_context(|| format!("reading truth {}", truth_path.display()))?;
        let score = physfit_track::score_tracks(&outcome.table, &truth, outcome.stats.match_radius());
        println!("{}", score.to_markdown());
    }
    Ok(())
}
