//! Streaming least squares by normal equations, tiled (the engine of the streaming
//! identification benchmark).

use nalgebra::{DMatrix, DVector};

use super::{BenchError, SamplePool};
use crate::model::Model;

/// Streaming least squares by normal equations: `G = Σ Ybᵀ·Yb`, `b = Σ Ybᵀ·τ`, `Σ τ²`.
///
/// Memory is `O(nb²)` whatever the number of samples. Samples are buffered in blocks of
/// [`Self::BLOCK`] and folded into `G` tile by tile (`4 × 8` tiles held in registers while all
/// buffered rows stream through, as in a matrix-multiply micro-kernel). Row `i` of a serial
/// arm's base regressor is zero left of some column `start[i]` (joint i does not feel the links
/// before it, and the base parameters are ordered by link), so row `i` only touches the tiles
/// from that column on: about half the work of a dense update for a 6-DOF arm.
#[derive(Debug, Clone)]
pub struct NormalEquations {
    nb: usize,
    /// `nb` rounded up to a multiple of 8: the row stride of `g` and of the buffered rows.
    pub(super) stride: usize,
    start: Vec<usize>,
    /// `stride × stride`, row-major; the upper triangle is the result (diagonal tiles are
    /// computed whole, and the padding stays zero).
    pub(super) g: Vec<f64>,
    pub(super) b: Vec<f64>,
    tau2: f64,
    rows: usize,
    /// Buffered rows: row `i` of buffered sample `k` at `(i·BLOCK + k)·stride`, zero-padded.
    buf: Vec<f64>,
    tau: Vec<f64>,
    pending: usize,
}

/// The least-squares solution of a [`NormalEquations`] system.
#[derive(Debug, Clone)]
pub struct Solution {
    /// Identified base parameters.
    pub theta: Vec<f64>,
    /// Condition number of the column-scaled regressor, `sqrt(cond(D⁻½·G·D⁻½))`.
    pub cond: f64,
    /// Root-mean-square torque residual over all rows.
    pub rms_residual: f64,
}

const TILE_R: usize = 4;
const TILE_C: usize = 8;

/// `acc[a][l] += y[r0 + a]·y[c0 + l]` over the rows `y` of `rows` (stride `stride`): the
/// micro-kernel of [`NormalEquations`]. Written with fixed-size arrays and index loops so that
/// the compiler keeps `acc` in vector registers; not inlined, because inlined into the tile loops
/// the vectoriser combines the wrong dimensions (measured: 3× slower).
#[inline(never)]
fn tile_update(
    acc: &mut [[f64; TILE_C]; TILE_R],
    rows: &[f64],
    stride: usize,
    r0: usize,
    c0: usize,
) {
    let mut t = *acc;
    for y in rows.chunks_exact(stride) {
        let yr: [f64; TILE_R] = y[r0..r0 + TILE_R].try_into().expect("tile rows");
        let yc: [f64; TILE_C] = y[c0..c0 + TILE_C].try_into().expect("tile columns");
        for a in 0..TILE_R {
            for l in 0..TILE_C {
                t[a][l] = crate::trig::mul_add(yr[a], yc[l], t[a][l]);
            }
        }
    }
    *acc = t;
}

impl NormalEquations {
    /// Samples buffered before they are folded into `G`.
    pub const BLOCK: usize = 32;

    /// An empty system for `nb` parameters; `start[i]` is the first column that can be non-zero
    /// in row `i` of a sample, one entry per row (use `vec![0; dof]` when unknown).
    pub fn new(nb: usize, start: Vec<usize>) -> Self {
        let stride = nb.div_ceil(TILE_C) * TILE_C;
        let dof = start.len();
        NormalEquations {
            nb,
            stride,
            start,
            g: vec![0.0; stride * stride],
            b: vec![0.0; nb],
            tau2: 0.0,
            rows: 0,
            buf: vec![0.0; dof * Self::BLOCK * stride],
            tau: vec![0.0; dof * Self::BLOCK],
            pending: 0,
        }
    }

    /// First structurally non-zero column of each row of `arm`'s base regressor, found on a few
    /// random samples (a column that is zero on all of them is zero everywhere: the entries are
    /// analytic in `q, q̇, q̈`).
    pub fn row_starts(arm: &dyn Model) -> Vec<usize> {
        let (n, nb) = (arm.dof(), arm.nb());
        let pool = SamplePool::new(n, 3);
        let mut start = vec![nb; n];
        let mut yb = vec![0.0; n * nb];
        for k in 0..16 {
            arm.base_regressor(pool.q(k), pool.dq(k), pool.ddq(k), &mut yb);
            for i in 0..n {
                if let Some(j) = yb[i * nb..(i + 1) * nb].iter().position(|&v| v != 0.0) {
                    start[i] = start[i].min(j);
                }
            }
        }
        start
    }

    /// Rows added so far.
    pub fn rows(&self) -> usize {
        self.rows + self.pending * self.start.len()
    }

