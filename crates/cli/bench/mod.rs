//! `physfit bench`: speed measurements, reported as Markdown tables (never timed assertions).

pub mod fit;
pub mod render;
pub mod sweep;
pub mod track;

use anyhow::Context;

use crate::cli::{BenchArgs, BenchTarget};
use crate::progress::Verbosity;

/// Runs the chosen benchmarks and prints (and optionally saves) their tables.
pub fn run(args: &BenchArgs, _verbosity: Verbosity) -> anyhow::Result<()> {
    if args.sweep {
        anyhow::ensure!(
            args.what == BenchTarget::Track,
            "--sweep applies to `physfit bench track` only"
        );
        let report = sweep::run(args.quick)?;
        print!("{report}");
        if let Some(path) = &args.out {
            physfit_model::write_atomic(path, report.as_bytes())
                .with_context(|| format!("writing {}", path.display()))?;
        }
        return Ok(());
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
    print!("{report}");
    if let Some(path) = &args.out {
        physfit_model::write_atomic(path, report.as_bytes())
            .with_context(|| format!("writing {}", path.display()))?;
    }
    Ok(())
}
