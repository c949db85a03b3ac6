//! The paper's Logistic excitation (Qian et al. 2022, eq. 14) generalised to `n` joints moving at
//! once: joint `j` rises from `q0_j` by `A_j` (either sign) around `T/4` and returns around
//! `3T/4`, with its own steepness `w_j`, all over one common period `T`:
//!
//! ```text
//! q_j(t) = q0_j + A_j · (s_j(t) − s_j(0)),   s_j = the unit logistic of eq. 14 with w_j, T
//! ```
//!
//! Shifting by `s_j(0)` makes `q(0) = q(T) = q0` exactly; `w_j ≥` [`min_steepness`] keeps
//! `|q̇|, |q̈|` at the ends below `REST_TOL`. The peaks are analytic (`|A|`, `|A| w/4`,
//! `|A| w²/(6√3)`), so the limits hold in continuous time, not only at samples.

use serde::{Deserialize, Serialize};

use super::logistic::{LogisticJoint, PEAK_ACCEL_FACTOR};
use super::Motion;

/// Largest `|q̇|`, `|q̈|` allowed at the start and end (eq. 11's tolerance), rad/s, rad/s².
pub const REST_TOL: f64 = 1e-4;

/// One joint of [`LogisticN`].
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct LnJoint {
    pub q0: f64,
    /// Signed amplitude, rad.
    pub a: f64,
    /// Steepness, 1/s.
    pub w: f64,
}

/// `n` joints on the Logistic family over one period.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LogisticN {
    pub period: f64,
    pub joints: Vec<LnJoint>,
}

/// The smallest steepness for which an amplitude up to `amp` rests within [`REST_TOL`] at the
/// ends of a period `T`: `amp·max(1, w, w²)·e^{−wT/4} ≤ tol` (the bound of
/// [`LogisticJoint::resting_ends`]), solved by bisection on `w`.
pub fn min_steepness(amp: f64, period: f64) -> f64 {
    let f = |w: f64| amp * w.max(w * w).max(1.0) * (-0.25 * w * period).exp() - REST_TOL;
    let (mut lo, mut hi) = (1e-6, 1.0);
    while f(hi) > 0.0 && hi < 1e6 {
        hi *= 2.0;
    }
    // the bound is decreasing in w beyond w = 8/T, where the search starts to matter
    for _ in 0..80 {
        let mid = 0.5 * (lo + hi);
        if f(mid) > 0.0 {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    hi
}

impl LnJoint {
    fn unit(&self, period: f64) -> LogisticJoint {
        LogisticJoint {
            a: 1.0,
            w: self.w,
            h: 0.0,
            period,
        }
    }

    /// Peak `|q − q0|`, `|q̇|`, `|q̈|` over the period (analytic).
    pub fn peaks(&self) -> [f64; 3] {
        let a = self.a.abs();
        [
            a,
            0.25 * a * self.w,
            PEAK_ACCEL_FACTOR * a * self.w * self.w,
        ]
    }
}

impl Motion for LogisticN {
    fn dof(&self) -> usize {
        self.joints.len()
    }

    fn duration(&self) -> f64 {
        self.period
    }

    fn eval(&self, t: f64, q: &mut [f64], dq: &mut [f64], ddq: &mut [f64]) {
        for (j, jt) in self.joints.iter().enumerate() {
            let u = jt.unit(self.period);
            let (s0, _, _) = u.eval(0.0);
            // the end of the period is the start of the next: the same rest posture
            let (s, ds, dds) = if t >= self.period {
                u.eval(0.0)
            } else {
                u.eval(t)
            };
            q[j] = jt.q0 + jt.a * (s - s0);
            dq[j] = jt.a * ds;
            ddq[j] = jt.a * dds;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Rest at the ends within the tolerance, and the analytic peaks bound a dense sampling and
    /// are reached by it within 0.1 % (the peaks sit inside the period, not at its ends).
    #[test]
    fn rests_at_the_ends_and_peaks_are_tight() {
        let period = 8.0;
        let w = min_steepness(1.0, period);
        let traj = LogisticN {
            period,
            joints: vec![
                LnJoint {
                    q0: 0.2,
                    a: -0.8,
                    w,
                },
                LnJoint {
                    q0: 0.0,
                    a: 1.0,
                    w: 2.0 * w,
                },
            ],
        };
        let (mut q, mut dq, mut ddq) = ([0.0; 2], [0.0; 2], [0.0; 2]);
        for t in [0.0, period] {
            traj.eval(t, &mut q, &mut dq, &mut ddq);
            assert!((q[0] - 0.2).abs() < 1e-12 && q[1].abs() < 1e-12);
            assert!(dq.iter().chain(&ddq).all(|v| v.abs() < REST_TOL));
        }
        let mut peak = [[0.0_f64; 3]; 2];
        for k in 0..=200_000 {
            traj.eval(k as f64 * period / 200_000.0, &mut q, &mut dq, &mut ddq);
            for j in 0..2 {
                let d = q[j] - traj.joints[j].q0;
                peak[j][0] = peak[j][0].max(d.abs());
                peak[j][1] = peak[j][1].max(dq[j].abs());
                peak[j][2] = peak[j][2].max(ddq[j].abs());
            }
        }
        for (j, jt) in traj.joints.iter().enumerate() {
            let p = jt.peaks();
            for m in 0..3 {
                assert!(peak[j][m] <= p[m] * (1.0 + 1e-12), "{j} {m}");
                assert!(
                    peak[j][m] >= p[m] * 0.999,
                    "{j} {m}: {} vs {}",
                    peak[j][m],
                    p[m]
                );
            }
        }
    }
}
