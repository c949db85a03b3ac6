//! The streaming estimator: set up once per file (sampling, grid, cut-off, filter), then run
//! window by window.

use super::{DerivativeReport, Filter, Method, Options, States, SPECTRUM_PIECES, SPECTRUM_WHOLE};
use rayon::prelude::*;

use crate::data::Trajectory;
use crate::log::Log;
use crate::signal::{
    auto_cutoff, resample_linear, ChannelSpectrum, DerivativeError, Grid, Psd, Sampling, PIECE,
};

/// The estimator of one file, set up once (sampling, grid, cut-off, filter) and then run window
/// by window ([`Estimator::window`]) on the file's [`Log`], so no copy of the whole log — raw
/// or estimated — is ever needed: each window reads the raw rows it covers plus the filter's
/// reach of margin on both sides, which makes it equal to estimating the whole signal at once
/// to ~1e-7 of the signal's range (test: 7e-8).
#[derive(Debug, Clone)]
pub struct Estimator {
    pub grid: Grid,
    pub filter: Filter,
    pub report: DerivativeReport,
    /// A q̇ column of the file is filtered (instead of differentiating q).
    use_dq: bool,
    /// Derivatives taken from the file as they are (it has q̇ and q̈).
    given: bool,
}

impl Estimator {
    /// Checks the samples and sets up the estimator (cut-off automatic from the spectrum unless
    /// given) — see the module docs. A q̇ column is filtered if `file_velocity` (else q is
    /// differentiated); a file with both q̇ and q̈ columns is used as given.
    pub fn new(log: &Log, file_velocity: bool, opts: &Options) -> Result<Self, DerivativeError> {
        let l = log.layout;
        let given = l.dq && l.ddq;
        let use_dq = l.dq && (file_velocity || given);
        let sampling = Sampling::of_log(log)?;
        // The channels used, as offsets of their blocks in the row (channel c·dof + j + 1).
        let n_j = l.dof;
        let used: Vec<usize> = [(true, 1), (use_dq, 1 + n_j), (given, 1 + 2 * n_j)]
            .into_iter()
            .filter_map(|(u, at)| u.then_some(at))
            .collect();
        let (mut r, mut bad) = (0, None);
        log.rows(0, log.len(), |row| {
            if bad.is_none() {
                for (c, &at) in used.iter().enumerate() {
                    if let Some(j) = row[at..at + n_j].iter().position(|v| !v.is_finite()) {
                        bad = Some(DerivativeError::NonFinite {
                            channel: c * n_j + j + 1,
                            row: r,
                        });
                        break;
                    }
                }
            }
            r += 1;
        });
        if let Some(e) = bad {
            return Err(e);
        }
        let grid = grid_for_log(log, &sampling);
        let fs = 1.0 / grid.dt;
        let reader = Reader {
            grid,
            uniform: sampling.uniform,
        };
        let (fc, per_channel) = match opts.cutoff_hz {
            Some(fc) => (fc, Vec::new()),
            None => reader.auto_cutoff(log, use_dq && !given),
        };
        let filter = Filter::lowpass(opts.method, fc, fs)?;
        let (dq_source, ddq_source) = match (use_dq, given) {
            (_, true) => ("file (as given)", "file (as given)"),
            (true, false) => ("file, filtered", "differentiated filtered dq"),
            (false, false) => ("differentiated q", "differentiated q"),
        };
        let report = DerivativeReport {
            method: opts.method,
            filter: filter.as_zero_phase().describe(),
            cutoff_hz: fc,
            cutoff_auto: opts.cutoff_hz.is_none(),
            per_channel,
            sampling,
            resampled: !sampling.uniform,
            dq_source: dq_source.into(),
            ddq_source: ddq_source.into(),
            fs_hz: fs,
        };
        Ok(Estimator {
            grid,
            filter,
            report,
            use_dq,
            given,
        })
    }

    /// This estimator with the given cut-off (`method`'s filter): what [`Estimator::new`] with
    /// `cutoff_hz: Some(fc)` returns for the same log, without reading the log again (the
    /// sampling, grid and checks do not depend on the cut-off).
    pub fn with_cutoff(&self, method: Method, fc: f64) -> Result<Self, DerivativeError> {
        let filter = Filter::lowpass(method, fc, self.report.fs_hz)?;
        let mut report = self.report.clone();
        report.method = method;
        report.filter = filter.as_zero_phase().describe();
        report.cutoff_hz = fc;
        report.cutoff_auto = false;
        report.per_channel = Vec::new();
        Ok(Estimator {
            grid: self.grid,
            filter,
            report,
            use_dq: self.use_dq,
            given: self.given,
        })
    }

    fn reader(&self) -> Reader {
        Reader {
            grid: self.grid,
            uniform: self.report.sampling.uniform,
        }
    }

    /// The measured torque of `log` on grid samples `lo..hi`, per joint.
    pub fn tau_on_grid(&self, log: &Log, lo: usize, hi: usize) -> Vec<Vec<f64>> {
        let w = self.reader().rows_for(log, lo, hi);
        let tau = w.rows.tau.as_deref().unwrap_or(&[]);
        self.reader().on_grid(&w, tau, lo, hi)
    }

