//! Streaming least squares: incremental QR of `[W | τ]` in constant memory, weighted solves of any
//! column subset from the triangular factors, condition numbers and rank diagnosis.
//!
//! An [`Accumulator`] holds the upper-triangular `R` (size `(p+1)²`) with `RᵀR = [W τ]ᵀ[W τ]` for
//! all rows pushed so far: rows are buffered in blocks and folded in by a Householder QR of
//! `[R; block]`, so a log of any length needs `O(p²)` memory and the conditioning of the problem
//! is never squared. Because `R` carries everything least squares needs, a fit of a *subset* of
//! columns, a fit with per-joint weights (stacking `wⱼ·Rⱼ`), or the error of any parameter vector
//! on the rows of one accumulator are all computed from the factors alone.

use super::dot::{self, dot};
use nalgebra::{DMatrix, DVector};

/// Rows buffered before each QR update.
const BLOCK: usize = 128;

/// Incremental QR factor of `[W | τ]` (the target is the last of `cols` columns).
///
/// Only the columns in the accumulator's *active* set are stored (rows of one joint touch only
/// the base parameters that act on it and that joint's effect columns): the factor is `k × k`
/// for `k` active columns, and [`Accumulator::r`] presents it as `k × cols` with zero columns
/// elsewhere, so fits over any column subset read it like a full factor.
#[derive(Debug, Clone)]
pub struct Accumulator {
    cols: usize,
    /// Active columns (sorted, the target `cols − 1` last).
    map: Vec<usize>,
    /// Upper-triangular `k × k` factor over the active columns, column-major.
    local: Vec<f64>,
    /// Pending rows over the active columns, column-major with stride [`BLOCK`].
    buf: Vec<f64>,
    pending: usize,
    rows: usize,
    /// `local` spread to all `cols` columns (valid when nothing is pending).
    r: DMatrix<f64>,
}

impl Accumulator {
    /// An empty accumulator for rows of `cols` values (regressors then the target).
    pub fn new(cols: usize) -> Self {
        Self::with_active(cols, (0..cols).collect())
    }

    /// An empty accumulator for rows of `cols` values of which only `active` can be non-zero
    /// (values pushed in other columns are ignored). The target column is always active.
    pub fn with_active(cols: usize, mut active: Vec<usize>) -> Self {
        active.retain(|&c| c + 1 < cols);
        active.sort_unstable();
        active.dedup();
        active.push(cols - 1);
        let k = active.len();
        Accumulator {
            cols,
            map: active,
            local: vec![0.0; k * k],
            buf: vec![0.0; k * BLOCK],
            pending: 0,
            rows: 0,
            r: DMatrix::zeros(k, cols),
        }
    }

    /// An empty accumulator with the same columns.
    pub fn empty_like(&self) -> Self {
        Self::with_active(self.cols, self.map.clone())
    }

    pub fn cols(&self) -> usize {
        self.cols
    }

    /// Rows pushed so far.
    pub fn rows(&self) -> usize {
        self.rows
    }

    /// Adds one row `[w₁ … w_p, τ]`.
    pub fn push(&mut self, row: &[f64]) {
        debug_assert_eq!(row.len(), self.cols);
        let i = self.pending;
        if self.buf.is_empty() {
            // Released by `finish`: rows after it are buffered anew.
            self.buf = vec![0.0; self.map.len() * BLOCK];
        }
        for (l, &c) in self.map.iter().enumerate() {
            self.buf[l * BLOCK + i] = row[c];
        }
        self.pending += 1;
        self.rows += 1;
        if self.pending == BLOCK {
            self.fold_pending();
        }
    }

    fn fold_pending(&mut self) {
        if self.pending == 0 {
            return;
        }
        let k = self.map.len();
        householder_update(&mut self.local, k, &mut self.buf, BLOCK, self.pending);
        self.pending = 0;
    }

    fn flush(&mut self) {
        self.fold_pending();
        let k = self.map.len();
        for (l, &c) in self.map.iter().enumerate() {
            for i in 0..k {
                self.r[(i, c)] = self.local[l * k + i];
            }
        }
    }

