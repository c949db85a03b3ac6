//! Eight samples per kernel call: [`Pack8`], the generated `<kernel>_lanes8` methods of
//! [`crate::model::Model`], and the run-time choice of how they run.
//!
//! Where the CPU has AVX-512F (checked once, at run time, by [`avx512`]), an eight-lane kernel is
//! the generic lane-batched kernel instantiated for one 512-bit register per value and compiled
//! for AVX-512F (`#[target_feature]`), so one instruction does the work of eight scalar ones and
//! the 32 vector registers hold more of a long kernel's values than AVX2's 16. Elsewhere (an
//! AVX2-only CPU, another architecture, a build without FMA) it is the four-lane kernel
//! ([`crate::pack::Pack`]) on each half. Either way every lane is, bit for bit, what the scalar
//! kernel computes for that sample: the operations are the same IEEE operations lane by lane, and
//! the trigonometry is [`crate::trig::sin_cos`]'s polynomial (tested against it, and against
//! the four-lane form, on this module's inputs and on every kernel of every arm).
//!
//! Set `DYNID_NO_AVX512=1` to run the four-lane halves on an AVX-512 CPU (to compare the two).
//!
//! ```
//! use dynid::pack::wide::{Pack8, WIDE_LANES};
//! let a = Pack8::new([1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0]);
//! assert_eq!(a.to_array()[WIDE_LANES - 1], 8.0);
//! assert_eq!(a.half(1).to_array(), [5.0, 6.0, 7.0, 8.0]);
//! ```

use super::{Pack, LANES};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::OnceLock;

/// Samples per [`Pack8`].
pub const WIDE_LANES: usize = 8;

/// One value of eight independent samples, in memory (64-byte aligned: one AVX-512 register).
/// Kernel inputs and outputs are arrays of these, structure of arrays as for [`Pack`].
#[derive(Clone, Copy, PartialEq)]
#[repr(C, align(64))]
pub struct Pack8([f64; WIDE_LANES]);

impl Pack8 {
    /// The eight lanes.
    #[inline(always)]
    pub fn new(v: [f64; WIDE_LANES]) -> Self {
        Pack8(v)
    }
    /// `x` in every lane.
    #[inline(always)]
    pub fn splat(x: f64) -> Self {
        Pack8([x; WIDE_LANES])
    }
    /// The eight lanes.
    #[inline(always)]
    pub fn to_array(self) -> [f64; WIDE_LANES] {
        self.0
    }
    /// Lanes `4h … 4h + 3` (`h` is 0 or 1) as a four-lane [`Pack`].
    #[inline(always)]
    pub fn half(self, h: usize) -> Pack {
        Pack::new(std::array::from_fn(|l| self.0[h * LANES + l]))
    }
    /// The eight lanes of `lo` then `hi`.
    #[inline(always)]
    pub fn join(lo: Pack, hi: Pack) -> Self {
        let (lo, hi) = (lo.to_array(), hi.to_array());
        Pack8(std::array::from_fn(|l| {
            if l < LANES {
                lo[l]
            } else {
                hi[l - LANES]
            }
        }))
    }
}

impl Default for Pack8 {
    fn default() -> Self {
        Pack8::splat(0.0)
    }
}

impl std::fmt::Debug for Pack8 {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "Pack8({:?})", self.0)
    }
}

static FORCE_HALVES: AtomicBool = AtomicBool::new(false);

/// True when the eight-lane kernels run as AVX-512 code: the build has FMA (the scalar kernels'
/// trigonometry is fused; the AVX-512 form must round the same way), the CPU has AVX-512F, and
/// neither `DYNID_NO_AVX512` is set nor [`force_halves`] is on. Checked once per process (the
/// CPU and the variable), then one relaxed load.
#[inline]
pub fn avx512() -> bool {
    static DETECTED: OnceLock<bool> = OnceLock::new();
    let detected = *DETECTED.get_or_init(|| {
        #[cfg(all(target_arch = "x86_64", target_feature = "fma"))]
        {
            std::is_x86_feature_detected!("avx512f")
                && std::env::var_os("DYNID_NO_AVX512").is_none_or(|v| v.is_empty() || v == "0")
        }
        #[cfg(not(all(target_arch = "x86_64", target_feature = "fma")))]
        {
            false
        }
    });
    detected && !FORCE_HALVES.load(Ordering::Relaxed)
}

/// Runs the eight-lane kernels as two four-lane calls from now on (`true`) or back to the run-time
/// choice (`false`): for tests and benchmarks that compare the two forms in one process. Both
/// give the same bits, so flipping it while other threads run kernels changes only their speed.
#[doc(hidden)]
pub fn force_halves(on: bool) {
    FORCE_HALVES.store(on, Ordering::Relaxed);
}

/// How the eight-lane kernels run in this process: `"avx512"` or `"4-lane halves"`.
pub fn wide_form() -> &'static str {
    if avx512() {
        "avx512"
    } else {
        "4-lane halves"
    }
}

