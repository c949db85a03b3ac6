//! Regression rows of one state: `[Yb(q, q̇, q̈) | effect columns]` per joint, the load-dependent
//! columns from the first-stage model's torque ([`Rows`]). Used by the regression and by every
//! prediction.

use rayon::prelude::*;

use super::base::{self, BaseModel};
use super::layout::Layout;
use super::ls;
use super::prepare::{cores, Prepared};
use crate::derivative::States;

/// Fills regression rows for one state into its own buffer, `row[j * ncols + c]`. A joint's row
/// holds zeros in the other joints' effect columns: they are never written, so the buffer is
/// zeroed once, not per state.
pub(super) struct Rows<'a> {
    base: &'a BaseModel,
    pub(super) layout: &'a Layout,
    scratch: base::Scratch,
    yb: Vec<f64>,
    /// The rows of the last state.
    row: Vec<f64>,
    /// State buffers of [`Rows::fill_grid`].
    q: Vec<f64>,
    dq: Vec<f64>,
    ddq: Vec<f64>,
}

impl<'a> Rows<'a> {
    pub(super) fn new(base: &'a BaseModel, layout: &'a Layout) -> Self {
        Rows {
            base,
            layout,
            scratch: base.scratch(),
            yb: vec![0.0; layout.dof * layout.nb],
            row: vec![0.0; layout.dof * layout.ncols()],
            q: vec![0.0; layout.dof],
            dq: vec![0.0; layout.dof],
            ddq: vec![0.0; layout.dof],
        }
    }

    /// Rows at grid sample `k` of estimated states `st`.
    pub(super) fn fill_grid(&mut self, st: &States, k: usize) -> &[f64] {
        let i = k - st.lo;
        for j in 0..self.layout.dof {
            (self.q[j], self.dq[j], self.ddq[j]) = (st.q[j][i], st.dq[j][i], st.ddq[j][i]);
        }
        let (q, dq, ddq) = (
            std::mem::take(&mut self.q),
            std::mem::take(&mut self.dq),
            std::mem::take(&mut self.ddq),
        );
        self.fill(&q, &dq, &ddq);
        (self.q, self.dq, self.ddq) = (q, dq, ddq);
        &self.row
    }

    fn fill(&mut self, q: &[f64], dq: &[f64], ddq: &[f64]) {
        let (n, nb, nc) = (self.layout.dof, self.layout.nb, self.layout.ncols());
        self.base.eval(&mut self.scratch, q, dq, ddq, &mut self.yb);
        let out = &mut self.row;
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

/// A file's unfiltered regression rows (and measured torque) on its whole grid, per joint its active columns
/// (`rows[j][k · a_j + l]` for joint `j`'s `l`-th active column at grid sample `k`): evaluated
/// once per cut-off and read by every pass the cut-off scan makes over them (the fits with both
/// regression filters and their predictions), where each pass evaluated the regressor anew.
#[derive(Debug)]
pub(super) struct RowTable {
    widths: Vec<usize>,
    rows: Vec<Vec<f64>>,
    /// The measured torque on the grid, per joint.
    tau: Vec<Vec<f64>>,
}

/// Largest [`RowTable`]s the cut-off scan keeps (bytes, all files of one cut-off): beyond it the
/// passes evaluate the rows themselves (memory stays bounded whatever the arm).
pub(super) const ROW_TABLE_BYTES: usize = 48 << 20;

impl RowTable {
    /// Bytes of the table of `p` with `layout`'s active columns (and the torque).
    pub(super) fn bytes(p: &Prepared, layout: &Layout) -> usize {
        let width: usize = (0..layout.dof).map(|j| layout.active(j).len() + 1).sum();
        p.est.grid.n * width * std::mem::size_of::<f64>()
    }

    /// The rows of `p`'s whole grid (chunks in parallel, each from its own window of states).
    pub(super) fn new(p: &Prepared, base: &BaseModel, layout: &Layout) -> RowTable {
        let n = layout.dof;
        let active: Vec<Vec<usize>> = (0..n).map(|j| layout.active(j)).collect();
        let widths: Vec<usize> = active.iter().map(Vec::len).collect();
        let nc = layout.ncols();
        // Per chunk: each joint's rows, each joint's torque.
        type Part = (Vec<Vec<f64>>, Vec<Vec<f64>>);
        let parts: Vec<Part> = cores(p, 0, p.est.grid.n)
            .par_iter()
            .map(|&(a, b)| {
                let mut rows = Rows::new(base, layout);
                let st = p.states(a, b);
                let tau = p.grid_tau(a, b);
                let mut out: Vec<Vec<f64>> = widths
                    .iter()
                    .map(|w| Vec::with_capacity(w * (b - a)))
                    .collect();
                for k in a..b {
                    let buf = rows.fill_grid(&st, k);
                    for (j, o) in out.iter_mut().enumerate() {
                        o.extend(active[j].iter().map(|&c| buf[j * nc + c]));
                    }
                }
                (out, tau)
            })
            .collect();
        let g = p.est.grid.n;
        let mut table: Vec<Vec<f64>> = widths.iter().map(|w| Vec::with_capacity(w * g)).collect();
        let mut tau: Vec<Vec<f64>> = (0..n).map(|_| Vec::with_capacity(g)).collect();
        for (part, t) in parts {
            for (dst, o) in table.iter_mut().zip(part) {
                dst.extend(o);
            }
            for (dst, o) in tau.iter_mut().zip(t) {
                dst.extend(o);
            }
        }
        RowTable {
            widths,
            rows: table,
            tau,
        }
    }

    /// Joint `j`'s measured torque on grid samples `lo..hi`.
    pub(super) fn tau(&self, j: usize, lo: usize, hi: usize) -> &[f64] {
        &self.tau[j][lo..hi]
    }

    /// Joint `j`'s active columns at grid sample `k`.
    pub(super) fn row(&self, j: usize, k: usize) -> &[f64] {
        let w = self.widths[j];
        &self.rows[j][k * w..(k + 1) * w]
    }
}