    /// Adds all rows of `other` (same columns).
    pub fn merge(&mut self, other: &Accumulator) {
        assert_eq!(
            self.map, other.map,
            "merging accumulators of different columns"
        );
        let mut o = other.clone();
        o.fold_pending();
        self.fold_pending();
        let k = self.map.len();
        householder_update(&mut self.local, k, &mut o.local, k, k);
        self.rows += other.rows;
        self.flush();
    }

    /// The triangular factor (`k × cols`), pending rows folded in.
    pub fn factor(&mut self) -> &DMatrix<f64> {
        self.flush();
        &self.r
    }

    /// The factor of a finished accumulator (call [`Accumulator::finish`] first).
    pub fn r(&self) -> &DMatrix<f64> {
        debug_assert_eq!(self.pending, 0);
        &self.r
    }

    /// Folds in buffered rows and releases the row buffer (a finished factor is kept for its
    /// fits, often many at once).
    pub fn finish(&mut self) {
        self.flush();
        self.buf = Vec::new();
    }

    /// Sum of squares of the target column, `Σ τ²`.
    pub fn target_ss(&self) -> f64 {
        let t = self.cols - 1;
        (0..self.r.nrows()).map(|i| self.r[(i, t)].powi(2)).sum()
    }

    /// Sum of squared residuals `Σ (τ − w·x)²` of these rows for a parameter vector `x` over the
    /// columns `subset` (indices into the regressor columns).
    pub fn sse(&self, subset: &[usize], x: &[f64]) -> f64 {
        let t = self.cols - 1;
        let mut s = 0.0;
        for i in 0..self.r.nrows() {
            let mut v = self.r[(i, t)];
            for (k, &c) in subset.iter().enumerate() {
                v -= self.r[(i, c)] * x[k];
            }
            s += v * v;
        }
        s
    }
}

/// Folds the first `m` rows of the column-major block `b` (`k` columns, column stride `ld`)
/// into the upper-triangular `k × k` column-major factor `r`: afterwards `rᵀr` has grown by
/// `bᵀb`. Householder reflections that exploit the triangle (each touches one row of `r` and
/// the block), so a row costs `≈ 2k²` flops; `b` is overwritten.
fn householder_update(r: &mut [f64], k: usize, b: &mut [f64], ld: usize, m: usize) {
    householder_taus(r, k, b, ld, m, &mut []);
}

/// [`householder_update`], recording each column's reflection (`taus[c]`, `None` for a zero
/// column) when `taus` is long enough: reflector `c` is left in column `c` of `b`, so the same
/// reflections can be applied later to further columns ([`Prefix`]).
fn householder_taus(
    r: &mut [f64],
    k: usize,
    b: &mut [f64],
    ld: usize,
    m: usize,
    taus: &mut [Option<f64>],
) {
    for c in 0..k {
        let (left, right) = b.split_at_mut((c + 1) * ld);
        let v = &mut left[c * ld..c * ld + m];
        let tau = reflector(r, k, v, c);
        if let Some(t) = taus.get_mut(c) {
            *t = tau;
        }
        let Some(tau) = tau else { continue };
        // Later columns four at a time: their dot products with the reflector in one sweep
        // (`dots`: `v` read once, four chains of sums side by side, each summed as `dot` sums).
        let mut l = c + 1;
        while l < k {
            let g = (k - l).min(4);
            let col = |i: usize| (l + i - c - 1) * ld;
            let mut d = [0.0; 4];
            let sets: [&[f64]; 4] = std::array::from_fn(|i| &right[col(i.min(g - 1))..][..m]);
            dot::dots(v, &sets[..g], &mut d);
            for (i, d) in d[..g].iter().enumerate() {
                let at = col(i);
                reflect(tau, v, &mut r[(l + i) * k + c], &mut right[at..at + m], *d);
            }
            l += g;
        }
    }
}

/// Forms the reflection of column `c` (`v`, the block's part of it, and row `c` of `r`): `v`
/// becomes the reflector, `r[c, c]` the diagonal; `None` when `v` is zero (nothing to do).
/// H = I − τ·u·uᵀ with u = [1; v / (x0 − α)], τ = (α − x0)/α.
fn reflector(r: &mut [f64], k: usize, v: &mut [f64], c: usize) -> Option<f64> {
    let x0 = r[c * k + c];
    let sb = dot(v, v);
    if sb == 0.0 {
        return None;
    }
    let norm = (x0 * x0 + sb).sqrt();
    let alpha = if x0 > 0.0 { -norm } else { norm };
    let v0 = x0 - alpha;
    let inv = 1.0 / v0;
    for e in v.iter_mut() {
        *e *= inv;
    }
    r[c * k + c] = alpha;
    Some((alpha - x0) / alpha)
}

