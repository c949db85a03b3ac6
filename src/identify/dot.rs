//! **Dot products in a fixed summation order** ([`dot`], and [`dots`] of one row with many
//! coefficient sets): four partial sums, so they vectorise without reassociation licence and
//! every caller (the QR's reflections, the predictions of every judged model, the load-dependent
//! columns' torque) gets the same bits for the same numbers, however many sets are asked at once.

use crate::pack::Pack;

/// Dot product of two slices of the same length, summed in four partial sums (element `i` in
/// sum `i mod 4`, the four combined as `(s0 + s2) + (s1 + s3)`, the last `len mod 4` elements
/// added after them in order): a fixed order, so vectorised without reassociation licence.
pub fn dot(a: &[f64], b: &[f64]) -> f64 {
    debug_assert_eq!(a.len(), b.len());
    dot_group(a, [b])[0]
}

/// [`dot`] of `a` with each of `sets` (`out[s] = dot(a, sets[s])`, the same sums),
/// four sets at a time: `a` is read once per four sets and their four sums' chains overlap (a
/// model's prediction of one joint is one such product per coefficient set, and judging asks for
/// a dozen sets per sample). Every set must be as long as `a`.
pub fn dots(a: &[f64], sets: &[&[f64]], out: &mut [f64]) {
    debug_assert!(sets.iter().all(|s| s.len() == a.len()) && out.len() >= sets.len());
    let mut s = 0;
    while s + 4 <= sets.len() {
        let r = dot_group(a, [sets[s], sets[s + 1], sets[s + 2], sets[s + 3]]);
        out[s..s + 4].copy_from_slice(&r);
        s += 4;
    }
    match sets.len() - s {
        3 => out[s..s + 3].copy_from_slice(&dot_group(a, [sets[s], sets[s + 1], sets[s + 2]])),
        2 => out[s..s + 2].copy_from_slice(&dot_group(a, [sets[s], sets[s + 1]])),
        1 => out[s] = dot_group(a, [sets[s]])[0],
        _ => {}
    }
}

/// [`dot`] of `a` with `G` vectors at once (each summed in [`dot`]'s order).
#[inline(always)]
fn dot_group<const G: usize>(a: &[f64], b: [&[f64]; G]) -> [f64; G] {
    let len = a.len();
    let b = b.map(|v| &v[..len]);
    // One pack per set: its four partial sums in one register (LLVM, left to a plain
    // `[[f64; 4]; G]`, vectorised across the sets instead, with a shuffle per product).
    let mut acc = [Pack::splat(0.0); G];
    let four = |v: &[f64]| Pack::new([v[0], v[1], v[2], v[3]]);
    for (c, x) in a.chunks_exact(4).enumerate() {
        let x = four(x);
        for (acc, v) in acc.iter_mut().zip(&b) {
            *acc = *acc + x * four(&v[4 * c..4 * c + 4]);
        }
    }
    let tail = len / 4 * 4;
    let mut out = [0.0; G];
    for ((o, acc), v) in out.iter_mut().zip(&acc).zip(&b) {
        let acc = acc.to_array();
        let mut s = (acc[0] + acc[2]) + (acc[1] + acc[3]);
        for (x, y) in a[tail..].iter().zip(&v[tail..]) {
            s += x * y;
        }
        *o = s;
    }
    out
}

#[cfg(test)]
pub(in crate::identify) mod tests {
    use super::*;

    /// Uniform in [−0.5, 0.5) from a 64-bit LCG (the identification's unit tests' numbers).
    pub(in crate::identify) fn lcg(seed: &mut u64) -> f64 {
        *seed = seed
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((*seed >> 11) as f64 / (1u64 << 53) as f64) - 0.5
    }

    #[test]
    fn dot_and_dots_sum_in_their_documented_order_bit_for_bit() {
        // Lengths around the four-wide chunks and set counts around the groups of four; the
        // oracle is the documented order of `dot`'s sums, written out element by element.
        let ordered = |a: &[f64], b: &[f64]| {
            let four = a.len() / 4 * 4;
            let mut acc = [0.0; 4];
            for i in 0..four {
                acc[i % 4] += a[i] * b[i];
            }
            let mut s = (acc[0] + acc[2]) + (acc[1] + acc[3]);
            for i in four..a.len() {
                s += a[i] * b[i];
            }
            s
        };
        let mut seed = 5u64;
        for len in [0, 1, 3, 4, 5, 7, 8, 13, 31, 40] {
            for nsets in 0..10 {
                let a: Vec<f64> = (0..len).map(|_| lcg(&mut seed) * 1e3).collect();
                let sets: Vec<Vec<f64>> = (0..nsets)
                    .map(|_| (0..len).map(|_| lcg(&mut seed) / 7.0).collect())
                    .collect();
                let refs: Vec<&[f64]> = sets.iter().map(Vec::as_slice).collect();
                let mut out = vec![f64::NAN; nsets + 1];
                dots(&a, &refs, &mut out);
                for (s, set) in sets.iter().enumerate() {
                    let want = ordered(&a, set).to_bits();
                    assert_eq!(out[s].to_bits(), want, "len {len} set {s}/{nsets}");
                    assert_eq!(dot(&a, set).to_bits(), want, "dot, len {len}");
                }
                assert!(out[nsets].is_nan(), "wrote past the sets");
            }
        }
    }
}
