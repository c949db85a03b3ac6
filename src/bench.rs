//! Quick in-process throughput measurement behind `dynid bench`: every generated kernel against
//! the hand-written [`reference`](crate::reference) dynamics on the same inputs, and a streaming
//! identification of a 1,000,000-sample PUMA 560 log.
//!
//! Method (the same as the Pinocchio harness in `benches/peers/pinocchio/`, so numbers can sit
//! side by side): a pool of [`POOL`] random samples, `q ~ U(−π, π)`, `q̇ ~ U(−2, 2)`,
//! `q̈ ~ U(−5, 5)`; call `i` uses sample `i mod 1024`; one repetition is `N` consecutive calls
//! with `N` calibrated to last [`Settings::target`] and rounded to whole passes over the pool; one
//! warm-up repetition, then [`Settings::reps`] timed ones; the median of elapsed/N is reported in
//! ns per call, single thread. Inputs go through [`std::hint::black_box`] so nothing is hoisted
//! or folded. `cargo bench` (criterion, `benches/kernels.rs`) is the careful measurement; this is
//! the quick one (a few seconds plus about one for the identification). Each kernel is also timed
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

use nalgebra::{DMatrix, DVector};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::Serialize;

use crate::dh::DhTable;
use crate::model::Model;
use crate::pack::{gather, Pack, LANES};
use crate::reference::{RefModel, Workspace};

