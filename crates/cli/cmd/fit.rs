//! `physfit fit TRACKS --structure S --out FITTED.toml [--report fit.json] ...`.

use anyhow::Context;
use physfit_identify::{FitOptions, Method};

use crate::cli::{FitArgs, MethodArg};
use crate::progress::{self, Verbosity};

/// The identification method chosen on the command line.
pub fn method(arg: MethodArg) -> Method {
    match arg {
        MethodArg::Auto => Method::Auto,
        MethodArg::Lsq => Method::Lsq,
        MethodArg::Anneal => Method::Anneal,
        MethodArg::Ga => Method::Ga,
        MethodArg::GaLocal => Method::GaLocal,
    }
}

/// A progress bar as a solver observer.
struct BarObserver(indicatif::ProgressBar);

impl physfit_identify::Observer for BarObserver {
    fn observe(&self, iteration: usize, best_cost: f64) {
        self.0.set_position(iteration as u64);
        self.0.set_message(format!("cost {best_cost:.4e}"));
    }
}

/// Fits a structure to tracks.
pub fn run(args: &FitArgs, verbosity: Verbosity) -> anyhow::Result<()> {
    let mut structure = super::load_scene(&args.structure)?;
    super::apply_scale(&mut structure, args.scale)?;
    let tracks = super::load_tracks(&args.tracks, &args.table, &structure, args.window, verbosity)?;
    let mut options = FitOptions {
        method: method(args.method),
        seed: args.seed,
        window: args.window,
        ..FitOptions::default()
    };
    if let Some(p) = args.population {
        options.population = p;
    }
    if let Some(g) = args.generations {
        options.generations = g;
    }
    let truth = match &args.truth {
        Some(p) => Some(super::load_scene(p)?),
        None => None,
    };
    let bar = progress::bar(verbosity, "fit", options.generations as u64);
    let mut result = physfit_identify::fit(&structure, &tracks, &options, &BarObserver(bar.clone()))
        .with_context(|| {
            format!(
                "fitting {} to {}",
                args.structure.display(),
                args.tracks.display()
            )
        })?;
    bar.finish_and_clear();
    if let Some(truth) = &truth {
        result.report.compare_truth(truth);
    }
    if verbosity != Verbosity::Quiet {
        for w in &result.report.warnings {
            eprintln!("physfit: warning: {w}");
        }
    }
    crate::output::clean_stale_temps(&args.out);
    result
        .fitted
        .save(&args.out)
        .with_context(|| format!("writing {}", args.out.display()))?;
    if let Some(path) = &args.report {
        let json = serde_json::to_string_pretty(&result.report).context("serialising the fit report")?;
        physfit_model::write_atomic(path, json.as_bytes())
            .with_context(|| format!("writing {}", path.display()))?;
    }
    if verbosity != Verbosity::Quiet {
        print!("{}", summary(&result.report));
        println!("fitted model -> {}", args.out.display());
    }
    Ok(())
}

/// A short plain-text account of a fit: each value with its standard error, and the costs.
pub fn summary(report: &physfit_identify::FitReport) -> String {
    use physfit_identify::BondKeys;
    let mut out = format!(
        "{} fitted by {} on frames {}..{} in {:.3} s ({} cost evaluations)\n",
        report.structure,
        report.method_used,
        report.window[0],
        report.window[1],
        report.seconds,
        report.cost_count
    );
    for p in &report.parameters {
        let bond = match &p.bond {
            BondKeys::Spring { between } => format!("spring {}-{}", between[0], between[1]),
            BondKeys::Torsion { at, between } => format!("torsion {}-{}-{}", between[0], at, between[1]),
        };
        let mut line = format!("  {bond:<24} {:<9} = {}", p.name, p.text());
        if let (Some(a), Some(e)) = (p.rest_angle_deg, p.rest_angle_std_error_deg) {
            line.push_str(&format!(
                "  ({} deg)",
                physfit_identify::units::format_value_se(a, Some(e))
            ));
        }
        if let Some(r) = p.relative_error {
            line.push_str(&format!("  [error {:+.3}%]", 100.0 * r));
        }
        if !p.identifiable {
            line.push_str("  (not determined by this recording)");
        }
        out.push_str(&line);
        out.push('\n');
    }
    out.push_str(&format!(
        "  multi-step RMS over the whole sequence: {:.4} px; measured track noise {:.4} px\n",
        report.costs.multi_step_sequence.rms, report.track_noise
    ));
    if let Some(u) = &report.units {
        out.push_str(&format!("  units: {}\n", u.text));
    }
    out
}