    /// Estimated states of `log` on grid samples `lo..hi`.
    pub fn window(&self, log: &Log, lo: usize, hi: usize) -> States {
        let n = self.grid.n;
        let margin = if self.given {
            0
        } else {
            self.filter.as_zero_phase().reach() + 4
        };
        let (mut elo, mut ehi) = (lo.saturating_sub(margin), (hi + margin).min(n));
        // A short window at an end still gets a full margin on its inner side (end treatments
        // such as a Savitzky–Golay end fit or the padding length depend on the length).
        let span = 2 * margin + 1;
        if ehi - elo < span {
            if elo == 0 {
                ehi = span.min(n);
            } else {
                elo = ehi.saturating_sub(span);
            }
        }
        let (pad_left, pad_right) = (elo == 0, ehi == n);
        let dt = self.grid.dt;
        let r = self.reader();
        let w = r.rows_for(log, elo, ehi);
        let g = |x: &[f64]| r.on_grid(&w, x, elo, ehi);
        let qg = g(&w.rows.q);
        let dqg = w.rows.dq.as_deref().filter(|_| self.use_dq).map(g);
        let ddqg = w.rows.ddq.as_deref().filter(|_| self.given).map(g);
        let keep = lo - elo..hi - elo;
        let [q, dq, ddq] = match (dqg, ddqg) {
            (Some(d), Some(dd)) if self.given => {
                [qg, d, dd].map(|c| c.into_iter().map(|x| x[keep.clone()].to_vec()).collect())
            }
            (dqg, _) => self
                .filter
                .as_zero_phase()
                .derivatives_many(qg, dqg, dt, pad_left, pad_right, keep),
        };
        States { lo, dt, q, dq, ddq }
    }
}

/// How a log's raw rows map onto an estimator's grid.
#[derive(Debug, Clone, Copy)]
struct Reader {
    grid: Grid,
    uniform: bool,
}

impl Reader {
    /// The spectrum's cut-off ([`auto_cutoff`]) over the positions, and over the q̇ channels
    /// if `integrate_dq` (integrated, so their spectrum is judged like q's by one rule).
    fn auto_cutoff(&self, log: &Log, integrate_dq: bool) -> (f64, Vec<ChannelSpectrum>) {
        let n = self.grid.n;
        let pieces: Vec<(usize, usize)> = if n <= SPECTRUM_WHOLE {
            vec![(0, n)]
        } else {
            let count = (n / PIECE).min(SPECTRUM_PIECES);
            let gap = (n - count * PIECE) / count;
            (0..count)
                .map(|i| {
                    let a = gap / 2 + i * (PIECE + gap);
                    (a, a + PIECE)
                })
                .collect()
        };
        let fs = 1.0 / self.grid.dt;
        // Each piece's spectra in parallel, summed in piece order (the same sums as one by one).
        let spectra: Vec<Vec<Psd>> = pieces
            .par_iter()
            .map(|&(lo, hi)| {
                let w = self.rows_for(log, lo, hi);
                let mut chans = self.on_grid(&w, &w.rows.q, lo, hi);
                if let (Some(d), true) = (&w.rows.dq, integrate_dq) {
                    for x in self.on_grid(&w, d, lo, hi) {
                        let mut acc = 0.0;
                        chans.push(
                            x.iter()
                                .map(|v| {
                                    acc += v * self.grid.dt;
                                    acc
                                })
                                .collect(),
                        );
                    }
                }
                chans.par_iter().map(|x| Psd::of(x, fs)).collect()
            })
            .collect();
        let mut psd: Vec<Option<Psd>> = Vec::new();
        for piece in spectra {
            psd.resize_with(piece.len(), || None);
            for (p, piece) in psd.iter_mut().zip(piece) {
                match p {
                    Some(p) => p.add(&piece),
                    None => *p = Some(piece),
                }
            }
        }
        let psd: Vec<Psd> = psd.into_iter().flatten().collect();
        auto_cutoff(&psd, fs, n)
    }

    /// The raw rows covering grid samples `lo..hi` (one more on each side if resampled), and
    /// the first one's index.
    fn rows_for(&self, log: &Log, lo: usize, hi: usize) -> Window {
        if self.uniform {
            return Window {
                r0: lo,
                rows: log.read(lo, hi),
            };
        }
        let g = &self.grid;
        let (t0, t1) = (g.time(lo), g.time(hi.max(lo + 1) - 1));
        let r0 = log.partition_point(|v| v <= t0).saturating_sub(1);
        let r1 = (log.partition_point(|v| v < t1) + 1).min(log.len() - 1);
        let (r0, r1) = (r0.min(r1.saturating_sub(1)), r1.max(1));
        Window {
            r0,
            rows: log.read(r0, r1 + 1),
        }
    }

    /// Channel `x` (row-major, of the window's rows) on grid samples `lo..hi`, per joint
    /// (resampled linearly if the sampling is uneven).
    fn on_grid(&self, w: &Window, x: &[f64], lo: usize, hi: usize) -> Vec<Vec<f64>> {
        let dof = w.rows.dof;
        if self.uniform {
            return (0..dof)
                .map(|j| (lo..hi).map(|k| x[(k - w.r0) * dof + j]).collect())
                .collect();
        }
        let sub = Grid {
            t0: self.grid.time(lo),
            dt: self.grid.dt,
            n: hi - lo,
        };
        (0..dof)
            .map(|j| {
                let xs: Vec<f64> = (0..w.rows.len()).map(|k| x[k * dof + j]).collect();
                resample_linear(&w.rows.t, &xs, &sub)
            })
            .collect()
    }
}

/// Raw rows of a log read for a window of grid samples: `rows` are the log's rows `r0..`.
struct Window {
    r0: usize,
    rows: Trajectory,
}

/// The uniform grid of a log: its samples themselves if uniform, else `[t0, t_end]` at the
/// median step (only the first and last times are read).
fn grid_for_log(log: &Log, s: &Sampling) -> Grid {
    let (t0, t1, n) = (log.t(0), log.t(log.len() - 1), log.len());
    if s.uniform {
        return Grid {
            t0,
            dt: (t1 - t0) / (n - 1) as f64,
            n,
        };
    }
    Grid {
        t0,
        dt: s.dt_median,
        n: ((t1 - t0) / s.dt_median).floor() as usize + 1,
    }
}
