use crate::effects::{Effect, EffectsSpec, Scales};
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
