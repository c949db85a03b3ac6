//! Criterion benchmarks of the generated kernels (`cargo bench`).
//!
//! - `kernels/<arm>/<kernel>/{generated,reference}`: every kernel of every arm in
//!   `dynid::arms::all()` against the hand-written reference on the same inputs. Inputs follow the
//!   Pinocchio harness (`benches/peers/pinocchio/`): a pool of 1024 random samples
//!   (q ~ U(−π, π), q̇ ~ U(−2, 2), q̈ ~ U(−5, 5)), call i uses sample i mod 1024, inputs through
//!   `black_box`, one call per iteration through the `Model` trait (`&dyn Model`, as the CLI uses
//!   it).
//! - `static/puma560/*`: the PUMA kernels called directly (fixed-size arrays, no dynamic dispatch),
//!   to show what the trait call costs.
//! - `trig/*`: `(sin, cos)` of six joint angles: std, `trig::sin_cos` per joint, `trig::sin_cos_n`.
//! - `batch/puma560_base_regressor_1e6`: base-regressor rows per second over 1e6 samples, one
//!   thread and rayon on two threads.
//! - `identify/puma560_1e6`: streaming identification of a generated 1,000,000-sample log.
//!
//! Measurement times are short (the whole run takes a few minutes); `dynid bench` is the quick
//! in-process version and `scripts/bench_table.sh` the README table with Pinocchio.

use std::hint::black_box;
use std::time::Duration;

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use dynid::arms::puma560;
use dynid::bench::{
    identify_streaming, plausible_params, Case, Kernel, Reference, SamplePool, POOL,
};
use rayon::prelude::*;

fn kernels(c: &mut Criterion) {
    for &arm in dynid::arms::all() {
        let case = Case::new(arm);
        let mut reference = Reference::new(arm).expect("built-in table parses");
        for kernel in Kernel::ALL {
            assert!(
                case.check(&mut reference, kernel) < 1e-9,
                "{} {kernel:?} disagrees with the reference",
                arm.name()
            );
            let mut g = c.benchmark_group(format!("kernels/{}/{}", arm.name(), kernel.name()));
            let mut out = vec![0.0; case.out_len(kernel)];
            g.bench_function("generated", |b| {
                let mut i = 0usize;
                b.iter(|| {
                    case.call_generated(kernel, i, &mut out);
                    i = i.wrapping_add(1);
                    black_box(&mut out);
                })
            });
            g.bench_function("reference", |b| {
                let mut i = 0usize;
                b.iter(|| {
                    case.call_reference(&mut reference, kernel, i, &mut out);
                    i = i.wrapping_add(1);
                    black_box(&mut out);
                })
            });
            g.finish();
        }
    }
}

type Sample = ([f64; 6], [f64; 6], [f64; 6]);

fn puma_pool() -> Vec<Sample> {
    let pool = SamplePool::new(6, 42);
    let arr = |s: &[f64]| -> [f64; 6] { s.try_into().expect("6 joints") };
    (0..POOL)
        .map(|k| (arr(pool.q(k)), arr(pool.dq(k)), arr(pool.ddq(k))))
        .collect()
}

fn puma_theta() -> [f64; puma560::NB] {
    let p: [f64; puma560::NP] = plausible_params(6, 7).try_into().expect("60 parameters");
    let mut theta = [0.0; puma560::NB];
    puma560::base_params(&p, &mut theta);
    theta
}

fn static_dispatch(c: &mut Criterion) {
    let pool = puma_pool();
    let theta = puma_theta();
    let mut g = c.benchmark_group("static/puma560");
    macro_rules! bench {
        ($name:literal, $n:expr, |$q:ident, $dq:ident, $ddq:ident, $out:ident| $call:expr) => {
            g.bench_function($name, |b| {
                let mut $out = [0.0; $n];
                let mut i = 0usize;
                b.iter(|| {
                    let ($q, $dq, $ddq) = black_box(&pool[i & (POOL - 1)]);
                    let _ = ($q, $dq, $ddq);
                    $call;
                    i = i.wrapping_add(1);
                    black_box(&mut $out);
                })
            });
        };
    }
    bench!("regressor", 6 * puma560::NP, |q, dq, ddq, out| {
        puma560::regressor(q, dq, ddq, &mut out)
    });
    bench!("base_regressor", 6 * puma560::NB, |q, dq, ddq, out| {
        puma560::base_regressor(q, dq, ddq, &mut out)
    });
    bench!("mass_matrix", 36, |q, dq, ddq, out| puma560::mass_matrix(
        q, &theta, &mut out
    ));
    bench!("bias", 6, |q, dq, ddq, out| puma560::bias(
        q, dq, &theta, &mut out
    ));
    bench!("gravity", 6, |q, dq, ddq, out| puma560::gravity(
        q, &theta, &mut out
    ));
    bench!("inverse_dynamics", 6, |q, dq, ddq, out| {
        puma560::inverse_dynamics(q, dq, ddq, &theta, &mut out)
    });
    g.finish();
}

fn trig(c: &mut Criterion) {
    let pool = puma_pool();
    let mut g = c.benchmark_group("trig/six_joints");
    g.bench_function("std_sin_cos", |b| {
        let mut i = 0usize;
        b.iter(|| {
            let q = &black_box(&pool[i & (POOL - 1)]).0;
            i = i.wrapping_add(1);
            black_box(q.map(f64::sin_cos))
        })
    });
    g.bench_function("trig_sin_cos", |b| {
        let mut i = 0usize;
        b.iter(|| {
            let q = &black_box(&pool[i & (POOL - 1)]).0;
            i = i.wrapping_add(1);
            black_box(q.map(dynid::trig::sin_cos))
        })
    });
    g.bench_function("trig_sin_cos_n", |b| {
        let mut i = 0usize;
        b.iter(|| {
            let q = &black_box(&pool[i & (POOL - 1)]).0;
            i = i.wrapping_add(1);
            black_box(dynid::trig::sin_cos_n(q))
        })
    });
    g.finish();
}

