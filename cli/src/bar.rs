//! The terminal's progress bar: an [`indicatif`] bar behind the library's
//! [`Observer`](dynid::progress::Observer) (drawn on stderr when it is a terminal, hidden elsewhere).

use std::sync::Arc;

use indicatif::{ProgressBar, ProgressStyle};

use dynid::progress::{Observer, Progress};

/// A spinner-and-count bar for the stages of long work.
pub struct Bar(pub ProgressBar);

impl Bar {
    /// A bar that ticks while a stage runs, and the [`Progress`] that reports to it.
    pub fn start() -> (ProgressBar, Progress) {
        let bar = ProgressBar::new(0);
        bar.enable_steady_tick(std::time::Duration::from_millis(200));
        let progress = Progress::to(Arc::new(Bar(bar.clone())));
        (bar, progress)
    }
}

impl Observer for Bar {
    fn stage(&self, msg: &str, len: u64) {
        let template = if len == 0 {
            "{spinner} {msg} [{elapsed}]"
        } else {
            "{spinner} {msg} {pos}/{len} [{elapsed}]"
        };
        self.0.set_length(len);
        self.0.set_position(0);
        if let Ok(style) = ProgressStyle::with_template(template) {
            self.0.set_style(style);
        }
        self.0.set_message(msg.to_string());
    }

    fn grow(&self, n: u64) {
        self.0.inc_length(n);
    }

    fn advance(&self, n: u64) {
        self.0.inc(n);
    }
}

/// One bar per stage, each kept on screen when the next begins (the paper's GA, iterations, noise study).
pub struct Bars(std::sync::Mutex<Option<ProgressBar>>);

impl Bars {
    /// The [`Progress`] that draws a new bar at every stage.
    pub fn progress() -> Progress {
        Progress::to(Arc::new(Bars(std::sync::Mutex::new(None))))
    }

    fn with(&self, f: impl FnOnce(&ProgressBar)) {
        if let Ok(guard) = self.0.lock() {
            if let Some(bar) = guard.as_ref() {
                f(bar);
            }
        }
    }
}

impl Observer for Bars {
    fn stage(&self, msg: &str, len: u64) {
        let bar = ProgressBar::new(len);
        let style =
            ProgressStyle::with_template("{prefix:>16} [{bar:36}] {pos}/{len} {elapsed_precise}")
                .unwrap_or_else(|_| ProgressStyle::default_bar());
        bar.set_style(style.progress_chars("=> "));
        bar.set_prefix(msg.to_string());
        if let Ok(mut guard) = self.0.lock() {
            if let Some(done) = guard.replace(bar) {
                done.finish();
            }
        }
    }

    fn grow(&self, n: u64) {
        self.with(|b| b.inc_length(n));
    }

    fn advance(&self, n: u64) {
        self.with(|b| b.inc(n));
    }
}

impl Drop for Bars {
    fn drop(&mut self) {
        self.with(|b| b.finish());
    }
}
