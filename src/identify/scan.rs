//! Stage 0, **the cut-off and smoothing scan** ([`choose_cutoff`]): candidate derivative
//! cut-offs from the spectrum, each with every [`Smoothing`], judged by held-out error against
//! the measured torque; long training sets are scanned on evenly spaced pieces
//! ([`scan_pieces`]).

use std::f64::consts::SQRT_2;
use std::sync::Arc;

use rayon::prelude::*;
use serde::Serialize;

use super::base::BaseModel;
use super::columns::make_layout;
use super::evaluate::heldout_per_filter;
use super::layout::Layout;
use super::load_stage::LoadModel;
use super::prepare::{PrepCache, Prepared, Smoothing};
use super::problem::Problem;
use super::row_table::{GridBaseCache, RowTable};
use super::{Config, IdentifyError, MIN_SAMPLES};
use crate::effects::Term;
use crate::log::Log;

/// Most samples the cut-off scan fits per cut-off: longer training sets are scanned on
/// [`SCAN_PIECES`] evenly spaced pieces of each file (the final fit uses every sample).
pub const SCAN_SAMPLES: usize = 100_000;

/// Pieces per file of the cut-off scan of a long training set.
pub const SCAN_PIECES: usize = 4;

/// How the cut-off scan samples a long training set.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ScanSampling {
    /// Evenly spaced pieces of each training file.
    pub pieces_per_file: usize,
    /// Samples in all.
    pub samples: usize,
}

/// How the scan samples `train`: `None` when it fits the files whole (see [`scan_pieces`]).
pub fn scan_sampling(train: &[Log]) -> Option<ScanSampling> {
    let total: usize = train.iter().map(|t| t.len()).sum();
    (total > SCAN_SAMPLES).then_some(ScanSampling {
        pieces_per_file: SCAN_PIECES,
        samples: SCAN_SAMPLES,
    })
}

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

/// The automatic cut-off: the spectral rule ([`crate::derivative::auto_cutoff`], largest over
/// files) proposes the centre of a grid of octaves over a real range (`cutoff_grid`), and half
/// an octave either side of the grid's best is tried too (only the given cut-off with
/// `--cutoff`); each cut-off with every
/// [`Smoothing`] (regression filter at 1 or ½ of the cut-off, predictions from the filtered
/// rows or from the states), and the combination with the smallest held-out error against the
/// measured torque wins (rigid model plus every candidate effect, leave-one-block-out, the same
/// samples for every trial; each unit's joints pooled on their own, weak joints left out:
/// [`super::weak::unit_groups`]). Too low a cut-off distorts the motion; too high a one lets noise
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
            let fs = first
                .iter()
                .map(|p| p.est.report.fs_hz)
                .fold(f64::INFINITY, f64::min);
            let proposal = first
                .iter()
                .map(|p| p.est.report.cutoff_hz)
                .fold(0.0, f64::max);
            cutoff_grid(proposal, fs)
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
    let scan_files: Vec<Result<Prepared, IdentifyError>> = scan_pieces(train)
        .into_par_iter()
        .map(|t| Prepared::with_cutoff(t, cfg, Some(lowest), Smoothing::default(), None))
        .collect();
    let scan_files: Vec<Prepared> = scan_files.into_iter().collect::<Result<_, _>>()?;
    let all: Vec<Term> = layout.terms.clone();
    // Each unit's joints pooled on their own and weak joints left out, as the reports do: a
    // prismatic joint's newtons would otherwise choose the cut-off for the arm's newton-metres.
    let weak = super::weak::quantised(&first, base.dof());
    let groups = super::weak::unit_groups(table, base.dof(), &weak);
    let scan = Scan {
        base,
        layout: &layout,
        files: &scan_files,
        cfg,
        edge_fc,
        all: &all,
        ratios: &ratios,
        modes: &modes,
        grids: &cache.grids,
        groups,
    };
    let what = if load.is_some() {
        "cut-off scan again, with the load-dependent friction found"
    } else {
        "cut-off scan"
    };
    cfg.progress.stage(what, grid.len() as u64);
    let mut trials = scan.run(&grid)?;
    // Half a step either side of the coarse grid's best.
    if grid.len() > 1 {
        if let Some(best) = best_trial(&trials).map(|b| b.cutoff_hz) {
            let (lo, hi) = (grid[0], grid[grid.len() - 1]);
            let near: Vec<f64> = [best / SQRT_2, best * SQRT_2]
                .into_iter()
                .filter(|fc| (lo..=hi).contains(fc))
                .collect();
            cfg.progress.more(near.len() as u64);
            trials.extend(scan.run(&near)?);
        }
    }
    let choice = best_trial(&trials).map_or(fallback, |b| FilterChoice {
        cutoff_hz: Some(b.cutoff_hz),
        smoothing: b.smoothing,
    });
    trials.sort_by(|a, b| a.cutoff_hz.total_cmp(&b.cutoff_hz));
    Ok((choice, trials))
}

