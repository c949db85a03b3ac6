//! Stage 5, **errors against the measured torque**: models' residuals at every used raw sample
//! of the files, with their full-data and their leave-one-block-out parameters ([`raw_sums`]),
//! as relative RMS errors ([`Errors`]) of each model ([`ModelResult`]).

use rayon::prelude::*;
use serde::Serialize;

use super::base::BaseModel;
use super::layout::Layout;
use super::predict::{interpolate, spread, Predicted};
use super::prepare::{raw_cores, raw_in_core, Prepared};
use super::rows::Rows;

/// A model judged against the measured torque: its columns, its parameters fitted on all
/// training blocks (for the error) and those fitted without each block (for the held-out
/// error); either may be left out.
pub struct Judged<'a> {
    pub subset: &'a [usize],
    pub x: Option<&'a [f64]>,
    pub loo: Option<&'a [Vec<f64>]>,
}

/// Which prediction of a model is judged: the one the file's [`super::prepare::Smoothing`]
/// chose (from the parallel-filtered rows or from the estimated states), or always the one from
/// the estimated states (what a controller fed those states would compute).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Prediction {
    Chosen,
    States,
    /// Always the one from the parallel-filtered rows (the cut-off scan judges both).
    Filtered,
}

/// Per model and joint, `Σ (τ − τ̂)²` over the raw samples (with the full-data parameters) and
/// the same with each block predicted by the fit without it; per joint `Σ τ²`.
#[derive(Debug, Clone)]
pub struct RawSums {
    pub sse: Vec<Vec<f64>>,
    pub heldout: Vec<Vec<f64>>,
    pub tss: Vec<f64>,
}

impl RawSums {
    fn zero(models: usize, n: usize) -> Self {
        RawSums {
            sse: vec![vec![0.0; n]; models],
            heldout: vec![vec![0.0; n]; models],
            tss: vec![0.0; n],
        }
    }

    fn add(&mut self, o: &RawSums) {
        for (a, b) in self.sse.iter_mut().zip(&o.sse) {
            a.iter_mut().zip(b).for_each(|(x, y)| *x += y);
        }
        for (a, b) in self.heldout.iter_mut().zip(&o.heldout) {
            a.iter_mut().zip(b).for_each(|(x, y)| *x += y);
        }
        self.tss.iter_mut().zip(&o.tss).for_each(|(x, y)| *x += y);
    }

    /// Errors of model `m` with its full-data parameters.
    pub fn errors(&self, m: usize) -> Errors {
        Errors::from_sums(self.sse[m].clone(), self.tss.clone())
    }

    /// Held-out relative RMS error of model `m`, pooled over joints.
    pub fn heldout(&self, m: usize) -> f64 {
        (self.heldout[m].iter().sum::<f64>() / self.tss.iter().sum::<f64>()).sqrt()
    }

    /// Held-out error of model `m` with each group of joints pooled on its own: the root of the
    /// sum over `groups` of each group's relative mean square error (one group of every joint:
    /// [`RawSums::heldout`]). Joints in no group are left out.
    pub fn heldout_grouped(&self, m: usize, groups: &[Vec<usize>]) -> f64 {
        groups
            .iter()
            .map(|g| {
                let e: f64 = g.iter().map(|&j| self.heldout[m][j]).sum();
                let t: f64 = g.iter().map(|&j| self.tss[j]).sum();
                e / t
            })
            .sum::<f64>()
            .sqrt()
    }
}

/// Residuals of `models` against the torque as measured, over the raw samples of `files`;
/// `blocks` (blocks per file) names the block whose leave-out parameters predict a sample.
/// One pass, in parallel over chunks; the chunk sums are added in a fixed order
/// (deterministic).
pub fn raw_sums(
    base: &BaseModel,
    layout: &Layout,
    files: &[Prepared],
    blocks: Option<&[usize]>,
    models: &[Judged],
    prediction: Prediction,
) -> RawSums {
    let mut all = raw_sums_each(base, layout, files, blocks, models, &[prediction]);
    all.pop().expect("one prediction asked, one returned")
}

