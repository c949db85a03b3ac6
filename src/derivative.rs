//! Derivative estimation from sampled positions: zero-phase low-pass filtering, finite differences,
//! Savitzky–Golay, resampling of uneven grids and the automatic choice of the cut-off frequency.
//!
//! What an [`Estimator`] does, in order (and reports in [`DerivativeReport`]); it is set up once
//! per file and then run window by window ([`Estimator::window`], each window with the filter's
//! reach of margin, so a long log's states never exist all at once; [`estimate`] is the whole
//! signal as one window):
//! 1. **Sampling check.** Times must be finite and strictly increasing, without gaps (a step over
//!    [`GAP_STEPS`] median steps is rejected: split the file there). If the spacing is uneven
//!    (jitter larger than 10⁻⁶ of the median step), every channel is *resampled* by linear
//!    interpolation onto a uniform grid with the median step, so the filters below are well
//!    defined; the jitter (min/median/max/std of dt) is reported. Identification brings its
//!    predictions back to the original sample times by linear interpolation between grid
//!    samples; [`Estimate::at`] interpolates the states themselves (cubic Hermite).
//! 2. **Cut-off.** By default chosen from the spectrum of the positions ([`auto_cutoff`]): a Welch
//!    periodogram of the second difference (which whitens the steep position spectrum and so
//!    limits window leakage), divided back by the difference operator's gain, gives the position
//!    spectrum. Its noise floor is the median over the upper half of the band; the *noise edge* is
//!    the highest frequency where the spectrum still stands a factor 2 above that floor (signal
//!    power ≈ noise power: the Wiener cross-over); the *motion band* is the frequency below which
//!    99 % of the velocity power lies. The cut-off is `min(5 × motion band, 1.25 × noise edge)`
//!    (five times the band keeps the pass band flat where the dynamics live, the classic rule for
//!    identification filters); one cut-off (the largest over the channels) serves all joints.
//! 3. **Filter + differences.** Either a 4th-order Butterworth run forward and backward
//!    ([`Butterworth::filtfilt`], −6 dB at the cut-off, odd-reflection padding at the ends)
//!    followed by 5-point central differences, or a quintic Savitzky–Golay fit whose window is
//!    matched to the same −6 dB cut-off ([`SavGol`]).
//!
//! The same zero-phase filter ([`ZeroPhase`]) is what the identification applies to the measured
//! torque and to every regressor column ("parallel filtering"), so filtering never biases the
//! fit; errors are always computed against the unfiltered torque.
//!
//! ```
//! use dynid::derivative::{Butterworth, ZeroPhase};
//! let fs = 500.0;
//! let f = Butterworth::lowpass(4, 5.0, fs).unwrap();
//! let mut x: Vec<f64> = (0..2000).map(|k| (k as f64 / fs).sin()).collect();
//! let orig = x.clone();
//! f.apply(&mut x, true, true);
//! assert!((x[1000] - orig[1000]).abs() < 1e-6); // 0.16 Hz passes unchanged, no phase lag
//! ```

use std::borrow::Cow;
use std::f64::consts::PI;

use serde::Serialize;

use crate::data::Trajectory;
use crate::log::Log;

/// Fewest samples any estimator accepts.
pub const MIN_SAMPLES: usize = 32;

/// A time step longer than this many median steps is a gap in the recording (rejected).
pub const GAP_STEPS: f64 = 10.0;

/// Errors of derivative estimation (inputs come from user files, so every case has a message).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum DerivativeError {
    #[error("too few samples: {n} (at least {min} are needed to estimate derivatives)")]
    TooFewSamples { n: usize, min: usize },
    #[error("sample times must be strictly increasing: row {row} has t = {t} after t = {prev}")]
    NotIncreasing { row: usize, t: f64, prev: f64 },
    #[error("gap in the sample times at data row {row}: t jumps from {prev} to {t} s, {:.0}× the median step of {dt_median} s — split the file at the gap (several --data files are fitted together, each filtered on its own) or remove it", (t - prev) / dt_median)]
    Gap {
        row: usize,
        t: f64,
        prev: f64,
        dt_median: f64,
    },
    #[error("non-finite value in channel {channel} at row {row}")]
    NonFinite { channel: usize, row: usize },
    #[error("cut-off {fc} Hz is not inside (0, {max}) Hz for a sampling rate of {fs} Hz")]
    BadCutoff { fc: f64, max: f64, fs: f64 },
    #[error("filter order must be between 1 and 12, got {0}")]
    BadOrder(usize),
}

// ---------------------------------------------------------------------------------------------
// Sampling
// ---------------------------------------------------------------------------------------------

/// Statistics of the sample spacing of one file.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Sampling {
    pub n: usize,
    pub dt_median: f64,
    pub dt_min: f64,
    pub dt_max: f64,
    pub dt_std: f64,
    /// `true` when the spacing is uniform to 1e-6 of the median step (no resampling needed).
    pub uniform: bool,
}

impl Sampling {
    /// Checks `t` (finite, strictly increasing, enough samples) and measures its spacing.
    pub fn of(t: &[f64]) -> Result<Self, DerivativeError> {
        Self::measure(t.len(), |a, b| Cow::Borrowed(&t[a..b]))
    }

    /// [`Sampling::of`] the times of a log, read piece by piece (constant memory).
    pub fn of_log(log: &Log) -> Result<Self, DerivativeError> {
        Self::measure(log.len(), |a, b| {
            let mut t = Vec::with_capacity(b - a);
            log.rows(a, b, |row| t.push(row[0]));
            Cow::Owned(t)
        })
    }

    /// [`Sampling::of`] for `n` times read in pieces by `times(a, b)` = `t[a..b]`: a few passes
    /// over the pieces (the median by histogram refinement, exact), nothing of size `n` kept.
    fn measure<'a>(
        n: usize,
        times: impl Fn(usize, usize) -> Cow<'a, [f64]>,
    ) -> Result<Self, DerivativeError> {
        if n < MIN_SAMPLES {
            return Err(DerivativeError::TooFewSamples {
                n,
                min: MIN_SAMPLES,
            });
        }
        // Every step dt_k = t[k] − t[k−1], k = 1..n, in order, piece by piece.
        let steps = |f: &mut dyn FnMut(usize, f64, f64, f64) -> Result<(), DerivativeError>| {
            let mut prev = f64::NAN;
            for a in (0..n).step_by(PIECE) {
                let t = times(a, (a + PIECE).min(n));
                for (i, &v) in t.iter().enumerate() {
                    if a + i > 0 {
                        f(a + i, v - prev, v, prev)?;
                    }
                    prev = v;
                }
            }
            Ok(())
        };
        let (mut sum, mut dt_min, mut dt_max) = (0.0, f64::INFINITY, 0.0f64);
        if !times(0, 1)[0].is_finite() {
            return Err(DerivativeError::NonFinite { channel: 0, row: 0 });
        }
        steps(&mut |row, dt, t, prev| {
            if !t.is_finite() {
                return Err(DerivativeError::NonFinite { channel: 0, row });
            }
            if dt <= 0.0 {
                return Err(DerivativeError::NotIncreasing { row, t, prev });
            }
            sum += dt;
            (dt_min, dt_max) = (dt_min.min(dt), dt_max.max(dt));
            Ok(())
        })?;
        let m = n - 1;
        let mut each = |f: &mut dyn FnMut(f64)| {
            let _ = steps(&mut |_, dt, _, _| {
                f(dt);
                Ok(())
            });
        };
        let dt_median = if m % 2 == 1 {
            kth_smallest(m / 2, (dt_min, dt_max), &mut each)
        } else {
            let lo = kth_smallest(m / 2 - 1, (dt_min, dt_max), &mut each);
            0.5 * (lo + kth_smallest(m / 2, (dt_min, dt_max), &mut each))
        };
        // One more pass: the spread of the steps, and gaps (resampling would bridge a gap with a
        // straight line, and the filters would smear it).
        let mean = sum / m as f64;
        let mut ss = 0.0;
        steps(&mut |row, dt, t, prev| {
            if dt > GAP_STEPS * dt_median {
                return Err(DerivativeError::Gap {
                    row: row + 1,
                    t,
                    prev,
                    dt_median,
                });
            }
            ss += (dt - mean).powi(2);
            Ok(())
        })?;
        Ok(Sampling {
            n,
            dt_median,
            dt_min,
            dt_max,
            dt_std: (ss / m as f64).sqrt(),
            uniform: dt_max - dt_min <= 1e-6 * dt_median,
        })
    }

    /// Sampling rate of the (possibly resampled) uniform grid.
    pub fn fs(&self) -> f64 {
        1.0 / self.dt_median
    }
}