/// Half `h` of every pack of `a` (the fallback's inputs).
#[doc(hidden)]
#[inline(always)]
pub fn halves<const N: usize>(a: &[Pack8; N], h: usize) -> [Pack; N] {
    std::array::from_fn(|i| a[i].half(h))
}

/// `out[i] = join(lo[i], hi[i])` (the fallback's outputs).
#[doc(hidden)]
#[inline(always)]
pub fn join_into<const N: usize>(lo: &[Pack; N], hi: &[Pack; N], out: &mut [Pack8; N]) {
    for ((o, l), h) in out.iter_mut().zip(lo).zip(hi) {
        *o = Pack8::join(*l, *h);
    }
}

#[cfg(all(target_arch = "x86_64", target_feature = "fma"))]
pub use zmm::{as_zmm, as_zmm_mut, Zmm};

#[cfg(all(target_arch = "x86_64", target_feature = "fma"))]
mod zmm {
    use super::{Pack8, WIDE_LANES};
    use crate::pack::Lane;
    use std::arch::x86_64::*;
    use std::ops::{Add, Div, Mul, Neg, Sub};

    /// One value of eight samples in an AVX-512 register: the type the generated kernels are
    /// instantiated for inside their `#[target_feature(enable = "avx512f")]` wrappers. Only such
    /// a wrapper, called after [`super::avx512`] said yes, may make or use one; hidden from the
    /// docs for that reason.
    #[doc(hidden)]
    #[derive(Clone, Copy)]
    #[repr(transparent)]
    pub struct Zmm(__m512d);

    /// `a` seen as registers (the same size and alignment: 64 bytes).
    ///
    /// # Safety
    /// The CPU must have AVX-512F.
    #[doc(hidden)]
    #[inline(always)]
    pub unsafe fn as_zmm<const N: usize>(a: &[Pack8; N]) -> &[Zmm; N] {
        // SAFETY: `Pack8` is `repr(C, align(64))` of `[f64; 8]` and `Zmm` `repr(transparent)` of
        // `__m512d` (64 bytes, align 64): the same layout, every bit pattern valid in both.
        unsafe { &*(a as *const [Pack8; N] as *const [Zmm; N]) }
    }

    /// `a` seen as registers, for writing.
    ///
    /// # Safety
    /// The CPU must have AVX-512F.
    #[doc(hidden)]
    #[inline(always)]
    pub unsafe fn as_zmm_mut<const N: usize>(a: &mut [Pack8; N]) -> &mut [Zmm; N] {
        // SAFETY: as in `as_zmm`.
        unsafe { &mut *(a as *mut [Pack8; N] as *mut [Zmm; N]) }
    }

    // SAFETY (every `unsafe` below): a `Zmm` exists only inside code compiled with AVX-512F that
    // runs after the CPU was found to have it (see the type's docs); register operations only.
    macro_rules! binary {
        ($trait:ident, $method:ident, $intrinsic:ident) => {
            impl $trait for Zmm {
                type Output = Self;
                #[inline(always)]
                fn $method(self, b: Self) -> Self {
                    Zmm(unsafe { $intrinsic(self.0, b.0) })
                }
            }
        };
    }
    binary!(Add, add, _mm512_add_pd);
    binary!(Sub, sub, _mm512_sub_pd);
    binary!(Mul, mul, _mm512_mul_pd);
    binary!(Div, div, _mm512_div_pd);

    impl Neg for Zmm {
        type Output = Self;
        #[inline(always)]
        fn neg(self) -> Self {
            // Flip the sign bit: exactly `-x` per lane (also for ±0 and NaN).
            Zmm(unsafe {
                _mm512_castsi512_pd(_mm512_xor_si512(
                    _mm512_castpd_si512(self.0),
                    _mm512_set1_epi64(i64::MIN),
                ))
            })
        }
    }

    impl Lane for Zmm {
        #[inline(always)]
        fn splat(x: f64) -> Self {
            Zmm(unsafe { _mm512_set1_pd(x) })
        }
        /// One `vfmadd` (AVX-512F): the fused value, as [`crate::trig::mul_add`] gives it on
        /// this target (AVX-512F implies FMA).
        #[inline(always)]
        fn mul_add(self, b: Self, c: Self) -> Self {
            Zmm(unsafe { _mm512_fmadd_pd(self.0, b.0, c.0) })
        }
        /// One store per zero (volatile: never merged into a `memset`; see
        /// [`crate::pack::store_zero`]).
        #[inline(always)]
        fn store_zero(dst: &mut Self) {
            // SAFETY: `dst` is a valid, aligned, exclusive reference.
            unsafe { std::ptr::write_volatile(dst, Self::splat(0.0)) }
        }
        #[inline(always)]
        fn sin_cos(self) -> (Self, Self) {
            if let Some((s, c)) = unsafe { crate::trig::avx512::sin_cos(self.0) } {
                return (Zmm(s), Zmm(c));
            }
            let x = Pack8(unsafe { std::mem::transmute::<__m512d, [f64; WIDE_LANES]>(self.0) });
            let (s, c) = sin_cos_slow(x);
            // SAFETY: plain bit copies of 64 bytes.
            unsafe {
                (
                    Zmm(std::mem::transmute::<[f64; WIDE_LANES], __m512d>(s.0)),
                    Zmm(std::mem::transmute::<[f64; WIDE_LANES], __m512d>(c.0)),
                )
            }
        }
    }

