//! `physfit diagnose TRACKS --structure S --out DIR [--window A..B] [--seed N]`: locate the
//! mismatch between the fitted model and the tracks, name the missing physics, refit.

use std::path::Path;

use anyhow::Context;
use physfit_identify::diagnose::{diagnose, DiagnoseOptions, Diagnosis};
use physfit_track::TrackTable;

use crate::cli::DiagnoseArgs;
use crate::progress::Verbosity;
use crate::report::{self, LineChart, Series};

/// Diagnoses a structure against tracks and writes `fitted.toml` and the reports into `--out`.
pub fn run(args: &DiagnoseArgs, verbosity: Verbosity) -> anyhow::Result<()> {
    let structure = super::load_scene(&args.structure)?;
    let tracks = TrackTable::read_csv(&args.tracks)
        .with_context(|| format!("reading tracks {}", args.tracks.display()))?;
    let options = DiagnoseOptions {
        seed: args.seed,
        window: args.window,
        ..DiagnoseOptions::default()
    };
    let d = diagnose(&structure, &tracks, &options, &()).with_context(|| {
        format!(
            "diagnosing {} against {}",
            args.structure.display(),
            args.tracks.display()
        )
    })?;
    let out = &args.out;
    std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
    for stale in ["report.json", "report.md", "report.html"] {
        let _ = std::fs::remove_file(out.join(stale));
    }
    d.final_scene
        .save(&out.join("fitted.toml"))
        .context("writing fitted.toml")?;
    let pictures = residual_charts(out, &d)?;
    let doc = report::ReportDocument {
        title: format!("physfit diagnosis: {}", d.structure),
        markdown: markdown(&d, &pictures),
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
    if verbosity != Verbosity::Quiet {
        print!("{}", summary(&d));
        println!(
            "diagnosed model -> {}; report -> {}",
            out.join("fitted.toml").display(),
            out.join("report.md").display()
        );
    }
    Ok(())
}

/// Residual magnitude per particle over time, before and after the diagnosis (one chart each,
/// on the same axes).
fn residual_charts(out: &Path, d: &Diagnosis) -> anyhow::Result<String> {
    let r = &d.residuals;
    let mut md = String::new();
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
        report::line_chart(&out.join(name), &chart)?;
        md.push_str(&report::markdown_image(title, name));
        md.push_str("\n\n");
    }
    Ok(md)
}

fn value_text(v: &physfit_identify::diagnose::FittedValue) -> String {
    match v.std_error {
        Some(e) => format!("{} = {:.6} ± {:.2e} {}", v.name, v.value, e, v.unit),
        None => format!("{} = {:.6} {}", v.name, v.value, v.unit),
    }
}

/// A plain-text account: each finding with its values, and the costs before and after.
fn summary(d: &Diagnosis) -> String {
    let mut s = String::new();
    if d.findings.is_empty() {
        s.push_str("no missing physics found: the structure explains the tracks to the noise level\n");
    }
    for f in &d.findings {
        let values: Vec<String> = f.parameters.iter().map(value_text).collect();
        s.push_str(&format!(
            "found {}: {}\n  seen: {}\n",
            f.label,
            values.join(", "),
            f.seen.text
        ));
    }
    s.push_str(&format!(
        "multi-step RMS over the sequence: base {:.4} px, diagnosed {:.4} px (track noise {:.4} px)\n",
        d.base.costs.multi_step.rms, d.final_model.costs.multi_step.rms, d.track_noise
    ));
    s
}

fn markdown(d: &Diagnosis, pictures: &str) -> String {
    let mut s = format!("# physfit diagnosis: {}\n\n", d.structure);
    s.push_str(&format!(
        "Frames {}..{} analysed; track noise {:.4} px; {:.1} s.\n\n## Findings\n\n",
        d.window[0], d.window[1], d.track_noise, d.seconds
    ));
    if d.findings.is_empty() {
        s.push_str("Nothing added: the structure explains the tracks to the noise level.\n\n");
    } else {
        let rows: Vec<Vec<String>> = d
            .findings
            .iter()
            .map(|f| {
                vec![
                    f.label.clone(),
                    f.parameters.iter().map(value_text).collect::<Vec<_>>().join("; "),
                    f.seen.text.clone(),
                    f.evidence
                        .held_out_cost_before
                        .map_or("-".into(), |v| format!("{v:.4}")),
                    f.evidence
                        .held_out_cost_after
                        .map_or("-".into(), |v| format!("{v:.4}")),
                    f.evidence.score.map_or("-".into(), |v| format!("{v:.1}")),
                ]
            })
            .collect();
        s.push_str(&report::markdown_table(
            &[
                "effect",
                "fitted values",
                "where it was seen",
                "held-out cost before, px²",
                "after, px²",
                "score",
            ],
            &rows,
        ));
        s.push('\n');
    }
    if !d.rejected.is_empty() {
        s.push_str("\n### Rejected candidates\n\n");
        let rows: Vec<Vec<String>> = d
            .rejected
            .iter()
            .map(|r| {
                vec![
                    r.label.clone(),
                    r.evidence.score.map_or("-".into(), |v| format!("{v:.1}")),
                ]
            })
            .collect();
        s.push_str(&report::markdown_table(&["candidate", "score"], &rows));
        s.push('\n');
    }
    s.push_str("\n## Where the base model disagreed\n\n");
    for line in &d.localisation.summary {
        s.push_str(&format!("- {line}\n"));
    }
    s.push_str("\n## Costs over the whole sequence\n\n");
    s.push_str(&report::markdown_table(
        &["model", "one-step, px²", "multi-step, px²", "multi-step RMS, px"],
        &[
            vec![
                "base".into(),
                format!("{:.4}", d.base.costs.one_step),
                format!("{:.4}", d.base.costs.multi_step.sum_squares),
                format!("{:.4}", d.base.costs.multi_step.rms),
            ],
            vec![
                "diagnosed".into(),
                format!("{:.4}", d.final_model.costs.one_step),
                format!("{:.4}", d.final_model.costs.multi_step.sum_squares),
                format!("{:.4}", d.final_model.costs.multi_step.rms),
            ],
        ],
    ));
    for w in &d.warnings {
        s.push_str(&format!("\n- warning: {w}"));
    }
    s.push_str("\n\n## Pictures\n\n");
    s.push_str(pictures);
    s
}