/// Applies a reflection (τ, reflector `v`) to a later column: its entry `r_lc` in the reflected
/// row of `r` and its block part `col`, whose dot product with `v` is `vc`.
fn reflect(tau: f64, v: &[f64], r_lc: &mut f64, col: &mut [f64], vc: f64) {
    let s = tau * (*r_lc + vc);
    *r_lc -= s;
    for (y, &x) in col.iter_mut().zip(v.iter()) {
        *y -= s * x;
    }
}

/// `R` of the QR of `m` (rows ≥ cols), as a square `cols × cols` upper-triangular matrix.
pub fn triangular(m: DMatrix<f64>) -> DMatrix<f64> {
    let c = m.ncols();
    let r = m.qr().r();
    let mut out = DMatrix::zeros(c, c);
    let k = r.nrows().min(c);
    out.view_mut((0, 0), (k, c)).copy_from(&r.rows(0, k));
    out
}

/// Result of a weighted least-squares fit over a column subset.
#[derive(Debug, Clone)]
pub struct Fit {
    /// The columns fitted (indices into the regressor columns).
    pub subset: Vec<usize>,
    pub x: Vec<f64>,
    /// Weighted residual sum of squares.
    pub wsse: f64,
    /// Singular values of the column-scaled weighted regressor, largest first.
    pub singular: Vec<f64>,
    /// Condition number of the weighted regressor (unscaled columns).
    pub cond: f64,
    /// `(RᵀR)⁻¹` of the weighted regressor: parameter covariance up to the residual variance.
    pub inv_normal: DMatrix<f64>,
}

/// Why a subset cannot be fitted.
#[derive(Debug, Clone, PartialEq)]
pub struct RankDeficient {
    /// Columns (indices into the regressor columns) that are combinations of earlier ones in
    /// this data.
    pub dependent: Vec<usize>,
}

/// Relative tolerance below which a column counts as a combination of the previous ones.
pub const RANK_TOL: f64 = 1e-7;

/// Weighted least squares over `subset` from per-group factors: minimises
/// `Σ_g w_g² ‖W_g x − τ_g‖²` by a QR of the stacked `w_g · R_g[:, subset ∪ τ]`.
pub fn solve(factors: &[(&DMatrix<f64>, f64)], subset: &[usize]) -> Result<Fit, RankDeficient> {
    let stacked = stack(factors, subset);
    let s = subset.len();
    // Column scaling to unit norm: the rank test and the condition number must not depend on
    // units (kg·m² next to N·m).
    let norms: Vec<f64> = (0..s).map(|k| stacked.column(k).norm()).collect();
    let dependent = dependent_columns(&stacked.columns(0, s).into_owned(), &norms);
    if !dependent.is_empty() {
        return Err(RankDeficient {
            dependent: dependent.iter().map(|&k| subset[k]).collect(),
        });
    }
    let mut scaled = stacked.clone();
    #[allow(clippy::needless_range_loop)]
    for k in 0..s {
        let n = norms[k];
        scaled.column_mut(k).scale_mut(1.0 / n);
    }
    let r = triangular(scaled);
    let rs = r.view((0, 0), (s, s)).into_owned();
    let rhs = r.view((0, s), (s, 1)).into_owned();
    let y = rs.solve_upper_triangular(&rhs).ok_or(RankDeficient {
        dependent: Vec::new(),
    })?;
    let x: Vec<f64> = (0..s).map(|k| y[k] / norms[k]).collect();
    let wsse = r[(s, s)].powi(2);
    let singular = {
        let mut v: Vec<f64> = rs
            .clone()
            .svd(false, false)
            .singular_values
            .iter()
            .copied()
            .collect();
        v.sort_by(|a, b| b.total_cmp(a));
        v
    };
    let cond = {
        let rr = triangular(stacked.columns(0, s).into_owned());
        let sv = rr.svd(false, false).singular_values;
        let (mx, mn) = (sv.max(), sv.min());
        if mn > 0.0 {
            mx / mn
        } else {
            f64::INFINITY
        }
    };
    // (RᵀR)⁻¹ in original units: D⁻¹ (RsᵀRs)⁻¹ D⁻¹ with D = diag(norms).
    let rinv = rs.clone().try_inverse().ok_or(RankDeficient {
        dependent: Vec::new(),
    })?;
    let mut inv = &rinv * rinv.transpose();
    for i in 0..s {
        for j in 0..s {
            inv[(i, j)] /= norms[i] * norms[j];
        }
    }
    Ok(Fit {
        subset: subset.to_vec(),
        x,
        wsse,
        singular,
        cond,
        inv_normal: inv,
    })
}

