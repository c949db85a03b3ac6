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

mod estimator;
#[cfg(test)]
mod tests;

use serde::Serialize;

use crate::data::Trajectory;
use crate::log::Log;

pub use estimator::Estimator;
// The building blocks, where they were before they moved to `crate::signal`.
pub use crate::signal::{
    auto_cutoff, central_uneven, central_uniform, resample_linear, welch_psd, Butterworth,
    ChannelSpectrum, DerivativeError, Grid, Psd, Sampling, SavGol, ZeroPhase, GAP_STEPS,
    MIN_SAMPLES, SG_DEGREE,
};

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

/// Estimated states of grid samples `lo..lo + len`: `q[j][k - lo]`, likewise q̇, q̈.
#[derive(Debug, Clone)]
pub struct States {
    pub lo: usize,
    /// Grid step (s): grid sample `k` is at `k·dt` since the start of the run.
    pub dt: f64,
    pub q: Vec<Vec<f64>>,
    pub dq: Vec<Vec<f64>>,
    pub ddq: Vec<Vec<f64>>,
}

/// Grid samples up to which the spectrum of the cut-off choice is taken over the whole signal;
/// a longer one is judged on evenly spaced pieces of 65536 samples (at most
/// [`SPECTRUM_PIECES`]), their periodograms averaged.
pub const SPECTRUM_WHOLE: usize = 1 << 18;
pub const SPECTRUM_PIECES: usize = 16;

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
