//! Quick in-process throughput measurement behind `dynid bench`: every generated kernel against
//! the hand-written [`reference`](crate::reference) dynamics on the same inputs, and a streaming
//! identification of a 1,000,000-sample PUMA 560 log.
//!
//! Method (the same as the Pinocchio harness in `benches/peers/pinocchio/`, so numbers can sit
//! side by side): a pool of [`POOL`] random samples, `q ~ U(−π, π)`, `q̇ ~ U(−2, 2)`,
//! `q̈ ~ U(−5, 5)`; call `i` uses sample `i mod 1024`; one repetition is `N` consecutive calls
//! with `N` calibrated to last [`Settings::target`] and rounded to whole passes over the pool; one
//! warm-up repetition, then [`Settings::reps`] timed ones; the median of elapsed/N is reported in
//! ns per call, single thread. The kernel is chosen once per timing loop and called through the
//! `Model` trait (an opaque call per sample, as a user's loop makes it); the reference's inputs
//! go through [`std::hint::black_box`] so nothing is hoisted or folded. `cargo bench`
//! (criterion, `benches/kernels.rs`) is the careful measurement; this is the quick one (a few
//! seconds plus about one for the identification). Each kernel is also timed
//! lane-batched ([`crate::pack`]: `LANES` samples per call from the same pool), reported per
//! sample.
//!
//! ```no_run
//! let settings = dynid::bench::Settings::quick();
//! let arm = dynid::arms::find("puma560").unwrap();
//! for t in dynid::bench::measure_arm(arm, &settings).unwrap() {
//!     println!("{} {}: {:.1} ns vs {:.1} ns", t.arm, t.kernel, t.generated_ns, t.reference_ns);
//! }
//! ```

use std::hint::black_box;
use std::time::{Duration, Instant};

use nalgebra::DMatrix;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::Serialize;

use crate::dh::DhTable;
use crate::model::Model;
use crate::pack::wide::{Pack8, WIDE_LANES};
use crate::pack::{gather, Pack, LANES};
use crate::reference::{RefModel, Workspace};

mod normal_equations;
mod streaming;
pub mod table;
#[cfg(test)]
mod tests;

pub use normal_equations::{NormalEquations, Solution};
pub use streaming::{identify_streaming, BenchExcitation, IdentifyRun};

/// Number of samples in the input pool (a power of two: call `i` uses sample `i & (POOL − 1)`).
pub const POOL: usize = 1024;

/// The kernel kinds (the generator's list; see [`crate::model::Kernel`]).
pub use crate::model::Kernel;

/// Samples in the streaming identification run of `dynid bench`.
pub const IDENTIFY_SAMPLES: usize = 1_000_000;

/// How long to measure.
#[derive(Debug, Clone, Copy)]
pub struct Settings {
    /// Wall time of one repetition.
    pub target: Duration,
    /// Timed repetitions (the median is reported).
    pub reps: usize,
    /// Busy time before the first measurement, so that it does not pay for the CPU leaving its
    /// idle clock (seen as a 1.7× slower first kernel without it).
    pub warm_up: Duration,
}

impl Settings {
    /// About 0.1 s per (kernel, implementation): the whole `dynid bench` takes a few seconds.
    pub fn quick() -> Self {
        Settings {
            target: Duration::from_millis(10),
            reps: 7,
            warm_up: Duration::from_millis(300),
        }
    }
}

/// One line of the kernel table.
#[derive(Debug, Clone, Serialize)]
pub struct KernelTiming {
    pub arm: String,
    pub kernel: &'static str,
    /// Generated kernel, ns per call (median).
    pub generated_ns: f64,
    /// Hand-written reference on the same inputs, ns per call (median).
    pub reference_ns: f64,
    /// The lane-batched generated kernel ([`crate::pack`], `LANES` samples per call) on the
    /// same pool, ns per *sample* (median). Not in `--json`, whose keys are fixed by issue 7;
    /// in the human and markdown tables.
    #[serde(skip)]
    pub lanes_ns: f64,
    /// The eight-lane generated kernel ([`crate::pack::wide`]: AVX-512 where the CPU has it)
    /// on the same pool, ns per *sample* (median). Not in `--json`, like `lanes_ns`.
    #[serde(skip)]
    pub lanes8_ns: f64,
    /// `lanes_ns` of the form that leaves the constant-zero outputs to the buffer
    /// (`call_lanes_skip_zeros`). Not in `--json`.
    #[serde(skip)]
    pub lanes_skip_ns: f64,
    /// `lanes8_ns` of the form that leaves the constant-zero outputs to the buffer
    /// (`call_lanes8_skip_zeros`). Not in `--json`.
    #[serde(skip)]
    pub lanes8_skip_ns: f64,
}

