//! Stage 7, **the outcome**: everything a report reads ([`Outcome`]): the files, the estimates,
//! the selection, the models' errors and the step table.

use serde::Serialize;

use super::evaluate::Errors;
use super::load_stage::LoadModel;
use super::predict::{Predictions, Series};
use super::prepare::{Prepared, Smoothing};
use super::regress::decimation;
use super::scan::CutoffTrial;
use super::select::Selection;
use crate::derivative::DerivativeReport;
use crate::effects::{Scales, Term};

/// One identified parameter.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Estimated {
    pub name: String,
    /// Grouped expression (base parameters) or effect description.
    pub expression: String,
    pub value: f64,
    /// Standard deviation (block jackknife).
    pub std: f64,
    /// `100 · std / |value|`.
    pub rel_std_percent: f64,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub unit: Option<String>,
}

/// A fitted model and its errors.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ModelResult {
    pub terms: Vec<String>,
    pub train: Errors,
    pub validation: Option<Errors>,
    /// Held-out error of leave-one-block-out refits on the (filtered) training data.
    pub heldout_rms: f64,
    #[serde(skip)]
    pub subset: Vec<usize>,
    #[serde(skip)]
    pub x: Vec<f64>,
}

/// Summary of one data file.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FileInfo {
    pub file: String,
    pub rows: usize,
    pub rows_used: usize,
    pub duration_s: f64,
    pub derivative: DerivativeReport,
    /// Every how many grid samples a filtered row enters the regression (see
    /// [`super::KEEP_RATE_PER_CUTOFF`]).
    pub regression_row_every: usize,
    /// The parallel (regression) filter, e.g. `zero-phase Butterworth, order 4, fc 2.93 Hz`.
    pub regression_filter: String,
    pub smoothing: Smoothing,
}

impl FileInfo {
    pub(super) fn of(p: &Prepared) -> Self {
        let n = p.log.len();
        FileInfo {
            file: p.name.clone(),
            rows: n,
            rows_used: p.raw_keep.1 - p.raw_keep.0,
            duration_s: p.log.t(n - 1) - p.log.t(0),
            derivative: p.est.report.clone(),
            regression_row_every: decimation(p),
            regression_filter: p.rfilter.as_zero_phase().describe(),
            smoothing: p.smoothing,
        }
    }
}

/// A row of the rigid → +effect → … table.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct StepRow {
    pub model: String,
    pub added: Option<String>,
    pub train: Errors,
    pub heldout_rms: f64,
    pub validation: Option<Errors>,
}

/// Everything [`super::run`] found.
#[derive(Debug, Clone, Serialize)]
pub struct Outcome {
    pub arm: String,
    pub dof: usize,
    pub base_source: String,
    pub train: Vec<FileInfo>,
    pub validate: Option<FileInfo>,
    pub effects_mode: String,
    pub theta: Vec<Estimated>,
    pub effects: Vec<(Term, Estimated)>,
    pub selection: Selection,
    /// Effects merged with rigid-body parameters for every motion (not identifiable).
    pub merged: Vec<(String, Vec<String>)>,
    pub before: ModelResult,
    pub after: ModelResult,
    pub steps: Vec<StepRow>,
    pub cond: f64,
    pub cond_scaled: f64,
    pub sigma: Vec<f64>,
    pub blocks: usize,
    pub scales: Vec<Scales>,
    /// Cut-offs tried by the automatic choice and their held-out errors (empty if fixed).
    pub cutoff_scan: Vec<CutoffTrial>,
    /// Load-dependent terms the scan was repeated with (found by the first pass).
    pub rescanned_with: Vec<String>,
    /// The final model's load-dependent terms and its torque without them (for a rescan).
    #[serde(skip)]
    pub load_model: Option<LoadModel>,
    #[serde(skip)]
    pub series: Series,
    #[serde(skip)]
    pub predictions: Option<Predictions>,
}
