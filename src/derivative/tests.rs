use std::f64::consts::PI;

use super::*;
use crate::signal::sines;

#[test]
fn butterworth_derivatives_match_analytic_ones() {
    let fs = 500.0;
    let n = 10_000;
    let t: Vec<f64> = (0..n).map(|k| k as f64 / fs).collect();
    // Quantise like a 2^17-count encoder: the noise the estimator must reject.
    let res = 2.0 * PI / 131072.0;
    let q: Vec<f64> = t
        .iter()
        .map(|&t| (sines(t).0 / res).round() * res)
        .collect();
    let est = estimate(&t, &[q], None, &Options::default()).unwrap();
    let fc = est.report.cutoff_hz;
    assert!(fc > 1.5 && fc < 20.0, "auto cut-off {fc}");
    let (mut e1, mut e2) = (0.0f64, 0.0f64);
    #[allow(clippy::needless_range_loop)]
    for k in n / 10..9 * n / 10 {
        let (_, dq, ddq) = sines(t[k]);
        e1 = e1.max((est.dq[0][k] - dq).abs());
        e2 = e2.max((est.ddq[0][k] - ddq).abs());
    }
    // |dq| ≤ 4.5 rad/s, |ddq| ≤ 25 rad/s²: errors well below 1 %.
    assert!(e1 < 0.01 && e2 < 0.15, "dq err {e1}, ddq err {e2}, fc {fc}");
}

#[test]
fn savgol_derivatives_match_analytic_ones_and_are_exact_on_cubics() {
    let dt = 0.01;
    let sg = SavGol::new(6, 3, dt);
    let x: Vec<f64> = (0..100)
        .map(|k| {
            let t = k as f64 * dt;
            1.0 + 2.0 * t - 3.0 * t * t + 0.5 * t * t * t
        })
        .collect();
    let [s, d1, d2] = sg.derivatives(&x);
    for k in 0..100 {
        let t = k as f64 * dt;
        assert!((s[k] - x[k]).abs() < 1e-9);
        assert!((d1[k] - (2.0 - 6.0 * t + 1.5 * t * t)).abs() < 1e-7, "{k}");
        assert!((d2[k] - (-6.0 + 3.0 * t)).abs() < 1e-5, "{k}");
    }
    let fs = 500.0;
    let t: Vec<f64> = (0..5000).map(|k| k as f64 / fs).collect();
    let q: Vec<f64> = t.iter().map(|&t| sines(t).0).collect();
    let est = estimate(
        &t,
        &[q],
        None,
        &Options {
            method: Method::SavitzkyGolay,
            cutoff_hz: Some(10.0),
        },
    )
    .unwrap();
    let sg = match &est.filter {
        Filter::SavGol(s) => s.clone(),
        Filter::Butterworth(_) => unreachable!(),
    };
    assert!((sg.gain(10.0) - 0.5).abs() < 0.05);
    #[allow(clippy::needless_range_loop)]
    for k in 200..4800 {
        let (_, dq, ddq) = sines(t[k]);
        assert!(
            (est.dq[0][k] - dq).abs() < 2e-3 && (est.ddq[0][k] - ddq).abs() < 0.05,
            "{k}"
        );
    }
}

#[test]
fn uneven_sampling_is_resampled_and_reported() {
    let mut t = Vec::new();
    let mut tk = 0.0;
    for k in 0..6000 {
        t.push(tk);
        tk += if k % 97 == 0 { 0.0035 } else { 0.002 } + 1e-5 * ((k * 31) % 7) as f64;
    }
    let q: Vec<f64> = t.iter().map(|&t| sines(t).0).collect();
    let est = estimate(
        &t,
        &[q],
        None,
        &Options {
            cutoff_hz: Some(8.0),
            ..Default::default()
        },
    )
    .unwrap();
    assert!(est.report.resampled && !est.report.sampling.uniform);
    assert!(est.report.sampling.dt_max > 0.0035);
    for &tk in &t[600..5400] {
        let (q, dq, ddq) = est.at(0, tk);
        let (qe, dqe, ddqe) = sines(tk);
        assert!(
            (q - qe).abs() < 5e-5 && (dq - dqe).abs() < 1e-3 && (ddq - ddqe).abs() < 0.02,
            "t={tk}"
        );
    }
}

