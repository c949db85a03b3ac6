//! Regression rows of one state: `[Yb(q, q̇, q̈) | effect columns]` per joint, the load-dependent
//! columns from the first-stage model's torque ([`Rows`]). Used by the regression and by every
//! prediction.

use std::sync::Arc;

use rayon::prelude::*;

use super::base::{self, BaseModel};
use super::dot;
use super::layout::Layout;
use super::prepare::{cores, Prepared};
use super::row_table::{
    BasePart, GridBase, GridBaseCache, RowTable, GRID_BASE_BYTES, ROW_TABLE_BYTES,
};
use crate::derivative::States;
use crate::effects::{JointState, Run};
use crate::log::Log;
use crate::pack::LANES;

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
    /// Base regressors of [`LANES`] consecutive states evaluated at once
    /// ([`BaseModel::eval_lanes`]), and each lane's state (q, q̇, q̈): the passes walk the grid
    /// in order, so three rows in four come from here — each only for the very state it was
    /// evaluated at (compared bit for bit), whoever asks.
    batch_yb: Vec<f64>,
    batch_state: Vec<f64>,
    batch_lanes: usize,
    /// Each joint's state for its effect columns (reused across states: no allocation).
    states: Vec<JointState>,
    /// The run of the file whose rows these are (read by the per-run columns).
    run: Run,
    /// Time from the run's start to the file's first sample (read by `drift`).
    run_time: f64,
}

impl<'a> Rows<'a> {
    /// Rows of `layout` for a file of recording `run` ([`crate::log::Log::run`]).
    pub(super) fn new(base: &'a BaseModel, layout: &'a Layout, run: &str) -> Self {
        Rows {
            run: layout.run_of(run),
            run_time: 0.0,
            base,
            layout,
            scratch: base.scratch(),
            yb: vec![0.0; layout.dof * layout.nb],
            row: vec![0.0; layout.dof * layout.ncols()],
            q: vec![0.0; layout.dof],
            dq: vec![0.0; layout.dof],
            ddq: vec![0.0; layout.dof],
            batch_yb: vec![0.0; LANES * layout.dof * layout.nb],
            batch_state: vec![0.0; LANES * 3 * layout.dof],
            batch_lanes: 0,
            states: Vec::with_capacity(layout.dof),
        }
    }

    /// Rows of `layout` for `log`: its run and its time since the run's start.
    pub(super) fn for_log(base: &'a BaseModel, layout: &'a Layout, log: &Log) -> Self {
        Rows {
            run_time: log.run_time(),
            ..Rows::new(base, layout, log.run())
        }
    }

    /// Rows at grid sample `k` of estimated states `st`.
    pub(super) fn fill_grid(&mut self, st: &States, k: usize) -> &[f64] {
        self.fill_grid_from(st, k, None)
    }

    /// [`Rows::fill_grid`] with the base regressor of the state given (`yb`, as
    /// [`BaseModel::eval`] writes it) instead of evaluated.
    fn fill_grid_with(&mut self, st: &States, k: usize, yb: &[f64]) -> &[f64] {
        self.fill_grid_from(st, k, Some(yb))
    }

    fn fill_grid_from(&mut self, st: &States, k: usize, yb: Option<&[f64]>) -> &[f64] {
        self.state_and_base(st, k, yb);
        let (q, dq, ddq) = (
            std::mem::take(&mut self.q),
            std::mem::take(&mut self.dq),
            std::mem::take(&mut self.ddq),
        );
        self.place(&q, &dq, &ddq, self.run_time + k as f64 * st.dt);
        (self.q, self.dq, self.ddq) = (q, dq, ddq);
        &self.row
    }