/// [`raw_sums`] of each of `predictions` (in order) from one evaluation of the rows: the
/// prediction from the states is that of the filtered rows before the filter (the filter is
/// linear), so both cost one pass.
pub fn raw_sums_each(
    base: &BaseModel,
    layout: &Layout,
    files: &[Prepared],
    blocks: Option<&[usize]>,
    models: &[Judged],
    predictions: &[Prediction],
) -> Vec<RawSums> {
    raw_sums_sampled(
        base,
        layout,
        files,
        blocks,
        models,
        predictions,
        None,
        &mut |_, _| {},
    )
}

/// Samples asked of [`raw_sums_sampled`]: every `stride`-th used raw sample of each file (and,
/// when `map_stride` is given, every `map_stride`-th too) with the chosen predictions of the
/// (full-data) `models`.
#[derive(Debug, Clone, Copy)]
pub struct Sampling<'a> {
    pub stride: usize,
    pub map_stride: Option<usize>,
    pub models: &'a [usize],
    /// The model (index into the judged models) whose held-out prediction — by the fit without
    /// the sample's block — each sample also carries, after `models`' (when it has one).
    pub heldout: Option<usize>,
}

/// [`raw_sums_each`], handing `sink` in the same pass the samples `sampling` asks for (see
/// [`super::predict::Predicted::push_samples`]) with their file's index: files in order, each file's samples in order,
/// a few chunks' at a time (memory stays that of a few chunks whatever the files' length).
#[allow(clippy::too_many_arguments)]
pub fn raw_sums_sampled(
    base: &BaseModel,
    layout: &Layout,
    files: &[Prepared],
    blocks: Option<&[usize]>,
    models: &[Judged],
    predictions: &[Prediction],
    sampling: Option<Sampling>,
    sink: &mut dyn FnMut(usize, &[f64]),
) -> Vec<RawSums> {
    let n = layout.dof;
    let batch = match sampling {
        Some(_) => 4 * rayon::current_num_threads(),
        None => usize::MAX,
    };
    let active: Vec<Vec<usize>> = (0..n).map(|j| layout.active(j)).collect();
    let mut total = vec![RawSums::zero(models.len(), n); predictions.len()];
    let mut offset = 0;
    for (fi, p) in files.iter().enumerate() {
        let nblocks = blocks.map_or(1, |b| b[fi]);
        // Coefficient sets `[set][joint][active column]`: model m's full-data parameters (if
        // any) at `placed[m].first`, then its leave-one-block-out ones, block by block.
        let (mut sets, mut placed) = (Vec::new(), Vec::new());
        for m in models {
            placed.push(ModelSets {
                first: sets.len(),
                full: m.x.is_some(),
                heldout: m.loo.is_some(),
            });
            let per_joint = |x: &[f64]| -> Vec<Vec<f64>> {
                (0..n).map(|j| spread(&active[j], m.subset, x)).collect()
            };
            sets.extend(m.x.map(per_joint));
            if let Some(loo) = m.loo {
                sets.extend((0..nblocks).map(|b| per_joint(&loo[offset + b])));
            }
        }
        // Per prediction asked: whether it is of the filtered rows in this file.
        let filtered: Vec<bool> = predictions
            .iter()
            .map(|&pr| match pr {
                Prediction::Chosen => p.smoothing.filtered_prediction,
                Prediction::States => false,
                Prediction::Filtered => true,
            })
            .collect();
        // The sets whose samples are collected, in the pass of the chosen prediction.
        let sampled: Option<(Sampling, Vec<usize>)> = sampling.map(|a| {
            let sets = a.models.iter().map(|&m| placed[m].first).collect();
            (a, sets)
        });
        // The held-out sets of `sampling.heldout`: the first block's, and how many blocks (a
        // model without held-out fits gives its full-data one, as one block: the rows keep
        // their width).
        let heldout = sampling.and_then(|a| a.heldout).map(|m| {
            if placed[m].heldout {
                (placed[m].block_set(0), nblocks)
            } else {
                (placed[m].first, 1)
            }
        });
        let cores = raw_cores(p);
        for cores in cores.chunks(batch) {
            let parts: Vec<(Vec<RawSums>, Vec<f64>)> = cores
                .par_iter()
                .map(|&core| {
                    let mut rows = Rows::for_log(base, layout, &p.log);
                    let (b0, b1) = core_blocks(p, core, nblocks);
                    let mut wanted = vec![false; sets.len()];
                    for model in &placed {
                        wanted[model.first] |= model.full;
                        if model.heldout {
                            for blk in b0..=b1 {
                                wanted[model.block_set(blk)] = true;
                            }
                        }
                    }
                    let any_filtered = filtered.iter().any(|&f| f)
                        || (sampled.is_some() && p.smoothing.filtered_prediction);
                    let reach = if any_filtered {
                        p.rfilter.as_zero_phase().reach()
                    } else {
                        1
                    };
                    let mut pc = Predicted::new(p, &mut rows, &active, core, &sets, &wanted, reach);
                    let mut out = vec![RawSums::zero(models.len(), n); predictions.len()];
                    let mut picked = Vec::new();
                    for pass in [false, true] {
                        if pass {
                            if !any_filtered {
                                break;
                            }
                            pc.filter(p);
                        }
                        for (sums, _) in out.iter_mut().zip(&filtered).filter(|(_, &f)| f == pass) {
                            add_core(sums, p, core, nblocks, &placed, &pc);
                        }
                        if let Some((a, sets)) = &sampled {
                            if pass == p.smoothing.filtered_prediction {
                                let strides = (a.stride, a.map_stride);
                                pc.push_samples(p, core, strides, (sets, heldout), &mut picked);
                            }
                        }
                    }
                    (out, picked)
                })
                .collect();
            for (part, picked) in &parts {
                for (t, s) in total.iter_mut().zip(part) {
                    t.add(s);
                }
                if !picked.is_empty() {
                    sink(fi, picked);
                }
            }
        }
        offset += nblocks;
    }
    total
}

