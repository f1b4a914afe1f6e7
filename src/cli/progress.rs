//! Progress on the terminal for the `tagk` command and the examples: an indicatif bar or
//! spinner on stderr.
//!
//! A bar is drawn only when stderr is a terminal, and never when hidden (`--quiet`). It
//! writes nothing to stdout: piped output stays the same bytes. The library crates only
//! report progress (a callback, a [`SweepObserver`], a [`ProgressHook`]); the drawing is here.
//!
//! [`ProgressHook`]: tagk_diagnose::ProgressHook

use std::time::Duration;

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use tagk_sim::SweepObserver;

/// A progress bar over a count, or a spinner with a message, on stderr.
#[derive(Debug, Clone)]
pub struct Progress {
    bar: ProgressBar,
}

impl Progress {
    /// A bar over trials (its length set by the sweep), or a hidden one.
    pub fn new(visible: bool) -> Self {
        Self::counting(visible, 0, "trials")
    }

    /// A bar over `len` items called `unit` (e.g. `flights`), or a hidden one.
    pub fn counting(visible: bool, len: u64, unit: &str) -> Self {
        let bar = Self::on_stderr(visible, ProgressBar::new(len));
        if let Ok(style) = ProgressStyle::with_template(&format!(
            "{{elapsed_precise}} [{{wide_bar}}] {{pos}}/{{len}} {unit}, eta {{eta}} {{msg}}"
        )) {
            bar.set_style(style);
        }
        Self { bar }
    }

    /// A spinner with the elapsed time and `message`, for work of unknown length, or a
    /// hidden one.
    pub fn spinner(visible: bool, message: impl Into<String>) -> Self {
        let bar = Self::on_stderr(visible, ProgressBar::new_spinner());
        if let Ok(style) = ProgressStyle::with_template("{spinner} {elapsed_precise} {msg}") {
            bar.set_style(style);
        }
        bar.set_message(message.into());
        if !bar.is_hidden() {
            bar.enable_steady_tick(Duration::from_millis(200));
        }
        Self { bar }
    }

    /// `bar` drawing on stderr (only if it is a terminal), or hidden.
    fn on_stderr(visible: bool, bar: ProgressBar) -> ProgressBar {
        bar.set_draw_target(if visible {
            ProgressDrawTarget::stderr()
        } else {
            ProgressDrawTarget::hidden()
        });
        bar
    }

    /// Whether nothing is drawn (hidden, or stderr is not a terminal).
    pub fn is_hidden(&self) -> bool {
        self.bar.is_hidden()
    }

    /// One item done.
    pub fn inc(&self) {
        self.bar.inc(1);
    }

    /// `n` items done.
    pub fn inc_by(&self, n: u64) {
        self.bar.inc(n);
    }

    /// `done` items of `total` done.
    pub fn set(&self, done: u64, total: u64) {
        if self.bar.length() != Some(total) {
            self.bar.set_length(total);
        }
        self.bar.set_position(done);
    }

    /// Shows `message` beside the bar (what is being done).
    pub fn message(&self, message: impl Into<String>) {
        self.bar.set_message(message.into());
    }

    /// Runs `f` with the bar cleared (to print a line on the terminal), then redraws it.
    pub fn suspend<R>(&self, f: impl FnOnce() -> R) -> R {
        self.bar.suspend(f)
    }

    /// Clears the bar.
    pub fn finish(&self) {
        self.bar.finish_and_clear();
    }
}

impl SweepObserver for Progress {
    fn trial_finished(&self, _done: usize, total: usize) {
        if self.bar.length() != Some(total as u64) {
            self.bar.set_length(total as u64);
        }
        self.inc();
    }

    fn sweep_finished(&mut self) {
        self.finish();
    }
}
