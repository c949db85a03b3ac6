//! Base parameters for any arm: the generated base regressor when the arm is a registered
//! generated arm, otherwise a numerical one built at run time from the reference full regressor.
//!
//! Numerical base (for a D-H table without generated kernels): stack the full regressor `Y` on
//! random states, walk its columns greedily in parameter order (links 1..n; within a link
//! `XX, XY, XZ, YY, YZ, ZZ, MX, MY, MZ, M`) keeping each column that is independent of the kept
//! ones, then regroup every dropped column onto the kept ones: with `Y_dep = Y_ind·K`,
//! `Y·p = Y_ind·(p_ind + K·p_dep)`, so `θ = p_ind + K·p_dep`. A kept column with regrouped terms
//! gets Khalil's `R` suffix (`ZZR1 = ZZ1 + a2²·M2`).
//!
//! ```
//! use dynid::dh::DhTable;
//! use dynid::identify::base::BaseModel;
//! let arm = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/arms/planar2.toml")).unwrap();
//! let table = DhTable::from_str(&arm, "planar2.toml").unwrap();
//! let base = BaseModel::numeric(&table);
//! assert_eq!(base.names(), ["ZZR1", "MXR1", "MY1", "ZZ2", "MX2", "MY2"]);
//! ```

use nalgebra::DMatrix;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::arms::ArmSource;
use crate::derivative::States;
use crate::dh::{DhTable, JointKind};
use crate::model::{Model, PARAM_ORDER};
use crate::pack::{Pack, LANES};
use crate::reference::{RefModel, Workspace};

/// Numerical base-parameter map of a D-H table (see the module docs).
#[derive(Debug, Clone)]
pub struct NumericBase {
    model: RefModel,
    /// Full-parameter index of each base parameter's kept column.
    independent: Vec<usize>,
    /// `θ[row] += coef · p[col]` (the identity part included).
    map: Vec<(usize, usize, f64)>,
    names: Vec<String>,
    exprs: Vec<String>,
}

/// Where base regressor rows come from.
#[derive(Debug, Clone)]
pub enum BaseModel {
    Generated(&'static dyn Model),
    Numeric(Box<NumericBase>),
}

/// Scratch for one evaluation (the numeric path needs the full regressor and an RNEA workspace;
/// the lane-batched one its packs).
#[derive(Debug, Clone)]
pub struct Scratch {
    ws: Option<Workspace>,
    full: Vec<f64>,
    packs: Vec<Pack>,
}

fn full_names(dof: usize) -> Vec<String> {
    (1..=dof)
        .flat_map(|i| PARAM_ORDER.iter().map(move |p| format!("{p}{i}")))
        .collect()
}

/// Random states covering the joint space: revolute q ∈ [−π, π], prismatic q ∈ [−1, 1] m,
/// q̇, q̈ ∈ [−2, 2].
pub fn random_states(table: &DhTable, count: usize, seed: u64) -> Vec<[Vec<f64>; 3]> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    (0..count)
        .map(|_| {
            let q = table
                .joints
                .iter()
                .map(|j| match j.kind {
                    JointKind::Revolute => {
                        rng.gen_range(-std::f64::consts::PI..std::f64::consts::PI)
                    }
                    _ => rng.gen_range(-1.0..1.0),
                })
                .collect();
            let dq = (0..table.dof()).map(|_| rng.gen_range(-2.0..2.0)).collect();
            let ddq = (0..table.dof()).map(|_| rng.gen_range(-2.0..2.0)).collect();
            [q, dq, ddq]
        })
        .collect()
}

