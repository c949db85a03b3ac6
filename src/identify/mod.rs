//! Identification from measured or simulated data: base-parameter least squares, the residual →
//! effect loop (see [`crate::effects`]) and everything a report needs.
//!
//! Pipeline of [`run`] (every step is reported):
//! 1. **Derivatives** per file ([`crate::derivative::Estimator`], run window by window on the
//!    file's [`Log`] as each pass needs them, so neither a long log nor its states are ever held
//!    whole — a long log lives in a temporary file): uneven sampling is resampled to
//!    a uniform grid, q is low-passed with a zero-phase filter whose cut-off is chosen from the
//!    spectrum, q̇/q̈ come from central differences (a q̇ column in the file is used, filtered,
//!    and differentiated for q̈). Files with both q̇ and q̈ are used as given.
//! 2. **Regression** with *parallel filtering*: on each file's uniform grid the rows
//!    `[Yb(q,q̇,q̈) | effect columns | τ]` are filtered column by column with a zero-phase
//!    *regression filter* (also τ) of the same kind as the derivative filter, at its cut-off or
//!    half of it ([`Smoothing`]), in overlapping chunks so memory does not grow with the log
//!    length, kept at [`KEEP_RATE_PER_CUTOFF`] times the regression cut-off (Gautier's
//!    decimation: nothing above a few cut-offs survives the filter) and folded into
//!    incremental QR factors ([`ls::Accumulator`]) per joint and per time block; a joint's
//!    factor holds only the columns that can be non-zero in its rows. Filter edges are
//!    dropped. Several files are fitted together, each filtered on its own.
//! 3. **Weighted least squares**: each joint's rows are weighted by the inverse of its residual
//!    standard deviation (two passes), solved by QR over the stacked factors. Parameter standard
//!    deviations come from a block jackknife over the time blocks (honest under the residual
//!    autocorrelation that filtering creates), reported also as %σ = 100·σ/|θ|. No physical
//!    consistency constraints are imposed (plain least squares); the condition number of the
//!    weighted regressor is reported.
//! 4. **Errors** are computed against the torque *as measured in the file* (unfiltered), at
//!    every one of the file's own sample times, by predicting each reported model directly
//!    ([`raw_sums`]) from the rows of the estimated states or from the parallel-filtered rows
//!    (whichever [`Smoothing`] the scan chose; rows interpolated between grid samples):
//!    relative RMS per joint `‖τ̂ⱼ−τⱼ‖/‖τⱼ‖` and overall `‖τ̂−τ‖/‖τ‖`, for the declared
//!    (rigid) and the augmented model, on training and validation data, and held out (each
//!    time block predicted by the fit without it).
//!
//! The automatic cut-off ([`choose_cutoff`]) scans candidates and smoothings by that held-out
//! error; training sets over [`SCAN_SAMPLES`] samples are scanned on evenly spaced pieces
//! ([`scan_pieces`]). Load-dependent effects ([`Effect::LOADED`]) are searched in a second
//! stage on top of the first stage's model (their columns hold its torque); when one is found,
//! the scan is repeated with it in its models ([`LoadModel`]).

pub mod base;
pub mod ls;
pub mod synth;

use std::sync::Arc;

use nalgebra::{DMatrix, DVector};
use rayon::prelude::*;
use serde::Serialize;

use crate::arms::ArmSource;
use crate::derivative::{self, DerivativeReport, Estimator, Filter, States};
use crate::effects::{self, Effect, EffectsSpec, Rules, Scales, Selection, Term};
use crate::log::{Log, Table, TableWriter, SPILL_ROWS};
use base::BaseModel;
use ls::Accumulator;

/// Fewest samples per file.
pub const MIN_SAMPLES: usize = 64;

/// Why identification could not run. Nothing is written when this is returned.
#[derive(Debug, thiserror::Error)]
pub enum IdentifyError {
    #[error(transparent)]
    Data(#[from] crate::data::DataError),
    #[error("{file}: {source}")]
    Derivative {
        file: String,
        source: derivative::DerivativeError,
    },
    #[error("{file}: no torque columns — identification needs measured torques tau1..tau{dof}")]
    NoTorque { file: String, dof: usize },
    #[error("{file}: the file is for {found} joints but the arm has {dof}")]
    Dof {
        file: String,
        found: usize,
        dof: usize,
    },
    #[error(transparent)]
    Rank(#[from] RankError),
    #[error("{0}")]
    Effects(String),
    #[error("cannot write a temporary file (validation predictions of a long log): {0} — free space in the temporary directory or point TMPDIR elsewhere")]
    Spill(std::io::Error),
}

/// Rank-deficient excitation: some parameters cannot be told apart with the given data.
#[derive(Debug, Clone, PartialEq)]
pub struct RankError {
    pub files: String,
    /// The parameters whose columns depend on earlier ones, e.g. `MX2`, `coulomb1`.
    pub params: Vec<String>,
    /// Which joints hardly move, if any (starts with a space).
    pub hint: String,
}

impl std::fmt::Display for RankError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let names = self
            .params
            .iter()
            .map(|p| format!("`{p}`"))
            .collect::<Vec<_>>()
            .join(", ");
        write!(
            f,
            "rank-deficient excitation in {}: {} cannot be identified (each is a combination of the other columns in this data){} — record a trajectory that moves every joint through a wide range with changing velocity",
            self.files, names, self.hint
        )
    }
}

impl std::error::Error for RankError {}

/// Options of [`run`].
#[derive(Debug, Clone, PartialEq)]
pub struct Config {
    pub derivative: derivative::Options,
    /// Use a q̇ column of the file (filtered) instead of differentiating q.
    pub file_velocity: bool,
    pub effects: EffectsSpec,
    pub rules: Rules,
    /// Number of time blocks over all training files (for held-out tests and the jackknife).
    pub blocks: usize,
    /// Regression filter and prediction; `None` = chosen by the scan with the cut-off.
    pub smoothing: Option<Smoothing>,
}

impl Default for Config {
    fn default() -> Self {
        Config {
            derivative: derivative::Options::default(),
            file_velocity: true,
            effects: EffectsSpec::Auto,
            rules: Rules::default(),
            blocks: 20,
            smoothing: None,
        }
    }
}

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
}

/// How the regression rows are filtered and how a model predicts the measured torque; chosen
/// with the cut-off by held-out error against the measured torque ([`choose_cutoff`]).
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
        })
    }

    /// Every how many grid samples a filtered regression row is kept.
    fn decimation(&self) -> usize {
        let r = self.est.report.fs_hz / (KEEP_RATE_PER_CUTOFF * self.rfilter_hz);
        (r.floor() as usize).max(1)
    }

    /// Block of grid sample `k` when the kept range is split into `nblocks`.
    fn block_of(&self, k: usize, nblocks: usize) -> usize {
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
    fn state_sums(&self, f: impl Fn(&States, usize) -> f64) -> (f64, usize) {
        let mut s = 0.0;
        for (a, b) in cores(self, self.keep.0, self.keep.1) {
            let st = self.states(a, b);
            s += (0..b - a).map(|i| f(&st, i)).sum::<f64>();
        }
        (s, self.keep.1 - self.keep.0)
    }

    /// Measured torque on grid samples `lo..hi` (`tau[j][k - lo]`).
    fn grid_tau(&self, lo: usize, hi: usize) -> Vec<Vec<f64>> {
        self.est.tau_on_grid(&self.log, lo, hi)
    }
}

/// Which columns the regression has: base parameters, then effect terms.
#[derive(Debug, Clone)]
pub struct Layout {
    pub dof: usize,
    pub nb: usize,
    pub base_names: Vec<String>,
    pub base_exprs: Vec<String>,
    pub terms: Vec<Term>,
    pub scales: Vec<Scales>,
    /// Per joint, the base columns that can be non-zero in its rows (structurally zero ones
    /// are left out of its accumulators).
    pub base_active: Vec<Vec<usize>>,
    /// Coefficients (one per column, zero on the [`Effect::LOADED`] ones) of the first-stage
    /// model whose predicted torque the load-dependent columns use; empty when there are none.
    pub load: Vec<f64>,
}

