//! **Extrapolation warnings**: a validation file that takes a joint beyond the positions the
//! training files cover, on a joint whose model holds terms shaped by its position (a spring, a
//! position ripple). The rigid-body model extrapolates by its physics; those terms were fitted
//! only over the training range — a spring's slope may stand in for part of a slow ripple there,
//! and a ripple's wavenumber is known to a fraction of `2π / range` — so the prediction beyond it
//! is not what the training data vouch for (extended suite, seed 129, before the ripple stage
//! fitted the wavenumber: a spring and a ripple fitted over 2 rad predicted a run reaching 0.7 rad
//! further at 31× the true model's error).
//!
//! The same holds in time for a **drift** (its column is the time since the run's start, a line
//! fitted over the training files' durations): a validation file that runs longer carries the
//! line past where it was fitted, while a thermal drift levels off.

use super::prepare::Prepared;
use crate::effects::{Effect, Term};

/// Share of the training span a validation file may reach beyond either end before the warning:
/// a few per cent is the edge of any run, not a new region.
pub const MARGIN: f64 = 0.1;

/// Each joint's least and greatest position over `files` (their kept raw samples).
pub fn ranges(files: &[&Prepared], dof: usize) -> (Vec<f64>, Vec<f64>) {
    let mut lo = vec![f64::INFINITY; dof];
    let mut hi = vec![f64::NEG_INFINITY; dof];
    for p in files {
        p.log.rows(p.raw_keep.0, p.raw_keep.1, |row| {
            for j in 0..dof {
                let q = row[1 + j];
                lo[j] = lo[j].min(q);
                hi[j] = hi[j].max(q);
            }
        });
    }
    (lo, hi)
}

/// The longest time since its run's start over `files`' kept raw samples (s): how far a drift
/// column reaches (a file that goes on from a training file starts at that run's time).
pub fn duration(files: &[&Prepared]) -> f64 {
    files
        .iter()
        .filter(|p| p.raw_keep.1 > p.raw_keep.0)
        .map(|p| p.log.run_time() + p.log.t(p.raw_keep.1 - 1) - p.log.t(0))
        .fold(0.0, f64::max)
}

/// One warning naming the drift terms of `terms` when the validation file `val` runs more than
/// [`MARGIN`] longer than `train` (s, [`duration`] of the training files).
pub fn time_warning(train: f64, val: Option<&Prepared>, terms: &[Term]) -> Option<String> {
    let val = val?;
    let names: Vec<String> = terms
        .iter()
        .filter(|t| t.effect == Effect::Drift)
        .map(Term::label)
        .collect();
    let reach = duration(&[val]);
    (!names.is_empty() && train > 0.0 && reach > (1.0 + MARGIN) * train).then(|| {
        format!(
            "the validation file `{}` reaches {:.1} s since its run's start, the training files at most {:.1} s: {} (a line in the time since the run's start) is extrapolated over the rest, where a thermal drift would have levelled off, so the validation error late in that file is not what the training data vouch for. Train on runs as long as the ones you predict, or read the validation plot up to {:.1} s.",
            val.name,
            reach,
            train,
            names.join(", "),
            train
        )
    })
}

/// Whether `t`'s column depends on its joint's position beyond the rigid-body model.
fn position_shaped(t: &Term) -> bool {
    t.effect == Effect::Spring || t.effect.is_ripple()
}

