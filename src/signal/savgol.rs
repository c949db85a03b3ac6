//! Savitzky–Golay smoothing and differentiation (local polynomial fits; FFT convolution for
//! long windows, fits at the ends).

use std::f64::consts::PI;
use std::ops::Range;

use super::fft::fft;
use super::{DerivativeError, ZeroPhase};

/// Degree of the Savitzky–Golay fits built by [`SavGol::matched`]: quintic, because the second
/// derivative of a cubic fit has a much narrower pass band than its smoothing response.
pub const SG_DEGREE: usize = 5;

/// Windows longer than this are convolved by FFT in [`SavGol::derivatives`].
const FFT_CONVOLUTION_ABOVE: usize = 64;

/// Savitzky–Golay smoothing/differentiation on a uniform grid, with windows
/// fitted at the ends (no padding needed).
#[derive(Debug, Clone)]
pub struct SavGol {
    half: usize,
    poly: usize,
    dt: f64,
    fs: f64,
    /// `coef[d][i]`: weight of sample `k + i - half` for the d-th derivative at `k` (centre).
    centre: [Vec<f64>; 3],
    /// `fit[j][i]`: weight of window sample `i` in the fit's coefficient of `u^j`, with
    /// `u = (i - half) / scale` (the end fits evaluate this one polynomial off-centre).
    fit: Vec<Vec<f64>>,
    scale: f64,
}

impl SavGol {
    /// Window of `2·half + 1` samples, polynomial degree `poly` (≥ 2 so q̈ exists).
    pub fn new(half: usize, poly: usize, dt: f64) -> Self {
        let poly = poly.clamp(2, 2 * half);
        let len = 2 * half + 1;
        let scale = (len as f64 / 2.0).max(1.0);
        // Coefficient c_j of the centred fit; the d-th derivative at the centre is d!·c_d/(scale·dt)^d.
        // One pseudo-inverse: its row j holds the weights of c_j.
        let a = nalgebra::DMatrix::from_fn(len, poly + 1, |i, j| {
            ((i as f64 - half as f64) / scale).powi(j as i32)
        });
        let fit: Vec<Vec<f64>> = match a.pseudo_inverse(1e-12) {
            Ok(p) => (0..=poly)
                .map(|j| (0..len).map(|i| p[(j, i)]).collect())
                .collect(),
            Err(_) => vec![vec![0.0; len]; poly + 1],
        };
        let centre = [0, 1, 2].map(|d| {
            let s = (1..=d).product::<usize>() as f64 / (scale * dt).powi(d as i32);
            fit[d].iter().map(|v| v * s).collect()
        });
        SavGol {
            half,
            poly,
            dt,
            fs: 1.0 / dt,
            centre,
            fit,
            scale,
        }
    }

    /// The centred fits of samples `half..n - half` by FFT convolution (O(n log n) instead of
    /// O(n · window); the same sums to rounding).
    fn centre_by_fft(&self, x: &[f64], out: &mut [Vec<f64>; 3], orders: usize) {
        let (n, m) = (x.len(), self.half);
        let size = (n + 2 * m + 1).next_power_of_two();
        let (mut xr, mut xi) = (vec![0.0; size], vec![0.0; size]);
        xr[..n].copy_from_slice(x);
        fft(&mut xr, &mut xi);
        for (d, o) in out.iter_mut().enumerate().take(orders) {
            // o[k] = Σ_i c[i]·x[k + i − m] = (x ∗ reversed c)[k + m].
            let (mut hr, mut hi) = (vec![0.0; size], vec![0.0; size]);
            for (l, h) in hr.iter_mut().take(2 * m + 1).enumerate() {
                *h = self.centre[d][2 * m - l];
            }
            fft(&mut hr, &mut hi);
            // Inverse FFT of X·H as conj(FFT(conj(X·H))) / size.
            for k in 0..size {
                let (a, b) = (xr[k] * hr[k] - xi[k] * hi[k], xr[k] * hi[k] + xi[k] * hr[k]);
                (hr[k], hi[k]) = (a, -b);
            }
            fft(&mut hr, &mut hi);
            for k in m..n - m {
                o[k] = hr[k + m] / size as f64;
            }
        }
    }

