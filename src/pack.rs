//! SIMD across samples: [`Pack`] holds one value of [`LANES`] independent samples, and every
//! generated kernel also exists as a lane-batched copy (`base_regressor_lanes`, …) that runs the
//! same straight-line code on packs, so four samples cost about one sample's instructions.
//!
//! Why: one call of a generated kernel is a few hundred dependent scalar operations; the CPU
//! already issues them about as fast as it can, so a single call cannot get much faster. Many
//! samples (identification, the GA's condition numbers, a trajectory's torques) are independent,
//! and the same code over four lanes fills the vector units instead (one AVX instruction per
//! operation).
//!
//! With AVX (x86-64 built with `target-cpu=native`, as `.cargo/config.toml` does) a pack is one
//! `__m256d` register and every operation one instruction: LLVM does not vectorise lane loops
//! over a plain `[f64; 4]` in kernels this long (it scalarises them: 4× the instructions).
//! Elsewhere the portable `[f64; 4]` form is used.
//!
//! The macro makes the lane copies from the generated f64 code by replacing the type `f64` with
//! a lane type `L` ([`Lane`]: [`Pack`] here), each float literal `c` with `L::splat(c)`, each
//! constant-zero output with [`store_zero`] and the trigonometry with `L::sin_cos` ([`sin_cos`]
//! for [`Pack`]: the same polynomial as [`crate::trig::sin_cos`], lane by lane); nothing else changes, so
//! every lane computes bit for bit what the straight-line scalar kernel computes for that sample
//! (the tests check equality, not closeness). A kernel with a compact scalar form (the Panda's
//! forward-dynamics derivatives, `codegen/FORMAT.md`) has its lanes equal its straight-line
//! (`_straight`) form, and its scalar method to rounding.
//!
//! Eight samples per call where the CPU has AVX-512: [`wide`] (the same generic lane copies,
//! instantiated for 512-bit registers and chosen at run time).
//!
//! Constant-zero outputs: a regressor's output is mostly zeros that do not depend on the sample
//! (the Panda regressor: 235 of 490; joint `i`'s torque does not see links before `i`). Writing
//! them costs the lane forms about one store each — at eight lanes a 64-byte store, about a cycle,
//! a third of the Panda regressor's time — so every lane form also exists without them
//! (`<kernel>_lanes_skip_zeros`, `<kernel>_lanes8_skip_zeros`; `Kernel::call_lanes_skip_zeros`,
//! `call_lanes8_skip_zeros`): those outputs keep what the buffer held, so a caller zeroes its
//! buffer once and then reuses it for the same kernel of the same model (another kernel's outputs
//! there would be left in place). The eight-lane form's four-lane fallback writes them anyway.
//!
//! Layout: structure of arrays. A kernel input `q: &[Pack; DOF]` has `q[j].0[l]` = joint `j`
//! of sample `l`; outputs likewise.
//!
//! ```
//! use dynid::pack::Pack;
//! let a = Pack::new([1.0, 2.0, 3.0, 4.0]);
//! let b = Pack::splat(0.5);
//! assert_eq!((a * b - a).to_array(), [-0.5, -1.0, -1.5, -2.0]);
//! ```

use std::ops::{Add, Div, Mul, Neg, Sub};

/// Samples per pack.
pub const LANES: usize = 4;

#[cfg(all(target_arch = "x86_64", target_feature = "avx"))]
mod imp {
    use std::arch::x86_64::{
        __m256d, _mm256_add_pd, _mm256_div_pd, _mm256_loadu_pd, _mm256_mul_pd, _mm256_set1_pd,
        _mm256_storeu_pd, _mm256_sub_pd, _mm256_xor_pd,
    };

    /// Four doubles in one AVX register.
    #[derive(Clone, Copy)]
    #[repr(transparent)]
    pub struct Pack(pub(crate) __m256d);

