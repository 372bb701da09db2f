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

/// A spinner for a stage whose length is unknown (a fit, a diagnosis), fed by the solver's
/// progress calls; hidden unless stderr is a terminal, like [`bar`].
pub struct Spinner {
    bar: ProgressBar,
    stage: &'static str,
}

/// A spinner labelled `stage`, ticking on its own until [`Spinner::finish`].
pub fn spinner(verbosity: Verbosity, stage: &'static str) -> Spinner {
    let bar = self::bar(verbosity, stage, 0);
    if let Ok(style) = ProgressStyle::with_template("{spinner} {msg} {elapsed_precise}") {
        bar.set_style(style);
    }
    if !bar.is_hidden() {
        bar.enable_steady_tick(std::time::Duration::from_millis(120));
    }
    Spinner { bar, stage }
}

impl Spinner {
    /// Clears the spinner from the terminal.
    pub fn finish(&self) {
        self.bar.finish_and_clear();
    }
}

impl physfit_identify::Observer for Spinner {
    fn observe(&self, iteration: usize, best_cost: f64) {
        self.bar.set_message(format!(
            "{}: step {iteration}, cost {best_cost:.4e} px²",
            self.stage
        ));
    }
}
