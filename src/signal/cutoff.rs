//! The automatic cut-off rule: from the Welch spectrum of each channel's second difference, the
//! noise floor, noise edge and motion band, and the cut-off they ask for.

use std::f64::consts::PI;

use serde::Serialize;

use super::order_statistics::median;
use super::welch::welch_psd;

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
