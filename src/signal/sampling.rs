//! Sampling statistics of a file's times: checks (finite, increasing, no gaps) and the spread of
//! the steps, with the exact median read piece by piece.

use std::borrow::Cow;

use serde::Serialize;

use super::order_statistics::kth_smallest;
use super::{DerivativeError, PIECE};
use crate::log::Log;

/// Fewest samples any estimator accepts.
pub const MIN_SAMPLES: usize = 32;

/// A time step longer than this many median steps is a gap in the recording (rejected).
pub const GAP_STEPS: f64 = 10.0;

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

#[cfg(test)]
mod tests {
    use super::*;

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
}
