//! Trigonometry for the generated kernels: [`sin_cos8`] (five to eight joints at once),
//! [`sin_cos4`] (four joints at once, then [`sin_cos3`], [`sin_cos2`] or [`sin_cos`] for the rest), [`sin_cos_n`] (any number
//! at once) and [`sin_cos`].
//!
//! Every generated kernel starts with the sines and cosines of its revolute joints, and
//! everything else depends on them, so their *latency* is paid once per call: the kernel bodies
//! are longer than the CPU's reorder window, so one call's trigonometry cannot overlap the previous
//! call's arithmetic. The standard library's `f64::sin_cos` is two out-of-line libm calls per
//! joint. This module computes all joints together, inlined, in vector lanes, with a short
//! dependency chain (about 57 cycles for one lane, against about 80 for fdlibm's Horner form with
//! its three-step reduction; still about a quarter of a 100 ns PUMA 560 kernel call).
//!
//! Algorithm (fdlibm/musl `__rem_pio2` "medium" case and `__kernel_sin`/`__kernel_cos`
//! coefficients):
//! - `k = round(|x|·2/π)` with the `1.5·2⁵²` rounding trick (no SSE4.1 needed), and
//!   `|x| − k·π/2 = y0 + y1` (a double-double) by Cody–Waite subtraction of a 33+53-bit π/2: good
//!   to 85 bits, every `k·π/2` piece exact because `k < 2²⁰`.
//! - If more than 16 bits cancelled in any lane (`|x|` within about `2⁻¹⁶·|x|` of a multiple of
//!   π/2, e.g. `x = fl(π)`), the whole call takes the out-of-line exact path: fdlibm's second
//!   (118-bit) and third (151-bit) steps, so `sin(fl(π))` still has full relative precision.
//! - Minimax polynomials on `[−π/4, π/4]` (degree 13 for sin, 14 for cos) in Estrin form, with
//!   the first-order correction for the tail `y1`; fused multiply-adds where the target has FMA.
//! - Quadrant `k mod 4` selects and negates the pair branch-free; the sign of `x` goes to the sine.
//!
//! Domain: the fast path covers `|x| ≤ ` [`FAST_PATH_MAX`] (10⁶ rad, far beyond any joint angle);
//! larger magnitudes, infinities and NaN fall back to the standard library (out of line).
//!
//! Accuracy: about 1 ulp of the exact values; the tests check ≤ 2 ulp against `f64::sin`/`cos`
//! (glibc) on random inputs over several ranges and on every bit pattern class, on the doubles
//! nearest to every multiple of π/4 up to the bound, on ±0 (sign kept), subnormals, the bound
//! itself, huge values, infinities and NaN; the largest difference observed is 1 ulp.
//!
//! ```
//! let (s, c) = dynid::trig::sin_cos_n(&[0.5, -2.0]);
//! assert!((s[0] - 0.5f64.sin()).abs() <= f64::EPSILON && (c[1] - 2.0f64.cos()).abs() <= f64::EPSILON);
//! assert_eq!(dynid::trig::sin_cos(0.5), (s[0], c[0]));
//! ```

/// Largest `|x|` handled by the inlined fast path; beyond it the standard library is called.
pub const FAST_PATH_MAX: f64 = 1.0e6;

/// Elements [`sin_cos_n`] evaluates together (one AVX2 register of `f64`).
pub const LANES: usize = 4;

// `1.5·2⁵²`: adding and subtracting it rounds a double below 2⁵¹ to the nearest integer, and the
// low bits of the sum's representation are that integer (two's complement).
const TOINT: f64 = 6_755_399_441_055_744.0;
const INV_PIO2: f64 = std::f64::consts::FRAC_2_PI;
// π/2 split into 33-bit pieces (each `k·PIO2_n` is exact for k < 2²⁰) and their tails. All
// constants are fdlibm's (shortest decimals of the bit patterns in the comments).
const PIO2_1: f64 = 1.5707963267341256; // fdlibm 0x3FF921FB54400000
const PIO2_1T: f64 = 6.077100506506192e-11; // fdlibm 0x3DD0B4611A626331
const PIO2_2: f64 = 6.077100506303966e-11; // fdlibm 0x3DD0B4611A600000
const PIO2_2T: f64 = 2.0222662487959506e-21; // fdlibm 0x3BA3198A2E037073
const PIO2_3: f64 = 2.0222662487111665e-21; // fdlibm 0x3BA3198A2E000000
const PIO2_3T: f64 = 8.4784276603689e-32; // fdlibm 0x397B839A252049C1
/// `2⁻¹⁶`: a reduced argument smaller than this fraction of `|x|` lost more than 16 bits.
const CANCEL_16: f64 = 1.0 / 65_536.0;

