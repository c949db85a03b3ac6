//! The fast path of [`super::sin_cos_lanes`] on one AVX-512 register (eight lanes), the same
//! operations as [`super::avx::sin_cos`] (so bit for bit the same values): for the eight-lane
//! kernels of [`crate::pack::wide`]. Compiled wherever the crate has FMA, called only from
//! functions compiled with AVX-512F after the CPU was checked for it
//! (`crate::pack::wide::avx512`).

use super::*;
use std::arch::x86_64::*;

// Helpers as `#[inline(always)]` functions, not closures: a closure is a function of its own,
// without the caller's target features, and LLVM then leaves the AVX-512 intrinsics in it as
// calls in builds whose crate-wide features lack AVX-512 (seen: `_mm512_fmadd_pd` and
// `_mm512_set1_pd` out of line, the eight-lane kernels 3-6× slower).
#[inline(always)]
fn set(v: f64) -> __m512d {
    // SAFETY: see `sin_cos`'s contract; inlined into it.
    unsafe { _mm512_set1_pd(v) }
}

#[inline(always)]
fn bits(v: __m512d) -> __m512i {
    // SAFETY: a bit cast.
    unsafe { _mm512_castpd_si512(v) }
}

/// `(c0 + c1·z) + z²·(c2 + c3·z) + z⁴·(c4 + c5·z)` as [`super::kernel`] evaluates it.
#[inline(always)]
fn poly(z: __m512d, z2: __m512d, z4: __m512d, c: [f64; 6]) -> __m512d {
    // SAFETY: see `sin_cos`'s contract; inlined into it.
    unsafe {
        let a = _mm512_fmadd_pd(set(c[1]), z, set(c[0]));
        let b = _mm512_fmadd_pd(set(c[3]), z, set(c[2]));
        let c = _mm512_fmadd_pd(set(c[5]), z, set(c[4]));
        _mm512_fmadd_pd(z4, c, _mm512_fmadd_pd(z2, b, a))
    }
}

/// `(sin x, cos x)` of the eight lanes, or `None` when a lane needs the standard library or
/// the exact reduction (`|x| > FAST_PATH_MAX`, NaN, or more than 16 bits cancelled).
///
/// # Safety
/// The CPU must have AVX-512F (inlined into a function compiled with it).
#[inline(always)]
pub(crate) unsafe fn sin_cos(x: __m512d) -> Option<(__m512d, __m512d)> {
    // SAFETY: the caller guarantees AVX-512F; register operations only.
    unsafe {
        let sign = _mm512_set1_epi64(SIGN as i64);
        let ax = _mm512_castsi512_pd(_mm512_andnot_si512(sign, bits(x)));
        if _mm512_cmp_pd_mask::<_CMP_LE_OQ>(ax, set(FAST_PATH_MAX)) != 0xFF {
            return None;
        }
        let t = _mm512_fmadd_pd(ax, set(INV_PIO2), set(TOINT));
        let f = _mm512_sub_pd(t, set(TOINT));
        // mul_add(-f, PIO2_1, a): fnmadd rounds −(f·c) + a once, the same value.
        let r = _mm512_fnmadd_pd(f, set(PIO2_1), ax);
        let w = _mm512_mul_pd(f, set(PIO2_1T));
        let y0 = _mm512_sub_pd(r, w);
        let ay0 = _mm512_castsi512_pd(_mm512_andnot_si512(sign, bits(y0)));
        if _mm512_cmp_pd_mask::<_CMP_LT_OQ>(ay0, _mm512_mul_pd(ax, set(CANCEL_16))) != 0 {
            return None;
        }
        let y1 = _mm512_sub_pd(_mm512_sub_pd(r, y0), w);
        // kernel
        let z = _mm512_mul_pd(y0, y0);
        let z2 = _mm512_mul_pd(z, z);
        let z4 = _mm512_mul_pd(z2, z2);
        let p = poly(z, z2, z4, [S1, S2, S3, S4, S5, S6]);
        let q = poly(z, z2, z4, [C1, C2, C3, C4, C5, C6]);
        let v = _mm512_mul_pd(z, y0);
        let hz = _mm512_mul_pd(set(0.5), z);
        let tail = _mm512_fnmadd_pd(hz, y1, y1);
        let s = _mm512_add_pd(y0, _mm512_fmadd_pd(v, p, tail));
        let one_m_hz = _mm512_sub_pd(set(1.0), hz);
        let small = _mm512_fnmadd_pd(y0, y1, _mm512_sub_pd(_mm512_sub_pd(set(1.0), one_m_hz), hz));
        let c = _mm512_add_pd(one_m_hz, _mm512_fmadd_pd(z2, q, small));
        // quadrant
        let n = bits(t);
        let one = _mm512_set1_epi64(1);
        let two = _mm512_set1_epi64(2);
        let swap = _mm512_sub_epi64(_mm512_setzero_si512(), _mm512_and_si512(n, one));
        let (sb, cb) = (bits(s), bits(c));
        let s2 = _mm512_or_si512(_mm512_andnot_si512(swap, sb), _mm512_and_si512(cb, swap));
        let c2 = _mm512_or_si512(_mm512_andnot_si512(swap, cb), _mm512_and_si512(sb, swap));
        let s_sign = _mm512_xor_si512(
            _mm512_slli_epi64::<62>(_mm512_and_si512(n, two)),
            _mm512_and_si512(bits(x), sign),
        );
        let c_sign = _mm512_slli_epi64::<62>(_mm512_and_si512(_mm512_add_epi64(n, one), two));
        Some((
            _mm512_castsi512_pd(_mm512_xor_si512(s2, s_sign)),
            _mm512_castsi512_pd(_mm512_xor_si512(c2, c_sign)),
        ))
    }
}

/// [`super::sin_cos8`]'s eight-lane form: [`sin_cos`] on one register, the same operations as
/// every other form (so the same values, bit for bit); a value off the fast path sends all eight
/// through [`super::sin_cos`] one by one, out of line. Compiled wherever the crate has AVX-512F,
/// so `trig`'s `sin_cos8` test checks it on any such CPU whichever form [`super::sin_cos8`] uses.
#[cfg(target_feature = "avx512f")]
#[cfg_attr(not(dynid_zmm_trig), allow(dead_code))]
#[inline(always)]
pub(crate) fn sin_cos8(v: [f64; 8]) -> [(f64, f64); 8] {
    // SAFETY: the crate is compiled with AVX-512F (the `cfg` above); register operations.
    let fast = unsafe {
        sin_cos(_mm512_setr_pd(
            v[0], v[1], v[2], v[3], v[4], v[5], v[6], v[7],
        ))
    };
    let Some((s, c)) = fast else {
        return sin_cos8_each(v);
    };
    // SAFETY: a `__m512d` is eight `f64`s.
    let (s, c) = unsafe {
        (
            std::mem::transmute::<__m512d, [f64; 8]>(s),
            std::mem::transmute::<__m512d, [f64; 8]>(c),
        )
    };
    std::array::from_fn(|i| (s[i], c[i]))
}

#[cfg(target_feature = "avx512f")]
#[cfg_attr(not(dynid_zmm_trig), allow(dead_code))]
#[cold]
#[inline(never)]
fn sin_cos8_each(v: [f64; 8]) -> [(f64, f64); 8] {
    v.map(super::sin_cos)
}