/// A uniform time grid `t0 + k·dt`, `k = 0..n`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Grid {
    pub t0: f64,
    pub dt: f64,
    pub n: usize,
}

impl Grid {
    pub fn time(&self, k: usize) -> f64 {
        self.t0 + k as f64 * self.dt
    }
}

/// Linear interpolation of samples `(t, x)` onto `grid` (`t` strictly increasing, grid inside).
pub fn resample_linear(t: &[f64], x: &[f64], grid: &Grid) -> Vec<f64> {
    let mut out = Vec::with_capacity(grid.n);
    let mut j = 0usize;
    for k in 0..grid.n {
        let tk = grid.time(k);
        while j + 2 < t.len() && t[j + 1] < tk {
            j += 1;
        }
        let (ta, tb) = (t[j], t[j + 1]);
        let w = ((tk - ta) / (tb - ta)).clamp(0.0, 1.0);
        out.push(x[j] + w * (x[j + 1] - x[j]));
    }
    out
}

// ---------------------------------------------------------------------------------------------
// Zero-phase filters
// ---------------------------------------------------------------------------------------------

/// A linear zero-phase low-pass filter applied to a window of a longer uniformly sampled signal.
///
/// `pad_left`/`pad_right` say whether the window starts/ends at the true end of the signal (then
/// the filter's end treatment is applied); otherwise the caller keeps [`ZeroPhase::reach`] samples
/// of margin on that side and discards them, which makes chunked filtering equal to whole-signal
/// filtering to ~1e-8 relative.
pub trait ZeroPhase: Sync {
    fn apply(&self, x: &mut [f64], pad_left: bool, pad_right: bool);
    /// [`ZeroPhase::apply`] on several channels of equal length (a filter may run them side by
    /// side; the result is the same).
    fn apply_many(&self, xs: &mut [&mut [f64]], pad_left: bool, pad_right: bool) {
        for x in xs.iter_mut() {
            self.apply(x, pad_left, pad_right);
        }
    }
    /// Samples beyond which the filter's influence is negligible (≈1e-8 relative).
    fn reach(&self) -> usize;
    /// Amplitude gain at frequency `f` (Hz).
    fn gain(&self, f: f64) -> f64;
    /// Short description for reports.
    fn describe(&self) -> String;
}

#[derive(Debug, Clone, Copy)]
struct Biquad {
    b: [f64; 3],
    a: [f64; 2], // a1, a2 (a0 = 1)
}

impl Biquad {
    /// The sections in cascade (direct form II transposed, each starting from the steady state
    /// for its own first input) over `L` interleaved channels in the order the iterator gives,
    /// fused into one sweep.
    fn cascade_lanes<'a, const L: usize>(
        sections: &[Biquad],
        mut x: impl Iterator<Item = &'a mut [f64; L]>,
    ) {
        let Some(first) = x.next() else { return };
        let m = sections.len();
        let mut z = vec![([0.0; L], [0.0; L]); m];
        for (s, (z1, z2)) in sections.iter().zip(z.iter_mut()) {
            for l in 0..L {
                z2[l] = (s.b[2] - s.a[1]) * first[l];
                z1[l] = (s.b[1] - s.a[0]) * first[l] + z2[l];
            }
            s.step_lanes(first, z1, z2);
        }
        for v in x {
            for (s, (z1, z2)) in sections.iter().zip(z.iter_mut()) {
                s.step_lanes(v, z1, z2);
            }
        }
    }

    #[inline(always)]
    fn step_lanes<const L: usize>(&self, v: &mut [f64; L], z1: &mut [f64; L], z2: &mut [f64; L]) {
        for l in 0..L {
            let xi = v[l];
            let y = self.b[0] * xi + z1[l];
            z1[l] = self.b[1] * xi - self.a[0] * y + z2[l];
            z2[l] = self.b[2] * xi - self.a[1] * y;
            v[l] = y;
        }
    }

    fn response(&self, w: f64) -> (f64, f64) {
        // H(e^{jw}) = (b0 + b1 z^-1 + b2 z^-2) / (1 + a1 z^-1 + a2 z^-2)
        let (c1, s1, c2, s2) = (w.cos(), -w.sin(), (2.0 * w).cos(), -(2.0 * w).sin());
        let nr = self.b[0] + self.b[1] * c1 + self.b[2] * c2;
        let ni = self.b[1] * s1 + self.b[2] * s2;
        let dr = 1.0 + self.a[0] * c1 + self.a[1] * c2;
        let di = self.a[0] * s1 + self.a[1] * s2;
        let d2 = dr * dr + di * di;
        ((nr * dr + ni * di) / d2, (ni * dr - nr * di) / d2)
    }
}

/// Digital Butterworth low-pass (bilinear transform with pre-warping), as second-order sections.
#[derive(Debug, Clone)]
pub struct Butterworth {
    sections: Vec<Biquad>,
    order: usize,
    fc: f64,
    fs: f64,
}

impl Butterworth {
    /// Design an `order`-th order low-pass with cut-off `fc` (−3 dB for one pass, −6 dB forward and
    /// backward) at sampling rate `fs`.
    pub fn lowpass(order: usize, fc: f64, fs: f64) -> Result<Self, DerivativeError> {
        if !(1..=12).contains(&order) {
            return Err(DerivativeError::BadOrder(order));
        }
        let max = 0.45 * fs;
        if !(fc.is_finite() && fc > 0.0 && fc < max) {
            return Err(DerivativeError::BadCutoff { fc, max, fs });
        }
        let k = 2.0 * fs;
        let wc = k * (PI * fc / fs).tan();
        let mut sections = Vec::new();
        for i in 1..=order / 2 {
            let theta = PI * (2 * i + order - 1) as f64 / (2 * order) as f64;
            let a = -2.0 * wc * theta.cos(); // > 0
            let d0 = k * k + a * k + wc * wc;
            let d1 = 2.0 * (wc * wc - k * k);
            let d2 = k * k - a * k + wc * wc;
            let g = wc * wc / d0;
            sections.push(Biquad {
                b: [g, 2.0 * g, g],
                a: [d1 / d0, d2 / d0],
            });
        }
        if order % 2 == 1 {
            let d0 = k + wc;
            let g = wc / d0;
            sections.push(Biquad {
                b: [g, g, 0.0],
                a: [(wc - k) / d0, 0.0],
            });
        }
        Ok(Butterworth {
            sections,
            order,
            fc,
            fs,
        })
    }

    pub fn cutoff(&self) -> f64 {
        self.fc
    }

    pub fn order(&self) -> usize {
        self.order
    }

    /// Zero-phase filtering of `L` equally long channels at once, interleaved so the recursions
    /// of all channels and sections run side by side in one sweep each way (per channel the
    /// same operations whatever `L`, so the same numbers bit for bit). Odd reflection about the
    /// end points (value and slope continuous) pads the ends that are the signal's own.
    fn apply_lanes<const L: usize>(&self, xs: &mut [&mut [f64]], pad_left: bool, pad_right: bool) {
        let n = xs[0].len();
        if n < 2 {
            return;
        }
        let p = self.pad_len().min(n - 1);
        let (pl, pr) = (if pad_left { p } else { 0 }, if pad_right { p } else { 0 });
        let len = n + pl + pr;
        let mut ext = vec![[0.0f64; L]; len];
        for (l, x) in xs.iter().enumerate() {
            for i in 1..=pl {
                ext[pl - i][l] = 2.0 * x[0] - x[i];
            }
            for k in 0..n {
                ext[pl + k][l] = x[k];
            }
            for i in 1..=pr {
                ext[pl + n - 1 + i][l] = 2.0 * x[n - 1] - x[n - 1 - i];
            }
        }
        Biquad::cascade_lanes(&self.sections, ext.iter_mut());
        Biquad::cascade_lanes(&self.sections, ext.iter_mut().rev());
        for (l, x) in xs.iter_mut().enumerate() {
            for k in 0..n {
                x[k] = ext[pl + k][l];
            }
        }
    }