/// Windows with the filter's reach of margin reproduce the whole-signal estimate (the claim
/// that lets identification never hold a long log's states): uneven times, two joints, with
/// and without a q̇ column, both filters; windows cut anywhere, including at the ends.
#[test]
fn windows_equal_the_whole_signal_estimate() {
    let mut t = Vec::new();
    let mut tk = 0.0;
    for k in 0..9000 {
        t.push(tk);
        tk += if k % 89 == 0 { 0.003 } else { 0.002 } + 1e-5 * ((k * 13) % 5) as f64;
    }
    let rows = |f: fn((f64, f64, f64)) -> f64| -> Vec<f64> {
        t.iter()
            .flat_map(|&tk| [f(sines(tk)), 0.5 * f(sines(1.3 * tk + 0.2))])
            .collect()
    };
    let (q, dq) = (rows(|s| s.0), rows(|s| s.1));
    let mut worst = 0.0f64;
    for method in [Method::Butterworth, Method::SavitzkyGolay] {
        for with_dq in [false, true] {
            let log = Log::from(Trajectory {
                source: String::new(),
                dof: 2,
                t: t.clone(),
                q: q.clone(),
                dq: with_dq.then(|| dq.clone()),
                ddq: None,
                tau: None,
            });
            let opts = Options {
                method,
                cutoff_hz: Some(6.0),
            };
            let e = Estimator::new(&log, true, &opts).unwrap();
            let n = e.grid.n;
            let whole = e.window(&log, 0, n);
            // Another cut-off's estimator re-filtered at this one is this one, bit for bit.
            let three = Options {
                cutoff_hz: Some(3.0),
                ..opts
            };
            let again = Estimator::new(&log, true, &three)
                .unwrap()
                .with_cutoff(method, 6.0)
                .unwrap();
            assert_eq!(again.report, e.report);
            let (a, b) = (again.window(&log, 1234, 4321), e.window(&log, 1234, 4321));
            assert!(a.q == b.q && a.dq == b.dq && a.ddq == b.ddq);
            for (lo, hi) in [(0, 700), (1234, 4321), (4000, n), (n - 1, n)] {
                let w = e.window(&log, lo, hi);
                assert_eq!((w.lo, w.q[1].len()), (lo, hi - lo));
                let pairs = [(&w.q, &whole.q), (&w.dq, &whole.dq), (&w.ddq, &whole.ddq)];
                for (c, (a, b)) in pairs.into_iter().enumerate() {
                    for j in 0..2 {
                        let scale = b[j].iter().fold(0.0f64, |m, v| m.max(v.abs()));
                        let d = (lo..hi)
                            .map(|k| (a[j][k - lo] - b[j][k]).abs())
                            .fold(0.0, f64::max);
                        assert!(
                            d <= 1e-6 * scale,
                            "{method:?} dq {with_dq} [{lo},{hi}) j{j} channel {c}: {d} of {scale}"
                        );
                        worst = worst.max(d / scale);
                    }
                }
            }
        }
    }
    println!("largest window/whole difference: {worst:.1e} of the channel's range");
}

#[test]
fn bad_times_are_rejected_with_the_row() {
    let t: Vec<f64> = (0..100)
        .map(|k| if k == 40 { 0.39 } else { k as f64 * 0.01 })
        .collect();
    let q = vec![vec![0.0; 100]];
    assert_eq!(
        estimate(&t, &q, None, &Options::default()).unwrap_err(),
        DerivativeError::NotIncreasing {
            row: 40,
            t: 0.39,
            prev: 0.39
        }
    );
    assert!(matches!(
        estimate(&t[..10], &q, None, &Options::default()),
        Err(DerivativeError::TooFewSamples { n: 10, .. })
    ));
}
