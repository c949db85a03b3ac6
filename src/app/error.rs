//! What the application layer says when a request cannot run, and how each front end spells an
//! option in those messages (`--torque-scale` on the command line, `torque_scale` in Python), so
//! that one validator serves both with the same text.

use crate::arms::ArmError;
use crate::bag::BagError;
use crate::data::DataError;
use crate::dh::DhError;
use crate::io::WriteError;
use crate::params::ParamsError;

/// The front end a request comes from: decides only how options are named in messages.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Front {
    /// The `dynid` command line: `--cutoff`, `` `--physical off` ``.
    Cli,
    /// The Python bindings: `cutoff`, `physical=False`.
    Python,
}

impl Front {
    /// Option `name` (Python's spelling, `torque_scale`) as this front end spells it.
    pub fn name(self, name: &str) -> String {
        match self {
            Front::Cli => format!("--{}", name.replace('_', "-")),
            Front::Python => name.to_string(),
        }
    }

    /// Option `name` set to a value: `` `--physical off` `` on the command line, `physical=False`
    /// (`python`, the value as Python writes it) in Python.
    pub fn setting(self, name: &str, cli: &str, python: &str) -> String {
        match self {
            Front::Cli => format!("`{} {cli}`", self.name(name)),
            Front::Python => format!("{name}={python}"),
        }
    }
}

/// Why a request failed. Every variant but [`AppError::Failed`] is the input's fault (the CLI's
/// exit code 2); the library's own errors pass through unchanged, source chain included.
#[derive(Debug, thiserror::Error)]
pub enum AppError {
    /// An option, or a combination of options, that cannot work; the message names the option.
    #[error("{0}")]
    Input(String),
    #[error(transparent)]
    Data(#[from] DataError),
    #[error(transparent)]
    Bag(#[from] BagError),
    #[error(transparent)]
    Arm(#[from] ArmError),
    #[error(transparent)]
    Dh(#[from] DhError),
    #[error(transparent)]
    Params(#[from] ParamsError),
    #[error(transparent)]
    Write(#[from] WriteError),
    /// A step that failed on its own account (`what`: "writing the report"); whether the input
    /// is to blame is up to `source` (the CLI walks the chain).
    #[error("{what}")]
    Step {
        what: String,
        #[source]
        source: Box<dyn std::error::Error + Send + Sync>,
    },
    /// Not the input's fault (a numerical failure): the CLI's exit code 1.
    #[error("{0}")]
    Failed(String),
}

impl AppError {
    /// True when the input (files, options) is to blame, not dynid; for a
    /// [`AppError::Step`] its source says.
    pub fn is_bad_input(&self) -> bool {
        !matches!(self, AppError::Failed(_) | AppError::Step { .. })
    }

    /// `what` failed because of `source`.
    pub fn step(
        what: impl Into<String>,
        source: impl std::error::Error + Send + Sync + 'static,
    ) -> Self {
        AppError::Step {
            what: what.into(),
            source: Box::new(source),
        }
    }

    /// The whole message on one line (what the Python bindings raise): a step's own words and
    /// its source's, as the CLI prints them.
    pub fn message(&self) -> String {
        match self {
            AppError::Step { what, source } => format!("{what}: {source}"),
            other => other.to_string(),
        }
    }
}