    // SAFETY (every `unsafe` below): this module is compiled only when AVX is enabled for the
    // whole crate (`cfg(target_feature = "avx")`), so the instructions exist; loads and stores go
    // through `[f64; 4]` references of the right size.
    #[allow(unused_unsafe)]
    impl Pack {
        #[inline(always)]
        pub fn splat(x: f64) -> Self {
            Pack(unsafe { _mm256_set1_pd(x) })
        }
        #[inline(always)]
        pub fn new(v: [f64; 4]) -> Self {
            Pack(unsafe { _mm256_loadu_pd(v.as_ptr()) })
        }
        #[inline(always)]
        pub fn to_array(self) -> [f64; 4] {
            let mut out = [0.0; 4];
            unsafe { _mm256_storeu_pd(out.as_mut_ptr(), self.0) };
            out
        }
        #[inline(always)]
        pub(super) fn add(self, b: Self) -> Self {
            Pack(unsafe { _mm256_add_pd(self.0, b.0) })
        }
        #[inline(always)]
        pub(super) fn sub(self, b: Self) -> Self {
            Pack(unsafe { _mm256_sub_pd(self.0, b.0) })
        }
        #[inline(always)]
        pub(super) fn mul(self, b: Self) -> Self {
            Pack(unsafe { _mm256_mul_pd(self.0, b.0) })
        }
        #[inline(always)]
        pub(super) fn div(self, b: Self) -> Self {
            Pack(unsafe { _mm256_div_pd(self.0, b.0) })
        }
        #[inline(always)]
        pub(super) fn neg(self) -> Self {
            // Flip the sign bit: exactly `-x` per lane (also for ±0 and NaN).
            Pack(unsafe { _mm256_xor_pd(self.0, _mm256_set1_pd(-0.0)) })
        }
        /// `self·b + c` lane by lane, [`crate::trig::mul_add`]'s value: one fused instruction
        /// where the target has FMA.
        #[inline(always)]
        pub(super) fn mul_add(self, b: Self, c: Self) -> Self {
            #[cfg(target_feature = "fma")]
            {
                Pack(unsafe { std::arch::x86_64::_mm256_fmadd_pd(self.0, b.0, c.0) })
            }
            #[cfg(not(target_feature = "fma"))]
            {
                let (a, b, c) = (self.to_array(), b.to_array(), c.to_array());
                Pack::new(std::array::from_fn(|l| {
                    crate::trig::mul_add(a[l], b[l], c[l])
                }))
            }
        }
    }
}

#[cfg(not(all(target_arch = "x86_64", target_feature = "avx")))]
mod imp {
    /// Four doubles (portable form).
    #[derive(Clone, Copy)]
    #[repr(C, align(32))]
    pub struct Pack([f64; 4]);

    impl Pack {
        #[inline(always)]
        pub fn splat(x: f64) -> Self {
            Pack([x; 4])
        }
        #[inline(always)]
        pub fn new(v: [f64; 4]) -> Self {
            Pack(v)
        }
        #[inline(always)]
        pub fn to_array(self) -> [f64; 4] {
            self.0
        }
        #[inline(always)]
        fn zip(self, b: Self, f: impl Fn(f64, f64) -> f64) -> Self {
            Pack(std::array::from_fn(|l| f(self.0[l], b.0[l])))
        }
        #[inline(always)]
        pub(super) fn add(self, b: Self) -> Self {
            self.zip(b, |x, y| x + y)
        }
        #[inline(always)]
        pub(super) fn sub(self, b: Self) -> Self {
            self.zip(b, |x, y| x - y)
        }
        #[inline(always)]
        pub(super) fn mul(self, b: Self) -> Self {
            self.zip(b, |x, y| x * y)
        }
        #[inline(always)]
        pub(super) fn div(self, b: Self) -> Self {
            self.zip(b, |x, y| x / y)
        }
        #[inline(always)]
        pub(super) fn neg(self) -> Self {
            Pack(self.0.map(|x| -x))
        }
        /// `self·b + c` lane by lane, [`crate::trig::mul_add`]'s value.
        #[inline(always)]
        pub(super) fn mul_add(self, b: Self, c: Self) -> Self {
            Pack(std::array::from_fn(|l| {
                crate::trig::mul_add(self.0[l], b.0[l], c.0[l])
            }))
        }
    }
}

pub use imp::Pack;

impl Default for Pack {
    fn default() -> Self {
        Pack::splat(0.0)
    }
}

impl std::fmt::Debug for Pack {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "Pack({:?})", self.to_array())
    }
}

impl PartialEq for Pack {
    fn eq(&self, other: &Self) -> bool {
        self.to_array() == other.to_array()
    }
}

macro_rules! forward {
    ($trait:ident, $method:ident) => {
        impl $trait for Pack {
            type Output = Self;
            #[inline(always)]
            fn $method(self, rhs: Self) -> Self {
                Pack::$method(self, rhs)
            }
        }
    };
}

forward!(Add, add);
forward!(Sub, sub);
forward!(Mul, mul);
forward!(Div, div);

impl Neg for Pack {
    type Output = Self;
    #[inline(always)]
    fn neg(self) -> Self {
        Pack::neg(self)
    }
}

