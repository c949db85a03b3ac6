//! Digital Butterworth low-pass as second-order sections, run forward and backward (zero phase).

use std::f64::consts::PI;

use super::{DerivativeError, ZeroPhase};

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
        if let [s0, s1] = sections {
            return Self::cascade2_lanes(s0, s1, first, x);
        }
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

    /// [`Biquad::cascade_lanes`] of two sections (order 4, the usual one) with the states in
    /// local arrays the compiler keeps in registers: the same operations in the same order.
    fn cascade2_lanes<'a, const L: usize>(
        s0: &Biquad,
        s1: &Biquad,
        first: &'a mut [f64; L],
        x: impl Iterator<Item = &'a mut [f64; L]>,
    ) {
        let (mut z01, mut z02, mut z11, mut z12) = ([0.0; L], [0.0; L], [0.0; L], [0.0; L]);
        for l in 0..L {
            z02[l] = (s0.b[2] - s0.a[1]) * first[l];
            z01[l] = (s0.b[1] - s0.a[0]) * first[l] + z02[l];
        }
        s0.step_lanes(first, &mut z01, &mut z02);
        for l in 0..L {
            z12[l] = (s1.b[2] - s1.a[1]) * first[l];
            z11[l] = (s1.b[1] - s1.a[0]) * first[l] + z12[l];
        }
        s1.step_lanes(first, &mut z11, &mut z12);
        for v in x {
            s0.step_lanes(v, &mut z01, &mut z02);
            s1.step_lanes(v, &mut z11, &mut z12);
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

    /// Zero-phase filtering of up to `L` equally long channels at once, interleaved so the
    /// recursions of all channels and sections run side by side in one sweep each way (per
    /// channel the same operations whatever `L`, so the same numbers bit for bit; lanes beyond
    /// the channels given repeat the last one and are not written back). Odd reflection about
    /// the end points (value and slope continuous) pads the ends that are the signal's own.
    fn apply_lanes<const L: usize>(&self, xs: &mut [&mut [f64]], pad_left: bool, pad_right: bool) {
        let n = xs[0].len();
        if n < 2 {
            return;
        }
        let p = self.pad_len().min(n - 1);
        let (pl, pr) = (if pad_left { p } else { 0 }, if pad_right { p } else { 0 });
        let len = n + pl + pr;
        let mut ext = vec![[0.0f64; L]; len];
        for l in 0..L {
            let x = &xs[l.min(xs.len() - 1)];
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

    /// [`Butterworth::apply_lanes`] of `L` columns `cols` of a row-major block `x` (rows of
    /// `stride` values), writing only rows `keep` to `out` (see [`ZeroPhase::apply_rows`]): the
    /// same padded signals and sweeps, so the same numbers bit for bit, without copying whole
    /// columns in and out.
    #[allow(clippy::too_many_arguments)]
    fn apply_rows_lanes<const L: usize>(
        &self,
        x: &[f64],
        stride: usize,
        cols: &[usize; L],
        pad_left: bool,
        pad_right: bool,
        keep: &[usize],
        out: &mut [f64],
    ) {
        let n = x.len() / stride;
        let adjacent = cols.windows(2).all(|w| w[1] == w[0] + 1);
        // Row k's columns: one contiguous load when they are adjacent (the usual case).
        let at = |k: usize| -> [f64; L] {
            let r = &x[k * stride..(k + 1) * stride];
            if adjacent {
                r[cols[0]..cols[0] + L]
                    .try_into()
                    .expect("L adjacent columns")
            } else {
                let mut v = [0.0; L];
                for (v, &c) in v.iter_mut().zip(cols) {
                    *v = r[c];
                }
                v
            }
        };
        if n < 2 {
            for (i, &k) in keep.iter().enumerate() {
                let v = at(k);
                for l in 0..L {
                    out[i * stride + cols[l]] = v[l];
                }
            }
            return;
        }
        let p = self.pad_len().min(n - 1);
        let (pl, pr) = (if pad_left { p } else { 0 }, if pad_right { p } else { 0 });
        let mut ext: Vec<[f64; L]> = Vec::with_capacity(n + pl + pr);
        let (first, last) = (at(0), at(n - 1));
        ext.extend((1..=pl).rev().map(|i| {
            let v = at(i);
            std::array::from_fn(|l| 2.0 * first[l] - v[l])
        }));
        ext.extend((0..n).map(at));
        ext.extend((1..=pr).map(|i| {
            let v = at(n - 1 - i);
            std::array::from_fn(|l| 2.0 * last[l] - v[l])
        }));
        Biquad::cascade_lanes(&self.sections, ext.iter_mut());
        Biquad::cascade_lanes(&self.sections, ext.iter_mut().rev());
        for (i, &k) in keep.iter().enumerate() {
            let o = &mut out[i * stride..(i + 1) * stride];
            if adjacent {
                o[cols[0]..cols[0] + L].copy_from_slice(&ext[pl + k]);
            } else {
                for (&c, &v) in cols.iter().zip(&ext[pl + k]) {
                    o[c] = v;
                }
            }
        }
    }

    /// Columns `cols` of [`ZeroPhase::apply_rows`] by `L` side by side, the last group
    /// overlapping the one before it (its shared columns are filtered twice, to the same
    /// numbers); fewer than `L` columns go alone.
    #[allow(clippy::too_many_arguments)]
    fn apply_rows_by<const L: usize>(
        &self,
        x: &[f64],
        stride: usize,
        cols: &[usize],
        pad_left: bool,
        pad_right: bool,
        keep: &[usize],
        out: &mut [f64],
    ) {
        let m = cols.len();
        let starts = (0..m.saturating_sub(L))
            .step_by(L)
            .chain((m >= L).then(|| m - L));
        for s in starts {
            let g: &[usize; L] = cols[s..s + L].try_into().expect("L columns");
            self.apply_rows_lanes::<L>(x, stride, g, pad_left, pad_right, keep, out);
        }
        if m < L {
            for c in cols {
                self.apply_rows_lanes::<1>(x, stride, &[*c], pad_left, pad_right, keep, out);
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
        // Sixteen channels side by side (two vectors of independent recursions in flight hide
        // each other's latency); the last group in the narrowest form that holds it.
        for g in xs.chunks_mut(16) {
            match g.len() {
                9.. => self.apply_lanes::<16>(g, pad_left, pad_right),
                5.. => self.apply_lanes::<8>(g, pad_left, pad_right),
                2.. => self.apply_lanes::<4>(g, pad_left, pad_right),
                _ => self.apply_lanes::<1>(g, pad_left, pad_right),
            }
        }
    }

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
        // Sixteen columns side by side (two vectors of independent recursions in flight hide
        // each other's latency), eight when there are fewer, four when fewer still.
        let f = match cols.len() {
            16.. => Self::apply_rows_by::<16>,
            8.. => Self::apply_rows_by::<8>,
            _ => Self::apply_rows_by::<4>,
        };
        f(self, x, stride, cols, pad_left, pad_right, keep, out);
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::signal::sines;

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
        // Channel counts that make every group form: alone, four, eight and sixteen side by
        // side, a last group padded (`apply_many`) or overlapping the one before (`apply_rows`);
        // with and without end padding; order 5 includes the first-order section.
        for count in [1, 3, 5, 13, 21, 35] {
            for order in [4, 5] {
                let f = Butterworth::lowpass(order, 3.0, 200.0).unwrap();
                for (pl, pr) in [(true, true), (false, true), (true, false), (false, false)] {
                    check_side_by_side(&f, count, pl, pr);
                }
            }
        }
    }

    fn check_side_by_side(f: &Butterworth, count: usize, pl: bool, pr: bool) {
        let what = format!("{count} channels, order {}, pads {pl} {pr}", f.order);
        let chans: Vec<Vec<f64>> = (0..count)
            .map(|c| {
                (0..700)
                    .map(|k| sines(k as f64 * 0.005 + c as f64).0 + 0.01 * c as f64)
                    .collect()
            })
            .collect();
        let one: Vec<Vec<f64>> = chans
            .iter()
            .map(|x| reference_filtfilt(f, x, pl, pr))
            .collect();
        let mut alone = chans.clone();
        for x in &mut alone {
            f.apply(x, pl, pr);
        }
        assert_eq!(one, alone, "{what}");
        let mut many = chans.clone();
        let mut refs: Vec<&mut [f64]> = many.iter_mut().map(|v| v.as_mut_slice()).collect();
        f.apply_many(&mut refs, pl, pr);
        assert_eq!(one, many, "{what}");
        assert_ne!(one, chans);
        // Row-major, columns not asked for in between and at the end (left as they were in
        // `out`; a run of adjacent columns is read as one), every 7th row kept.
        let cols: Vec<usize> = (0..).filter(|c| c % 11 != 3).take(count).collect();
        let stride = cols[count - 1] + 2;
        let mut x = vec![f64::NAN; 700 * stride];
        for (ch, &c) in chans.iter().zip(&cols) {
            for (k, v) in ch.iter().enumerate() {
                x[k * stride + c] = *v;
            }
        }
        let keep: Vec<usize> = (0..700).step_by(7).collect();
        let mut out = vec![-1.0; keep.len() * stride];
        f.apply_rows(&x, stride, &cols, pl, pr, &keep, &mut out);
        for (i, &k) in keep.iter().enumerate() {
            let row = &out[i * stride..(i + 1) * stride];
            for (c, &v) in row.iter().enumerate() {
                match cols.iter().position(|&a| a == c) {
                    Some(ch) => assert_eq!(v, one[ch][k], "{what}, column {c}, row {k}"),
                    None => assert_eq!(v, -1.0, "{what}, column {c} not asked for"),
                }
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
}
