//! Stage 2, **which columns**: the base parameters (per joint only those that can be non-zero in
//! its rows), then the effect terms declared or searched, minus those structurally merged with the
//! base ([`make_layout`]).

use super::base::{self, BaseModel};
use super::layout::Layout;
use super::prepare::Prepared;
use super::Config;
use crate::effects::{self, Effect, EffectsSpec, Scales, Term};

/// Effects merged with base parameters, and the base parameters they merge into.
pub(super) type Merged = Vec<(Term, Vec<String>)>;

/// The column layout for `train`: base parameters, then the effect terms (declared and searched,
/// minus those structurally merged with the base), with friction scales from the data.
pub(super) fn make_layout(
    base: &BaseModel,
    table: Option<&crate::dh::DhTable>,
    train: &[Prepared],
    cfg: &Config,
) -> (Layout, Vec<Term>, Vec<Term>, Merged) {
    let n = base.dof();
    let fast = mean_over_samples(train, n, |st, j, i| st.dq[j][i].powi(8));
    let scales: Vec<Scales> = mean_over_samples(train, n, |st, j, i| st.dq[j][i].powi(2))
        .into_iter()
        .zip(fast)
        .map(|(ms, m8)| {
            Scales::from_rms_velocity(ms.sqrt())
                .with_coulomb_fraction(cfg.coulomb_width.unwrap_or(Scales::COULOMB_FRACTION))
                .with_spline_unit(effects::spline::velocity_unit(m8))
        })
        .collect();
    // Each joint's share of samples at rest, 1 − mean |tanh(q̇ / v)|.
    let at_rest: Vec<f64> =
        mean_over_samples(train, n, |st, j, i| scales[j].sign(st.dq[j][i]).abs())
            .into_iter()
            .map(|m| 1.0 - m)
            .collect();
    let runs: Vec<String> = crate::log::Log::runs(train.iter().map(|p| &p.log))
        .into_iter()
        .map(str::to_string)
        .collect();
    let (declared, searched): (Vec<Term>, Vec<Term>) = match &cfg.effects {
        EffectsSpec::Auto => (
            Vec::new(),
            Effect::ALL
                .iter()
                .chain(&Effect::PER_RUN)
                .flat_map(|&e| (0..n).map(move |j| Term::new(e, j)))
                .flat_map(|t| per_run(t, runs.len()))
                .filter(|t| {
                    t.effect != Effect::AsymCoulomb || Effect::rests_enough(at_rest[t.joint])
                })
                .collect(),
        ),
        // Ripple and load-dependent terms come in later stages (see `ripple`, `load_stage`).
        EffectsSpec::Fixed(t) => (
            t.iter()
                .copied()
                .filter(|t| !t.effect.needs_load() && !t.effect.is_ripple())
                .flat_map(|t| per_run(t, runs.len()))
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
            // A per-run column is no function of the state: never merged.
            let all: Vec<Term> = declared
                .iter()
                .chain(&searched)
                .filter(|t| !t.effect.is_per_run())
                .copied()
                .collect();
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
        fixed: Vec::new(),
        load: Vec::new(),
        runs,
        at_rest,
    };
    (layout, declared, searched, merged)
}

/// Per joint, the mean of `f` over every training sample (each file's states in one pass).
fn mean_over_samples(
    train: &[Prepared],
    n: usize,
    f: impl Fn(&crate::derivative::States, usize, usize) -> f64 + Sync + Copy,
) -> Vec<f64> {
    let sums: Vec<(Vec<f64>, usize)> = train.iter().map(|p| p.state_sums(f)).collect();
    (0..n)
        .map(|j| {
            let (s, c) = sums
                .iter()
                .fold((0.0, 0usize), |(s, c), (s1, c1)| (s + s1[j], c + c1));
            s / c.max(1) as f64
        })
        .collect()
}

/// `t` itself, or for a per-run effect one term per training run after the first (`t.run` 0:
/// every run; none with one run — the first run's is the effect without runs, `offset`).
fn per_run(t: Term, runs: usize) -> Vec<Term> {
    match (t.effect.is_per_run(), t.run) {
        (false, _) => vec![t],
        (true, 0) => (1..runs).map(|run| Term { run, ..t }).collect(),
        (true, r) => (r < runs).then_some(t).into_iter().collect(),
    }
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
