//! The batch driver behind every kernel method of `dynid.Arm`: `N` samples in, `N` outputs out,
//! row-major, no Python in sight (so `examples/batch_throughput.rs` compiles this file on its own
//! and times the very code the bindings run).
//!
//! Generated arms run the lane-batched kernels ([`dynid::pack`]: [`LANES`] samples per call,
//! each lane bit for bit the straight-line scalar kernel's result, to rounding where the
//! scalar method has a compact form: `codegen/FORMAT.md`); the last `N mod LANES` samples go through
//! the scalar kernel. Arms without generated kernels run the hand-written reference dynamics
//! ([`dynid::reference`]) sample by sample, the base regressor through the numerical base of
//! [`BaseModel`]. Work is split into chunks of [`CHUNK`] samples, spread over rayon's threads.

use dynid::identify::base::{BaseModel, Scratch};
use dynid::model::{Kernel, Model};
use dynid::pack::{gather, Pack, LANES};
use dynid::reference::{RefModel, Workspace};
use rayon::prelude::*;

/// Samples per unit of work (a multiple of [`LANES`]): large enough that a chunk's bookkeeping
/// is noise, small enough that two threads share a 100-sample batch.
pub const CHUNK: usize = 64;

/// What evaluates an arm's dynamics.
pub enum Dynamics {
    /// Generated, unrolled kernels (`dynid::arms`).
    Generated(&'static dyn Model),
    /// The reference recursive Newton–Euler of a D-H table and its numerical base parameters.
    Reference { model: RefModel, base: BaseModel },
}

/// The joint-space inputs of one call: `samples × dof` values each, row-major. A kernel reads
/// only the ones it takes; the others may be empty. `ddq` holds τ for the forward-dynamics
/// kernels (the third slot of [`Kernel::call`]).
pub struct States<'a> {
    pub samples: usize,
    pub q: &'a [f64],
    pub dq: &'a [f64],
    pub ddq: &'a [f64],
}

impl Dynamics {
    pub fn dof(&self) -> usize {
        match self {
            Dynamics::Generated(m) => m.dof(),
            Dynamics::Reference { model, .. } => model.dof(),
        }
    }

    /// Full inertial parameters, `10 · dof`.
    pub fn np(&self) -> usize {
        10 * self.dof()
    }

    pub fn nb(&self) -> usize {
        match self {
            Dynamics::Generated(m) => m.nb(),
            Dynamics::Reference { base, .. } => base.nb(),
        }
    }

    /// Output values per sample of `kernel`.
    pub fn out_len(&self, kernel: Kernel) -> usize {
        kernel.out_len(self.dof(), self.np(), self.nb())
    }

    /// Base parameters `θ = B·p` of full parameters `p`.
    pub fn base_params(&self, p: &[f64]) -> Vec<f64> {
        match self {
            Dynamics::Generated(m) => {
                let mut out = vec![0.0; m.nb()];
                m.base_params(p, &mut out);
                out
            }
            Dynamics::Reference { base, .. } => base.base_params(p),
        }
    }

    /// Runs `kernel` on every sample of `x` with full parameters `p` (ignored by the
    /// regressors), writing sample `s`'s output to `out[s·len .. (s+1)·len]`. `threads`: 1 runs
    /// on the calling thread, 0 on rayon's global pool, `k` on a pool of `k` threads.
    ///
    /// `out_is_new`: `out` was just allocated and never written (its pages are faulted in by the
    /// kernels' stores, each fault bringing a zeroed page into the cache: normal stores are then
    /// the cheap ones); otherwise a large output is written with non-temporal stores
    /// ([`STREAM_BYTES`]).
    ///
    /// Panics if a slice has the wrong length (the bindings check shapes before calling).
    pub fn run(
        &self,
        kernel: Kernel,
        x: &States,
        p: &[f64],
        out: &mut [f64],
        threads: usize,
        out_is_new: bool,
    ) {
        let len = self.out_len(kernel);
        assert_eq!(out.len(), x.samples * len, "output length");
        if x.samples == 0 || len == 0 {
            return;
        }
        let stream = !out_is_new && std::mem::size_of_val(out) >= STREAM_BYTES;
        let work = Work::new(self, kernel, p, stream);
        let body = |(c, o): (usize, &mut [f64])| work.chunk(x, c * CHUNK, o);
        let chunks = out.chunks_mut(CHUNK * len).enumerate();
        match threads {
            1 => chunks.for_each(body),
            0 => out.par_chunks_mut(CHUNK * len).enumerate().for_each(body),
            k => match rayon::ThreadPoolBuilder::new().num_threads(k).build() {
                Ok(pool) => {
                    pool.install(|| out.par_chunks_mut(CHUNK * len).enumerate().for_each(body))
                }
                Err(_) => chunks.for_each(body),
            },
        }
    }
}

