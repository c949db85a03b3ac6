//! Order statistics: the exact k-th smallest of values visited in passes (histogram refinement,
//! nothing of the values' size kept) and the median of a slice.

use super::PIECE;

/// Visits every value of a collection with the callback it is given.
pub(crate) type Visit<'a> = dyn FnMut(&mut dyn FnMut(f64)) + 'a;

/// The `k`-th smallest (0-based) of the values that `each` visits (all within `range`, the
/// values' min and max), exactly, without holding them: histogram passes narrow the range to
/// the bin holding rank `k` until few enough values are left to sort.
pub(crate) fn kth_smallest(k: usize, range: (f64, f64), each: &mut Visit) -> f64 {
    const BINS: usize = 4096;
    let (mut lo, mut hi) = range;
    let mut below = 0; // values < lo
    loop {
        if lo >= hi {
            return lo;
        }
        // Values in [lo, hi] per bin, with each bin's own min and max: the bin map is monotone,
        // so the values of bins b1..=b2 are exactly those in [min(b1), max(b2)].
        let mut count = vec![0usize; BINS];
        let mut vmin = vec![f64::INFINITY; BINS];
        let mut vmax = vec![f64::NEG_INFINITY; BINS];
        let bin = |v: f64| (((v - lo) / (hi - lo) * BINS as f64) as usize).min(BINS - 1);
        each(&mut |v| {
            if v >= lo && v <= hi {
                let b = bin(v);
                count[b] += 1;
                vmin[b] = vmin[b].min(v);
                vmax[b] = vmax[b].max(v);
            }
        });
        let total: usize = count.iter().sum();
        if total <= PIECE {
            let mut vals = Vec::with_capacity(total);
            each(&mut |v| {
                if v >= lo && v <= hi {
                    vals.push(v);
                }
            });
            vals.sort_by(f64::total_cmp);
            return vals[k - below];
        }
        let mut acc = below;
        let Some(b) = (0..BINS).find(|&b| {
            let here = acc + count[b] > k;
            if !here {
                acc += count[b];
            }
            here
        }) else {
            return hi; // unreachable: rank k lies in [lo, hi]
        };
        (lo, hi, below) = (vmin[b], vmax[b], acc);
    }
}

pub(crate) fn median(v: &mut [f64]) -> f64 {
    if v.is_empty() {
        return 0.0;
    }
    v.sort_by(|a, b| a.total_cmp(b));
    let m = v.len() / 2;
    if v.len() % 2 == 1 {
        v[m]
    } else {
        0.5 * (v[m - 1] + v[m])
    }
}