/// Held-out errors (leave-one-block-out, pooled) of one model per regression filter, from one
/// evaluation of the rows: `variants[v]` are the same files prepared with filter `v` (same
/// logs, grids, states and used samples; only the regression filter differs) and `loo[v]` the
/// model's leave-one-block-out parameters fitted with it (over `subsets[v]`). Per variant `(from the estimated
/// states, from the filtered rows)` — what [`raw_sums_each`] gives each variant on its own
/// (windows reach as far as the widest filter: the same numbers to the filters' truncation,
/// ~1e-8). Joints are pooled in `groups` ([`RawSums::heldout_grouped`]).
#[allow(clippy::too_many_arguments)]
pub(super) fn heldout_per_filter(
    base: &BaseModel,
    layout: &Layout,
    variants: &[&[Prepared]],
    blocks: &[usize],
    groups: &[Vec<usize>],
    subsets: &[&[usize]],
    loo: &[&[Vec<f64>]],
) -> Vec<(f64, f64)> {
    let n = layout.dof;
    let nv = variants.len();
    let active: Vec<Vec<usize>> = (0..n).map(|j| layout.active(j)).collect();
    // Per variant, states then filtered.
    let mut total = vec![RawSums::zero(1, n); 2 * nv];
    let mut offset = 0;
    for (fi, &nblocks) in blocks.iter().enumerate() {
        // Coefficient sets `[variant · nblocks + block][joint][active column]`.
        let sets: Vec<Vec<Vec<f64>>> = loo
            .iter()
            .zip(subsets)
            .flat_map(|(l, subset)| {
                (0..nblocks).map(|b| {
                    (0..n)
                        .map(|j| spread(&active[j], subset, &l[offset + b]))
                        .collect()
                })
            })
            .collect();
        // The variant of the widest filter lays out the windows.
        let reach = |v: usize| variants[v][fi].rfilter.as_zero_phase().reach();
        let widest = (0..nv).max_by_key(|&v| reach(v)).unwrap_or(0);
        let p = &variants[widest][fi];
        let parts: Vec<Vec<RawSums>> = raw_cores(p)
            .par_iter()
            .map(|&core| {
                let mut rows = Rows::for_log(base, layout, &p.log);
                let (b0, b1) = core_blocks(p, core, nblocks);
                let wanted: Vec<bool> = (0..sets.len())
                    .map(|s| (b0..=b1).contains(&(s % nblocks)))
                    .collect();
                let states =
                    Predicted::new(p, &mut rows, &active, core, &sets, &wanted, reach(widest));
                let mut out = vec![RawSums::zero(1, n); 2 * nv];
                for v in 0..nv {
                    let pv = &variants[v][fi];
                    // The model's leave-one-block-out sets with this variant's filter.
                    let model = [ModelSets {
                        first: v * nblocks,
                        full: false,
                        heldout: true,
                    }];
                    add_core(&mut out[2 * v], pv, core, nblocks, &model, &states);
                    let filtered = states.filtered_copy(pv, v * nblocks..(v + 1) * nblocks);
                    add_core(&mut out[2 * v + 1], pv, core, nblocks, &model, &filtered);
                }
                out
            })
            .collect();
        for part in &parts {
            for (t, s) in total.iter_mut().zip(part) {
                t.add(s);
            }
        }
        offset += nblocks;
    }
    (0..nv)
        .map(|v| {
            (
                total[2 * v].heldout_grouped(0, groups),
                total[2 * v + 1].heldout_grouped(0, groups),
            )
        })
        .collect()
}

