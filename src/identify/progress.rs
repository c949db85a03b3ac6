//! **Progress** of a long identification ([`Progress`]): the stage it is in and how many of the
//! cut-off scan's cut-offs (or a study's folds) are done, on an [`indicatif::ProgressBar`] the
//! caller owns (the CLI draws it on a terminal's stderr; hidden elsewhere). Reporting never
//! changes a result.

use indicatif::{ProgressBar, ProgressStyle};

/// Where an identification reports its progress (nowhere by default).
#[derive(Clone, Default)]
pub struct Progress(Option<ProgressBar>);

impl Progress {
    /// Reports to `bar`.
    pub fn to(bar: ProgressBar) -> Self {
        Progress(Some(bar))
    }

    /// A new stage of `len` steps (0: a stage without a count).
    pub(super) fn stage(&self, msg: &str, len: u64) {
        if let Some(b) = &self.0 {
            let template = if len == 0 {
                "{spinner} {msg} [{elapsed}]"
            } else {
                "{spinner} {msg} {pos}/{len} [{elapsed}]"
            };
            b.set_length(len);
            b.set_position(0);
            if let Ok(style) = ProgressStyle::with_template(template) {
                b.set_style(style);
            }
            b.set_message(msg.to_string());
        }
    }

    /// `n` more steps in the current stage.
    pub(super) fn more(&self, n: u64) {
        if let Some(b) = &self.0 {
            b.inc_length(n);
        }
    }

    /// One step of the stage done (safe from parallel workers).
    pub(super) fn step(&self) {
        if let Some(b) = &self.0 {
            b.inc(1);
        }
    }

    /// Steps done in the current stage.
    pub fn position(&self) -> u64 {
        self.0.as_ref().map_or(0, ProgressBar::position)
    }

    /// The same bar, for nested work that must not report (e.g. each fold of a study whose
    /// folds run in parallel and report as a whole).
    pub(super) fn silent() -> Self {
        Progress(None)
    }
}

impl std::fmt::Debug for Progress {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(if self.0.is_some() {
            "Progress(bar)"
        } else {
            "Progress(none)"
        })
    }
}

/// Observers are not options: two configurations that differ only in where they report are
/// the same identification.
impl PartialEq for Progress {
    fn eq(&self, _: &Self) -> bool {
        true
    }
}
