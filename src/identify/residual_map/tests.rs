use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use super::*;

/// A standard normal sample (Box–Muller).
fn gauss(rng: &mut ChaCha8Rng) -> f64 {
    let (u, v): (f64, f64) = (rng.gen_range(1e-300..1.0), rng.gen());
    (-2.0 * u.ln()).sqrt() * (2.0 * std::f64::consts::PI * v).cos()
}

/// Positions of `n` consecutive samples of one file.
fn one_file(n: usize) -> Vec<(usize, u64)> {
    (0..n as u64).map(|t| (0, t)).collect()
}

/// A stationary AR(1) sequence with lag-1 correlation `rho` and unit variance.
fn ar1(rng: &mut ChaCha8Rng, n: usize, rho: f64) -> Vec<f64> {
    let s = (1.0 - rho * rho).sqrt();
    let mut x = gauss(rng);
    (0..n)
        .map(|_| {
            let v = x;
            x = rho * x + s * gauss(rng);
            v
        })
        .collect()
}

#[test]
fn a_coulomb_like_residual_shows_on_the_velocity_map_and_not_on_an_unrelated_one() {
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    let n = 6000;
    let t: Vec<f64> = (0..n).map(|k| k as f64 * 0.01).collect();
    let dq: Vec<f64> = t
        .iter()
        .map(|t| (1.3 * t).sin() + 0.4 * (3.1 * t).cos())
        .collect();
    let r: Vec<f64> = dq
        .iter()
        .map(|v| 0.3 * v.signum() + 0.5 * gauss(&mut rng))
        .collect();
    let at = one_file(n);
    let m = quantile_map(1, Variable::Velocity, &dq, &r, &at);
    assert_eq!(m.bins.len(), BINS);
    assert_eq!(m.bins.iter().map(|b| b.n).sum::<usize>(), n);
    // Noise about the bin means is white: ρ small, bands from nearly all samples.
    assert!(m.rho < 0.05, "rho {}", m.rho);
    let mut covered = 0;
    let mut one_signed = 0;
    for b in &m.bins {
        assert!(b.lo <= b.centre && b.centre <= b.hi && b.ci95_lo < b.mean && b.mean < b.ci95_hi);
        if b.lo > 0.0 || b.hi < 0.0 {
            one_signed += 1;
            let truth = 0.3 * b.centre.signum();
            covered += usize::from(b.ci95_lo <= truth && truth <= b.ci95_hi);
            assert!((b.mean - truth).abs() < 0.1, "{b:?}");
        }
    }
    assert!(
        one_signed >= 10 && covered + 1 >= one_signed,
        "{covered}/{one_signed}"
    );
    assert!(m.p_value < 1e-12 && m.dof == BINS, "{m:?}");
    // The same residual against white noise: nothing to see.
    let u: Vec<f64> = (0..n).map(|_| gauss(&mut rng)).collect();
    let m = quantile_map(1, Variable::Torque, &u, &r, &at);
    assert!(m.p_value > 1e-3, "{}", m.p_value);
}

/// White-noise residuals: the bands cover the true mean 0 in about 95 % of the bins and the
/// p-values are spread like a uniform variable's (few below 1 %).
#[test]
fn white_noise_bands_cover_zero_95_percent_and_p_values_are_uniform() {
    let mut rng = ChaCha8Rng::seed_from_u64(2);
    let (reps, n) = (200, 2400);
    let at = one_file(n);
    let (mut covered, mut bins, mut small_p, mut p_sum) = (0, 0, 0, 0.0);
    for _ in 0..reps {
        let x: Vec<f64> = (0..n).map(|_| rng.gen::<f64>()).collect();
        let r: Vec<f64> = (0..n).map(|_| gauss(&mut rng)).collect();
        let m = quantile_map(0, Variable::Position, &x, &r, &at);
        for b in &m.bins {
            bins += 1;
            covered += usize::from(b.ci95_lo <= 0.0 && 0.0 <= b.ci95_hi);
        }
        small_p += usize::from(m.p_value < 0.01);
        p_sum += m.p_value;
    }
    let coverage = covered as f64 / bins as f64;
    assert!((0.93..0.97).contains(&coverage), "coverage {coverage}");
    assert!(small_p <= 8, "{small_p} of {reps} maps with p < 0.01");
    let mean_p = p_sum / reps as f64;
    assert!((0.42..0.58).contains(&mean_p), "mean p {mean_p}");
}

