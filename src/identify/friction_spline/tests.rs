use crate::effects::{Effect, EffectsSpec, Scales, Term};
use crate::identify::synth::{generate, Spec};
use crate::identify::{run, Config, Outcome};
use crate::log::Log;

/// A planar arm with viscous friction on both joints and Coulomb friction on the second, plus,
/// with `curve`, a friction curve on the second: a natural cubic spline on the plant's own
/// velocity unit (0.8 rad/s, not the model's, which comes from the data).
fn identify_curve(seed: u64, curve: bool) -> Outcome {
    let arm = crate::arms::resolve("planar2").unwrap();
    let mut s = Spec::new(arm.dh_table().unwrap(), seed)
        .with_effect(Effect::Viscous, 0, 0.4)
        .with_effect(Effect::Viscous, 1, 0.3)
        .with_effect(Effect::Coulomb, 1, 0.2);
    if curve {
        s = s
            .with_effect(Effect::SplineA, 1, 0.25)
            .with_effect(Effect::SplineB, 1, -0.15)
            .with_effect(Effect::SplineC, 1, 0.3);
        let plant = Scales::EXACT.with_spline_unit(0.8);
        s.plant_scales = vec![plant, plant];
    }
    let cfg = Config {
        effects: EffectsSpec::Auto,
        ..Config::default()
    };
    run(&arm, vec![Log::from(generate(&s))], None, &cfg).unwrap()
}

fn splined_joints(out: &Outcome) -> Vec<usize> {
    let mut j: Vec<usize> = out
        .selection
        .terms
        .iter()
        .filter(|t| t.effect.is_spline())
        .map(|t| t.joint)
        .collect();
    j.dedup();
    j
}

/// The oracle is the plant: its friction curve is found on its joint (all three columns, on one
/// joint F test), and the same plant without it gets no spline anywhere.
#[test]
fn the_stage_finds_a_plants_friction_curve_and_invents_none() {
    for seed in [5, 6] {
        let out = identify_curve(seed, true);
        assert_eq!(
            splined_joints(&out),
            vec![1],
            "seed {seed}: {:?}",
            out.selection.terms
        );
        let steps: Vec<_> = out
            .selection
            .steps
            .iter()
            .filter(|s| s.added.effect.is_spline())
            .collect();
        assert_eq!(steps.len(), 3, "seed {seed}");
        let test = steps[0].evidence.coefficient.expect("the joint F test");
        assert!(test.columns == 3 && test.z > test.z_crit, "{test:?}");
        let clean = identify_curve(seed, false);
        assert!(
            splined_joints(&clean).is_empty(),
            "seed {seed}: {:?}",
            clean.selection.terms
        );
    }
}

/// A curve with no linear part and no step (the suite's kind: what viscous and Coulomb friction
/// take removed, so neither stands out on its own) is a spline *with* them: it is found on its
/// joint, and the model predicts held-out blocks within 5 % of a fit of the plant's own terms
/// (the oracle; 1 % torque noise, so both sit near the noise).
#[test]
fn a_curve_without_a_line_or_a_step_is_fitted_with_its_closed_forms() {
    let arm = crate::arms::resolve("planar2").unwrap();
    let plant = Scales::EXACT.with_spline_unit(0.8);
    let curve = [
        (Effect::SplineA, 0.5),
        (Effect::SplineB, -0.3),
        (Effect::SplineC, 0.6),
    ];
    let spec = |line: [f64; 2]| {
        let mut s = Spec::new(arm.dh_table().unwrap(), 11).with_effect(Effect::Viscous, 0, 0.4);
        for (e, v) in curve {
            s = s.with_effect(e, 1, v);
        }
        s = s
            .with_effect(Effect::Viscous, 1, line[0])
            .with_effect(Effect::Coulomb, 1, line[1]);
        s.plant_scales = vec![plant, plant];
        s
    };
    // The curve's least-squares line and step on this motion, taken out of the plant.
    let mut with_dq = spec([0.0, 0.0]);
    with_dq.with_derivatives = true;
    let dq = generate(&with_dq).dq.unwrap(); // sample-major: [q̇₀, q̇₁] per sample
    let (mut n, mut b) = ([[0.0; 2]; 2], [0.0; 2]);
    for v in dq.iter().skip(1).step_by(2) {
        let f: f64 = curve
            .iter()
            .map(|&(e, c)| c * e.column(0.0, *v, 0.0, 0.0, &plant))
            .sum();
        let x = [*v, Effect::Coulomb.column(0.0, *v, 0.0, 0.0, &plant)];
        for i in 0..2 {
            b[i] += x[i] * f;
            for k in 0..2 {
                n[i][k] += x[i] * x[k];
            }
        }
    }
    let det = n[0][0] * n[1][1] - n[0][1] * n[1][0];
    let line = [
        -(n[1][1] * b[0] - n[0][1] * b[1]) / det,
        -(n[0][0] * b[1] - n[1][0] * b[0]) / det,
    ];
    let logs = || vec![Log::from(generate(&spec(line)))];
    let auto = Config {
        effects: EffectsSpec::Auto,
        ..Config::default()
    };
    let out = run(&arm, logs(), None, &auto).unwrap();
    assert_eq!(splined_joints(&out), vec![1], "{:?}", out.selection.terms);
    let truth: Vec<Term> = [
        (Effect::Viscous, 0),
        (Effect::Viscous, 1),
        (Effect::Coulomb, 1),
    ]
    .into_iter()
    .chain(curve.map(|(e, _)| (e, 1)))
    .map(|(e, j)| Term::new(e, j))
    .collect();
    let oracle = Config {
        effects: EffectsSpec::Fixed(truth),
        ..Config::default()
    };
    let best = run(&arm, logs(), None, &oracle).unwrap();
    let (got, want) = (out.after.heldout_rms, best.after.heldout_rms);
    assert!(
        got <= 1.05 * want,
        "held out {got} against the oracle's {want}"
    );
}