/// A vector of samples the lane-batched kernels run on: the generated `<kernel>_lanes` functions
/// are generic over it (the macro's copy of the scalar body with `f64` → `P`, each float literal
/// `c` → `P::splat(c)` and `crate::trig::sin_cos` → `P::sin_cos`), instantiated for [`Pack`]
/// (four lanes) and, where the CPU has AVX-512, for eight lanes ([`wide`]). Every operation
/// must be the scalar one lane by lane, bit for bit.
pub trait Lane:
    Copy
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Div<Output = Self>
    + Neg<Output = Self>
{
    /// `x` in every lane.
    fn splat(x: f64) -> Self;
    /// `self·b + c` lane by lane, bit for bit [`crate::trig::mul_add`] of each lane (fused where
    /// the target has FMA): the generated kernels' fused multiply-adds.
    fn mul_add(self, b: Self, c: Self) -> Self;
    /// `(sin x, cos x)` lane by lane, bit for bit [`crate::trig::sin_cos`] of each lane.
    fn sin_cos(self) -> (Self, Self);
    /// [`Lane::sin_cos`] of four values (the lane form of [`crate::trig::sin_cos4`]: the lanes
    /// are full already, so four calls).
    #[inline(always)]
    fn sin_cos4(a: Self, b: Self, c: Self, d: Self) -> [(Self, Self); 4] {
        [a.sin_cos(), b.sin_cos(), c.sin_cos(), d.sin_cos()]
    }
    /// [`Lane::sin_cos`] of three values (the lane form of [`crate::trig::sin_cos3`]).
    #[inline(always)]
    fn sin_cos3(a: Self, b: Self, c: Self) -> [(Self, Self); 3] {
        [a.sin_cos(), b.sin_cos(), c.sin_cos()]
    }
    /// [`Lane::sin_cos`] of two values (the lane form of [`crate::trig::sin_cos2`]).
    #[inline(always)]
    fn sin_cos2(a: Self, b: Self) -> [(Self, Self); 2] {
        [a.sin_cos(), b.sin_cos()]
    }
    /// [`Lane::sin_cos`] of up to eight values (the lane form of [`crate::trig::sin_cos8`]).
    #[inline(always)]
    fn sin_cos8<const N: usize>(x: [Self; N]) -> [(Self, Self); N] {
        std::array::from_fn(|i| x[i].sin_cos())
    }
    /// `*dst = 0` in every lane (see [`store_zero`]): a plain store unless the type says
    /// otherwise.
    #[inline(always)]
    fn store_zero(dst: &mut Self) {
        *dst = Self::splat(0.0);
    }
}

impl Lane for Pack {
    #[inline(always)]
    fn splat(x: f64) -> Self {
        Pack::splat(x)
    }
    #[inline(always)]
    fn mul_add(self, b: Self, c: Self) -> Self {
        Pack::mul_add(self, b, c)
    }
    #[inline(always)]
    fn sin_cos(self) -> (Self, Self) {
        sin_cos(self)
    }
}

pub mod wide;

/// `*dst = 0` in every lane: how the lane copies write their constant-zero outputs
/// ([`Lane::store_zero`]). LLVM merges runs of constant-zero stores into a `memset` call, which
/// glibc serves with `rep stosb` from 2 KB on; the eight-lane form ([`wide`]) stores each zero on
/// its own instead (its regressors' zero runs reach that size: the Panda base regressor 1.4×
/// faster per sample; the four-lane kernels, measured alongside, kept the `memset`).
#[inline(always)]
pub fn store_zero<L: Lane>(dst: &mut L) {
    L::store_zero(dst);
}

/// `(sin x, cos x)` lane by lane: the generated kernels' `crate::trig::sin_cos`, batched, with
/// the same values bit for bit.
#[inline(always)]
pub fn sin_cos(x: Pack) -> (Pack, Pack) {
    #[cfg(dynid_avx)]
    if let Some((s, c)) = crate::trig::avx::sin_cos(x.0) {
        return (Pack(s), Pack(c));
    }
    sin_cos_slow(x)
}

#[cfg_attr(dynid_avx, cold, inline(never))]
fn sin_cos_slow(x: Pack) -> (Pack, Pack) {
    // Lane by lane through the scalar function (not `sin_cos_n` of all four, which sends every
    // lane to the standard library when one needs it): each lane equals the scalar kernel's.
    let sc = x.to_array().map(crate::trig::sin_cos);
    (Pack::new(sc.map(|v| v.0)), Pack::new(sc.map(|v| v.1)))
}

