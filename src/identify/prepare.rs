//! Stage 1, **preparation**: one data file and its derivative estimator ([`Prepared`]), with the
//! regression filter and prediction it is used with ([`Smoothing`]). States are estimated window
//! by window ([`cores`], [`raw_cores`], [`raw_in_core`]) as each later pass needs them, never for
//! the whole log; [`PrepCache`] keeps prepared files per cut-off for scans and studies.

use std::sync::Arc;

use rayon::prelude::*;
use serde::Serialize;

use super::row_table::{GridBaseCache, RowTable};
use super::{Config, IdentifyError, MIN_SAMPLES};
use crate::derivative::{self, Estimator, Filter, States};
use crate::log::Log;

/// One data file after derivative estimation.
#[derive(Debug, Clone)]
pub struct Prepared {
    pub name: String,
    pub log: Log,
    /// The file's estimator: states are estimated window by window when needed
    /// ([`Prepared::states`]), never held for the whole log.
    pub est: Estimator,
    /// Grid samples used for the regression (filter edges dropped).
    pub keep: (usize, usize),
    /// Raw samples used for errors and predictions.
    pub raw_keep: (usize, usize),
    /// The regression filter: parallel filtering of the rows and τ (and of the predictions,
    /// if `smoothing` says so), cut-off `rfilter_hz`.
    pub rfilter: Filter,
    pub rfilter_hz: f64,
    pub smoothing: Smoothing,
    /// The unfiltered regression rows of the whole grid, when kept (the cut-off scan's, see
    /// [`RowTable`]); otherwise each pass evaluates them from the states.
    pub(super) rows: Option<Arc<RowTable>>,
}

/// How the regression rows are filtered and how a model predicts the measured torque; chosen
/// with the cut-off by held-out error against the measured torque ([`super::scan::choose_cutoff`]).
///
/// Which prediction is right depends on where the sharp features of the data live. Where the
/// motion is smooth and the torque jumps (a stiff position loop, or inverse dynamics: Coulomb
/// friction flips the torque at each velocity reversal), the rows of the estimated states
/// predict the jump. Where the torque is smooth and the motion kinks (an arm driven by smooth
/// torques: friction flips and the acceleration jumps instead), the low-passed q̈ cannot follow
/// the kink while `sgn q̇` does, and only the rows filtered like the fit's — the very rows the
/// parameters were fitted to — predict consistently. A lower regression cut-off (Gautier's
/// decimation filter below the derivative filter) keeps the derivative filter's band for the
/// states while smoothing the products of noisy states.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Smoothing {
    /// Regression filter cut-off over the derivative filter's.
    pub regression_ratio: f64,
    /// Predictions from the parallel-filtered rows (`true`) or from the rows of the estimated
    /// states (`false`).
    pub filtered_prediction: bool,
}

impl Default for Smoothing {
    fn default() -> Self {
        Smoothing {
            regression_ratio: 1.0,
            filtered_prediction: false,
        }
    }
}

impl Smoothing {
    /// Regression filter ratios the scan tries.
    pub const RATIOS: [f64; 2] = [1.0, 0.5];

    /// Parses `RATIO,states` or `RATIO,filtered` (e.g. `0.5,filtered`), ratio in (0, 1].
    pub fn parse(s: &str) -> Result<Self, String> {
        let bad = || {
            format!("`{s}` is not `auto` or RATIO,PREDICTION with RATIO in (0, 1] and PREDICTION `states` or `filtered` (e.g. `0.5,filtered`)")
        };
        let (r, p) = s.split_once(',').ok_or_else(bad)?;
        let ratio: f64 = r.trim().parse().map_err(|_| bad())?;
        if !(ratio > 0.0 && ratio <= 1.0) {
            return Err(bad());
        }
        let filtered_prediction = match p.trim() {
            "states" => false,
            "filtered" => true,
            _ => return Err(bad()),
        };
        Ok(Smoothing {
            regression_ratio: ratio,
            filtered_prediction,
        })
    }

