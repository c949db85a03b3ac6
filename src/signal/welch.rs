//! Welch power spectral density (Hann window, 50 % overlap).

use std::f64::consts::PI;

use super::fft::fft;

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