/// The streaming identification run.
#[derive(Debug, Clone, Serialize)]
pub struct IdentifyTiming {
    pub arm: String,
    pub samples: usize,
    /// Wall time: trajectory, inverse dynamics, base regressor, normal equations and solve.
    pub seconds: f64,
    /// Peak resident set size of the process (`VmHWM`), MB.
    pub peak_rss_mb: f64,
}

/// What `dynid bench --json` prints.
#[derive(Debug, Clone, Serialize)]
pub struct Report {
    pub kernels: Vec<KernelTiming>,
    pub identify: IdentifyTiming,
}

/// The bench found generated and reference kernels disagreeing, or a degenerate identification.
#[derive(Debug, thiserror::Error)]
pub enum BenchError {
    #[error("{arm}: generated `{kernel}` differs from the reference dynamics by {err:.3e} (relative) — the generated kernels are stale or wrong; run `cargo build` to regenerate and `cargo test`")]
    Mismatch {
        arm: String,
        kernel: &'static str,
        err: f64,
    },
    #[error("{arm}: a lane of the {lanes}-lane `{kernel}` differs from the scalar kernel — a bug in the lane copy (macros/src/lanes.rs) or in crate::pack")]
    LanesMismatch {
        arm: String,
        kernel: &'static str,
        lanes: usize,
    },
    #[error("{arm}: the built-in D-H table does not parse: {msg}")]
    Table { arm: String, msg: String },
    #[error("identification: the information matrix is singular or ill-conditioned (cond(Yb) = {cond:.3e}) — the excitation does not identify all base parameters")]
    IllConditioned { cond: f64 },
    #[error("arm `{0}` is not built in")]
    MissingArm(&'static str),
}

/// What the skip-zeros checks fill the output with before a call: a NaN no kernel computes
/// (its payload is not the default NaN's).
const UNWRITTEN: f64 = f64::from_bits(0x7ff8_dead_beef_0001);

/// Sample `k mod POOL` of a pool column of `POOL · dof` values, without bounds checks, as the C
/// harnesses index with bare pointers: the timing loops take three samples per call, and their
/// checks (six branches) are charged to the kernel — about 1.5 % of a 2-DOF kernel's time
/// (planar2 mass matrix 6.01 against 5.92 ns).
#[inline(always)]
fn sample(column: &[f64], k: usize, dof: usize) -> &[f64] {
    let start = (k & (POOL - 1)) * dof;
    assert!(column.len() == POOL * dof);
    // SAFETY: `start + dof ≤ (POOL − 1)·dof + dof = column.len()`, checked just above (the check
    // is hoisted out of the timing loops, where `column` and `dof` do not change).
    unsafe { column.get_unchecked(start..start + dof) }
}

/// The random input pool of the Pinocchio harness: `POOL` samples of `(q, q̇, q̈)`.
#[derive(Debug, Clone)]
pub struct SamplePool {
    dof: usize,
    q: Vec<f64>,
    dq: Vec<f64>,
    ddq: Vec<f64>,
}

impl SamplePool {
    /// `q ~ U(−π, π)`, `q̇ ~ U(−2, 2)`, `q̈ ~ U(−5, 5)`, deterministic for a seed.
    pub fn new(dof: usize, seed: u64) -> Self {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let pi = std::f64::consts::PI;
        let mut draw = |lo: f64, hi: f64| {
            (0..POOL * dof)
                .map(|_| rng.gen_range(lo..hi))
                .collect::<Vec<f64>>()
        };
        let q = draw(-pi, pi);
        let dq = draw(-2.0, 2.0);
        let ddq = draw(-5.0, 5.0);
        SamplePool { dof, q, dq, ddq }
    }

    /// Degrees of freedom of each sample.
    pub fn dof(&self) -> usize {
        self.dof
    }

    /// Positions of sample `k` (any `k`; taken modulo the pool size).
    #[inline(always)]
    pub fn q(&self, k: usize) -> &[f64] {
        sample(&self.q, k, self.dof)
    }

