//! Progress reporting: bars on a terminal, silence in pipes, CI and with `-q`.

use std::io::IsTerminal;

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};

/// How chatty the binary is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Verbosity {
    /// Errors only.
    Quiet,
    /// Results and progress bars.
    Normal,
    /// Also explain each stage.
    Verbose,
}

/// A progress bar for `total` steps of `stage`, hidden unless stderr is a terminal.
pub fn bar(verbosity: Verbosity, stage: &str, total: u64) -> ProgressBar {
    let visible =
        verbosity != Verbosity::Quiet && std::io::stderr().is_terminal() && std::env::var_os("CI").is_none();
    let bar = ProgressBar::with_draw_target(
        Some(total),
        if visible {
            ProgressDrawTarget::stderr()
        } else {
            ProgressDrawTarget::hidden()
        },
    );
    if let Ok(style) = ProgressStyle::with_template("{msg:>10} [{bar:30}] {pos}/{len} {elapsed_precise}") {
        bar.set_style(style.progress_chars("=> "));
    }
    bar.set_message(stage.to_string());
    bar
}
