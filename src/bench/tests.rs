//! Tests of the quick benchmark: the pool, the parameters, the kernels against the reference,
//! the normal equations and the streaming identification.

use super::*;

#[test]
fn pool_follows_the_pinocchio_distribution() {
    let pool = SamplePool::new(6, 1);
    assert_eq!(pool.q(3), pool.q(3 + POOL));
    let all = |f: &dyn Fn(usize) -> Vec<f64>| (0..POOL).flat_map(f).collect::<Vec<f64>>();
    let q = all(&|k| pool.q(k).to_vec());
    let dq = all(&|k| pool.dq(k).to_vec());
    let ddq = all(&|k| pool.ddq(k).to_vec());
    let max = |v: &[f64]| v.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    assert!(max(&q) <= std::f64::consts::PI && max(&q) > 3.0);
    assert!(max(&dq) <= 2.0 && max(&dq) > 1.9);
    assert!(max(&ddq) <= 5.0 && max(&ddq) > 4.9);
}

#[test]
fn plausible_params_are_physical() {
    let p = plausible_params(3, 2);
    for link in p.chunks(10) {
        let m = link[9];
        assert!(m > 0.0);
        let c = [link[6] / m, link[7] / m, link[8] / m];
        let c2 = c.iter().map(|x| x * x).sum::<f64>();
        // Back to the centre of mass: the diagonal must be positive.
        for (k, idx) in [0usize, 3, 5].into_iter().enumerate() {
            assert!(link[idx] - m * (c2 - c[k] * c[k]) > 0.0);
        }
    }
}

#[test]
fn every_generated_kernel_matches_the_reference() {
    for &arm in crate::arms::all() {
        let case = Case::new(arm);
        let mut r = Reference::new(arm).unwrap();
        for kernel in Kernel::ALL {
            let err = case.check(&mut r, kernel);
            assert!(err < 1e-9, "{} {kernel:?}: {err:e}", arm.name());
        }
    }
}

#[test]
fn fourier_derivatives_are_consistent() {
    let traj = BenchExcitation::random(2, 4);
    let h = 1e-5;
    let (mut q, mut dq, mut ddq) = ([[0.0; 2]; 3], [[0.0; 2]; 3], [[0.0; 2]; 3]);
    for (i, t) in [1.3 - h, 1.3, 1.3 + h].into_iter().enumerate() {
        traj.eval(t, &mut q[i], &mut dq[i], &mut ddq[i]);
    }
    for j in 0..2 {
        assert!(((q[2][j] - q[0][j]) / (2.0 * h) - dq[1][j]).abs() < 1e-7);
        assert!(((dq[2][j] - dq[0][j]) / (2.0 * h) - ddq[1][j]).abs() < 1e-7);
    }
}

#[test]
fn streaming_identification_recovers_the_base_parameters() {
    let arm = crate::arms::find("puma560").unwrap();
    let run = identify_streaming(arm, 20_000, 0.0).unwrap();
    assert!(run.max_rel_error < 1e-6, "{}", run.max_rel_error);
    // Σ τ² − 2θᵀb + θᵀGθ cancels to about 1e-8 of the torque scale: zero up to rounding.
    assert!(
        run.solution.rms_residual < 1e-3,
        "{}",
        run.solution.rms_residual
    );
    assert!(run.solution.cond < 1e6, "{}", run.solution.cond);
    assert_eq!(run.timing.samples, 20_000);
}

#[test]
fn blocked_sparse_accumulation_equals_the_dense_sums() {
    for &arm in crate::arms::all() {
        let (n, nb) = (arm.dof(), arm.nb());
        let mut ne = NormalEquations::new(nb, NormalEquations::row_starts(arm));
        let (mut g, mut b) = (vec![0.0; nb * nb], vec![0.0; nb]);
        let pool = SamplePool::new(n, 8);
        let mut yb = vec![0.0; n * nb];
        let samples = 2 * NormalEquations::BLOCK + 5; // two flushes and a partial block
        for k in 0..samples {
            arm.base_regressor(pool.q(k), pool.dq(k), pool.ddq(k), &mut yb);
            let tau: Vec<f64> = (0..n).map(|i| pool.ddq(k)[i] - 0.5).collect();
            ne.add(&yb, &tau);
            for i in 0..n {
                for r in 0..nb {
                    b[r] += yb[i * nb + r] * tau[i];
                    for c in 0..nb {
                        g[r * nb + c] += yb[i * nb + r] * yb[i * nb + c];
                    }
                }
            }
        }
        assert_eq!(ne.rows(), samples * n);
        ne.flush();
        let scale = g.iter().fold(1.0f64, |m, v| m.max(v.abs()));
        for r in 0..nb {
            assert!(
                (ne.b[r] - b[r]).abs() <= 1e-12 * scale,
                "{} b[{r}]",
                arm.name()
            );
            for c in r..nb {
                let got = ne.g[r * ne.stride + c];
                assert!(
                    (got - g[r * nb + c]).abs() <= 1e-12 * scale,
                    "{} G[{r},{c}]",
                    arm.name()
                );
            }
        }
    }
}