    /// Velocities of sample `k`.
    #[inline(always)]
    pub fn dq(&self, k: usize) -> &[f64] {
        sample(&self.dq, k, self.dof)
    }

    /// Accelerations of sample `k`.
    #[inline(always)]
    pub fn ddq(&self, k: usize) -> &[f64] {
        sample(&self.ddq, k, self.dof)
    }
}

/// Physically consistent random inertial parameters (`10·dof`, Khalil/Gautier order about the
/// link-frame origin): mass in [1, 5] kg, centre of mass within 0.15 m, principal inertias about
/// the centre of mass in [0.01, 0.1] kg·m² satisfying the triangle inequality.
pub fn plausible_params(dof: usize, seed: u64) -> Vec<f64> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut p = Vec::with_capacity(10 * dof);
    for _ in 0..dof {
        let m: f64 = rng.gen_range(1.0..5.0);
        let c: [f64; 3] = std::array::from_fn(|_| rng.gen_range(-0.15..0.15));
        let d: [f64; 3] = std::array::from_fn(|_| rng.gen_range(0.01..0.1));
        let (ixx, iyy) = (d[0] + d[1], d[1] + d[2]);
        let izz = d[0] + d[2]; // pairwise sums of positives: the triangle inequality holds
        let c2 = c[0] * c[0] + c[1] * c[1] + c[2] * c[2];
        // Parallel axis: I_o = I_c + m(|c|²·1 − c·cᵀ).
        p.extend_from_slice(&[
            ixx + m * (c2 - c[0] * c[0]),
            -m * c[0] * c[1],
            -m * c[0] * c[2],
            iyy + m * (c2 - c[1] * c[1]),
            -m * c[1] * c[2],
            izz + m * (c2 - c[2] * c[2]),
            m * c[0],
            m * c[1],
            m * c[2],
            m,
        ]);
    }
    p
}

/// Times one generated kernel, single call and lane-batched (ns per call, ns per sample), with
/// the kernel chosen once, outside the timing loops ([`Kernel::with`](crate::model::Kernel::with)):
/// each call is then one call through the `Model` trait on the pool sample's slices, as a user's
/// loop would make it — and as SymPyBotics' harness calls its C through a function pointer.
struct TimeGenerated<'a> {
    case: &'a Case,
    settings: &'a Settings,
}

/// A lane form's call through [`crate::model::KernelCall`] (`model, q, q̇, q̈, θ, out`).
type LaneCall<T> = fn(&dyn Model, &[T], &[T], &[T], &[T], &mut [T]);

/// [`TimeGenerated`]'s times: ns per call (`single`), else ns per sample.
struct GeneratedTimes {
    single: f64,
    lanes: f64,
    lanes8: f64,
    lanes_skip: f64,
    lanes8_skip: f64,
}

impl crate::model::KernelVisitor for TimeGenerated<'_> {
    type Output = GeneratedTimes;

    fn visit<K: crate::model::KernelCall>(self) -> GeneratedTimes {
        let case = self.case;
        let len = case.out_len(K::KERNEL);
        // The arm through `black_box`: its calls stay calls through the trait.
        let (arm, pool, theta) = (black_box(case.arm), &case.pool, &case.theta[..]);
        let mut buf = vec![0.0; len];
        let single = time_per_call(self.settings, |i| {
            K::call(arm, pool.q(i), pool.dq(i), pool.ddq(i), theta, &mut buf);
            black_box(&mut buf);
        });
        // Each lane form into a buffer zeroed once (as the skip-zeros forms require).
        let mut packs = vec![Pack::default(); len];
        let theta = &case.theta_packed[..];
        let mut time_lanes = |call: LaneCall<Pack>| {
            time_per_call(self.settings, |c| {
                let [q, dq, ddq] = case.packs(c);
                call(arm, q, dq, ddq, theta, &mut packs);
                black_box(&mut packs);
            }) / LANES as f64
        };
        let lanes = time_lanes(K::call_lanes);
        let lanes_skip = time_lanes(K::call_lanes_skip_zeros);
        let mut packs8 = vec![Pack8::default(); len];
        let theta = &case.theta_packed8[..];
        let mut time_lanes8 = |call: LaneCall<Pack8>| {
            time_per_call(self.settings, |c| {
                let [q, dq, ddq] = case.packs8(c);
                call(arm, q, dq, ddq, theta, &mut packs8);
                black_box(&mut packs8);
            }) / WIDE_LANES as f64
        };
        let lanes8 = time_lanes8(K::call_lanes8);
        let lanes8_skip = time_lanes8(K::call_lanes8_skip_zeros);
        GeneratedTimes {
            single,
            lanes,
            lanes8,
            lanes_skip,
            lanes8_skip,
        }
    }
}

