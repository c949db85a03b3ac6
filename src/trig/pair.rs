//! [`super::sin_cos`] of one value with the sine and the cosine in the two lanes of one SSE
//! register: one polynomial evaluation for both, and the quadrant's swap and signs as three
//! vector operations instead of a dozen on general registers; [`super::sin_cos2`] likewise, two
//! values in the four lanes of an AVX register. One or two values are what the kernels of a
//! one- or two-joint arm start with, and there the call's instruction count is the kernel's time
//! (planar2's mass matrix: about 100 instructions, 70 of them the sine/cosine).
//!
//! One value has its own form: [`sin_cos2`] with a zero beside it measured 5 % slower on the
//! planar2 mass matrix and 10 % on its inverse (the AVX form's lane spreads and interleaves).
//!
//! Every lane runs [`super::kernel`]'s and [`super::quadrant`]'s operations in their order, so
//! the values are those of a lane of [`super::sin_cos_n`], bit for bit (the module's tests check
//! it on every input class).

use super::*;
use std::arch::x86_64::*;

/// `[a, b]` as one register.
#[inline(always)]
fn pair(a: f64, b: f64) -> __m128d {
    // SAFETY: SSE2 is part of x86-64; register operations only.
    unsafe { _mm_setr_pd(a, b) }
}

/// `(sin x, cos x)`, or `None` when `x` needs the standard library or the exact reduction
/// (`|x| > FAST_PATH_MAX`, NaN, or more than 16 bits cancelled).
#[inline(always)]
pub(crate) fn sin_cos(x: f64) -> Option<(f64, f64)> {
    let ax = x.abs();
    // NaN fails the comparison too.
    let fast = ax <= FAST_PATH_MAX;
    if !fast {
        return None;
    }
    // The reduction, as `sin_cos_lanes_with` (scalar: one value).
    let t = mul_add(ax, INV_PIO2, TOINT);
    let f = t - TOINT;
    let r = mul_add(-f, PIO2_1, ax);
    let w = f * PIO2_1T;
    let y0 = r - w;
    if y0.abs() < ax * CANCEL_16 {
        return None;
    }
    let y1 = (r - y0) - w;
    let z = y0 * y0;
    let z2 = z * z;
    let z4 = z2 * z2;
    let v = z * y0;
    let hz = 0.5 * z;
    let tail = mul_add(-hz, y1, y1);
    let one_m_hz = 1.0 - hz;
    let small = mul_add(-y0, y1, (1.0 - one_m_hz) - hz);
    // SAFETY: SSE2 is part of x86-64 and the module is compiled only with FMA; register
    // operations only.
    unsafe {
        // Lane 0 the sine's polynomial p, lane 1 the cosine's q (`super::kernel`'s Estrin form).
        let (zv, z2v, z4v) = (_mm_set1_pd(z), _mm_set1_pd(z2), _mm_set1_pd(z4));
        let a = _mm_fmadd_pd(pair(S2, C2), zv, pair(S1, C1));
        let b = _mm_fmadd_pd(pair(S4, C4), zv, pair(S3, C3));
        let c = _mm_fmadd_pd(pair(S6, C6), zv, pair(S5, C5));
        let pq = _mm_fmadd_pd(z4v, c, _mm_fmadd_pd(z2v, b, a));
        // s = y0 + (v·p + tail), c = (1 − z/2) + (z²·q + small).
        let sc = _mm_add_pd(
            pair(y0, one_m_hz),
            _mm_fmadd_pd(pair(v, z2), pq, pair(tail, small)),
        );
        // Quadrant n = k mod 4 (`super::quadrant`): odd n swaps the lanes; the sine's sign is
        // bit 1 of n xor the sign of x, the cosine's bit 1 of n + 1.
        let n = _mm_castpd_si128(_mm_set1_pd(t));
        let odd = _mm_and_si128(n, _mm_set1_epi64x(1));
        // `_mm_permutevar_pd` takes lane i from bit 1 of control i: [n&1, 1 − n&1] · 2.
        let control = _mm_slli_epi64::<1>(_mm_xor_si128(odd, _mm_set_epi64x(1, 0)));
        let swapped = _mm_permutevar_pd(sc, control);
        let quarter = _mm_and_si128(_mm_add_epi64(n, _mm_set_epi64x(1, 0)), _mm_set1_epi64x(2));
        let x_sign = _mm_and_pd(_mm_set_sd(x), _mm_set_sd(-0.0));
        let signs = _mm_xor_pd(_mm_castsi128_pd(_mm_slli_epi64::<62>(quarter)), x_sign);
        let out = _mm_xor_pd(swapped, signs);
        Some((_mm_cvtsd_f64(out), _mm_cvtsd_f64(_mm_unpackhi_pd(out, out))))
    }
}

