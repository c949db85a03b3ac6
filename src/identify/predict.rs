//! **Predictions** of fitted models at a file's raw samples ([`Predicted`], from the rows of the
//! estimated states or the parallel-filtered rows, as the file's smoothing says): the shared
//! predictor of the errors, and the plot series and validation table of the outcome.

use std::sync::Arc;

use super::dot;
use super::prepare::{raw_in_core, Prepared};
use super::residual_map::{category_map, quantile_map, ResidualMaps, Variable};
use super::rows::Rows;
use super::IdentifyError;
use crate::derivative::States;
use crate::log::{Table, TableWriter, SPILL_ROWS};

/// Torque predictions of several coefficient sets (`[set][joint][active column]`) on a file's
/// grid around a core `a..b`: `pred[set][j][k - lo]` for the sets asked for (the others stay
/// empty), from the rows of the estimated states — then parallel-filtered ([`Predicted::filter`])
/// when the file's [`Smoothing`] predicts from the filtered rows (the same thing: the filter is
/// linear, so filtering a prediction equals predicting from filtered rows, at a fraction of the
/// channels).
pub(super) struct Predicted {
    lo: usize,
    hi: usize,
    pred: Vec<Vec<Vec<f64>>>,
    /// The window's estimated states (`None` when the rows came from the file's
    /// [`super::rows::RowTable`]).
    states: Option<States>,
}

impl Predicted {
    pub(super) fn new(
        p: &Prepared,
        rows: &mut Rows,
        active: &[Vec<usize>],
        (a, b): (usize, usize),
        coefs: &[Vec<Vec<f64>>],
        wanted: &[bool],
        reach: usize,
    ) -> Predicted {
        let n = rows.layout.dof;
        let g = p.est.grid;
        // One sample either side at least, for the interpolation to raw sample times; the
        // regression filter's reach when the predictions are to be filtered ([`Predicted::filter`]).
        let reach = reach.max(1);
        let (lo, hi) = (a.saturating_sub(reach), (b + reach).min(g.n));
        let w = hi - lo;
        let mut pred: Vec<Vec<Vec<f64>>> = wanted
            .iter()
            .map(|&u| if u { vec![vec![0.0; w]; n] } else { Vec::new() })
            .collect();
        // Per joint, the coefficients of the sets asked for, in order.
        let asked: Vec<usize> = (0..coefs.len()).filter(|&s| wanted[s]).collect();
        let per_joint: Vec<Vec<&[f64]>> = (0..n)
            .map(|j| asked.iter().map(|&s| coefs[s][j].as_slice()).collect())
            .collect();
        let mut dots = vec![0.0; asked.len()];
        let mut predict = |pred: &mut [Vec<Vec<f64>>], j: usize, k: usize, row: &[f64]| {
            dot::dots(row, &per_joint[j], &mut dots);
            for (&s, &d) in asked.iter().zip(&dots) {
                pred[s][j][k - lo] = d;
            }
        };
        if let Some(table) = p.rows.as_deref().filter(|t| t.fits(rows.layout)) {
            for k in lo..hi {
                for j in 0..n {
                    predict(&mut pred, j, k, table.row(j, k));
                }
            }
            return Predicted {
                lo,
                hi,
                pred,
                states: None,
            };
        }
        let mut row: Vec<Vec<f64>> = active.iter().map(|a| Vec::with_capacity(a.len())).collect();
        let states = p.states(lo, hi);
        for k in lo..hi {
            row.iter_mut().for_each(Vec::clear);
            rows.append_active(&states, k, active, &mut row);
            for (j, row) in row.iter().enumerate() {
                predict(&mut pred, j, k, row);
            }
        }
        Predicted {
            lo,
            hi,
            pred,
            states: Some(states),
        }
    }

    /// The predictions from the filtered rows: those from the states, filtered. Built with
    /// `filtered`, the window reaches far enough; the samples of the core are then exact.
    pub(super) fn filter(&mut self, p: &Prepared) {
        self.filter_sets(p, 0..self.pred.len());
    }

    /// A copy of the predictions (not the states) with the sets `sets` filtered by `p`'s
    /// regression filter ([`Predicted::filter_sets`]).
    pub(super) fn filtered_copy(&self, p: &Prepared, sets: std::ops::Range<usize>) -> Predicted {
        let mut out = Predicted {
            lo: self.lo,
            hi: self.hi,
            pred: self.pred.clone(),
            states: None,
        };
        out.filter_sets(p, sets);
        out
    }