/// What every trial of one scan shares.
struct Scan<'a> {
    base: &'a BaseModel,
    layout: &'a Layout,
    /// The files scanned, prepared once (each trial re-filters them at its cut-off).
    files: &'a [Prepared],
    cfg: &'a Config,
    edge_fc: f64,
    /// Every candidate term (the scan's models fit all that the data tell apart).
    all: &'a [Term],
    ratios: &'a [f64],
    /// Predictions judged: from the filtered rows or not.
    modes: &'a [bool],
    /// The files' states and base regressor per cut-off, shared with other scans of them.
    grids: &'a GridBaseCache,
    /// Joints pooled together in the held-out error ([`super::weak::unit_groups`]).
    groups: Vec<Vec<usize>>,
}

impl Scan<'_> {
    /// The trials of cut-offs `fcs`, in parallel, in order.
    fn run(&self, fcs: &[f64]) -> Result<Vec<CutoffTrial>, IdentifyError> {
        let done: Vec<Result<Vec<CutoffTrial>, IdentifyError>> =
            fcs.par_iter().map(|&fc| self.cutoff(fc)).collect();
        let mut out = Vec::new();
        for d in done {
            out.extend(d?);
        }
        Ok(out)
    }

    /// One cut-off: each regression ratio's problem, both predictions judged on it — all ratios'
    /// problems built in one pass over the rows and judged in one more (the rows are the same
    /// for every ratio), or from a table of the rows when they fit in
    /// [`super::rows::ROW_TABLE_BYTES`].
    fn cutoff(&self, fc: f64) -> Result<Vec<CutoffTrial>, IdentifyError> {
        let sm = |ratio| Smoothing {
            regression_ratio: ratio,
            filtered_prediction: false,
        };
        // Not cached: one cut-off's estimates at a time per thread (memory stays that of one
        // copy per core).
        let prepare = |ratio| -> Result<Vec<Prepared>, IdentifyError> {
            self.files
                .iter()
                .map(|f| f.at_cutoff(self.cfg, fc, sm(ratio), Some(self.edge_fc)))
                .collect()
        };
        let mut tables: Option<Vec<Arc<RowTable>>> = None;
        // Every regression ratio's files (the same rows: the table, if any, is shared) ...
        let mut variants: Vec<Vec<Prepared>> = Vec::new();
        for &ratio in self.ratios {
            let mut preps = prepare(ratio)?;
            if tables.is_none() {
                tables = RowTable::for_files(self.base, self.layout, &preps, self.grids);
            }
            if let Some(t) = &tables {
                for (p, t) in preps.iter_mut().zip(t) {
                    p.rows = Some(Arc::clone(t));
                }
            }
            variants.push(preps);
        }
        // ... their problems built from one evaluation of the rows, and then all of them judged
        // in one more pass.
        let shared: Vec<&[Prepared]> = variants.iter().map(Vec::as_slice).collect();
        let problems = Problem::build_variants(self.base, self.layout, &shared, self.cfg.blocks);
        let mut fitted = Vec::new();
        for ((&ratio, preps), problem) in self.ratios.iter().zip(variants).zip(problems) {
            let subset = problem.independent(&problem.subset(self.all));
            let Ok(w) = problem.weights(&subset) else {
                continue;
            };
            let Ok(loo) = problem.loo_fits(&subset, &w) else {
                continue;
            };
            // Only the fits are kept (each problem is dropped here).
            fitted.push(RatioFit {
                ratio,
                files: preps,
                blocks: problem.raw_blocks().to_vec(),
                subset,
                loo,
            });
        }
        let Some(first) = fitted.first().map(|f| &f.blocks) else {
            self.cfg.progress.step();
            return Ok(Vec::new());
        };
        // The same files and blocks (the kept samples do not depend on the ratio).
        debug_assert!(fitted.iter().all(|f| f.blocks == *first));
        let variants: Vec<&[Prepared]> = fitted.iter().map(|f| f.files.as_slice()).collect();
        let subsets: Vec<&[usize]> = fitted.iter().map(|f| f.subset.as_slice()).collect();
        let loo: Vec<&[Vec<f64>]> = fitted.iter().map(|f| f.loo.as_slice()).collect();
        let errors = heldout_per_filter(
            self.base,
            self.layout,
            &variants,
            first,
            &self.groups,
            &subsets,
            &loo,
        );
        let mut out = Vec::new();
        for (RatioFit { ratio, .. }, (states, filtered)) in fitted.iter().zip(errors) {
            for (mode, e) in [(false, states), (true, filtered)] {
                if self.modes.contains(&mode) {
                    out.push(CutoffTrial {
                        cutoff_hz: fc,
                        smoothing: Smoothing {
                            filtered_prediction: mode,
                            ..sm(*ratio)
                        },
                        heldout_error: e,
                    });
                }
            }
        }
        self.cfg.progress.step();
        Ok(out)
    }
}

