//! The Rust side of `python/bench.py`: the batch driver the bindings call (`src/batch.rs`,
//! compiled here on its own, without Python), timed on the jobs the Python calls do.
//!
//! Modes:
//! - `fresh`: `N` samples into a newly allocated `N × len` output each time (`vec![0.0; ..]`,
//!   calloc'd pages, first touched by the kernels), as `Arm.<kernel>(Q, DQ, DDQ)` does;
//! - `reuse`: into one preallocated, already touched output, as `Arm.<kernel>(..., out=Y)` does;
//! - `kernel`: the lane-batched kernels alone: the `N` samples in chunks whose output stays in
//!   the cache (`dynid bench`'s lanes column, with the gather and scatter of the driver).
//!
//! ```sh
//! cargo run --profile python -p dynid-python --example batch_throughput -- puma560 base_regressor 100000 7 1 fresh
//! ```
//! Arguments: arm, kernel, samples, repetitions, threads (1 = this thread, 0 = all cores), mode.
//! Prints one JSON object: the median and every repetition in ns per sample (one warm-up first).

#[path = "../src/batch.rs"]
#[allow(dead_code)]
mod batch;

use std::time::Instant;

use dynid::model::Kernel;

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let get = |i: usize, default: &str| args.get(i).cloned().unwrap_or_else(|| default.to_string());
    let arm_name = get(0, "puma560");
    let kernel_name = get(1, "base_regressor");
    let samples: usize = get(2, "100000").parse().expect("samples: a whole number");
    let reps: usize = get(3, "7").parse().expect("repetitions: a whole number");
    let threads: usize = get(4, "1").parse().expect("threads: a whole number");
    let mode = get(5, "fresh");
    if !["fresh", "reuse", "kernel"].contains(&mode.as_str()) {
        eprintln!("error: mode `{mode}` — use fresh, reuse or kernel");
        std::process::exit(2);
    }
    let Some(arm) = dynid::arms::find(&arm_name) else {
        eprintln!(
            "error: unknown arm `{arm_name}` — known: {}",
            dynid::arms::names().join(", ")
        );
        std::process::exit(2);
    };
    let Some(kernel) = Kernel::ALL.into_iter().find(|k| k.name() == kernel_name) else {
        eprintln!("error: unknown kernel `{kernel_name}`");
        std::process::exit(2);
    };
    let d = batch::Dynamics::Generated(arm);
    let n = arm.dof();
    // q ~ U(−π, π), q̇ ~ U(−2, 2), q̈ ~ U(−5, 5), as python/bench.py draws them (xorshift).
    let mut state: u64 = 0x9E37_79B9_7F4A_7C15;
    let mut uniform = |lo: f64, hi: f64| {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        lo + (hi - lo) * ((state >> 11) as f64 / (1u64 << 53) as f64)
    };
    let pi = std::f64::consts::PI;
    let q: Vec<f64> = (0..samples * n).map(|_| uniform(-pi, pi)).collect();
    let dq: Vec<f64> = (0..samples * n).map(|_| uniform(-2.0, 2.0)).collect();
    let ddq: Vec<f64> = (0..samples * n).map(|_| uniform(-5.0, 5.0)).collect();
    let p: Vec<f64> = (0..d.np()).map(|_| uniform(0.1, 1.0)).collect();
    let x = batch::States {
        samples,
        q: &q,
        dq: &dq,
        ddq: &ddq,
    };
    let len = d.out_len(kernel);
    let mut ns = Vec::with_capacity(reps);
    let mut checksum = 0.0;
    let mut kept = vec![0.0; samples * len];
    let mut chunk = vec![0.0; batch::CHUNK * len];
    for rep in 0..=reps {
        let t0 = Instant::now();
        match mode.as_str() {
            "fresh" => {
                let mut out = vec![0.0; samples * len];
                d.run(kernel, &x, &p, &mut out, threads, true);
                checksum += std::hint::black_box(&out)[samples * len / 2];
            }
            "reuse" => {
                d.run(kernel, &x, &p, &mut kept, threads, false);
                checksum += std::hint::black_box(&kept)[samples * len / 2];
            }
            _ => {
                for s0 in (0..samples).step_by(batch::CHUNK) {
                    let m = batch::CHUNK.min(samples - s0);
                    let part = batch::States {
                        samples: m,
                        q: &q[s0 * n..(s0 + m) * n],
                        dq: &dq[s0 * n..(s0 + m) * n],
                        ddq: &ddq[s0 * n..(s0 + m) * n],
                    };
                    d.run(kernel, &part, &p, &mut chunk[..m * len], 1, false);
                    checksum += std::hint::black_box(&chunk)[0];
                }
            }
        }
        let dt = t0.elapsed().as_secs_f64();
        if rep > 0 {
            ns.push(dt * 1e9 / samples as f64);
        }
    }
    let mut sorted = ns.clone();
    sorted.sort_by(f64::total_cmp);
    let median = sorted[sorted.len() / 2];
    let runs: Vec<String> = ns.iter().map(|v| format!("{v:.3}")).collect();
    println!(
        "{{\"arm\": \"{arm_name}\", \"kernel\": \"{kernel_name}\", \"mode\": \"{mode}\", \"samples\": {samples}, \"threads\": {threads}, \"median_ns_per_sample\": {median:.3}, \"runs_ns_per_sample\": [{}], \"checksum\": {checksum:e}}}",
        runs.join(", ")
    );
}