// sin(x) ≈ x + x³·(S1 + S2·x² + … + S6·x¹⁰) on [−π/4, π/4] (fdlibm k_sin.c).
const S1: f64 = -0.16666666666666632; // fdlibm 0xBFC5555555555549
const S2: f64 = 0.00833333333332249; // fdlibm 0x3F8111111110F8A6
const S3: f64 = -0.0001984126982985795; // fdlibm 0xBF2A01A019C161D5
const S4: f64 = 2.7557313707070068e-06; // fdlibm 0x3EC71DE357B1FE7D
const S5: f64 = -2.5050760253406863e-08; // fdlibm 0xBE5AE5E68A2B9CEB
const S6: f64 = 1.58969099521155e-10; // fdlibm 0x3DE5D93A5ACFD57C
                                      // cos(x) ≈ 1 − x²/2 + x⁴·(C1 + C2·x² + … + C6·x¹⁰) on [−π/4, π/4] (fdlibm k_cos.c).
const C1: f64 = 0.0416666666666666; // fdlibm 0x3FA555555555554C
const C2: f64 = -0.001388888888887411; // fdlibm 0xBF56C16C16C15177
const C3: f64 = 2.480158728947673e-05; // fdlibm 0x3EFA01A019CB1590
const C4: f64 = -2.7557314351390663e-07; // fdlibm 0xBE927E4F809C52AD
const C5: f64 = 2.087572321298175e-09; // fdlibm 0x3E21EE9EBDB4B1C4
const C6: f64 = -1.1359647557788195e-11; // fdlibm 0xBDA8FAE9BE8838D4

const SIGN: u64 = 1 << 63;

/// `(sin x, cos x)` (see the module docs; the same values as a lane of [`sin_cos_n`]).
#[inline(always)]
pub fn sin_cos(x: f64) -> (f64, f64) {
    // `sin_cos_n(&[x])` in effect, but the rare paths take `x` by value, in a register: passing
    // them an array (or a reference) made every call store `x` to the stack first, in the hot
    // path — six times per PUMA 560 kernel.
    #[cfg(dynid_avx)]
    {
        // Both values in one register's two lanes (`pair`): the same values, fewer instructions.
        match pair::sin_cos(x) {
            Some(sc) => sc,
            None => sin_cos_rare_one(x),
        }
    }
    #[cfg(not(dynid_avx))]
    {
        // NaN fails the comparison too.
        let fast = x.abs() <= FAST_PATH_MAX;
        if !fast {
            return sin_cos_std_one(x);
        }
        let (s, c) = sin_cos_lanes_with([x, 0.0, 0.0, 0.0], || {
            let (s, c) = sin_cos_exact_one(x);
            ([s, 0.0, 0.0, 0.0], [c, 0.0, 0.0, 0.0])
        });
        (s[0], c[0])
    }
}

/// [`sin_cos`] of four values from one evaluation of the four-lane polynomial: the same values
/// as four calls, bit for bit (a value the fast path does not cover sends all four through
/// [`sin_cos`] one by one, out of line).
#[inline(always)]
pub fn sin_cos4(a: f64, b: f64, c: f64, d: f64) -> [(f64, f64); 4] {
    // With AVX2, the register form: the array form's fallback closure kept its captures on the
    // stack in the hot path, and LLVM assembled its quadrant step from lane permutations (a third
    // of a 2-DOF kernel's instructions).
    #[cfg(dynid_avx)]
    {
        use std::arch::x86_64::{__m256d, _mm256_setr_pd};
        // SAFETY: the crate is compiled with AVX (the `cfg` above); register operations.
        let Some((s, co)) = avx::sin_cos(unsafe { _mm256_setr_pd(a, b, c, d) }) else {
            return sin_cos4_each(a, b, c, d);
        };
        // SAFETY: a `__m256d` is four `f64`s.
        let [s, co] = unsafe { std::mem::transmute::<[__m256d; 2], [[f64; 4]; 2]>([s, co]) };
        [(s[0], co[0]), (s[1], co[1]), (s[2], co[2]), (s[3], co[3])]
    }
    #[cfg(not(dynid_avx))]
    {
        let fast = (a.abs() <= FAST_PATH_MAX)
            & (b.abs() <= FAST_PATH_MAX)
            & (c.abs() <= FAST_PATH_MAX)
            & (d.abs() <= FAST_PATH_MAX);
        if !fast {
            return sin_cos4_each(a, b, c, d);
        }
        let (s, co) = sin_cos_lanes_with([a, b, c, d], || {
            let e = sin_cos4_each(a, b, c, d);
            (e.map(|p| p.0), e.map(|p| p.1))
        });
        [(s[0], co[0]), (s[1], co[1]), (s[2], co[2]), (s[3], co[3])]
    }
}

/// [`sin_cos`] of three values from one evaluation of the four-lane polynomial ([`sin_cos4`]
/// with a zero in the spare lane, which changes no other lane).
#[inline(always)]
pub fn sin_cos3(a: f64, b: f64, c: f64) -> [(f64, f64); 3] {
    let [x, y, z, _] = sin_cos4(a, b, c, 0.0);
    [x, y, z]
}

