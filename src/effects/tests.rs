//! Tests of the effect vocabulary and physics.

use super::*;

#[test]
fn effects_list_parses_all_joint_and_single_joint_forms() {
    let spec = parse_list("viscous, coulomb:2", 2).unwrap();
    assert_eq!(
        spec,
        EffectsSpec::Fixed(vec![
            Term::new(Effect::Viscous, 0),
            Term::new(Effect::Viscous, 1),
            Term::new(Effect::Coulomb, 1),
        ])
    );
    assert_eq!(parse_list("auto", 3).unwrap(), EffectsSpec::Auto);
    assert_eq!(parse_list("none", 3).unwrap(), EffectsSpec::Fixed(vec![]));
    assert!(parse_list("viscus", 2)
        .unwrap_err()
        .contains("unknown effect `viscus`"));
    assert!(parse_list("coulomb:3", 2)
        .unwrap_err()
        .contains("joint must be 1..2"));
}

#[test]
fn coulomb_column_is_a_smoothed_sign() {
    let s = Scales::from_rms_velocity(1.0);
    assert!((Effect::Coulomb.column(0.0, 0.5, 0.0, 0.0, &s) - 1.0).abs() < 1e-12);
    assert!((Effect::Coulomb.column(0.0, -0.5, 0.0, 0.0, &s) + 1.0).abs() < 1e-12);
    assert_eq!(Effect::Coulomb.column(0.0, 0.0, 0.0, 0.0, &s), 0.0);
    assert!(Effect::Stribeck.column(0.0, 1.0, 0.0, 0.0, &s).abs() < 1e-30);
}

#[test]
fn the_plant_uses_the_exact_sign_and_the_column_its_smoothing() {
    let s = Scales::from_rms_velocity(1.0);
    assert_eq!(
        Effect::Coulomb.column(0.0, 1e-4, 0.0, 0.0, &Scales::EXACT),
        1.0
    );
    assert!(Effect::Coulomb.column(0.0, 1e-4, 0.0, 0.0, &s) < 0.011);
    assert_eq!(
        Effect::Coulomb.column(0.0, 0.0, 0.0, 0.0, &Scales::EXACT),
        0.0
    );
    assert_eq!(
        Effect::LoadCoulomb.column(0.0, -2.0, 0.0, -3.0, &Scales::EXACT),
        -3.0
    );
}

/// The drift column is the time since the start of the run, whatever the motion: 0 at the start,
/// `t` later (so its coefficient is the torque's rate of change, N·m/s).
#[test]
fn drift_column_is_the_time_since_the_run_started() {
    let s = Scales::from_rms_velocity(1.0);
    assert_eq!(Effect::Drift.column(0.3, 1.0, 2.0, 0.0, &s), 0.0);
    let st = JointState::new(0.3, 1.0, 2.0, &s).at(12.5);
    assert_eq!(Effect::Drift.column_at(&st, 0.0), 12.5);
    assert_eq!(Effect::parse("drift"), Some(Effect::Drift));
}

/// A per-run offset's column is its run's indicator in training data and `1/R` in a run not
/// trained on, so the model predicts a new run with the mean of the runs' offsets.
#[test]
fn per_run_offset_columns_are_run_indicators_and_the_mean_elsewhere() {
    let s = Scales::from_rms_velocity(1.0);
    let term = |run| Term {
        run,
        ..Term::new(Effect::RunOffset, 1)
    };
    let at = |run: Run| JointState::new(0.3, 1.0, 2.0, &s).in_run(run);
    assert_eq!(term(2).column_at(&at(Run::Training(2)), 0.0), 1.0);
    assert_eq!(term(2).column_at(&at(Run::Training(1)), 0.0), 0.0);
    assert_eq!(term(2).column_at(&at(Run::Training(0)), 0.0), 0.0);
    assert_eq!(term(2).column_at(&at(Run::Unseen { runs: 4 }), 0.0), 0.25);
    assert_eq!(term(1).label(), "run_offset2@2");
}

/// `run_offset:J@R` names training run R's column (R from 2); `@R` on another effect, or run 1
/// (whose offset is `offset`), is an error that says so.
#[test]
fn effects_lists_name_a_runs_offset_with_at() {
    let EffectsSpec::Fixed(t) = parse_list("run_offset:2@3, run_offset:1", 2).unwrap() else {
        panic!("not a fixed list");
    };
    assert_eq!(
        t,
        [
            Term::new(Effect::RunOffset, 0),
            Term {
                run: 2,
                ..Term::new(Effect::RunOffset, 1)
            }
        ]
    );
    let err = parse_list("run_offset:2@1", 2).unwrap_err();
    assert!(err.contains("run 1's offset is `offset`"), "{err}");
    let err = parse_list("viscous:2@2", 2).unwrap_err();
    assert!(err.contains("per-run effects only"), "{err}");
    let err = parse_list("run_offset:2@x", 2).unwrap_err();
    assert!(err.contains("a number from 2"), "{err}");
}

#[test]
fn coulomb_and_asym_coulomb_make_two_friction_levels() {
    // Fc⁺ = 0.9 forward, Fc⁻ = 0.3 backward: coulomb ½(Fc⁺+Fc⁻), asym_coulomb ½(Fc⁺−Fc⁻).
    let (up, down) = (0.9, 0.3);
    let friction = |dq: f64| {
        let s = &Scales::EXACT;
        0.5 * (up + down) * Effect::Coulomb.column(0.0, dq, 0.0, 0.0, s)
            + 0.5 * (up - down) * Effect::AsymCoulomb.column(0.0, dq, 0.0, 0.0, s)
    };
    assert!((friction(0.2) - up).abs() < 1e-15);
    assert!((friction(-0.2) + down).abs() < 1e-15);
    assert_eq!(friction(0.0), 0.0);
    // Smoothed like `coulomb`: the same width near rest.
    let s = Scales::from_rms_velocity(1.0);
    let near = Effect::AsymCoulomb.column(0.0, -1e-4, 0.0, 0.0, &s);
    assert!((near - Effect::Coulomb.column(0.0, 1e-4, 0.0, 0.0, &s)).abs() < 1e-15);
}
