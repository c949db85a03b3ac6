//! Signal-processing building blocks of derivative estimation, one algorithm per file; the
//! streaming estimator that puts them together is [`crate::derivative`].
//!
//! - `sampling.rs`: [`Sampling`], checks of a file's times (finite, increasing, no gap over
//!   [`GAP_STEPS`] median steps) and the spread of the steps, the median exact and read in pieces.
//! - `order_statistics.rs`: the exact k-th smallest of values visited in passes (histogram
//!   refinement) and the median of a slice.
//! - `resample.rs`: the uniform [`Grid`] and linear resampling onto it ([`resample_linear`]).
//! - `butterworth.rs`: [`Butterworth`] low-pass as second-order sections, run forward and
//!   backward, several channels side by side.
//! - `savgol.rs`: [`SavGol`], Savitzky–Golay fits (value, q̇, q̈), window matched to a cut-off,
//!   FFT convolution for long windows, fits at the ends.
//! - `fft.rs`: in-place radix-2 FFT (Savitzky–Golay convolution, Welch).
//! - `central_difference.rs`: [`central_uniform`] (5-point) and [`central_uneven`] (parabolas).
//! - `welch.rs`: [`welch_psd`], Welch power spectral density.
//! - `cutoff.rs`: the automatic cut-off rule ([`auto_cutoff`], [`Psd`], [`ChannelSpectrum`]).
//!
//! [`ZeroPhase`] (here) is the one interface the estimator and the identification's parallel
//! filtering call: `apply`/`apply_many` filter, `derivatives_many` gives value, q̇ and q̈ of a
//! window (by default filtering side by side, then [`central_uniform`]; Savitzky–Golay overrides
//! it with its own fitted derivatives). **To add a derivative estimator or smoother:** add a file
//! implementing [`ZeroPhase`] (override `derivatives_many` if it differentiates by itself), and a
//! variant to [`crate::derivative::Method`] and to [`crate::derivative::Filter`] with its arms in
//! `Filter::lowpass` and `Filter::as_zero_phase`.

pub mod butterworth;
pub mod central_difference;
pub mod cutoff;
pub mod fft;
pub mod order_statistics;
pub mod resample;
pub mod sampling;
pub mod savgol;
pub mod welch;

pub use butterworth::Butterworth;
pub use central_difference::{central_uneven, central_uniform};
pub use cutoff::{auto_cutoff, ChannelSpectrum, Psd};
pub use resample::{resample_linear, Grid};
pub use sampling::{Sampling, GAP_STEPS, MIN_SAMPLES};
pub use savgol::{SavGol, SG_DEGREE};
pub use welch::welch_psd;

use std::ops::Range;

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

/// Pieces in which long signals are read (times, spectra): 65536 samples.
pub(crate) const PIECE: usize = 1 << 16;

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
    /// Columns `cols` of the row-major block `x` (rows of `stride` values), each filtered as
    /// [`ZeroPhase::apply`] filters a channel, but only rows `keep` written, to
    /// `out[i * stride + c]` for `keep[i]` (the other columns of `out` are left as they are).
    /// A filter may run the columns side by side; the result is the same.
    #[allow(clippy::too_many_arguments)]
    fn apply_rows(
        &self,
        x: &[f64],
        stride: usize,
        cols: &[usize],
        pad_left: bool,
        pad_right: bool,
        keep: &[usize],
        out: &mut [f64],
    ) {
        let rows = x.len() / stride;
        for &c in cols {
            let mut ch: Vec<f64> = (0..rows).map(|k| x[k * stride + c]).collect();
            self.apply(&mut ch, pad_left, pad_right);
            for (i, &k) in keep.iter().enumerate() {
                out[i * stride + c] = ch[k];
            }
        }
    }
    /// Samples beyond which the filter's influence is negligible (≈1e-8 relative).
    fn reach(&self) -> usize;
    /// Amplitude gain at frequency `f` (Hz).
    fn gain(&self, f: f64) -> f64;
    /// Short description for reports.
    fn describe(&self) -> String;
    /// Filtered value, first and second derivative of the channels `q` (one window, step `dt`,
    /// ends as in [`ZeroPhase::apply`]), each cut to the samples `keep`: `[value, q̇, q̈][j]`.
    /// With measured velocities `dq` (the same channels), q̇ is the filtered `dq` and q̈ its
    /// derivative. By default all channels are filtered side by side
    /// ([`ZeroPhase::apply_many`]) and differentiated by 5-point central differences
    /// ([`central_uniform`]); a filter that differentiates by itself overrides this.
    fn derivatives_many(
        &self,
        q: Vec<Vec<f64>>,
        dq: Option<Vec<Vec<f64>>>,
        dt: f64,
        pad_left: bool,
        pad_right: bool,
        keep: Range<usize>,
    ) -> [Vec<Vec<f64>>; 3] {
        let cut = |x: Vec<f64>| x[keep.clone()].to_vec();
        let dof = q.len();
        let mut out = [(); 3].map(|_| Vec::with_capacity(dof));
        // All channels in one side-by-side sweep.
        let mut q = q;
        let mut v = dq.unwrap_or_default();
        let mut chans: Vec<&mut [f64]> = q
            .iter_mut()
            .chain(v.iter_mut())
            .map(|c| c.as_mut_slice())
            .collect();
        self.apply_many(&mut chans, pad_left, pad_right);
        for j in 0..dof {
            let (d1, d2) = if v.is_empty() {
                central_uniform(&q[j], dt)
            } else {
                let a = central_uniform(&v[j], dt).0;
                (std::mem::take(&mut v[j]), a)
            };
            out[0].push(cut(std::mem::take(&mut q[j])));
            out[1].push(cut(d1));
            out[2].push(cut(d2));
        }
        out
    }
}

/// Sum of sines with known derivatives, content up to 1.5 Hz: `(q, q̇, q̈)` at `t` (tests).
#[cfg(test)]
pub(crate) fn sines(t: f64) -> (f64, f64, f64) {
    use std::f64::consts::PI;
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