impl Layout {
    /// Regressor columns (without the target).
    pub fn ncols(&self) -> usize {
        self.nb + self.terms.len()
    }

    /// Column index of a term.
    pub fn col(&self, t: &Term) -> Option<usize> {
        self.terms.iter().position(|x| x == t).map(|i| self.nb + i)
    }

    /// Columns that can be non-zero in joint `j`'s rows: its base columns and its own terms.
    pub fn active(&self, j: usize) -> Vec<usize> {
        let mut a = self.base_active[j].clone();
        a.extend(
            (0..self.terms.len())
                .filter(|&i| self.terms[i].joint == j)
                .map(|i| self.nb + i),
        );
        a
    }

    /// Empty `[joint]` accumulators for rows of this layout (with the target column).
    fn accumulators(&self) -> Vec<Accumulator> {
        (0..self.dof)
            .map(|j| Accumulator::with_active(self.ncols() + 1, self.active(j)))
            .collect()
    }

    /// Name of a column.
    pub fn col_name(&self, c: usize) -> String {
        if c < self.nb {
            self.base_names[c].clone()
        } else {
            self.terms[c - self.nb].label()
        }
    }
}

/// Fills regression rows for one state: `out[j * ncols + c]`.
struct Rows<'a> {
    base: &'a BaseModel,
    layout: &'a Layout,
    scratch: base::Scratch,
    yb: Vec<f64>,
    /// State buffers of [`Rows::fill_grid`].
    q: Vec<f64>,
    dq: Vec<f64>,
    ddq: Vec<f64>,
}

impl<'a> Rows<'a> {
    fn new(base: &'a BaseModel, layout: &'a Layout) -> Self {
        Rows {
            base,
            layout,
            scratch: base.scratch(),
            yb: vec![0.0; layout.dof * layout.nb],
            q: vec![0.0; layout.dof],
            dq: vec![0.0; layout.dof],
            ddq: vec![0.0; layout.dof],
        }
    }

    /// Rows at grid sample `k` of estimated states `st`.
    fn fill_grid(&mut self, st: &States, k: usize, out: &mut [f64]) {
        let i = k - st.lo;
        for j in 0..self.layout.dof {
            (self.q[j], self.dq[j], self.ddq[j]) = (st.q[j][i], st.dq[j][i], st.ddq[j][i]);
        }
        let (q, dq, ddq) = (
            std::mem::take(&mut self.q),
            std::mem::take(&mut self.dq),
            std::mem::take(&mut self.ddq),
        );
        self.fill(&q, &dq, &ddq, out);
        (self.q, self.dq, self.ddq) = (q, dq, ddq);
    }

    fn fill(&mut self, q: &[f64], dq: &[f64], ddq: &[f64], out: &mut [f64]) {
        let (n, nb, nc) = (self.layout.dof, self.layout.nb, self.layout.ncols());
        self.base.eval(&mut self.scratch, q, dq, ddq, &mut self.yb);
        out.fill(0.0);
        for j in 0..n {
            out[j * nc..j * nc + nb].copy_from_slice(&self.yb[j * nb..(j + 1) * nb]);
        }
        let terms = &self.layout.terms;
        for (i, t) in terms
            .iter()
            .enumerate()
            .filter(|(_, t)| !t.effect.needs_load())
        {
            let j = t.joint;
            out[j * nc + nb + i] =
                t.effect
                    .column(q[j], dq[j], ddq[j], 0.0, &self.layout.scales[j]);
        }
        // Load-dependent columns: the first-stage model's torque from the columns just filled.
        let load = &self.layout.load;
        for (i, t) in terms
            .iter()
            .enumerate()
            .filter(|(_, t)| t.effect.needs_load())
        {
            let j = t.joint;
            let tau = ls::dot(&out[j * nc..(j + 1) * nc], load);
            out[j * nc + nb + i] =
                t.effect
                    .column(q[j], dq[j], ddq[j], tau, &self.layout.scales[j]);
        }
    }
}

/// Rows of the filtered regression are kept at this many times the cut-off (Gautier's
/// decimation after parallel filtering): the filtered columns carry nothing above a few
/// cut-offs (a 4th-order zero-phase Butterworth is down 2.6e-6 at 5·fc), so sums over the
/// decimated rows equal those over all rows to that order, at a fraction of the cost.
pub const KEEP_RATE_PER_CUTOFF: f64 = 20.0;

/// Fewest grid samples per chunk core (plus the filter's reach on each side).
const CHUNK_CORE: usize = 8192;

/// Regression rows of one file on its grid around a core `a..b`: the grid samples `lo..hi`
/// (the core with the regression filter's reach on each side); per joint its active columns
/// then τ, column-major: `cols[j][l * w + (k - lo)]`, `w = hi - lo`.
struct Chunk {
    lo: usize,
    hi: usize,
    cols: Vec<Vec<f64>>,
}

impl Chunk {
    /// Unfiltered rows and the measured τ on the grid around the core `a..b`.
    fn new(p: &Prepared, rows: &mut Rows, active: &[Vec<usize>], (a, b): (usize, usize)) -> Chunk {
        let (n, nc) = (rows.layout.dof, rows.layout.ncols());
        let reach = p.rfilter.as_zero_phase().reach();
        let (lo, hi) = (a.saturating_sub(reach), (b + reach).min(p.est.grid.n));
        let w = hi - lo;
        let st = p.states(lo, hi);
        let tau = p.grid_tau(lo, hi);
        let mut cols: Vec<Vec<f64>> = active
            .iter()
            .map(|a| vec![0.0; (a.len() + 1) * w])
            .collect();
        let mut buf = vec![0.0; n * nc];
        for k in lo..hi {
            rows.fill_grid(&st, k, &mut buf);
            for j in 0..n {
                for (l, &c) in active[j].iter().enumerate() {
                    cols[j][l * w + (k - lo)] = buf[j * nc + c];
                }
                cols[j][active[j].len() * w + (k - lo)] = tau[j][k - lo];
            }
        }
        Chunk { lo, hi, cols }
    }

    fn w(&self) -> usize {
        self.hi - self.lo
    }

    /// Parallel filtering of one joint's channels (all-zero channels are left as they are).
    fn filter_joint(p: &Prepared, cols: &mut [f64], w: usize, lo: usize, hi: usize) {
        let mut chans: Vec<&mut [f64]> = cols
            .chunks_mut(w)
            .filter(|ch| ch.iter().any(|v| *v != 0.0))
            .collect();
        p.rfilter
            .as_zero_phase()
            .apply_many(&mut chans, lo == 0, hi == p.est.grid.n);
    }
}

/// Chunk cores covering grid samples `k0..k1` of `p`: at least twice the regression filter's
/// reach long, so the margins never cost more than the core.
fn cores(p: &Prepared, k0: usize, k1: usize) -> Vec<(usize, usize)> {
    let core = (2 * p.rfilter.as_zero_phase().reach()).max(CHUNK_CORE);
    (k0..k1)
        .step_by(core)
        .map(|a| (a, (a + core).min(k1)))
        .collect()
}

/// Parallel-filtered regression of one file into `[block][joint]` accumulators, rows decimated
/// to [`KEEP_RATE_PER_CUTOFF`]·fc.
fn accumulate_fit(
    p: &Prepared,
    base: &BaseModel,
    layout: &Layout,
    nblocks: usize,
) -> Vec<Vec<Accumulator>> {
    let (n, nc) = (layout.dof, layout.ncols());
    let decim = p.decimation();
    // `[joint][block]` while accumulating, so joints run in parallel.
    let mut accs: Vec<Vec<Accumulator>> = layout
        .accumulators()
        .into_iter()
        .map(|a| vec![a; nblocks])
        .collect();
    let active: Vec<Vec<usize>> = (0..n).map(|j| layout.active(j)).collect();
    let mut rows = Rows::new(base, layout);
    let (k0, k1) = p.keep;
    for (a, b) in cores(p, k0, k1) {
        let mut chunk = Chunk::new(p, &mut rows, &active, (a, b));
        let (lo, hi, w) = (chunk.lo, chunk.hi, chunk.w());
        let keep: Vec<(usize, usize)> = (a..b)
            .filter(|&k| (k - k0) % decim == 0)
            .map(|k| (k, p.block_of(k, nblocks)))
            .collect();
        chunk
            .cols
            .par_iter_mut()
            .zip(accs.par_iter_mut())
            .zip(active.par_iter())
            .for_each(|((cj, acc), act)| {
                Chunk::filter_joint(p, cj, w, lo, hi);
                let mut row = vec![0.0; nc + 1];
                for &(k, blk) in &keep {
                    for (l, &c) in act.iter().enumerate() {
                        row[c] = cj[l * w + (k - lo)];
                    }
                    row[nc] = cj[act.len() * w + (k - lo)];
                    acc[blk].push(&row);
                }
            });
    }
    finish_transposed(accs, nblocks)
}

