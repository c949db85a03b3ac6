//! Stage 3, **regression**: a file's rows built chunk by chunk on its grid, parallel-filtered
//! (rows and τ, zero-phase), decimated to [`KEEP_RATE_PER_CUTOFF`] times the regression cut-off
//! and folded into incremental QR factors per time block and joint ([`accumulate_fit`]).

use rayon::prelude::*;

use super::base::BaseModel;
use super::layout::Layout;
use super::ls::Accumulator;
use super::prepare::{cores, Prepared};
use super::rows::Rows;

/// Rows of the filtered regression are kept at this many times the cut-off (Gautier's
/// decimation after parallel filtering): the filtered columns carry nothing above a few
/// cut-offs (a 4th-order zero-phase Butterworth is down 2.6e-6 at 5·fc), so sums over the
/// decimated rows equal those over all rows to that order, at a fraction of the cost.
pub const KEEP_RATE_PER_CUTOFF: f64 = 20.0;

/// Every how many grid samples a filtered regression row is kept.
pub(super) fn decimation(p: &Prepared) -> usize {
    let r = p.est.report.fs_hz / (KEEP_RATE_PER_CUTOFF * p.rfilter_hz);
    (r.floor() as usize).max(1)
}

/// Regression rows of one file on its grid around a core `a..b`: the grid samples `lo..hi`
/// (the core with the regression filter's reach on each side); per joint, row-major, its active
/// columns then τ: `rows[j][(k - lo) * (a_j + 1) + l]`.
struct Chunk {
    lo: usize,
    hi: usize,
    rows: Vec<Vec<f64>>,
}

impl Chunk {
    /// Unfiltered rows and the measured τ on the grid around the core `a..b`.
    fn new(p: &Prepared, rows: &mut Rows, active: &[Vec<usize>], (a, b): (usize, usize)) -> Chunk {
        let reach = p.rfilter.as_zero_phase().reach();
        let (lo, hi) = (a.saturating_sub(reach), (b + reach).min(p.est.grid.n));
        let w = hi - lo;
        let mut out: Vec<Vec<f64>> = active
            .iter()
            .map(|a| Vec::with_capacity((a.len() + 1) * w))
            .collect();
        match p.rows.as_deref().filter(|t| t.fits(rows.layout)) {
            Some(table) => {
                for (j, o) in out.iter_mut().enumerate() {
                    let tau = table.tau(j, lo, hi);
                    for k in lo..hi {
                        o.extend_from_slice(table.row(j, k));
                        o.push(tau[k - lo]);
                    }
                }
            }
            None => {
                let st = p.states(lo, hi);
                let tau = p.grid_tau(lo, hi);
                for k in lo..hi {
                    rows.append_active(&st, k, active, &mut out);
                    for (o, t) in out.iter_mut().zip(&tau) {
                        o.push(t[k - lo]);
                    }
                }
            }
        }
        debug_assert!(out
            .iter()
            .zip(active)
            .all(|(o, a)| o.len() == (a.len() + 1) * w));
        Chunk { lo, hi, rows: out }
    }

    /// Parallel filtering of one joint's row-major channels (all-zero channels are left as
    /// they are), only the rows `keep` (indices into the chunk) written to a new block.
    fn filter_joint(
        p: &Prepared,
        rows: &[f64],
        width: usize,
        lo: usize,
        hi: usize,
        keep: &[usize],
    ) -> Vec<f64> {
        // A column is known non-zero at its first non-zero value (almost always the first row).
        let cols: Vec<usize> = (0..width)
            .filter(|&c| rows.iter().skip(c).step_by(width).any(|&v| v != 0.0))
            .collect();
        let mut out = vec![0.0; keep.len() * width];
        p.rfilter.as_zero_phase().apply_rows(
            rows,
            width,
            &cols,
            lo == 0,
            hi == p.est.grid.n,
            keep,
            &mut out,
        );
        out
    }
}

/// Parallel-filtered regression of one file into `[block][joint]` accumulators, rows decimated
/// to [`KEEP_RATE_PER_CUTOFF`]·fc.
pub(super) fn accumulate_fit(
    p: &Prepared,
    base: &BaseModel,
    layout: &Layout,
    nblocks: usize,
) -> Vec<Vec<Accumulator>> {
    let mut all = accumulate_fits(&[p], base, layout, nblocks);
    all.pop().expect("one file variant in, one out")
}

/// [`accumulate_fit`] of the same file prepared with several regression filters (`variants`:
/// the same log, grid, states and kept samples), from one evaluation of its rows: chunks laid
/// out by the widest filter, each variant filtering its own reach of them.
pub(super) fn accumulate_fits(
    variants: &[&Prepared],
    base: &BaseModel,
    layout: &Layout,
    nblocks: usize,
) -> Vec<Vec<Vec<Accumulator>>> {
    let (n, nc) = (layout.dof, layout.ncols());
    let reach = |p: &Prepared| p.rfilter.as_zero_phase().reach();
    let Some(&p) = variants.iter().max_by_key(|p| reach(p)) else {
        return Vec::new();
    };
    // Per variant `[joint][block]` while accumulating, so joints run in parallel.
    let mut accs: Vec<Vec<Vec<Accumulator>>> = variants
        .iter()
        .map(|_| {
            layout
                .accumulators()
                .into_iter()
                .map(|a| vec![a; nblocks])
                .collect()
        })
        .collect();
    let active: Vec<Vec<usize>> = (0..n).map(|j| layout.active(j)).collect();
    let mut rows = Rows::for_log(base, layout, &p.log);
    let (k0, k1) = p.keep;
    let all = cores(p, k0, k1);
    // The next chunk's rows are evaluated while this one is filtered and folded in (the folding
    // stays in order, so the factors are the same bit for bit).
    let mut next = all.first().map(|&c| Chunk::new(p, &mut rows, &active, c));
    for (i, &(a, b)) in all.iter().enumerate() {
        let Some(chunk) = next.take() else { break };
        let fold = || {
            for (v, accs) in variants.iter().zip(accs.iter_mut()) {
                // This variant's own reach of the chunk's rows.
                let r = reach(v);
                let (lo, hi) = (a.saturating_sub(r).max(chunk.lo), (b + r).min(chunk.hi));
                let decim = decimation(v);
                let (keep, blocks): (Vec<usize>, Vec<usize>) = (a..b)
                    .filter(|&k| (k - k0) % decim == 0)
                    .map(|k| (k - lo, v.block_of(k, nblocks)))
                    .unzip();
                chunk
                    .rows
                    .par_iter()
                    .zip(accs.par_iter_mut())
                    .zip(active.par_iter())
                    .for_each(|((rj, acc), act)| {
                        let width = act.len() + 1;
                        let rj = &rj[(lo - chunk.lo) * width..(hi - chunk.lo) * width];
                        let kept = Chunk::filter_joint(v, rj, width, lo, hi, &keep);
                        let mut row = vec![0.0; nc + 1];
                        for (r, &blk) in kept.chunks_exact(width).zip(&blocks) {
                            for (l, &c) in act.iter().enumerate() {
                                row[c] = r[l];
                            }
                            row[nc] = r[act.len()];
                            acc[blk].push(&row);
                        }
                    });
            }
        };
        let ahead = || {
            all.get(i + 1)
                .map(|&c| Chunk::new(p, &mut rows, &active, c))
        };
        next = rayon::join(fold, ahead).1;
    }
    accs.into_iter()
        .map(|a| finish_transposed(a, nblocks))
        .collect()
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