/// One warning per joint of `terms`' position-shaped terms that the validation file `val` takes
/// more than [`MARGIN`] of its training span beyond the training files' range (`lo`, `hi`:
/// [`ranges`] of the training files).
pub fn warnings((lo, hi): (&[f64], &[f64]), val: Option<&Prepared>, terms: &[Term]) -> Vec<String> {
    let Some(val) = val else {
        return Vec::new();
    };
    let mut joints: Vec<usize> = terms
        .iter()
        .filter(|t| position_shaped(t))
        .map(|t| t.joint)
        .collect();
    joints.sort();
    joints.dedup();
    if joints.is_empty() {
        return Vec::new();
    }
    let (vlo, vhi) = ranges(&[val], lo.len());
    joints
        .into_iter()
        .filter(|&j| {
            let span = hi[j] - lo[j];
            span.is_finite() && (vlo[j] < lo[j] - MARGIN * span || vhi[j] > hi[j] + MARGIN * span)
        })
        .map(|j| {
            let names: Vec<String> = terms
                .iter()
                .filter(|t| t.joint == j && position_shaped(t))
                .map(Term::label)
                .collect();
            format!(
                "the validation file `{}` moves joint {} over [{:.3}, {:.3}], beyond the training files' [{:.3}, {:.3}]: its {} (shaped by the joint's position) were fitted only over the training range and are extrapolated there, so the validation error there is not what the training data vouch for. Train over the range the arm will use, or read the validation plot where the joint leaves it.",
                val.name,
                j + 1,
                vlo[j],
                vhi[j],
                lo[j],
                hi[j],
                names.join(", ")
            )
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use crate::effects::{Effect, EffectsSpec, Term};
    use crate::identify::synth::{generate, Spec};
    use crate::identify::{run, Config};
    use crate::log::Log;

    /// A planar2 fit of `terms` on `train`, validated on `val`.
    fn fit(train: Log, val: Log, terms: Vec<Term>) -> crate::identify::Outcome {
        let arm = crate::arms::resolve("planar2").unwrap();
        let cfg = Config {
            effects: EffectsSpec::Fixed(terms),
            ..Config::default()
        };
        run(&arm, vec![train], Some(val), &cfg).unwrap()
    }

    /// The warnings of a fit of `terms` on `train`, validated on `val`.
    fn warnings_of(
        train: &crate::data::Trajectory,
        val: &crate::data::Trajectory,
        terms: Vec<Term>,
    ) -> Vec<String> {
        fit(Log::from(train.clone()), Log::from(val.clone()), terms).warnings
    }

    /// The oracle is a known shift: the training run itself as validation gives no warning; the
    /// same run with joint 1's positions moved by 1 rad warns for the joint whose model holds a
    /// spring, naming it, and not for a model without one.
    #[test]
    fn a_validation_run_beyond_the_training_range_is_named_where_a_spring_is_extrapolated() {
        let arm = crate::arms::resolve("planar2").unwrap();
        let spec = Spec::new(arm.dh_table().unwrap(), 3)
            .with_effect(Effect::Viscous, 0, 0.4)
            .with_effect(Effect::Spring, 0, 2.0);
        let train = generate(&spec);
        let mut shifted = train.clone();
        for k in 0..shifted.t.len() {
            shifted.q[k * shifted.dof] += 1.0;
        }
        let identify =
            |terms: Vec<Term>, val: &crate::data::Trajectory| warnings_of(&train, val, terms);
        let spring = vec![Term::new(Effect::Viscous, 0), Term::new(Effect::Spring, 0)];
        let beyond = |w: &[String]| {
            w.iter()
                .filter(|w| w.contains("beyond the training"))
                .cloned()
                .collect::<Vec<_>>()
        };
        assert!(beyond(&identify(spring.clone(), &train)).is_empty());
        let w = beyond(&identify(spring, &shifted));
        assert_eq!(w.len(), 1, "{w:?}");
        assert!(
            w[0].contains("joint 1 ") && w[0].contains("spring1"),
            "{w:?}"
        );
        let plain = vec![Term::new(Effect::Viscous, 0)];
        assert!(beyond(&identify(plain, &shifted)).is_empty());
    }

    /// The oracle is the files' own clocks: a validation file twice as long as the training
    /// one warns, naming the drift and both durations; the training run itself and a model
    /// without a drift do not.
    #[test]
    fn a_validation_run_longer_than_the_training_runs_is_named_where_a_drift_is_extrapolated() {
        let arm = crate::arms::resolve("planar2").unwrap();
        let spec = Spec::new(arm.dh_table().unwrap(), 5)
            .with_effect(Effect::Viscous, 1, 0.4)
            .with_effect(Effect::Drift, 1, 0.02);
        let long = generate(&spec);
        let half = long.t.len() / 2;
        let mut train = long.clone();
        train.t.truncate(half);
        train.q.truncate(half * long.dof);
        for v in [&mut train.dq, &mut train.ddq, &mut train.tau]
            .into_iter()
            .flatten()
        {
            v.truncate(half * long.dof);
        }
        let identify = |terms: Vec<Term>, val: &crate::data::Trajectory| {
            let w = warnings_of(&train, val, terms);
            w.into_iter()
                .filter(|w| w.contains("levelled off"))
                .collect::<Vec<_>>()
        };
        let drift = vec![Term::new(Effect::Viscous, 1), Term::new(Effect::Drift, 1)];
        assert!(identify(drift.clone(), &train).is_empty());
        let w = identify(drift, &long);
        assert_eq!(w.len(), 1, "{w:?}");
        assert!(w[0].contains("drift2"), "{w:?}");
        // The two durations named, each within the samples the filters' edges drop (≤ 5 %).
        let after = |key: &str| -> f64 {
            let rest = &w[0][w[0].find(key).unwrap() + key.len()..];
            rest.split(' ').next().unwrap().parse().unwrap()
        };
        let (t_long, t_train) = (
            long.t[long.t.len() - 1] - long.t[0],
            train.t[half - 1] - train.t[0],
        );
        assert!(
            (after("reaches ") / t_long - 1.0).abs() < 0.05,
            "{w:?} {t_long}"
        );
        assert!(
            (after("at most ") / t_train - 1.0).abs() < 0.05,
            "{w:?} {t_train}"
        );
        assert!(identify(vec![Term::new(Effect::Viscous, 1)], &long).is_empty());
    }

    /// The oracle is the drift the data were made with: a run cut by time into a fit file and
    /// a holdout whose clock goes on is one run, so the holdout's drift goes on from the fit's
    /// and a model with the true drift predicts it to the noise (within 1.2× its in-sample
    /// error on that joint). The same holdout on a clock of its own is a new run whose drift
    /// starts again: its error is several times larger, and no "goes on" notice is given.
    #[test]
    fn a_holdout_that_goes_on_from_the_fit_file_goes_on_with_its_drift() {
        let arm = crate::arms::resolve("planar2").unwrap();
        let spec = Spec::new(arm.dh_table().unwrap(), 7)
            .with_effect(Effect::Viscous, 1, 0.4)
            .with_effect(Effect::Drift, 1, 0.02);
        let run_log = Log::from(generate(&spec));
        let cut = run_log.len() * 7 / 10;
        let (train, hold) = (run_log.slice(0, cut), run_log.slice(cut, run_log.len()));
        let fresh = {
            let mut t = hold.read(0, hold.len());
            let t0 = t.t[0];
            t.t.iter_mut().for_each(|x| *x -= t0);
            Log::from(t)
        };
        let terms = vec![Term::new(Effect::Viscous, 1), Term::new(Effect::Drift, 1)];
        let on = fit(train.clone(), hold, terms.clone());
        let new = fit(train, fresh, terms);
        let j2 = |o: &crate::identify::Outcome| o.after.validation.as_ref().unwrap().per_joint[1];
        let in_sample = on.after.train.per_joint[1];
        assert!(
            on.warnings.iter().any(|w| w.contains("goes on where")),
            "{:?}",
            on.warnings
        );
        assert!(
            !new.warnings.iter().any(|w| w.contains("goes on where")),
            "{:?}",
            new.warnings
        );
        assert!(
            j2(&on) <= 1.2 * in_sample,
            "{} against in-sample {in_sample}",
            j2(&on)
        );
        assert!(
            j2(&new) >= 3.0 * j2(&on),
            "new run {} against {}",
            j2(&new),
            j2(&on)
        );
    }
}