/// The parameters and weighted residual sum of squares of [`solve`], without the condition
/// number and covariance (for the many refits of held-out tests). The rank test is the same:
/// with unit-norm columns the QR diagonal `|R_kk|` is the norm of column `k` orthogonal to the
/// previous ones, the quantity [`dependent_columns`] tests; when one falls below
/// [`RANK_TOL`], [`dependent_columns`] names the culprits.
pub fn solve_x(
    factors: &[(&DMatrix<f64>, f64)],
    subset: &[usize],
) -> Result<(Vec<f64>, f64), RankDeficient> {
    let s = subset.len();
    let c = s + 1;
    let mut stacked = stack(factors, subset);
    let rows = stacked.nrows();
    let norms: Vec<f64> = (0..s).map(|k| stacked.column(k).norm()).collect();
    let fallback = || RankDeficient {
        dependent: dependent_columns(&stack(factors, subset).columns(0, s).into_owned(), &norms)
            .iter()
            .map(|&k| subset[k])
            .collect(),
    };
    if any_degenerate(&norms) {
        return Err(fallback());
    }
    // nalgebra's storage is column-major: the QR below works on it in place.
    let m = stacked.as_mut_slice();
    scale_columns(m, rows, &norms);
    let mut r = vec![0.0; c * c];
    householder_update(&mut r, c, m, rows, rows);
    if (0..s).any(|k| r[k * c + k].abs() < RANK_TOL) {
        let e = fallback();
        if !e.dependent.is_empty() {
            return Err(e);
        }
    }
    Ok(back_substitute(&r, s, &norms))
}

/// `x` and the weighted residual sum of squares from the `(s+1)²` factor of the column-scaled
/// stacked problem (`norms`: the scales).
fn back_substitute(r: &[f64], s: usize, norms: &[f64]) -> (Vec<f64>, f64) {
    let c = s + 1;
    // Back substitution R_s y = rhs.
    let mut y = vec![0.0; s];
    for i in (0..s).rev() {
        let mut v = r[s * c + i];
        for k in i + 1..s {
            v -= r[k * c + i] * y[k];
        }
        y[i] = v / r[i * c + i];
    }
    let x = (0..s).map(|k| y[k] / norms[k]).collect();
    (x, r[s * c + s].powi(2))
}

/// The QR of [`solve_x`]'s stacked factors over the first columns of a fit, kept so that fits
/// adding columns after them (each candidate of a selection step, on each left-out block)
/// apply its reflections to the new columns only: per column the same operations in the same
/// order as [`solve_x`] on the whole subset, so [`solve_x_after`] returns bit-identical results
/// at a fraction of the cost (a 40-column prefix: ~2 columns of work instead of 41).
pub struct Prefix {
    subset: Vec<usize>,
    rows: usize,
    norms: Vec<f64>,
    /// The reflectors, `rows × s` column-major.
    q: Vec<f64>,
    taus: Vec<Option<f64>>,
    /// The prefix's `s × s` factor, column-major.
    r: Vec<f64>,
}

impl Prefix {
    /// The QR of `factors` (weighted) over the columns `subset`.
    pub fn new(factors: &[(&DMatrix<f64>, f64)], subset: &[usize]) -> Prefix {
        let s = subset.len();
        let stacked = stack(factors, subset);
        let rows = stacked.nrows();
        let norms: Vec<f64> = (0..s).map(|k| stacked.column(k).norm()).collect();
        let mut q = stacked.as_slice()[..rows * s].to_vec();
        scale_columns(&mut q, rows, &norms);
        let (mut r, mut taus) = (vec![0.0; s * s], vec![None; s]);
        householder_taus(&mut r, s, &mut q, rows, rows, &mut taus);
        Prefix {
            subset: subset.to_vec(),
            rows,
            norms,
            q,
            taus,
            r,
        }
    }
}