/// One regression ratio's fit at a scanned cut-off: what judging it needs.
struct RatioFit {
    ratio: f64,
    /// The files prepared with this ratio's regression filter.
    files: Vec<Prepared>,
    /// Time blocks per file.
    blocks: Vec<usize>,
    /// The columns fitted and the fit without each block, block by block.
    subset: Vec<usize>,
    loo: Vec<Vec<f64>>,
}

/// Lowest derivative cut-off the scan tries (Hz), unless the spectrum proposes less: robot
/// motion has content up to a few hertz, so lower cut-offs only distort it (the held-out error
/// says so); a slow arm's spectrum extends the range down.
pub const SCAN_LOWEST_HZ: f64 = 0.5;

/// Highest derivative cut-off the scan tries, as a share of the sampling rate.
pub const SCAN_HIGHEST_PER_FS: f64 = 0.2;

/// The coarse grid of the automatic cut-off: the spectral rule's `proposal` times powers of 2,
/// from [`SCAN_LOWEST_HZ`] (or a quarter of the proposal, if lower) to
/// [`SCAN_HIGHEST_PER_FS`]` · fs` — a real range whatever the spectrum says, because jittery or
/// resampled timestamps and a drive's velocity column can put its motion band anywhere (a
/// 500 Hz log with 20 % timing jitter reads as motion up to 250 Hz). The proposal is clamped
/// into the range.
pub fn cutoff_grid(proposal: f64, fs: f64) -> Vec<f64> {
    let hi = SCAN_HIGHEST_PER_FS * fs;
    if !(hi.is_finite() && hi > 0.0) {
        return Vec::new();
    }
    let p = if proposal.is_finite() && proposal > 0.0 {
        proposal.min(hi)
    } else {
        hi / 8.0
    };
    let lo = SCAN_LOWEST_HZ.min(p / 4.0);
    let mut f = p;
    while f / 2.0 >= lo * (1.0 - 1e-9) {
        f /= 2.0;
    }
    let mut grid = Vec::new();
    while f <= hi * (1.0 + 1e-9) {
        grid.push(f);
        f *= 2.0;
    }
    grid
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::log::Log;

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
    fn the_cutoff_grid_spans_a_real_range_whatever_the_spectrum_proposes() {
        // A sensible proposal: octaves through it, from 0.5 Hz to 0.2·fs.
        let g = cutoff_grid(3.0, 500.0);
        assert_eq!(g, vec![0.75, 1.5, 3.0, 6.0, 12.0, 24.0, 48.0, 96.0]);
        // Jitter read as motion up to 250 Hz at 500 Hz: the proposal is clamped, the range kept.
        let g = cutoff_grid(248.6, 500.0);
        assert_eq!((g[0], *g.last().unwrap(), g.len()), (0.78125, 100.0, 8));
        // A slow arm's spectrum extends it down; 100 Hz and 2 kHz logs alike.
        assert_eq!(cutoff_grid(0.8, 100.0)[0], 0.2);
        assert!(cutoff_grid(0.8, 100.0).last().unwrap() <= &20.0);
        let g = cutoff_grid(10.0, 2000.0);
        assert!(
            g[0] >= 0.5 && g[0] < 1.0 && *g.last().unwrap() <= 400.0 && g.len() == 10,
            "{g:?}"
        );
        // No proposal (flat spectrum): still the range.
        assert!(cutoff_grid(f64::NAN, 1000.0).len() >= 8);
        assert!(cutoff_grid(5.0, f64::NAN).is_empty());
    }

    #[test]
    fn a_row_table_gives_the_fits_and_errors_of_rows_evaluated_pass_by_pass() {
        use crate::effects::Effect;
        use crate::identify::synth::{generate, Spec};
        let arm = crate::arms::resolve("planar2").unwrap();
        let table = arm.dh_table().unwrap();
        let mut spec = Spec::new(table.clone(), 5).with_effect(Effect::Coulomb, 0, 0.8);
        spec.duration = 12.0;
        spec.jitter = 0.1;
        let log = Log::from(generate(&spec));
        let base = BaseModel::for_arm(&arm);
        let cfg = Config::default();
        let sm = Smoothing {
            regression_ratio: 0.5,
            filtered_prediction: false,
        };
        let plain = vec![Prepared::with_cutoff(log, &cfg, Some(6.0), sm, None).unwrap()];
        let layout = make_layout(&base, Some(&table), &plain, &cfg).0;
        let mut tabled = plain.clone();
        tabled[0].rows = Some(Arc::new(RowTable::new(&plain[0], &base, &layout, None)));
        let judge = |preps: &[Prepared]| {
            let p = Problem::build(&base, layout.clone(), preps, cfg.blocks);
            let subset = p.subset(&layout.terms);
            let w = p.weights(&subset).unwrap();
            let x = p.fit(&subset, &w).unwrap().x;
            let (s, f) = p.cv_raw_both(&base, preps, &subset, &w).unwrap();
            (x, s, f)
        };
        let (a, b) = (judge(&plain), judge(&tabled));
        // The table's rows come from windows of states over other margins: equal to ~1e-7 of
        // the signal (estimator.rs), so fits and errors agree far below anything reported.
        let close = |u: f64, v: f64| (u - v).abs() <= 1e-7 * u.abs().max(v.abs()).max(1e-12);
        assert!(
            a.0.iter().zip(&b.0).all(|(u, v)| close(*u, *v)),
            "{:?} {:?}",
            a.0,
            b.0
        );
        assert!(close(a.1, b.1) && close(a.2, b.2), "{a:?} {b:?}");
        // And the filtered prediction is not the states' one (the two passes differ).
        assert!((a.1 - a.2).abs() > 1e-6 * a.1, "{a:?}");
        // A table of another layout's rows (another training set's friction scales) is not
        // read: the passes evaluate the rows themselves, bit for bit as without a table.
        let mut other = layout.clone();
        other.scales[0] = crate::effects::Scales::from_rms_velocity(3.0);
        let mut stale = plain.clone();
        stale[0].rows = Some(Arc::new(RowTable::new(&plain[0], &base, &other, None)));
        assert_eq!(judge(&stale), a);
    }

    /// The scan builds every regression ratio's problem of a cut-off in one pass over the rows
    /// and judges them all in another: the same fits and held-out errors as each ratio's
    /// problem built and judged on its own.
    #[test]
    fn one_pass_builds_and_one_judges_every_ratio_as_each_would_be_alone() {
        use crate::effects::Effect;
        use crate::identify::synth::{generate, Spec};
        let arm = crate::arms::resolve("planar2").unwrap();
        let table = arm.dh_table().unwrap();
        let mut spec = Spec::new(table.clone(), 7).with_effect(Effect::Viscous, 1, 0.3);
        spec.duration = 40.0;
        spec.rate_hz = 500.0;
        let log = Log::from(generate(&spec));
        let base = BaseModel::for_arm(&arm);
        let cfg = Config::default();
        let (fc, edge) = (2.0, Some(1.0));
        let prep = |ratio| {
            let sm = Smoothing {
                regression_ratio: ratio,
                filtered_prediction: false,
            };
            vec![Prepared::with_cutoff(log.clone(), &cfg, Some(fc), sm, edge).unwrap()]
        };
        let (a, b) = (prep(1.0), prep(0.5));
        // The two filters' windows differ (so the shared pass lays them out by the wider).
        assert!(b[0].rfilter.as_zero_phase().reach() > a[0].rfilter.as_zero_phase().reach());
        let layout = make_layout(&base, Some(&table), &a, &cfg).0;
        let alone = |preps: &[Prepared]| {
            let p = Problem::build(&base, layout.clone(), preps, cfg.blocks);
            let subset = p.independent(&p.subset(&layout.terms));
            let w = p.weights(&subset).unwrap();
            let errors = p.cv_raw_both(&base, preps, &subset, &w).unwrap();
            let loo = p.loo_fits(&subset, &w).unwrap();
            let x = p.fit(&subset, &w).unwrap().x;
            (errors, subset, loo, p.raw_blocks().to_vec(), (w, x))
        };
        let ((ea, sa, la, blocks, fa), (eb, sb, lb, _, fb)) = (alone(&a), alone(&b));
        // Both problems built from one evaluation of the rows: the fits of each built alone.
        let built = Problem::build_variants(&base, &layout, &[&a, &b], cfg.blocks);
        for ((p, subset), (w, x)) in built.iter().zip([&sa, &sb]).zip([&fa, &fb]) {
            let got = p.fit(subset, w).unwrap().x;
            let close = |u: f64, v: f64| (u - v).abs() <= 1e-7 * u.abs().max(v.abs()).max(1e-9);
            assert!(
                got.iter().zip(x).all(|(u, v)| close(*u, *v)),
                "{got:?} {x:?}"
            );
        }
        assert!(fa
            .1
            .iter()
            .zip(&fb.1)
            .any(|(u, v)| (u - v).abs() > 1e-6 * u.abs()));
        let both = heldout_per_filter(
            &base,
            &layout,
            &[&a, &b],
            &blocks,
            &[vec![0, 1]],
            &[&sa, &sb],
            &[&la, &lb],
        );
        // Windows of other margins: the filters' truncation (~1.5e-8 of the signal) and the
        // states' windows (~1e-7 of its range, estimator.rs) bound the difference.
        let close = |u: f64, v: f64| (u - v).abs() <= 1e-7 * u.abs().max(v.abs());
        for (got, want) in both.iter().zip([ea, eb]) {
            assert!(
                close(got.0, want.0) && close(got.1, want.1),
                "{got:?} {want:?}"
            );
        }
        // Four different numbers: a mix-up of ratios or predictions would show.
        assert!(
            (ea.0 - eb.0).abs() > 1e-6 * ea.0 && (ea.0 - ea.1).abs() > 1e-6 * ea.0,
            "{ea:?} {eb:?}"
        );
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