    /// Zero-phase filtering of a whole signal (odd-reflection padding at both ends).
    pub fn filtfilt(&self, x: &mut [f64]) {
        self.apply(x, true, true);
    }

    fn pad_len(&self) -> usize {
        // About three time constants of the slowest pole: enough for the start-up transient of
        // the padded signal to die out before the true data begins.
        (1.25 * self.fs / self.fc).ceil() as usize
    }
}

impl ZeroPhase for Butterworth {
    fn apply(&self, x: &mut [f64], pad_left: bool, pad_right: bool) {
        self.apply_lanes::<1>(&mut [x], pad_left, pad_right);
    }

    fn apply_many(&self, xs: &mut [&mut [f64]], pad_left: bool, pad_right: bool) {
        // Eight channels hide the latency of the recursions; the rest go by four, then alone.
        let wide = xs.len() / 8 * 8;
        let (a, rest) = xs.split_at_mut(wide);
        for group in a.chunks_mut(8) {
            self.apply_lanes::<8>(group, pad_left, pad_right);
        }
        let mid = rest.len() / 4 * 4;
        let (b, rest) = rest.split_at_mut(mid);
        for group in b.chunks_mut(4) {
            self.apply_lanes::<4>(group, pad_left, pad_right);
        }
        for x in rest.iter_mut() {
            self.apply(x, pad_left, pad_right);
        }
    }

    fn reach(&self) -> usize {
        // Slowest pole pair decays with time constant ≈ 0.42/fc (4th order; less for lower
        // orders); 18 time constants ≈ 1.5e-8.
        (7.5 * self.fs / self.fc).ceil() as usize
    }

    fn gain(&self, f: f64) -> f64 {
        let w = 2.0 * PI * f / self.fs;
        let mut g = 1.0;
        for s in &self.sections {
            let (re, im) = s.response(w);
            g *= re * re + im * im; // |H|² = gain of the forward–backward pair
        }
        g
    }

    fn describe(&self) -> String {
        format!(
            "Butterworth order {} low-pass, run forward and backward (zero phase, -6 dB at {:.3} Hz)",
            self.order, self.fc
        )
    }
}

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

// ---------------------------------------------------------------------------------------------
// Finite differences
// ---------------------------------------------------------------------------------------------

/// First and second derivatives of a uniformly sampled signal: 5-point central differences
/// inside, 3-point one-sided formulas at the two ends.
pub fn central_uniform(x: &[f64], dt: f64) -> (Vec<f64>, Vec<f64>) {
    let n = x.len();
    let mut d1 = vec![0.0; n];
    let mut d2 = vec![0.0; n];
    if n < 5 {
        let t: Vec<f64> = (0..n).map(|k| k as f64 * dt).collect();
        return central_uneven(&t, x);
    }
    for k in 2..n - 2 {
        d1[k] = (-x[k + 2] + 8.0 * x[k + 1] - 8.0 * x[k - 1] + x[k - 2]) / (12.0 * dt);
        d2[k] = (-x[k + 2] + 16.0 * x[k + 1] - 30.0 * x[k] + 16.0 * x[k - 1] - x[k - 2])
            / (12.0 * dt * dt);
    }
    for k in [1, n - 2] {
        d1[k] = (x[k + 1] - x[k - 1]) / (2.0 * dt);
        d2[k] = (x[k + 1] - 2.0 * x[k] + x[k - 1]) / (dt * dt);
    }
    d1[0] = (-3.0 * x[0] + 4.0 * x[1] - x[2]) / (2.0 * dt);
    d1[n - 1] = (3.0 * x[n - 1] - 4.0 * x[n - 2] + x[n - 3]) / (2.0 * dt);
    d2[0] = (2.0 * x[0] - 5.0 * x[1] + 4.0 * x[2] - x[3]) / (dt * dt);
    d2[n - 1] = (2.0 * x[n - 1] - 5.0 * x[n - 2] + 4.0 * x[n - 3] - x[n - 4]) / (dt * dt);
    (d1, d2)
}

/// First and second derivatives on an uneven grid: the exact derivatives of the parabola through
/// each three consecutive samples (second-order accurate); one-sided parabolas at the ends.
pub fn central_uneven(t: &[f64], x: &[f64]) -> (Vec<f64>, Vec<f64>) {
    let n = x.len();
    let mut d1 = vec![0.0; n];
    let mut d2 = vec![0.0; n];
    if n < 3 {
        if n == 2 {
            let s = (x[1] - x[0]) / (t[1] - t[0]);
            d1 = vec![s, s];
        }
        return (d1, d2);
    }
    // Derivatives at `at` of the parabola through (t[i], x[i]) for i = j-1, j, j+1.
    let para = |j: usize, at: f64| -> (f64, f64) {
        let (t0, t1, t2) = (t[j - 1], t[j], t[j + 1]);
        let (x0, x1, x2) = (x[j - 1], x[j], x[j + 1]);
        let l0 = 1.0 / ((t0 - t1) * (t0 - t2));
        let l1 = 1.0 / ((t1 - t0) * (t1 - t2));
        let l2 = 1.0 / ((t2 - t0) * (t2 - t1));
        let d1 = x0 * l0 * ((at - t1) + (at - t2))
            + x1 * l1 * ((at - t0) + (at - t2))
            + x2 * l2 * ((at - t0) + (at - t1));
        let d2 = 2.0 * (x0 * l0 + x1 * l1 + x2 * l2);
        (d1, d2)
    };
    for k in 1..n - 1 {
        (d1[k], d2[k]) = para(k, t[k]);
    }
    (d1[0], d2[0]) = para(1, t[0]);
    (d1[n - 1], d2[n - 1]) = para(n - 2, t[n - 1]);
    (d1, d2)
}

// ---------------------------------------------------------------------------------------------
// Spectrum and automatic cut-off
// ---------------------------------------------------------------------------------------------

/// In-place iterative radix-2 FFT (`re.len()` a power of two).
fn fft(re: &mut [f64], im: &mut [f64]) {
    let n = re.len();
    let mut j = 0usize;
    for i in 1..n {
        let mut bit = n >> 1;
        while j & bit != 0 {
            j ^= bit;
            bit >>= 1;
        }
        j |= bit;
        if i < j {
            re.swap(i, j);
            im.swap(i, j);
        }
    }
    let mut len = 2;
    while len <= n {
        let ang = -2.0 * PI / len as f64;
        let (wr, wi) = (ang.cos(), ang.sin());
        for start in (0..n).step_by(len) {
            let (mut cr, mut ci) = (1.0, 0.0);
            for k in 0..len / 2 {
                let (a, b) = (start + k, start + k + len / 2);
                let tr = re[b] * cr - im[b] * ci;
                let ti = re[b] * ci + im[b] * cr;
                re[b] = re[a] - tr;
                im[b] = im[a] - ti;
                re[a] += tr;
                im[a] += ti;
                let nr = cr * wr - ci * wi;
                ci = cr * wi + ci * wr;
                cr = nr;
            }
        }
        len <<= 1;
    }
}