    /// Value and derivatives at window positions `positions` of the fit over `window`
    /// (`2·half + 1` samples): `out[d][i]` for `positions[i]`.
    fn off_centre(&self, window: &[f64], positions: impl Iterator<Item = usize>) -> Vec<[f64; 3]> {
        let c: Vec<f64> = self
            .fit
            .iter()
            .map(|w| w.iter().zip(window).map(|(a, b)| a * b).sum())
            .collect();
        let h = self.scale * self.dt;
        positions
            .map(|pos| {
                let u = (pos as f64 - self.half as f64) / self.scale;
                let mut out = [0.0; 3];
                for (d, o) in out.iter_mut().enumerate() {
                    // d-th derivative of Σ c_j u^j, in time units.
                    let mut v = 0.0;
                    for (j, cj) in c.iter().enumerate().skip(d) {
                        let falling = ((j - d + 1)..=j).product::<usize>() as f64;
                        v += cj * falling * u.powi((j - d) as i32);
                    }
                    *o = v / h.powi(d as i32);
                }
                out
            })
            .collect()
    }

    /// The degree-[`SG_DEGREE`] Savitzky–Golay filter whose −6 dB frequency is closest to `fc`.
    pub fn matched(fc: f64, fs: f64) -> Result<Self, DerivativeError> {
        let max = 0.45 * fs;
        if !(fc.is_finite() && fc > 0.0 && fc < max) {
            return Err(DerivativeError::BadCutoff { fc, max, fs });
        }
        // Gain at fc decreases with the window length: bisection on `half`.
        let (mut lo, mut hi) = (2usize, 2usize);
        while SavGol::new(hi, SG_DEGREE, 1.0 / fs).gain(fc) > 0.5 && hi < 200_000 {
            lo = hi;
            hi *= 2;
        }
        while hi - lo > 1 {
            let mid = (lo + hi) / 2;
            if SavGol::new(mid, SG_DEGREE, 1.0 / fs).gain(fc) > 0.5 {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        let glo = SavGol::new(lo, SG_DEGREE, 1.0 / fs).gain(fc);
        let ghi = SavGol::new(hi, SG_DEGREE, 1.0 / fs).gain(fc);
        let half = if (glo - 0.5).abs() < (ghi - 0.5).abs() {
            lo
        } else {
            hi
        };
        Ok(SavGol::new(half, SG_DEGREE, 1.0 / fs))
    }

    pub fn half_window(&self) -> usize {
        self.half
    }

    /// Value, first and second derivative of the local polynomial fit at every sample.
    pub fn derivatives(&self, x: &[f64]) -> [Vec<f64>; 3] {
        self.derivatives_ends(x, true, true)
    }

    /// [`SavGol::derivatives`], with the end fits only at the ends that are the signal's own
    /// (`left`/`right`; inside a window of a longer signal the caller discards those samples).
    pub fn derivatives_ends(&self, x: &[f64], left: bool, right: bool) -> [Vec<f64>; 3] {
        self.fits(x, left, right, 3)
    }

    /// The first `orders` of value, q̇, q̈ inside (the ends get all three); the rest stay zero.
    fn fits(&self, x: &[f64], left: bool, right: bool, orders: usize) -> [Vec<f64>; 3] {
        let n = x.len();
        let mut out = [vec![0.0; n], vec![0.0; n], vec![0.0; n]];
        if n < 2 * self.half + 1 {
            // Window longer than the signal: one global fit of the same degree.
            let w: [Vec<Vec<f64>>; 3] = [0, 1, 2].map(|d| {
                (0..n)
                    .map(|k| sg_weights_n(n, self.poly.min(n - 1), k, d, self.dt))
                    .collect()
            });
            for d in 0..3 {
                for k in 0..n {
                    out[d][k] = w[d][k].iter().zip(x).map(|(a, b)| a * b).sum();
                }
            }
            return out;
        }
        let m = self.half;
        if 2 * m + 1 > FFT_CONVOLUTION_ABOVE {
            self.centre_by_fft(x, &mut out, orders);
        } else {
            for (d, o) in out.iter_mut().enumerate().take(orders) {
                for k in m..n - m {
                    o[k] = self.centre[d]
                        .iter()
                        .zip(&x[k - m..=k + m])
                        .map(|(a, b)| a * b)
                        .sum();
                }
            }
        }
        // Ends: evaluate the fit over the first/last window at the off-centre positions.
        if left {
            for (pos, v) in self
                .off_centre(&x[..2 * m + 1], 0..m)
                .into_iter()
                .enumerate()
            {
                for d in 0..3 {
                    out[d][pos] = v[d];
                }
            }
        }
        if right {
            let vals = self.off_centre(&x[n - 2 * m - 1..], m + 1..2 * m + 1);
            for (i, v) in vals.into_iter().enumerate() {
                for d in 0..3 {
                    out[d][n - m + i] = v[d];
                }
            }
        }
        out
    }
}

impl ZeroPhase for SavGol {
    fn apply(&self, x: &mut [f64], pad_left: bool, pad_right: bool) {
        // Interior windows: the caller discards `reach` samples at unpadded sides (no end fit).
        let [s, _, _] = self.fits(x, pad_left, pad_right, 1);
        x.copy_from_slice(&s);
    }

    fn reach(&self) -> usize {
        self.half + 1
    }

    /// The fit's own derivatives (in its own step; `dt` is not used), channel by channel.
    fn derivatives_many(
        &self,
        q: Vec<Vec<f64>>,
        dq: Option<Vec<Vec<f64>>>,
        _dt: f64,
        pad_left: bool,
        pad_right: bool,
        keep: Range<usize>,
    ) -> [Vec<Vec<f64>>; 3] {
        let cut = |x: Vec<f64>| x[keep.clone()].to_vec();
        let mut out = [(); 3].map(|_| Vec::with_capacity(q.len()));
        for (j, qj) in q.iter().enumerate() {
            let [a, b, c] = self.derivatives_ends(qj, pad_left, pad_right);
            let (b, c) = match &dq {
                Some(d) => {
                    let [v, acc, _] = self.derivatives_ends(&d[j], pad_left, pad_right);
                    (v, acc)
                }
                None => (b, c),
            };
            out[0].push(cut(a));
            out[1].push(cut(b));
            out[2].push(cut(c));
        }
        out
    }

    fn gain(&self, f: f64) -> f64 {
        let w = 2.0 * PI * f / self.fs;
        let m = self.half as isize;
        self.centre[0]
            .iter()
            .enumerate()
            .map(|(i, c)| c * ((i as isize - m) as f64 * w).cos())
            .sum::<f64>()
            .abs()
    }

    fn describe(&self) -> String {
        format!(
            "Savitzky-Golay degree {} over {} samples ({:.4} s), zero phase, -6 dB at {:.3} Hz",
            self.poly,
            2 * self.half + 1,
            (2 * self.half) as f64 * self.dt,
            self.sixdb()
        )
    }
}

impl SavGol {
    fn sixdb(&self) -> f64 {
        let (mut lo, mut hi) = (0.0, 0.5 * self.fs);
        for _ in 0..60 {
            let mid = 0.5 * (lo + hi);
            if self.gain(mid) > 0.5 {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        0.5 * (lo + hi)
    }
}

/// Weights for the `d`-th derivative at window position `pos` of a degree-`poly` least-squares fit
/// over `2·half + 1` equally spaced samples.
fn sg_weights_n(len: usize, poly: usize, pos: usize, d: usize, dt: f64) -> Vec<f64> {
    // Abscissae centred at `pos` and scaled to O(1) for conditioning.
    let scale = (len as f64 / 2.0).max(1.0);
    let a = nalgebra::DMatrix::from_fn(len, poly + 1, |i, j| {
        ((i as f64 - pos as f64) / scale).powi(j as i32)
    });
    // Row d of pinv(A) gives coefficient c_d; the d-th derivative at pos is d!·c_d/(scale·dt)^d.
    let Some(pinv) = a.clone().pseudo_inverse(1e-12).ok() else {
        return vec![0.0; len];
    };
    if d > poly {
        return vec![0.0; len];
    }
    let fact = (1..=d).product::<usize>() as f64;
    let s = fact / (scale * dt).powi(d as i32);
    (0..len).map(|i| pinv[(d, i)] * s).collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::signal::sines;

    /// The trait's row-major filtering (what the regression uses) is each column filtered on
    /// its own, only the kept rows written.
    #[test]
    fn row_major_filtering_is_each_column_filtered_alone() {
        let sg = SavGol::new(20, 3, 0.002);
        let (rows, stride) = (300, 3);
        let x: Vec<f64> = (0..rows * stride)
            .map(|i| sines((i / stride) as f64 * 0.002 + (i % stride) as f64).0)
            .collect();
        let keep = [0, 7, 150, 299];
        let mut out = vec![-1.0; keep.len() * stride];
        sg.apply_rows(&x, stride, &[0, 2], true, false, &keep, &mut out);
        for c in [0, 2] {
            let mut ch: Vec<f64> = (0..rows).map(|k| x[k * stride + c]).collect();
            sg.apply(&mut ch, true, false);
            for (i, &k) in keep.iter().enumerate() {
                assert_eq!(out[i * stride + c], ch[k]);
            }
        }
        assert!(keep
            .iter()
            .enumerate()
            .all(|(i, _)| out[i * stride + 1] == -1.0));
    }

    /// Long windows go through the FFT convolution and the end fits through one polynomial per
    /// end: both must still be exact on a cubic (the fit reproduces it), here with a 401-sample
    /// window over 3000 samples, and the interior must equal the direct sums.
    #[test]
    fn long_savgol_windows_are_exact_on_cubics_and_match_direct_sums() {
        let dt = 0.002;
        let sg = SavGol::new(200, 3, dt);
        let cubic = |t: f64| {
            (
                1.0 + 2.0 * t - 3.0 * t * t + 0.5 * t * t * t,
                2.0 - 6.0 * t + 1.5 * t * t,
                -6.0 + 3.0 * t,
            )
        };
        let x: Vec<f64> = (0..3000).map(|k| cubic(k as f64 * dt).0).collect();
        let [s, d1, d2] = sg.derivatives(&x);
        for k in 0..3000 {
            let (v, a, b) = cubic(k as f64 * dt);
            assert!((s[k] - v).abs() < 1e-9, "{k}: {} vs {v}", s[k]);
            assert!((d1[k] - a).abs() < 1e-6, "{k}: {} vs {a}", d1[k]);
            assert!((d2[k] - b).abs() < 1e-4, "{k}: {} vs {b}", d2[k]);
        }
        let y: Vec<f64> = (0..3000)
            .map(|k| sines(k as f64 * dt).0 + 0.01 * ((k * 7919) % 13) as f64)
            .collect();
        let fast = sg.derivatives(&y);
        for (d, (f, c)) in fast.iter().zip(&sg.centre).enumerate() {
            let scale = f.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            for k in (200..2800).step_by(37) {
                let direct: f64 = c
                    .iter()
                    .zip(&y[k - 200..=k + 200])
                    .map(|(a, b)| a * b)
                    .sum();
                assert!((f[k] - direct).abs() < 1e-12 * scale.max(1.0), "d{d} k{k}");
            }
        }
    }
}
