//! Stage 7, **the outcome**: everything a report reads ([`Outcome`]): the files, the estimates,
//! the selection, the models' errors and the step table.

use serde::Serialize;

use super::base::BaseModel;
use super::columns::Merged;
use super::evaluate::{
    raw_sums_sampled, Errors, Judged, ModelResult, Prediction, RawSums, Sampling, StateErrors,
};
use super::identifiability::Undetermined;
use super::jackknife;
use super::layout::Layout;
use super::load_stage::{load_model, LoadModel};
use super::ls;
use super::physical::{self, Physical};
use super::predict::{series_strides, PredictionSink, Predictions, Series, TrainSamples};
use super::prepare::{Prepared, Smoothing};
use super::problem::{with_hint, Problem};
use super::regress::decimation;
use super::residual_map::ResidualMaps;
use super::scan::{CutoffTrial, ScanSampling};
use super::select::{Selected, Selection};
use super::{Config, IdentifyError};
use crate::derivative::DerivativeReport;
use crate::effects::{EffectsSpec, Scales, Term};

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
    /// The training runs a per-run term's [`Term::run`] indexes ([`super::Layout::runs`]).
    pub runs: Vec<String>,
    /// Per joint, the share of training samples at rest ([`super::Layout::at_rest`]).
    pub at_rest: Vec<f64>,
    /// Cut-offs tried by the automatic choice and their held-out errors (empty if fixed).
    pub cutoff_scan: Vec<CutoffTrial>,
    /// How the scan sampled a long training set (`None`: scanned whole, or not scanned).
    #[serde(skip)]
    pub scan_sampling: Option<ScanSampling>,
    /// Load-dependent terms the scan was repeated with (found by the first pass).
    pub rescanned_with: Vec<String>,
    /// The final model's load-dependent terms and its torque without them (for a rescan).
    #[serde(skip)]
    pub load_model: Option<LoadModel>,
    #[serde(skip)]
    pub series: Series,
    /// The final model's training residual binned per joint against q, q̇, q̈, time, run and τ̂
    /// ([`super::residual_map`]), from the same samples and prediction as `series`.
    pub residual_maps: ResidualMaps,
    #[serde(skip)]
    pub predictions: Option<Predictions>,
    /// Stage 8: the physically consistent estimate (none when switched off or failed).
    pub physical: Option<Physical>,
    /// Why stage 8 failed (the least-squares result stands).
    pub physical_error: Option<String>,
    /// The consistent estimate judged like `after` (its held-out error is not computed: NaN).
    pub consistent: Option<ModelResult>,
    /// What the training data cannot determine ([`super::identifiability`]).
    pub warnings: Vec<String>,
    /// Base parameters held at zero: the training data cannot determine them at all.
    pub fixed: Vec<String>,
    /// Parameters whose one-σ uncertainty moves the prediction by more than the residual
    /// ([`super::identifiability::torque_sigma`]).
    pub undetermined: Vec<Undetermined>,
    /// The plain fit (rigid + viscous, Coulomb, offset, armature on every joint) judged like
    /// `after`, when the guard ran.
    pub plain: Option<ModelResult>,
    /// The per-joint guard against the plain fit, and the weak joints (`--effects auto`).
    pub guard: Option<super::guard::Guard>,
    /// The Coulomb width scan (`None`: the model has no Coulomb column, or load-dependent ones).
    pub coulomb_width: Option<super::coulomb_width::WidthScan>,
    /// The ripple wavenumber scan per joint scanned (empty when none was).
    pub ripple: Vec<super::ripple::RippleScan>,
}