    /// What a prediction is computed from: `states` or `filtered rows`.
    pub fn prediction_source(&self) -> &'static str {
        if self.filtered_prediction {
            "filtered rows"
        } else {
            "states"
        }
    }

    /// Short label for reports, e.g. `regression filter at 0.5·fc, prediction from filtered rows`.
    pub fn label(&self) -> String {
        format!(
            "regression filter at {}·fc, prediction from {}",
            self.regression_ratio,
            self.prediction_source()
        )
    }
}

impl Prepared {
    /// Sets up derivative estimation of a log (which must have torques) with the options of
    /// `cfg` (cut-off automatic from the spectrum unless given).
    pub fn new(log: Log, cfg: &Config) -> Result<Self, IdentifyError> {
        let s = Smoothing::default();
        Self::with_cutoff(log, cfg, cfg.derivative.cutoff_hz, s, None)
    }

    /// As [`Prepared::new`] with the cut-off `fc` (`None` = automatic), the regression filter
    /// and prediction of `smoothing`, and filter edges dropped as for a regression cut-off of
    /// `edge_fc` (default its own; a common value keeps the samples used the same when cut-offs
    /// are compared).
    pub fn with_cutoff(
        log: Log,
        cfg: &Config,
        fc: Option<f64>,
        smoothing: Smoothing,
        edge_fc: Option<f64>,
    ) -> Result<Self, IdentifyError> {
        let name = log.source.clone();
        let dof = log.dof();
        if !log.layout.tau {
            return Err(IdentifyError::NoTorque { file: name, dof });
        }
        log.require_samples(MIN_SAMPLES, "identification")?;
        let derr = |source| IdentifyError::Derivative {
            file: name.clone(),
            source,
        };
        let opts = derivative::Options {
            cutoff_hz: fc,
            ..cfg.derivative
        };
        let est = Estimator::new(&log, cfg.file_velocity, &opts).map_err(derr)?;
        Self::from_estimator(log, est, cfg, smoothing, edge_fc)
    }

    /// This file prepared at another cut-off `fc` (with `smoothing`, edges as for `edge_fc`):
    /// [`Prepared::with_cutoff`] of the same log, without reading it again.
    pub(super) fn at_cutoff(
        &self,
        cfg: &Config,
        fc: f64,
        smoothing: Smoothing,
        edge_fc: Option<f64>,
    ) -> Result<Self, IdentifyError> {
        let est = self
            .est
            .with_cutoff(cfg.derivative.method, fc)
            .map_err(|source| IdentifyError::Derivative {
                file: self.name.clone(),
                source,
            })?;
        Self::from_estimator(self.log.clone(), est, cfg, smoothing, edge_fc)
    }

    /// The regression filter and kept ranges of `log` with its estimator `est`.
    fn from_estimator(
        log: Log,
        est: Estimator,
        cfg: &Config,
        smoothing: Smoothing,
        edge_fc: Option<f64>,
    ) -> Result<Self, IdentifyError> {
        let name = log.source.clone();
        let derr = |source| IdentifyError::Derivative {
            file: name.clone(),
            source,
        };
        let g = est.grid;
        let ratio = smoothing.regression_ratio;
        let fr = est.report.cutoff_hz * ratio;
        let rfilter = if ratio == 1.0 {
            est.filter.clone()
        } else {
            Filter::lowpass(cfg.derivative.method, fr, est.report.fs_hz).map_err(derr)?
        };
        let efc = edge_fc.unwrap_or(fr).min(fr);
        let edge = ((0.5 / efc / g.dt).ceil() as usize).min(g.n / 40);
        let keep = (edge, g.n - edge);
        let (t0, t1) = (g.time(keep.0), g.time(keep.1 - 1));
        let lo = log.partition_point(|t| t < t0 - 1e-12);
        let hi = log.partition_point(|t| t <= t1 + 1e-12);
        Ok(Prepared {
            name,
            log,
            est,
            keep,
            raw_keep: (lo, hi.max(lo)),
            rfilter,
            rfilter_hz: fr,
            smoothing,
            rows: None,
        })
    }