/// Welch power spectral density (Hann window, 50 % overlap, mean removed per segment).
/// Returns `(frequencies, psd)` for bins `0..=seg/2`.
pub fn welch_psd(x: &[f64], fs: f64, seg: usize) -> (Vec<f64>, Vec<f64>) {
    let seg = seg
        .next_power_of_two()
        .min(x.len().next_power_of_two() / 2)
        .max(8);
    let win: Vec<f64> = (0..seg)
        .map(|i| 0.5 - 0.5 * (2.0 * PI * i as f64 / seg as f64).cos())
        .collect();
    let wpow: f64 = win.iter().map(|w| w * w).sum();
    let nb = seg / 2 + 1;
    let mut psd = vec![0.0; nb];
    let mut count = 0usize;
    let mut start = 0usize;
    let (mut re, mut im) = (vec![0.0; seg], vec![0.0; seg]);
    while start + seg <= x.len() {
        let s = &x[start..start + seg];
        let mean = s.iter().sum::<f64>() / seg as f64;
        for i in 0..seg {
            re[i] = (s[i] - mean) * win[i];
            im[i] = 0.0;
        }
        fft(&mut re, &mut im);
        for (k, p) in psd.iter_mut().enumerate() {
            let mut v = (re[k] * re[k] + im[k] * im[k]) / (fs * wpow);
            if k != 0 && k != seg / 2 {
                v *= 2.0;
            }
            *p += v;
        }
        count += 1;
        start += seg / 2;
    }
    if count > 0 {
        psd.iter_mut().for_each(|p| *p /= count as f64);
    }
    let freqs = (0..nb).map(|k| k as f64 * fs / seg as f64).collect();
    (freqs, psd)
}

/// What [`auto_cutoff`] found for one channel.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct ChannelSpectrum {
    /// Median position PSD over the upper half of the band (unit²/Hz).
    pub noise_floor: f64,
    /// Highest frequency where the PSD stands ≥ 2× above the floor (Hz): beyond it the
    /// channel is mostly noise.
    pub noise_edge_hz: f64,
    /// Frequency below which 99 % of the velocity power (floor removed) lies (Hz): the band of
    /// the motion.
    pub motion_band_hz: f64,
    /// The cut-off this channel asks for: `min(5 · motion band, 1.25 · noise edge)`.
    pub cutoff_hz: f64,
}

/// Automatic cut-off: the largest of the channels' choices (see [`ChannelSpectrum`]), clamped to
/// `[4/T, 0.2·fs]` for a record of `len` samples. Five times the motion band keeps the pass
/// band flat where the dynamics live (the classic rule for identification filters); the noise
/// edge caps it where the data hold only noise.
pub fn auto_cutoff(channels: &[Psd], fs: f64, len: usize) -> (f64, Vec<ChannelSpectrum>) {
    let mut per = Vec::new();
    let mut fc = 0.0f64;
    for p in channels {
        let c = channel_spectrum(p, fs);
        fc = fc.max(c.cutoff_hz);
        per.push(c);
    }
    let lo = (4.0 * fs / len.max(1) as f64).min(0.02 * fs);
    (fc.clamp(lo, 0.2 * fs), per)
}

/// Welch periodogram of a channel's second difference (which whitens the spectrum: less window
/// leakage), summed over pieces of equal length so a long record is judged piece by piece.
/// Segments of a quarter of a piece give fine low-frequency resolution for the motion band.
#[derive(Debug, Clone)]
pub struct Psd {
    freqs: Vec<f64>,
    sum: Vec<f64>,
    count: usize,
}

impl Psd {
    pub fn of(x: &[f64], fs: f64) -> Psd {
        let n = x.len();
        if n < 16 {
            return Psd {
                freqs: Vec::new(),
                sum: Vec::new(),
                count: 0,
            };
        }
        let d2: Vec<f64> = (1..n - 1)
            .map(|k| x[k + 1] - 2.0 * x[k] + x[k - 1])
            .collect();
        let seg = (d2.len() / 4).max(256).min(d2.len());
        let (freqs, sum) = welch_psd(&d2, fs, seg);
        Psd {
            freqs,
            sum,
            count: 1,
        }
    }

    /// Adds another piece's periodogram (same length, so the same bins).
    pub fn add(&mut self, o: &Psd) {
        if o.freqs.len() == self.freqs.len() {
            self.sum.iter_mut().zip(&o.sum).for_each(|(a, b)| *a += b);
            self.count += o.count;
        }
    }
}

fn channel_spectrum(p: &Psd, fs: f64) -> ChannelSpectrum {
    if p.count == 0 {
        let f = 0.2 * fs;
        return ChannelSpectrum {
            noise_floor: 0.0,
            noise_edge_hz: f,
            motion_band_hz: f,
            cutoff_hz: f,
        };
    }
    // Undo the second difference's gain |2 sin(πf/fs)|⁴ per bin.
    let f = &p.freqs;
    let nb = f.len();
    let psd: Vec<f64> = (0..nb)
        .map(|k| {
            let g = (2.0 * (PI * f[k] / fs).sin()).powi(4);
            if g > 0.0 {
                p.sum[k] / p.count as f64 / g
            } else {
                0.0
            }
        })
        .collect();
    let mut upper: Vec<f64> = psd[nb / 2..].to_vec();
    let floor = median(&mut upper);
    // Smooth over ±10 % in frequency, at least ±2 bins (geometric mean), to tame the
    // periodogram's scatter.
    let mut cum = vec![0.0; nb + 1];
    for k in 0..nb {
        cum[k + 1] = cum[k] + psd[k].max(1e-300).ln();
    }
    let smooth: Vec<f64> = (0..nb)
        .map(|k| {
            let w = (k / 10).max(2);
            let (a, b) = (k.saturating_sub(w), (k + w + 1).min(nb));
            ((cum[b] - cum[a]) / (b - a) as f64).exp()
        })
        .collect();
    let mut edge = f[1.min(nb - 1)];
    for k in (1..nb).rev() {
        if smooth[k] > 2.0 * floor {
            edge = f[k];
            break;
        }
    }
    let vel: Vec<f64> = (0..nb)
        .map(|k| (2.0 * PI * f[k]).powi(2) * (psd[k] - floor).max(0.0))
        .collect();
    let total: f64 = vel.iter().sum();
    let mut band = edge;
    let mut acc = 0.0;
    for k in 0..nb {
        acc += vel[k];
        if acc >= 0.99 * total {
            band = f[k].max(f[1.min(nb - 1)]);
            break;
        }
    }
    ChannelSpectrum {
        noise_floor: floor,
        noise_edge_hz: edge,
        motion_band_hz: band,
        cutoff_hz: (5.0 * band).min(1.25 * edge),
    }
}

/// Visits every value of a collection with the callback it is given.
type Visit<'a> = dyn FnMut(&mut dyn FnMut(f64)) + 'a;

/// Pieces in which long signals are read (times, spectra): 65536 samples.
const PIECE: usize = 1 << 16;

/// The `k`-th smallest (0-based) of the values that `each` visits (all within `range`, the
/// values' min and max), exactly, without holding them: histogram passes narrow the range to
/// the bin holding rank `k` until few enough values are left to sort.
fn kth_smallest(k: usize, range: (f64, f64), each: &mut Visit) -> f64 {
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

fn median(v: &mut [f64]) -> f64 {
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

// ---------------------------------------------------------------------------------------------
// The estimator
// ---------------------------------------------------------------------------------------------

/// Which estimator to use.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum Method {
    /// Zero-phase Butterworth (4th order) + 5-point central differences.
    #[default]
    Butterworth,
    /// Savitzky–Golay (degree [`SG_DEGREE`]) with the window matched to the cut-off.
    SavitzkyGolay,
}

/// Options of [`estimate`].
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Options {
    pub method: Method,
    /// Cut-off in Hz; `None` = automatic from the spectrum.
    pub cutoff_hz: Option<f64>,
}

/// The filter that was built, shared by derivative estimation and parallel filtering.
#[derive(Debug, Clone)]
pub enum Filter {
    Butterworth(Butterworth),
    SavGol(SavGol),
}

impl Filter {
    /// The low-pass of `method` at `fc` (−6 dB): the 4th-order Butterworth or the matched
    /// Savitzky–Golay.
    pub fn lowpass(method: Method, fc: f64, fs: f64) -> Result<Self, DerivativeError> {
        Ok(match method {
            Method::Butterworth => Filter::Butterworth(Butterworth::lowpass(4, fc, fs)?),
            Method::SavitzkyGolay => Filter::SavGol(SavGol::matched(fc, fs)?),
        })
    }

    pub fn as_zero_phase(&self) -> &(dyn ZeroPhase + Sync) {
        match self {
            Filter::Butterworth(b) => b,
            Filter::SavGol(s) => s,
        }
    }
}

/// Everything a report needs to say how derivatives were obtained.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct DerivativeReport {
    pub method: Method,
    pub filter: String,
    pub cutoff_hz: f64,
    pub cutoff_auto: bool,
    pub per_channel: Vec<ChannelSpectrum>,
    pub sampling: Sampling,
    pub resampled: bool,
    /// Where q̇ came from: `"file (filtered)"` or `"estimated"`; same for q̈.
    pub dq_source: String,
    pub ddq_source: String,
    pub fs_hz: f64,
}