    /// Appends to `out[j]` joint `j`'s `active[j]` columns ([`Layout::active`]) at grid sample
    /// `k` of `st`: the values [`Rows::fill_grid`] puts there, written straight (no full row to
    /// gather from) unless the layout has load-dependent columns, whose torque is summed over
    /// the full row.
    pub(super) fn append_active(
        &mut self,
        st: &States,
        k: usize,
        active: &[Vec<usize>],
        out: &mut [Vec<f64>],
    ) {
        let (nb, nc) = (self.layout.nb, self.layout.ncols());
        if self.layout.terms.iter().any(|t| t.effect.needs_load()) {
            let buf = self.fill_grid(st, k);
            for (j, o) in out.iter_mut().enumerate() {
                let row = &buf[j * nc..(j + 1) * nc];
                o.extend(active[j].iter().map(move |&c| row[c]));
            }
            return;
        }
        self.state_and_base(st, k, None);
        let (terms, scales) = (&self.layout.terms, &self.layout.scales);
        let time = self.run_time + k as f64 * st.dt;
        for (j, o) in out.iter_mut().enumerate() {
            let (q, dq, ddq) = (self.q[j], self.dq[j], self.ddq[j]);
            // From locals moved into the closure: reading `self.yb` and `nb` through references
            // reloaded them for every element (the writes to `o` could alias them).
            let (yb, scale) = (&self.yb[j * nb..(j + 1) * nb], &scales[j]);
            let st = JointState::new(q, dq, ddq, scale).at(time).in_run(self.run);
            o.extend(active[j].iter().map(move |&c| match c.checked_sub(nb) {
                None => yb[c],
                Some(i) => terms[i].column_at(&st, 0.0),
            }));
        }
    }

    /// The state at grid sample `k` of `st` into `self.q`, `self.dq`, `self.ddq` and its base
    /// regressor into `self.yb` (`yb` if given, else evaluated).
    fn state_and_base(&mut self, st: &States, k: usize, yb: Option<&[f64]>) {
        let i = k - st.lo;
        for j in 0..self.layout.dof {
            (self.q[j], self.dq[j], self.ddq[j]) = (st.q[j][i], st.dq[j][i], st.ddq[j][i]);
        }
        let (q, dq, ddq) = (
            std::mem::take(&mut self.q),
            std::mem::take(&mut self.dq),
            std::mem::take(&mut self.ddq),
        );
        match yb {
            Some(yb) => self.yb.copy_from_slice(yb),
            None => self.eval_batched(st, i, &q, &dq, &ddq),
        }
        (self.q, self.dq, self.ddq) = (q, dq, ddq);
    }

    /// The base regressor of state `i` of `st` (`q`, `dq`, `ddq`) into `self.yb`: from the
    /// batch if it holds that state, else with the next states as a new batch where `st` has
    /// them and the kernels are lane-batched, else alone.
    fn eval_batched(&mut self, st: &States, i: usize, q: &[f64], dq: &[f64], ddq: &[f64]) {
        let (n, w) = (self.layout.dof, self.yb.len());
        let same = |a: &[f64], b: &[f64]| a.iter().zip(b).all(|(x, y)| x.to_bits() == y.to_bits());
        let held = (0..self.batch_lanes).find(|&l| {
            let s = &self.batch_state[l * 3 * n..(l + 1) * 3 * n];
            same(&s[..n], q) && same(&s[n..2 * n], dq) && same(&s[2 * n..], ddq)
        });
        if let Some(l) = held {
            self.yb.copy_from_slice(&self.batch_yb[l * w..(l + 1) * w]);
            return;
        }
        let len = st.q.first().map_or(0, Vec::len);
        if i + LANES <= len
            && self
                .base
                .eval_lanes(&mut self.scratch, st, i, &mut self.batch_yb)
        {
            for (l, s) in self.batch_state.chunks_exact_mut(3 * n).enumerate() {
                for j in 0..n {
                    (s[j], s[n + j], s[2 * n + j]) =
                        (st.q[j][i + l], st.dq[j][i + l], st.ddq[j][i + l]);
                }
            }
            self.batch_lanes = LANES;
            self.yb.copy_from_slice(&self.batch_yb[..w]);
        } else {
            self.base.eval(&mut self.scratch, q, dq, ddq, &mut self.yb);
        }
    }