/// One call's constants: the kernel, its parameters (as packs for the lanes).
struct Work<'a> {
    dynamics: &'a Dynamics,
    kernel: Kernel,
    p: &'a [f64],
    theta: Vec<f64>,
    theta_packed: Vec<Pack>,
    /// Write the output with non-temporal stores (see [`STREAM_BYTES`]).
    stream: bool,
}

impl<'a> Work<'a> {
    fn new(dynamics: &'a Dynamics, kernel: Kernel, p: &'a [f64], stream: bool) -> Self {
        let takes_params = !matches!(kernel, Kernel::Regressor | Kernel::BaseRegressor);
        let theta = match dynamics {
            Dynamics::Generated(_) if takes_params => dynamics.base_params(p),
            _ => Vec::new(),
        };
        let theta_packed = theta.iter().map(|&t| Pack::splat(t)).collect();
        Work {
            dynamics,
            kernel,
            p,
            theta,
            theta_packed,
            stream,
        }
    }

    /// Samples `s0 .. s0 + out.len() / len`.
    fn chunk(&self, x: &States, s0: usize, out: &mut [f64]) {
        match self.dynamics {
            Dynamics::Generated(m) => self.chunk_generated(*m, x, s0, out),
            Dynamics::Reference { model, base } => self.chunk_reference(model, base, x, s0, out),
        }
    }

    fn chunk_generated(&self, m: &dyn Model, x: &States, s0: usize, out: &mut [f64]) {
        let n = m.dof();
        let len = self.dynamics.out_len(self.kernel);
        let count = out.len() / len;
        let mut inputs = [
            vec![Pack::default(); n],
            vec![Pack::default(); n],
            vec![Pack::default(); n],
        ];
        let mut packed = vec![Pack::default(); len];
        let whole = count - count % LANES;
        for g in (0..whole).step_by(LANES) {
            for (dst, src) in inputs.iter_mut().zip([x.q, x.dq, x.ddq]) {
                if !src.is_empty() {
                    let rows: [&[f64]; LANES] = std::array::from_fn(|l| row(src, s0 + g + l, n));
                    gather(rows, dst);
                }
            }
            let [q, dq, ddq] = &inputs;
            self.kernel
                .call_lanes(m, q, dq, ddq, &self.theta_packed, &mut packed);
            scatter(&packed, &mut out[g * len..(g + LANES) * len], self.stream);
        }
        if self.stream {
            store_fence();
        }
        for s in whole..count {
            let (q, dq, ddq) = (
                row(x.q, s0 + s, n),
                row(x.dq, s0 + s, n),
                row(x.ddq, s0 + s, n),
            );
            self.kernel
                .call(m, q, dq, ddq, &self.theta, &mut out[s * len..(s + 1) * len]);
        }
    }

    fn chunk_reference(
        &self,
        model: &RefModel,
        base: &BaseModel,
        x: &States,
        s0: usize,
        out: &mut [f64],
    ) {
        let n = model.dof();
        let len = self.dynamics.out_len(self.kernel);
        let mut ws: Workspace = model.workspace();
        let mut scratch: Scratch = base.scratch();
        let p = self.p;
        for (s, o) in out.chunks_mut(len).enumerate() {
            let (q, dq, ddq) = (
                row(x.q, s0 + s, n),
                row(x.dq, s0 + s, n),
                row(x.ddq, s0 + s, n),
            );
            match self.kernel {
                Kernel::Regressor => model.regressor(&mut ws, q, dq, ddq, o),
                Kernel::BaseRegressor => base.eval(&mut scratch, q, dq, ddq, o),
                Kernel::MassMatrix => model.mass_matrix(&mut ws, q, p, o),
                Kernel::Bias => model.bias(&mut ws, q, dq, p, o),
                Kernel::Gravity => model.gravity(&mut ws, q, p, o),
                Kernel::InverseDynamics => model.inverse_dynamics(&mut ws, q, dq, ddq, p, o),
                // The forward-dynamics kernels read τ from the third slot (`States::ddq`).
                Kernel::ForwardDynamics => model.forward_dynamics(&mut ws, q, dq, ddq, p, o),
                Kernel::InverseMassMatrix => model.inverse_mass_matrix(&mut ws, q, p, o),
                Kernel::InverseDynamicsDerivatives => {
                    model.inverse_dynamics_derivatives(&mut ws, q, dq, ddq, p, o)
                }
                Kernel::ForwardDynamicsDerivatives => {
                    model.forward_dynamics_derivatives(&mut ws, q, dq, ddq, p, o)
                }
            }
        }
    }
}

/// Outputs at least this large (bytes), unless new, are written with non-temporal stores: they
/// do not fit in the caches, so a normal store would first read each cache line from memory only
/// to overwrite it (a 100,000-sample PUMA base regressor is 173 MB of output: its memory traffic,
/// not the kernels, sets the pace; measured on the 2-core VM: 350–470 → 190–245 ns per sample
/// into a reused output).
pub const STREAM_BYTES: usize = 8 << 20;