/// [`sin_cos`] of two values from one evaluation of the four-lane polynomial (see [`sin_cos3`]).
#[inline(always)]
pub fn sin_cos2(a: f64, b: f64) -> [(f64, f64); 2] {
    #[cfg(dynid_avx)]
    {
        // Both values' sines and cosines in one register (`pair`): the same values.
        match pair::sin_cos2(a, b) {
            Some(v) => v,
            None => {
                let [x, y, _, _] = sin_cos4_each(a, b, 0.0, 0.0);
                [x, y]
            }
        }
    }
    #[cfg(not(dynid_avx))]
    {
        let [x, y, _, _] = sin_cos4(a, b, 0.0, 0.0);
        [x, y]
    }
}

/// [`sin_cos`] of up to eight values (`N ≤ 8`), bit for bit one call each: two [`sin_cos4`], or
/// one eight-lane (AVX-512) evaluation (`avx512::sin_cos8`) where the build chose it
/// (`cfg(dynid_zmm_trig)`, set by build.rs for an AMD CPU with AVX-512 building for itself).
///
/// The eight-lane form is a quarter fewer instructions, and on an AMD EPYC (Zen 4) it made the
/// Panda's kernels 1.09–1.5× faster. On Intel cores a 512-bit instruction in flight shuts one of
/// the vector ports for everything else, and the rest of a kernel is scalar floating point: on a
/// Rocket Lake Xeon it made the PUMA 560 kernels 1.4–1.7× slower (inverse dynamics 99 against
/// 59 ns per call). Hence a build-time choice: choosing by CPU at run time inside the inlined
/// kernels does not work, LLVM assembles the eight values in a 512-bit register before the
/// branch (PUMA 560 gravity 20 → 51 ns on Intel).
#[inline(always)]
pub fn sin_cos8<const N: usize>(x: [f64; N]) -> [(f64, f64); N] {
    const { assert!(N <= 8) };
    // Element by element: the lanes are assembled in registers (see `sin_cos_n`).
    let v: [f64; 8] = std::array::from_fn(|i| if i < N { x[i] } else { 0.0 });
    #[cfg(dynid_zmm_trig)]
    let all = avx512::sin_cos8(v);
    #[cfg(not(dynid_zmm_trig))]
    let all = {
        let lo = sin_cos4(v[0], v[1], v[2], v[3]);
        let hi = sin_cos4(v[4], v[5], v[6], v[7]);
        std::array::from_fn::<_, 8, _>(|i| if i < 4 { lo[i] } else { hi[i - 4] })
    };
    std::array::from_fn(|i| all[i])
}

#[cold]
#[inline(never)]
fn sin_cos4_each(a: f64, b: f64, c: f64, d: f64) -> [(f64, f64); 4] {
    [a, b, c, d].map(sin_cos)
}

#[cold]
#[inline(never)]
fn sin_cos_std_one(x: f64) -> (f64, f64) {
    (x.sin(), x.cos())
}

/// [`sin_cos`] off the two-lane fast path: the standard library beyond [`FAST_PATH_MAX`] (and for
/// NaN), else the exact reduction.
#[cfg(dynid_avx)]
#[cold]
#[inline(never)]
fn sin_cos_rare_one(x: f64) -> (f64, f64) {
    if x.abs() <= FAST_PATH_MAX {
        sin_cos_exact_one(x)
    } else {
        sin_cos_std_one(x)
    }
}

#[cold]
#[inline(never)]
fn sin_cos_exact_one(x: f64) -> (f64, f64) {
    let (s, c) = sin_cos_lanes_exact([x, 0.0, 0.0, 0.0]);
    (s[0], c[0])
}

/// `(sin x[i], cos x[i])` for all `i` at once (the kernels call [`sin_cos4`], whose values are
/// [`sin_cos`]'s whatever the other lanes hold; here one element off the fast path sends all).
///
/// The joints are evaluated in groups of [`LANES`] that the compiler vectorises (SSE2: 2 per
/// instruction, AVX2: 4). If any `|x[i]|` exceeds [`FAST_PATH_MAX`] or is NaN, every element goes
/// through the standard library.
#[inline(always)]
pub fn sin_cos_n<const N: usize>(x: &[f64; N]) -> ([f64; N], [f64; N]) {
    let mut s = [0.0; N];
    let mut c = [0.0; N];
    // `fold` with `&` (not `all`): no early exit, so the test itself is branch-free.
    if !x.iter().fold(true, |ok, v| ok & (v.abs() <= FAST_PATH_MAX)) {
        return sin_cos_std(x);
    }
    let mut i = 0;
    while i < N {
        // Element by element (not `copy_from_slice`): the lanes are then assembled in registers
        // instead of through a stack copy (scalar stores then a vector load, which stalls).
        let lane: Lanes = std::array::from_fn(|l| if i + l < N { x[i + l] } else { 0.0 });
        let (ls, lc) = sin_cos_lanes(lane);
        // Element by element here too: in the PUMA 560 kernels a slice copy or an iterator
        // costs up to 25 ns more per call (the lanes go through the stack).
        #[allow(clippy::manual_memcpy)]
        for l in 0..LANES.min(N - i) {
            s[i + l] = ls[l];
            c[i + l] = lc[l];
        }
        i += LANES;
    }
    (s, c)
}