/// `[joint][block]` → finished `[block][joint]`.
fn finish_transposed(accs: Vec<Vec<Accumulator>>, nblocks: usize) -> Vec<Vec<Accumulator>> {
    let mut out: Vec<Vec<Accumulator>> = (0..nblocks).map(|_| Vec::new()).collect();
    for joint in accs {
        for (b, mut a) in joint.into_iter().enumerate() {
            a.finish();
            out[b].push(a);
        }
    }
    out
}

/// Where raw sample `r`, at time `t`, lies on the grid: `(k, s)`, at `(1 − s)·k + s·(k + 1)`.
fn grid_pos(p: &Prepared, r: usize, t: f64) -> (usize, f64) {
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
fn raw_cores(p: &Prepared) -> Vec<(usize, usize)> {
    let (lo, hi) = p.raw_keep;
    if lo >= hi {
        return Vec::new();
    }
    let at = |r| grid_pos(p, r, p.log.t(r)).0;
    cores(p, at(lo), at(hi - 1) + 1)
}

/// Torque predictions of several coefficient sets (`[set][joint][active column]`) on a file's
/// grid around a core `a..b`: `pred[set][j][k - lo]` for the sets asked for (the others stay
/// empty), from the rows of the estimated states — and parallel-filtered when the file's
/// [`Smoothing`] predicts from the filtered rows (the same thing: the filter is linear, so
/// filtering a prediction equals predicting from filtered rows, at a fraction of the channels).
struct Predicted {
    lo: usize,
    pred: Vec<Vec<Vec<f64>>>,
    /// The window's estimated states.
    states: States,
}

impl Predicted {
    fn new(
        p: &Prepared,
        rows: &mut Rows,
        active: &[Vec<usize>],
        (a, b): (usize, usize),
        coefs: &[Vec<Vec<f64>>],
        wanted: &[bool],
    ) -> Predicted {
        let (n, nc) = (rows.layout.dof, rows.layout.ncols());
        let g = p.est.grid;
        let filtered = p.smoothing.filtered_prediction;
        // One sample either side at least, for the interpolation to raw sample times.
        let reach = if filtered {
            p.rfilter.as_zero_phase().reach().max(1)
        } else {
            1
        };
        let (lo, hi) = (a.saturating_sub(reach), (b + reach).min(g.n));
        let w = hi - lo;
        let mut pred: Vec<Vec<Vec<f64>>> = wanted
            .iter()
            .map(|&u| if u { vec![vec![0.0; w]; n] } else { Vec::new() })
            .collect();
        let mut buf = vec![0.0; n * nc];
        let mut row: Vec<Vec<f64>> = active.iter().map(|a| vec![0.0; a.len()]).collect();
        let states = p.states(lo, hi);
        for k in lo..hi {
            rows.fill_grid(&states, k, &mut buf);
            for (j, rj) in row.iter_mut().enumerate() {
                for (v, &c) in rj.iter_mut().zip(&active[j]) {
                    *v = buf[j * nc + c];
                }
            }
            for (set, out) in coefs.iter().zip(pred.iter_mut()) {
                for (j, o) in out.iter_mut().enumerate() {
                    o[k - lo] = ls::dot(&row[j], &set[j]);
                }
            }
        }
        if filtered {
            let mut chans: Vec<&mut [f64]> = pred
                .iter_mut()
                .flatten()
                .map(|c| c.as_mut_slice())
                .collect();
            p.rfilter
                .as_zero_phase()
                .apply_many(&mut chans, lo == 0, hi == g.n);
        }
        Predicted { lo, pred, states }
    }

    /// Set `c`'s prediction for joint `j` at grid position `(k, s)` (see [`grid_pos`]).
    fn at(&self, c: usize, j: usize, (k, s): (usize, f64)) -> f64 {
        let x = &self.pred[c][j];
        let v = x[k - self.lo];
        if s > 0.0 {
            v + s * (x[k + 1 - self.lo] - v)
        } else {
            v
        }
    }
}

/// Used raw samples of `p` whose grid position lies in the core `a..b`, every `stride`-th of
/// the used range: `(r, t, τ, grid position)` of each, from one read of the log's rows.
fn raw_in_core(
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
    let rows = p.log.read(first, r1);
    let n = p.dof();
    let tau = rows.tau.as_deref().unwrap_or(&[]);
    for r in (first..r1).step_by(stride) {
        let (i, t) = (r - first, rows.t[r - first]);
        f(r, t, &tau[i * n..(i + 1) * n], grid_pos(p, r, t));
    }
}

/// A model's parameters spread over joint `j`'s active columns (zero outside the model), so a
/// prediction is one contiguous dot product.
fn spread(active: &[usize], subset: &[usize], x: &[f64]) -> Vec<f64> {
    active
        .iter()
        .map(|c| subset.iter().position(|s| s == c).map_or(0.0, |k| x[k]))
        .collect()
}

/// A model judged against the measured torque: its columns, its parameters fitted on all
/// training blocks (for the error) and those fitted without each block (for the held-out
/// error); either may be left out.
pub struct Judged<'a> {
    pub subset: &'a [usize],
    pub x: Option<&'a [f64]>,
    pub loo: Option<&'a [Vec<f64>]>,
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
        let per_joint = (0..self.tss.len())
            .map(|j| {
                if self.tss[j] > 0.0 {
                    (self.sse[m][j] / self.tss[j]).sqrt()
                } else {
                    f64::NAN
                }
            })
            .collect();
        let overall = (self.sse[m].iter().sum::<f64>() / self.tss.iter().sum::<f64>()).sqrt();
        Errors { per_joint, overall }
    }

    /// Held-out relative RMS error of model `m`, pooled over joints.
    pub fn heldout(&self, m: usize) -> f64 {
        (self.heldout[m].iter().sum::<f64>() / self.tss.iter().sum::<f64>()).sqrt()
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
) -> RawSums {
    let n = layout.dof;
    let active: Vec<Vec<usize>> = (0..n).map(|j| layout.active(j)).collect();
    let mut total = RawSums::zero(models.len(), n);
    let mut offset = 0;
    for (fi, p) in files.iter().enumerate() {
        let nblocks = blocks.map_or(1, |b| b[fi]);
        // Coefficient sets `[set][joint][active column]`: model m's full-data parameters (if
        // any) at `first_set[m]`, then its leave-one-block-out ones, block by block.
        let (mut sets, mut first_set) = (Vec::new(), Vec::new());
        for m in models {
            first_set.push(sets.len());
            let per_joint = |x: &[f64]| -> Vec<Vec<f64>> {
                (0..n).map(|j| spread(&active[j], m.subset, x)).collect()
            };
            sets.extend(m.x.map(per_joint));
            if let Some(loo) = m.loo {
                sets.extend((0..nblocks).map(|b| per_joint(&loo[offset + b])));
            }
        }
        let parts: Vec<RawSums> = raw_cores(p)
            .par_iter()
            .map(|&core| {
                let mut sums = RawSums::zero(models.len(), n);
                let mut rows = Rows::new(base, layout);
                // Only the blocks this chunk's samples can fall in (filter margins included).
                let (b0, b1) = (
                    p.block_of(core.0.saturating_sub(1), nblocks),
                    p.block_of(core.1, nblocks),
                );
                let mut wanted = vec![false; sets.len()];
                for (m, model) in models.iter().enumerate() {
                    let full = usize::from(model.x.is_some());
                    wanted[first_set[m]] |= full == 1;
                    if model.loo.is_some() {
                        for blk in b0..=b1 {
                            wanted[first_set[m] + full + blk] = true;
                        }
                    }
                }
                let pc = Predicted::new(p, &mut rows, &active, core, &sets, &wanted);
                raw_in_core(p, core, 1, |_, _, tau, (k, s)| {
                    let blk = p.block_of(k + usize::from(s >= 0.5), nblocks);
                    for (ss, t) in sums.tss.iter_mut().zip(tau) {
                        *ss += t * t;
                    }
                    for (m, model) in models.iter().enumerate() {
                        let full = usize::from(model.x.is_some());
                        for (j, &t) in tau.iter().enumerate() {
                            if full == 1 {
                                let e = t - pc.at(first_set[m], j, (k, s));
                                sums.sse[m][j] += e * e;
                            }
                            if model.loo.is_some() {
                                let e = t - pc.at(first_set[m] + full + blk, j, (k, s));
                                sums.heldout[m][j] += e * e;
                            }
                        }
                    }
                });
                sums
            })
            .collect();
        for part in &parts {
            total.add(part);
        }
        offset += nblocks;
    }
    total
}

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
        let total_rows: usize = train.iter().map(|p| p.keep.1 - p.keep.0).sum();
        let (mut blocks, mut file_blocks) = (Vec::new(), Vec::new());
        for p in train {
            let share = (target_blocks as f64 * (p.keep.1 - p.keep.0) as f64
                / total_rows.max(1) as f64)
                .round() as usize;
            blocks.extend(accumulate_fit(p, base, &layout, share.max(2)));
            file_blocks.push(share.max(2));
        }
        let files = train
            .iter()
            .map(|p| p.name.as_str())
            .collect::<Vec<_>>()
            .join(", ");
        Problem::new(layout, blocks, file_blocks, files)
    }

    /// Held-out relative RMS error against the *measured* torque of the training files this
    /// problem was built from: each block predicted by the fit on the other blocks,
    /// `‖τ̂−τ‖/‖τ‖` pooled over blocks and joints.
    pub fn cv_raw(
        &self,
        base: &BaseModel,
        train: &[Prepared],
        subset: &[usize],
        w: &[f64],
    ) -> Result<f64, RankError> {
        let loo = self.loo_fits(subset, w)?;
        let m = [Judged {
            subset,
            x: None,
            loo: Some(&loo),
        }];
        let sums = raw_sums(base, &self.layout, train, Some(self.raw_blocks()), &m);
        Ok(sums.heldout(0))
    }

    /// Blocks per training file, for [`raw_sums`].
    pub fn raw_blocks(&self) -> &[usize] {
        &self.file_blocks
    }

    /// Parameters of every leave-one-block-out fit (an error if one is rank-deficient).
    pub fn loo_fits(&self, subset: &[usize], w: &[f64]) -> Result<Vec<Vec<f64>>, RankError> {
        (0..self.blocks())
            .map(|b| {
                let f: Vec<(&DMatrix<f64>, f64)> =
                    self.loo[b].iter().zip(w).map(|(r, &w)| (r, w)).collect();
                ls::solve_x(&f, subset)
                    .map(|(x, _)| x)
                    .map_err(|e| self.rank_error(&e.dependent))
            })
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
        let mut s: Vec<usize> = (0..self.layout.nb).collect();
        s.extend(terms.iter().filter_map(|t| self.layout.col(t)));
        s
    }

    fn rank_error(&self, dependent: &[usize]) -> RankError {
        RankError {
            files: self.files.clone(),
            params: dependent.iter().map(|&c| self.layout.col_name(c)).collect(),
            hint: String::new(),
        }
    }

    /// Weighted fit over the full training set.
    pub fn fit(&self, subset: &[usize], w: &[f64]) -> Result<ls::Fit, RankError> {
        ls::solve(&self.total_factors(w), subset).map_err(|e| self.rank_error(&e.dependent))
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
        let n = self.layout.dof;
        let fits = self.loo_fits(subset, w)?;
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

/// Relative RMS errors against measured torque.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Errors {
    pub per_joint: Vec<f64>,
    pub overall: f64,
}

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

