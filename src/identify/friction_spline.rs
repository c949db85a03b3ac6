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
//! tested. A passing unit is added as it was tested — the curve with the joint's offset, viscous
//! and Coulomb terms the model lacks (those the data tell apart) — when it meets the search's
//! practical rules (≥ 1 % of the joint's held-out residual removed, ≥ 1e-6 of its torque
//! power); each of those closed forms must then pass the search's test again or it goes, and if
//! one goes the curve must meet the practical rules without it. A Stribeck term the first
//! stage added on that joint may have stood in for the curve (both bend friction at low speed):
//! once a curve is in, it must pass the search's test again or it goes. Then the first stage's
//! candidates are searched again on top of the curve: a slow drift or a per-run offset on that
//! joint fails while the curve is in its residual, and an offset, viscous or Coulomb term
//! completes the curve's span. The load stage searches after this one: searched after it, a
//! curve took what the two-stage model of load-dependent friction leaves (its load is a
//! model's torque, not the truth) on a plant with that friction only; searched before, a curve
//! can take the load term's place (the DFKI pendulum's elbow on a 3-run split).

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
    let layout = first.problem.layout.with_terms(units.iter().flatten());
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
        // The unit the test fitted, less the per-run offsets: the curve with the joint's closed
        // forms (without them it spans no curve through the origin with a slope).
        let companions = closed_forms(&p2, &terms, &unit);
        let whole: Vec<Term> = unit.iter().chain(&companions).copied().collect();
        let Some(mut ev) = relevant(&p2, &terms, &whole, cfg)? else {
            continue;
        };
        ev.coefficient = Some(CoefficientTest {
            z: f.f,
            z_crit: f_crit,
            columns: unit.len(),
        });
        for &t in &whole {
            select::accept(&mut terms, &mut steps, t, ev.clone());
        }
        // A closed form the curve does not need goes (the search's test, as for any term); the
        // curve then must still meet the practical rules on its own, or it goes too.
        let mut lost = false;
        for &t in &companions {
            if !passes_again(&p2, &mut terms, t, &cfg.rules)? {
                steps.retain(|s| s.added != t);
                lost = true;
            }
        }
        if lost {
            let without: Vec<Term> = terms
                .iter()
                .filter(|t| !unit.contains(t))
                .copied()
                .collect();
            if relevant(&p2, &without, &unit, cfg)?.is_none() {
                terms = without;
                steps.retain(|s| !unit.contains(&s.added));
            }
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

/// The evidence for adding `unit` to the model `terms` when it meets the search's practical
/// rules (held-out gain and torque share), else `None`.
fn relevant(
    p: &Problem,
    terms: &[Term],
    unit: &[Term],
    cfg: &Config,
) -> Result<Option<select::Evidence>, IdentifyError> {
    let (subset, w, prefixes, cur) = select::fitted(p, terms).map_err(IdentifyError::Rank)?;
    let ev = select::evidence(p, terms, (&subset, &prefixes), &w, &cur, unit, f64::NAN);
    Ok(ev.filter(|e| cfg.rules.relevant(e)))
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
        .filter(|t| t.effect.is_per_run() && t.joint == j && !terms.contains(t));
    with.extend(closed_forms(p, terms, unit).into_iter().chain(per_run));
    with.extend(unit);
    let independent = p.independent(&p.subset(&with));
    let cols: Vec<usize> = unit.iter().filter_map(|t| p.layout.col(t)).collect();
    if cols.len() != unit.len() || !cols.iter().all(|c| independent.contains(c)) {
        return Ok(None);
    }
    hotelling::joint_f(p, &independent, &cols)
}

/// The offset, viscous and Coulomb friction of `unit`'s joint that the model `terms` lacks and
/// the data tell apart from it and the unit (an offset on a vertical prismatic joint is its
/// weight): fitted with a curve, they give it a constant, a slope and a step.
fn closed_forms(p: &Problem, terms: &[Term], unit: &[Term; 3]) -> Vec<Term> {
    let j = unit[0].joint;
    let missing: Vec<Term> = [Effect::Viscous, Effect::Coulomb, Effect::Offset]
        .map(|e| Term::new(e, j))
        .into_iter()
        .filter(|t| !terms.contains(t) && p.layout.col(t).is_some())
        .collect();
    let with: Vec<Term> = terms.iter().chain(&missing).chain(unit).copied().collect();
    let independent = p.independent(&p.subset(&with));
    missing
        .into_iter()
        .filter(|t| p.layout.col(t).is_some_and(|c| independent.contains(&c)))
        .collect()
}

#[cfg(test)]
mod tests;
