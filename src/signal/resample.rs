//! Uniform time grids and linear resampling onto them.

use serde::Serialize;

/// A uniform time grid `t0 + k·dt`, `k = 0..n`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Grid {
    pub t0: f64,
    pub dt: f64,
    pub n: usize,
}

impl Grid {
    pub fn time(&self, k: usize) -> f64 {
        self.t0 + k as f64 * self.dt
    }
}

/// Linear interpolation of samples `(t, x)` onto `grid` (`t` strictly increasing, grid inside).
pub fn resample_linear(t: &[f64], x: &[f64], grid: &Grid) -> Vec<f64> {
    let mut out = Vec::with_capacity(grid.n);
    let mut j = 0usize;
    for k in 0..grid.n {
        let tk = grid.time(k);
        while j + 2 < t.len() && t[j + 1] < tk {
            j += 1;
        }
        let (ta, tb) = (t[j], t[j + 1]);
        let w = ((tk - ta) / (tb - ta)).clamp(0.0, 1.0);
        out.push(x[j] + w * (x[j + 1] - x[j]));
    }
    out
}
