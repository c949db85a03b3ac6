//! Regression rows of one state: `[Yb(q, q̇, q̈) | effect columns]` per joint, the load-dependent
//! columns from the first-stage model's torque ([`Rows`]). Used by the regression and by every
//! prediction.

use super::base::{self, BaseModel};
use super::layout::Layout;
use super::ls;
use crate::derivative::States;

/// Fills regression rows for one state: `out[j * ncols + c]`.
pub(super) struct Rows<'a> {
    base: &'a BaseModel,
    pub(super) layout: &'a Layout,
    scratch: base::Scratch,
    yb: Vec<f64>,
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
            q: vec![0.0; layout.dof],
            dq: vec![0.0; layout.dof],
            ddq: vec![0.0; layout.dof],
        }
    }

    /// Rows at grid sample `k` of estimated states `st`.
    pub(super) fn fill_grid(&mut self, st: &States, k: usize, out: &mut [f64]) {
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

    pub(super) fn fill(&mut self, q: &[f64], dq: &[f64], ddq: &[f64], out: &mut [f64]) {
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
