//! Tests of the effect vocabulary and physics.

use super::*;

#[test]
fn effects_list_parses_all_joint_and_single_joint_forms() {
    let spec = parse_list("viscous, coulomb:2", 2).unwrap();
    assert_eq!(
        spec,
        EffectsSpec::Fixed(vec![
            Term {
                effect: Effect::Viscous,
                joint: 0
            },
            Term {
                effect: Effect::Viscous,
                joint: 1
            },
            Term {
                effect: Effect::Coulomb,
                joint: 1
            },
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