/// [`solve_x`] of `subset` on the same `factors` as `prefix`, from the prefix's reflections when
/// `subset` starts with its columns (otherwise, or when the fit is rank-deficient, by
/// [`solve_x`] itself): bit-identical to `solve_x(factors, subset)`.
pub fn solve_x_after(
    prefix: &Prefix,
    factors: &[(&DMatrix<f64>, f64)],
    subset: &[usize],
) -> Result<(Vec<f64>, f64), RankDeficient> {
    let (s0, s) = (prefix.subset.len(), subset.len());
    let c = s + 1;
    let rows: usize = factors.iter().map(|(r, _)| r.nrows()).sum();
    if !subset.starts_with(&prefix.subset) || rows < c || rows != prefix.rows {
        return solve_x(factors, subset);
    }
    let mut m = stack(factors, &subset[s0..]);
    let mut norms = prefix.norms.clone();
    norms.extend((0..s - s0).map(|k| m.column(k).norm()));
    if any_degenerate(&norms) {
        return solve_x(factors, subset);
    }
    let m = m.as_mut_slice();
    scale_columns(m, rows, &norms[s0..]);
    let mut r = vec![0.0; c * c];
    for l in 0..s0 {
        r[l * c..l * c + l + 1].copy_from_slice(&prefix.r[l * s0..l * s0 + l + 1]);
    }
    // The prefix's reflections on each new column, in order; then the new columns' own.
    for l in s0..c {
        let col = &mut m[(l - s0) * rows..(l - s0 + 1) * rows];
        for (k, tau) in prefix.taus.iter().enumerate() {
            if let Some(tau) = *tau {
                let q = &prefix.q[k * rows..(k + 1) * rows];
                let vc = dot(q, col);
                reflect(tau, q, &mut r[l * c + k], col, vc);
            }
        }
    }
    for k in s0..c {
        let (left, right) = m.split_at_mut((k - s0 + 1) * rows);
        let v = &mut left[(k - s0) * rows..];
        let Some(tau) = reflector(&mut r, c, v, k) else {
            continue;
        };
        for l in k + 1..c {
            let col = &mut right[(l - k - 1) * rows..(l - k) * rows];
            let vc = dot(v, col);
            reflect(tau, v, &mut r[l * c + k], col, vc);
        }
    }
    if (0..s).any(|k| r[k * c + k].abs() < RANK_TOL) {
        return solve_x(factors, subset);
    }
    Ok(back_substitute(&r, s, &norms))
}

/// A column norm that is NaN or negligible next to the largest (`maxn`): the column carries
/// nothing this data can use.
fn degenerate(n: f64, maxn: f64) -> bool {
    n.is_nan() || n <= 1e-12 * maxn.max(1e-300)
}

/// Whether any of `norms` is [`degenerate`].
fn any_degenerate(norms: &[f64]) -> bool {
    let maxn = norms.iter().copied().fold(0.0, f64::max);
    norms.iter().any(|&n| degenerate(n, maxn))
}

/// Scales column `k` of the column-major `m` (`rows` long columns) by `1 / norms[k]`.
fn scale_columns(m: &mut [f64], rows: usize, norms: &[f64]) {
    for (k, n) in norms.iter().enumerate() {
        let inv = 1.0 / n;
        for v in &mut m[k * rows..(k + 1) * rows] {
            *v *= inv;
        }
    }
}

/// Stacks `w_g · R_g[:, subset ∪ τ]` (τ last).
fn stack(factors: &[(&DMatrix<f64>, f64)], subset: &[usize]) -> DMatrix<f64> {
    let s = subset.len();
    let rows: usize = factors.iter().map(|(r, _)| r.nrows()).sum();
    let mut m = DMatrix::zeros(rows.max(s + 1), s + 1);
    let mut off = 0;
    for (r, w) in factors {
        let t = r.ncols() - 1;
        for i in 0..r.nrows() {
            for (k, &c) in subset.iter().enumerate() {
                m[(off + i, k)] = w * r[(i, c)];
            }
            m[(off + i, s)] = w * r[(i, t)];
        }
        off += r.nrows();
    }
    m
}

