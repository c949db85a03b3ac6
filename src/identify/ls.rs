//! Streaming least squares: incremental QR of `[W | τ]` in constant memory, weighted solves of any
//! column subset from the triangular factors, condition numbers and rank diagnosis.
//!
//! An [`Accumulator`] holds the upper-triangular `R` (size `(p+1)²`) with `RᵀR = [W τ]ᵀ[W τ]` for
//! all rows pushed so far: rows are buffered in blocks and folded in by a Householder QR of
//! `[R; block]`, so a log of any length needs `O(p²)` memory and the conditioning of the problem
//! is never squared. Because `R` carries everything least squares needs, a fit of a *subset* of
//! columns, a fit with per-joint weights (stacking `wⱼ·Rⱼ`), or the error of any parameter vector
//! on the rows of one accumulator are all computed from the factors alone.

use nalgebra::{DMatrix, DVector};

/// Rows buffered before each QR update.
const BLOCK: usize = 128;

/// Incremental QR factor of `[W | τ]` (the target is the last of `cols` columns).
#[derive(Debug, Clone)]
pub struct Accumulator {
    cols: usize,
    r: DMatrix<f64>,
    buf: Vec<f64>,
    pending: usize,
    rows: usize,
}

impl Accumulator {
    /// An empty accumulator for rows of `cols` values (regressors then the target).
    pub fn new(cols: usize) -> Self {
        Accumulator {
            cols,
            r: DMatrix::zeros(cols, cols),
            buf: Vec::with_capacity(BLOCK * cols),
            pending: 0,
            rows: 0,
        }
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
        self.buf.extend_from_slice(row);
        self.pending += 1;
        self.rows += 1;
        if self.pending == BLOCK {
            self.flush();
        }
    }

    fn flush(&mut self) {
        if self.pending == 0 {
            return;
        }
        let c = self.cols;
        let block = DMatrix::from_row_slice(self.pending, c, &self.buf);
        let mut stacked = DMatrix::zeros(c + self.pending, c);
        stacked.view_mut((0, 0), (c, c)).copy_from(&self.r);
        stacked
            .view_mut((c, 0), (self.pending, c))
            .copy_from(&block);
        self.r = triangular(stacked);
        self.buf.clear();
        self.pending = 0;
    }

    /// Adds all rows of `other` (same columns).
    pub fn merge(&mut self, other: &Accumulator) {
        let mut o = other.clone();
        o.flush();
        self.flush();
        let c = self.cols;
        let mut stacked = DMatrix::zeros(2 * c, c);
        stacked.view_mut((0, 0), (c, c)).copy_from(&self.r);
        stacked.view_mut((c, 0), (c, c)).copy_from(&o.r);
        self.r = triangular(stacked);
        self.rows += other.rows;
    }

    /// The triangular factor (`(p+1) × (p+1)`), pending rows folded in.
    pub fn factor(&mut self) -> &DMatrix<f64> {
        self.flush();
        &self.r
    }

    /// The factor of a finished accumulator (call [`Accumulator::finish`] first).
    pub fn r(&self) -> &DMatrix<f64> {
        debug_assert_eq!(self.pending, 0);
        &self.r
    }

    /// Folds in buffered rows.
    pub fn finish(&mut self) {
        self.flush();
    }

    /// Sum of squares of the target column, `Σ τ²`.
    pub fn target_ss(&self) -> f64 {
        let t = self.cols - 1;
        (0..self.cols).map(|i| self.r[(i, t)].powi(2)).sum()
    }

    /// Sum of squared residuals `Σ (τ − w·x)²` of these rows for a parameter vector `x` over the
    /// columns `subset` (indices into the regressor columns).
    pub fn sse(&self, subset: &[usize], x: &[f64]) -> f64 {
        let t = self.cols - 1;
        let mut s = 0.0;
        for i in 0..self.cols {
            let mut v = self.r[(i, t)];
            for (k, &c) in subset.iter().enumerate() {
                v -= self.r[(i, c)] * x[k];
            }
            s += v * v;
        }
        s
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
        if n.is_nan() || n <= 1e-12 * maxn.max(1e-300) {
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
    use super::*;

    fn lcg(seed: &mut u64) -> f64 {
        *seed = seed
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((*seed >> 11) as f64 / (1u64 << 53) as f64) - 0.5
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