impl NumericBase {
    /// Builds the base-parameter map of `table` (deterministic: fixed random states).
    pub fn new(table: &DhTable) -> Self {
        let model = RefModel::new(table);
        let n = model.dof();
        let np = model.np();
        let states = random_states(table, 12 * np / n.max(1) + 24, 0x6261_7365);
        let mut ws = model.workspace();
        let mut y = DMatrix::zeros(states.len() * n, np);
        let mut buf = vec![0.0; n * np];
        for (s, [q, dq, ddq]) in states.iter().enumerate() {
            model.regressor(&mut ws, q, dq, ddq, &mut buf);
            for i in 0..n {
                for k in 0..np {
                    y[(s * n + i, k)] = buf[i * np + k];
                }
            }
        }
        let norms: Vec<f64> = (0..np).map(|k| y.column(k).norm()).collect();
        let dep = super::ls::dependent_columns(&y, &norms);
        let independent: Vec<usize> = (0..np).filter(|k| !dep.contains(k)).collect();
        let dependent: Vec<usize> = dep
            .into_iter()
            .filter(|&k| norms[k] > 1e-9 * norms.iter().copied().fold(0.0, f64::max))
            .collect();
        // K from Y_ind·K = Y_dep (least squares; exact up to rounding).
        let yi =
            DMatrix::from_columns(&independent.iter().map(|&k| y.column(k)).collect::<Vec<_>>());
        let mut map: Vec<(usize, usize, f64)> = independent
            .iter()
            .enumerate()
            .map(|(r, &c)| (r, c, 1.0))
            .collect();
        if !dependent.is_empty() {
            let yd =
                DMatrix::from_columns(&dependent.iter().map(|&k| y.column(k)).collect::<Vec<_>>());
            let svd = yi.clone().svd(true, true);
            let k = svd
                .solve(&yd, 1e-12)
                .unwrap_or_else(|_| DMatrix::zeros(independent.len(), dependent.len()));
            for (d, &col) in dependent.iter().enumerate() {
                for r in 0..independent.len() {
                    let c = clean(k[(r, d)]);
                    if c != 0.0 {
                        map.push((r, col, c));
                    }
                }
            }
        }
        let pn = full_names(n);
        let mut names = Vec::new();
        let mut exprs = Vec::new();
        for (r, &c) in independent.iter().enumerate() {
            let terms: Vec<&(usize, usize, f64)> =
                map.iter().filter(|m| m.0 == r && m.1 != c).collect();
            let name = if terms.is_empty() {
                pn[c].clone()
            } else {
                let p = &pn[c];
                let split = p.find(|ch: char| ch.is_ascii_digit()).unwrap_or(p.len());
                format!("{}R{}", &p[..split], &p[split..])
            };
            let mut e = pn[c].clone();
            for &&(_, col, coef) in &terms {
                let sign = if coef < 0.0 { " - " } else { " + " };
                let a = coef.abs();
                if (a - 1.0).abs() < 1e-12 {
                    e += &format!("{sign}{}", pn[col]);
                } else {
                    e += &format!("{sign}{}·{}", fmt_coef(a), pn[col]);
                }
            }
            names.push(name);
            exprs.push(e);
        }
        NumericBase {
            model,
            independent,
            map,
            names,
            exprs,
        }
    }

    pub fn nb(&self) -> usize {
        self.independent.len()
    }
}

/// Rounds regrouping coefficients that are integers or zero up to rounding noise.
fn clean(c: f64) -> f64 {
    if c.abs() < 1e-9 {
        0.0
    } else if (c - c.round()).abs() < 1e-9 {
        c.round()
    } else {
        c
    }
}

fn fmt_coef(a: f64) -> String {
    let s = format!("{a:.6}");
    s.trim_end_matches('0').trim_end_matches('.').to_string()
}

impl BaseModel {
    /// The generated kernels for a registered arm, the numerical base for a table.
    pub fn for_arm(arm: &ArmSource) -> Self {
        match arm {
            ArmSource::Generated(m) => BaseModel::Generated(*m),
            ArmSource::Table(t) => BaseModel::numeric(t),
        }
    }

    /// The numerical base of a D-H table.
    pub fn numeric(table: &DhTable) -> Self {
        BaseModel::Numeric(Box::new(NumericBase::new(table)))
    }

    pub fn dof(&self) -> usize {
        match self {
            BaseModel::Generated(m) => m.dof(),
            BaseModel::Numeric(b) => b.model.dof(),
        }
    }

    pub fn nb(&self) -> usize {
        match self {
            BaseModel::Generated(m) => m.nb(),
            BaseModel::Numeric(b) => b.nb(),
        }
    }

