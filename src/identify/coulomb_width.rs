//! Stage 6a, **the Coulomb width scan** (`choose_width`): the Coulomb column is the smoothed
//! sign `tanh(q̇ / v)`, and how sharp a real joint's friction turns at a reversal is a property of
//! the arm, not a constant. Each width of [`FRACTIONS`] (times the joint's RMS training velocity)
//! refits the selected model and is judged by its held-out error on the training data (by run,
//! or by block with one file); the default ([`Scales::COULOMB_FRACTION`]) is kept unless another
//! width lowers the geometric mean of the joints' held-out errors.
//!
//! Why: on the MuJoCo suite the plant's friction flips within about 10 ms of a reversal, so the
//! default width (1 % of the RMS velocity) leaves a residual at every reversal and a trajectory
//! with more reversals is judged worse than it is; measured arms can be smoother than the
//! default. Models with load-dependent friction keep the width the load stage used (their
//! columns hold that model's torque).

use serde::Serialize;

use super::base::BaseModel;
use super::guard::heldout_per_joint;
use super::prepare::Prepared;
use super::problem::Problem;
use super::row_table::{GridBaseCache, RowTable};
use super::select::Selected;
use crate::effects::{Effect, Scales};

/// The widths tried, as fractions of each joint's RMS training velocity.
pub const FRACTIONS: [f64; 3] = [0.003, Scales::COULOMB_FRACTION, 0.03];

/// A relative gain in the score below this is a tie (the default width is kept).
const TIE: f64 = 1e-3;

/// One width tried.
#[derive(Debug, Clone, Serialize)]
pub struct WidthTrial {
    /// `v` as a fraction of the joint's RMS velocity.
    pub fraction: f64,
    /// Held-out relative RMS error per joint (NaN where the fit failed).
    pub heldout: Vec<f64>,
    /// Geometric mean of `heldout` over the compared joints.
    pub score: f64,
}

/// The scan's result (report.json `coulomb_width`).
#[derive(Debug, Clone, Serialize)]
pub struct WidthScan {
    /// "run" or "block".
    pub cross_validation: String,
    pub trials: Vec<WidthTrial>,
    /// The fraction kept.
    pub chosen: f64,
}

/// Whether `selected`'s model has a smoothed-sign column the width changes, and no
/// load-dependent one.
fn scannable(selected: &Selected) -> bool {
    let terms = &selected.selection.terms;
    terms
        .iter()
        .any(|t| matches!(t.effect, Effect::Coulomb | Effect::Stribeck))
        && !terms.iter().any(|t| t.effect.needs_load())
}

/// Scans the Coulomb width of `selected` on `train` (joints in `skip` are not judged) and
/// returns the model refitted at the width kept, with the scan (`None` when not scannable).
/// Each width's rows are tabulated once when they fit (the base part shared through `grids`).
pub(super) fn choose_width(
    base: &BaseModel,
    (train, grids): (&[Prepared], &GridBaseCache),
    blocks: usize,
    selected: Selected,
    skip: &[usize],
) -> (Selected, Option<WidthScan>) {
    if !scannable(&selected) {
        return (selected, None);
    }
    let terms = selected.selection.terms.clone();
    let by_run = selected.problem.files() > 1;
    let judge = |p: &Problem, train: &[Prepared]| -> Vec<f64> {
        heldout_per_joint(base, p, train, &terms, by_run)
            .or_else(|_| heldout_per_joint(base, p, train, &terms, false))
            .unwrap_or_else(|_| vec![f64::NAN; p.layout.dof])
    };
    let score = |e: &[f64]| -> f64 {
        let logs: Vec<f64> = e
            .iter()
            .enumerate()
            .filter(|(j, _)| !skip.contains(j))
            .map(|(_, e)| e.ln())
            .collect();
        if logs.is_empty() || logs.iter().any(|l| !l.is_finite()) {
            return f64::NAN;
        }
        (logs.iter().sum::<f64>() / logs.len() as f64).exp()
    };
    let mut trials = Vec::new();
    let mut best: Option<(f64, f64, Problem)> = None;
    let mut default_score = f64::NAN;
    for &fraction in &FRACTIONS {
        let (problem, heldout) = if fraction == Scales::COULOMB_FRACTION {
            (None, judge(&selected.problem, train))
        } else {
            let mut layout = selected.problem.layout.clone();
            for s in &mut layout.scales {
                *s = s.with_coulomb_fraction(fraction);
            }
            let tabled = RowTable::attach(base, &layout, train, grids);
            let files = tabled.as_deref().unwrap_or(train);
            let p = Problem::build(base, layout, files, blocks);
            let e = judge(&p, files);
            (Some(p), e)
        };
        let s = score(&heldout);
        trials.push(WidthTrial {
            fraction,
            heldout,
            score: s,
        });
        match problem {
            None => default_score = s,
            Some(p) if s.is_finite() && best.as_ref().is_none_or(|(b, _, _)| s < *b) => {
                best = Some((s, fraction, p))
            }
            Some(_) => {}
        }
    }
    let mut selected = selected;
    let mut chosen = Scales::COULOMB_FRACTION;
    if let Some((s, fraction, p)) = best {
        if !default_score.is_finite() || s < default_score * (1.0 - TIE) {
            chosen = fraction;
            selected.problem = p;
        }
    }
    let scan = WidthScan {
        cross_validation: if by_run { "run" } else { "block" }.into(),
        trials,
        chosen,
    };
    (selected, Some(scan))
}