/// Filtered positions and derivatives on the uniform grid.
#[derive(Debug, Clone)]
pub struct Estimate {
    pub grid: Grid,
    /// `q[j][k]`: joint j at grid sample k (filtered).
    pub q: Vec<Vec<f64>>,
    pub dq: Vec<Vec<f64>>,
    pub ddq: Vec<Vec<f64>>,
    pub filter: Filter,
    pub report: DerivativeReport,
}

impl Estimate {
    /// Estimated `(q, q̇, q̈)` of joint `j` at time `t` (cubic Hermite for q and q̇, linear for q̈).
    pub fn at(&self, j: usize, t: f64) -> (f64, f64, f64) {
        let g = &self.grid;
        let u = ((t - g.t0) / g.dt).clamp(0.0, (g.n - 1) as f64);
        let k = (u.floor() as usize).min(g.n.saturating_sub(2));
        let s = u - k as f64;
        let h = g.dt;
        let herm = |p0: f64, m0: f64, p1: f64, m1: f64| {
            let (s2, s3) = (s * s, s * s * s);
            (2.0 * s3 - 3.0 * s2 + 1.0) * p0
                + (s3 - 2.0 * s2 + s) * h * m0
                + (-2.0 * s3 + 3.0 * s2) * p1
                + (s3 - s2) * h * m1
        };
        let (q, dq, ddq) = (&self.q[j], &self.dq[j], &self.ddq[j]);
        if g.n < 2 {
            return (q[0], dq[0], ddq[0]);
        }
        (
            herm(q[k], dq[k], q[k + 1], dq[k + 1]),
            herm(dq[k], ddq[k], dq[k + 1], ddq[k + 1]),
            ddq[k] + s * (ddq[k + 1] - ddq[k]),
        )
    }
}

/// The estimator of one file, set up once (sampling, grid, cut-off, filter) and then run window
/// by window ([`Estimator::window`]) on the file's [`Log`], so no copy of the whole log — raw
/// or estimated — is ever needed: each window reads the raw rows it covers plus the filter's
/// reach of margin on both sides, which makes it equal to estimating the whole signal at once
/// to ~1e-7 of the signal's range (test: 7e-8).
#[derive(Debug, Clone)]
pub struct Estimator {
    pub grid: Grid,
    pub filter: Filter,
    pub report: DerivativeReport,
    /// A q̇ column of the file is filtered (instead of differentiating q).
    use_dq: bool,
    /// Derivatives taken from the file as they are (it has q̇ and q̈).
    given: bool,
}

/// Estimated states of grid samples `lo..lo + len`: `q[j][k - lo]`, likewise q̇, q̈.
#[derive(Debug, Clone)]
pub struct States {
    pub lo: usize,
    pub q: Vec<Vec<f64>>,
    pub dq: Vec<Vec<f64>>,
    pub ddq: Vec<Vec<f64>>,
}

/// Grid samples up to which the spectrum of the cut-off choice is taken over the whole signal;
/// a longer one is judged on evenly spaced pieces of 65536 samples (at most
/// [`SPECTRUM_PIECES`]), their periodograms averaged.
pub const SPECTRUM_WHOLE: usize = 1 << 18;
pub const SPECTRUM_PIECES: usize = 16;

impl Estimator {
    /// Checks the samples and sets up the estimator (cut-off automatic from the spectrum unless
    /// given) — see the module docs. A q̇ column is filtered if `file_velocity` (else q is
    /// differentiated); a file with both q̇ and q̈ columns is used as given.
    pub fn new(log: &Log, file_velocity: bool, opts: &Options) -> Result<Self, DerivativeError> {
        let l = log.layout;
        let given = l.dq && l.ddq;
        let use_dq = l.dq && (file_velocity || given);
        let sampling = Sampling::of_log(log)?;
        // The channels used, as offsets of their blocks in the row (channel c·dof + j + 1).
        let n_j = l.dof;
        let used: Vec<usize> = [(true, 1), (use_dq, 1 + n_j), (given, 1 + 2 * n_j)]
            .into_iter()
            .filter_map(|(u, at)| u.then_some(at))
            .collect();
        let (mut r, mut bad) = (0, None);
        log.rows(0, log.len(), |row| {
            if bad.is_none() {
                for (c, &at) in used.iter().enumerate() {
                    if let Some(j) = row[at..at + n_j].iter().position(|v| !v.is_finite()) {
                        bad = Some(DerivativeError::NonFinite {
                            channel: c * n_j + j + 1,
                            row: r,
                        });
                        break;
                    }
                }
            }
            r += 1;
        });
        if let Some(e) = bad {
            return Err(e);
        }
        let grid = grid_for_log(log, &sampling);
        let fs = 1.0 / grid.dt;
        let reader = Reader {
            grid,
            uniform: sampling.uniform,
        };
        let (fc, per_channel) = match opts.cutoff_hz {
            Some(fc) => (fc, Vec::new()),
            None => reader.auto_cutoff(log, use_dq && !given),
        };
        let filter = Filter::lowpass(opts.method, fc, fs)?;
        let (dq_source, ddq_source) = match (use_dq, given) {
            (_, true) => ("file (as given)", "file (as given)"),
            (true, false) => ("file, filtered", "differentiated filtered dq"),
            (false, false) => ("differentiated q", "differentiated q"),
        };
        let report = DerivativeReport {
            method: opts.method,
            filter: filter.as_zero_phase().describe(),
            cutoff_hz: fc,
            cutoff_auto: opts.cutoff_hz.is_none(),
            per_channel,
            sampling,
            resampled: !sampling.uniform,
            dq_source: dq_source.into(),
            ddq_source: ddq_source.into(),
            fs_hz: fs,
        };
        Ok(Estimator {
            grid,
            filter,
            report,
            use_dq,
            given,
        })
    }

    fn reader(&self) -> Reader {
        Reader {
            grid: self.grid,
            uniform: self.report.sampling.uniform,
        }
    }

    /// The measured torque of `log` on grid samples `lo..hi`, per joint.
    pub fn tau_on_grid(&self, log: &Log, lo: usize, hi: usize) -> Vec<Vec<f64>> {
        let w = self.reader().rows_for(log, lo, hi);
        let tau = w.rows.tau.as_deref().unwrap_or(&[]);
        self.reader().on_grid(&w, tau, lo, hi)
    }

