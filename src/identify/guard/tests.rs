//! The guard's tests: synthetic arms whose truth says which terms a joint lacks.
use crate::effects::{Effect, EffectsSpec, Term};
use crate::identify::synth::{generate, Spec};
use crate::identify::{run, Config, Rules};
use crate::log::Log;

fn spec(seed: u64) -> Spec {
    let arm = crate::arms::resolve("planar2").unwrap();
    let mut s = Spec::new(arm.dh_table().unwrap(), seed)
        .with_effect(Effect::Viscous, 1, 0.6)
        .with_effect(Effect::Coulomb, 1, 0.8);
    s.duration = 20.0;
    s.rate_hz = 200.0;
    s
}

/// Joint 2's validation error on the unseen run: the model's and the plain fit's.
fn unseen_joint2(out: &crate::identify::Outcome) -> (f64, f64) {
    let joint2 = |m: &crate::identify::ModelResult| m.validation.as_ref().unwrap().per_joint[1];
    (joint2(&out.after), joint2(out.plain.as_ref().unwrap()))
}

#[test]
fn a_model_that_missed_a_joints_friction_gets_the_plain_terms_back() {
    // The oracle: joint 2 has viscous and Coulomb friction, joint 1 none. A search made
    // blind (allowed no step) selects the rigid body only, which
    // the plain fit — with friction on every joint — beats on joint 2. The guard must see
    // that on held-out training blocks and add joint 2's plain terms (the true friction
    // among them), after which the model predicts joint 2 as well as the plain fit does on
    // a validation run it never saw.
    let arm = crate::arms::resolve("planar2").unwrap();
    let train = Log::from(generate(&spec(4)));
    let val = Log::from(generate(&spec(5)));
    let cfg = Config {
        rules: Rules {
            max_steps: 0,
            ..Rules::default()
        },
        ..Config::default()
    };
    let out = run(&arm, vec![train], Some(val), &cfg).unwrap();
    assert!(out.selection.steps.is_empty(), "{:?}", out.selection.steps);
    let g = out.guard.as_ref().unwrap();
    assert_eq!(g.cross_validation, "block");
    let j2 = &g.joints[1];
    // Before the guard the rigid model lost joint 2's friction (several times the plain
    // fit's error); after it, joint 2 is no worse than the plain fit.
    assert!(j2.selected_before_guard > 2.0 * j2.plain, "{j2:?}");
    assert!(j2.selected <= j2.plain, "{j2:?}");
    assert_eq!(j2.winner, "selected");
    for e in [Effect::Viscous, Effect::Coulomb] {
        let t = Term::new(e, 1);
        assert!(
            out.selection.guarded.contains(&t),
            "{:?}",
            out.selection.guarded
        );
    }
    // On the unseen run: within 2 % of the plain fit's joint-2 error (the same joint
    // model; only the shared rigid-body parameters differ by the other joint's terms).
    let (after, plain) = unseen_joint2(&out);
    assert!(after <= 1.02 * plain, "after {after} plain {plain}");
    // The friction coefficients come out close to the truth (1 % torque noise).
    let coef = |e: Effect| {
        out.effects
            .iter()
            .find(|(t, _)| *t == Term::new(e, 1))
            .map(|(_, est)| est.value)
            .unwrap()
    };
    assert!(
        (coef(Effect::Viscous) - 0.6).abs() < 0.06,
        "{}",
        coef(Effect::Viscous)
    );
    assert!(
        (coef(Effect::Coulomb) - 0.8).abs() < 0.08,
        "{}",
        coef(Effect::Coulomb)
    );
}

#[test]
fn a_joint_the_plain_fit_leads_by_more_than_the_bar_gets_its_plain_terms_whatever_the_tests() {
    // Joint 2's torque drifts over the run, joint 1's does not. Blind to the drift, the rigid
    // model's held-out blocks lose to the plain fit's (whose offset takes the drift's mean)
    // late in the run and win early: a pooled lead past the 2 % bar that no per-block test
    // calls significant. The search is made blind and the tests unpassable (α = 1e-30), so
    // only the lead route can act: joint 2's plain terms must be added, and the unseen
    // run's joint 2 must come within 2 % of the plain fit's. Joint 1 gets nothing.
    let arm = crate::arms::resolve("planar2").unwrap();
    let drift = |seed| {
        let mut s = Spec::new(arm.dh_table().unwrap(), seed).with_effect(Effect::Drift, 1, 0.01);
        s.duration = 20.0;
        s.rate_hz = 200.0;
        s
    };
    let train = Log::from(generate(&drift(4)));
    let val = Log::from(generate(&drift(5)));
    let cfg = Config {
        rules: Rules {
            max_steps: 0,
            guard_alpha: 1e-30,
            ..Rules::default()
        },
        ..Config::default()
    };
    let out = run(&arm, vec![train], Some(val), &cfg).unwrap();
    let g = out.guard.as_ref().unwrap();
    let (j1, j2) = (&g.joints[0], &g.joints[1]);
    assert!(
        j2.selected_before_guard > (1.0 + super::LEAD) * j2.plain,
        "{j2:?}"
    );
    assert!(!j2.significant, "{j2:?}");
    assert!(
        j2.added.contains(&Term::new(Effect::Offset, 1).label()),
        "{j2:?}"
    );
    assert!(j2.selected <= (1.0 + super::LEAD) * j2.plain, "{j2:?}");
    assert!(g.fixes.iter().any(|f| f.contains("bar")), "{:?}", g.fixes);
    assert!(
        j1.selected_before_guard <= (1.0 + super::LEAD) * j1.plain,
        "{j1:?}"
    );
    assert!(j1.added.is_empty(), "{j1:?}");
    let (after, plain) = unseen_joint2(&out);
    assert!(after <= 1.02 * plain, "after {after} plain {plain}");
}