    /// Adds one sample: `yb` is `dof × nb` row-major (`dof = start.len()`), `tau` has `dof`
    /// entries.
    #[inline]
    pub fn add(&mut self, yb: &[f64], tau: &[f64]) {
        let (nb, stride, dof, k) = (self.nb, self.stride, self.start.len(), self.pending);
        assert!(
            yb.len() == dof * nb && tau.len() == dof,
            "sample shape does not match the system"
        );
        for i in 0..dof {
            let row = &yb[i * nb..(i + 1) * nb];
            debug_assert!(
                row[..self.start[i].min(nb)].iter().all(|&v| v == 0.0),
                "row {i} is non-zero left of its start"
            );
            let at = (i * Self::BLOCK + k) * stride;
            self.buf[at..at + nb].copy_from_slice(row);
            self.tau[i * Self::BLOCK + k] = tau[i];
        }
        self.pending += 1;
        if self.pending == Self::BLOCK {
            self.flush();
        }
    }

    /// Folds the buffered samples into `G`, `b` and `Σ τ²`.
    pub(super) fn flush(&mut self) {
        let (nb, stride, dof, n) = (self.nb, self.stride, self.start.len(), self.pending);
        if n == 0 {
            return;
        }
        for r0 in (0..stride).step_by(TILE_R) {
            for c0 in (r0 / TILE_C * TILE_C..stride).step_by(TILE_C) {
                let mut acc = [[0.0f64; TILE_C]; TILE_R];
                for i in 0..dof {
                    if self.start[i] >= r0 + TILE_R {
                        continue; // these rows of joint i are structurally zero
                    }
                    let rows = &self.buf[i * Self::BLOCK * stride..(i * Self::BLOCK + n) * stride];
                    tile_update(&mut acc, rows, stride, r0, c0);
                }
                for (a, row) in acc
                    .iter()
                    .zip(self.g[r0 * stride..].chunks_exact_mut(stride))
                {
                    for (gl, &al) in row[c0..c0 + TILE_C].iter_mut().zip(a) {
                        *gl += al;
                    }
                }
            }
        }
        for i in 0..dof {
            let taus = &self.tau[i * Self::BLOCK..i * Self::BLOCK + n];
            let rows = &self.buf[i * Self::BLOCK * stride..(i * Self::BLOCK + n) * stride];
            for (y, &t) in rows.chunks_exact(stride).zip(taus) {
                for (br, &yr) in self.b.iter_mut().zip(&y[..nb]) {
                    *br += yr * t;
                }
                self.tau2 += t * t;
            }
        }
        self.rows += n * dof;
        self.pending = 0;
    }

    /// Merges another accumulator (e.g. from another thread) of the same shape.
    pub fn merge(&mut self, other: &NormalEquations) {
        let mut other = other.clone();
        other.flush();
        self.flush();
        self.g.iter_mut().zip(&other.g).for_each(|(a, b)| *a += b);
        self.b.iter_mut().zip(&other.b).for_each(|(a, b)| *a += b);
        self.tau2 += other.tau2;
        self.rows += other.rows;
    }

    /// Solves `G·θ = b` after Jacobi scaling, with a conditioning check: a singular or
    /// ill-conditioned system (cond of the scaled regressor above `max_cond`) is an error.
    pub fn solve(&mut self, max_cond: f64) -> Result<Solution, BenchError> {
        self.flush();
        let nb = self.nb;
        let st = self.stride;
        let g = DMatrix::from_fn(nb, nb, |r, c| {
            if r <= c {
                self.g[r * st + c]
            } else {
                self.g[c * st + r]
            }
        });
        let d: Vec<f64> = (0..nb).map(|j| g[(j, j)].sqrt()).collect();
        if d.iter().any(|&x| x.is_nan() || x <= 0.0) {
            return Err(BenchError::IllConditioned {
                cond: f64::INFINITY,
            });
        }
        let gs = DMatrix::from_fn(nb, nb, |r, c| g[(r, c)] / (d[r] * d[c]));
        let eig = gs.clone().symmetric_eigenvalues();
        let (lo, hi) = eig.iter().fold((f64::INFINITY, 0.0f64), |(lo, hi), &e| {
            (lo.min(e), hi.max(e))
        });
        let cond = if lo > 0.0 {
            (hi / lo).sqrt()
        } else {
            f64::INFINITY
        };
        if cond.is_nan() || cond > max_cond {
            return Err(BenchError::IllConditioned { cond });
        }
        let bs = DVector::from_fn(nb, |r, _| self.b[r] / d[r]);
        let chol = gs.cholesky().ok_or(BenchError::IllConditioned { cond })?;
        let ts = chol.solve(&bs);
        let theta: Vec<f64> = (0..nb).map(|j| ts[j] / d[j]).collect();
        // Σ(τ − Yθ)² = Σ τ² − 2 θᵀb + θᵀGθ
        let th = DVector::from_column_slice(&theta);
        let sse =
            self.tau2 - 2.0 * th.dot(&DVector::from_column_slice(&self.b)) + th.dot(&(&g * &th));
        let rms_residual = (sse.max(0.0) / self.rows.max(1) as f64).sqrt();
        Ok(Solution {
            theta,
            cond,
            rms_residual,
        })
    }
}