/// Stage 7: the outcome of an identification whose effects are selected (`selected`, the
/// effects structurally merged with the base in `merged`): the reported models fitted and
/// judged against the measured torque, the final model's estimates, plots and predictions.
pub(super) fn assemble(
    arm: &str,
    base: &BaseModel,
    train: &[Prepared],
    val: Option<&Prepared>,
    cfg: &Config,
    selected: Selected,
    merged: &Merged,
) -> Result<Outcome, IdentifyError> {
    let Selected {
        problem,
        selection,
        declared,
    } = selected;
    let layout = &problem.layout;
    let models = Models::fit(&problem, train, &declared, &selection)?;
    let last = &models.fitted[1];
    let (physical, physical_error) = if cfg.physical.enabled {
        match physical::consistent(
            &problem,
            &base.base_map(),
            &last.fit,
            &last.w,
            &cfg.physical,
        ) {
            Ok(p) => (Some(p), None),
            Err(e) => (None, Some(e)),
        }
    } else {
        (None, None)
    };
    let consistent_x = physical
        .as_ref()
        .map(|p| (p.subset.as_slice(), p.x.as_slice()));
    let Judgement {
        before,
        after,
        plain,
        consistent,
        steps,
        series,
        residual_maps,
        predictions,
    } = models.judge(base, &problem, train, val, consistent_x)?;
    let std = jackknife::std(&last.loo, last.subset.len());
    let (theta, effects) = estimates(layout, &selection, &after, &std);
    // Per column of the final model (held-at-zero base columns are not among them).
    let sig = super::identifiability::torque_sigma(&problem, &last.subset, &last.w, &std);
    let undetermined: Vec<Undetermined> = last
        .subset
        .iter()
        .zip(&sig)
        .filter(|(_, &c)| c > super::identifiability::UNDETERMINED_SIGMA)
        .filter_map(|(&col, &c)| {
            let e = if col < layout.nb {
                theta.get(col)
            } else {
                let t = layout.terms[col - layout.nb];
                effects.iter().find(|(u, _)| *u == t).map(|(_, e)| e)
            }?;
            Some(Undetermined {
                name: e.name.clone(),
                value: e.value,
                std: e.std,
                torque_sigma: c,
            })
        })
        .collect();
    let sigma = last.w.iter().map(|w| 1.0 / w).collect();
    let load_model = load_model(layout, &selection.terms, &last.subset, &after.x);
    let fit = &last.fit;
    Ok(Outcome {
        arm: arm.to_string(),
        dof: base.dof(),
        base_source: base.source().to_string(),
        train: train.iter().map(FileInfo::of).collect(),
        validate: val.map(FileInfo::of),
        effects_mode: match &cfg.effects {
            EffectsSpec::Auto => "auto".into(),
            EffectsSpec::Fixed(t) if t.is_empty() => "none".into(),
            EffectsSpec::Fixed(t) => t.iter().map(Term::label).collect::<Vec<_>>().join(","),
        },
        theta,
        effects,
        selection,
        merged: merged.iter().map(|(t, w)| (t.label(), w.clone())).collect(),
        before,
        after,
        steps,
        cond: fit.cond,
        cond_scaled: fit.singular.first().copied().unwrap_or(f64::NAN)
            / fit.singular.last().copied().unwrap_or(f64::NAN),
        sigma,
        blocks: problem.blocks(),
        scales: layout.scales.clone(),
        runs: layout.runs.clone(),
        at_rest: layout.at_rest.clone(),
        cutoff_scan: Vec::new(),
        scan_sampling: None,
        rescanned_with: Vec::new(),
        load_model,
        series,
        residual_maps,
        predictions,
        physical,
        physical_error,
        consistent,
        warnings: Vec::new(),
        fixed: layout
            .fixed
            .iter()
            .map(|&c| layout.base_names[c].clone())
            .collect(),
        undetermined,
        plain,
        guard: None,
        coulomb_width: None,
        ripple: Vec::new(),
    })
}

/// What [`Models::judge`] finds: the rigid (`before`), final (`after`) and consistent models'
/// errors, the step table, the plot series, the residual maps and the validation file's
/// predictions.
struct Judgement {
    before: ModelResult,
    after: ModelResult,
    plain: Option<ModelResult>,
    consistent: Option<ModelResult>,
    steps: Vec<StepRow>,
    series: Series,
    residual_maps: ResidualMaps,
    predictions: Option<Predictions>,
}

/// The models reported — rigid, the final one, and rigid → +declared → +each added effect —
/// each fitted on all training blocks and without each block.
struct Models {
    /// What each row of the step table adds (the declared terms first, if any).
    added: Vec<Vec<Term>>,
    /// Each model's terms: rigid, final, then one per step.
    terms: Vec<Vec<Term>>,
    fitted: Vec<Fitted>,
}

/// One model's columns, weights, fit and leave-one-block-out parameters.
struct Fitted {
    subset: Vec<usize>,
    w: Vec<f64>,
    fit: ls::Fit,
    loo: Vec<Vec<f64>>,
}

impl Models {
    fn fit(
        problem: &Problem,
        train: &[Prepared],
        declared: &[Term],
        selection: &Selection,
    ) -> Result<Models, IdentifyError> {
        let mut added: Vec<Vec<Term>> = Vec::new();
        if !declared.is_empty() {
            added.push(declared.to_vec());
        }
        for s in &selection.steps {
            added.push(vec![s.added]);
        }
        if !selection.guarded.is_empty() {
            added.push(selection.guarded.clone());
        }
        let mut terms: Vec<Vec<Term>> = vec![Vec::new(), selection.terms.clone()];
        let mut acc_terms: Vec<Term> = Vec::new();
        for add in &added {
            acc_terms.extend(add.iter().copied());
            terms.push(acc_terms.clone());
        }
        // The plain fit last, when the guard compared with it.
        if !selection.plain.is_empty() {
            terms.push(selection.plain.clone());
        }
        let fitted: Vec<Fitted> = terms
            .iter()
            .map(|terms| -> Result<Fitted, IdentifyError> {
                let subset = problem.subset(terms);
                let w = problem.weights(&subset).map_err(|e| with_hint(e, train))?;
                let fit = problem.fit(&subset, &w).map_err(|e| with_hint(e, train))?;
                let loo = problem
                    .loo_fits(&subset, &w)
                    .map_err(|e| with_hint(e, train))?;
                Ok(Fitted {
                    subset,
                    w,
                    fit,
                    loo,
                })
            })
            .collect::<Result<_, _>>()?;
        Ok(Models {
            added,
            terms,
            fitted,
        })
    }

