//! **Progress** of long work (an identification, a design, the paper run): the library reports
//! stages and steps to an [`Observer`] the caller implements (the CLI draws a terminal bar,
//! Python stays silent), so the library depends on no progress-bar crate. Reporting never
//! changes a result.

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;

/// What a caller implements to watch long work. Called from parallel workers, so `Sync`.
pub trait Observer: Send + Sync {
    /// A new stage named `msg` of `len` steps (0: a stage without a count).
    fn stage(&self, msg: &str, len: u64);
    /// The current stage has `n` more steps than announced.
    fn grow(&self, n: u64);
    /// `n` steps of the current stage done.
    fn advance(&self, n: u64);
}

/// Where long work reports its progress (nowhere by default). Cheap to clone; counts the
/// current stage's steps itself so that callers can read [`Progress::position`].
#[derive(Clone, Default)]
pub struct Progress {
    to: Option<Arc<dyn Observer>>,
    done: Arc<AtomicU64>,
}

impl Progress {
    /// Reports to `observer`.
    pub fn to(observer: Arc<dyn Observer>) -> Self {
        Progress {
            to: Some(observer),
            done: Arc::default(),
        }
    }

    /// Reports nowhere (nested work that must not report, e.g. each fold of a study whose
    /// folds run in parallel and report as a whole).
    pub fn silent() -> Self {
        Progress::default()
    }

    /// A new stage of `len` steps (0: a stage without a count).
    pub fn stage(&self, msg: &str, len: u64) {
        self.done.store(0, Ordering::Relaxed);
        if let Some(o) = &self.to {
            o.stage(msg, len);
        }
    }

    /// `n` more steps in the current stage.
    pub fn more(&self, n: u64) {
        if let Some(o) = &self.to {
            o.grow(n);
        }
    }

    /// One step of the stage done (safe from parallel workers).
    pub fn step(&self) {
        self.done.fetch_add(1, Ordering::Relaxed);
        if let Some(o) = &self.to {
            o.advance(1);
        }
    }

    /// Steps done in the current stage.
    pub fn position(&self) -> u64 {
        self.done.load(Ordering::Relaxed)
    }
}

impl std::fmt::Debug for Progress {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(if self.to.is_some() {
            "Progress(observer)"
        } else {
            "Progress(none)"
        })
    }
}

/// Observers are not options: two configurations that differ only in where they report are
/// the same work.
impl PartialEq for Progress {
    fn eq(&self, _: &Self) -> bool {
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::Mutex;

    #[derive(Default)]
    struct Log(Mutex<Vec<String>>);

    impl Observer for Log {
        fn stage(&self, msg: &str, len: u64) {
            self.0.lock().unwrap().push(format!("{msg}/{len}"));
        }
        fn grow(&self, n: u64) {
            self.0.lock().unwrap().push(format!("+{n}"));
        }
        fn advance(&self, n: u64) {
            self.0.lock().unwrap().push(format!(">{n}"));
        }
    }

    #[test]
    fn an_observer_sees_every_call_and_position_counts_the_stage() {
        let log = Arc::new(Log::default());
        let p = Progress::to(log.clone());
        p.stage("scan", 2);
        p.step();
        p.more(1);
        p.step();
        assert_eq!(p.position(), 2);
        p.stage("fit", 0);
        assert_eq!(p.position(), 0);
        assert_eq!(
            *log.0.lock().unwrap(),
            ["scan/2", ">1", "+1", ">1", "fit/0"]
        );
        Progress::silent().step();
    }
}