#[cfg(test)]
mod tests {
    use crate::effects::{Effect, EffectsSpec, Scales, Term};
    use crate::identify::synth::{generate, Spec};
    use crate::identify::{run, Config};
    use crate::log::Log;

    /// A planar arm with strong Coulomb friction on both joints, its plant's sign smoothed at
    /// `fraction` of each joint's RMS velocity (from a first, exact-sign run of the same motion).
    fn spec(seed: u64, fraction: Option<f64>) -> Spec {
        let arm = crate::arms::resolve("planar2").unwrap();
        let mut s = Spec::new(arm.dh_table().unwrap(), seed)
            .with_effect(Effect::Coulomb, 0, 1.5)
            .with_effect(Effect::Coulomb, 1, 1.0)
            .with_effect(Effect::Viscous, 1, 0.3);
        s.duration = 20.0;
        s.rate_hz = 500.0;
        s.base_hz = 0.2;
        s.with_derivatives = true;
        if let Some(f) = fraction {
            let d = generate(&s);
            let dq = d.dq.expect("exact velocities were asked for");
            let n = 2;
            s.plant_scales = (0..n)
                .map(|j| {
                    let ms = dq.iter().skip(j).step_by(n).map(|v| v * v).sum::<f64>()
                        / (dq.len() / n) as f64;
                    Scales::from_rms_velocity(ms.sqrt()).with_coulomb_fraction(f)
                })
                .collect();
        }
        s
    }

    fn chosen(fraction: Option<f64>) -> (f64, Vec<(f64, f64)>) {
        let arm = crate::arms::resolve("planar2").unwrap();
        let cfg = Config {
            effects: EffectsSpec::Fixed(vec![
                Term::new(Effect::Coulomb, 0),
                Term::new(Effect::Coulomb, 1),
                Term::new(Effect::Viscous, 1),
            ]),
            ..Config::default()
        };
        let out = run(
            &arm,
            vec![Log::from(generate(&spec(3, fraction)))],
            None,
            &cfg,
        )
        .unwrap();
        let w = out
            .coulomb_width
            .expect("a model with Coulomb friction is scanned");
        let scores = w.trials.iter().map(|t| (t.fraction, t.score)).collect();
        (w.chosen, scores)
    }

    #[test]
    fn the_scan_finds_the_plants_coulomb_width() {
        // The oracle is the plant: its Coulomb sign is smoothed at a known width, one of the
        // scanned ones on either side of the default; the held-out error must be lowest there.
        for f in [0.03, 0.003] {
            let (c, scores) = chosen(Some(f));
            assert_eq!(c, f, "plant width {f}: scores {scores:?}");
        }
    }
}