/// A fitted model and its errors.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ModelResult {
    pub terms: Vec<String>,
    pub train: Errors,
    pub validation: Option<Errors>,
    /// Held-out error of leave-one-block-out refits on the (filtered) training data.
    pub heldout_rms: f64,
    #[serde(skip)]
    pub subset: Vec<usize>,
    #[serde(skip)]
    pub x: Vec<f64>,
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
    /// [`KEEP_RATE_PER_CUTOFF`]).
    pub regression_row_every: usize,
    /// The parallel (regression) filter, e.g. `zero-phase Butterworth, order 4, fc 2.93 Hz`.
    pub regression_filter: String,
    pub smoothing: Smoothing,
}

impl FileInfo {
    fn of(p: &Prepared) -> Self {
        let n = p.log.len();
        FileInfo {
            file: p.name.clone(),
            rows: n,
            rows_used: p.raw_keep.1 - p.raw_keep.0,
            duration_s: p.log.t(n - 1) - p.log.t(0),
            derivative: p.est.report.clone(),
            regression_row_every: p.decimation(),
            regression_filter: p.rfilter.as_zero_phase().describe(),
            smoothing: p.smoothing,
        }
    }
}

/// `(velocity, residual)` points before and after.
pub type BeforeAfter = (Vec<(f64, f64)>, Vec<(f64, f64)>);

/// Effects merged with base parameters, and the base parameters they merge into.
type Merged = Vec<(Term, Vec<String>)>;

/// Plot data: per joint, (velocity, residual) of the training data before and after.
#[derive(Debug, Clone, Default)]
pub struct Series {
    pub resid_vs_vel: Vec<BeforeAfter>,
    /// Validation: per joint, (t, measured, before, after).
    pub validation: Vec<Vec<(f64, f64, f64, f64)>>,
}

/// The rows of `validation_prediction.csv`: per validation sample used, its time, then the
/// measured τ and the torques predicted by the declared (`before`) and augmented (`after`)
/// models, n each — in a [`Table`] (a long validation log's spill to a temporary file).
#[derive(Debug, Clone)]
pub struct Predictions {
    pub dof: usize,
    table: Arc<Table>,
}

impl Predictions {
    pub fn len(&self) -> usize {
        self.table.len()
    }

    pub fn is_empty(&self) -> bool {
        self.table.is_empty()
    }

