//! `physfit bench`: speed measurements, and the diagnosis's accuracy on random recordings,
//! reported as Markdown tables (never timed assertions).

pub mod diagnose;
pub mod fit;
pub mod render;
pub mod sweep;
pub mod track;

use std::path::{Path, PathBuf};

use anyhow::Context;

use crate::cli::{BenchArgs, BenchTarget};
use crate::progress::Verbosity;

/// Runs the chosen benchmarks and prints (and optionally saves) their tables.
pub fn run(args: &BenchArgs, verbosity: Verbosity) -> anyhow::Result<()> {
    let diagnose_only = [
        ("--count", args.count.is_some()),
        ("--small", args.small),
        ("--minutes", args.minutes.is_some()),
        ("--json", args.json.is_some()),
    ];
    if let Some((flag, _)) = diagnose_only.iter().find(|(_, given)| *given) {
        anyhow::ensure!(
            args.what == BenchTarget::Diagnose,
            "{flag} applies to `physfit bench diagnose` only"
        );
    }
    if args.what == BenchTarget::Diagnose {
        return run_diagnose(args, verbosity);
    }
    if args.sweep {
        anyhow::ensure!(
            args.what == BenchTarget::Track,
            "--sweep applies to `physfit bench track` only"
        );
        let report = sweep::run(args.quick)?;
        return print_and_save(&report, args.out.as_deref());
    }
    let mut report = String::new();
    if matches!(args.what, BenchTarget::Render | BenchTarget::All) {
        report.push_str(&render::run(args.quick)?);
        report.push('\n');
    }
    if matches!(args.what, BenchTarget::Track | BenchTarget::All) {
        report.push_str(&track::run(args.quick)?);
        report.push('\n');
    }
    if matches!(args.what, BenchTarget::Fit | BenchTarget::All) {
        report.push_str(&fit::run(args.quick)?);
        report.push('\n');
    }
    if args.what == BenchTarget::Scaling {
        report.push_str(&fit::scaling(args.quick)?);
        report.push('\n');
    }
    print_and_save(&report, args.out.as_deref())
}

/// `physfit bench diagnose`: the tables to stdout and `--out`, the results to `--json`.
fn run_diagnose(args: &BenchArgs, verbosity: Verbosity) -> anyhow::Result<()> {
    anyhow::ensure!(!args.sweep, "--sweep applies to `physfit bench track` only");
    let count = args.count.unwrap_or(if args.quick {
        diagnose::QUICK_COUNT
    } else {
        diagnose::DEFAULT_COUNT
    });
    anyhow::ensure!(count >= 1, "--count {count}: at least one recording");
    if let Some(m) = args.minutes {
        anyhow::ensure!(
            m.is_finite() && m > 0.0,
            "--minutes {m}: a positive number of minutes"
        );
    }
    let options = diagnose::BenchOptions {
        first_seed: args.seed,
        count,
        small: args.small || args.quick,
        minutes: args.minutes,
        keep: args.keep.clone(),
        search_seeds: args.search_seeds as usize,
    };
    let (report, results) = diagnose::run(&options, verbosity)?;
    if let Some(path) = &args.json {
        let json = serde_json::to_string_pretty(&results).context("serialising the results")?;
        save(&json, path)?;
    }
    print_and_save(&report, args.out.as_deref())
}

/// Prints `report` and writes it to `out` when given.
fn print_and_save(report: &str, out: Option<&Path>) -> anyhow::Result<()> {
    print!("{report}");
    match out {
        Some(path) => save(report, path),
        None => Ok(()),
    }
}

/// Writes `text` to `path` atomically, naming the file in an error.
fn save(text: &str, path: &Path) -> anyhow::Result<()> {
    physfit_model::write_atomic(path, text.as_bytes()).with_context(|| format!("writing {}", path.display()))
}

/// A scratch folder under the system's temporary folder, named after the process and a
/// label, emptied when made and removed when dropped.
pub struct Scratch(pub PathBuf);

impl Scratch {
    /// Makes (or empties) the folder `physfit-bench-PID-LABEL`.
    pub fn new(label: &str) -> anyhow::Result<Scratch> {
        let dir = std::env::temp_dir().join(format!("physfit-bench-{}-{label}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).with_context(|| format!("creating {}", dir.display()))?;
        Ok(Scratch(dir))
    }
}

impl Drop for Scratch {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}
