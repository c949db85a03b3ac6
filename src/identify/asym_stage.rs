//! Stage 6a′, **asymmetric Coulomb friction by its coefficient** ([`asym_stage`]).
//!
//! `asym_coulomb`'s column is 1 while the joint moves and 0 at rest: beside an offset it differs
//! only at the rests, which a point-to-point motion has at its waypoints, in a few of the
//! held-out blocks. The search's block test (a t-test over the per-block log ratios of the joint's
//! held-out error) then has little power: the blocks with rests gain much, the rest nothing
//! (suite cases with a 0.1–0.2 torque-share asymmetry: 5–18 % of the joint's held-out residual
//! removed at t = 2.2–2.8 against 3.8–4.1). The same situation as the guard's coefficient route
//! ([`super::guard`]), tested the same way: on every joint whose model holds `coulomb` and where
//! `asym_coulomb` was searched (rests enough) but not added, its coefficient fitted with the
//! model — and the joint's offset, so that a constant is not taken for it — is tested,
//! `|x| / σ` with σ from the block jackknife, two-sided at the selection's level, Bonferroni over
//! the joints tested; a passing term is added when it also meets the search's practical rules
//! (≥ 1 % of the joint's held-out residual removed, ≥ 1e-6 of its torque power). Asymmetric
//! friction is a refinement of the Coulomb friction the search already found, so the family is
//! those joints, not every candidate.

use super::jackknife;
use super::ls::t_quantile;
use super::problem::Problem;
use super::select::{self, CoefficientTest, Selected};
use super::{Config, IdentifyError, RankError};
use crate::effects::{Effect, EffectsSpec, Term};

/// The stage (see the module docs) on the selection `selected`, whose search covered
/// `searched`.
pub(super) fn asym_stage(
    cfg: &Config,
    mut selected: Selected,
    searched: &[Term],
) -> Result<Selected, IdentifyError> {
    if !matches!(cfg.effects, EffectsSpec::Auto) {
        return Ok(selected);
    }
    let terms = &selected.selection.terms;
    let candidates: Vec<Term> = searched
        .iter()
        .copied()
        .filter(|t| t.effect == Effect::AsymCoulomb && !terms.contains(t))
        .filter(|t| terms.contains(&Term::new(Effect::Coulomb, t.joint)))
        .collect();
    if candidates.is_empty() {
        return Ok(selected);
    }
    let p = &selected.problem;
    let dof = (p.blocks().max(2) - 1) as f64;
    let z_crit = t_quantile(1.0 - cfg.rules.alpha / (2.0 * candidates.len() as f64), dof);
    let tested: Vec<(Term, f64)> = candidates
        .into_iter()
        .filter_map(|c| coef_z(p, terms, c).transpose().map(|z| z.map(|z| (c, z))))
        .collect::<Result<_, _>>()
        .map_err(IdentifyError::Rank)?;
    let mut terms = terms.clone();
    let mut steps = Vec::new();
    for (c, z) in tested {
        if z <= z_crit {
            continue;
        }
        let (subset, w, prefixes, cur) = select::fitted(p, &terms).map_err(IdentifyError::Rank)?;
        let Some(mut ev) =
            select::evidence(p, &terms, (&subset, &prefixes), &w, &cur, &[c], f64::NAN)
        else {
            continue;
        };
        // Practically relevant as in the search: it lowers the joint's held-out error enough.
        if !cfg.rules.relevant(&ev) {
            continue;
        }
        ev.coefficient = Some(CoefficientTest {
            z,
            z_crit,
            columns: 1,
        });
        select::accept(&mut terms, &mut steps, c, ev);
    }
    selected.selection.terms = terms;
    selected.selection.steps.extend(steps);
    Ok(selected)
}

/// `|x| / σ` of `c`'s coefficient fitted with the model `terms` and the joint's offset (when the
/// data tell it apart), σ from the block jackknife; `None` when `c` is collinear with them.
fn coef_z(p: &Problem, terms: &[Term], c: Term) -> Result<Option<f64>, RankError> {
    let mut with = terms.to_vec();
    let offset = Term::new(Effect::Offset, c.joint);
    if !with.contains(&offset) {
        with.push(offset);
    }
    with.push(c);
    let independent = p.independent(&p.subset(&with));
    match p.layout.col(&c) {
        Some(col) if independent.contains(&col) => {
            jackknife::coefficient_z(p, &independent, col).map(Some)
        }
        _ => Ok(None),
    }
}