    /// The plain fit's place among the models, when there is one (last; judged from the states
    /// too, like the rigid and the final model).
    fn plain(&self) -> Option<usize> {
        (self.terms.len() > 2 + self.added.len()).then(|| self.terms.len() - 1)
    }

    /// The fits to judge, each set of columns once (the final model is the step table's last
    /// row), then the consistent estimate if any; and each model's place among them.
    fn to_judge<'s>(
        &'s self,
        consistent: Option<(&'s [usize], &'s [f64])>,
    ) -> (Vec<Judged<'s>>, Vec<usize>) {
        let mut judged: Vec<Judged> = Vec::new();
        let mut slot: Vec<usize> = Vec::new();
        for (m, f) in self.fitted.iter().enumerate() {
            match self.fitted[..m].iter().position(|g| g.subset == f.subset) {
                Some(first) => slot.push(slot[first]),
                None => {
                    slot.push(judged.len());
                    judged.push(Judged {
                        subset: &f.subset,
                        x: Some(&f.fit.x),
                        loo: Some(&f.loo),
                    });
                }
            }
        }
        // The consistent estimate last, on its columns (the final model's, and any base column
        // least squares held at zero; no held-out refits).
        if let Some((subset, x)) = consistent {
            judged.push(Judged {
                subset,
                x: Some(x),
                loo: None,
            });
        }
        (judged, slot)
    }

    /// The step table: rigid, then each added effect (`result(m)` judges model `m`).
    fn step_rows(
        &self,
        before: &ModelResult,
        result: impl Fn(usize) -> ModelResult,
    ) -> Vec<StepRow> {
        let mut steps = vec![StepRow {
            model: "rigid".into(),
            added: None,
            train: before.train.clone(),
            heldout_rms: before.heldout_rms,
            validation: before.validation.clone(),
        }];
        for (i, add) in self.added.iter().enumerate() {
            let m = result(2 + i);
            steps.push(StepRow {
                model: format!(
                    "rigid + {}",
                    self.terms[2 + i]
                        .iter()
                        .map(Term::label)
                        .collect::<Vec<_>>()
                        .join(" + ")
                ),
                added: Some(add.iter().map(Term::label).collect::<Vec<_>>().join(", ")),
                train: m.train,
                heldout_rms: m.heldout_rms,
                validation: m.validation,
            });
        }
        steps
    }

    /// Every model judged against the measured torque: the rigid (`before`) and the final
    /// (`after`) model and the step table.
    fn judge(
        &self,
        base: &BaseModel,
        problem: &Problem,
        train: &[Prepared],
        val: Option<&Prepared>,
        consistent: Option<(&[usize], &[f64])>,
    ) -> Result<Judgement, IdentifyError> {
        let layout = &problem.layout;
        let (judged, slot) = self.to_judge(consistent);
        let blocks = Some(problem.raw_blocks());
        // When the prediction is from the filtered rows, the rigid, final and consistent
        // models are judged from the estimated states too (the same pass over the rows).
        let filtered = train
            .iter()
            .chain(val)
            .any(|p| p.smoothing.filtered_prediction);
        let preds: &[Prediction] = if filtered {
            &[Prediction::Chosen, Prediction::States]
        } else {
            &[Prediction::Chosen]
        };
        // The rigid, final and consistent models' places among those judged.
        let consistent_slot = judged.len() - 1;
        let states: Vec<usize> = [slot[0], slot[1]]
            .into_iter()
            .chain(consistent.map(|_| consistent_slot))
            .collect();
        // The same passes collect the plot series (rigid and final model), the residual maps'
        // samples and, of the validation file, every sample for the predictions table and plot.
        let (train_stride, val_stride, map_stride) = series_strides(train, val);
        let t0 = train.iter().map(|p| p.log.t(0));
        let mut train_samples = TrainSamples::new(layout.dof, t0.collect(), map_stride);
        let mut train_each = raw_sums_sampled(
            base,
            layout,
            train,
            blocks,
            &judged,
            preds,
            Some(Sampling {
                stride: train_stride,
                map_stride: Some(map_stride),
                models: &states[..2],
                heldout: Some(states[1]),
            }),
            &mut |file, s| train_samples.take(file, s),
        );
        let (mut val_each, val_out) = match val {
            Some(p) => {
                let (sums, out) =
                    judge_validation(base, layout, p, (&judged, preds, &states), val_stride)?;
                (Some(sums), Some(out))
            }
            None => (None, None),
        };
        let (predictions, val_plotted) = val_out.unzip();
        let series =
            Series::from_samples(layout.dof, &train_samples.series, val_plotted.as_deref());
        let residual_maps = train_samples.maps.maps();
        let state_sums = filtered.then(|| {
            let t = train_each.pop().expect("two predictions");
            (t, val_each.as_mut().and_then(Vec::pop))
        });
        let train_sums = train_each.remove(0);
        let val_sums = val_each.map(|mut v| v.remove(0));
        let plain_slot = self.plain().map(|m| slot[m]);
        let from_states = |m: usize| {
            (states.contains(&m) || plain_slot == Some(m)).then_some(())?;
            let (t, v) = state_sums.as_ref()?;
            Some(StateErrors {
                train: t.errors(m),
                validation: v.as_ref().map(|v| v.errors(m)),
            })
        };
        let result = |m: usize| ModelResult {
            terms: self.terms[m].iter().map(Term::label).collect(),
            train: train_sums.errors(slot[m]),
            validation: val_sums.as_ref().map(|v| v.errors(slot[m])),
            heldout_rms: train_sums.heldout(slot[m]),
            from_states: from_states(slot[m]),
            subset: self.fitted[m].subset.clone(),
            x: self.fitted[m].fit.x.clone(),
        };
        let before = result(0);
        let after = result(1);
        let consistent = consistent.map(|(subset, x)| {
            let m = consistent_slot;
            ModelResult {
                terms: after.terms.clone(),
                train: train_sums.errors(m),
                validation: val_sums.as_ref().map(|v| v.errors(m)),
                heldout_rms: f64::NAN,
                from_states: from_states(m),
                subset: subset.to_vec(),
                x: x.to_vec(),
            }
        });
        let steps = self.step_rows(&before, result);
        let plain = self.plain().map(result);
        Ok(Judgement {
            before,
            after,
            plain,
            consistent,
            steps,
            series,
            residual_maps,
            predictions,
        })
    }
}