    /// Estimated states of `log` on grid samples `lo..hi`.
    pub fn window(&self, log: &Log, lo: usize, hi: usize) -> States {
        let n = self.grid.n;
        let margin = if self.given {
            0
        } else {
            self.filter.as_zero_phase().reach() + 4
        };
        let (mut elo, mut ehi) = (lo.saturating_sub(margin), (hi + margin).min(n));
        // A short window at an end still gets a full margin on its inner side (end treatments
        // such as a Savitzky–Golay end fit or the padding length depend on the length).
        let span = 2 * margin + 1;
        if ehi - elo < span {
            if elo == 0 {
                ehi = span.min(n);
            } else {
                elo = ehi.saturating_sub(span);
            }
        }
        let (pad_left, pad_right) = (elo == 0, ehi == n);
        let dt = self.grid.dt;
        let r = self.reader();
        let w = r.rows_for(log, elo, ehi);
        let g = |x: &[f64]| r.on_grid(&w, x, elo, ehi);
        let qg = g(&w.rows.q);
        let dqg = w.rows.dq.as_deref().filter(|_| self.use_dq).map(g);
        let ddqg = w.rows.ddq.as_deref().filter(|_| self.given).map(g);
        let cut = |x: Vec<f64>| x[lo - elo..hi - elo].to_vec();
        let dof = w.rows.dof;
        let mut st = States {
            lo,
            q: Vec::with_capacity(dof),
            dq: Vec::with_capacity(dof),
            ddq: Vec::with_capacity(dof),
        };
        match (&self.filter, dqg, ddqg) {
            (_, Some(d), Some(dd)) if self.given => {
                (st.q, st.dq, st.ddq) = (qg, d, dd);
                for x in st.q.iter_mut().chain(&mut st.dq).chain(&mut st.ddq) {
                    *x = cut(std::mem::take(x));
                }
            }
            (Filter::Butterworth(bw), dqg, _) => {
                // All channels in one side-by-side sweep.
                let mut q = qg;
                let mut v = dqg.unwrap_or_default();
                let mut chans: Vec<&mut [f64]> = q
                    .iter_mut()
                    .chain(v.iter_mut())
                    .map(|c| c.as_mut_slice())
                    .collect();
                bw.apply_many(&mut chans, pad_left, pad_right);
                for j in 0..dof {
                    let (d1, d2) = if v.is_empty() {
                        central_uniform(&q[j], dt)
                    } else {
                        let a = central_uniform(&v[j], dt).0;
                        (std::mem::take(&mut v[j]), a)
                    };
                    st.q.push(cut(std::mem::take(&mut q[j])));
                    st.dq.push(cut(d1));
                    st.ddq.push(cut(d2));
                }
            }
            (Filter::SavGol(sg), dqg, _) => {
                for (j, qj) in qg.iter().enumerate() {
                    let [a, b, c] = sg.derivatives_ends(qj, pad_left, pad_right);
                    let (b, c) = match &dqg {
                        Some(d) => {
                            let [v, acc, _] = sg.derivatives_ends(&d[j], pad_left, pad_right);
                            (v, acc)
                        }
                        None => (b, c),
                    };
                    st.q.push(cut(a));
                    st.dq.push(cut(b));
                    st.ddq.push(cut(c));
                }
            }
        }
        st
    }
}

/// How a log's raw rows map onto an estimator's grid.
#[derive(Debug, Clone, Copy)]
struct Reader {
    grid: Grid,
    uniform: bool,
}

impl Reader {
    /// The spectrum's cut-off ([`auto_cutoff`]) over the positions, and over the q̇ channels
    /// if `integrate_dq` (integrated, so their spectrum is judged like q's by one rule).
    fn auto_cutoff(&self, log: &Log, integrate_dq: bool) -> (f64, Vec<ChannelSpectrum>) {
        let n = self.grid.n;
        let pieces: Vec<(usize, usize)> = if n <= SPECTRUM_WHOLE {
            vec![(0, n)]
        } else {
            let count = (n / PIECE).min(SPECTRUM_PIECES);
            let gap = (n - count * PIECE) / count;
            (0..count)
                .map(|i| {
                    let a = gap / 2 + i * (PIECE + gap);
                    (a, a + PIECE)
                })
                .collect()
        };
        let fs = 1.0 / self.grid.dt;
        let mut psd: Vec<Option<Psd>> = Vec::new();
        for &(lo, hi) in &pieces {
            let w = self.rows_for(log, lo, hi);
            let mut chans = self.on_grid(&w, &w.rows.q, lo, hi);
            if let (Some(d), true) = (&w.rows.dq, integrate_dq) {
                for x in self.on_grid(&w, d, lo, hi) {
                    let mut acc = 0.0;
                    chans.push(
                        x.iter()
                            .map(|v| {
                                acc += v * self.grid.dt;
                                acc
                            })
                            .collect(),
                    );
                }
            }
            psd.resize_with(chans.len(), || None);
            for (p, x) in psd.iter_mut().zip(&chans) {
                let piece = Psd::of(x, fs);
                match p {
                    Some(p) => p.add(&piece),
                    None => *p = Some(piece),
                }
            }
        }
        let psd: Vec<Psd> = psd.into_iter().flatten().collect();
        auto_cutoff(&psd, fs, n)
    }

    /// The raw rows covering grid samples `lo..hi` (one more on each side if resampled), and
    /// the first one's index.
    fn rows_for(&self, log: &Log, lo: usize, hi: usize) -> Window {
        if self.uniform {
            return Window {
                r0: lo,
                rows: log.read(lo, hi),
            };
        }
        let g = &self.grid;
        let (t0, t1) = (g.time(lo), g.time(hi.max(lo + 1) - 1));
        let r0 = log.partition_point(|v| v <= t0).saturating_sub(1);
        let r1 = (log.partition_point(|v| v < t1) + 1).min(log.len() - 1);
        let (r0, r1) = (r0.min(r1.saturating_sub(1)), r1.max(1));
        Window {
            r0,
            rows: log.read(r0, r1 + 1),
        }
    }

    /// Channel `x` (row-major, of the window's rows) on grid samples `lo..hi`, per joint
    /// (resampled linearly if the sampling is uneven).
    fn on_grid(&self, w: &Window, x: &[f64], lo: usize, hi: usize) -> Vec<Vec<f64>> {
        let dof = w.rows.dof;
        if self.uniform {
            return (0..dof)
                .map(|j| (lo..hi).map(|k| x[(k - w.r0) * dof + j]).collect())
                .collect();
        }
        let sub = Grid {
            t0: self.grid.time(lo),
            dt: self.grid.dt,
            n: hi - lo,
        };
        (0..dof)
            .map(|j| {
                let xs: Vec<f64> = (0..w.rows.len()).map(|k| x[k * dof + j]).collect();
                resample_linear(&w.rows.t, &xs, &sub)
            })
            .collect()
    }
}

/// Raw rows of a log read for a window of grid samples: `rows` are the log's rows `r0..`.
struct Window {
    r0: usize,
    rows: Trajectory,
}

/// The uniform grid of a log: its samples themselves if uniform, else `[t0, t_end]` at the
/// median step (only the first and last times are read).
fn grid_for_log(log: &Log, s: &Sampling) -> Grid {
    let (t0, t1, n) = (log.t(0), log.t(log.len() - 1), log.len());
    if s.uniform {
        return Grid {
            t0,
            dt: (t1 - t0) / (n - 1) as f64,
            n,
        };
    }
    Grid {
        t0,
        dt: s.dt_median,
        n: ((t1 - t0) / s.dt_median).floor() as usize + 1,
    }
}