/// Greedy in column order: a column is dependent when its component orthogonal to the kept
/// columns is below [`RANK_TOL`] of its norm (zero columns are always dependent).
pub fn dependent_columns(a: &DMatrix<f64>, norms: &[f64]) -> Vec<usize> {
    let maxn = norms.iter().copied().fold(0.0, f64::max);
    let mut basis: Vec<DVector<f64>> = Vec::new();
    let mut dep = Vec::new();
    #[allow(clippy::needless_range_loop)]
    for k in 0..a.ncols() {
        let n = norms[k];
        if degenerate(n, maxn) {
            dep.push(k);
            continue;
        }
        let mut v = a.column(k) / n;
        for _ in 0..2 {
            for b in &basis {
                let d = b.dot(&v);
                v.axpy(-d, b, 1.0);
            }
        }
        let r = v.norm();
        if r < RANK_TOL {
            dep.push(k);
        } else {
            basis.push(v / r);
        }
    }
    dep
}

/// `Φ⁻¹(p)` of the standard normal (Acklam's rational approximation, |error| < 1.2e-9).
#[allow(clippy::excessive_precision)]
pub fn normal_quantile(p: f64) -> f64 {
    let p = p.clamp(1e-300, 1.0 - 1e-16);
    const A: [f64; 6] = [
        -3.969683028665376e1,
        2.209460984245205e2,
        -2.759285104469687e2,
        1.383577518672690e2,
        -3.066479806614716e1,
        2.506628277459239,
    ];
    const B: [f64; 5] = [
        -5.447609879822406e1,
        1.615858368580409e2,
        -1.556989798598866e2,
        6.680131188771972e1,
        -1.328068155288572e1,
    ];
    const C: [f64; 6] = [
        -7.784894002430293e-3,
        -3.223964580411365e-1,
        -2.400758277161838,
        -2.549732539343734,
        4.374664141464968,
        2.938163982698783,
    ];
    const D: [f64; 4] = [
        7.784695709041462e-3,
        3.224671290700398e-1,
        2.445134137142996,
        3.754408661907416,
    ];
    let pl = 0.02425;
    if p < pl {
        let q = (-2.0 * p.ln()).sqrt();
        (((((C[0] * q + C[1]) * q + C[2]) * q + C[3]) * q + C[4]) * q + C[5])
            / ((((D[0] * q + D[1]) * q + D[2]) * q + D[3]) * q + 1.0)
    } else if p <= 1.0 - pl {
        let q = p - 0.5;
        let r = q * q;
        (((((A[0] * r + A[1]) * r + A[2]) * r + A[3]) * r + A[4]) * r + A[5]) * q
            / (((((B[0] * r + B[1]) * r + B[2]) * r + B[3]) * r + B[4]) * r + 1.0)
    } else {
        -normal_quantile(1.0 - p)
    }
}

/// Upper quantile `t_{1−α}` of Student's t with `nu` degrees of freedom (Cornish–Fisher
/// expansion around the normal quantile; within 1 % for ν ≥ 5 at the levels used here).
pub fn t_quantile(p: f64, nu: f64) -> f64 {
    let z = normal_quantile(p);
    let (z3, z5, z7) = (z.powi(3), z.powi(5), z.powi(7));
    z + (z3 + z) / (4.0 * nu)
        + (5.0 * z5 + 16.0 * z3 + 3.0 * z) / (96.0 * nu * nu)
        + (3.0 * z7 + 19.0 * z5 + 17.0 * z3 - 15.0 * z) / (384.0 * nu.powi(3))
}

#[cfg(test)]
mod tests {
    use super::super::dot::tests::lcg;
    use super::*;