    /// [`Predicted::filter`] of the sets `sets` only, with `p`'s regression filter.
    pub(super) fn filter_sets(&mut self, p: &Prepared, sets: std::ops::Range<usize>) {
        let mut chans: Vec<&mut [f64]> = self.pred[sets]
            .iter_mut()
            .flatten()
            .map(|c| c.as_mut_slice())
            .collect();
        p.rfilter
            .as_zero_phase()
            .apply_many(&mut chans, self.lo == 0, self.hi == p.est.grid.n);
    }

    /// Appends, for every used raw sample of `p` in the core `(a, b)` (the core this was built
    /// for) that is a `stride`-th or a `map_stride`-th one of the file's used samples, one
    /// [`SampleRow`]: which strides it is of, its index among the used samples, t, q̇ (n,
    /// interpolated from the window's estimated states — estimated now when the rows came from a
    /// table), τ (n), the prediction of each of `sets` (n each), with `heldout = (first, blocks)`
    /// the prediction of set `first + b` for a sample of block `b` (n: the fit without the
    /// sample's block), then q and q̈ (n each).
    pub(super) fn push_samples(
        &mut self,
        p: &Prepared,
        core: (usize, usize),
        (stride, map_stride): (usize, Option<usize>),
        (sets, heldout): (&[usize], Option<(usize, usize)>),
        out: &mut Vec<f64>,
    ) {
        let n = p.dof();
        if self.states.is_none() {
            self.states = Some(p.states(self.lo, self.hi));
        }
        let this = &*self;
        let Some(st) = this.states.as_ref() else {
            return;
        };
        let stride = stride.max(1);
        // Without map samples the series' stride alone: only those rows are visited.
        let visit = if map_stride.is_some() { 1 } else { stride };
        raw_in_core(p, core, visit, |r, t, tau, (k, s)| {
            let used = r - p.raw_keep.0;
            let which = u8::from(used.is_multiple_of(stride))
                | (u8::from(map_stride.is_some_and(|m| used.is_multiple_of(m.max(1)))) << 1);
            if which == 0 {
                return;
            }
            out.push(f64::from(which));
            out.push(used as f64);
            out.push(t);
            let i = k - this.lo;
            for d in &st.dq[..n] {
                out.push(interpolate(d, i, s));
            }
            out.extend_from_slice(tau);
            for &m in sets {
                out.extend((0..n).map(|j| this.at(m, j, (k, s))));
            }
            if let Some((first, blocks)) = heldout {
                // The block as the held-out sums assign it (`evaluate::add_core`).
                let set = first + p.block_of(k + usize::from(s >= 0.5), blocks);
                out.extend((0..n).map(|j| this.at(set, j, (k, s))));
            }
            for d in st.q[..n].iter().chain(&st.ddq[..n]) {
                out.push(interpolate(d, i, s));
            }
        });
    }

    /// Set `c`'s prediction for joint `j` at grid position `(k, s)` (see [`super::prepare::grid_pos`]).
    pub(super) fn at(&self, c: usize, j: usize, (k, s): (usize, f64)) -> f64 {
        interpolate(&self.pred[c][j], k - self.lo, s)
    }

    /// Set `c`'s predictions for joint `j` on the window's grid samples (`[k - lo]`), and `lo`.
    pub(super) fn of(&self, c: usize, j: usize) -> (&[f64], usize) {
        (&self.pred[c][j], self.lo)
    }
}

/// `x` at `i + s` (`0 ≤ s < 1`), linear between samples.
#[inline]
pub(super) fn interpolate(x: &[f64], i: usize, s: f64) -> f64 {
    let v = x[i];
    if s > 0.0 {
        v + s * (x[i + 1] - v)
    } else {
        v
    }
}

/// A model's parameters spread over joint `j`'s active columns (zero outside the model), so a
/// prediction is one contiguous dot product.
pub(super) fn spread(active: &[usize], subset: &[usize], x: &[f64]) -> Vec<f64> {
    active
        .iter()
        .map(|c| subset.iter().position(|s| s == c).map_or(0.0, |k| x[k]))
        .collect()
}

/// `(velocity, residual)` points before and after.
pub type BeforeAfter = (Vec<(f64, f64)>, Vec<(f64, f64)>);

/// Plot data: per joint, (velocity, residual) of the training data before and after.
#[derive(Debug, Clone, Default)]
pub struct Series {
    pub resid_vs_vel: Vec<BeforeAfter>,
    /// Validation: per joint, (t, measured, before, after).
    pub validation: Vec<Vec<(f64, f64, f64, f64)>>,
}

/// The rows of `validation_prediction.csv`: per validation sample used, its time, then the
/// measured τ and the torques predicted by the declared (`before`) and augmented (`after`)
/// models and, when stage 8 ran, the consistent estimate, n each — in a [`Table`] (a long validation log's spill to a temporary file).
#[derive(Debug, Clone)]
pub struct Predictions {
    pub dof: usize,
    /// Whether the rows hold the consistent estimate's torques after the final model's.
    pub consistent: bool,
    table: Arc<Table>,
}

