//! Stage 4, **the least-squares problem** of a training set ([`Problem`]): per-block and total QR
//! factors, leave-one-block-out factors, weighted fits of any column subset, held-out fits and
//! partial correlations — everything the effect selection and the reported models ask.

use nalgebra::{DMatrix, DVector};

use super::base::BaseModel;
use super::evaluate::{raw_sums_each, Judged, Prediction};
use super::layout::Layout;
use super::ls::{self, Accumulator};
use super::prepare::{cores, Prepared};
use super::regress::{accumulate_fit, accumulate_fits};
use super::RankError;
use crate::effects::Term;

/// Merges `[block][joint]` accumulators into `[joint]` (at least one block).
fn merge_blocks(blocks: &[Vec<Accumulator>], n: usize) -> Vec<Accumulator> {
    let mut out: Vec<Accumulator> = blocks[0].iter().map(Accumulator::empty_like).collect();
    for b in blocks {
        for j in 0..n {
            out[j].merge(&b[j]);
        }
    }
    out
}

/// The accumulated least-squares problem of a training set (all candidate columns present).
#[derive(Debug, Clone)]
pub struct Problem {
    pub layout: Layout,
    /// `[block][joint]`, parallel-filtered.
    blocks: Vec<Vec<Accumulator>>,
    /// `[joint]`, all blocks.
    total: Vec<Accumulator>,
    /// `[block][joint]`: factor of all blocks but this one.
    loo: Vec<Vec<DMatrix<f64>>>,
    /// Blocks per training file, in order.
    file_blocks: Vec<usize>,
    files: String,
}

impl Problem {
    fn new(
        layout: Layout,
        blocks: Vec<Vec<Accumulator>>,
        file_blocks: Vec<usize>,
        files: String,
    ) -> Self {
        let n = layout.dof;
        let nbk = blocks.len();
        let total = merge_blocks(&blocks, n);
        // Leave-one-block-out factors from prefix and suffix merges: O(blocks) QR updates.
        let mut loo = vec![Vec::with_capacity(n); nbk];
        #[allow(clippy::needless_range_loop)]
        for j in 0..n {
            let mut prefix = vec![blocks[0][j].empty_like()];
            for b in 0..nbk {
                let mut a = prefix[b].clone();
                a.merge(&blocks[b][j]);
                prefix.push(a);
            }
            let mut suffix = vec![blocks[0][j].empty_like(); nbk + 1];
            for b in (0..nbk).rev() {
                let mut a = suffix[b + 1].clone();
                a.merge(&blocks[b][j]);
                suffix[b] = a;
            }
            for b in 0..nbk {
                let mut a = prefix[b].clone();
                a.merge(&suffix[b + 1]);
                loo[b].push(a.r().clone());
            }
        }
        Problem {
            layout,
            blocks,
            total,
            loo,
            file_blocks,
            files,
        }
    }

    /// Builds the problem of `train` (blocks proportional to each file's length, ≥ 2 per file).
    pub fn build(
        base: &BaseModel,
        layout: Layout,
        train: &[Prepared],
        target_blocks: usize,
    ) -> Self {
        let (file_blocks, files) = Self::file_blocks(train, target_blocks);
        let mut blocks = Vec::new();
        for (p, &nb) in train.iter().zip(&file_blocks) {
            blocks.extend(accumulate_fit(p, base, &layout, nb));
        }
        Problem::new(layout, blocks, file_blocks, files)
    }

    /// [`Problem::build`] of the same files prepared with each of several regression filters
    /// (`variants[v]`: the files, prepared with filter `v`), from one evaluation of each
    /// file's rows ([`accumulate_fits`]).
    pub(super) fn build_variants(
        base: &BaseModel,
        layout: &Layout,
        variants: &[&[Prepared]],
        target_blocks: usize,
    ) -> Vec<Self> {
        let Some(first) = variants.first() else {
            return Vec::new();
        };
        let (file_blocks, files) = Self::file_blocks(first, target_blocks);
        let mut blocks: Vec<Vec<Vec<Accumulator>>> = vec![Vec::new(); variants.len()];
        for (f, &nb) in file_blocks.iter().enumerate() {
            let ps: Vec<&Prepared> = variants.iter().map(|v| &v[f]).collect();
            for (b, fit) in blocks
                .iter_mut()
                .zip(accumulate_fits(&ps, base, layout, nb))
            {
                b.extend(fit);
            }
        }
        blocks
            .into_iter()
            .map(|b| Problem::new(layout.clone(), b, file_blocks.clone(), files.clone()))
            .collect()
    }