#[cold]
#[inline(never)]
fn sin_cos_std<const N: usize>(x: &[f64; N]) -> ([f64; N], [f64; N]) {
    (x.map(f64::sin), x.map(f64::cos))
}

/// `a·b + c`: fused (one rounding, one instruction) where the target has FMA; otherwise two
/// operations — never the slow software `fma` of a target without it.
#[inline(always)]
pub fn mul_add(a: f64, b: f64, c: f64) -> f64 {
    #[cfg(target_feature = "fma")]
    {
        a.mul_add(b, c)
    }
    #[cfg(not(target_feature = "fma"))]
    {
        a * b + c
    }
}

type Lanes = [f64; LANES];

/// `f` on every lane: one vector operation per use after vectorisation.
#[inline(always)]
fn map2(a: &Lanes, b: &Lanes, f: impl Fn(f64, f64) -> f64) -> Lanes {
    let mut o = [0.0; LANES];
    for l in 0..LANES {
        o[l] = f(a[l], b[l]);
    }
    o
}

/// One group of lanes, all on the fast path (`|x| ≤ FAST_PATH_MAX`). Written statement by
/// statement over whole arrays so that every step is one vector instruction.
#[inline(always)]
fn sin_cos_lanes(x: Lanes) -> (Lanes, Lanes) {
    sin_cos_lanes_with(x, || sin_cos_lanes_exact(x))
}

/// [`sin_cos_lanes`], with `exact` (which must equal [`sin_cos_lanes_exact`]`(x)`) called when
/// a lane lost more than 16 bits.
#[inline(always)]
fn sin_cos_lanes_with(x: Lanes, exact: impl FnOnce() -> (Lanes, Lanes)) -> (Lanes, Lanes) {
    let ax = x.map(f64::abs);
    let t = ax.map(|a| mul_add(a, INV_PIO2, TOINT));
    let f = t.map(|t| t - TOINT);
    // First Cody–Waite step (85 bits); r is exact.
    let r = map2(&ax, &f, |a, f| mul_add(-f, PIO2_1, a));
    let w = f.map(|f| f * PIO2_1T);
    let y0 = map2(&r, &w, |r, w| r - w);
    let mut cancelled = false;
    for l in 0..LANES {
        cancelled |= y0[l].abs() < ax[l] * CANCEL_16;
    }
    if cancelled {
        return exact();
    }
    let y1 = {
        let d = map2(&r, &y0, |r, y| r - y);
        map2(&d, &w, |d, w| d - w)
    };
    let (s, c) = kernel(&y0, &y1);
    quadrant(&x, &t, &s, &c)
}

/// [`sin_cos_lanes`] with fdlibm's second and third reduction steps: for arguments within
/// about `2⁻¹⁶·|x|` of a multiple of π/2 (rare; out of line).
#[cold]
#[inline(never)]
fn sin_cos_lanes_exact(x: Lanes) -> (Lanes, Lanes) {
    let mut y0 = [0.0; LANES];
    let mut y1 = [0.0; LANES];
    let mut t = [0.0; LANES];
    for l in 0..LANES {
        let ax = x[l].abs();
        t[l] = ax * INV_PIO2 + TOINT;
        let f = t[l] - TOINT;
        let mut r = ax - f * PIO2_1;
        let mut w = f * PIO2_1T;
        let mut y = r - w;
        if y.abs() < ax * CANCEL_16 {
            let u = r;
            w = f * PIO2_2;
            r = u - w;
            w = f * PIO2_2T - ((u - r) - w);
            y = r - w;
            if y.abs() < ax * (1.0 / 562_949_953_421_312.0) {
                // more than 49 bits cancelled
                let u = r;
                w = f * PIO2_3;
                r = u - w;
                w = f * PIO2_3T - ((u - r) - w);
                y = r - w;
            }
        }
        y0[l] = y;
        y1[l] = (r - y) - w;
    }
    let (s, c) = kernel(&y0, &y1);
    quadrant(&x, &t, &s, &c)
}