impl Predictions {
    pub fn len(&self) -> usize {
        self.table.len()
    }

    pub fn is_empty(&self) -> bool {
        self.table.is_empty()
    }

    /// Calls `f(t, tau, before, after, consistent)` for rows `a..b` in order.
    pub fn rows(
        &self,
        a: usize,
        b: usize,
        mut f: impl FnMut(f64, &[f64], &[f64], &[f64], Option<&[f64]>),
    ) {
        let n = self.dof;
        let c = self.consistent;
        self.table.rows(a, b, |r| {
            let consistent = c.then(|| &r[1 + 3 * n..1 + 4 * n]);
            f(
                r[0],
                &r[1..1 + n],
                &r[1 + n..1 + 2 * n],
                &r[1 + 2 * n..1 + 3 * n],
                consistent,
            )
        });
    }
}

/// Most samples of the training files the residual maps bin (about; memory ~ `5·dof + 4` floats
/// a sample).
pub const MAP_SAMPLES: usize = 50_000;

/// Strides of the plot series: every how many used raw samples of the training files (about
/// 3000 points over all) and of the validation file (about 4000) a sample is plotted, and of the
/// training files one enters the residual maps (at most [`MAP_SAMPLES`]).
pub(super) fn series_strides(train: &[Prepared], val: Option<&Prepared>) -> (usize, usize, usize) {
    let used = |p: &Prepared| p.raw_keep.1 - p.raw_keep.0;
    let total: usize = train.iter().map(used).sum();
    (
        total.div_ceil(3000).max(1),
        val.map_or(1, |p| used(p).div_ceil(4000).max(1)),
        total.div_ceil(MAP_SAMPLES).max(1),
    )
}

/// Floats in a row of [`Predicted::push_samples`] with `sets` predictions of `n` joints.
fn sample_width(n: usize, sets: usize) -> usize {
    3 + (4 + sets) * n
}

/// The training samples the judging pass hands over ([`Predicted::push_samples`] of the rigid
/// and the final model, and the final model's held-out prediction, files in order): those of
/// the plot series' stride kept as [`Series::from_samples`] reads them, those of the maps'
/// stride as [`MapSamples`].
pub(super) struct TrainSamples {
    dof: usize,
    pub(super) series: Vec<f64>,
    pub(super) maps: MapSamples,
}

impl TrainSamples {
    /// For files starting at times `t0` (their first sample's, whether used or not), sampled
    /// every `every`-th used sample for the maps.
    pub(super) fn new(dof: usize, t0: Vec<f64>, every: usize) -> Self {
        TrainSamples {
            dof,
            series: Vec::new(),
            maps: MapSamples {
                every: every.max(1),
                t0,
                at: Vec::new(),
                time: Vec::new(),
                vars: vec![Default::default(); dof],
            },
        }
    }

    /// Whole samples of training file `file`, in order.
    pub(super) fn take(&mut self, file: usize, samples: &[f64]) {
        let n = self.dof;
        for x in samples.chunks_exact(sample_width(n, 3)) {
            let which = x[0] as u8;
            if which & 1 != 0 {
                // t, q̇, τ, rigid and final model.
                self.series.extend_from_slice(&x[2..3 + 4 * n]);
            }
            if which & 2 != 0 {
                self.maps.push(n, file, x);
            }
        }
    }
}

/// The samples of the residual maps: per sample its (file, index among the file's map samples)
/// and time since the file's start, per joint q, q̇, q̈, the final model's τ̂ and its held-out
/// residual τ − τ̂₋ᵦ, τ̂₋ᵦ the prediction of the fit without the sample's block (in that order).
pub(super) struct MapSamples {
    every: usize,
    t0: Vec<f64>,
    at: Vec<(usize, u64)>,
    time: Vec<f64>,
    vars: Vec<[Vec<f64>; 5]>,
}

impl MapSamples {
    fn push(&mut self, n: usize, file: usize, x: &[f64]) {
        self.at.push((file, (x[1] as usize / self.every) as u64));
        self.time
            .push(x[2] - self.t0.get(file).copied().unwrap_or(f64::NAN));
        let (dq, tau) = (&x[3..3 + n], &x[3 + n..3 + 2 * n]);
        let (after, heldout) = (&x[3 + 3 * n..3 + 4 * n], &x[3 + 4 * n..3 + 5 * n]);
        let (q, ddq) = (&x[3 + 5 * n..3 + 6 * n], &x[3 + 6 * n..3 + 7 * n]);
        for (j, v) in self.vars.iter_mut().enumerate() {
            for (c, value) in v
                .iter_mut()
                .zip([q[j], dq[j], ddq[j], after[j], tau[j] - heldout[j]])
            {
                c.push(value);
            }
        }
    }