#[test]
fn a_model_the_search_got_right_keeps_its_effects_and_its_accuracy() {
    // With the default rules the search finds joint 2's friction itself. The plain fit has
    // two more columns on joint 2 (offset, armature: zero in truth), so it may win there by
    // noise — measured 0.03 % better, per-block t = -0.6 — which the guard's test must not
    // take for evidence: nothing is added, the joint-2 error is the plain fit's to 0.1 %,
    // and nothing is weak.
    let arm = crate::arms::resolve("planar2").unwrap();
    let train = Log::from(generate(&spec(6)));
    let out = run(&arm, vec![train], None, &Config::default()).unwrap();
    let mut found: Vec<String> = out
        .selection
        .steps
        .iter()
        .map(|s| s.label.clone())
        .collect();
    found.sort();
    assert_eq!(found, ["coulomb2", "viscous2"]);
    let g = out.guard.as_ref().unwrap();
    let j2 = &g.joints[1];
    assert!(
        (j2.selected_before_guard / j2.plain - 1.0).abs() < 1e-3,
        "{j2:?}"
    );
    assert!((j2.selected / j2.plain - 1.0).abs() < 1e-3, "{j2:?}");
    assert!(!j2.significant, "{j2:?}");
    assert!(out.selection.guarded.is_empty(), "{:?}", g.fixes);
    assert!(g.weak.is_empty(), "{:?}", g.weak);
}

#[test]
fn a_guarded_model_with_load_dependent_terms_is_the_model_its_effects_name() {
    // The load-dependent columns hold the torque of the model's other terms. When the guard
    // adds plain terms after the load stage, those columns must be rebuilt from the guarded
    // model, so that the same effects given as a fixed list (a user re-running the found
    // model) predict the same torque. The search is made to miss joint 1's small Coulomb
    // friction (an effect must explain 0.2 % of the torque power), not joint 2's
    // load-dependent friction; the guard then adds joint 1's plain terms.
    let arm = crate::arms::resolve("planar2").unwrap();
    let mut s = Spec::new(arm.dh_table().unwrap(), 48)
        .with_effect(Effect::Coulomb, 0, 0.08)
        .with_effect(Effect::LoadCoulomb, 1, 0.15);
    s.duration = 20.0;
    s.rate_hz = 200.0;
    let train = Log::from(generate(&s));
    let val = Log::from(generate(&Spec { seed: 49, ..s }));
    let fixed = |effects| Config {
        effects,
        rules: Rules {
            min_share: 2e-3,
            ..Rules::default()
        },
        smoothing: Some(crate::identify::Smoothing::default()),
        derivative: crate::derivative::Options {
            cutoff_hz: Some(8.0),
            ..Default::default()
        },
        ..Config::default()
    };
    let auto = run(
        &arm,
        vec![train.clone()],
        Some(val.clone()),
        &fixed(EffectsSpec::Auto),
    )
    .unwrap();
    let terms = auto.selection.terms.clone();
    assert!(
        !auto.selection.guarded.is_empty(),
        "the guard added nothing: {:?} {:?}",
        auto.selection.terms,
        auto.guard
    );
    assert!(
        terms.iter().any(|t| t.effect.needs_load()),
        "no load-dependent term: {terms:?}"
    );
    let again = run(
        &arm,
        vec![train],
        Some(val),
        &fixed(EffectsSpec::Fixed(terms)),
    )
    .unwrap();
    let per_joint =
        |o: &crate::identify::Outcome| o.after.validation.as_ref().unwrap().per_joint.clone();
    for (a, b) in per_joint(&auto).iter().zip(per_joint(&again)) {
        // Equal but for the order of summation.
        assert!((a - b).abs() < 1e-9 * b, "auto {a}, fixed list {b}");
    }
}