    #[test]
    fn fits_from_a_kept_prefix_are_bit_identical_to_whole_fits() {
        // Three groups (joints) with active subsets, as the identification stacks them.
        let mut seed = 11u64;
        let cols = 9;
        let mut accs: Vec<Accumulator> = [vec![0, 1, 2, 5, 6], vec![0, 1, 3, 7], vec![1, 2, 4, 8]]
            .into_iter()
            .map(|a| Accumulator::with_active(cols + 1, a))
            .collect();
        for acc in &mut accs {
            for _ in 0..300 {
                let row: Vec<f64> = (0..=cols).map(|_| lcg(&mut seed)).collect();
                acc.push(&row);
            }
            acc.finish();
        }
        let f: Vec<(&DMatrix<f64>, f64)> = accs
            .iter()
            .zip([1.0, 2.5, 0.3])
            .map(|(a, w)| (a.r(), w))
            .collect();
        let prefix = Prefix::new(&f, &[0, 1, 2, 3]);
        for extra in [vec![], vec![5], vec![8, 4], vec![6, 7, 5]] {
            let subset: Vec<usize> = [0, 1, 2, 3].iter().chain(&extra).copied().collect();
            let whole = solve_x(&f, &subset).unwrap();
            let after = solve_x_after(&prefix, &f, &subset).unwrap();
            assert_eq!(whole.0, after.0, "{extra:?}");
            assert_eq!(whole.1.to_bits(), after.1.to_bits());
        }
        // Not starting with the prefix, or a column no row touches: the same answer as whole.
        assert_eq!(
            solve_x(&f, &[1, 0, 5]).unwrap().0,
            solve_x_after(&prefix, &f, &[1, 0, 5]).unwrap().0
        );
        let mut zero = Accumulator::with_active(cols + 1, vec![0, 1]);
        for _ in 0..20 {
            let mut row: Vec<f64> = (0..=cols).map(|_| lcg(&mut seed)).collect();
            row[1] = 2.0 * row[0];
            zero.push(&row);
        }
        zero.finish();
        let g = [(zero.r(), 1.0)];
        let p2 = Prefix::new(&g, &[0]);
        assert_eq!(
            solve_x_after(&p2, &g, &[0, 1]).unwrap_err(),
            solve_x(&g, &[0, 1]).unwrap_err()
        );
    }

    #[test]
    fn streaming_qr_equals_batch_least_squares() {
        let mut s = 7u64;
        let (n, p) = (1000, 4);
        let truth = [1.5, -2.0, 0.25, 4.0];
        let mut acc = Accumulator::new(p + 1);
        let mut w = DMatrix::zeros(n, p);
        let mut y = DVector::zeros(n);
        for i in 0..n {
            let row: Vec<f64> = (0..p).map(|_| lcg(&mut s)).collect();
            let t: f64 =
                row.iter().zip(&truth).map(|(a, b)| a * b).sum::<f64>() + 0.01 * lcg(&mut s);
            for k in 0..p {
                w[(i, k)] = row[k];
            }
            y[i] = t;
            let mut full = row.clone();
            full.push(t);
            acc.push(&full);
        }
        acc.finish();
        let fit = solve(&[(acc.r(), 1.0)], &[0, 1, 2, 3]).unwrap();
        let batch = (w.transpose() * &w)
            .cholesky()
            .unwrap()
            .solve(&(w.transpose() * &y));
        for k in 0..p {
            assert!((fit.x[k] - batch[k]).abs() < 1e-10);
        }
        let resid = &y - &w * DVector::from_vec(fit.x.clone());
        assert!((fit.wsse - resid.norm_squared()).abs() < 1e-10);
        assert!((acc.sse(&[0, 1, 2, 3], &fit.x) - fit.wsse).abs() < 1e-10);
        assert!((acc.target_ss() - y.norm_squared()).abs() < 1e-9);
        // A subset from the same factor equals a fit of those columns alone.
        let sub = solve(&[(acc.r(), 1.0)], &[0, 3]).unwrap();
        let w2 = DMatrix::from_columns(&[w.column(0), w.column(3)]);
        let b2 = (w2.transpose() * &w2)
            .cholesky()
            .unwrap()
            .solve(&(w2.transpose() * &y));
        assert!((sub.x[0] - b2[0]).abs() < 1e-10 && (sub.x[1] - b2[1]).abs() < 1e-10);
    }