    /// Every joint's maps ([`Variable::ALL`] each).
    pub(super) fn maps(&self) -> ResidualMaps {
        let run: Vec<usize> = self.at.iter().map(|a| a.0).collect();
        let maps = self
            .vars
            .iter()
            .enumerate()
            .flat_map(|(j, [q, dq, ddq, tau_hat, r])| {
                Variable::ALL.map(|v| {
                    let x = match v {
                        Variable::Position => q,
                        Variable::Velocity => dq,
                        Variable::Acceleration => ddq,
                        Variable::Time => &self.time,
                        Variable::Torque => tau_hat,
                        Variable::Run => return category_map(j, v, &run, r, &self.at),
                    };
                    quantile_map(j, v, x, r, &self.at)
                })
            })
            .collect();
        ResidualMaps {
            every: self.every,
            samples: self.at.len(),
            maps,
        }
    }
}

impl Series {
    /// The plot series from the samples the judging pass collected ([`Predicted::push_samples`]
    /// of the rigid and the final model, training files then the validation file).
    pub(super) fn from_samples(n: usize, train: &[f64], val: Option<&[f64]>) -> Series {
        let width = 1 + 4 * n;
        let mut rv: Vec<BeforeAfter> = vec![(Vec::new(), Vec::new()); n];
        for x in train.chunks_exact(width) {
            let (dq, tau) = (&x[1..1 + n], &x[1 + n..1 + 2 * n]);
            let (before, after) = (&x[1 + 2 * n..1 + 3 * n], &x[1 + 3 * n..]);
            for j in 0..n {
                rv[j].0.push((dq[j], tau[j] - before[j]));
                rv[j].1.push((dq[j], tau[j] - after[j]));
            }
        }
        let mut validation = vec![Vec::new(); n];
        for x in val.unwrap_or_default().chunks_exact(width) {
            let tau = &x[1 + n..1 + 2 * n];
            let (before, after) = (&x[1 + 2 * n..1 + 3 * n], &x[1 + 3 * n..]);
            for j in 0..n {
                validation[j].push((x[0], tau[j], before[j], after[j]));
            }
        }
        Series {
            resid_vs_vel: rv,
            validation,
        }
    }
}

/// The validation file's samples as the judging pass hands them over (every used raw sample's
/// [`Predicted::push_samples`] row: t, q̇, τ, then the rigid, final and — when stage 8 ran —
/// consistent models' predictions, …),
/// written to the [`Predictions`] table (spilled to a temporary file for a long log) with every
/// `stride`-th one kept for the validation plot.
pub(super) struct PredictionSink {
    dof: usize,
    models: usize,
    table: TableWriter,
    row: Vec<f64>,
    failed: Option<std::io::Error>,
    stride: usize,
    seen: usize,
    plotted: Vec<f64>,
}

impl PredictionSink {
    pub(super) fn new(dof: usize, models: usize, stride: usize) -> Self {
        PredictionSink {
            dof,
            models,
            table: TableWriter::new(1 + (1 + models) * dof, SPILL_ROWS),
            row: Vec::new(),
            failed: None,
            stride: stride.max(1),
            seen: 0,
            plotted: Vec::new(),
        }
    }

    /// Whole samples ([`Predicted::push_samples`] rows), in order.
    pub(super) fn take(&mut self, samples: &[f64]) {
        let n = self.dof;
        for x in samples.chunks_exact(sample_width(n, self.models)) {
            if self.seen.is_multiple_of(self.stride) {
                // The plot's sample: t, q̇, τ, rigid and final model.
                self.plotted.extend_from_slice(&x[2..3 + 4 * n]);
            }
            self.seen += 1;
            self.row.clear();
            self.row.push(x[2]);
            self.row
                .extend_from_slice(&x[3 + n..3 + (2 + self.models) * n]);
            if let Err(e) = self.table.push(&self.row) {
                self.failed.get_or_insert(e);
            }
        }
    }

    /// The predictions table and the plot's samples (as [`Series::from_samples`] reads them).
    pub(super) fn finish(self) -> Result<(Predictions, Vec<f64>), IdentifyError> {
        let table = match self.failed {
            Some(e) => Err(e),
            None => self.table.finish(),
        }
        .map_err(IdentifyError::Spill)?;
        let predictions = Predictions {
            dof: self.dof,
            consistent: self.models > 2,
            table: Arc::new(table),
        };
        Ok((predictions, self.plotted))
    }
}