/// The recursion of [`bin_n_eff`] against the closed form of an AR(1) mean's variance,
/// `Σ_ik ρ^|i−k| = n(1+ρ)/(1−ρ) − 2ρ(1−ρⁿ)/(1−ρ)²`, for one contiguous bin and for two bins
/// taking every other sample (lag 2 in between: ρ²).
#[test]
fn n_eff_matches_the_closed_form_of_an_ar1_mean() {
    let closed = |n: f64, rho: f64| {
        let s =
            n * (1.0 + rho) / (1.0 - rho) - 2.0 * rho * (1.0 - rho.powf(n)) / (1.0 - rho).powi(2);
        n * n / s
    };
    for &(n, rho) in &[(50usize, 0.5), (1000, 0.9), (400, 0.99), (30, 0.0)] {
        let at = one_file(n);
        let one = bin_n_eff(&vec![Some(0); n], 1, &at, rho)[0];
        let want = closed(n as f64, rho).max(2.0);
        assert!(
            (one - want).abs() < 1e-9 * want,
            "n {n} rho {rho}: {one} vs {want}"
        );
        let alternate: Vec<Option<usize>> = (0..n).map(|k| Some(k % 2)).collect();
        let two = bin_n_eff(&alternate, 2, &at, rho);
        let want = closed((n / 2) as f64, rho * rho).max(2.0);
        assert!((two[0] - want).abs() < 1e-9 * want, "{} vs {want}", two[0]);
    }
    // A long stretch: n·(1−ρ)/(1+ρ).
    let (n, rho) = (100_000, 0.8);
    let got = bin_n_eff(&vec![Some(0); n], 1, &one_file(n), rho)[0];
    let factor = (1.0 - rho) / (1.0 + rho);
    assert!((got / (n as f64 * factor) - 1.0).abs() < 1e-3, "{got}");
    // Two files: no correlation between them (twice one file's n_eff).
    let at: Vec<(usize, u64)> = (0..2 * n).map(|k| (k / n, (k % n) as u64)).collect();
    let both = bin_n_eff(&vec![Some(0); 2 * n], 1, &at, rho)[0];
    assert!((both - 2.0 * got).abs() < 1e-6 * got);
}

/// AR(1) residuals (ρ = 0.9) on the time map, whose bins are contiguous stretches: the map
/// estimates ρ, and its bands still cover the true mean 0 about 95 % of the time — where bands
/// from the raw sample count would cover far less.
#[test]
fn bands_of_autocorrelated_residuals_keep_their_coverage() {
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let (reps, n, rho) = (150, 3600, 0.9);
    let at = one_file(n);
    let t: Vec<f64> = (0..n).map(|k| k as f64).collect();
    let (mut covered, mut naive, mut bins, mut rho_sum) = (0, 0, 0, 0.0);
    for _ in 0..reps {
        let r = ar1(&mut rng, n, rho);
        let m = quantile_map(0, Variable::Time, &t, &r, &at);
        rho_sum += m.rho;
        for b in &m.bins {
            bins += 1;
            covered += usize::from(b.ci95_lo <= 0.0 && 0.0 <= b.ci95_hi);
            let half = 1.96 * b.std / (b.n as f64).sqrt();
            naive += usize::from(b.mean.abs() <= half);
        }
    }
    let rho_hat = rho_sum / reps as f64;
    assert!((rho_hat - rho).abs() < 0.03, "rho {rho_hat}");
    let (coverage, naive) = (covered as f64 / bins as f64, naive as f64 / bins as f64);
    assert!((0.91..0.98).contains(&coverage), "coverage {coverage}");
    assert!(naive < 0.6, "naive coverage {naive}");
}

#[test]
fn chi_square_tail_matches_known_values() {
    for x in [0.1, 1.0, 5.0, 30.0] {
        assert!((chi2_sf(x, 2.0) - (-x / 2.0).exp()).abs() < 1e-12);
    }
    // Tables: the 5 % point of χ²₁, the 1 % point of χ²₁₀, the 0.1 % point of χ²₁₂.
    for (x, k, p) in [
        (3.841459, 1.0, 0.05),
        (23.209251, 10.0, 0.01),
        (32.909490, 12.0, 0.001),
    ] {
        assert!((chi2_sf(x, k) / p - 1.0).abs() < 1e-5, "{x} {k}");
    }
    assert_eq!(chi2_sf(0.0, 3.0), 1.0);
    assert_eq!(chi2_sf(f64::INFINITY, 3.0), 0.0);
}

/// A joint that never moves, NaN samples, no samples at all, a run with none: no panic, a
/// single bin or none, and a note.
#[test]
fn degenerate_inputs_give_one_bin_or_none_with_a_note() {
    let n = 500;
    let at = one_file(n);
    let r: Vec<f64> = (0..n).map(|k| (k as f64 * 0.37).sin()).collect();
    let m = quantile_map(0, Variable::Position, &vec![0.25; n], &r, &at);
    assert_eq!(m.bins.len(), 1);
    assert_eq!(m.bins[0].n, n);
    assert!(m.note.as_deref().unwrap().contains("does not vary"));
    let mut x: Vec<f64> = (0..n).map(|k| k as f64).collect();
    x[7] = f64::NAN;
    let mut r2 = r.clone();
    r2[9] = f64::INFINITY;
    let m = quantile_map(0, Variable::Position, &x, &r2, &at);
    assert_eq!(m.bins.iter().map(|b| b.n).sum::<usize>(), n - 2);
    let m = quantile_map(0, Variable::Position, &[], &[], &[]);
    assert!(m.bins.is_empty() && m.p_value.is_nan() && m.note.is_some());
    let runs: Vec<usize> = (0..n).map(|k| if k < 100 { 0 } else { 2 }).collect();
    let m = category_map(0, Variable::Run, &runs, &r, &at);
    assert_eq!(m.bins.len(), 2);
    assert_eq!((m.bins[0].centre, m.bins[1].centre), (0.0, 2.0));
    // A handful of samples: one bin whose band is defined from two on.
    let m = quantile_map(0, Variable::Position, &x[..3], &r[..3], &at[..3]);
    assert_eq!(m.bins.len(), 1);
    assert!(m.bins[0].ci95_lo.is_finite());
    let m = quantile_map(0, Variable::Position, &x[..1], &r[..1], &at[..1]);
    assert!(m.bins[0].ci95_lo.is_nan() && m.p_value.is_nan());
}