    /// Calls `f(t, tau, before, after)` for rows `a..b` in order.
    pub fn rows(&self, a: usize, b: usize, mut f: impl FnMut(f64, &[f64], &[f64], &[f64])) {
        let n = self.dof;
        self.table.rows(a, b, |r| {
            f(r[0], &r[1..1 + n], &r[1 + n..1 + 2 * n], &r[1 + 2 * n..])
        });
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

/// Everything [`run`] found.
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
    /// Cut-offs tried by the automatic choice and their held-out errors (empty if fixed).
    pub cutoff_scan: Vec<CutoffTrial>,
    /// Load-dependent terms the scan was repeated with (found by the first pass).
    pub rescanned_with: Vec<String>,
    /// The final model's load-dependent terms and its torque without them (for a rescan).
    #[serde(skip)]
    pub load_model: Option<LoadModel>,
    #[serde(skip)]
    pub series: Series,
    #[serde(skip)]
    pub predictions: Option<Predictions>,
}

/// A model's load-dependent terms and the coefficients of its torque without them, over the
/// columns of a first-stage layout (what [`choose_cutoff`] needs to judge cut-offs with them).
#[derive(Debug, Clone, PartialEq)]
pub struct LoadModel {
    pub terms: Vec<Term>,
    pub coefs: Vec<f64>,
}

fn load_model(layout: &Layout, terms: &[Term], subset: &[usize], x: &[f64]) -> Option<LoadModel> {
    let loaded: Vec<Term> = terms
        .iter()
        .copied()
        .filter(|t| t.effect.needs_load())
        .collect();
    if loaded.is_empty() {
        return None;
    }
    // Load-dependent columns sort last, so the first stage's are the first ones.
    let first = layout.ncols()
        - layout
            .terms
            .iter()
            .filter(|t| t.effect.needs_load())
            .count();
    let mut coefs = vec![0.0; first];
    for (&c, &v) in subset.iter().zip(x) {
        if c < first {
            coefs[c] = v;
        }
    }
    Some(LoadModel {
        terms: loaded,
        coefs,
    })
}

/// Chooses the filters on `train`, prepares the files and identifies; if the model found has
/// load-dependent terms (which the first scan's models lack, see [`Effect::LOADED`]) and the
/// choice was automatic, the scan is repeated with them in its models, and the identification
/// with its choice if that differs.
fn scan_and_run(
    arm: &ArmSource,
    base: &BaseModel,
    train: &[Log],
    val: Option<&Log>,
    cfg: &Config,
    cache: &mut PrepCache,
) -> Result<Outcome, IdentifyError> {
    let table = arm.dh_table().ok();
    let fit = |cache: &mut PrepCache, choice: FilterChoice| -> Result<Outcome, IdentifyError> {
        let (fc, sm) = (choice.cutoff_hz, choice.smoothing);
        let preps = cache.get_all(train, cfg, fc, sm)?;
        let val = match val {
            Some(v) => {
                Some(cache.get(v, cfg, fc.or(Some(preps[0].est.report.cutoff_hz)), sm, None)?)
            }
            None => None,
        };
        run_prepared(arm.name(), base, table.as_ref(), &preps, val.as_ref(), cfg)
    };
    let (choice, scan) = choose_cutoff(base, table.as_ref(), train, cfg, cache, None)?;
    let mut out = fit(cache, choice)?;
    out.cutoff_scan = scan;
    let automatic = cfg.derivative.cutoff_hz.is_none() || cfg.smoothing.is_none();
    if let (Some(lm), true) = (out.load_model.clone(), automatic) {
        let (again, scan) = choose_cutoff(base, table.as_ref(), train, cfg, cache, Some(&lm))?;
        if again != choice {
            out = fit(cache, again)?;
        }
        out.cutoff_scan = scan;
        out.rescanned_with = lm.terms.iter().map(Term::label).collect();
    }
    Ok(out)
}

/// Identifies `arm` from `train` files, validating on `validate` if given (see the module docs).
pub fn run(
    arm: &ArmSource,
    train: Vec<Log>,
    validate: Option<Log>,
    cfg: &Config,
) -> Result<Outcome, IdentifyError> {
    let base = BaseModel::for_arm(arm);
    for t in &train {
        check_dof(t, &base)?;
    }
    if let Some(v) = &validate {
        check_dof(v, &base)?;
    }
    scan_and_run(
        arm,
        &base,
        &train,
        validate.as_ref(),
        cfg,
        &mut PrepCache::default(),
    )
}

fn check_dof(t: &Log, base: &BaseModel) -> Result<(), IdentifyError> {
    if t.dof() != base.dof() {
        return Err(IdentifyError::Dof {
            file: t.source.clone(),
            found: t.dof(),
            dof: base.dof(),
        });
    }
    Ok(())
}

/// Prepared files per (file, cut-off), so cut-off scans and leave-one-out studies reuse them.
#[derive(Debug, Default)]
pub struct PrepCache {
    map: Vec<((usize, usize), u64, Prepared)>,
}

impl PrepCache {
    fn get(
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
        let p = Prepared::with_cutoff(t.clone(), cfg, fc, sm, edge_fc)?;
        self.map.push((key.0, key.1, p.clone()));
        Ok(p)
    }

    fn get_all(
        &mut self,
        ts: &[Log],
        cfg: &Config,
        fc: Option<f64>,
        sm: Smoothing,
    ) -> Result<Vec<Prepared>, IdentifyError> {
        ts.iter().map(|t| self.get(t, cfg, fc, sm, None)).collect()
    }
}

/// Most samples the cut-off scan fits per cut-off: longer training sets are scanned on
/// [`SCAN_PIECES`] evenly spaced pieces of each file (the final fit uses every sample).
pub const SCAN_SAMPLES: usize = 100_000;

/// Pieces per file of the cut-off scan of a long training set.
pub const SCAN_PIECES: usize = 4;

/// The files the cut-off scan fits: `train` itself up to [`SCAN_SAMPLES`] samples in all, else
/// [`SCAN_PIECES`] evenly spaced pieces of each file, of lengths proportional to the files'
/// (each piece filtered on its own, as a file of its own).
pub fn scan_pieces(train: &[Log]) -> Vec<Log> {
    let total: usize = train.iter().map(|t| t.len()).sum();
    if total <= SCAN_SAMPLES {
        return train.to_vec();
    }
    let mut out = Vec::new();
    for t in train {
        let share = (SCAN_SAMPLES as f64 * t.len() as f64 / total as f64) as usize;
        let piece = share / SCAN_PIECES;
        if piece < 4 * MIN_SAMPLES {
            out.push(t.clone());
            continue;
        }
        let gap = (t.len() - SCAN_PIECES * piece) / SCAN_PIECES;
        for i in 0..SCAN_PIECES {
            let lo = gap / 2 + i * (piece + gap);
            out.push(t.slice(lo, lo + piece));
        }
    }
    out
}

/// One point of the cut-off scan.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CutoffTrial {
    pub cutoff_hz: f64,
    pub smoothing: Smoothing,
    /// Held-out relative RMS error against the measured torque (leave-one-block-out).
    pub heldout_error: f64,
}

/// What the scan chose: the derivative cut-off (`None` = the spectral rule) and the smoothing.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FilterChoice {
    pub cutoff_hz: Option<f64>,
    pub smoothing: Smoothing,
}

/// The automatic cut-off: the spectrum gives the motion band `f_m` (largest over files and
/// joints, see [`derivative::auto_cutoff`]); cut-offs `f_m · 2^(k/2)`, k = −2..7, below the
/// noise edge and 0.2·fs are tried (only the given one with `--cutoff`), each with every
/// [`Smoothing`] (regression filter at 1 or ½ of the cut-off, predictions from the filtered
/// rows or from the states), and the combination with the smallest held-out error against the
/// measured torque wins (rigid model plus every candidate effect, leave-one-block-out, the same
/// samples for every trial). Too low a cut-off distorts the motion; too high a one lets noise
/// and vibration into q̈, which biases least squares towards zero — the scan sees both.
pub fn choose_cutoff(
    base: &BaseModel,
    table: Option<&crate::dh::DhTable>,
    train: &[Log],
    cfg: &Config,
    cache: &mut PrepCache,
    load: Option<&LoadModel>,
) -> Result<(FilterChoice, Vec<CutoffTrial>), IdentifyError> {
    let fallback = FilterChoice {
        cutoff_hz: cfg.derivative.cutoff_hz,
        smoothing: cfg.smoothing.unwrap_or_default(),
    };
    if cfg.derivative.cutoff_hz.is_some() && cfg.smoothing.is_some() {
        return Ok((fallback, Vec::new()));
    }
    let first = cache.get_all(train, cfg, cfg.derivative.cutoff_hz, Smoothing::default())?;
    let grid: Vec<f64> = match cfg.derivative.cutoff_hz {
        Some(fc) => vec![fc],
        None => {
            let (mut band, mut cap) = (0.0f64, f64::INFINITY);
            for p in &first {
                let fs = p.est.report.fs_hz;
                cap = cap.min(0.2 * fs);
                for c in &p.est.report.per_channel {
                    band = band.max(c.motion_band_hz);
                    cap = cap.min(1.25 * c.noise_edge_hz.max(c.motion_band_hz));
                }
            }
            if band.is_nan() || band <= 0.0 {
                Vec::new()
            } else {
                (-2..=7)
                    .map(|k| band * 2f64.powf(k as f64 / 2.0))
                    .filter(|&f| f <= cap)
                    .collect()
            }
        }
    };
    let Some(&lowest) = grid.first() else {
        return Ok((fallback, Vec::new()));
    };
    let (ratios, modes): (Vec<f64>, Vec<bool>) = match cfg.smoothing {
        Some(s) => (vec![s.regression_ratio], vec![s.filtered_prediction]),
        None => (Smoothing::RATIOS.to_vec(), vec![false, true]),
    };
    let edge_fc = lowest * ratios.iter().copied().fold(1.0, f64::min);
    let mut layout = make_layout(base, table, &first, cfg).0;
    if let Some(lm) = load.filter(|lm| lm.coefs.len() == layout.ncols()) {
        layout.terms.extend(&lm.terms);
        layout.load = lm.coefs.clone();
        layout.load.resize(layout.ncols(), 0.0);
    }
    let scan_files = scan_pieces(train);
    let all: Vec<Term> = layout.terms.clone();
    let mut trials = Vec::new();
    // One cut-off and regression ratio: both predictions judged on one problem.
    let trial = |trials: &mut Vec<CutoffTrial>, fc: f64, ratio: f64| -> Result<(), IdentifyError> {
        let sm = Smoothing {
            regression_ratio: ratio,
            filtered_prediction: false,
        };
        // Not cached: one cut-off's estimates at a time (memory stays that of one copy).
        let mut preps: Vec<Prepared> = scan_files
            .iter()
            .map(|t| Prepared::with_cutoff(t.clone(), cfg, Some(fc), sm, Some(edge_fc)))
            .collect::<Result<_, _>>()?;
        let problem = Problem::build(base, layout.clone(), &preps, cfg.blocks);
        let subset = problem.subset(&all);
        let Ok(w) = problem.weights(&subset) else {
            return Ok(());
        };
        for &filtered in &modes {
            for p in &mut preps {
                p.smoothing.filtered_prediction = filtered;
            }
            if let Ok(e) = problem.cv_raw(base, &preps, &subset, &w) {
                trials.push(CutoffTrial {
                    cutoff_hz: fc,
                    smoothing: preps[0].smoothing,
                    heldout_error: e,
                });
            }
        }
        Ok(())
    };
    for &fc in &grid {
        for &ratio in &ratios {
            trial(&mut trials, fc, ratio)?;
        }
    }
    let choice = best_trial(&trials).map_or(fallback, |b| FilterChoice {
        cutoff_hz: Some(b.cutoff_hz),
        smoothing: b.smoothing,
    });
    trials.sort_by(|a, b| a.cutoff_hz.total_cmp(&b.cutoff_hz));
    Ok((choice, trials))
}