/// The validation predictions and the plotted samples ([`PredictionSink::finish`]).
type ValidationOut = (Predictions, Vec<f64>);

/// The validation file's pass of [`Models::judge`]: the sums of every judged model under each of
/// `preds`, and every `stride`-th sample of the `states` models for the predictions table and plot.
fn judge_validation(
    base: &BaseModel,
    layout: &Layout,
    val: &Prepared,
    (judged, preds, states): (&[Judged], &[Prediction], &[usize]),
    stride: usize,
) -> Result<(Vec<RawSums>, ValidationOut), IdentifyError> {
    let mut sink = PredictionSink::new(layout.dof, states.len(), stride);
    let sums = raw_sums_sampled(
        base,
        layout,
        std::slice::from_ref(val),
        None,
        judged,
        preds,
        Some(Sampling {
            stride: 1,
            map_stride: None,
            models: states,
            heldout: None,
        }),
        &mut |_, s| sink.take(s),
    );
    Ok((sums, sink.finish()?))
}

/// The final model's (`after`) parameters, base then effects, with their standard deviations
/// `std` (per column of `after.subset`, from [`jackknife::std`]). A base parameter held at zero
/// (`layout.fixed`) is 0 with no standard deviation.
fn estimates(
    layout: &Layout,
    selection: &Selection,
    after: &ModelResult,
    std: &[f64],
) -> (Vec<Estimated>, Vec<(Term, Estimated)>) {
    let est = |col: usize, name: String, expression: String, unit: Option<String>| {
        let (value, std) = match after.subset.iter().position(|&c| c == col) {
            Some(k) => (after.x[k], std[k]),
            None => (0.0, f64::NAN),
        };
        Estimated {
            name,
            expression,
            value,
            std,
            rel_std_percent: if value != 0.0 {
                100.0 * std / value.abs()
            } else {
                f64::INFINITY
            },
            unit,
        }
    };
    let theta: Vec<Estimated> = (0..layout.nb)
        .map(|k| {
            let name = layout.base_names[k].clone();
            let mut expr = layout.base_exprs[k].clone();
            if layout.fixed.contains(&k) {
                expr += " (held at 0: not identifiable from this data)";
            }
            est(k, name, expr, None)
        })
        .collect();
    let effects: Vec<(Term, Estimated)> = selection
        .terms
        .iter()
        .filter_map(|t| {
            let col = layout.col(t)?;
            Some((
                *t,
                est(
                    col,
                    t.label(),
                    format!("{} on joint {}", t.effect.name(), t.joint + 1),
                    Some(t.effect.unit().to_string()),
                ),
            ))
        })
        .collect();
    (theta, effects)
}