/// sin and cos of `y0 + y1`, `|y0| ≤ π/4` (about), `|y1| ≤ ulp(y0)/2`, in Estrin form:
/// `sin = y0 + (v·p(z) + y1·(1 − z/2))` with `v = y0³`, and
/// `cos = (1 − z/2) + ((((1 − (1 − z/2)) − z/2) − y0·y1) + z²·q(z))`, where the first bracket
/// recovers the rounding error of `1 − z/2` (fdlibm's summation).
#[inline(always)]
fn kernel(y0: &Lanes, y1: &Lanes) -> (Lanes, Lanes) {
    let z = map2(y0, y0, |a, b| a * b);
    let z2 = map2(&z, &z, |a, b| a * b);
    let z4 = map2(&z2, &z2, |a, b| a * b);
    let poly = |c0: f64, c1: f64, c2: f64, c3: f64, c4: f64, c5: f64| {
        let mut p = [0.0; LANES];
        for l in 0..LANES {
            let (a, b, c) = (
                mul_add(c1, z[l], c0),
                mul_add(c3, z[l], c2),
                mul_add(c5, z[l], c4),
            );
            p[l] = mul_add(z4[l], c, mul_add(z2[l], b, a));
        }
        p
    };
    let p = poly(S1, S2, S3, S4, S5, S6);
    let q = poly(C1, C2, C3, C4, C5, C6);
    let mut s = [0.0; LANES];
    let mut c = [0.0; LANES];
    for l in 0..LANES {
        let (x, y, z) = (y0[l], y1[l], z[l]);
        let v = z * x;
        let hz = 0.5 * z;
        let tail = mul_add(-hz, y, y);
        s[l] = x + mul_add(v, p[l], tail);
        let one_m_hz = 1.0 - hz;
        let small = mul_add(-x, y, (1.0 - one_m_hz) - hz);
        c[l] = one_m_hz + mul_add(z2[l], q[l], small);
    }
    (s, c)
}

/// Quadrant `n = k mod 4` (low bits of `t`): `(sin, cos)` of `|x|` is `(s, c)`, `(c, −s)`,
/// `(−s, −c)`, `(−c, s)` for n = 0, 1, 2, 3; then the sign of `x` goes to the sine.
#[inline(always)]
fn quadrant(x: &Lanes, t: &Lanes, s: &Lanes, c: &Lanes) -> (Lanes, Lanes) {
    let mut so = [0.0; LANES];
    let mut co = [0.0; LANES];
    for l in 0..LANES {
        let n = t[l].to_bits();
        let swap = 0u64.wrapping_sub(n & 1); // all ones in odd quadrants
        let (sb, cb) = (s[l].to_bits(), c[l].to_bits());
        let s2 = (sb & !swap) | (cb & swap);
        let c2 = (cb & !swap) | (sb & swap);
        let s_sign = ((n & 2) << 62) ^ (x[l].to_bits() & SIGN);
        let c_sign = (n.wrapping_add(1) & 2) << 62;
        so[l] = f64::from_bits(s2 ^ s_sign);
        co[l] = f64::from_bits(c2 ^ c_sign);
    }
    (so, co)
}

/// The fast path of [`sin_cos_lanes`] on one AVX register, instruction for instruction the same
/// operations (so bit for bit the same values): for the lane-batched kernels of
/// [`crate::pack`], where LLVM does not vectorise the array form inside a long kernel.
#[cfg(dynid_avx)]
pub(crate) mod avx {
    use super::*;
    use std::arch::x86_64::*;

