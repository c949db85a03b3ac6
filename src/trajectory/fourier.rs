//! Finite Fourier series excitation (Swevers et al. 1997) with analytic derivatives, and a
//! least-squares Fourier fit of measured positions used as a derivative estimator.
//!
//! ```text
//! q_i(t) = q_i0 + Σ_{k=1..N} a_ik/(w_f k) sin(w_f k t) − b_ik/(w_f k) cos(w_f k t)
//! q̇_i(t) =        Σ a_ik cos(w_f k t) + b_ik sin(w_f k t)
//! q̈_i(t) =        Σ w_f k (−a_ik sin(w_f k t) + b_ik cos(w_f k t))
//! ```
//!
//! ```
//! use dynid::trajectory::fourier::FourierJoint;
//! let j = FourierJoint::starting_at_rest(0.2 * std::f64::consts::PI, &[0.1, 0.2, -0.05], &[0.0, 0.3, 0.1], 0.0);
//! let (q, dq, ddq) = j.eval(0.0);
//! assert!(q.abs() < 1e-12 && dq.abs() < 1e-12 && ddq.abs() < 1e-12);
//! ```

use serde::{Deserialize, Serialize};

use super::{Motion, TrajectoryError};

/// One joint's Fourier series.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FourierJoint {
    /// Fundamental angular frequency `w_f` (rad/s).
    pub wf: f64,
    /// Offset `q_i0`.
    pub q0: f64,
    /// Sine-velocity coefficients `a_ik`, `k = 1..N`.
    pub a: Vec<f64>,
    /// Cosine-velocity coefficients `b_ik`.
    pub b: Vec<f64>,
}

impl FourierJoint {
    /// A series that starts at `q_start` with zero velocity and acceleration: `a_1` and `b_1` are
    /// solved from the free higher harmonics `a_2..`, `b_2..` (`Σ a_k = 0`, `Σ k b_k = 0`) and `q_0`
    /// from the start position. `a_free`, `b_free` hold harmonics 2..=N.
    pub fn starting_at_rest(wf: f64, a_free: &[f64], b_free: &[f64], q_start: f64) -> Self {
        let n = a_free.len().max(b_free.len()) + 1;
        let mut a = vec![0.0; n];
        let mut b = vec![0.0; n];
        a[1..=a_free.len()].copy_from_slice(a_free);
        b[1..=b_free.len()].copy_from_slice(b_free);
        a[0] = -a[1..].iter().sum::<f64>();
        b[0] = -(1..n).map(|k| (k + 1) as f64 * b[k]).sum::<f64>();
        let mut j = Self { wf, q0: 0.0, a, b };
        let (q, _, _) = j.eval(0.0);
        j.q0 = q_start - q;
        j
    }

    /// Number of harmonics `N`.
    pub fn harmonics(&self) -> usize {
        self.a.len().max(self.b.len())
    }

    /// Period `2π / w_f`.
    pub fn period(&self) -> f64 {
        std::f64::consts::TAU / self.wf
    }

    /// Position, velocity, acceleration at `t`.
    pub fn eval(&self, t: f64) -> (f64, f64, f64) {
        let (mut q, mut dq, mut ddq) = (self.q0, 0.0, 0.0);
        // harmonics by the angle-addition recurrence: one sin_cos per call
        let (s1, c1) = (self.wf * t).sin_cos();
        let (mut s, mut c) = (s1, c1);
        for k in 0..self.harmonics() {
            let wk = self.wf * (k + 1) as f64;
            let a = self.a.get(k).copied().unwrap_or(0.0);
            let b = self.b.get(k).copied().unwrap_or(0.0);
            q += a / wk * s - b / wk * c;
            dq += a * c + b * s;
            ddq += wk * (-a * s + b * c);
            (s, c) = (s * c1 + c * s1, c * c1 - s * s1);
        }
        (q, dq, ddq)
    }
}

/// A multi-joint Fourier trajectory, `periods` periods long.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Fourier {
    pub joints: Vec<FourierJoint>,
    pub periods: usize,
}

impl Motion for Fourier {
    fn dof(&self) -> usize {
        self.joints.len()
    }

    fn duration(&self) -> f64 {
        self.joints
            .iter()
            .map(FourierJoint::period)
            .fold(0.0, f64::max)
            * self.periods as f64
    }

    fn eval(&self, t: f64, q: &mut [f64], dq: &mut [f64], ddq: &mut [f64]) {
        for (j, f) in self.joints.iter().enumerate() {
            (q[j], dq[j], ddq[j]) = f.eval(t);
        }
    }
}