/// Estimates filtered `q, q̇, q̈` on a uniform grid from samples `t`, `q[j]` and optionally
/// measured `dq[j]` (then q̈ comes from differentiating the filtered q̇, and the cut-off is chosen
/// from both) — see the module docs. The whole signal as one [`Estimator::window`].
pub fn estimate(
    t: &[f64],
    q: &[Vec<f64>],
    dq: Option<&[Vec<f64>]>,
    opts: &Options,
) -> Result<Estimate, DerivativeError> {
    let dof = q.len();
    let rows = |c: &[Vec<f64>]| -> Vec<f64> {
        (0..t.len())
            .flat_map(|k| c.iter().map(move |x| x.get(k).copied().unwrap_or(f64::NAN)))
            .collect()
    };
    let log = Log::from(Trajectory {
        source: String::new(),
        dof,
        t: t.to_vec(),
        q: rows(q),
        dq: dq.map(rows),
        ddq: None,
        tau: None,
    });
    let e = Estimator::new(&log, true, opts)?;
    let st = e.window(&log, 0, e.grid.n);
    Ok(Estimate {
        grid: e.grid,
        q: st.q,
        dq: st.dq,
        ddq: st.ddq,
        filter: e.filter,
        report: e.report,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sines(t: f64) -> (f64, f64, f64) {
        // Sum of sines with known derivatives, content up to 1.5 Hz.
        let comps = [(0.3, 0.8, 0.2), (0.9, 0.4, 1.0), (1.5, 0.15, -0.5)];
        let (mut q, mut dq, mut ddq) = (0.0, 0.0, 0.0);
        for (f, a, ph) in comps {
            let w = 2.0 * PI * f;
            q += a * (w * t + ph).sin();
            dq += a * w * (w * t + ph).cos();
            ddq -= a * w * w * (w * t + ph).sin();
        }
        (q, dq, ddq)
    }

    /// The textbook form: each section over the whole padded signal in turn, reverse, again,
    /// reverse back.
    fn reference_filtfilt(f: &Butterworth, x: &[f64], pad_left: bool, pad_right: bool) -> Vec<f64> {
        let n = x.len();
        let p = f.pad_len().min(n - 1);
        let (pl, pr) = (if pad_left { p } else { 0 }, if pad_right { p } else { 0 });
        let mut ext: Vec<f64> = (1..=pl).rev().map(|i| 2.0 * x[0] - x[i]).collect();
        ext.extend_from_slice(x);
        ext.extend((1..=pr).map(|i| 2.0 * x[n - 1] - x[n - 1 - i]));
        let pass = |v: &mut Vec<f64>| {
            for s in &f.sections {
                let x0 = v[0];
                let mut z2 = (s.b[2] - s.a[1]) * x0;
                let mut z1 = (s.b[1] - s.a[0]) * x0 + z2;
                for e in v.iter_mut() {
                    let xi = *e;
                    let y = s.b[0] * xi + z1;
                    z1 = s.b[1] * xi - s.a[0] * y + z2;
                    z2 = s.b[2] * xi - s.a[1] * y;
                    *e = y;
                }
            }
        };
        pass(&mut ext);
        ext.reverse();
        pass(&mut ext);
        ext.reverse();
        ext[pl..pl + n].to_vec()
    }

    #[test]
    fn side_by_side_filtering_equals_one_channel_at_a_time() {
        // 13 channels: a group of 8, one of 4 and one alone, with and without end padding; order 5
        // includes the first-order section.
        for order in [4, 5] {
            let f = Butterworth::lowpass(order, 3.0, 200.0).unwrap();
            for (pl, pr) in [(true, true), (false, true), (true, false), (false, false)] {
                let chans: Vec<Vec<f64>> = (0..13)
                    .map(|c| {
                        (0..700)
                            .map(|k| sines(k as f64 * 0.005 + c as f64).0 + 0.01 * c as f64)
                            .collect()
                    })
                    .collect();
                let one: Vec<Vec<f64>> = chans
                    .iter()
                    .map(|x| reference_filtfilt(&f, x, pl, pr))
                    .collect();
                let mut alone = chans.clone();
                for x in &mut alone {
                    f.apply(x, pl, pr);
                }
                assert_eq!(one, alone, "order {order}, pads {pl} {pr}");
                let mut many = chans.clone();
                let mut refs: Vec<&mut [f64]> = many.iter_mut().map(|v| v.as_mut_slice()).collect();
                f.apply_many(&mut refs, pl, pr);
                assert_eq!(one, many, "order {order}, pads {pl} {pr}");
                assert_ne!(one, chans);
            }
        }
    }

    #[test]
    fn butterworth_has_unit_dc_gain_and_minus_6db_at_cutoff() {
        let f = Butterworth::lowpass(4, 7.0, 500.0).unwrap();
        assert!((f.gain(0.0) - 1.0).abs() < 1e-12);
        assert!((f.gain(7.0) - 0.5).abs() < 1e-9);
        assert!(f.gain(30.0) < 1e-4);
        let f3 = Butterworth::lowpass(3, 7.0, 500.0).unwrap();
        assert!((f3.gain(7.0) - 0.5).abs() < 1e-9);
    }

    #[test]
    fn rejects_bad_cutoff_and_order() {
        assert!(matches!(
            Butterworth::lowpass(4, 300.0, 500.0),
            Err(DerivativeError::BadCutoff { .. })
        ));
        assert!(matches!(
            Butterworth::lowpass(0, 3.0, 500.0),
            Err(DerivativeError::BadOrder(0))
        ));
        assert!(Butterworth::lowpass(4, f64::NAN, 500.0).is_err());
    }

    #[test]
    fn filtfilt_has_no_phase_lag_and_keeps_a_constant() {
        let fs = 500.0;
        let f = Butterworth::lowpass(4, 10.0, fs).unwrap();
        let mut c = vec![3.0; 1000];
        f.filtfilt(&mut c);
        assert!(c.iter().all(|v| (v - 3.0).abs() < 1e-12));
        let x: Vec<f64> = (0..5000).map(|k| sines(k as f64 / fs).0).collect();
        let mut y = x.clone();
        f.filtfilt(&mut y);
        let err = x[500..4500]
            .iter()
            .zip(&y[500..4500])
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        // gain at 1.5 Hz: 1/(1+(0.15)^8) - 1 ≈ -2.6e-7 of 0.15 amplitude
        assert!(err < 1e-6, "{err}");
    }

    #[test]
    fn chunked_filtering_matches_whole_signal() {
        let fs = 200.0;
        let f = Butterworth::lowpass(4, 4.0, fs).unwrap();
        let x: Vec<f64> = (0..4000)
            .map(|k| sines(k as f64 / fs).0 + ((k * 7919) % 13) as f64 * 0.01)
            .collect();
        let mut whole = x.clone();
        f.filtfilt(&mut whole);
        let r = f.reach();
        let (a, b) = (1500, 2500);
        let mut win = x[a - r..b + r].to_vec();
        f.apply(&mut win, false, false);
        let err = (a..b)
            .map(|k| (win[k - a + r] - whole[k]).abs())
            .fold(0.0, f64::max);
        assert!(err < 1e-7, "{err}");
    }

    #[test]
    fn butterworth_derivatives_match_analytic_ones() {
        let fs = 500.0;
        let n = 10_000;
        let t: Vec<f64> = (0..n).map(|k| k as f64 / fs).collect();
        // Quantise like a 2^17-count encoder: the noise the estimator must reject.
        let res = 2.0 * PI / 131072.0;
        let q: Vec<f64> = t
            .iter()
            .map(|&t| (sines(t).0 / res).round() * res)
            .collect();
        let est = estimate(&t, &[q], None, &Options::default()).unwrap();
        let fc = est.report.cutoff_hz;
        assert!(fc > 1.5 && fc < 20.0, "auto cut-off {fc}");
        let (mut e1, mut e2) = (0.0f64, 0.0f64);
        #[allow(clippy::needless_range_loop)]
        for k in n / 10..9 * n / 10 {
            let (_, dq, ddq) = sines(t[k]);
            e1 = e1.max((est.dq[0][k] - dq).abs());
            e2 = e2.max((est.ddq[0][k] - ddq).abs());
        }
        // |dq| ≤ 4.5 rad/s, |ddq| ≤ 25 rad/s²: errors well below 1 %.
        assert!(e1 < 0.01 && e2 < 0.15, "dq err {e1}, ddq err {e2}, fc {fc}");
    }

    #[test]
    fn savgol_derivatives_match_analytic_ones_and_are_exact_on_cubics() {
        let dt = 0.01;
        let sg = SavGol::new(6, 3, dt);
        let x: Vec<f64> = (0..100)
            .map(|k| {
                let t = k as f64 * dt;
                1.0 + 2.0 * t - 3.0 * t * t + 0.5 * t * t * t
            })
            .collect();
        let [s, d1, d2] = sg.derivatives(&x);
        for k in 0..100 {
            let t = k as f64 * dt;
            assert!((s[k] - x[k]).abs() < 1e-9);
            assert!((d1[k] - (2.0 - 6.0 * t + 1.5 * t * t)).abs() < 1e-7, "{k}");
            assert!((d2[k] - (-6.0 + 3.0 * t)).abs() < 1e-5, "{k}");
        }
        let fs = 500.0;
        let t: Vec<f64> = (0..5000).map(|k| k as f64 / fs).collect();
        let q: Vec<f64> = t.iter().map(|&t| sines(t).0).collect();
        let est = estimate(
            &t,
            &[q],
            None,
            &Options {
                method: Method::SavitzkyGolay,
                cutoff_hz: Some(10.0),
            },
        )
        .unwrap();
        let sg = match &est.filter {
            Filter::SavGol(s) => s.clone(),
            Filter::Butterworth(_) => unreachable!(),
        };
        assert!((sg.gain(10.0) - 0.5).abs() < 0.05);
        #[allow(clippy::needless_range_loop)]
        for k in 200..4800 {
            let (_, dq, ddq) = sines(t[k]);
            assert!(
                (est.dq[0][k] - dq).abs() < 2e-3 && (est.ddq[0][k] - ddq).abs() < 0.05,
                "{k}"
            );
        }
    }

    #[test]
    fn uneven_central_differences_are_exact_on_parabolas() {
        let t = [0.0, 0.1, 0.25, 0.3, 0.5, 0.52];
        let x: Vec<f64> = t.iter().map(|t| 1.0 - 2.0 * t + 4.0 * t * t).collect();
        let (d1, d2) = central_uneven(&t, &x);
        for k in 0..t.len() {
            assert!((d1[k] - (-2.0 + 8.0 * t[k])).abs() < 1e-10);
            assert!((d2[k] - 8.0).abs() < 1e-9);
        }
    }

    #[test]
    fn uneven_sampling_is_resampled_and_reported() {
        let mut t = Vec::new();
        let mut tk = 0.0;
        for k in 0..6000 {
            t.push(tk);
            tk += if k % 97 == 0 { 0.0035 } else { 0.002 } + 1e-5 * ((k * 31) % 7) as f64;
        }
        let q: Vec<f64> = t.iter().map(|&t| sines(t).0).collect();
        let est = estimate(
            &t,
            &[q],
            None,
            &Options {
                cutoff_hz: Some(8.0),
                ..Default::default()
            },
        )
        .unwrap();
        assert!(est.report.resampled && !est.report.sampling.uniform);
        assert!(est.report.sampling.dt_max > 0.0035);
        for &tk in &t[600..5400] {
            let (q, dq, ddq) = est.at(0, tk);
            let (qe, dqe, ddqe) = sines(tk);
            assert!(
                (q - qe).abs() < 5e-5 && (dq - dqe).abs() < 1e-3 && (ddq - ddqe).abs() < 0.02,
                "t={tk}"
            );
        }
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

    /// Windows with the filter's reach of margin reproduce the whole-signal estimate (the claim
    /// that lets identification never hold a long log's states): uneven times, two joints, with
    /// and without a q̇ column, both filters; windows cut anywhere, including at the ends.
    #[test]
    fn windows_equal_the_whole_signal_estimate() {
        let mut t = Vec::new();
        let mut tk = 0.0;
        for k in 0..9000 {
            t.push(tk);
            tk += if k % 89 == 0 { 0.003 } else { 0.002 } + 1e-5 * ((k * 13) % 5) as f64;
        }
        let rows = |f: fn((f64, f64, f64)) -> f64| -> Vec<f64> {
            t.iter()
                .flat_map(|&tk| [f(sines(tk)), 0.5 * f(sines(1.3 * tk + 0.2))])
                .collect()
        };
        let (q, dq) = (rows(|s| s.0), rows(|s| s.1));
        let mut worst = 0.0f64;
        for method in [Method::Butterworth, Method::SavitzkyGolay] {
            for with_dq in [false, true] {
                let log = Log::from(Trajectory {
                    source: String::new(),
                    dof: 2,
                    t: t.clone(),
                    q: q.clone(),
                    dq: with_dq.then(|| dq.clone()),
                    ddq: None,
                    tau: None,
                });
                let opts = Options {
                    method,
                    cutoff_hz: Some(6.0),
                };
                let e = Estimator::new(&log, true, &opts).unwrap();
                let n = e.grid.n;
                let whole = e.window(&log, 0, n);
                for (lo, hi) in [(0, 700), (1234, 4321), (4000, n), (n - 1, n)] {
                    let w = e.window(&log, lo, hi);
                    assert_eq!((w.lo, w.q[1].len()), (lo, hi - lo));
                    let pairs = [(&w.q, &whole.q), (&w.dq, &whole.dq), (&w.ddq, &whole.ddq)];
                    for (c, (a, b)) in pairs.into_iter().enumerate() {
                        for j in 0..2 {
                            let scale = b[j].iter().fold(0.0f64, |m, v| m.max(v.abs()));
                            let d = (lo..hi)
                                .map(|k| (a[j][k - lo] - b[j][k]).abs())
                                .fold(0.0, f64::max);
                            assert!(
                                d <= 1e-6 * scale,
                                "{method:?} dq {with_dq} [{lo},{hi}) j{j} channel {c}: {d} of {scale}"
                            );
                            worst = worst.max(d / scale);
                        }
                    }
                }
            }
        }
        println!("largest window/whole difference: {worst:.1e} of the channel's range");
    }

    /// The piecewise sampling statistics equal the direct ones, the median exactly: spread
    /// steps (histogram refinement), nearly all steps equal with rare late cycles (one bin
    /// holds almost everything), odd and even step counts.
    #[test]
    fn streamed_sampling_statistics_equal_the_direct_ones() {
        let mut x = 12345u64;
        let mut uniform = move || {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            (x >> 11) as f64 / (1u64 << 53) as f64
        };
        let spread: Vec<f64> = (0..300_001).map(|_| 1e-3 * (1.0 + uniform())).collect();
        let late: Vec<f64> = (0..200_000)
            .map(|k| if k % 997 == 0 { 3.7e-3 } else { 2e-3 })
            .collect();
        for dts in [spread.clone(), spread[1..].to_vec(), late] {
            let mut t = vec![0.0];
            for d in &dts {
                t.push(t[t.len() - 1] + d);
            }
            let s = Sampling::of(&t).unwrap();
            let mut sorted: Vec<f64> = t.windows(2).map(|w| w[1] - w[0]).collect();
            sorted.sort_by(f64::total_cmp);
            let m = sorted.len();
            let median = if m % 2 == 1 {
                sorted[m / 2]
            } else {
                0.5 * (sorted[m / 2 - 1] + sorted[m / 2])
            };
            assert_eq!(s.dt_median, median);
            assert_eq!((s.dt_min, s.dt_max), (sorted[0], sorted[m - 1]));
        }
    }

    #[test]
    fn bad_times_are_rejected_with_the_row() {
        let t: Vec<f64> = (0..100)
            .map(|k| if k == 40 { 0.39 } else { k as f64 * 0.01 })
            .collect();
        let q = vec![vec![0.0; 100]];
        assert_eq!(
            estimate(&t, &q, None, &Options::default()).unwrap_err(),
            DerivativeError::NotIncreasing {
                row: 40,
                t: 0.39,
                prev: 0.39
            }
        );
        assert!(matches!(
            estimate(&t[..10], &q, None, &Options::default()),
            Err(DerivativeError::TooFewSamples { n: 10, .. })
        ));
    }

    #[test]
    fn fft_matches_a_direct_dft() {
        let x: Vec<f64> = (0..16).map(|k| ((k * k) % 5) as f64 - 1.0).collect();
        let (mut re, mut im) = (x.clone(), vec![0.0; 16]);
        fft(&mut re, &mut im);
        for f in 0..16 {
            let (mut r, mut i) = (0.0, 0.0);
            for (k, v) in x.iter().enumerate() {
                let a = -2.0 * PI * (f * k) as f64 / 16.0;
                r += v * a.cos();
                i += v * a.sin();
            }
            assert!((r - re[f]).abs() < 1e-9 && (i - im[f]).abs() < 1e-9);
        }
    }
}