/// The first and last block a core's raw samples can fall in (filter margins included): only
/// those blocks' held-out parameters are predicted there.
fn core_blocks(p: &Prepared, core: (usize, usize), nblocks: usize) -> (usize, usize) {
    (
        p.block_of(core.0.saturating_sub(1), nblocks),
        p.block_of(core.1, nblocks),
    )
}

/// Adds the residuals of one core's raw samples to `sums` (predictions `pc`): the samples'
/// grid positions, blocks and torques read once, then each model's and joint's sums in one
/// sweep over them (in sample order, as every sum was always added).
fn add_core(
    sums: &mut RawSums,
    p: &Prepared,
    core: (usize, usize),
    nblocks: usize,
    models: &[ModelSets],
    pc: &Predicted,
) {
    let n = sums.tss.len();
    let mut pos: Vec<(usize, f64)> = Vec::new();
    // Runs of consecutive samples in one block: (end, block).
    let mut runs: Vec<(usize, usize)> = Vec::new();
    let mut tau: Vec<Vec<f64>> = vec![Vec::new(); n];
    raw_in_core(p, core, 1, |_, _, t, (k, s)| {
        let blk = p.block_of(k + usize::from(s >= 0.5), nblocks);
        match runs.last_mut() {
            Some((end, b)) if *b == blk => *end += 1,
            _ => runs.push((pos.len() + 1, blk)),
        }
        pos.push((k, s));
        for (c, &v) in tau.iter_mut().zip(t) {
            c.push(v);
        }
    });
    for (ss, t) in sums.tss.iter_mut().zip(&tau) {
        for t in t {
            *ss += t * t;
        }
    }
    let sse = |acc: &mut f64, set: usize, j: usize, from: usize, to: usize| {
        let (x, lo) = pc.of(set, j);
        for (&(k, s), &t) in pos[from..to].iter().zip(&tau[j][from..to]) {
            let e = t - interpolate(x, k - lo, s);
            *acc += e * e;
        }
    };
    for (m, model) in models.iter().enumerate() {
        for j in 0..n {
            if model.full {
                sse(&mut sums.sse[m][j], model.first, j, 0, pos.len());
            }
            if model.heldout {
                let mut from = 0;
                for &(to, blk) in &runs {
                    sse(&mut sums.heldout[m][j], model.block_set(blk), j, from, to);
                    from = to;
                }
            }
        }
    }
}