    /// `(sin x, cos x)` of the four lanes, or `None` when a lane needs the standard library or
    /// the exact reduction (`|x| > FAST_PATH_MAX`, NaN, or more than 16 bits cancelled).
    #[inline(always)]
    #[allow(unused_unsafe)]
    pub(crate) fn sin_cos(x: __m256d) -> Option<(__m256d, __m256d)> {
        // SAFETY: compiled only with AVX2 and FMA enabled for the crate; register operations only.
        unsafe {
            let set = |v: f64| _mm256_set1_pd(v);
            let sign = set(-0.0);
            let ax = _mm256_andnot_pd(sign, x);
            if _mm256_movemask_pd(_mm256_cmp_pd(ax, set(FAST_PATH_MAX), _CMP_LE_OQ)) != 0xF {
                return None;
            }
            let t = _mm256_fmadd_pd(ax, set(INV_PIO2), set(TOINT));
            let f = _mm256_sub_pd(t, set(TOINT));
            // mul_add(-f, PIO2_1, a): fnmadd rounds −(f·c) + a once, the same value.
            let r = _mm256_fnmadd_pd(f, set(PIO2_1), ax);
            let w = _mm256_mul_pd(f, set(PIO2_1T));
            let y0 = _mm256_sub_pd(r, w);
            let lost = _mm256_cmp_pd(
                _mm256_andnot_pd(sign, y0),
                _mm256_mul_pd(ax, set(CANCEL_16)),
                _CMP_LT_OQ,
            );
            if _mm256_movemask_pd(lost) != 0 {
                return None;
            }
            let y1 = _mm256_sub_pd(_mm256_sub_pd(r, y0), w);
            // kernel
            let z = _mm256_mul_pd(y0, y0);
            let z2 = _mm256_mul_pd(z, z);
            let z4 = _mm256_mul_pd(z2, z2);
            let poly = |c0: f64, c1: f64, c2: f64, c3: f64, c4: f64, c5: f64| {
                let a = _mm256_fmadd_pd(set(c1), z, set(c0));
                let b = _mm256_fmadd_pd(set(c3), z, set(c2));
                let c = _mm256_fmadd_pd(set(c5), z, set(c4));
                _mm256_fmadd_pd(z4, c, _mm256_fmadd_pd(z2, b, a))
            };
            let p = poly(S1, S2, S3, S4, S5, S6);
            let q = poly(C1, C2, C3, C4, C5, C6);
            let v = _mm256_mul_pd(z, y0);
            let hz = _mm256_mul_pd(set(0.5), z);
            let tail = _mm256_fnmadd_pd(hz, y1, y1);
            let s = _mm256_add_pd(y0, _mm256_fmadd_pd(v, p, tail));
            let one_m_hz = _mm256_sub_pd(set(1.0), hz);
            let small =
                _mm256_fnmadd_pd(y0, y1, _mm256_sub_pd(_mm256_sub_pd(set(1.0), one_m_hz), hz));
            let c = _mm256_add_pd(one_m_hz, _mm256_fmadd_pd(z2, q, small));
            // quadrant
            let n = _mm256_castpd_si256(t);
            let one = _mm256_set1_epi64x(1);
            let two = _mm256_set1_epi64x(2);
            let swap = _mm256_sub_epi64(_mm256_setzero_si256(), _mm256_and_si256(n, one));
            let (sb, cb) = (_mm256_castpd_si256(s), _mm256_castpd_si256(c));
            let s2 = _mm256_or_si256(_mm256_andnot_si256(swap, sb), _mm256_and_si256(cb, swap));
            let c2 = _mm256_or_si256(_mm256_andnot_si256(swap, cb), _mm256_and_si256(sb, swap));
            let s_sign = _mm256_xor_si256(
                _mm256_slli_epi64::<62>(_mm256_and_si256(n, two)),
                _mm256_and_si256(_mm256_castpd_si256(x), _mm256_castpd_si256(sign)),
            );
            let c_sign = _mm256_slli_epi64::<62>(_mm256_and_si256(_mm256_add_epi64(n, one), two));
            Some((
                _mm256_castsi256_pd(_mm256_xor_si256(s2, s_sign)),
                _mm256_castsi256_pd(_mm256_xor_si256(c2, c_sign)),
            ))
        }
    }
}