const BATCH: usize = 1_000_000;

/// Base-regressor rows per second over 1e6 samples (cycling through the pool); each thread
/// writes into its own 64-sample block, as a least-squares consumer would.
fn batch(c: &mut Criterion) {
    let pool = puma_pool();
    let mut g = c.benchmark_group("batch/puma560_base_regressor_1e6");
    g.throughput(Throughput::Elements((BATCH * 6) as u64));
    g.sample_size(10);
    let block = || vec![[0.0; 6 * puma560::NB]; 64];
    g.bench_function(BenchmarkId::new("threads", 1), |b| {
        let mut buf = block();
        b.iter(|| {
            for i in 0..BATCH {
                let (q, dq, ddq) = black_box(&pool[i & (POOL - 1)]);
                puma560::base_regressor(q, dq, ddq, &mut buf[i & 63]);
            }
            black_box(&mut buf);
        })
    });
    let threads = 2;
    let tp = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .expect("rayon pool");
    g.bench_function(BenchmarkId::new("threads", threads), |b| {
        b.iter(|| {
            tp.install(|| {
                (0..BATCH)
                    .into_par_iter()
                    .with_min_len(1 << 14)
                    .for_each_init(block, |buf, i| {
                        let (q, dq, ddq) = black_box(&pool[i & (POOL - 1)]);
                        puma560::base_regressor(q, dq, ddq, &mut buf[i & 63]);
                        black_box(&mut buf[i & 63]);
                    })
            })
        })
    });
    g.finish();
}

/// SIMD across samples: the lane-batched PUMA kernels (`dynid::pack`, 4 samples per call), time
/// per *sample* (criterion's throughput) on the same pool, against the scalar kernels called
/// directly.
fn lanes(c: &mut Criterion) {
    use dynid::pack::{gather, Pack, LANES};
    let pool = puma_pool();
    let theta = puma_theta();
    let packed: Vec<[[Pack; 6]; 3]> = pool
        .chunks_exact(LANES)
        .map(|s| {
            let mut out = [[Pack::default(); 6]; 3];
            gather([&s[0].0, &s[1].0, &s[2].0, &s[3].0], &mut out[0]);
            gather([&s[0].1, &s[1].1, &s[2].1, &s[3].1], &mut out[1]);
            gather([&s[0].2, &s[1].2, &s[2].2, &s[3].2], &mut out[2]);
            out
        })
        .collect();
    let theta_packed = theta.map(Pack::splat);

    let mut g = c.benchmark_group("lanes/puma560/base_regressor");
    g.throughput(Throughput::Elements(1));
    g.bench_function("scalar", |b| {
        let mut out = [0.0; 6 * puma560::NB];
        let mut i = 0usize;
        b.iter(|| {
            let (q, dq, ddq) = black_box(&pool[i & (POOL - 1)]);
            puma560::base_regressor(q, dq, ddq, &mut out);
            i = i.wrapping_add(1);
            black_box(&mut out);
        })
    });
    g.throughput(Throughput::Elements(LANES as u64));
    g.bench_function("lanes", |b| {
        let mut out = [Pack::default(); 6 * puma560::NB];
        let mut i = 0usize;
        b.iter(|| {
            let [q, dq, ddq] = black_box(&packed[i % packed.len()]);
            puma560::base_regressor_lanes::<_, true>(q, dq, ddq, &mut out);
            i = i.wrapping_add(1);
            black_box(&mut out);
        })
    });
    g.finish();

    let mut g = c.benchmark_group("lanes/puma560/inverse_dynamics");
    g.throughput(Throughput::Elements(1));
    g.bench_function("scalar", |b| {
        let mut out = [0.0; 6];
        let mut i = 0usize;
        b.iter(|| {
            let (q, dq, ddq) = black_box(&pool[i & (POOL - 1)]);
            puma560::inverse_dynamics(q, dq, ddq, &theta, &mut out);
            i = i.wrapping_add(1);
            black_box(&mut out);
        })
    });
    g.throughput(Throughput::Elements(LANES as u64));
    g.bench_function("lanes", |b| {
        let mut out = [Pack::default(); 6];
        let mut i = 0usize;
        b.iter(|| {
            let [q, dq, ddq] = black_box(&packed[i % packed.len()]);
            puma560::inverse_dynamics_lanes::<_, true>(q, dq, ddq, &theta_packed, &mut out);
            i = i.wrapping_add(1);
            black_box(&mut out);
        })
    });
    g.finish();
}

fn identify(c: &mut Criterion) {
    let arm = dynid::arms::find("puma560").expect("puma560 is built in");
    let mut g = c.benchmark_group("identify");
    g.sample_size(10);
    g.throughput(Throughput::Elements(BATCH as u64));
    g.bench_function("puma560_1e6", |b| {
        b.iter(|| identify_streaming(arm, BATCH, 0.05).expect("well-conditioned excitation"))
    });
    g.finish();
}

fn config() -> Criterion {
    Criterion::default()
        .warm_up_time(Duration::from_millis(300))
        .measurement_time(Duration::from_millis(1000))
        .sample_size(30)
}

criterion_group! { name = benches; config = config(); targets = kernels, static_dispatch, trig, batch, lanes, identify }
criterion_main!(benches);
