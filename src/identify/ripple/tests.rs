use super::*;

/// A sine of known wavenumber and phase plus noise: the peak is at its wavenumber.
#[test]
fn the_periodogram_peaks_at_the_ripples_wavenumber() {
    use rand::{Rng, SeedableRng};
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
    for &(k, phase) in &[(3.3, 0.4), (7.9, 2.0), (14.2, -1.1), (41.0, 0.0)] {
        let q: Vec<f64> = (0..20_000)
            .map(|i| 1.4 * (i as f64 * 0.003).sin())
            .collect();
        let r: Vec<f64> = q
            .iter()
            .map(|x| 0.2 * (k * x + phase).sin() + 0.3 * rng.gen_range(-1.0..1.0) + 0.5)
            .collect();
        let p = periodogram_peak((&q, &r, &vec![0; q.len()]), (K_MIN, K_MAX), false).unwrap();
        // Over a range of 2.8 rad the peak's width is ~2π/2.8; the estimate is far inside it.
        assert!((p.k - k).abs() < 0.05, "k {k}: got {}", p.k);
        // Signal variance 0.02 against noise 0.03: share ≈ 0.4.
        assert!((0.3..0.5).contains(&p.share), "k {k}: share {}", p.share);
        assert!(p.significant(), "k {k}: {p:?}");
    }
}

/// Pure noise: no peak explains more than a small share, and about one draw in ten passes the
/// prominence pre-filter (its measured rate; 60 draws, at most 12 pass: the binomial(60, 0.1)
/// tail beyond 12 is about 1 %). A rate near 1 (a background estimate gone wrong) fails.
#[test]
fn noise_has_no_strong_peak() {
    use rand::{Rng, SeedableRng};
    let mut passed = 0;
    for seed in 0..60 {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(8 + seed);
        let q: Vec<f64> = (0..4_000).map(|i| 1.4 * (i as f64 * 0.011).sin()).collect();
        let r: Vec<f64> = q.iter().map(|_| rng.gen_range(-1.0..1.0)).collect();
        let p = periodogram_peak((&q, &r, &vec![0; q.len()]), (K_MIN, K_MAX), false).unwrap();
        assert!(p.share < 0.02, "seed {seed}: {p:?}");
        passed += usize::from(p.significant());
    }
    assert!(passed <= 12, "{passed} of 60 noise draws passed");
}

/// A joint that spans only a few periods of the shortest ripple leaves no background to stand
/// out of: its peak on noise is never significant (not an infinite prominence).
#[test]
fn a_short_range_has_no_significant_noise_peak() {
    use rand::{Rng, SeedableRng};
    for seed in 0..20 {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(100 + seed);
        let q: Vec<f64> = (0..4_000)
            .map(|i| 0.12 * (i as f64 * 0.011).sin())
            .collect();
        let r: Vec<f64> = q.iter().map(|_| rng.gen_range(-1.0..1.0)).collect();
        let p = periodogram_peak((&q, &r, &vec![0; q.len()]), (K_MIN, K_MAX), false).unwrap();
        assert!(!p.significant(), "seed {seed}: {p:?}");
    }
}

/// A constant per run is not a ripple: two runs over different parts of the range, each with its
/// own offset, give no peak; a ripple added to them is still found.
#[test]
fn a_per_run_offset_is_not_a_ripple() {
    use rand::{Rng, SeedableRng};
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(9);
    let mut q: Vec<f64> = (0..10_000)
        .map(|i| 0.8 * (i as f64 * 0.003).sin() - 0.6)
        .collect();
    q.extend((0..10_000).map(|i| 0.8 * (i as f64 * 0.004).sin() + 0.6));
    let run: Vec<usize> = (0..20_000).map(|i| i / 10_000).collect();
    let noise: Vec<f64> = q.iter().map(|_| 0.05 * rng.gen_range(-1.0..1.0)).collect();
    let offset: Vec<f64> = run
        .iter()
        .zip(&noise)
        .map(|(&g, e)| if g == 0 { 0.5 } else { -0.5 } + e)
        .collect();
    let p = periodogram_peak((&q, &offset, &run), (K_MIN, K_MAX), false).unwrap();
    assert!(p.share < 0.01 && !p.significant(), "{p:?}");
    // Pooled (one run), the offset is a step in q that a low wavenumber fits.
    let pooled = periodogram_peak((&q, &offset, &vec![0; q.len()]), (K_MIN, K_MAX), false).unwrap();
    assert!(pooled.share > 0.3, "pooled {pooled:?}");
    let with: Vec<f64> = offset
        .iter()
        .zip(&q)
        .map(|(o, x)| o + 0.1 * (5.0 * x).sin())
        .collect();
    let p = periodogram_peak((&q, &with, &run), (K_MIN, K_MAX), false).unwrap();
    assert!((p.k - 5.0).abs() < 0.05 && p.significant(), "{p:?}");
}

/// Too small a range for one period of the largest wavenumber: no scan.
#[test]
fn a_joint_that_hardly_moves_is_not_scanned() {
    let q: Vec<f64> = (0..1000).map(|i| 0.05 * (i as f64 * 0.01).sin()).collect();
    let r: Vec<f64> = q.iter().map(|x| x.sin()).collect();
    assert!(periodogram_peak((&q, &r, &vec![0; q.len()]), (K_MIN, K_MAX), false).is_none());
}