/// `[a, b]` as `[a, a, b, b]`.
#[inline(always)]
fn spread(u: __m128d) -> __m256d {
    // SAFETY: the module is compiled only with AVX2; register operations only.
    unsafe { _mm256_permute4x64_pd::<0b01_01_00_00>(_mm256_castpd128_pd256(u)) }
}

/// `[a₀, a₁]`, `[b₀, b₁]` as `[a₀, b₀, a₁, b₁]`.
#[inline(always)]
fn interleave(a: __m128d, b: __m128d) -> __m256d {
    // SAFETY: the module is compiled only with AVX2; register operations only.
    unsafe { _mm256_permute4x64_pd::<0b11_01_10_00>(_mm256_set_m128d(b, a)) }
}

/// `[(sin a, cos a), (sin b, cos b)]`: the reduction in the two lanes of an SSE register, then
/// both values' sines and cosines in the four lanes of one AVX register (one polynomial
/// evaluation where the four-lane form makes two, half of them on padding). `None` as
/// [`sin_cos`].
#[inline(always)]
pub(crate) fn sin_cos2(a: f64, b: f64) -> Option<[(f64, f64); 2]> {
    // SAFETY: the module is compiled only with AVX2 and FMA; register operations only.
    unsafe {
        let set = |v: f64| _mm_set1_pd(v);
        let x = _mm_setr_pd(a, b);
        let sign = set(-0.0);
        let ax = _mm_andnot_pd(sign, x);
        if _mm_movemask_pd(_mm_cmp_pd::<_CMP_LE_OQ>(ax, set(FAST_PATH_MAX))) != 0b11 {
            return None;
        }
        // The reduction and the kernel's scalar parts, as `super::avx::sin_cos` per lane.
        let t = _mm_fmadd_pd(ax, set(INV_PIO2), set(TOINT));
        let f = _mm_sub_pd(t, set(TOINT));
        let r = _mm_fnmadd_pd(f, set(PIO2_1), ax);
        let w = _mm_mul_pd(f, set(PIO2_1T));
        let y0 = _mm_sub_pd(r, w);
        let lost =
            _mm_cmp_pd::<_CMP_LT_OQ>(_mm_andnot_pd(sign, y0), _mm_mul_pd(ax, set(CANCEL_16)));
        if _mm_movemask_pd(lost) != 0 {
            return None;
        }
        let y1 = _mm_sub_pd(_mm_sub_pd(r, y0), w);
        let z = _mm_mul_pd(y0, y0);
        let z2 = _mm_mul_pd(z, z);
        let z4 = _mm_mul_pd(z2, z2);
        let v = _mm_mul_pd(z, y0);
        let hz = _mm_mul_pd(set(0.5), z);
        let tail = _mm_fnmadd_pd(hz, y1, y1);
        let one_m_hz = _mm_sub_pd(set(1.0), hz);
        let small = _mm_fnmadd_pd(y0, y1, _mm_sub_pd(_mm_sub_pd(set(1.0), one_m_hz), hz));
        // Lanes [sin a, cos a, sin b, cos b]: p in the sine lanes, q in the cosine lanes.
        let (zv, z2v, z4v) = (spread(z), spread(z2), spread(z4));
        let c = |s: f64, c: f64| _mm256_setr_pd(s, c, s, c);
        let pa = _mm256_fmadd_pd(c(S2, C2), zv, c(S1, C1));
        let pb = _mm256_fmadd_pd(c(S4, C4), zv, c(S3, C3));
        let pc = _mm256_fmadd_pd(c(S6, C6), zv, c(S5, C5));
        let pq = _mm256_fmadd_pd(z4v, pc, _mm256_fmadd_pd(z2v, pb, pa));
        let sc = _mm256_add_pd(
            interleave(y0, one_m_hz),
            _mm256_fmadd_pd(interleave(v, z2), pq, interleave(tail, small)),
        );
        // Quadrants as in `sin_cos` above, each value's in its two lanes.
        let n = _mm256_castpd_si256(spread(t));
        let lane = _mm256_setr_epi64x(0, 1, 0, 1);
        let odd = _mm256_and_si256(n, _mm256_set1_epi64x(1));
        let control = _mm256_slli_epi64::<1>(_mm256_xor_si256(odd, lane));
        let swapped = _mm256_permutevar_pd(sc, control);
        let quarter = _mm256_and_si256(_mm256_add_epi64(n, lane), _mm256_set1_epi64x(2));
        let x_sign = _mm256_and_pd(spread(x), _mm256_setr_pd(-0.0, 0.0, -0.0, 0.0));
        let signs = _mm256_xor_pd(
            _mm256_castsi256_pd(_mm256_slli_epi64::<62>(quarter)),
            x_sign,
        );
        let out = _mm256_xor_pd(swapped, signs);
        let [s0, c0, s1, c1] = std::mem::transmute::<__m256d, [f64; 4]>(out);
        Some([(s0, c0), (s1, c1)])
    }
}
