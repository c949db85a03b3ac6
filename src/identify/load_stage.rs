//! Stage 6b, **the load-dependent effects** ([`Effect::LOADED`]): a second selection on top of
//! the first stage's model, whose torque their columns use ([`load_stage`]); the final model's
//! load-dependent part for a rescan of the cut-off ([`LoadModel`]).

use super::base::BaseModel;
use super::layout::Layout;
use super::prepare::Prepared;
use super::problem::{with_hint, Problem};
use super::select::{add_collinear, chain_stages, passes_again, select, Selected};
use super::{Config, IdentifyError, RankError};
use crate::effects::{Effect, EffectsSpec, Term};

/// A model's load-dependent terms and the coefficients of its torque without them, over the
/// columns of a first-stage layout (what [`super::scan::choose_cutoff`] needs to judge cut-offs with them).
#[derive(Debug, Clone, PartialEq)]
pub struct LoadModel {
    pub terms: Vec<Term>,
    pub coefs: Vec<f64>,
}

pub(super) fn load_model(
    layout: &Layout,
    terms: &[Term],
    subset: &[usize],
    x: &[f64],
) -> Option<LoadModel> {
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

/// The second stage for the load-dependent effects ([`Effect::LOADED`]): their columns use the
/// torque the first stage's model predicts (rigid body and effects, parameters held fixed: the
/// joint torque the gear transmits), so the problem is rebuilt with them and they are searched
/// (or, declared, added) on top of the first stage's model. Without any accepted or declared, the first stage is returned as it
/// is. (The fixed parameters saw every training block, so the candidates' held-out test is
/// slightly optimistic — by one global, smooth estimate, not a per-block fit.)
pub(super) fn load_stage(
    base: &BaseModel,
    train: &[Prepared],
    cfg: &Config,
    first: Selected,
) -> Result<Selected, IdentifyError> {
    let Selected {
        problem,
        selection: first,
        declared,
    } = first;
    let n = base.dof();
    let (fixed, search): (Vec<Term>, Vec<Term>) = match &cfg.effects {
        EffectsSpec::Auto => (
            Vec::new(),
            Effect::LOADED
                .iter()
                .flat_map(|&effect| (0..n).map(move |joint| Term::new(effect, joint)))
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
        return Ok(Selected {
            problem,
            selection: first,
            declared,
        });
    }
    let mut l2 = problem.layout.clone();
    l2.terms.extend(fixed.iter().chain(&search));
    l2.terms.sort();
    l2.terms.dedup();
    // The new terms sort last (their effects are the last variants): first-stage columns keep
    // their indices.
    l2.load =
        first_stage_load(&problem, &first.terms, l2.ncols()).map_err(|e| with_hint(e, train))?;
    let p2 = Problem::build(base, l2, train, cfg.blocks);
    let start: Vec<Term> = first.terms.iter().chain(&fixed).copied().collect();
    let mut second = select(&p2, &start, &search, &cfg.rules)?;
    if fixed.is_empty() && second.steps.is_empty() {
        let mut first = first;
        add_collinear(&mut first.collinear, second.collinear);
        // Why the second stage stopped is the last word if it had the better candidate.
        if let Some(s) = second.stopped_on {
            if first
                .stopped_on
                .as_ref()
                .is_none_or(|f| s.heldout_gain > f.heldout_gain)
            {
                first.stopped_on = Some(s);
            }
        }
        return Ok(Selected {
            problem,
            selection: first,
            declared,
        });
    }
    // A first-stage effect may have stood in for the load-dependent one (a Coulomb term for
    // the mean of load-dependent friction): each must pass the same test again against the
    // final model without it, or it goes (last added first).
    let mut dropped = Vec::new();
    // (Not the friction spline's columns: one alone is not the unit its joint test passed.)
    for s in first
        .steps
        .iter()
        .rev()
        .filter(|s| !s.added.effect.is_spline())
    {
        if !passes_again(&p2, &mut second.terms, s.added, &cfg.rules)? {
            dropped.push(s.added);
        }
    }
    Ok(chain_stages(p2, first, second, declared, fixed, &dropped))
}

/// The coefficients of `terms`' fit on `problem` over `ncols` columns, zero elsewhere: the
/// first-stage model whose torque the load-dependent columns hold ([`Layout::load`]).
fn first_stage_load(
    problem: &Problem,
    terms: &[Term],
    ncols: usize,
) -> Result<Vec<f64>, RankError> {
    let subset = problem.subset(terms);
    let w = problem.weights(&subset)?;
    let fit = problem.fit(&subset, &w)?;
    let mut load = vec![0.0; ncols];
    for (&c, &x) in subset.iter().zip(&fit.x) {
        load[c] = x;
    }
    Ok(load)
}

/// `selected`, which has load-dependent terms, with those columns rebuilt from the torque of its
/// own first-stage terms (every term but the load-dependent ones, fitted on the same rows): what
/// the load stage computes for a fixed `--effects` list of the same terms, so a model the guard
/// extended after the load stage is the model its effects list names.
pub(super) fn reload(
    base: &BaseModel,
    train: &[Prepared],
    blocks: usize,
    selected: Selected,
) -> Result<Selected, RankError> {
    let Selected {
        problem,
        selection,
        declared,
    } = selected;
    let first: Vec<Term> = selection
        .terms
        .iter()
        .copied()
        .filter(|t| !t.effect.needs_load())
        .collect();
    let mut layout = problem.layout.clone();
    layout.load = first_stage_load(&problem, &first, layout.ncols())?;
    Ok(Selected {
        problem: Problem::build(base, layout, train, blocks),
        selection,
        declared,
    })
}