    /// The rows from the base regressor in `self.yb` and the effect columns of the state, at time
    /// `time` since the start of the run.
    fn place(&mut self, q: &[f64], dq: &[f64], ddq: &[f64], time: f64) {
        let (n, nb, nc) = (self.layout.dof, self.layout.nb, self.layout.ncols());
        let out = &mut self.row;
        for j in 0..n {
            out[j * nc..j * nc + nb].copy_from_slice(&self.yb[j * nb..(j + 1) * nb]);
        }
        let terms = &self.layout.terms;
        // Each joint's state, its velocity sign computed once for the columns that need it.
        let states: &mut Vec<JointState> = &mut self.states;
        states.clear();
        let run = self.run;
        states.extend((0..q.len()).map(|j| {
            JointState::new(q[j], dq[j], ddq[j], &self.layout.scales[j])
                .at(time)
                .in_run(run)
        }));
        for (i, t) in terms
            .iter()
            .enumerate()
            .filter(|(_, t)| !t.effect.needs_load())
        {
            let j = t.joint;
            out[j * nc + nb + i] = t.column_at(&states[j], 0.0);
        }
        // Load-dependent columns: the first-stage model's torque from the columns just filled.
        let load = &self.layout.load;
        for (i, t) in terms
            .iter()
            .enumerate()
            .filter(|(_, t)| t.effect.needs_load())
        {
            let j = t.joint;
            let tau = dot::dot(&out[j * nc..(j + 1) * nc], load);
            out[j * nc + nb + i] = t.column_at(&states[j], tau);
        }
    }
}

impl RowTable {
    /// Bytes of the table of `p` with `layout`'s active columns (and the torque).
    pub(super) fn bytes(p: &Prepared, layout: &Layout) -> usize {
        let width: usize = (0..layout.dof).map(|j| layout.active(j).len() + 1).sum();
        p.est.grid.n * width * std::mem::size_of::<f64>()
    }

    /// The rows of `p`'s whole grid (chunks in parallel, each from its own window of states),
    /// from `shared` (the same file's states, torque and base regressor at this cut-off) when
    /// given: the same numbers, only the effect columns evaluated.
    pub(super) fn new(
        p: &Prepared,
        base: &BaseModel,
        layout: &Layout,
        shared: Option<&GridBase>,
    ) -> RowTable {
        let n = layout.dof;
        let active: Vec<Vec<usize>> = (0..n).map(|j| layout.active(j)).collect();
        let widths: Vec<usize> = active.iter().map(Vec::len).collect();
        let nc = layout.ncols();
        // Per chunk: each joint's rows, each joint's torque.
        type Part = (Vec<Vec<f64>>, Vec<Vec<f64>>);
        let part = |(a, b): (usize, usize), given: Option<&BasePart>| -> Part {
            let mut rows = Rows::for_log(base, layout, &p.log);
            let mut out: Vec<Vec<f64>> = widths
                .iter()
                .map(|w| Vec::with_capacity(w * (b - a)))
                .collect();
            let mut add = |buf: &[f64]| {
                for (j, o) in out.iter_mut().enumerate() {
                    let row = &buf[j * nc..(j + 1) * nc];
                    o.extend(active[j].iter().map(move |&c| row[c]));
                }
            };
            let tau = match given {
                Some(g) => {
                    let m = n * layout.nb;
                    for (k, yb) in (a..b).zip(g.yb.chunks_exact(m)) {
                        add(rows.fill_grid_with(&g.st, k, yb));
                    }
                    g.tau.clone()
                }
                None => {
                    let st = p.states(a, b);
                    for k in a..b {
                        add(rows.fill_grid(&st, k));
                    }
                    p.grid_tau(a, b)
                }
            };
            (out, tau)
        };
        let parts: Vec<Part> = match shared {
            Some(g) => g
                .parts
                .par_iter()
                .map(|(c, bp)| part(*c, Some(bp)))
                .collect(),
            None => cores(p, 0, p.est.grid.n)
                .par_iter()
                .map(|&c| part(c, None))
                .collect(),
        };
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
            layout: layout.clone(),
            widths,
            rows: table,
            tau,
        }
    }

    /// The tables of `layout`'s rows of `files` (a file's own table kept where it is of
    /// `layout`), when all fit in [`ROW_TABLE_BYTES`] (the base part from `grids` where it holds
    /// it); `None` otherwise.
    pub(super) fn for_files(
        base: &BaseModel,
        layout: &Layout,
        files: &[Prepared],
        grids: &GridBaseCache,
    ) -> Option<Vec<Arc<RowTable>>> {
        let bytes: usize = files.iter().map(|p| RowTable::bytes(p, layout)).sum();
        if bytes > ROW_TABLE_BYTES {
            return None;
        }
        Some(
            files
                .iter()
                .map(|p| match p.rows.as_ref().filter(|t| t.fits(layout)) {
                    Some(t) => Arc::clone(t),
                    None => {
                        let shared = grids.get(p, base, p.est.report.cutoff_hz);
                        Arc::new(RowTable::new(p, base, layout, shared.as_deref()))
                    }
                })
                .collect(),
        )
    }

    /// `files` with their tables of `layout`'s rows ([`RowTable::for_files`]).
    pub(super) fn attach(
        base: &BaseModel,
        layout: &Layout,
        files: &[Prepared],
        grids: &GridBaseCache,
    ) -> Option<Vec<Prepared>> {
        let tables = Self::for_files(base, layout, files, grids)?;
        Some(
            files
                .iter()
                .zip(tables)
                .map(|(p, t)| Prepared {
                    rows: Some(t),
                    ..p.clone()
                })
                .collect(),
        )
    }
}