    /// Lane by lane through the scalar function (rare: a lane beyond the fast path, NaN, or
    /// near a multiple of π/2); out of line, in memory, so no AVX-512 register crosses a call.
    #[cold]
    #[inline(never)]
    fn sin_cos_slow(x: Pack8) -> (Pack8, Pack8) {
        let sc = x.0.map(crate::trig::sin_cos);
        (Pack8(sc.map(|v| v.0)), Pack8(sc.map(|v| v.1)))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn halves_join_round_trip() {
        let a = Pack8::new(std::array::from_fn(|l| l as f64 - 3.5));
        assert_eq!(Pack8::join(a.half(0), a.half(1)), a);
        let arr = [a, Pack8::splat(2.0)];
        let (lo, hi) = (halves(&arr, 0), halves(&arr, 1));
        let mut out = [Pack8::default(); 2];
        join_into(&lo, &hi, &mut out);
        assert_eq!(out, arr);
    }

    /// The AVX-512 operations (the fused multiply-add among them) and trigonometry are the scalar
    /// ones lane by lane, bit for bit (on
    /// a CPU without AVX-512 there is nothing of this form to run: the kernels use the halves).
    #[cfg(all(target_arch = "x86_64", target_feature = "fma"))]
    #[test]
    fn avx512_lanes_equal_the_scalar_operations_and_trig() {
        if !std::is_x86_feature_detected!("avx512f") {
            eprintln!("no AVX-512F on this CPU: only the four-lane halves can run here");
            return;
        }
        #[target_feature(enable = "avx512f")]
        fn check(a: [f64; 8], b: [f64; 8]) {
            let (pa, pb) = (Pack8::new(a), Pack8::new(b));
            // SAFETY: this function is compiled with AVX-512F and called only where the CPU has it.
            let (za, zb) = unsafe { (as_zmm(&[pa])[0], as_zmm(&[pb])[0]) };
            type Scalar = fn(f64, f64) -> f64;
            let ops: [(Zmm, Scalar); 6] = [
                (za + zb, |x, y| x + y),
                (za - zb, |x, y| x - y),
                (za * zb, |x, y| x * y),
                (za / zb, |x, y| x / y),
                (-za, |x, _| -x),
                (crate::pack::Lane::mul_add(za, zb, -za), |x, y| {
                    crate::trig::mul_add(x, y, -x)
                }),
            ];
            let (s, c) = crate::pack::Lane::sin_cos(za);
            let mut got = [[Pack8::default(); 1]; 8];
            for (g, z) in got.iter_mut().zip(ops.iter().map(|o| o.0).chain([s, c])) {
                // SAFETY: as above.
                unsafe { as_zmm_mut(g)[0] = z };
            }
            for l in 0..WIDE_LANES {
                for (k, (_, f)) in ops.iter().enumerate() {
                    assert_eq!(
                        got[k][0].0[l].to_bits(),
                        f(a[l], b[l]).to_bits(),
                        "op {k}, {a:?} {b:?}"
                    );
                }
                let (s0, c0) = crate::trig::sin_cos(a[l]);
                assert_eq!(
                    (got[6][0].0[l].to_bits(), got[7][0].0[l].to_bits()),
                    (s0.to_bits(), c0.to_bits()),
                    "x = {:e}",
                    a[l]
                );
            }
        }
        use std::f64::consts::{FRAC_PI_2, PI};
        let mut rng: u64 = 0x2545_F491_4F6C_DD1D;
        let mut next = || {
            rng ^= rng << 13;
            rng ^= rng >> 7;
            rng ^= rng << 17;
            (rng >> 11) as f64 / (1u64 << 53) as f64
        };
        let mut cases: Vec<[f64; 8]> = (0..4000)
            .map(|_| std::array::from_fn(|_| (next() - 0.5) * 20.0))
            .collect();
        // One lane off the fast path sends the whole pack to the scalar function: each kind.
        cases.push([PI, -FRAC_PI_2, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6]);
        cases.push([0.0, -0.0, 1e-300, -5e-324, 1.0, 2.0, 3.0, 4.0]);
        cases.push([
            2.0e6,
            1.0,
            f64::INFINITY,
            f64::NAN,
            -1.0,
            -2.0,
            -3.0,
            f64::NEG_INFINITY,
        ]);
        cases.push([1.0e6, -1.0e6, 1e5 * PI, 3.0e5, 7.0, -7.0, 1e-8, 0.5]);
        for a in cases {
            let b = a.map(|x| x * 0.75 - 1.0);
            // SAFETY: the CPU has AVX-512F (checked above).
            unsafe { check(a, b) };
        }
    }
}
