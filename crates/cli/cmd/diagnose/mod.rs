//! `physfit diagnose TRACKS --structure S --out DIR [--window A..B] [--seed N] [--seeds N]`: locate the
//! mismatch between the fitted model and the tracks, name the missing physics, refit.

use anyhow::Context;
use physfit_identify::diagnose::{check_seeds, diagnose, DiagnoseOptions};

use crate::cli::DiagnoseArgs;
use crate::progress::Verbosity;
use crate::report;

pub mod figures;
pub mod sections;

/// Diagnoses a structure against tracks and writes `fitted.toml` and the reports into `--out`.
pub fn run(args: &DiagnoseArgs, verbosity: Verbosity) -> anyhow::Result<()> {
    let mut structure = super::load_scene(&args.structure)?;
    super::apply_scale(&mut structure, args.scale)?;
    // Refuse an unusable --out before the work; everything is staged and swapped in at the end.
    let staged = crate::output::Staged::begin(
        &args.out,
        "diagnose",
        &["fitted.toml", "report.json", "report.md", "report.html"],
    )?;
    let tracks = super::load_tracks(&args.tracks, &args.table, &structure, args.window, verbosity)?;
    let options = DiagnoseOptions {
        seed: args.seed,
        window: args.window,
        ..DiagnoseOptions::default()
    };
    let spinner = crate::progress::spinner(verbosity, "diagnose");
    let diagnosed = diagnose(&structure, &tracks, &options, &spinner).and_then(|mut d| {
        check_seeds(&structure, &tracks, &options, args.seeds as usize, &mut d)?;
        Ok(d)
    });
    spinner.finish();
    let d = diagnosed.with_context(|| {
        format!(
            "diagnosing {} against {}",
            args.structure.display(),
            args.tracks.display()
        )
    })?;
    let out = staged.dir();
    d.final_scene
        .save(&out.join("fitted.toml"))
        .context("writing fitted.toml")?;
    let backdrop = figures::Backdrop {
        frame: None,
        frame_size: None,
    };
    let pictures = figures::figures(out, &d, &tracks, &backdrop)?;
    let doc = report::ReportDocument {
        title: format!("physfit diagnosis: {}", d.structure),
        markdown: sections::markdown(&d, &pictures),
        json: serde_json::to_value(&d).context("serialising report.json")?,
        dir: out.to_path_buf(),
    };
    report::write_reports(
        &doc,
        &[
            &report::MarkdownExporter,
            &report::HtmlExporter,
            &report::JsonExporter,
        ],
    )?;
    staged.commit()?;
    let out = &args.out;
    if verbosity != Verbosity::Quiet {
        for w in &d.warnings {
            eprintln!("physfit: warning: {w}");
        }
        print!("{}", sections::summary(&d));
        println!(
            "diagnosed model -> {}; report -> {}",
            out.join("fitted.toml").display(),
            out.join("report.md").display()
        );
    }
    Ok(())
}