    /// Block of grid sample `k` when the kept range is split into `nblocks`.
    pub(super) fn block_of(&self, k: usize, nblocks: usize) -> usize {
        let span = (self.keep.1 - self.keep.0).max(1);
        ((k.saturating_sub(self.keep.0)) * nblocks / span).min(nblocks - 1)
    }

    pub fn dof(&self) -> usize {
        self.log.dof()
    }

    /// Estimated states on grid samples `lo..hi`.
    pub fn states(&self, lo: usize, hi: usize) -> derivative::States {
        self.est.window(&self.log, lo, hi)
    }

    /// `(Σ f(states, i), count)` over the kept grid samples, window by window.
    /// Per joint `j`, `Σ f(states, j, i)` over the kept grid samples (windows in parallel, their
    /// sums added in order), and the number of samples.
    pub(super) fn state_sums(
        &self,
        f: impl Fn(&States, usize, usize) -> f64 + Sync,
    ) -> (Vec<f64>, usize) {
        let n = self.dof();
        let parts: Vec<Vec<f64>> = cores(self, self.keep.0, self.keep.1)
            .par_iter()
            .map(|&(a, b)| {
                let st = self.states(a, b);
                (0..n)
                    .map(|j| (0..b - a).map(|i| f(&st, j, i)).sum::<f64>())
                    .collect()
            })
            .collect();
        let mut s = vec![0.0; n];
        for part in &parts {
            for (sj, pj) in s.iter_mut().zip(part) {
                *sj += pj;
            }
        }
        (s, self.keep.1 - self.keep.0)
    }

    /// Measured torque on grid samples `lo..hi` (`tau[j][k - lo]`).
    pub(super) fn grid_tau(&self, lo: usize, hi: usize) -> Vec<Vec<f64>> {
        self.est.tau_on_grid(&self.log, lo, hi)
    }
}

/// Prepared files per (file, cut-off), so cut-off scans and leave-one-out studies reuse them.
#[derive(Debug, Default, Clone)]
pub struct PrepCache {
    map: Vec<((usize, usize), u64, Prepared)>,
    /// The scans' states and base regressor per file and cut-off (shared by clones: the folds
    /// of a study).
    pub(super) grids: GridBaseCache,
}

impl PrepCache {
    /// A cache whose clones share the scans' states and base regressor ([`GridBaseCache`]):
    /// for the folds of a study.
    pub(super) fn sharing_grids() -> Self {
        PrepCache {
            map: Vec::new(),
            grids: GridBaseCache::shared(),
        }
    }

    pub(super) fn get(
        &mut self,
        t: &Log,
        cfg: &Config,
        fc: Option<f64>,
        sm: Smoothing,
        edge_fc: Option<f64>,
    ) -> Result<Prepared, IdentifyError> {
        let key = (
            t.key(),
            fc.map_or(0, f64::to_bits)
                ^ edge_fc.map_or(1, f64::to_bits).rotate_left(17)
                ^ sm.regression_ratio.to_bits().rotate_left(31),
        );
        if let Some((_, _, p)) = self.map.iter().find(|(a, b, _)| (*a, *b) == key) {
            let mut p = p.clone();
            p.smoothing = sm;
            return Ok(p);
        }
        // A given cut-off of a file prepared before: its estimator, re-filtered (the log is not
        // read again).
        let known = self
            .map
            .iter()
            .find(|(a, _, p)| *a == key.0 && p.log.len() == t.len());
        let p = match (fc, known) {
            (Some(fc), Some((_, _, p))) => p.at_cutoff(cfg, fc, sm, edge_fc)?,
            _ => Prepared::with_cutoff(t.clone(), cfg, fc, sm, edge_fc)?,
        };
        self.map.push((key.0, key.1, p.clone()));
        Ok(p)
    }