/// Nanoseconds per call of `f(i)` for `i = 0, 1, 2, …` (median over repetitions; see the module
/// docs for the protocol).
pub fn time_per_call(settings: &Settings, mut f: impl FnMut(usize)) -> f64 {
    let mut run = |n: usize| {
        let t0 = Instant::now();
        for i in 0..n {
            f(i);
        }
        t0.elapsed().as_secs_f64()
    };
    let target = settings.target.as_secs_f64();
    let mut n = POOL;
    let mut t = run(n);
    while t < 0.5 * target {
        n *= 2;
        t = run(n);
    }
    let n = ((n as f64 * target / t) as usize).max(POOL).div_ceil(POOL) * POOL;
    run(n); // warm-up
    let mut per: Vec<f64> = (0..settings.reps.max(1))
        .map(|_| run(n) / n as f64 * 1e9)
        .collect();
    per.sort_by(f64::total_cmp);
    let m = per.len();
    if m % 2 == 1 {
        per[m / 2]
    } else {
        0.5 * (per[m / 2 - 1] + per[m / 2])
    }
}

/// The reference dynamics of a generated arm, with the column map that turns its full regressor
/// into the base regressor (`Yb[:, j] = Σ w·Y[:, k]`).
pub struct Reference {
    model: RefModel,
    ws: Workspace,
    base_map: Vec<(usize, usize, f64)>,
    y: Vec<f64>,
}

impl Reference {
    /// Builds the reference for `arm` from the D-H table its kernels were generated from.
    pub fn new(arm: &dyn Model) -> Result<Self, BenchError> {
        let table = DhTable::from_str(arm.arm_toml(), &format!("arms/{}.toml", arm.name()))
            .map_err(|e| BenchError::Table {
                arm: arm.name().to_string(),
                msg: e.to_string(),
            })?;
        let model = RefModel::new(&table);
        let ws = model.workspace();
        Ok(Reference {
            model,
            ws,
            base_map: base_column_map(arm),
            y: vec![0.0; arm.dof() * arm.np()],
        })
    }

    /// Full regressor.
    pub fn regressor(&mut self, q: &[f64], dq: &[f64], ddq: &[f64], out: &mut [f64]) {
        self.model.regressor(&mut self.ws, q, dq, ddq, out);
    }

    /// Base regressor: the full regressor, then the column map.
    pub fn base_regressor(&mut self, q: &[f64], dq: &[f64], ddq: &[f64], out: &mut [f64]) {
        self.model.regressor(&mut self.ws, q, dq, ddq, &mut self.y);
        let (n, np) = (self.model.dof(), self.model.np());
        let nb = out.len() / n;
        out.fill(0.0);
        for &(k, j, w) in &self.base_map {
            for i in 0..n {
                out[i * nb + j] += w * self.y[i * np + k];
            }
        }
    }

    /// Mass matrix for full parameters `p`.
    pub fn mass_matrix(&mut self, q: &[f64], p: &[f64], out: &mut [f64]) {
        self.model.mass_matrix(&mut self.ws, q, p, out);
    }

    /// Coriolis/centrifugal + gravity torques for full parameters `p`.
    pub fn bias(&mut self, q: &[f64], dq: &[f64], p: &[f64], out: &mut [f64]) {
        self.model.bias(&mut self.ws, q, dq, p, out);
    }

    /// Gravity torques for full parameters `p`.
    pub fn gravity(&mut self, q: &[f64], p: &[f64], out: &mut [f64]) {
        self.model.gravity(&mut self.ws, q, p, out);
    }

    /// Inverse dynamics for full parameters `p`.
    pub fn inverse_dynamics(
        &mut self,
        q: &[f64],
        dq: &[f64],
        ddq: &[f64],
        p: &[f64],
        out: &mut [f64],
    ) {
        self.model
            .inverse_dynamics(&mut self.ws, q, dq, ddq, p, out);
    }
}