/// The trial with the smallest held-out error (the first of equals).
fn best_trial(trials: &[CutoffTrial]) -> Option<&CutoffTrial> {
    trials
        .iter()
        .fold(None, |best: Option<&CutoffTrial>, t| match best {
            Some(b) if b.heldout_error <= t.heldout_error => Some(b),
            _ => Some(t),
        })
}

/// The column layout for `train`: base parameters, then the effect terms (declared and searched,
/// minus those structurally merged with the base), with friction scales from the data.
fn make_layout(
    base: &BaseModel,
    table: Option<&crate::dh::DhTable>,
    train: &[Prepared],
    cfg: &Config,
) -> (Layout, Vec<Term>, Vec<Term>, Merged) {
    let n = base.dof();
    let scales: Vec<Scales> = (0..n)
        .map(|j| {
            let (s, c) = train.iter().fold((0.0, 0usize), |(s, c), p| {
                let (s1, c1) = p.state_sums(|st, i| st.dq[j][i].powi(2));
                (s + s1, c + c1)
            });
            Scales::from_rms_velocity((s / c.max(1) as f64).sqrt())
        })
        .collect();
    let (declared, searched): (Vec<Term>, Vec<Term>) = match &cfg.effects {
        EffectsSpec::Auto => (
            Vec::new(),
            Effect::ALL
                .iter()
                .flat_map(|&e| {
                    (0..n).map(move |j| Term {
                        effect: e,
                        joint: j,
                    })
                })
                .collect(),
        ),
        // Load-dependent terms come in the second stage (see `run_prepared`).
        EffectsSpec::Fixed(t) => (
            t.iter()
                .copied()
                .filter(|t| !t.effect.needs_load())
                .collect(),
            Vec::new(),
        ),
    };
    let names = base.names();
    // Random states for the structural checks (merged effects, zero base columns per joint).
    let states = table.map(|tab| base::random_states(tab, 40, 11));
    let merged: Vec<(Term, Vec<String>)> = match &states {
        Some(states) => {
            let mut s = base.scratch();
            let all: Vec<Term> = declared.iter().chain(&searched).copied().collect();
            effects::structural_merges(
                &all,
                base.nb(),
                n,
                states,
                |q, dq, ddq, out| base.eval(&mut s, q, dq, ddq, out),
                &names,
            )
        }
        None => Vec::new(),
    };
    let is_merged = |t: &Term| merged.iter().any(|(m, _)| m == t);
    let declared: Vec<Term> = declared.into_iter().filter(|t| !is_merged(t)).collect();
    let searched: Vec<Term> = searched.into_iter().filter(|t| !is_merged(t)).collect();
    let mut terms: Vec<Term> = declared.iter().chain(&searched).copied().collect();
    terms.sort();
    terms.dedup();
    let base_active = match &states {
        Some(states) => structural_base_columns(base, states),
        None => vec![(0..base.nb()).collect(); n],
    };
    let layout = Layout {
        dof: n,
        nb: base.nb(),
        base_names: names,
        base_exprs: base.exprs(),
        terms,
        scales,
        base_active,
        load: Vec::new(),
    };
    (layout, declared, searched, merged)
}

/// Per joint, the base columns that are non-zero at some of the random `states` (a
/// structurally zero entry is exactly zero in the generated kernels and at rounding level,
/// ≤ 1e-10 of the column's largest entry, in the numeric base map).
fn structural_base_columns(base: &BaseModel, states: &[[Vec<f64>; 3]]) -> Vec<Vec<usize>> {
    let (n, nb) = (base.dof(), base.nb());
    let mut peak = vec![0.0f64; n * nb];
    let mut s = base.scratch();
    let mut yb = vec![0.0; n * nb];
    for [q, dq, ddq] in states {
        base.eval(&mut s, q, dq, ddq, &mut yb);
        for (p, y) in peak.iter_mut().zip(&yb) {
            *p = p.max(y.abs());
        }
    }
    (0..n)
        .map(|j| {
            (0..nb)
                .filter(|&c| {
                    let col_max = (0..n).map(|i| peak[i * nb + c]).fold(0.0, f64::max);
                    peak[j * nb + c] > 1e-10 * col_max
                })
                .collect()
        })
        .collect()
}