    #[test]
    fn weighted_groups_equal_scaled_rows_and_merge_is_exact() {
        let mut s = 3u64;
        let mut a = Accumulator::new(3);
        let mut b = Accumulator::new(3);
        let mut both = Accumulator::new(3);
        for i in 0..300 {
            let r = [lcg(&mut s), lcg(&mut s), lcg(&mut s)];
            if i % 2 == 0 {
                a.push(&r);
                both.push(&r);
            } else {
                b.push(&r);
                both.push(&[2.0 * r[0], 2.0 * r[1], 2.0 * r[2]]);
            }
        }
        a.finish();
        b.finish();
        both.finish();
        let f1 = solve(&[(a.r(), 1.0), (b.r(), 2.0)], &[0, 1]).unwrap();
        let f2 = solve(&[(both.r(), 1.0)], &[0, 1]).unwrap();
        assert!((f1.x[0] - f2.x[0]).abs() < 1e-12 && (f1.wsse - f2.wsse).abs() < 1e-10);
        let mut m = a.clone();
        m.merge(&b);
        assert_eq!(m.rows(), 300);
        assert!((m.target_ss() - a.target_ss() - b.target_ss()).abs() < 1e-10);
    }

    #[test]
    fn lean_solve_equals_full_solve() {
        let mut s = 11u64;
        let mut a = Accumulator::with_active(6, vec![0, 1, 3]);
        let mut b = Accumulator::new(6);
        for _ in 0..400 {
            let r: Vec<f64> = (0..6).map(|_| lcg(&mut s)).collect();
            a.push(&r);
            b.push(&r);
        }
        a.finish();
        b.finish();
        for subset in [vec![0, 1, 3], vec![1, 2, 4], vec![0, 1, 2, 3, 4]] {
            let f = [(a.r(), 1.5), (b.r(), 0.5)];
            let full = solve(&f, &subset).unwrap();
            let (x, wsse) = solve_x(&f, &subset).unwrap();
            for (u, v) in x.iter().zip(&full.x) {
                assert!((u - v).abs() < 1e-12, "{subset:?}: {u} vs {v}");
            }
            assert!((wsse - full.wsse).abs() < 1e-10 * full.wsse);
        }
        // Inactive columns of `a` are zero: alone they are dependent.
        assert_eq!(
            solve_x(&[(a.r(), 1.0)], &[0, 2]).unwrap_err().dependent,
            vec![2]
        );
    }

    #[test]
    fn compact_accumulator_equals_full_one() {
        let mut s = 5u64;
        let mut a = Accumulator::with_active(5, vec![0, 2]);
        let mut b = Accumulator::new(5);
        for _ in 0..333 {
            let r = [lcg(&mut s), 0.0, lcg(&mut s), 0.0, lcg(&mut s)];
            a.push(&r);
            b.push(&r);
        }
        a.finish();
        b.finish();
        let x = [0.7, -1.3];
        assert!((a.sse(&[0, 2], &x) - b.sse(&[0, 2], &x)).abs() < 1e-10);
        assert!((a.target_ss() - b.target_ss()).abs() < 1e-10);
        let (fa, fb) = (
            solve(&[(a.r(), 1.0)], &[0, 2]).unwrap(),
            solve(&[(b.r(), 1.0)], &[0, 2]).unwrap(),
        );
        assert!((fa.x[0] - fb.x[0]).abs() < 1e-12 && (fa.x[1] - fb.x[1]).abs() < 1e-12);
    }

    #[test]
    fn collinear_columns_are_named() {
        let mut acc = Accumulator::new(4);
        let mut s = 1u64;
        for _ in 0..50 {
            let (u, v) = (lcg(&mut s), lcg(&mut s));
            acc.push(&[u, 2.0 * u, v, u + v]);
        }
        acc.finish();
        let err = solve(&[(acc.r(), 1.0)], &[0, 1, 2]).unwrap_err();
        assert_eq!(err.dependent, vec![1]);
        let mut zero = Accumulator::new(3);
        for _ in 0..10 {
            zero.push(&[lcg(&mut s), 0.0, 1.0]);
        }
        zero.finish();
        assert_eq!(
            solve(&[(zero.r(), 1.0)], &[0, 1]).unwrap_err().dependent,
            vec![1]
        );
    }

    #[test]
    fn quantiles_match_tables() {
        assert!((normal_quantile(0.975) - 1.959964).abs() < 1e-5);
        assert!((normal_quantile(0.999) - 3.090232).abs() < 1e-5);
        assert!((t_quantile(0.975, 10.0) - 2.228).abs() < 0.01);
        assert!((t_quantile(0.999, 20.0) - 3.552).abs() < 0.04);
    }
}