/// `(k, j, w)` with `Yb[:, j] = Σ w·Y[:, k]`. Since `Y = Yb·B` (`θ = B·p`), a full parameter
/// that appears only in base parameter `j`, with coefficient 1, carries column `j` unchanged
/// (`ZZ1` for `ZZR1`); when some base parameter has no such parameter, `Yb = Y·Bᵀ(B·Bᵀ)⁻¹`.
fn base_column_map(arm: &dyn Model) -> Vec<(usize, usize, f64)> {
    let (np, nb) = (arm.np(), arm.nb());
    let mut b = DMatrix::<f64>::zeros(nb, np);
    let mut e = vec![0.0; np];
    let mut col = vec![0.0; nb];
    for k in 0..np {
        e[k] = 1.0;
        arm.base_params(&e, &mut col);
        e[k] = 0.0;
        b.column_mut(k).copy_from_slice(&col);
    }
    let lead: Vec<Option<usize>> = (0..nb)
        .map(|j| (0..np).find(|&k| b[(j, k)] == 1.0 && (0..nb).all(|i| i == j || b[(i, k)] == 0.0)))
        .collect();
    if lead.iter().all(Option::is_some) {
        return lead
            .into_iter()
            .enumerate()
            .map(|(j, k)| (k.unwrap_or_default(), j, 1.0))
            .collect();
    }
    let bbt = &b * b.transpose();
    let w = match bbt.try_inverse() {
        Some(inv) => b.transpose() * inv,
        None => return Vec::new(),
    };
    let mut map = Vec::new();
    for k in 0..np {
        for j in 0..nb {
            if w[(k, j)].abs() > 1e-14 {
                map.push((k, j, w[(k, j)]));
            }
        }
    }
    map
}

/// One arm's benchmark inputs: the sample pool, full parameters `p` and base parameters `θ`,
/// with the calls of every kernel by name (shared by `dynid bench` and `cargo bench`).
pub struct Case {
    arm: &'static dyn Model,
    pool: SamplePool,
    p: Vec<f64>,
    theta: Vec<f64>,
    /// The pool as packs of `LANES` consecutive samples: `[q, dq, ddq]`, each `dof` packs.
    packed: Vec<[Vec<Pack>; 3]>,
    theta_packed: Vec<Pack>,
    /// The pool as [`Pack8`]s of `WIDE_LANES` consecutive samples (pairs of `packed`).
    packed8: Vec<[Vec<Pack8>; 3]>,
    theta_packed8: Vec<Pack8>,
}

impl Case {
    /// Pool seed 42, parameters [`plausible_params`] with seed 7.
    pub fn new(arm: &'static dyn Model) -> Self {
        let pool = SamplePool::new(arm.dof(), 42);
        let p = plausible_params(arm.dof(), 7);
        let mut theta = vec![0.0; arm.nb()];
        arm.base_params(&p, &mut theta);
        let packed: Vec<[Vec<Pack>; 3]> = (0..POOL / LANES)
            .map(|c| {
                let group = |which: usize| {
                    let mut out = vec![Pack::default(); arm.dof()];
                    let rows: [&[f64]; LANES] = std::array::from_fn(|l| {
                        let k = c * LANES + l;
                        [pool.q(k), pool.dq(k), pool.ddq(k)][which]
                    });
                    gather(rows, &mut out);
                    out
                };
                [group(0), group(1), group(2)]
            })
            .collect();
        let theta_packed = theta.iter().map(|&t| Pack::splat(t)).collect();
        let packed8 = packed
            .chunks_exact(WIDE_LANES / LANES)
            .map(|pair: &[[Vec<Pack>; 3]]| {
                std::array::from_fn(|which| {
                    pair[0][which]
                        .iter()
                        .zip(&pair[1][which])
                        .map(|(&lo, &hi)| Pack8::join(lo, hi))
                        .collect()
                })
            })
            .collect();
        let theta_packed8 = theta.iter().map(|&t| Pack8::splat(t)).collect();
        Case {
            arm,
            pool,
            p,
            theta,
            packed,
            theta_packed,
            packed8,
            theta_packed8,
        }
    }