#[cfg(all(target_arch = "x86_64", target_feature = "fma"))]
pub(crate) mod avx512;
#[cfg(dynid_avx)]
mod pair;

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;
    use std::f64::consts::{FRAC_PI_2, FRAC_PI_4, PI};

    /// Monotone integer image of a double: adjacent doubles differ by 1, and ±0 both map to 0.
    fn ordinal(x: f64) -> i64 {
        let b = x.to_bits() as i64;
        if b < 0 {
            -(b & i64::MAX)
        } else {
            b
        }
    }

    /// Distance in units in the last place between two finite doubles (u64::MAX if either is not
    /// finite and they are not identical NaN/inf classes).
    fn ulps(a: f64, b: f64) -> u64 {
        if a.is_nan() || b.is_nan() {
            return if a.is_nan() && b.is_nan() {
                0
            } else {
                u64::MAX
            };
        }
        ordinal(a).abs_diff(ordinal(b))
    }

    /// Both implementations ([`sin_cos`] and one lane of [`sin_cos_n`]) within `tol` ulp of std.
    fn check(x: f64, tol: u64) {
        let (s0, c0) = (x.sin(), x.cos());
        let (sn, cn) = sin_cos_n(&[0.5, x, -1.0]);
        // The scalar path is a lane of the vector one, bit for bit (its rare paths are entered
        // apart: `sin_cos_std_one`, `sin_cos_exact_one`).
        let (s1, c1) = sin_cos(x);
        assert!(
            s1.to_bits() == sn[1].to_bits() && c1.to_bits() == cn[1].to_bits(),
            "sin_cos({x:e}) = ({s1:e}, {c1:e}), a lane of sin_cos_n ({:e}, {:e})",
            sn[1],
            cn[1]
        );
        for (what, (s, c)) in [("sin_cos", (s1, c1)), ("sin_cos_n", (sn[1], cn[1]))] {
            assert!(
                ulps(s, s0) <= tol,
                "{what}: sin({x:e}) = {s:e}, std {s0:e}, {} ulp",
                ulps(s, s0)
            );
            assert!(
                ulps(c, c0) <= tol,
                "{what}: cos({x:e}) = {c:e}, std {c0:e}, {} ulp",
                ulps(c, c0)
            );
        }
    }

    fn next_up(x: f64) -> f64 {
        f64::from_bits(if x >= 0.0 {
            x.to_bits() + 1
        } else {
            x.to_bits() - 1
        })
    }

    fn next_down(x: f64) -> f64 {
        -next_up(-x)
    }

    #[test]
    fn constants_are_fdlibms_bit_for_bit() {
        for (value, bits) in [
            (PIO2_1, 0x3FF921FB_54400000u64),
            (PIO2_1T, 0x3DD0B461_1A626331u64),
            (PIO2_2, 0x3DD0B461_1A600000u64),
            (PIO2_2T, 0x3BA3198A_2E037073u64),
            (PIO2_3, 0x3BA3198A_2E000000u64),
            (PIO2_3T, 0x397B839A_252049C1u64),
            (S1, 0xBFC55555_55555549u64),
            (S2, 0x3F811111_1110F8A6u64),
            (S3, 0xBF2A01A0_19C161D5u64),
            (S4, 0x3EC71DE3_57B1FE7Du64),
            (S5, 0xBE5AE5E6_8A2B9CEBu64),
            (S6, 0x3DE5D93A_5ACFD57Cu64),
            (C1, 0x3FA55555_5555554Cu64),
            (C2, 0xBF56C16C_16C15177u64),
            (C3, 0x3EFA01A0_19CB1590u64),
            (C4, 0xBE927E4F_809C52ADu64),
            (C5, 0x3E21EE9E_BDB4B1C4u64),
            (C6, 0xBDA8FAE9_BE8838D4u64),
        ] {
            assert_eq!(value.to_bits(), bits, "{value:e}");
        }
        assert_eq!(INV_PIO2.to_bits(), 0x3FE45F30_6DC9C883);
    }

    #[test]
    fn signed_zero_is_kept() {
        let (s, c) = sin_cos(0.0);
        assert_eq!((s.to_bits(), c), (0.0f64.to_bits(), 1.0));
        let (s, c) = sin_cos(-0.0);
        assert_eq!((s.to_bits(), c), ((-0.0f64).to_bits(), 1.0));
        let (s, c) = sin_cos_n(&[0.0, -0.0]);
        assert_eq!(
            (s[0].to_bits(), s[1].to_bits(), c),
            (0.0f64.to_bits(), (-0.0f64).to_bits(), [1.0; 2])
        );
    }

    #[test]
    fn sin_cos_n_handles_every_length_and_falls_back_per_call() {
        let xs = [0.3, -1.2, 2.9, 100.0, -7.5, 0.0, 1e-9, 3.0];
        fn all<const N: usize>(x: [f64; N]) {
            let (s, c) = sin_cos_n(&x);
            for i in 0..N {
                let (s1, c1) = sin_cos(x[i]);
                assert!(
                    ulps(s[i], s1) <= 1 && ulps(c[i], c1) <= 1,
                    "N = {N}, x = {}",
                    x[i]
                );
            }
        }
        all::<1>(xs[..1].try_into().unwrap());
        all::<3>(xs[..3].try_into().unwrap());
        all::<4>(xs[..4].try_into().unwrap());
        all::<5>(xs[..5].try_into().unwrap());
        all::<7>(xs[..7].try_into().unwrap());
        all::<8>(xs);
        all::<0>([]);
        // One element off the fast path: the whole call goes through `sin_cos`, still exact.
        let (s, c) = sin_cos_n(&[0.5, f64::NAN, 1e300, f64::INFINITY]);
        assert_eq!((s[0], c[0]), sin_cos(0.5));
        assert!(s[1].is_nan() && c[1].is_nan() && s[3].is_nan() && c[3].is_nan());
        assert_eq!((s[2], c[2]), 1e300f64.sin_cos());
    }

    #[test]
    fn the_avx_alias_is_the_target_condition() {
        // build.rs sets `dynid_avx`; a silent miss would leave every kernel on the portable forms.
        let target = cfg!(all(
            target_arch = "x86_64",
            target_feature = "avx2",
            target_feature = "fma"
        ));
        assert_eq!(cfg!(dynid_avx), target);
    }

    #[test]
    fn sin_cos8_is_sin_cos_calls_bit_for_bit() {
        // Each position holds, in turn, each kind of value of the test above, the others all
        // another: whatever they hold, each value is `sin_cos`'s, for eight values and fewer,
        // in the form `sin_cos8` uses and (on AVX-512 builds) the eight-lane one.
        let xs = [0.5, -2.0, PI, 1e300, f64::NAN, -0.0, 1e-310, 1.0e6, -3.0];
        let same = |a: f64, b: f64| a.to_bits() == b.to_bits() || (a.is_nan() && b.is_nan());
        for &x in &xs {
            for &fill in &xs {
                for p in 0..8 {
                    let mut v = [fill; 8];
                    v[p] = x;
                    let want = v.map(sin_cos);
                    // The eight-lane form too, whichever one `sin_cos8` uses in this build.
                    #[cfg(all(target_feature = "avx512f", target_feature = "fma"))]
                    for (i, (got, w)) in avx512::sin_cos8(v).iter().zip(&want).enumerate() {
                        let ok = same(got.0, w.0) && same(got.1, w.1);
                        assert!(ok, "eight lanes: {x} at {p} among {fill}: {i}");
                    }
                    let five = sin_cos8([v[0], v[1], v[2], v[3], v[4]]);
                    for (i, (got, w)) in sin_cos8(v)
                        .iter()
                        .chain(&five)
                        .zip(want.iter().chain(&want))
                        .enumerate()
                    {
                        assert!(
                            same(got.0, w.0) && same(got.1, w.1),
                            "{x} at {p} among {fill}: {i}"
                        );
                    }
                }
            }
        }
    }

    #[test]
    fn sin_cos4_3_2_are_sin_cos_calls_bit_for_bit() {
        // Every position holds, in turn, an ordinary angle, one the fast path reduces with
        // cancellation (fl(π): the exact path), one beyond the fast path, a NaN, a signed zero and
        // a subnormal: whatever the others hold, each value is `sin_cos`'s.
        let xs = [
            0.5,
            -2.0,
            PI,
            3.0 * FRAC_PI_2,
            1e300,
            f64::NAN,
            -0.0,
            1e-310,
            1.0e6,
        ];
        let same = |a: f64, b: f64| a.to_bits() == b.to_bits() || (a.is_nan() && b.is_nan());
        for &a in &xs {
            for &b in &xs {
                for &c in &xs {
                    for &d in &xs {
                        let got = sin_cos4(a, b, c, d);
                        let fewer = sin_cos3(a, b, c).into_iter().chain(sin_cos2(a, b));
                        let want = [a, b, c, d, a, b, c, a, b].map(sin_cos);
                        for (x, ((s, co), (ws, wc))) in [a, b, c, d, a, b, c, a, b]
                            .into_iter()
                            .zip(got.into_iter().chain(fewer).zip(want))
                        {
                            assert!(same(s, ws) && same(co, wc), "{x} in {a} {b} {c} {d}");
                        }
                    }
                }
            }
        }
    }

    #[test]
    fn tiny_and_subnormal_arguments_are_exact() {
        for x in [
            f64::MIN_POSITIVE,
            f64::from_bits(1),
            1e-300,
            1e-20,
            2f64.powi(-27),
        ] {
            for x in [x, -x] {
                assert_eq!(sin_cos(x), (x, 1.0));
            }
        }
    }

    #[test]
    fn non_finite_arguments_give_nan() {
        for x in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
            let (s, c) = sin_cos(x);
            assert!(s.is_nan() && c.is_nan(), "{x}");
        }
    }

    #[test]
    fn beyond_the_fast_path_matches_std_exactly() {
        for x in [
            next_up(FAST_PATH_MAX),
            1.0e7,
            1.0e22,
            1.0e300,
            f64::MAX,
            -f64::MAX,
        ] {
            assert_eq!(sin_cos(x), x.sin_cos(), "{x:e}");
        }
    }

    #[test]
    fn around_the_fast_path_bound() {
        let mut x = FAST_PATH_MAX;
        for _ in 0..1000 {
            check(x, 2);
            check(-x, 2);
            x = next_down(x);
        }
    }

    #[test]
    fn special_angles() {
        for x in [
            FRAC_PI_4,
            FRAC_PI_2,
            PI,
            3.0 * FRAC_PI_2,
            2.0 * PI,
            1.0,
            0.5,
            0.785,
            2.356,
        ] {
            check(x, 2);
            check(-x, 2);
        }
    }

    /// The hard cases for range reduction: the doubles nearest to k·π/2 (and k·π/4, where the
    /// quadrant changes), and their neighbours, for every k in the fast path.
    #[test]
    fn multiples_of_half_pi_over_the_whole_fast_path() {
        let kmax = (FAST_PATH_MAX / FRAC_PI_2) as i64;
        for k in 0..=kmax {
            let x = k as f64 * FRAC_PI_2;
            let y = (k as f64 + 0.5) * FRAC_PI_2;
            for x in [x, next_up(x), next_down(x), y, next_up(y), next_down(y)] {
                if x.abs() <= FAST_PATH_MAX {
                    check(x, 2);
                    check(-x, 2);
                }
            }
        }
    }

    /// A dense deterministic sweep of the joint-angle range, for the largest observed error.
    #[test]
    fn joint_range_sweep_is_within_one_ulp() {
        let n = 200_000;
        let mut worst = 0;
        for i in 0..=n {
            let x = -8.0 * PI + 16.0 * PI * (i as f64 / n as f64);
            let (s, c) = sin_cos(x);
            worst = worst.max(ulps(s, x.sin())).max(ulps(c, x.cos()));
        }
        assert!(worst <= 1, "worst {worst} ulp");
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(20_000))]

        #[test]
        fn joint_angles(x in -4.0 * PI..4.0 * PI) {
            check(x, 2);
        }

        #[test]
        fn wide_range(x in -FAST_PATH_MAX..FAST_PATH_MAX) {
            check(x, 2);
        }

        #[test]
        fn any_double(bits in any::<u64>()) {
            check(f64::from_bits(bits), 2);
        }

        #[test]
        fn small_magnitudes(e in -60i32..3, m in 1.0f64..2.0, neg in any::<bool>()) {
            let x = m * 2f64.powi(e);
            check(if neg { -x } else { x }, 2);
        }
    }
}
