//! Least squares for the paper: one equation of the base regressor, a subset of the base
//! parameters, the others known (step-by-step), or everything at once (Fourier comparison).

use nalgebra::{DMatrix, DVector};

use crate::model::Model;

/// Identification failures.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum IdentError {
    #[error(
        "least squares has {rows} rows for {cols} unknowns; need more samples (widen the window δ)"
    )]
    TooFewRows { rows: usize, cols: usize },
    #[error("least-squares solve failed: {0}")]
    Solve(&'static str),
}

/// Row-major `n × dof` signals of one experiment.
pub struct Signals<'a> {
    pub dof: usize,
    pub q: &'a [f64],
    pub dq: &'a [f64],
    pub ddq: &'a [f64],
    pub tau: &'a [f64],
}

impl Signals<'_> {
    /// The base regressor at sample `k` into `yb` (`dof × nb`, row-major).
    fn base_regressor(&self, model: &dyn Model, k: usize, yb: &mut [f64]) {
        let span = k * self.dof..(k + 1) * self.dof;
        model.base_regressor(
            &self.q[span.clone()],
            &self.dq[span.clone()],
            &self.ddq[span],
            yb,
        );
    }
}

fn solve(a: DMatrix<f64>, y: DVector<f64>) -> Result<Vec<f64>, IdentError> {
    let (rows, cols) = a.shape();
    if rows < cols {
        return Err(IdentError::TooFewRows { rows, cols });
    }
    // QR is enough for these well-conditioned blocks; SVD would only matter near rank deficiency.
    let qr = a.qr();
    let qty = qr.q().transpose() * y;
    let r = qr.r();
    let x = r
        .solve_upper_triangular(&qty)
        .ok_or(IdentError::Solve("rank-deficient regressor"))?;
    Ok(x.iter().copied().collect())
}

/// Step-by-step least squares: equation `row` over the samples `idx`, unknowns `cols`; the other
/// base parameters take their values from `known` (`τ_row − Σ_known Y θ`).
pub fn step_ls(
    model: &dyn Model,
    s: &Signals,
    idx: &[usize],
    row: usize,
    cols: &[usize],
    known: &[f64],
) -> Result<Vec<f64>, IdentError> {
    let (dof, nb) = (s.dof, model.nb());
    let mut yb = vec![0.0; dof * nb];
    let mut a = DMatrix::<f64>::zeros(idx.len(), cols.len());
    let mut y = DVector::<f64>::zeros(idx.len());
    for (r, &k) in idx.iter().enumerate() {
        s.base_regressor(model, k, &mut yb);
        let line = &yb[row * nb..(row + 1) * nb];
        let mut rhs = s.tau[k * dof + row];
        for (c, &v) in line.iter().enumerate() {
            match cols.iter().position(|&u| u == c) {
                Some(i) => a[(r, i)] = v,
                None => rhs -= v * known[c],
            }
        }
        y[r] = rhs;
    }
    solve(a, y)
}

/// Ordinary least squares on all equations of the samples `idx` for all base parameters.
pub fn full_ls(model: &dyn Model, s: &Signals, idx: &[usize]) -> Result<Vec<f64>, IdentError> {
    let (dof, nb) = (s.dof, model.nb());
    let mut yb = vec![0.0; dof * nb];
    let mut a = DMatrix::<f64>::zeros(idx.len() * dof, nb);
    let mut y = DVector::<f64>::zeros(idx.len() * dof);
    for (r, &k) in idx.iter().enumerate() {
        s.base_regressor(model, k, &mut yb);
        for j in 0..dof {
            for c in 0..nb {
                a[(r * dof + j, c)] = yb[j * nb + c];
            }
            y[r * dof + j] = s.tau[k * dof + j];
        }
    }
    solve(a, y)
}

/// `max_k |a_k − b_k|`.
pub fn max_abs_diff(a: &[f64], b: &[f64]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f64::max)
}