    pub(super) fn get_all(
        &mut self,
        ts: &[Log],
        cfg: &Config,
        fc: Option<f64>,
        sm: Smoothing,
    ) -> Result<Vec<Prepared>, IdentifyError> {
        ts.iter().map(|t| self.get(t, cfg, fc, sm, None)).collect()
    }
}

/// Fewest grid samples per chunk core (plus the filter's reach on each side).
const CHUNK_CORE: usize = 8192;

/// Chunk cores covering grid samples `k0..k1` of `p`: at least twice the regression filter's
/// reach long, so the margins never cost more than the core.
pub(super) fn cores(p: &Prepared, k0: usize, k1: usize) -> Vec<(usize, usize)> {
    let core = (2 * p.rfilter.as_zero_phase().reach()).max(CHUNK_CORE);
    (k0..k1)
        .step_by(core)
        .map(|a| (a, (a + core).min(k1)))
        .collect()
}

/// Where raw sample `r`, at time `t`, lies on the grid: `(k, s)`, at `(1 − s)·k + s·(k + 1)`.
pub(super) fn grid_pos(p: &Prepared, r: usize, t: f64) -> (usize, f64) {
    let g = p.est.grid;
    if !p.est.report.resampled && g.n == p.log.len() {
        return (r, 0.0);
    }
    let u = ((t - g.t0) / g.dt).clamp(0.0, (g.n - 1) as f64);
    let k = (u.floor() as usize).min(g.n.saturating_sub(2));
    (k, u - k as f64)
}

/// First used raw sample at grid position `a` or later.
fn first_raw_from(p: &Prepared, a: usize) -> usize {
    let (mut lo, mut hi) = p.raw_keep;
    while lo < hi {
        let mid = (lo + hi) / 2;
        if grid_pos(p, mid, p.log.t(mid)).0 < a {
            lo = mid + 1;
        } else {
            hi = mid;
        }
    }
    lo
}

/// Chunk cores covering the grid positions of the used raw samples.
pub(super) fn raw_cores(p: &Prepared) -> Vec<(usize, usize)> {
    let (lo, hi) = p.raw_keep;
    if lo >= hi {
        return Vec::new();
    }
    let at = |r| grid_pos(p, r, p.log.t(r)).0;
    cores(p, at(lo), at(hi - 1) + 1)
}

/// Used raw samples of `p` whose grid position lies in the core `a..b`, every `stride`-th of
/// the used range: `(r, t, τ, grid position)` of each, from one read of the log's rows.
pub(super) fn raw_in_core(
    p: &Prepared,
    (a, b): (usize, usize),
    stride: usize,
    mut f: impl FnMut(usize, f64, &[f64], (usize, f64)),
) {
    let stride = stride.max(1);
    let (r0, r1) = (first_raw_from(p, a), first_raw_from(p, b));
    let first = r0 + (stride - (r0 - p.raw_keep.0) % stride) % stride;
    if first >= r1 {
        return;
    }
    let n = p.dof();
    let at = p
        .log
        .layout
        .tau_offset()
        .expect("prepared files have torque (checked when prepared)");
    // Straight from the log's rows (no copy into a trajectory).
    // Every `stride`-th row by a countdown (no division per row).
    let (mut r, mut skip) = (first, 0);
    p.log.rows(first, r1, |row| {
        if skip == 0 {
            let t = row[0];
            f(r, t, &row[at..at + n], grid_pos(p, r, t));
            skip = stride;
        }
        skip -= 1;
        r += 1;
    });
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn smoothing_parses_ratio_and_prediction_and_rejects_the_rest() {
        let s = Smoothing::parse("0.5, filtered").unwrap();
        assert_eq!((s.regression_ratio, s.filtered_prediction), (0.5, true));
        assert!(!Smoothing::parse("1,states").unwrap().filtered_prediction);
        for bad in ["0.5", "0,states", "1.5,states", "x,filtered", "1,raw"] {
            let e = Smoothing::parse(bad).unwrap_err();
            assert!(e.contains(bad) && e.contains("0.5,filtered"), "{e}");
        }
    }
}
