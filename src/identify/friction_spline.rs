//! Stage 6a″, **friction as a spline in the velocity** ([`Effect::SPLINE`], `spline_stage`).
//!
//! For a joint whose friction no closed form fits, the three natural-cubic-spline columns of
//! [`crate::effects::spline`] (with `viscous` and `offset`, any natural cubic spline in `q̇ / u`
//! on knots at 0, ±½ and ±1 of the joint's top speed `u`) are one unit per joint, tested after
//! the closed forms (the first stage, the ripple and asymmetric friction) have taken what they
//! explain: the spline is the catch-all, so it comes last. Its evidence sits where the joint
//! moves fast, in some of the held-out blocks, so the search's block t-test has little power on
//! it. Like asymmetric Coulomb friction (`asym_stage.rs`) it is tested on its
//! coefficients: fitted with the model and the joint's offset, per-run offsets, viscous and
//! Coulomb friction (so a constant, a line, a step or the offsets of runs at different speeds
//! are not taken for a curve), the three together by Hotelling's T² from their block-jackknife
//! covariance (`hotelling.rs`), at the selection's level, Bonferroni over the joints
//! tested; a passing unit is added when it also meets the search's practical rules (≥ 1 % of
//! the joint's held-out residual removed, ≥ 1e-6 of its torque power). A Stribeck term the first
//! stage added on that joint may have stood in for the curve (both bend friction at low speed):
//! once a curve is in, it must pass the search's test again or it goes. Then the first stage's
//! candidates are searched again on top of the curve: a slow drift or a per-run offset on that
//! joint fails while the curve is in its residual, and an offset, viscous or Coulomb term
//! completes the curve's span. The load stage searches after this one.

use super::base::BaseModel;
use super::hotelling;
use super::prepare::Prepared;
use super::problem::Problem;
use super::select::{self, passes_again, CoefficientTest, Selected};
use super::{Config, IdentifyError, RankError};
use crate::effects::{Effect, EffectsSpec, Term};

/// The stage (see the module docs) on `first`, whose search covered `searched`; the joints in
/// `skip` are not searched (their torque is their sensor's resolution floor).
pub(super) fn spline_stage(
    base: &BaseModel,
    train: &[Prepared],
    cfg: &Config,
    first: Selected,
    (skip, searched): (&[usize], &[Term]),
) -> Result<Selected, IdentifyError> {
    if !matches!(cfg.effects, EffectsSpec::Auto) || first.problem.blocks() < 3 {
        return Ok(first);
    }
    let units: Vec<[Term; 3]> = (0..base.dof())
        .filter(|j| !skip.contains(j))
        .map(|j| Effect::SPLINE.map(|e| Term::new(e, j)))
        .collect();
    let mut layout = first.problem.layout.clone();
    layout.terms.extend(units.iter().flatten());
    layout.terms.sort();
    layout.terms.dedup();
    let p2 = Problem::build(base, layout, train, cfg.blocks);
    let terms = &first.selection.terms;
    let tested: Vec<([Term; 3], hotelling::JointF)> = units
        .into_iter()
        .filter_map(|u| {
            joint_f(&p2, terms, &u)
                .transpose()
                .map(|f| f.map(|f| (u, f)))
        })
        .collect::<Result<_, _>>()
        .map_err(IdentifyError::Rank)?;
    let alpha = cfg.rules.alpha / tested.len().max(1) as f64;
    let mut terms = terms.clone();
    let mut steps = Vec::new();
    for (unit, f) in tested {
        let f_crit = f.critical(alpha);
        if f.f <= f_crit {
            continue;
        }
        let (subset, w, prefixes, cur) =
            select::fitted(&p2, &terms).map_err(IdentifyError::Rank)?;
        let Some(mut ev) =
            select::evidence(&p2, &terms, (&subset, &prefixes), &w, &cur, &unit, f64::NAN)
        else {
            continue;
        };
        if ev.heldout_gain < cfg.rules.min_gain || ev.torque_share < cfg.rules.min_share {
            continue;
        }
        ev.coefficient = Some(CoefficientTest {
            z: f.f,
            z_crit: f_crit,
            columns: unit.len(),
        });
        for t in unit {
            select::accept(&mut terms, &mut steps, t, ev.clone());
        }
    }
    if steps.is_empty() {
        return Ok(first);
    }
    let Selected {
        selection: mut sel,
        declared,
        ..
    } = first;
    // A Stribeck term on a joint that now has a curve must pass the search's test again.
    let mut dropped = Vec::new();
    for s in sel.steps.iter().rev() {
        let curved = terms.contains(&Term::new(Effect::SplineA, s.added.joint));
        if s.added.effect == Effect::Stribeck
            && curved
            && !passes_again(&p2, &mut terms, s.added, &cfg.rules)?
        {
            dropped.push(s.added);
        }
    }
    sel.steps.retain(|s| !dropped.contains(&s.added));
    sel.steps.extend(steps);
    sel.dropped.extend(dropped.iter().map(Term::label));
    // The first stage's candidates again on top of the curve: a slow drift or a per-run offset on
    // the same joint fails while the curve is in its residual.
    let again = select::select(&p2, &terms, searched, &cfg.rules)?;
    select::add_collinear(&mut sel.collinear, again.collinear);
    sel.steps.extend(again.steps);
    sel.terms = again.terms;
    Ok(Selected {
        problem: p2,
        selection: sel,
        declared,
    })
}

/// The joint F test of `unit`'s coefficients fitted with the model `terms` and the joint's
/// offset, per-run offsets, viscous and Coulomb friction (those the data tell apart); `None`
/// when a column of the unit is collinear with them.
fn joint_f(
    p: &Problem,
    terms: &[Term],
    unit: &[Term; 3],
) -> Result<Option<hotelling::JointF>, RankError> {
    let j = unit[0].joint;
    let mut with = terms.to_vec();
    // The joint's per-run offsets too: runs at different speeds would let the spline's even part
    // stand in for their offsets.
    let per_run = p
        .layout
        .terms
        .iter()
        .copied()
        .filter(|t| t.effect.is_per_run() && t.joint == j);
    let closed = [Effect::Offset, Effect::Viscous, Effect::Coulomb].map(|e| Term::new(e, j));
    for t in closed.into_iter().chain(per_run) {
        if !with.contains(&t) {
            with.push(t);
        }
    }
    with.extend(unit);
    let independent = p.independent(&p.subset(&with));
    let cols: Vec<usize> = unit.iter().filter_map(|t| p.layout.col(t)).collect();
    if cols.len() != unit.len() || !cols.iter().all(|c| independent.contains(c)) {
        return Ok(None);
    }
    hotelling::joint_f(p, &independent, &cols)
}

#[cfg(test)]
mod tests;