#[test]
fn normal_equations_detect_a_rank_deficient_excitation() {
    let mut ne = NormalEquations::new(2, vec![0]);
    for k in 0..10 {
        let x = k as f64;
        ne.add(&[x, 2.0 * x], &[x]);
    }
    assert!(matches!(
        ne.solve(1e8),
        Err(BenchError::IllConditioned { .. })
    ));
}

#[test]
fn normal_equations_merge_is_addition() {
    let mut a = NormalEquations::new(2, vec![0]);
    let mut b = a.clone();
    let mut all = a.clone();
    for k in 0..10 {
        let (y, t) = ([1.0, k as f64], [3.0 + 2.0 * k as f64]);
        all.add(&y, &t);
        if k % 2 == 0 {
            a.add(&y, &t)
        } else {
            b.add(&y, &t)
        }
    }
    a.merge(&b);
    let s = a.solve(1e8).unwrap();
    let s_all = all.solve(1e8).unwrap();
    assert!(s
        .theta
        .iter()
        .zip(&s_all.theta)
        .all(|(x, y)| (x - y).abs() < 1e-12));
    assert!((s.theta[0] - 3.0).abs() < 1e-12 && (s.theta[1] - 2.0).abs() < 1e-12);
    assert!(s.rms_residual < 1e-6);
}

#[test]
fn json_report_has_exactly_the_documented_keys() {
    let arm = crate::arms::find("planar2").unwrap();
    let settings = Settings {
        target: Duration::from_micros(200),
        reps: 1,
        warm_up: Duration::ZERO,
    };
    let (report, _) = run(&[arm], &settings, 2_000, |_| {}).unwrap();
    let v = serde_json::to_value(&report).unwrap();
    let keys = |o: &serde_json::Value| {
        let mut k: Vec<String> = o.as_object().unwrap().keys().cloned().collect();
        k.sort();
        k
    };
    assert_eq!(keys(&v), ["identify", "kernels"]);
    let kernels = v["kernels"].as_array().unwrap();
    assert_eq!(kernels.len(), Kernel::ALL.len());
    for (k, kernel) in kernels.iter().zip(Kernel::ALL) {
        assert_eq!(keys(k), ["arm", "generated_ns", "kernel", "reference_ns"]);
        assert_eq!(k["kernel"], kernel.name());
        assert!(k["generated_ns"].as_f64().unwrap() > 0.0);
    }
    assert_eq!(
        keys(&v["identify"]),
        ["arm", "peak_rss_mb", "samples", "seconds"]
    );
    assert_eq!(v["identify"]["arm"], "puma560");
    assert_eq!(v["identify"]["samples"], 2_000);
}

#[test]
fn peak_rss_is_reported_on_linux() {
    if std::path::Path::new("/proc/self/status").exists() {
        assert!(peak_rss_mb() > 0.0);
    }
}

/// The lane check the bench runs before timing says no when a lane holds another sample's
/// output, and yes for the kernels as they are, in both widths.
#[test]
fn the_lane_check_catches_a_lane_from_another_sample() {
    let arm = crate::arms::find("planar2").expect("planar2");
    let case = Case::new(arm);
    for kernel in Kernel::ALL {
        assert!(
            case.lanes_match(kernel) && case.lanes8_match(kernel),
            "{kernel:?}"
        );
        let shifted = case.every_lane_matches(kernel, 4, |c, l, got| {
            case.call_generated(kernel, c * 4 + (l + 1) % 4, got);
        });
        assert!(!shifted, "{kernel:?}: a shifted lane passed");
    }
}

/// The skip-zeros lane check says yes for the kernels as they are, in both widths, and no when an
/// output the scalar kernel gives as non-zero is left unwritten.
#[test]
fn the_skip_zeros_check_catches_an_unwritten_non_zero_output() {
    let arm = crate::arms::find("puma560").expect("puma560");
    let case = Case::new(arm);
    for kernel in Kernel::ALL {
        assert!(
            case.lanes_skip_zeros_match(kernel) && case.lanes8_skip_zeros_match(kernel),
            "{kernel:?}"
        );
        let left = case.every_lane_matches_skipping_zeros(kernel, 4, |c, l, got| {
            case.call_generated(kernel, c * 4 + l, got);
            if let Some(g) = got.iter_mut().find(|g| **g != 0.0) {
                *g = UNWRITTEN;
            }
        });
        assert!(!left, "{kernel:?}: an unwritten non-zero output passed");
    }
}