impl GridBase {
    fn bytes(p: &Prepared, base: &BaseModel) -> usize {
        let n = base.dof();
        p.est.grid.n * (n * base.nb() + 4 * n) * std::mem::size_of::<f64>()
    }

    fn new(p: &Prepared, base: &BaseModel) -> GridBase {
        let (n, m) = (base.dof(), base.dof() * base.nb());
        let parts = cores(p, 0, p.est.grid.n)
            .par_iter()
            .map(|&(a, b)| {
                let st = p.states(a, b);
                let mut scratch = base.scratch();
                let mut yb = vec![0.0; (b - a) * m];
                let (mut q, mut dq, mut ddq) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
                for (i, out) in yb.chunks_exact_mut(m).enumerate() {
                    for j in 0..n {
                        (q[j], dq[j], ddq[j]) = (st.q[j][i], st.dq[j][i], st.ddq[j][i]);
                    }
                    base.eval(&mut scratch, &q, &dq, &ddq, out);
                }
                let tau = p.grid_tau(a, b);
                ((a, b), BasePart { st, tau, yb })
            })
            .collect();
        GridBase { parts }
    }
}

impl GridBaseCache {
    /// `p`'s [`GridBase`] at cut-off `fc` (the one `p` was prepared at), made now if not held;
    /// `None` when it would not fit.
    pub(super) fn get(&self, p: &Prepared, base: &BaseModel, fc: f64) -> Option<Arc<GridBase>> {
        let cache = self.0.as_ref()?;
        let key = (p.log.key(), p.log.len(), fc.to_bits());
        let bytes = GridBase::bytes(p, base);
        {
            let held = cache.lock().ok()?;
            if let Some(g) = held.map.get(&key) {
                return Some(Arc::clone(g));
            }
            if held.bytes + bytes > GRID_BASE_BYTES {
                return None;
            }
        }
        let made = Arc::new(GridBase::new(p, base));
        let mut held = cache.lock().ok()?;
        // Another fold may have made it meanwhile: the same numbers; the first one is kept.
        if let Some(g) = held.map.get(&key) {
            return Some(Arc::clone(g));
        }
        if held.bytes + bytes <= GRID_BASE_BYTES {
            held.bytes += bytes;
            held.map.insert(key, Arc::clone(&made));
        }
        Some(made)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::effects::{Effect, Scales};
    use crate::identify::columns::make_layout;
    use crate::identify::prepare::Smoothing;
    use crate::identify::synth::{generate, Spec};
    use crate::identify::Config;
    use crate::log::Log;

    #[test]
    fn rows_from_a_shared_grid_base_are_those_evaluated_directly_bit_for_bit() {
        let arm = crate::arms::resolve("planar2").unwrap();
        let table = arm.dh_table().unwrap();
        let mut spec = Spec::new(table.clone(), 5).with_effect(Effect::Coulomb, 0, 0.8);
        spec.duration = 40.0; // 20,000 samples: several windows
        spec.jitter = 0.1;
        let log = Log::from(generate(&spec));
        let base = BaseModel::for_arm(&arm);
        let cfg = Config::default();
        let p = Prepared::with_cutoff(log, &cfg, Some(6.0), Smoothing::default(), None).unwrap();
        let layout = make_layout(&base, Some(&table), std::slice::from_ref(&p), &cfg).0;
        assert!(layout.terms.iter().any(|t| t.effect == Effect::Coulomb));

        assert!(GridBaseCache::default().get(&p, &base, 6.0).is_none());
        let cache = GridBaseCache::shared();
        let g = cache.get(&p, &base, 6.0).unwrap();
        assert!(g.parts.len() > 1);
        assert!(Arc::ptr_eq(&g, &cache.get(&p, &base, 6.0).unwrap()));
        let direct = RowTable::new(&p, &base, &layout, None);
        let shared = RowTable::new(&p, &base, &layout, Some(&g));
        assert_eq!((&direct.rows, &direct.tau), (&shared.rows, &shared.tau));

        // Another training set's friction scales (another fold): its own effect columns, the
        // same base part.
        let mut other = layout.clone();
        other.scales[0] = Scales::from_rms_velocity(3.0);
        let direct2 = RowTable::new(&p, &base, &other, None);
        assert!(direct.fits(&layout) && !direct.fits(&other) && direct2.fits(&other));
        assert_eq!(
            direct2.rows,
            RowTable::new(&p, &base, &other, Some(&g)).rows
        );
        assert_ne!(direct2.rows, direct.rows);
    }

    /// A 4 s synthetic log of `arm` (seed `seed`) prepared at a 6 Hz cut-off, and its layout
    /// with every effect candidate.
    fn four_seconds(arm: &str, seed: u64) -> (BaseModel, Prepared, crate::identify::Layout) {
        let arm = crate::arms::resolve(arm).unwrap();
        let table = arm.dh_table().unwrap();
        let mut spec = Spec::new(table.clone(), seed);
        spec.duration = 4.0;
        let log = Log::from(generate(&spec));
        let base = BaseModel::for_arm(&arm);
        let cfg = Config::default();
        let p = Prepared::with_cutoff(log, &cfg, Some(6.0), Smoothing::default(), None).unwrap();
        let layout = make_layout(&base, Some(&table), std::slice::from_ref(&p), &cfg).0;
        (base, p, layout)
    }

    /// A joint's active columns written straight are the full row's, gathered, bit for bit —
    /// with every effect candidate, and with a load-dependent column (which takes the full row).
    #[test]
    fn active_columns_written_straight_are_the_full_rows_gathered() {
        let (base, p, first) = four_seconds("puma560", 3);
        assert!(
            first.terms.len() >= 2 * first.dof && first.load.iter().all(|&l| l == 0.0),
            "{:?}",
            first.terms
        );
        let mut loaded = first.clone();
        loaded
            .terms
            .push(crate::effects::Term::new(Effect::LoadCoulomb, 2));
        loaded.load = (0..loaded.ncols()).map(|c| 0.01 * c as f64).collect();
        let st = p.states(0, 200);
        for layout in [&first, &loaded] {
            let (n, nc) = (layout.dof, layout.ncols());
            let active: Vec<Vec<usize>> = (0..n).map(|j| layout.active(j)).collect();
            let (mut straight, mut gathered) = (
                Rows::for_log(&base, layout, &p.log),
                Rows::for_log(&base, layout, &p.log),
            );
            for k in [0, 1, 2, 3, 4, 7, 150, 199] {
                let mut got = vec![Vec::new(); n];
                straight.append_active(&st, k, &active, &mut got);
                let full = gathered.fill_grid(&st, k);
                for j in 0..n {
                    let want: Vec<f64> = active[j].iter().map(|&c| full[j * nc + c]).collect();
                    assert_eq!(
                        got[j].iter().map(|v| v.to_bits()).collect::<Vec<_>>(),
                        want.iter().map(|v| v.to_bits()).collect::<Vec<_>>(),
                        "sample {k}, joint {j}"
                    );
                    assert!(want.iter().any(|&v| v != 0.0));
                }
            }
        }
    }

    /// The lane-batched base regressor serves a row only for the state it was evaluated at:
    /// rows asked in order, out of order, at the window's end and of another window with the
    /// same indices all equal the single-sample kernel's, bit for bit.
    #[test]
    fn batched_base_rows_are_the_single_sample_kernels_whatever_the_order() {
        let arm = crate::arms::resolve("puma560").unwrap();
        let base = BaseModel::for_arm(&arm);
        let n = base.dof();
        let nb = base.nb();
        let layout = Layout {
            dof: n,
            nb,
            base_names: vec![String::new(); nb],
            base_exprs: vec![String::new(); nb],
            terms: Vec::new(),
            scales: vec![Scales::from_rms_velocity(1.0); n],
            base_active: vec![(0..nb).collect(); n],
            fixed: Vec::new(),
            load: Vec::new(),
            runs: Vec::new(),
            at_rest: vec![0.0; n],
        };
        let window = |seed: u64| {
            let mut v = seed;
            let mut next = move || {
                v = v
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                (v >> 11) as f64 / (1u64 << 53) as f64 * 4.0 - 2.0
            };
            let mut col = || (0..10).map(|_| next()).collect::<Vec<f64>>();
            States {
                lo: 100,
                dt: 0.01,
                q: (0..n).map(|_| col()).collect(),
                dq: (0..n).map(|_| col()).collect(),
                ddq: (0..n).map(|_| col()).collect(),
            }
        };
        let (a, b) = (window(1), window(2));
        let mut rows = Rows::new(&base, &layout, "");
        let mut scratch = base.scratch();
        let mut want = vec![0.0; n * nb];
        let order = [0, 1, 2, 3, 4, 9, 8, 7, 5, 5, 6, 2, 0];
        for (st, k) in order
            .iter()
            .map(|&k| (&a, k))
            .chain(order.iter().map(|&k| (&b, k)))
        {
            let s = |v: &Vec<Vec<f64>>| (0..n).map(|j| v[j][k]).collect::<Vec<f64>>();
            base.eval(&mut scratch, &s(&st.q), &s(&st.dq), &s(&st.ddq), &mut want);
            let got = rows.fill_grid(st, st.lo + k);
            let nc = layout.ncols();
            for j in 0..n {
                let (g, w) = (&got[j * nc..j * nc + nb], &want[j * nb..(j + 1) * nb]);
                assert!(
                    g.iter().zip(w).all(|(x, y)| x.to_bits() == y.to_bits()),
                    "k = {k}"
                );
            }
        }
    }

    /// Terms added to a layout with load-dependent columns (a ripple pair on a rescan) leave
    /// every old column's values as they were: the first-stage model moves with the column
    /// indices, so the load-dependent columns hold the same torque.
    #[test]
    fn terms_added_beside_load_dependent_columns_leave_the_old_columns_as_they_were() {
        let (base, p, mut first) = four_seconds("planar2", 2);
        // A term that sorts first among them comes back with the spline's: every column moves.
        let viscous = crate::effects::Term::new(Effect::Viscous, 0);
        first.terms.retain(|t| *t != viscous);
        first
            .terms
            .push(crate::effects::Term::new(Effect::LoadCoulomb, 1));
        first.load = (0..first.ncols()).map(|c| 0.1 + 0.01 * c as f64).collect();
        *first.load.last_mut().unwrap() = 0.0;
        let added: Vec<_> = Effect::SPLINE
            .iter()
            .map(|&e| crate::effects::Term::new(e, 0))
            .chain([viscous])
            .collect();
        assert!(first.terms[0] > viscous);
        let wider = first.with_terms(&added);
        assert_eq!(wider.ncols(), first.ncols() + added.len());
        assert_eq!(
            wider.terms.last(),
            first.terms.last(),
            "load column stays last"
        );
        let st = p.states(0, 100);
        let (mut a, mut b) = (
            Rows::for_log(&base, &first, &p.log),
            Rows::for_log(&base, &wider, &p.log),
        );
        let (n, nc, nw) = (first.dof, first.ncols(), wider.ncols());
        let at: Vec<usize> = (0..nc)
            .map(|c| match c < first.nb {
                true => c,
                false => wider.col(&first.terms[c - first.nb]).unwrap(),
            })
            .collect();
        for k in [0, 5, 50, 99] {
            let old = a.fill_grid(&st, k).to_vec();
            let new = b.fill_grid(&st, k);
            for j in 0..n {
                for c in 0..nc {
                    // (The load column sums the same products in another order: rounding.)
                    let (x, y) = (old[j * nc + c], new[j * nw + at[c]]);
                    assert!(
                        (x - y).abs() <= 1e-12 * x.abs().max(1.0),
                        "sample {k}, joint {j}, col {c}: {x} vs {y}"
                    );
                }
            }
            assert!(
                old[nc - 1..].iter().step_by(nc).any(|&v| v != 0.0),
                "load column non-zero"
            );
        }
    }
}