    /// The arm.
    pub fn arm(&self) -> &'static dyn Model {
        self.arm
    }

    /// The input pool.
    pub fn pool(&self) -> &SamplePool {
        &self.pool
    }

    /// The full inertial parameters the kernels are evaluated with.
    pub fn params(&self) -> &[f64] {
        &self.p
    }

    /// Output length of `kernel`.
    pub fn out_len(&self, kernel: Kernel) -> usize {
        kernel.out_len(self.arm.dof(), self.arm.np(), self.arm.nb())
    }

    /// The generated `kernel` on pool sample `k` (inputs through `black_box`).
    #[inline]
    pub fn call_generated(&self, kernel: Kernel, k: usize, out: &mut [f64]) {
        let s = &self.pool;
        let (q, dq, ddq, th) = (
            black_box(s.q(k)),
            black_box(s.dq(k)),
            black_box(s.ddq(k)),
            &self.theta[..],
        );
        kernel.call(self.arm, q, dq, ddq, th, out);
    }

    /// [`Case::call_generated`] in the straight-line form the lane copies are made of
    /// (`Model::<kernel>_straight`).
    pub fn call_straight(&self, kernel: Kernel, k: usize, out: &mut [f64]) {
        let s = &self.pool;
        kernel.call_straight(self.arm, s.q(k), s.dq(k), s.ddq(k), &self.theta[..], out);
    }

    /// The lane-batched generated `kernel` on pool samples `LANES·c … LANES·c + LANES − 1`
    /// (`c` wraps around the pool; inputs through `black_box`).
    #[inline]
    pub fn call_lanes(&self, kernel: Kernel, c: usize, out: &mut [Pack]) {
        let [q, dq, ddq] = black_box(self.packs(c));
        kernel.call_lanes(self.arm, q, dq, ddq, &self.theta_packed[..], out);
    }

    /// `(q, q̇, q̈)` of pool samples `LANES·c … LANES·c + LANES − 1`, packed (`c` wraps around).
    #[inline]
    fn packs(&self, c: usize) -> &[Vec<Pack>; 3] {
        &self.packed[c % self.packed.len()]
    }

    /// The eight-lane generated `kernel` on pool samples `8c … 8c + 7` (`c` wraps around the
    /// pool; inputs through `black_box`).
    #[inline]
    pub fn call_lanes8(&self, kernel: Kernel, c: usize, out: &mut [Pack8]) {
        let [q, dq, ddq] = black_box(self.packs8(c));
        kernel.call_lanes8(self.arm, q, dq, ddq, &self.theta_packed8[..], out);
    }

    /// `(q, q̇, q̈)` of pool samples `8c … 8c + 7`, packed (`c` wraps around).
    #[inline]
    fn packs8(&self, c: usize) -> &[Vec<Pack8>; 3] {
        &self.packed8[c % self.packed8.len()]
    }

    /// True when every lane of [`Case::call_lanes8`] equals [`Case::call_generated`] on its
    /// sample, bit for bit, over the first few packs (in whichever form
    /// [`crate::pack::wide::avx512`] chose).
    pub fn lanes8_match(&self, kernel: Kernel) -> bool {
        let mut packed = vec![Pack8::default(); self.out_len(kernel)];
        self.every_lane_matches(kernel, WIDE_LANES, |c, l, got| {
            if l == 0 {
                self.call_lanes8(kernel, c, &mut packed);
            }
            for (g, p) in got.iter_mut().zip(&packed) {
                *g = p.to_array()[l];
            }
        })
    }

    /// True when every lane of `call_lanes_skip_zeros` into a buffer of NaNs is bit for bit
    /// [`Case::call_generated`] on its sample, except for outputs left as they were where the
    /// scalar kernel gives +0 (over the first few packs).
    pub fn lanes_skip_zeros_match(&self, kernel: Kernel) -> bool {
        let mut packed = vec![Pack::default(); self.out_len(kernel)];
        self.every_lane_matches_skipping_zeros(kernel, LANES, |c, l, got| {
            if l == 0 {
                packed.fill(Pack::splat(UNWRITTEN));
                let [q, dq, ddq] = black_box(self.packs(c));
                kernel.call_lanes_skip_zeros(
                    self.arm,
                    q,
                    dq,
                    ddq,
                    &self.theta_packed[..],
                    &mut packed,
                );
            }
            crate::pack::lane(&packed, l, got);
        })
    }

    /// [`Case::lanes_skip_zeros_match`] of the eight-lane form.
    pub fn lanes8_skip_zeros_match(&self, kernel: Kernel) -> bool {
        let mut packed = vec![Pack8::default(); self.out_len(kernel)];
        self.every_lane_matches_skipping_zeros(kernel, WIDE_LANES, |c, l, got| {
            if l == 0 {
                packed.fill(Pack8::splat(UNWRITTEN));
                let [q, dq, ddq] = black_box(self.packs8(c));
                kernel.call_lanes8_skip_zeros(
                    self.arm,
                    q,
                    dq,
                    ddq,
                    &self.theta_packed8[..],
                    &mut packed,
                );
            }
            for (g, p) in got.iter_mut().zip(&packed) {
                *g = p.to_array()[l];
            }
        })
    }

    /// [`Case::every_lane_matches`], where an output may also be [`UNWRITTEN`] if the scalar
    /// kernel's is +0: an unwritten output is read as +0, which matches only that.
    fn every_lane_matches_skipping_zeros(
        &self,
        kernel: Kernel,
        width: usize,
        mut lane: impl FnMut(usize, usize, &mut [f64]),
    ) -> bool {
        self.every_lane_matches(kernel, width, |c, l, got| {
            lane(c, l, got);
            for g in got
                .iter_mut()
                .filter(|g| g.to_bits() == UNWRITTEN.to_bits())
            {
                *g = 0.0;
            }
        })
    }

    /// Whether lane `l` of call `c` of a `width`-lane kernel (`lane(c, l, out)` writes it; lanes
    /// of one call are asked for in order from 0) is bit for bit [`Case::call_generated`] on
    /// sample `width·c + l`, for the first four calls.
    fn every_lane_matches(
        &self,
        kernel: Kernel,
        width: usize,
        mut lane: impl FnMut(usize, usize, &mut [f64]),
    ) -> bool {
        let len = self.out_len(kernel);
        let (mut want, mut got) = (vec![0.0; len], vec![0.0; len]);
        (0..4).all(|c| {
            (0..width).all(|l| {
                lane(c, l, &mut got);
                self.call_straight(kernel, c * width + l, &mut want);
                want.iter()
                    .zip(&got)
                    .all(|(a, b)| a.to_bits() == b.to_bits())
            })
        })
    }

    /// True when every lane of [`Case::call_lanes`] equals [`Case::call_generated`] on its
    /// sample, bit for bit, over the first few packs.
    pub fn lanes_match(&self, kernel: Kernel) -> bool {
        let mut packed = vec![Pack::default(); self.out_len(kernel)];
        self.every_lane_matches(kernel, LANES, |c, l, got| {
            if l == 0 {
                self.call_lanes(kernel, c, &mut packed);
            }
            crate::pack::lane(&packed, l, got);
        })
    }

    /// The reference `kernel` on pool sample `k` (inputs through `black_box`): the oracle of each
    /// kernel kind, written by hand (a new kind needs its reference here).
    #[inline]
    pub fn call_reference(&self, r: &mut Reference, kernel: Kernel, k: usize, out: &mut [f64]) {
        let s = &self.pool;
        let (q, dq, ddq, p) = (
            black_box(s.q(k)),
            black_box(s.dq(k)),
            black_box(s.ddq(k)),
            &self.p[..],
        );
        match kernel {
            Kernel::Regressor => r.regressor(q, dq, ddq, out),
            Kernel::BaseRegressor => r.base_regressor(q, dq, ddq, out),
            Kernel::MassMatrix => r.mass_matrix(q, p, out),
            Kernel::Bias => r.bias(q, dq, p, out),
            Kernel::Gravity => r.gravity(q, p, out),
            Kernel::InverseDynamics => r.inverse_dynamics(q, dq, ddq, p, out),
            // The forward-dynamics kernels read the third slot as τ.
            Kernel::ForwardDynamics => r.model.forward_dynamics(&mut r.ws, q, dq, ddq, p, out),
            Kernel::InverseMassMatrix => r.model.inverse_mass_matrix(&mut r.ws, q, p, out),
            Kernel::InverseDynamicsDerivatives => r
                .model
                .inverse_dynamics_derivatives(&mut r.ws, q, dq, ddq, p, out),
            Kernel::ForwardDynamicsDerivatives => r
                .model
                .forward_dynamics_derivatives(&mut r.ws, q, dq, ddq, p, out),
        }
    }

    /// Largest difference between generated and reference over a few pool samples, relative
    /// to the largest reference output.
    pub fn check(&self, r: &mut Reference, kernel: Kernel) -> f64 {
        let len = self.out_len(kernel);
        let (mut g, mut f) = (vec![0.0; len], vec![0.0; len]);
        let mut worst: f64 = 0.0;
        for k in 0..8 {
            self.call_generated(kernel, k, &mut g);
            self.call_reference(r, kernel, k, &mut f);
            let scale = f.iter().fold(1.0f64, |m, x| m.max(x.abs()));
            let err = g
                .iter()
                .zip(&f)
                .fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
            worst = worst.max(err / scale);
        }
        worst
    }
}