    /// Base-parameter names (`ZZR1`, `MX2`, …).
    pub fn names(&self) -> Vec<String> {
        match self {
            BaseModel::Generated(m) => m.base_param_names().iter().map(|s| s.to_string()).collect(),
            BaseModel::Numeric(b) => b.names.clone(),
        }
    }

    /// Grouped expressions in full parameters.
    pub fn exprs(&self) -> Vec<String> {
        match self {
            BaseModel::Generated(m) => m.base_param_exprs().iter().map(|s| s.to_string()).collect(),
            BaseModel::Numeric(b) => b.exprs.clone(),
        }
    }

    /// `"generated kernels"` or `"numerical (reference regressor + rank-revealing QR)"`.
    pub fn source(&self) -> &'static str {
        match self {
            BaseModel::Generated(_) => "generated kernels",
            BaseModel::Numeric(_) => "numerical: reference full regressor on random states, greedy independent columns, regrouped",
        }
    }

    pub fn scratch(&self) -> Scratch {
        match self {
            BaseModel::Generated(_) => Scratch {
                ws: None,
                full: Vec::new(),
                packs: Vec::new(),
            },
            BaseModel::Numeric(b) => Scratch {
                ws: Some(b.model.workspace()),
                full: vec![0.0; b.model.dof() * b.model.np()],
                packs: Vec::new(),
            },
        }
    }

    /// Base regressor `Yb(q, q̇, q̈)` into `out` (`dof × nb`, row-major).
    pub fn eval(&self, s: &mut Scratch, q: &[f64], dq: &[f64], ddq: &[f64], out: &mut [f64]) {
        match self {
            BaseModel::Generated(m) => m.base_regressor(q, dq, ddq, out),
            BaseModel::Numeric(b) => {
                let n = b.model.dof();
                let np = b.model.np();
                let nb = b.nb();
                let ws = s.ws.get_or_insert_with(|| b.model.workspace());
                s.full.resize(n * np, 0.0);
                b.model.regressor(ws, q, dq, ddq, &mut s.full);
                for i in 0..n {
                    for (r, &c) in b.independent.iter().enumerate() {
                        out[i * nb + r] = s.full[i * np + c];
                    }
                }
            }
        }
    }

    /// The base regressors of the [`LANES`] consecutive states `i..i + LANES` of `st` (indices
    /// from `st.lo`) at once, lane `l`'s at `out[l·dof·nb..]`: the lane-batched kernel, each lane
    /// bit for bit [`BaseModel::eval`]'s (`dynid::pack`). `false`, nothing written, where the
    /// rows do not come from generated kernels.
    pub fn eval_lanes(&self, s: &mut Scratch, st: &States, i: usize, out: &mut [f64]) -> bool {
        let BaseModel::Generated(m) = self else {
            return false;
        };
        let n = m.dof();
        let w = n * m.nb();
        s.packs.resize(3 * n + w, Pack::default());
        let (ins, res) = s.packs.split_at_mut(3 * n);
        let pack = |v: &[f64]| Pack::new(std::array::from_fn(|l| v[i + l]));
        for j in 0..n {
            ins[j] = pack(&st.q[j]);
            ins[n + j] = pack(&st.dq[j]);
            ins[2 * n + j] = pack(&st.ddq[j]);
        }
        let (q, rest) = ins.split_at(n);
        let (dq, ddq) = rest.split_at(n);
        m.base_regressor_lanes(q, dq, ddq, res);
        for (l, o) in out.chunks_exact_mut(w).take(LANES).enumerate() {
            crate::pack::lane(res, l, o);
        }
        true
    }

    /// The base-parameter map `K` (`nb × 10·dof`, `θ = K·p`), column `c` the base parameters of
    /// the unit vector `e_c` (the map is linear).
    pub fn base_map(&self) -> DMatrix<f64> {
        let np = 10 * self.dof();
        let mut k = DMatrix::zeros(self.nb(), np);
        let mut e = vec![0.0; np];
        for c in 0..np {
            e[c] = 1.0;
            for (r, v) in self.base_params(&e).into_iter().enumerate() {
                k[(r, c)] = v;
            }
            e[c] = 0.0;
        }
        k
    }

    /// Base parameters of full parameters `p`.
    pub fn base_params(&self, p: &[f64]) -> Vec<f64> {
        match self {
            BaseModel::Generated(m) => {
                let mut out = vec![0.0; m.nb()];
                m.base_params(p, &mut out);
                out
            }
            BaseModel::Numeric(b) => {
                let mut out = vec![0.0; b.nb()];
                for &(r, c, k) in &b.map {
                    out[r] += k * p[c];
                }
                out
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn table(name: &str) -> DhTable {
        let path = format!("{}/arms/{name}.toml", env!("CARGO_MANIFEST_DIR"));
        DhTable::from_path(std::path::Path::new(&path)).expect("arm table")
    }

    fn random_p(n: usize, seed: u64) -> Vec<f64> {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        (0..10 * n).map(|_| rng.gen_range(-1.0..1.0)).collect()
    }

    /// Yb·θ must equal Y·p (the defining identity) on states not used to build the map.
    #[test]
    fn numeric_base_reproduces_the_full_regressor() {
        for arm in ["planar2", "puma560", "scara", "panda"] {
            let t = table(arm);
            let base = BaseModel::numeric(&t);
            let model = RefModel::new(&t);
            let mut ws = model.workspace();
            let (n, np, nb) = (model.dof(), model.np(), base.nb());
            let p = random_p(n, 9);
            let theta = base.base_params(&p);
            let mut s = base.scratch();
            let (mut y, mut yb) = (vec![0.0; n * np], vec![0.0; n * nb]);
            for [q, dq, ddq] in random_states(&t, 20, 77) {
                model.regressor(&mut ws, &q, &dq, &ddq, &mut y);
                base.eval(&mut s, &q, &dq, &ddq, &mut yb);
                for i in 0..n {
                    let a: f64 = (0..np).map(|k| y[i * np + k] * p[k]).sum();
                    let b: f64 = (0..nb).map(|k| yb[i * nb + k] * theta[k]).sum();
                    assert!(
                        (a - b).abs() < 1e-8 * (1.0 + a.abs()),
                        "{arm} joint {i}: {a} vs {b}"
                    );
                }
            }
        }
    }

    /// Where generated kernels exist they must agree with the numerical base: same count, and the
    /// same torques for the same full parameters.
    #[test]
    fn numeric_base_agrees_with_generated_kernels() {
        for m in crate::arms::all() {
            let t = DhTable::from_str(m.arm_toml(), m.name()).expect("embedded table");
            let num = BaseModel::numeric(&t);
            let gen = BaseModel::Generated(*m);
            assert_eq!(num.nb(), gen.nb(), "{}", m.name());
            let (n, nb) = (m.dof(), m.nb());
            let p = random_p(n, 5);
            let (tn, tg) = (num.base_params(&p), gen.base_params(&p));
            let (mut sn, mut sg) = (num.scratch(), gen.scratch());
            let (mut yn, mut yg) = (vec![0.0; n * nb], vec![0.0; n * nb]);
            for [q, dq, ddq] in random_states(&t, 10, 3) {
                num.eval(&mut sn, &q, &dq, &ddq, &mut yn);
                gen.eval(&mut sg, &q, &dq, &ddq, &mut yg);
                for i in 0..n {
                    let a: f64 = (0..nb).map(|k| yn[i * nb + k] * tn[k]).sum();
                    let b: f64 = (0..nb).map(|k| yg[i * nb + k] * tg[k]).sum();
                    assert!(
                        (a - b).abs() < 1e-8 * (1.0 + a.abs()),
                        "{} joint {i}: {a} vs {b}",
                        m.name()
                    );
                }
            }
        }
    }

    #[test]
    fn planar2_base_is_the_papers() {
        let base = BaseModel::numeric(&table("planar2"));
        assert_eq!(base.names(), ["ZZR1", "MXR1", "MY1", "ZZ2", "MX2", "MY2"]);
        assert_eq!(base.exprs()[0], "ZZ1 + M2");
        assert_eq!(base.exprs()[1], "MX1 + M2");
    }
}