/// A planar arm whose second joint's torque has a position ripple of wavenumber `k` (both
/// phases), or none: what `--effects auto` finds.
fn identify_ripple(seed: u64, ripple: Option<f64>) -> crate::identify::Outcome {
    use crate::effects::Scales;
    use crate::identify::synth::{generate, Spec};
    use crate::identify::{run, Config};
    use crate::log::Log;
    let arm = crate::arms::resolve("planar2").unwrap();
    let mut s = Spec::new(arm.dh_table().unwrap(), seed)
        .with_effect(Effect::Viscous, 0, 0.4)
        .with_effect(Effect::Viscous, 1, 0.3);
    s.duration = 30.0;
    if let Some(k) = ripple {
        s = s
            .with_effect(Effect::RippleSin, 1, 0.12)
            .with_effect(Effect::RippleCos, 1, -0.08);
        s.plant_scales = vec![Scales::EXACT, Scales::EXACT.with_ripple(k)];
    }
    let cfg = Config {
        effects: EffectsSpec::Auto,
        ..Config::default()
    };
    run(&arm, vec![Log::from(generate(&s))], None, &cfg).unwrap()
}

/// The oracle is the plant: a ripple of known wavenumber is found on its joint, at that
/// wavenumber, and on no other joint; the same plant without it gets no ripple term.
#[test]
fn the_stage_finds_a_plants_ripple_and_invents_none() {
    for (seed, k) in [(5, 6.3), (6, 11.0)] {
        let out = identify_ripple(seed, Some(k));
        let scan = out
            .ripple
            .iter()
            .find(|s| s.joint == 1)
            .expect("joint 2 scanned");
        assert!(scan.accepted, "seed {seed}: {:?}", out.ripple);
        assert!(
            (scan.k - k).abs() < 0.05,
            "seed {seed}: k {} against {k}",
            scan.k
        );
        let labels: Vec<String> = out.selection.terms.iter().map(|t| t.label()).collect();
        assert!(
            labels
                .iter()
                .any(|l| l.starts_with("ripple_") && l.ends_with('2')),
            "{labels:?}"
        );
        assert!(
            !labels
                .iter()
                .any(|l| l.starts_with("ripple_") && l.ends_with('1')),
            "{labels:?}"
        );
        // The sine and the cosine are one candidate: both added, on one test of the pair.
        let pair: Vec<_> = out
            .selection
            .steps
            .iter()
            .filter(|st| st.added.effect.is_ripple())
            .collect();
        assert_eq!(pair.len(), 2, "seed {seed}: {labels:?}");
        assert_eq!(pair[0].evidence, pair[1].evidence, "seed {seed}");
        assert_eq!(pair[0].evidence.label, "ripple_sin2+ripple_cos2");
    }
    for seed in [5, 6, 7] {
        let out = identify_ripple(seed, None);
        assert!(
            out.ripple.iter().all(|s| !s.accepted),
            "seed {seed}: {:?}",
            out.ripple
        );
    }
}

/// A ripple whose period is about the joint's range (k = 3.5 and 4.4 rad⁻¹ on the base joint of
/// a planar arm) is partly a constant and a line there, which an offset and a spring take when
/// they enter the model first; the periodogram of what they leave then peaks off the ripple's
/// wavenumber (before this scan: errors up to 1.5 rad⁻¹, median 0.27, and a stand-in kept in 11
/// of these 16 runs). The stage scans the joint without them, refines `k` by backfitting and
/// least squares, and a stand-in goes back to the test with the ripple in the model.
#[test]
fn a_slow_ripple_is_found_at_its_wavenumber_without_stand_ins() {
    use crate::effects::Scales;
    use crate::identify::synth::{generate, Spec};
    use crate::identify::{run, Config};
    use crate::log::Log;
    let arm = crate::arms::resolve("planar2").unwrap();
    let (mut errors, mut stand_ins) = (Vec::new(), 0);
    for seed in 1..9u64 {
        for k in [3.5, 4.4] {
            let mut s = Spec::new(arm.dh_table().unwrap(), seed)
                .with_effect(Effect::Viscous, 1, 0.3)
                .with_effect(Effect::RippleSin, 0, 0.3)
                .with_effect(Effect::RippleCos, 0, 0.25);
            s.plant_scales = vec![Scales::EXACT.with_ripple(k), Scales::EXACT];
            let cfg = Config {
                effects: EffectsSpec::Auto,
                ..Config::default()
            };
            let out = run(&arm, vec![Log::from(generate(&s))], None, &cfg).unwrap();
            let scan = out
                .ripple
                .iter()
                .find(|s| s.joint == 0)
                .expect("joint 1 scanned");
            assert!(scan.accepted, "seed {seed}, k {k}: {:?}", out.ripple);
            errors.push((scan.k - k).abs());
            let terms = &out.selection.terms;
            stand_ins += usize::from(terms.iter().any(|t| stand_in(t, 0)));
        }
    }
    errors.sort_by(f64::total_cmp);
    // Measured: median 0.025, largest 0.30 (with an offset and a spring kept beside it, the one
    // run with a stand-in).
    assert!(errors[errors.len() / 2] < 0.05, "{errors:?}");
    assert!(errors[errors.len() - 1] < 0.5, "{errors:?}");
    assert!(
        stand_ins <= 2,
        "an offset or spring on joint 1 in {stand_ins} of 16 runs"
    );
}