/// Times every kernel of `arm`, generated and reference, after checking that they agree.
pub fn measure_arm(
    arm: &'static dyn Model,
    settings: &Settings,
) -> Result<Vec<KernelTiming>, BenchError> {
    let case = Case::new(arm);
    let mut reference = Reference::new(arm)?;
    let mut out = Vec::new();
    for kernel in Kernel::ALL {
        let err = case.check(&mut reference, kernel);
        if err.is_nan() || err >= 1e-9 {
            return Err(BenchError::Mismatch {
                arm: arm.name().to_string(),
                kernel: kernel.name(),
                err,
            });
        }
        for (lanes, ok) in [
            (
                LANES,
                case.lanes_match(kernel) && case.lanes_skip_zeros_match(kernel),
            ),
            (
                WIDE_LANES,
                case.lanes8_match(kernel) && case.lanes8_skip_zeros_match(kernel),
            ),
        ] {
            if !ok {
                return Err(BenchError::LanesMismatch {
                    arm: arm.name().to_string(),
                    kernel: kernel.name(),
                    lanes,
                });
            }
        }
        let t = kernel.with(TimeGenerated {
            case: &case,
            settings,
        });
        let mut buf = vec![0.0; case.out_len(kernel)];
        let reference_ns = time_per_call(settings, |i| {
            case.call_reference(&mut reference, kernel, i, &mut buf);
            black_box(&mut buf);
        });
        out.push(KernelTiming {
            arm: arm.name().to_string(),
            kernel: kernel.name(),
            generated_ns: t.single,
            reference_ns,
            lanes_ns: t.lanes,
            lanes8_ns: t.lanes8,
            lanes_skip_ns: t.lanes_skip,
            lanes8_skip_ns: t.lanes8_skip,
        });
    }
    Ok(out)
}