    /// Blocks per file (proportional to each file's kept length, ≥ 2) and the files' names.
    fn file_blocks(train: &[Prepared], target_blocks: usize) -> (Vec<usize>, String) {
        let total_rows: usize = train.iter().map(|p| p.keep.1 - p.keep.0).sum();
        let blocks = train
            .iter()
            .map(|p| {
                let share = (target_blocks as f64 * (p.keep.1 - p.keep.0) as f64
                    / total_rows.max(1) as f64)
                    .round() as usize;
                share.max(2)
            })
            .collect();
        let files = train
            .iter()
            .map(|p| p.name.as_str())
            .collect::<Vec<_>>()
            .join(", ");
        (blocks, files)
    }

    /// Held-out relative RMS error against the *measured* torque of the training files this
    /// problem was built from (each block predicted by the fit on the other blocks,
    /// `‖τ̂−τ‖/‖τ‖` pooled over blocks and joints) of both predictions, from one evaluation of
    /// the rows: `(from the estimated states, from the parallel-filtered rows)`.
    pub fn cv_raw_both(
        &self,
        base: &BaseModel,
        train: &[Prepared],
        subset: &[usize],
        w: &[f64],
    ) -> Result<(f64, f64), RankError> {
        let loo = self.loo_fits(subset, w)?;
        let m = [Judged {
            subset,
            x: None,
            loo: Some(&loo),
        }];
        let blocks = Some(self.raw_blocks());
        let preds = [Prediction::States, Prediction::Filtered];
        let sums = raw_sums_each(base, &self.layout, train, blocks, &m, &preds);
        Ok((sums[0].heldout(0), sums[1].heldout(0)))
    }

    /// Blocks per training file, for [`super::raw_sums`].
    pub fn raw_blocks(&self) -> &[usize] {
        &self.file_blocks
    }

    /// Parameters of every leave-one-block-out fit (an error if one is rank-deficient).
    pub fn loo_fits(&self, subset: &[usize], w: &[f64]) -> Result<Vec<Vec<f64>>, RankError> {
        self.loo_fits_from(None, subset, w)
    }

    /// [`Problem::loo_fits`], from kept QR prefixes of the left-out blocks' fits when given
    /// ([`Problem::loo_prefixes`] with the same weights; bit-identical, cheaper).
    fn loo_fits_from(
        &self,
        prefixes: Option<&[ls::Prefix]>,
        subset: &[usize],
        w: &[f64],
    ) -> Result<Vec<Vec<f64>>, RankError> {
        (0..self.blocks())
            .map(|b| {
                let f = self.loo_factors(b, w);
                match prefixes {
                    Some(p) => ls::solve_x_after(&p[b], &f, subset),
                    None => ls::solve_x(&f, subset),
                }
                .map(|(x, _)| x)
                .map_err(|e| self.rank_error(&e.dependent))
            })
            .collect()
    }

    /// Parameters fitted without each training file, one set per block (every block of a file
    /// gets the fit without that file): cross-validation by run. An error when a fit without
    /// one file is rank-deficient (that file alone excites some column).
    pub fn lofo_fits(&self, subset: &[usize], w: &[f64]) -> Result<Vec<Vec<f64>>, RankError> {
        let n = self.layout.dof;
        let mut out = Vec::with_capacity(self.blocks());
        let mut start = 0;
        for &nb in &self.file_blocks {
            let accs: Vec<Accumulator> = (0..n)
                .map(|j| {
                    let mut a = self.blocks[0][j].empty_like();
                    for (b, blk) in self.blocks.iter().enumerate() {
                        if !(start..start + nb).contains(&b) {
                            a.merge(&blk[j]);
                        }
                    }
                    a
                })
                .collect();
            let f: Vec<(&DMatrix<f64>, f64)> =
                accs.iter().zip(w).map(|(a, &w)| (a.r(), w)).collect();
            let (x, _) = ls::solve_x(&f, subset).map_err(|e| self.rank_error(&e.dependent))?;
            out.extend(std::iter::repeat_n(x, nb));
            start += nb;
        }
        Ok(out)
    }