/// Where a judged model's coefficient sets are among those predicted: its full-data set at
/// `first` (if `full`), then its leave-one-block-out sets block by block (if `heldout`).
#[derive(Debug, Clone, Copy)]
struct ModelSets {
    first: usize,
    full: bool,
    heldout: bool,
}

impl ModelSets {
    /// The set of the fit without block `blk`.
    fn block_set(&self, blk: usize) -> usize {
        self.first + usize::from(self.full) + blk
    }
}

/// A fitted model and its errors.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ModelResult {
    pub terms: Vec<String>,
    pub train: Errors,
    pub validation: Option<Errors>,
    /// Held-out error of leave-one-block-out refits on the (filtered) training data.
    pub heldout_rms: f64,
    /// The same model's errors with its torque predicted from the estimated states, when the
    /// errors above are of the prediction from the parallel-filtered rows (`None` otherwise:
    /// the errors above are already from the states).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub from_states: Option<StateErrors>,
    #[serde(skip)]
    pub subset: Vec<usize>,
    #[serde(skip)]
    pub x: Vec<f64>,
}

impl ModelResult {
    /// Every `overall` of this model over `joints` only ([`Errors::pool`]).
    pub fn pool(&mut self, joints: &[usize]) {
        self.train.pool(joints);
        if let Some(v) = &mut self.validation {
            v.pool(joints);
        }
        if let Some(s) = &mut self.from_states {
            s.train.pool(joints);
            if let Some(v) = &mut s.validation {
                v.pool(joints);
            }
        }
    }
}

/// A model's errors with its torque predicted from the estimated states.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct StateErrors {
    pub train: Errors,
    pub validation: Option<Errors>,
}

/// Relative RMS errors against measured torque.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Errors {
    pub per_joint: Vec<f64>,
    pub overall: f64,
    /// Per joint `Σ (τ − τ̂)²` and `Σ τ²` behind the ratios (to pool errors over files).
    #[serde(skip)]
    pub sse: Vec<f64>,
    #[serde(skip)]
    pub tss: Vec<f64>,
    /// The joints `overall` pools (0-based); `None` = all. An arm with joints of different
    /// units (a prismatic joint's N, a revolute one's N·m) or with weak joints pools only the
    /// identifiable joints of one unit ([`super::weak::pooled_joints`]).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub pooled_joints: Option<Vec<usize>>,
}

impl Errors {
    /// The errors of several files' samples together (`None` for none).
    pub fn pooled<'a>(parts: impl IntoIterator<Item = &'a Errors>) -> Option<Errors> {
        let mut it = parts.into_iter();
        let first = it.next()?;
        let (mut sse, mut tss) = (first.sse.clone(), first.tss.clone());
        for e in it {
            sse.iter_mut().zip(&e.sse).for_each(|(a, b)| *a += b);
            tss.iter_mut().zip(&e.tss).for_each(|(a, b)| *a += b);
        }
        let mut out = Errors::from_sums(sse, tss);
        if let Some(j) = &first.pooled_joints {
            out.pool(j);
        }
        Some(out)
    }

    /// `overall` over `joints` only (see [`Errors::pooled_joints`]).
    pub fn pool(&mut self, joints: &[usize]) {
        let sum = |v: &[f64]| joints.iter().filter_map(|&j| v.get(j)).sum::<f64>();
        self.overall = (sum(&self.sse) / sum(&self.tss)).sqrt();
        self.pooled_joints = Some(joints.to_vec());
    }

    /// Relative RMS errors from per-joint sums of squared residuals and of squared torque.
    pub fn from_sums(sse: Vec<f64>, tss: Vec<f64>) -> Errors {
        let per_joint = sse
            .iter()
            .zip(&tss)
            .map(|(e, t)| if *t > 0.0 { (e / t).sqrt() } else { f64::NAN })
            .collect();
        Errors {
            per_joint,
            overall: (sse.iter().sum::<f64>() / tss.iter().sum::<f64>()).sqrt(),
            sse,
            tss,
            pooled_joints: None,
        }
    }
}
