//! The automatic derivative cut-off of `dynid payload`. The spectral rule alone
//! ([`crate::derivative`]'s proposal) is not enough: on a fast log with timing jitter or coarse
//! encoders the noise reads as motion, the proposal lands at the top of its range (0.2·fs), and
//! the noise of the estimated q̈ in the regressor biases the least-squares payload towards zero
//! (MuJoCo, eval/payload.py case 5: a UR10e-like arm logged at 2 kHz with 14-bit encoders gave
//! 3.685 kg for 4.045 kg at the proposal's 400 Hz, 4.044 kg at 3 Hz). So, as `identify` does,
//! octaves of cut-offs are tried and judged on what they predict: the payload fitted on the
//! filtered rows, its torque predicted from the estimated states (unfiltered regressor) against
//! the measured unexplained torque `d` (unfiltered). The noise of `d` is the same for every
//! cut-off, so the scores compare; too low a cut-off distorts the motion, too high a one lets
//! the noise into q̈, and both raise the score.

use nalgebra::{DMatrix, DVector};

use super::rows::Rows;

/// Lowest cut-off tried (Hz).
pub const LOWEST_HZ: f64 = 0.5;

/// The cut-offs to try besides the proposal: octaves from [`LOWEST_HZ`] up to 0.2·fs, and the
/// proposal's own octave neighbours.
pub fn grid(proposal: f64, fs_hz: f64) -> Vec<f64> {
    let top = 0.2 * fs_hz;
    let mut out = Vec::new();
    let mut fc = LOWEST_HZ;
    while fc <= top {
        out.push(fc);
        fc *= 2.0;
    }
    for f in [proposal / 2.0, proposal * 2.0] {
        if (LOWEST_HZ..=top).contains(&f) {
            out.push(f);
        }
    }
    out.retain(|f| (f / proposal - 1.0).abs() > 1e-9);
    out
}

/// The score of one cut-off: the payload fitted (least squares, all 10 parameters) on the
/// filtered `rows`, then the mean over joints of the unfiltered residual's mean square relative
/// to that joint's unfiltered `d`.
pub fn score(rows: &[Rows], raw: &[Rows]) -> f64 {
    let Some(n) = rows.first().map(|r| r.n) else {
        return f64::INFINITY;
    };
    let mut nm = DMatrix::<f64>::zeros(10, 10);
    let mut g = DVector::<f64>::zeros(10);
    // Each joint weighted by its own filtered d's mean square, so no joint's scale dominates.
    let mut w = vec![0.0; n];
    let mut c = vec![0usize; n];
    for r in rows {
        for (i, d) in r.d.iter().enumerate() {
            w[i % n] += d * d;
            c[i % n] += 1;
        }
    }
    let w: Vec<f64> = w
        .iter()
        .zip(&c)
        .map(|(s, c)| (*c).max(1) as f64 / s.max(1e-300))
        .collect();
    for r in rows {
        for (i, (y, d)) in r.y.iter().zip(&r.d).enumerate() {
            let wj = w[i % n];
            for u in 0..10 {
                g[u] += wj * y[u] * d;
                for v in 0..10 {
                    nm[(u, v)] += wj * y[u] * y[v];
                }
            }
        }
    }
    let phi = match nm.clone().cholesky() {
        Some(ch) => ch.solve(&g),
        None => nm.pseudo_inverse(1e-12).map_or(g.clone() * 0.0, |p| p * g),
    };
    let (mut e, mut s, mut k) = (vec![0.0; n], vec![0.0; n], vec![0usize; n]);
    for r in raw {
        for (i, (y, d)) in r.y.iter().zip(&r.d).enumerate() {
            let j = i % n;
            let p: f64 = y.iter().zip(phi.iter()).map(|(a, b)| a * b).sum();
            e[j] += (d - p) * (d - p);
            s[j] += d * d;
            k[j] += 1;
        }
    }
    if k.iter().all(|&k| k == 0) {
        return f64::INFINITY;
    }
    e.iter()
        .zip(&s)
        .map(|(e, s)| e / s.max(1e-300))
        .sum::<f64>()
        / n as f64
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_grid_spans_octaves_below_a_fifth_of_the_rate_without_the_proposal() {
        let g = grid(400.0, 2000.0);
        assert_eq!(g.first(), Some(&0.5));
        assert!(g.iter().all(|f| *f <= 400.0 && (f - 400.0).abs() > 1e-9));
        assert!(g.contains(&256.0) && g.contains(&200.0));
        let g = grid(3.0, 100.0);
        assert_eq!(g, vec![0.5, 1.0, 2.0, 4.0, 8.0, 16.0, 1.5, 6.0]);
    }
}