    /// Training files.
    pub fn files(&self) -> usize {
        self.file_blocks.len()
    }

    /// The factors of all blocks but `b`, weighted by `w`.
    fn loo_factors(&self, b: usize, w: &[f64]) -> Vec<(&DMatrix<f64>, f64)> {
        self.loo[b].iter().zip(w).map(|(r, &w)| (r, w)).collect()
    }

    /// The QR of each leave-one-block-out fit over `subset` with weights `w`, kept for fits
    /// that add columns after `subset` ([`Problem::cv_sse_from`]: each candidate of a step).
    pub fn loo_prefixes(&self, subset: &[usize], w: &[f64]) -> Vec<ls::Prefix> {
        (0..self.blocks())
            .map(|b| ls::Prefix::new(&self.loo_factors(b, w), subset))
            .collect()
    }

    /// The all-blocks factors weighted by `w`, as [`ls::solve`] takes them.
    fn total_factors(&self, w: &[f64]) -> Vec<(&DMatrix<f64>, f64)> {
        self.total.iter().zip(w).map(|(a, &w)| (a.r(), w)).collect()
    }

    pub fn blocks(&self) -> usize {
        self.blocks.len()
    }

    /// Sum of squares of joint `j`'s (filtered) torque over the training set.
    pub fn target_ss(&self, j: usize) -> f64 {
        self.total[j].target_ss()
    }

    /// Base columns plus the columns of `terms`.
    pub fn subset(&self, terms: &[Term]) -> Vec<usize> {
        let fixed = &self.layout.fixed;
        let mut s: Vec<usize> = (0..self.layout.nb).filter(|c| !fixed.contains(c)).collect();
        s.extend(terms.iter().filter_map(|t| self.layout.col(t)));
        s
    }

    pub(super) fn rank_error(&self, dependent: &[usize]) -> RankError {
        RankError {
            files: self.files.clone(),
            params: dependent.iter().map(|&c| self.layout.col_name(c)).collect(),
            hint: String::new(),
        }
    }

    /// `subset` without the columns this data cannot tell apart from earlier ones (the effects
    /// come after the base parameters, so an effect goes: e.g. an offset on a vertical prismatic
    /// joint, which is its gravity load), so that a fit of every candidate at once exists.
    pub fn independent(&self, subset: &[usize]) -> Vec<usize> {
        let w = vec![1.0; self.layout.dof];
        let mut s = subset.to_vec();
        while let Err(e) = ls::solve_x(&self.total_factors(&w), &s) {
            let before = s.len();
            s.retain(|c| !e.dependent.contains(c));
            if s.len() == before {
                break;
            }
        }
        s
    }

    /// Weighted fit over the full training set.
    pub fn fit(&self, subset: &[usize], w: &[f64]) -> Result<ls::Fit, RankError> {
        ls::solve(&self.total_factors(w), subset).map_err(|e| self.rank_error(&e.dependent))
    }

    /// The weighted normal equations of `subset` over the full training set: `N = Σⱼ wⱼ²·Aⱼᵀ Aⱼ`
    /// and `Σⱼ wⱼ²·Aⱼᵀτⱼ`, in `subset` order (from the factors: `AⱼᵀAⱼ = RⱼᵀRⱼ` restricted to the
    /// columns). `(x − x̂)ᵀN(x − x̂)` is how much the weighted residual of `x` exceeds the fit's.
    pub fn normal_equations(&self, subset: &[usize], w: &[f64]) -> (DMatrix<f64>, DVector<f64>) {
        let k = subset.len();
        let (mut n, mut b) = (DMatrix::zeros(k, k), DVector::zeros(k));
        for (j, acc) in self.total.iter().enumerate() {
            let r = acc.r();
            let t = r.ncols() - 1;
            let a = DMatrix::from_fn(r.nrows(), k, |i, c| r[(i, subset[c])]);
            let w2 = w[j] * w[j];
            n += a.tr_mul(&a) * w2;
            b += a.tr_mul(&r.column(t).into_owned()) * w2;
        }
        (n, b)
    }