/// Peak resident set size of this process in MB (`VmHWM` of `/proc/self/status`; 0 where that
/// file does not exist).
pub fn peak_rss_mb() -> f64 {
    let status = std::fs::read_to_string("/proc/self/status").unwrap_or_default();
    status
        .lines()
        .find_map(|l| l.strip_prefix("VmHWM:"))
        .and_then(|v| v.trim().trim_end_matches("kB").trim().parse::<f64>().ok())
        .map_or(0.0, |kb| kb / 1024.0)
}

/// Runs the first arm's regressor for `time` (see [`Settings::warm_up`]).
fn warm_up(arms: &[&'static dyn Model], time: Duration) {
    let Some(&arm) = arms.first() else { return };
    let pool = SamplePool::new(arm.dof(), 1);
    let mut out = vec![0.0; arm.dof() * arm.np()];
    let t0 = Instant::now();
    let mut i = 0;
    while t0.elapsed() < time {
        for _ in 0..64 {
            arm.regressor(black_box(pool.q(i)), pool.dq(i), pool.ddq(i), &mut out);
            i += 1;
        }
        black_box(&mut out);
    }
}

/// Everything `dynid bench` measures: the kernels of `arms`, then the PUMA identification with
/// `samples` samples. `progress` is called after each arm.
pub fn run(
    arms: &[&'static dyn Model],
    settings: &Settings,
    samples: usize,
    mut progress: impl FnMut(&str),
) -> Result<(Report, IdentifyRun), BenchError> {
    warm_up(arms, settings.warm_up);
    let mut kernels = Vec::new();
    for &arm in arms {
        kernels.extend(measure_arm(arm, settings)?);
        progress(arm.name());
    }
    let puma = crate::arms::find("puma560").ok_or(BenchError::MissingArm("puma560"))?;
    let ident = identify_streaming(puma, samples, 0.05)?;
    progress("identify");
    Ok((
        Report {
            kernels,
            identify: ident.timing.clone(),
        },
        ident,
    ))
}
