//! The `physfit` binary: one subcommand per pipeline stage, chained by `physfit run`.

mod bench;
mod cli;
mod cmd;
mod limits;
mod output;
mod progress;
mod report;

use std::process::ExitCode;

use clap::Parser;

use crate::cli::{Cli, Command};
use crate::progress::Verbosity;

fn main() -> ExitCode {
    match run() {
        Ok(code) => code,
        Err(err) => {
            match limits::hint_for(&err) {
                Some(hint) => eprintln!("physfit: error: {err:#} ({hint})"),
                None => eprintln!("physfit: error: {err:#}"),
            }
            ExitCode::from(1)
        }
    }
}

fn run() -> anyhow::Result<ExitCode> {
    let cli = Cli::parse();
    limits::install(limits::Limits::from_settings(&cli.limits)?);
    let verbosity = if cli.quiet {
        Verbosity::Quiet
    } else if cli.verbose {
        Verbosity::Verbose
    } else {
        Verbosity::Normal
    };
    match cli.command {
        Command::Render(args) => cmd::render::run(&args, verbosity)?,
        Command::Simulate(args) => cmd::simulate::run(&args, verbosity)?,
        Command::Track(args) => cmd::track::run(&args, verbosity)?,
        Command::Fit(args) => cmd::fit::run(&args, verbosity)?,
        Command::Diagnose(args) => cmd::diagnose::run(&args, verbosity)?,
        Command::Run(args) => cmd::run::run(&args, verbosity)?,
        Command::Bench(args) => bench::run(&args, verbosity)?,
    }
    Ok(ExitCode::SUCCESS)
}