pub mod table;

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
    #[error("{arm}: a lane of the lane-batched `{kernel}` differs from the scalar kernel — a bug in the lane copy (macros/src/lanes.rs) or in crate::pack")]
    LanesMismatch { arm: String, kernel: &'static str },
    #[error("{arm}: the built-in D-H table does not parse: {msg}")]
    Table { arm: String, msg: String },
    #[error("identification: the information matrix is singular or ill-conditioned (cond(Yb) = {cond:.3e}) — the excitation does not identify all base parameters")]
    IllConditioned { cond: f64 },
    #[error("arm `{0}` is not built in")]
    MissingArm(&'static str),
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
        let k = k & (POOL - 1);
        &self.q[k * self.dof..(k + 1) * self.dof]
    }

    /// Velocities of sample `k`.
    #[inline(always)]
    pub fn dq(&self, k: usize) -> &[f64] {
        let k = k & (POOL - 1);
        &self.dq[k * self.dof..(k + 1) * self.dof]
    }

    /// Accelerations of sample `k`.
    #[inline(always)]
    pub fn ddq(&self, k: usize) -> &[f64] {
        let k = k & (POOL - 1);
        &self.ddq[k * self.dof..(k + 1) * self.dof]
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
}

impl Case {
    /// Pool seed 42, parameters [`plausible_params`] with seed 7.
    pub fn new(arm: &'static dyn Model) -> Self {
        let pool = SamplePool::new(arm.dof(), 42);
        let p = plausible_params(arm.dof(), 7);
        let mut theta = vec![0.0; arm.nb()];
        arm.base_params(&p, &mut theta);
        let packed = (0..POOL / LANES)
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
        Case {
            arm,
            pool,
            p,
            theta,
            packed,
            theta_packed,
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

    /// The lane-batched generated `kernel` on pool samples `LANES·c … LANES·c + LANES − 1`
    /// (`c` wraps around the pool; inputs through `black_box`).
    #[inline]
    pub fn call_lanes(&self, kernel: Kernel, c: usize, out: &mut [Pack]) {
        let [q, dq, ddq] = black_box(&self.packed[c % self.packed.len()]);
        kernel.call_lanes(self.arm, q, dq, ddq, &self.theta_packed[..], out);
    }

    /// True when every lane of [`Case::call_lanes`] equals [`Case::call_generated`] on its
    /// sample, bit for bit, over the first few packs.
    pub fn lanes_match(&self, kernel: Kernel) -> bool {
        let len = self.out_len(kernel);
        let mut packed = vec![Pack::default(); len];
        let (mut want, mut got) = (vec![0.0; len], vec![0.0; len]);
        (0..4).all(|c| {
            self.call_lanes(kernel, c, &mut packed);
            (0..LANES).all(|l| {
                self.call_generated(kernel, c * LANES + l, &mut want);
                crate::pack::lane(&packed, l, &mut got);
                want.iter()
                    .zip(&got)
                    .all(|(a, b)| a.to_bits() == b.to_bits())
            })
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
        if !case.lanes_match(kernel) {
            return Err(BenchError::LanesMismatch {
                arm: arm.name().to_string(),
                kernel: kernel.name(),
            });
        }
        let mut buf = vec![0.0; case.out_len(kernel)];
        let generated_ns = time_per_call(settings, |i| {
            case.call_generated(kernel, i, &mut buf);
            black_box(&mut buf);
        });
        let mut packs = vec![Pack::default(); case.out_len(kernel)];
        let lanes_ns = time_per_call(settings, |c| {
            case.call_lanes(kernel, c, &mut packs);
            black_box(&mut packs);
        }) / LANES as f64;
        let reference_ns = time_per_call(settings, |i| {
            case.call_reference(&mut reference, kernel, i, &mut buf);
            black_box(&mut buf);
        });
        out.push(KernelTiming {
            arm: arm.name().to_string(),
            kernel: kernel.name(),
            generated_ns,
            reference_ns,
            lanes_ns,
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

/// Streaming least squares by normal equations: `G = Σ Ybᵀ·Yb`, `b = Σ Ybᵀ·τ`, `Σ τ²`.
///
/// Memory is `O(nb²)` whatever the number of samples. Samples are buffered in blocks of
/// [`Self::BLOCK`] and folded into `G` tile by tile (`4 × 8` tiles held in registers while all
/// buffered rows stream through, as in a matrix-multiply micro-kernel). Row `i` of a serial
/// arm's base regressor is zero left of some column `start[i]` (joint i does not feel the links
/// before it, and the base parameters are ordered by link), so row `i` only touches the tiles
/// from that column on: about half the work of a dense update for a 6-DOF arm.
#[derive(Debug, Clone)]
pub struct NormalEquations {
    nb: usize,
    /// `nb` rounded up to a multiple of 8: the row stride of `g` and of the buffered rows.
    stride: usize,
    start: Vec<usize>,
    /// `stride × stride`, row-major; the upper triangle is the result (diagonal tiles are
    /// computed whole, and the padding stays zero).
    g: Vec<f64>,
    b: Vec<f64>,
    tau2: f64,
    rows: usize,
    /// Buffered rows: row `i` of buffered sample `k` at `(i·BLOCK + k)·stride`, zero-padded.
    buf: Vec<f64>,
    tau: Vec<f64>,
    pending: usize,
}

/// The least-squares solution of a [`NormalEquations`] system.
#[derive(Debug, Clone)]
pub struct Solution {
    /// Identified base parameters.
    pub theta: Vec<f64>,
    /// Condition number of the column-scaled regressor, `sqrt(cond(D⁻½·G·D⁻½))`.
    pub cond: f64,
    /// Root-mean-square torque residual over all rows.
    pub rms_residual: f64,
}

const TILE_R: usize = 4;
const TILE_C: usize = 8;

/// `acc[a][l] += y[r0 + a]·y[c0 + l]` over the rows `y` of `rows` (stride `stride`): the
/// micro-kernel of [`NormalEquations`]. Written with fixed-size arrays and index loops so that
/// the compiler keeps `acc` in vector registers; not inlined, because inlined into the tile loops
/// the vectoriser combines the wrong dimensions (measured: 3× slower).
#[inline(never)]
fn tile_update(
    acc: &mut [[f64; TILE_C]; TILE_R],
    rows: &[f64],
    stride: usize,
    r0: usize,
    c0: usize,
) {
    let mut t = *acc;
    for y in rows.chunks_exact(stride) {
        let yr: [f64; TILE_R] = y[r0..r0 + TILE_R].try_into().expect("tile rows");
        let yc: [f64; TILE_C] = y[c0..c0 + TILE_C].try_into().expect("tile columns");
        for a in 0..TILE_R {
            for l in 0..TILE_C {
                t[a][l] = crate::trig::mul_add(yr[a], yc[l], t[a][l]);
            }
        }
    }
    *acc = t;
}

impl NormalEquations {
    /// Samples buffered before they are folded into `G`.
    pub const BLOCK: usize = 32;

    /// An empty system for `nb` parameters; `start[i]` is the first column that can be non-zero
    /// in row `i` of a sample, one entry per row (use `vec![0; dof]` when unknown).
    pub fn new(nb: usize, start: Vec<usize>) -> Self {
        let stride = nb.div_ceil(TILE_C) * TILE_C;
        let dof = start.len();
        NormalEquations {
            nb,
            stride,
            start,
            g: vec![0.0; stride * stride],
            b: vec![0.0; nb],
            tau2: 0.0,
            rows: 0,
            buf: vec![0.0; dof * Self::BLOCK * stride],
            tau: vec![0.0; dof * Self::BLOCK],
            pending: 0,
        }
    }

    /// First structurally non-zero column of each row of `arm`'s base regressor, found on a few
    /// random samples (a column that is zero on all of them is zero everywhere: the entries are
    /// analytic in `q, q̇, q̈`).
    pub fn row_starts(arm: &dyn Model) -> Vec<usize> {
        let (n, nb) = (arm.dof(), arm.nb());
        let pool = SamplePool::new(n, 3);
        let mut start = vec![nb; n];
        let mut yb = vec![0.0; n * nb];
        for k in 0..16 {
            arm.base_regressor(pool.q(k), pool.dq(k), pool.ddq(k), &mut yb);
            for i in 0..n {
                if let Some(j) = yb[i * nb..(i + 1) * nb].iter().position(|&v| v != 0.0) {
                    start[i] = start[i].min(j);
                }
            }
        }
        start
    }

    /// Rows added so far.
    pub fn rows(&self) -> usize {
        self.rows + self.pending * self.start.len()
    }

    /// Adds one sample: `yb` is `dof × nb` row-major (`dof = start.len()`), `tau` has `dof`
    /// entries.
    #[inline]
    pub fn add(&mut self, yb: &[f64], tau: &[f64]) {
        let (nb, stride, dof, k) = (self.nb, self.stride, self.start.len(), self.pending);
        assert!(
            yb.len() == dof * nb && tau.len() == dof,
            "sample shape does not match the system"
        );
        for i in 0..dof {
            let row = &yb[i * nb..(i + 1) * nb];
            debug_assert!(
                row[..self.start[i].min(nb)].iter().all(|&v| v == 0.0),
                "row {i} is non-zero left of its start"
            );
            let at = (i * Self::BLOCK + k) * stride;
            self.buf[at..at + nb].copy_from_slice(row);
            self.tau[i * Self::BLOCK + k] = tau[i];
        }
        self.pending += 1;
        if self.pending == Self::BLOCK {
            self.flush();
        }
    }

    /// Folds the buffered samples into `G`, `b` and `Σ τ²`.
    fn flush(&mut self) {
        let (nb, stride, dof, n) = (self.nb, self.stride, self.start.len(), self.pending);
        if n == 0 {
            return;
        }
        for r0 in (0..stride).step_by(TILE_R) {
            for c0 in (r0 / TILE_C * TILE_C..stride).step_by(TILE_C) {
                let mut acc = [[0.0f64; TILE_C]; TILE_R];
                for i in 0..dof {
                    if self.start[i] >= r0 + TILE_R {
                        continue; // these rows of joint i are structurally zero
                    }
                    let rows = &self.buf[i * Self::BLOCK * stride..(i * Self::BLOCK + n) * stride];
                    tile_update(&mut acc, rows, stride, r0, c0);
                }
                for (a, row) in acc
                    .iter()
                    .zip(self.g[r0 * stride..].chunks_exact_mut(stride))
                {
                    for (gl, &al) in row[c0..c0 + TILE_C].iter_mut().zip(a) {
                        *gl += al;
                    }
                }
            }
        }
        for i in 0..dof {
            let taus = &self.tau[i * Self::BLOCK..i * Self::BLOCK + n];
            let rows = &self.buf[i * Self::BLOCK * stride..(i * Self::BLOCK + n) * stride];
            for (y, &t) in rows.chunks_exact(stride).zip(taus) {
                for (br, &yr) in self.b.iter_mut().zip(&y[..nb]) {
                    *br += yr * t;
                }
                self.tau2 += t * t;
            }
        }
        self.rows += n * dof;
        self.pending = 0;
    }

    /// Merges another accumulator (e.g. from another thread) of the same shape.
    pub fn merge(&mut self, other: &NormalEquations) {
        let mut other = other.clone();
        other.flush();
        self.flush();
        self.g.iter_mut().zip(&other.g).for_each(|(a, b)| *a += b);
        self.b.iter_mut().zip(&other.b).for_each(|(a, b)| *a += b);
        self.tau2 += other.tau2;
        self.rows += other.rows;
    }

    /// Solves `G·θ = b` after Jacobi scaling, with a conditioning check: a singular or
    /// ill-conditioned system (cond of the scaled regressor above `max_cond`) is an error.
    pub fn solve(&mut self, max_cond: f64) -> Result<Solution, BenchError> {
        self.flush();
        let nb = self.nb;
        let st = self.stride;
        let g = DMatrix::from_fn(nb, nb, |r, c| {
            if r <= c {
                self.g[r * st + c]
            } else {
                self.g[c * st + r]
            }
        });
        let d: Vec<f64> = (0..nb).map(|j| g[(j, j)].sqrt()).collect();
        if d.iter().any(|&x| x.is_nan() || x <= 0.0) {
            return Err(BenchError::IllConditioned {
                cond: f64::INFINITY,
            });
        }
        let gs = DMatrix::from_fn(nb, nb, |r, c| g[(r, c)] / (d[r] * d[c]));
        let eig = gs.clone().symmetric_eigenvalues();
        let (lo, hi) = eig.iter().fold((f64::INFINITY, 0.0f64), |(lo, hi), &e| {
            (lo.min(e), hi.max(e))
        });
        let cond = if lo > 0.0 {
            (hi / lo).sqrt()
        } else {
            f64::INFINITY
        };
        if cond.is_nan() || cond > max_cond {
            return Err(BenchError::IllConditioned { cond });
        }
        let bs = DVector::from_fn(nb, |r, _| self.b[r] / d[r]);
        let chol = gs.cholesky().ok_or(BenchError::IllConditioned { cond })?;
        let ts = chol.solve(&bs);
        let theta: Vec<f64> = (0..nb).map(|j| ts[j] / d[j]).collect();
        // Σ(τ − Yθ)² = Σ τ² − 2 θᵀb + θᵀGθ
        let th = DVector::from_column_slice(&theta);
        let sse =
            self.tau2 - 2.0 * th.dot(&DVector::from_column_slice(&self.b)) + th.dot(&(&g * &th));
        let rms_residual = (sse.max(0.0) / self.rows.max(1) as f64).sqrt();
        Ok(Solution {
            theta,
            cond,
            rms_residual,
        })
    }
}

/// The excitation of the streaming identification: per joint a random 5-harmonic Fourier series
/// (Swevers et al.; not the [`crate::trajectory::fourier::Fourier`] trajectory type), fundamental
/// 0.1 Hz, with closed-form velocity and acceleration evaluated by an angle-addition recurrence.
#[derive(Debug, Clone)]
pub struct BenchExcitation {
    omega: f64,
    q0: Vec<f64>,
    /// Per harmonic `l`, per joint: `(a_l, b_l)` of `q̇ = Σ a_l sin(lωt) + b_l cos(lωt)`.
    a: [Vec<f64>; 5],
    b: [Vec<f64>; 5],
}

impl BenchExcitation {
    const HARMONICS: usize = 5;

    /// Random coefficients (deterministic for a seed) giving joint excursions of about ±1.5 rad.
    pub fn random(dof: usize, seed: u64) -> Self {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let omega = 2.0 * std::f64::consts::PI * 0.1;
        let q0 = (0..dof).map(|_| rng.gen_range(-0.5..0.5)).collect();
        let mut a: [Vec<f64>; 5] = Default::default();
        let mut b: [Vec<f64>; 5] = Default::default();
        for _ in 0..dof {
            for l in 0..Self::HARMONICS {
                let s = 0.3 * omega * (l + 1) as f64;
                a[l].push(rng.gen_range(-s..s));
                b[l].push(rng.gen_range(-s..s));
            }
        }
        BenchExcitation { omega, q0, a, b }
    }

    /// `q, q̇, q̈` at time `t`.
    #[inline]
    pub fn eval(&self, t: f64, q: &mut [f64], dq: &mut [f64], ddq: &mut [f64]) {
        // sin/cos of the harmonics by the angle-addition recurrence from the fundamental.
        let (s1, c1) = crate::trig::sin_cos(self.omega * t);
        let (mut s, mut c) = (s1, c1);
        q.copy_from_slice(&self.q0);
        dq.fill(0.0);
        ddq.fill(0.0);
        for l in 0..Self::HARMONICS {
            let w = self.omega * (l + 1) as f64;
            let inv_w = 1.0 / w;
            for (j, (&a, &b)) in self.a[l].iter().zip(&self.b[l]).enumerate() {
                let (sa, cb) = (a * s + b * c, a * c - b * s);
                q[j] -= cb * inv_w;
                dq[j] += sa;
                ddq[j] += cb * w;
            }
            (s, c) = (s * c1 + c * s1, c * c1 - s * s1);
        }
    }
}

/// A tiny, fast generator for measurement noise (SplitMix64; not for anything cryptographic).
struct SplitMix64(u64);

impl SplitMix64 {
    /// Uniform in [0, 1).
    #[inline]
    fn uniform(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^= z >> 31;
        (z >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    }
}

/// Outcome of [`identify_streaming`].
#[derive(Debug, Clone)]
pub struct IdentifyRun {
    pub timing: IdentifyTiming,
    pub solution: Solution,
    /// Largest `|θ̂ − θ| / max(|θ|, 1e-3·max|θ|)` over the base parameters.
    pub max_rel_error: f64,
}

/// Streaming identification of a generated log: `samples` samples at 1 kHz along a
/// [`BenchExcitation`]; torques from the generated inverse dynamics plus uniform noise of
/// ±`noise` N·m; base regressor and [`NormalEquations`] per sample, nothing stored per sample;
/// one thread.
///
/// Normal equations rather than the incremental QR of [`crate::identify::ls::Accumulator`]:
/// that one costs about 2.3 µs per PUMA sample (2.7 s for 10⁶), this about 0.3 µs. Squaring the
/// condition number is harmless here — the column-scaled regressor has cond ≈ 16 on this
/// excitation — and [`NormalEquations::solve`] refuses anything above 10⁸.
pub fn identify_streaming(
    arm: &dyn Model,
    samples: usize,
    noise: f64,
) -> Result<IdentifyRun, BenchError> {
    let (n, nb) = (arm.dof(), arm.nb());
    let p = plausible_params(n, 11);
    let mut theta = vec![0.0; nb];
    arm.base_params(&p, &mut theta);
    let traj = BenchExcitation::random(n, 5);
    let mut rng = SplitMix64(9);
    let t0 = Instant::now();
    let mut ne = NormalEquations::new(nb, NormalEquations::row_starts(arm));
    let (mut q, mut dq, mut ddq, mut tau) =
        (vec![0.0; n], vec![0.0; n], vec![0.0; n], vec![0.0; n]);
    let mut yb = vec![0.0; n * nb];
    // Four samples per kernel call (crate::pack), in sample order; the tail one by one.
    let theta_p: Vec<Pack> = theta.iter().map(|&t| Pack::splat(t)).collect();
    let (mut qp, mut dqp, mut ddqp) = (
        vec![Pack::default(); n],
        vec![Pack::default(); n],
        vec![Pack::default(); n],
    );
    let (mut taup, mut ybp) = (vec![Pack::default(); n], vec![Pack::default(); n * nb]);
    let (mut qs, mut dqs, mut ddqs) = (
        vec![vec![0.0; n]; LANES],
        vec![vec![0.0; n]; LANES],
        vec![vec![0.0; n]; LANES],
    );
    let full = samples / LANES * LANES;
    for k0 in (0..full).step_by(LANES) {
        for l in 0..LANES {
            traj.eval(
                (k0 + l) as f64 * 1e-3,
                &mut qs[l],
                &mut dqs[l],
                &mut ddqs[l],
            );
        }
        gather(std::array::from_fn(|l| &qs[l][..]), &mut qp);
        gather(std::array::from_fn(|l| &dqs[l][..]), &mut dqp);
        gather(std::array::from_fn(|l| &ddqs[l][..]), &mut ddqp);
        arm.inverse_dynamics_lanes(&qp, &dqp, &ddqp, &theta_p, &mut taup);
        arm.base_regressor_lanes(&qp, &dqp, &ddqp, &mut ybp);
        for l in 0..LANES {
            crate::pack::lane(&taup, l, &mut tau);
            for t in tau.iter_mut() {
                *t += noise * (2.0 * rng.uniform() - 1.0);
            }
            crate::pack::lane(&ybp, l, &mut yb);
            ne.add(&yb, &tau);
        }
    }
    for k in full..samples {
        traj.eval(k as f64 * 1e-3, &mut q, &mut dq, &mut ddq);
        arm.inverse_dynamics(&q, &dq, &ddq, &theta, &mut tau);
        for t in tau.iter_mut() {
            *t += noise * (2.0 * rng.uniform() - 1.0);
        }
        arm.base_regressor(&q, &dq, &ddq, &mut yb);
        ne.add(&yb, &tau);
    }
    let solution = ne.solve(1e8)?;
    let seconds = t0.elapsed().as_secs_f64();
    let big = theta.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    let max_rel_error = solution.theta.iter().zip(&theta).fold(0.0f64, |m, (a, b)| {
        m.max((a - b).abs() / b.abs().max(1e-3 * big))
    });
    let timing = IdentifyTiming {
        arm: arm.name().to_string(),
        samples,
        seconds,
        peak_rss_mb: peak_rss_mb(),
    };
    Ok(IdentifyRun {
        timing,
        solution,
        max_rel_error,
    })
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

#[cfg(test)]
mod tests {
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
}