/// Writes the [`LANES`] samples held by `packed` (pack `k`: output value `k` of each sample) as
/// `LANES` consecutive rows of `block`. Four packs at a time are transposed, so each row gets
/// four consecutive values per store rather than one (the scatter, not the kernel, was most of
/// a chunk's time with one store per value); `stream`: non-temporal stores (16-byte pairs when
/// the rows allow, else value by value).
#[inline]
fn scatter(packed: &[Pack], block: &mut [f64], stream: bool) {
    let len = packed.len();
    let quads = len - len % 4;
    let pairs_aligned = len.is_multiple_of(2) && (block.as_ptr() as usize).is_multiple_of(16);
    for k in (0..quads).step_by(4) {
        let a: [[f64; 4]; 4] = std::array::from_fn(|i| packed[k + i].to_array());
        for l in 0..LANES {
            let v = [a[0][l], a[1][l], a[2][l], a[3][l]];
            let dst = &mut block[l * len + k..l * len + k + 4];
            if !stream {
                dst.copy_from_slice(&v);
            } else if pairs_aligned {
                let (lo, hi) = dst.split_at_mut(2);
                store_streaming_pair(lo, [v[0], v[1]]);
                store_streaming_pair(hi, [v[2], v[3]]);
            } else {
                for (d, x) in dst.iter_mut().zip(v) {
                    store_streaming(d, x);
                }
            }
        }
    }
    for (k, p) in packed.iter().enumerate().skip(quads) {
        for (l, v) in p.to_array().into_iter().enumerate() {
            if stream {
                store_streaming(&mut block[l * len + k], v);
            } else {
                block[l * len + k] = v;
            }
        }
    }
}

/// `dst = v` (two values at a 16-byte aligned address), bypassing the caches where the CPU can
/// (x86-64: `movntpd`); [`store_fence`] after.
#[inline(always)]
fn store_streaming_pair(dst: &mut [f64], v: [f64; 2]) {
    debug_assert!(dst.len() == 2 && (dst.as_ptr() as usize).is_multiple_of(16));
    #[cfg(target_arch = "x86_64")]
    // SAFETY: `dst` is two valid, exclusive f64s at a 16-byte aligned address (checked by the
    // caller: an aligned block and an even row length); `movntpd` is SSE2, in the x86-64
    // baseline. Its weak ordering is ended by `store_fence` before the chunk is done.
    unsafe {
        use std::arch::x86_64::{_mm_set_pd, _mm_stream_pd};
        _mm_stream_pd(dst.as_mut_ptr(), _mm_set_pd(v[1], v[0]))
    };
    #[cfg(not(target_arch = "x86_64"))]
    dst.copy_from_slice(&v);
}

/// `*dst = v`, bypassing the caches where the CPU can (x86-64: `movnti`); [`store_fence`] after.
#[inline(always)]
fn store_streaming(dst: &mut f64, v: f64) {
    #[cfg(target_arch = "x86_64")]
    // SAFETY: `dst` is a valid, aligned, exclusive f64 location; `movnti` is SSE2, part of the
    // x86-64 baseline. Its weak ordering is ended by `store_fence` before the chunk is done.
    unsafe {
        std::arch::x86_64::_mm_stream_si64((dst as *mut f64).cast::<i64>(), v.to_bits() as i64)
    };
    #[cfg(not(target_arch = "x86_64"))]
    {
        *dst = v;
    }
}

/// Orders the non-temporal stores before anything after (x86-64: `sfence`).
#[inline(always)]
fn store_fence() {
    #[cfg(target_arch = "x86_64")]
    // SAFETY: `sfence` is SSE, part of the x86-64 baseline.
    unsafe {
        std::arch::x86_64::_mm_sfence()
    };
}

/// Sample `s` of a `samples × n` block (an empty block stays empty: an input the kernel ignores).
fn row(v: &[f64], s: usize, n: usize) -> &[f64] {
    if v.is_empty() {
        v
    } else {
        &v[s * n..(s + 1) * n]
    }
}

/// Which of `(q, dq, ddq)` `kernel` reads (`ddq`: τ for the forward-dynamics kernels).
pub fn takes(kernel: Kernel) -> [bool; 3] {
    match kernel {
        Kernel::Regressor
        | Kernel::BaseRegressor
        | Kernel::InverseDynamics
        | Kernel::InverseDynamicsDerivatives
        | Kernel::ForwardDynamics
        | Kernel::ForwardDynamicsDerivatives => [true; 3],
        Kernel::MassMatrix | Kernel::Gravity | Kernel::InverseMassMatrix => [true, false, false],
        Kernel::Bias => [true, true, false],
    }
}