    /// Regression rows over all joints (after decimation).
    pub fn rows(&self) -> usize {
        self.total.iter().map(|a| a.rows()).sum()
    }

    /// Per-joint weights `1/σⱼ` from the residual of the model (OLS, then one WLS pass).
    pub fn weights(&self, subset: &[usize]) -> Result<Vec<f64>, RankError> {
        let n = self.layout.dof;
        let mut w = vec![1.0; n];
        for _ in 0..2 {
            let (x, _) = ls::solve_x(&self.total_factors(&w), subset)
                .map_err(|e| self.rank_error(&e.dependent))?;
            w = (0..n)
                .map(|j| {
                    let a = &self.total[j];
                    let rows = a.rows().max(1) as f64;
                    let scale = (a.target_ss() / rows).sqrt();
                    let s = (a.sse(subset, &x) / rows)
                        .sqrt()
                        .max(1e-9 * scale)
                        .max(1e-300);
                    1.0 / s
                })
                .collect();
        }
        Ok(w)
    }

    /// Held-out weighted SSE `[block][joint]` of leave-one-block-out refits.
    pub fn cv_sse(&self, subset: &[usize], w: &[f64]) -> Result<Vec<Vec<f64>>, RankError> {
        self.cv_sse_from(None, subset, w)
    }

    /// [`Problem::cv_sse`], from kept QR prefixes ([`Problem::loo_prefixes`] with the same
    /// weights) when given: the same numbers, bit for bit.
    pub fn cv_sse_from(
        &self,
        prefixes: Option<&[ls::Prefix]>,
        subset: &[usize],
        w: &[f64],
    ) -> Result<Vec<Vec<f64>>, RankError> {
        let n = self.layout.dof;
        let fits = self.loo_fits_from(prefixes, subset, w)?;
        Ok(fits
            .iter()
            .zip(&self.blocks)
            .map(|(x, blk)| {
                (0..n)
                    .map(|j| w[j] * w[j] * blk[j].sse(subset, x))
                    .collect()
            })
            .collect())
    }

    /// Partial correlation, on the term's joint, of the torque residual with the term's column,
    /// both taken orthogonal to the model's columns.
    pub fn partial_corr(&self, subset: &[usize], term: Term) -> Option<f64> {
        let c = self.layout.col(&term)?;
        let r = self.total[term.joint].r();
        let t = r.ncols() - 1;
        let a = DMatrix::from_fn(r.nrows(), subset.len(), |i, k| r[(i, subset[k])]);
        let svd = a.clone().svd(true, true);
        let resid = |v: DVector<f64>| -> Option<DVector<f64>> {
            let x = svd.solve(&v, 1e-10).ok()?;
            Some(v - &a * x)
        };
        let rt = resid(r.column(t).into_owned())?;
        let rc = resid(r.column(c).into_owned())?;
        let d = rt.norm() * rc.norm();
        (d > 0.0).then(|| rt.dot(&rc) / d)
    }
}

/// Adds which joints hardly move to a rank error.
pub(super) fn with_hint(mut e: RankError, train: &[Prepared]) -> RankError {
    let Some(p0) = train.first() else { return e };
    let mut hints = Vec::new();
    for j in 0..p0.dof() {
        let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
        for p in train {
            for (a, b) in cores(p, p.keep.0, p.keep.1) {
                for q in p.states(a, b).q[j].iter() {
                    (lo, hi) = (lo.min(*q), hi.max(*q));
                }
            }
        }
        if hi - lo < 1e-3 {
            hints.push(format!(
                "joint {} does not move (q{} range {:.2e})",
                j + 1,
                j + 1,
                hi - lo
            ));
        }
    }
    if !hints.is_empty() {
        e.hint = format!(" ({})", hints.join("; "));
    }
    e
}