/// Gathers [`LANES`] samples (rows of `n` values, e.g. `q` of each sample) into `n` packs.
#[inline]
pub fn gather(rows: [&[f64]; LANES], out: &mut [Pack]) {
    for (j, p) in out.iter_mut().enumerate() {
        *p = Pack::new(std::array::from_fn(|l| rows[l][j]));
    }
}

/// Lane `l` of `packs` as one sample's row.
#[inline]
pub fn lane(packs: &[Pack], l: usize, out: &mut [f64]) {
    for (o, p) in out.iter_mut().zip(packs) {
        *o = p.to_array()[l];
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gather_then_lane_round_trips() {
        let rows: [[f64; 3]; 4] = [
            [1.0, 2.0, 3.0],
            [4.0, 5.0, 6.0],
            [7.0, 8.0, 9.0],
            [0.0, -1.0, -2.0],
        ];
        let mut packs = [Pack::default(); 3];
        gather([&rows[0], &rows[1], &rows[2], &rows[3]], &mut packs);
        assert_eq!(packs[1].to_array(), [2.0, 5.0, 8.0, -1.0]);
        let mut row = [0.0; 3];
        lane(&packs, 3, &mut row);
        assert_eq!(row, rows[3]);
    }

    #[test]
    fn operations_are_the_scalar_ones_lane_by_lane() {
        let a = [0.1, -2.5, 7.0, 0.0];
        let b = [3.0, 1e-300, -0.0, 2.0];
        let (pa, pb) = (Pack::new(a), Pack::new(b));
        for l in 0..4 {
            assert_eq!((pa + pb).to_array()[l], a[l] + b[l]);
            assert_eq!((pa - pb).to_array()[l], a[l] - b[l]);
            assert_eq!((pa * pb).to_array()[l], a[l] * b[l]);
            assert_eq!((pa / pb).to_array()[l].to_bits(), (a[l] / b[l]).to_bits());
            assert_eq!((-pb).to_array()[l].to_bits(), (-b[l]).to_bits());
            let fused = Lane::mul_add(pa, pb, -pa).to_array()[l];
            assert_eq!(
                fused.to_bits(),
                crate::trig::mul_add(a[l], b[l], -a[l]).to_bits()
            );
        }
    }

    /// `crate::trig::mul_add` (the kernels' fused multiply-add) rounds once where the target has
    /// FMA — (1 + 2⁻³⁰)(1 − 2⁻³⁰) − 1 is −2⁻⁶⁰ exactly, 0 when the product is rounded first — and
    /// the four-lane form gives the same value.
    #[test]
    fn mul_add_is_fused_where_the_target_has_fma() {
        let e = (-30f64).exp2();
        let (a, b) = (1.0 + e, 1.0 - e);
        let want = if cfg!(target_feature = "fma") {
            -(-60f64).exp2()
        } else {
            0.0
        };
        assert_eq!(crate::trig::mul_add(a, b, -1.0), want);
        let p = Lane::mul_add(Pack::splat(a), Pack::splat(b), Pack::splat(-1.0));
        assert_eq!(p.to_array(), [want; 4]);
    }

    /// Bit for bit the scalar kernels' values, on the fast path, near multiples of π/2 (the
    /// exact reduction), past the fast-path bound and for ±0, ±∞ and NaN.
    #[test]
    fn trig_lanes_equal_the_scalar_kernel_trig() {
        use std::f64::consts::{FRAC_PI_2, PI};
        let mut rng: u64 = 0x9E37_79B9_7F4A_7C15;
        let mut next = || {
            rng ^= rng << 13;
            rng ^= rng >> 7;
            rng ^= rng << 17;
            (rng >> 11) as f64 / (1u64 << 53) as f64
        };
        let mut cases: Vec<[f64; 4]> = (0..2000)
            .map(|_| std::array::from_fn(|_| (next() - 0.5) * 20.0))
            .collect();
        cases.push([PI, -FRAC_PI_2, 0.1, 0.2]);
        cases.push([0.0, -0.0, 1e-300, -5e-324]);
        cases.push([2.0e6, 1.0, f64::INFINITY, f64::NAN]);
        cases.push([0.7, 1.3, -2.9, 1.0e7]);
        cases.push([1.0e6, -1.0e6, 1e5 * PI, 3.0e5]);
        for x in cases {
            let (s, c) = sin_cos(Pack::new(x));
            let (s, c) = (s.to_array(), c.to_array());
            for (l, &xl) in x.iter().enumerate() {
                let (s0, c0) = crate::trig::sin_cos(xl);
                assert_eq!(
                    (s[l].to_bits(), c[l].to_bits()),
                    (s0.to_bits(), c0.to_bits()),
                    "x = {xl:e}"
                );
            }
        }
    }
}