/// Least-squares fit of `q(t) ≈ c_0 + Σ_{k=1..K} α_k cos(k w t) + β_k sin(k w t)` to uniformly
/// sampled data covering a whole number of periods of `w`, returned as a [`FourierJoint`] whose
/// analytic derivatives then estimate `q̇`, `q̈`.
///
/// On such a grid the sampled sines and cosines are orthogonal, so the least-squares solution is
/// the discrete Fourier transform (exact, `O(n·K)`); the harmonics are generated with the
/// angle-addition recurrence instead of `n·K` calls to `sin_cos`.
pub fn fit_periodic(
    t: &[f64],
    q: &[f64],
    wf: f64,
    harmonics: usize,
) -> Result<FourierJoint, TrajectoryError> {
    let n = t.len();
    if n != q.len() || n < 2 * harmonics + 2 {
        return Err(TrajectoryError::Invalid(format!(
            "Fourier fit needs at least 2K+2 = {} samples of equal length (got t: {}, q: {})",
            2 * harmonics + 2,
            t.len(),
            q.len()
        )));
    }
    let dt = t[1] - t[0];
    let span = dt * n as f64;
    let cycles = span * wf / std::f64::consts::TAU;
    if dt.is_nan() || dt <= 0.0 || (cycles - cycles.round()).abs() > 1e-6 || cycles.round() < 1.0 {
        return Err(TrajectoryError::Invalid(format!(
            "Fourier fit needs uniform samples over a whole number of periods (got {cycles:.6} periods)"
        )));
    }
    let mut alpha = vec![0.0; harmonics];
    let mut beta = vec![0.0; harmonics];
    let mean = q.iter().sum::<f64>() / n as f64;
    for (&ti, &qi) in t.iter().zip(q) {
        let (s1, c1) = (wf * ti).sin_cos();
        let (mut s, mut c) = (s1, c1);
        let x = qi - mean;
        for k in 0..harmonics {
            alpha[k] += x * c;
            beta[k] += x * s;
            (s, c) = (s * c1 + c * s1, c * c1 - s * s1);
        }
    }
    let scale = 2.0 / n as f64;
    // α cos + β sin  ==  a/(wk) sin − b/(wk) cos   ⇒   a = wk β, b = −wk α
    let a = (0..harmonics)
        .map(|k| scale * beta[k] * wf * (k + 1) as f64)
        .collect();
    let b = (0..harmonics)
        .map(|k| -scale * alpha[k] * wf * (k + 1) as f64)
        .collect();
    Ok(FourierJoint { wf, q0: mean, a, b })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn derivatives_match_finite_differences() {
        let j = FourierJoint {
            wf: 0.7,
            q0: 0.3,
            a: vec![0.2, -0.1, 0.05],
            b: vec![0.1, 0.2, -0.3],
        };
        let h = 1e-4;
        for k in 0..100 {
            let t = 0.173 * k as f64;
            let (q, dq, ddq) = j.eval(t);
            let (qp, _, _) = j.eval(t + h);
            let (qm, _, _) = j.eval(t - h);
            assert!(((qp - qm) / (2.0 * h) - dq).abs() < 1e-7);
            assert!(((qp - 2.0 * q + qm) / (h * h) - ddq).abs() < 1e-4);
        }
    }

    #[test]
    fn starts_at_rest() {
        let j = FourierJoint::starting_at_rest(
            0.628,
            &[0.1, -0.2, 0.3, 0.05],
            &[0.2, 0.0, -0.1, 0.4],
            0.5,
        );
        let (q, dq, ddq) = j.eval(0.0);
        assert!((q - 0.5).abs() < 1e-12 && dq.abs() < 1e-12 && ddq.abs() < 1e-12);
        let (q, dq, _) = j.eval(j.period());
        assert!((q - 0.5).abs() < 1e-12 && dq.abs() < 1e-12);
    }

    #[test]
    fn fit_recovers_a_band_limited_signal_exactly() {
        let truth = FourierJoint {
            wf: 0.5,
            q0: 1.0,
            a: vec![0.2, -0.1, 0.05, 0.0],
            b: vec![0.1, 0.2, -0.3, 0.01],
        };
        let n = 400;
        let dt = 2.0 * truth.period() / n as f64;
        let t: Vec<f64> = (0..n).map(|i| 0.37 + i as f64 * dt).collect();
        let q: Vec<f64> = t.iter().map(|&ti| truth.eval(ti).0).collect();
        let fit = fit_periodic(&t, &q, truth.wf, 6).unwrap();
        for &ti in t.iter().step_by(17) {
            let (a, b) = (truth.eval(ti), fit.eval(ti));
            assert!(
                (a.0 - b.0).abs() < 1e-10 && (a.1 - b.1).abs() < 1e-10 && (a.2 - b.2).abs() < 1e-10
            );
        }
        assert!(fit_periodic(&t[..n - 3], &q[..n - 3], truth.wf, 6).is_err());
    }
}