/// [`run`] on files already prepared (so studies can rotate files without redoing derivatives).
pub fn run_prepared(
    arm: &str,
    base: &BaseModel,
    table: Option<&crate::dh::DhTable>,
    train: &[Prepared],
    val: Option<&Prepared>,
    cfg: &Config,
) -> Result<Outcome, IdentifyError> {
    let n = base.dof();
    let (layout, declared, searched, merged) = make_layout(base, table, train, cfg);
    let names = layout.base_names.clone();
    let scales = layout.scales.clone();
    let problem = Problem::build(base, layout.clone(), train, cfg.blocks);

    // Declared (rigid) model first: its rank is the excitation check.
    let rigid = problem.subset(&[]);
    problem.weights(&rigid).map_err(|e| with_hint(e, train))?;
    let selection = match &cfg.effects {
        EffectsSpec::Auto => effects::select(&problem, &declared, &searched, &cfg.rules)?,
        EffectsSpec::Fixed(_) => Selection {
            steps: Vec::new(),
            terms: declared.clone(),
            stopped_on: None,
            collinear: Vec::new(),
            dropped: Vec::new(),
        },
    };
    let (layout, problem, selection, declared) =
        load_stage(base, train, cfg, layout, problem, selection, declared)?;

    // The models reported: rigid, the final one, and rigid → +declared → +each added effect.
    let mut added_steps: Vec<Vec<Term>> = Vec::new();
    if !declared.is_empty() {
        added_steps.push(declared.clone());
    }
    for s in &selection.steps {
        added_steps.push(vec![s.added]);
    }
    let mut model_terms: Vec<Vec<Term>> = vec![Vec::new(), selection.terms.clone()];
    let mut acc_terms: Vec<Term> = Vec::new();
    for add in &added_steps {
        acc_terms.extend(add.iter().copied());
        model_terms.push(acc_terms.clone());
    }
    struct Fitted {
        subset: Vec<usize>,
        w: Vec<f64>,
        fit: ls::Fit,
        loo: Vec<Vec<f64>>,
    }
    let fitted: Vec<Fitted> = model_terms
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
    let judged: Vec<Judged> = fitted
        .iter()
        .map(|f| Judged {
            subset: &f.subset,
            x: Some(&f.fit.x),
            loo: Some(&f.loo),
        })
        .collect();
    let train_sums = raw_sums(base, &layout, train, Some(problem.raw_blocks()), &judged);
    let val_sums = val.map(|p| raw_sums(base, &layout, std::slice::from_ref(p), None, &judged));
    let result = |m: usize| ModelResult {
        terms: model_terms[m].iter().map(Term::label).collect(),
        train: train_sums.errors(m),
        validation: val_sums.as_ref().map(|v| v.errors(m)),
        heldout_rms: train_sums.heldout(m),
        subset: fitted[m].subset.clone(),
        x: fitted[m].fit.x.clone(),
    };
    let before = result(0);
    let after = result(1);
    let (w, fit) = (fitted[1].w.clone(), fitted[1].fit.clone());
    let mut steps = vec![StepRow {
        model: "rigid".into(),
        added: None,
        train: before.train.clone(),
        heldout_rms: before.heldout_rms,
        validation: before.validation.clone(),
    }];
    for (i, add) in added_steps.iter().enumerate() {
        let m = result(2 + i);
        steps.push(StepRow {
            model: format!(
                "rigid + {}",
                model_terms[2 + i]
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

    // Jackknife standard deviations over the blocks (the final model's leave-out fits).
    let loo = &fitted[1].loo;
    let nb_ = loo.len() as f64;
    let std: Vec<f64> = (0..after.x.len())
        .map(|k| {
            if loo.len() < 2 {
                return f64::NAN;
            }
            let mean = loo.iter().map(|x| x[k]).sum::<f64>() / nb_;
            ((nb_ - 1.0) / nb_ * loo.iter().map(|x| (x[k] - mean).powi(2)).sum::<f64>()).sqrt()
        })
        .collect();
    let est = |k: usize, name: String, expression: String, unit: Option<String>| Estimated {
        name,
        expression,
        value: after.x[k],
        std: std[k],
        rel_std_percent: if after.x[k] != 0.0 {
            100.0 * std[k] / after.x[k].abs()
        } else {
            f64::INFINITY
        },
        unit,
    };
    let theta: Vec<Estimated> = (0..layout.nb)
        .map(|k| est(k, names[k].clone(), layout.base_exprs[k].clone(), None))
        .collect();
    let effects_est: Vec<(Term, Estimated)> = selection
        .terms
        .iter()
        .enumerate()
        .map(|(i, t)| {
            let k = layout.nb + i;
            (
                *t,
                est(
                    k,
                    t.label(),
                    format!("{} on joint {}", t.effect.name(), t.joint + 1),
                    Some(t.effect.unit().to_string()),
                ),
            )
        })
        .collect();

    let series = make_series(base, &layout, train, val, &before, &after);
    let predictions = val
        .map(|p| predictions(base, &layout, p, &before, &after))
        .transpose()?;
    let sigma = w.iter().map(|w| 1.0 / w).collect();
    let load_model = load_model(&layout, &selection.terms, &fitted[1].subset, &after.x);
    Ok(Outcome {
        arm: arm.to_string(),
        dof: n,
        base_source: base.source().to_string(),
        train: train.iter().map(FileInfo::of).collect(),
        validate: val.map(FileInfo::of),
        effects_mode: match &cfg.effects {
            EffectsSpec::Auto => "auto".into(),
            EffectsSpec::Fixed(t) if t.is_empty() => "none".into(),
            EffectsSpec::Fixed(t) => t.iter().map(Term::label).collect::<Vec<_>>().join(","),
        },
        theta,
        effects: effects_est,
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
        scales,
        cutoff_scan: Vec::new(),
        rescanned_with: Vec::new(),
        load_model,
        series,
        predictions,
    })
}

/// The second stage for the load-dependent effects ([`Effect::LOADED`]): their columns use the
/// torque the first stage's model predicts (rigid body and effects, parameters held fixed: the
/// joint torque the gear transmits), so the problem is rebuilt with them and they are searched
/// (or, declared, added) on top of the first stage's model. Without any accepted or declared, the first stage is returned as it
/// is. (The fixed parameters saw every training block, so the candidates' held-out test is
/// slightly optimistic — by one global, smooth estimate, not a per-block fit.)
#[allow(clippy::type_complexity)]
fn load_stage(
    base: &BaseModel,
    train: &[Prepared],
    cfg: &Config,
    layout: Layout,
    problem: Problem,
    first: Selection,
    declared: Vec<Term>,
) -> Result<(Layout, Problem, Selection, Vec<Term>), IdentifyError> {
    let n = base.dof();
    let (fixed, search): (Vec<Term>, Vec<Term>) = match &cfg.effects {
        EffectsSpec::Auto => (
            Vec::new(),
            Effect::LOADED
                .iter()
                .flat_map(|&effect| (0..n).map(move |joint| Term { effect, joint }))
                .collect(),
        ),
        EffectsSpec::Fixed(t) => (
            t.iter()
                .copied()
                .filter(|t| t.effect.needs_load())
                .collect(),
            Vec::new(),
        ),
    };
    if fixed.is_empty() && search.is_empty() {
        return Ok((layout, problem, first, declared));
    }
    let subset = problem.subset(&first.terms);
    let w = problem.weights(&subset).map_err(|e| with_hint(e, train))?;
    let fit = problem.fit(&subset, &w).map_err(|e| with_hint(e, train))?;
    let mut l2 = layout.clone();
    l2.terms.extend(fixed.iter().chain(&search));
    l2.terms.sort();
    l2.terms.dedup();
    // The new terms sort last (their effects are the last variants): first-stage columns keep
    // their indices.
    l2.load = vec![0.0; l2.ncols()];
    for (&c, &x) in subset.iter().zip(&fit.x) {
        l2.load[c] = x;
    }
    let p2 = Problem::build(base, l2.clone(), train, cfg.blocks);
    let start: Vec<Term> = first.terms.iter().chain(&fixed).copied().collect();
    let second = effects::select(&p2, &start, &search, &cfg.rules)?;
    if fixed.is_empty() && second.steps.is_empty() {
        let mut first = first;
        first.collinear.extend(second.collinear);
        // Why the second stage stopped is the last word if it had the better candidate.
        if let Some(s) = second.stopped_on {
            if first
                .stopped_on
                .as_ref()
                .map_or(true, |f| s.heldout_gain > f.heldout_gain)
            {
                first.stopped_on = Some(s);
            }
        }
        return Ok((layout, problem, first, declared));
    }
    // A first-stage effect may have stood in for the load-dependent one (a Coulomb term for
    // the mean of load-dependent friction): each must pass the same test again against the
    // final model without it, or it goes (last added first).
    let mut terms = second.terms;
    let mut dropped = Vec::new();
    let once = Rules {
        max_steps: 1,
        ..cfg.rules
    };
    for s in first.steps.iter().rev() {
        let without: Vec<Term> = terms.iter().copied().filter(|t| *t != s.added).collect();
        if effects::select(&p2, &without, &[s.added], &once)?
            .steps
            .is_empty()
        {
            terms = without;
            dropped.push(s.added);
        }
    }
    let declared: Vec<Term> = declared.into_iter().chain(fixed).collect();
    let mut model: Vec<String> = declared.iter().map(Term::label).collect();
    let mut steps = Vec::new();
    for mut s in first.steps.into_iter().chain(second.steps) {
        if !dropped.contains(&s.added) {
            model.push(s.label.clone());
            s.model = model.clone();
            steps.push(s);
        }
    }
    let mut collinear = first.collinear;
    collinear.extend(second.collinear);
    Ok((
        l2,
        p2,
        Selection {
            steps,
            terms,
            stopped_on: second.stopped_on,
            collinear,
            dropped: dropped.iter().map(Term::label).collect(),
        },
        declared,
    ))
}

/// Adds which joints hardly move to a rank error.
fn with_hint(mut e: RankError, train: &[Prepared]) -> RankError {
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

/// Calls `f(t, dq, tau, before, after)` for every `stride`-th used raw sample of `p`, with
/// the predictions of both models (see [`Predicted`]), the estimated q̇ at the
/// sample and its measured τ.
fn for_predictions(
    base: &BaseModel,
    layout: &Layout,
    p: &Prepared,
    models: [&ModelResult; 2],
    stride: usize,
    mut f: impl FnMut(f64, &[f64], &[f64], &[f64], &[f64]),
) {
    let n = layout.dof;
    let active: Vec<Vec<usize>> = (0..n).map(|j| layout.active(j)).collect();
    let coef: Vec<Vec<Vec<f64>>> = models
        .iter()
        .map(|m| {
            (0..n)
                .map(|j| spread(&active[j], &m.subset, &m.x))
                .collect()
        })
        .collect();
    let mut rows = Rows::new(base, layout);
    let (mut dq, mut pb, mut pa) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
    for core in raw_cores(p) {
        let pc = Predicted::new(p, &mut rows, &active, core, &coef, &[true, true]);
        raw_in_core(p, core, stride, |_, t, tau, (k, s)| {
            for j in 0..n {
                let (d, i) = (&pc.states.dq[j], k - pc.lo);
                dq[j] = if s > 0.0 {
                    d[i] + s * (d[i + 1] - d[i])
                } else {
                    d[i]
                };
                pb[j] = pc.at(0, j, (k, s));
                pa[j] = pc.at(1, j, (k, s));
            }
            f(t, &dq, tau, &pb, &pa);
        });
    }
}

fn make_series(
    base: &BaseModel,
    layout: &Layout,
    train: &[Prepared],
    val: Option<&Prepared>,
    before: &ModelResult,
    after: &ModelResult,
) -> Series {
    let n = layout.dof;
    let total: usize = train.iter().map(|p| p.raw_keep.1 - p.raw_keep.0).sum();
    let stride = total.div_ceil(3000).max(1);
    let mut rv: Vec<BeforeAfter> = vec![(Vec::new(), Vec::new()); n];
    for p in train {
        for_predictions(
            base,
            layout,
            p,
            [before, after],
            stride,
            |_, dq, tau, pb, pa| {
                for j in 0..n {
                    rv[j].0.push((dq[j], tau[j] - pb[j]));
                    rv[j].1.push((dq[j], tau[j] - pa[j]));
                }
            },
        );
    }
    let mut validation = vec![Vec::new(); n];
    if let Some(p) = val {
        let stride = (p.raw_keep.1 - p.raw_keep.0).div_ceil(4000).max(1);
        for_predictions(
            base,
            layout,
            p,
            [before, after],
            stride,
            |t, _, tau, pb, pa| {
                for j in 0..n {
                    validation[j].push((t, tau[j], pb[j], pa[j]));
                }
            },
        );
    }
    Series {
        resid_vs_vel: rv,
        validation,
    }
}

fn predictions(
    base: &BaseModel,
    layout: &Layout,
    p: &Prepared,
    before: &ModelResult,
    after: &ModelResult,
) -> Result<Predictions, IdentifyError> {
    let n = layout.dof;
    let mut table = TableWriter::new(1 + 3 * n, SPILL_ROWS);
    let (mut row, mut failed) = (Vec::with_capacity(1 + 3 * n), None);
    for_predictions(base, layout, p, [before, after], 1, |t, _, tau, pb, pa| {
        row.clear();
        row.push(t);
        row.extend(tau.iter().chain(pb).chain(pa));
        if let Err(e) = table.push(&row) {
            failed.get_or_insert(e);
        }
    });
    let table = match failed {
        Some(e) => Err(e),
        None => table.finish(),
    }
    .map_err(IdentifyError::Spill)?;
    Ok(Predictions {
        dof: n,
        table: Arc::new(table),
    })
}

/// Leave-one-file-out study: each file in turn is the validation file, the others the training
/// set (cut-off chosen on the training files only). Returns one outcome per file, in order.
pub fn leave_one_out(
    arm: &ArmSource,
    files: Vec<Log>,
    cfg: &Config,
) -> Result<Vec<Outcome>, IdentifyError> {
    let base = BaseModel::for_arm(arm);
    for t in &files {
        check_dof(t, &base)?;
    }
    let mut cache = PrepCache::default();
    let mut out = Vec::new();
    for k in 0..files.len() {
        let train: Vec<Log> = files
            .iter()
            .enumerate()
            .filter(|(i, _)| *i != k)
            .map(|(_, p)| p.clone())
            .collect();
        out.push(scan_and_run(
            arm,
            &base,
            &train,
            Some(&files[k]),
            cfg,
            &mut cache,
        )?);
    }
    Ok(out)
}

/// Pooled validation error over a leave-one-out study: `‖τ̂−τ‖/‖τ‖` over all held-out files,
/// per joint and overall, for the `before` and `after` models.
pub fn pooled_validation(outcomes: &[Outcome]) -> Option<(Errors, Errors)> {
    let n = outcomes.first()?.dof;
    let mut acc = [vec![0.0; n], vec![0.0; n]];
    let mut tss = vec![0.0; n];
    for o in outcomes {
        let p = o.predictions.as_ref()?;
        p.rows(0, p.len(), |_, tau, before, after| {
            for j in 0..n {
                acc[0][j] += (before[j] - tau[j]).powi(2);
                acc[1][j] += (after[j] - tau[j]).powi(2);
                tss[j] += tau[j].powi(2);
            }
        });
    }
    let mk = |s: &Vec<f64>| Errors {
        per_joint: (0..n).map(|j| (s[j] / tss[j]).sqrt()).collect(),
        overall: (s.iter().sum::<f64>() / tss.iter().sum::<f64>()).sqrt(),
    };
    Some((mk(&acc[0]), mk(&acc[1])))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn log(len: usize) -> Log {
        Log::from(crate::data::Trajectory {
            source: "log.csv".into(),
            dof: 1,
            t: (0..len).map(|k| k as f64 * 1e-3).collect(),
            q: (0..len).map(|k| k as f64).collect(),
            dq: None,
            ddq: None,
            tau: Some(vec![0.0; len]),
        })
    }

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

    #[test]
    fn short_training_sets_are_scanned_whole_long_ones_on_spread_pieces() {
        let short = vec![log(30_000), log(40_000)];
        let same = scan_pieces(&short);
        assert!(same
            .iter()
            .zip(&short)
            .all(|(a, b)| a.key() == b.key() && a.len() == b.len()));

        let long = vec![log(900_000), log(300_000)];
        let pieces = scan_pieces(&long);
        assert_eq!(pieces.len(), 2 * SCAN_PIECES);
        let total: usize = pieces.iter().map(|p| p.len()).sum();
        assert!(
            total <= SCAN_SAMPLES && total > SCAN_SAMPLES * 9 / 10,
            "{total}"
        );
        // Proportional to the files, evenly spread over each, in order, rows copied intact.
        let first: Vec<&Log> = pieces[..SCAN_PIECES].iter().collect();
        assert_eq!(first[0].len(), 3 * pieces[SCAN_PIECES].len());
        let starts: Vec<f64> = first.iter().map(|p| p.read(0, 1).q[0]).collect();
        assert!(starts[0] > 0.0 && starts[3] + first[3].len() as f64 <= 900_000.0);
        let step = starts[1] - starts[0];
        assert!(starts.windows(2).all(|w| w[1] - w[0] == step) && step > 200_000.0);
        assert!(first[1]
            .read(0, first[1].len())
            .q
            .iter()
            .enumerate()
            .all(|(i, &v)| v == starts[1] + i as f64));
        assert!(first[0].source.starts_with("log.csv[rows "));
    }
}
