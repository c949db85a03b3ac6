//! Fourier series with a quintic boundary term (Swevers et al. 1997; the form of
//! dynamic_calibration): per joint
//!
//! ```text
//! q(t) = q0 + Σ_{k=1..N} [ a_k/(k w) sin(k w t) − b_k/(k w) cos(k w t) ] + Σ_{i=0..5} c_i t^i
//! ```
//!
//! with `w = 2π/T`. The harmonics are periodic, so the quintic only has to cancel their value,
//! slope and curvature at `t = 0` and `t = T`: the motion starts and ends at rest at `q0`
//! (`q = q0`, `q̇ = q̈ = 0`), for any coefficients. Every derivative is analytic, and
//! [`FourierQuintic::sup`] bounds each derivative over the whole period (used to guard the limits
//! between samples).
//!
//! ```
//! use dynid::trajectory::fourier_quintic::FourierQuintic;
//! use dynid::trajectory::Motion;
//! let f = FourierQuintic::new(10.0, &[0.3], &[vec![0.2, -0.1]], &[vec![0.05, 0.1]]);
//! let (mut q, mut dq, mut ddq) = ([0.0], [0.0], [0.0]);
//! for t in [0.0, 10.0] {
//!     f.eval(t, &mut q, &mut dq, &mut ddq);
//!     assert!((q[0] - 0.3).abs() < 1e-12 && dq[0].abs() < 1e-12 && ddq[0].abs() < 1e-12);
//! }
//! ```

use nalgebra::{Matrix3, Vector3};
use serde::{Deserialize, Serialize};

use super::Motion;

/// One joint: rest posture, harmonic coefficients (rad/s) and the boundary quintic.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FqJoint {
    pub q0: f64,
    pub a: Vec<f64>,
    pub b: Vec<f64>,
    /// `c_0..c_5` of `Σ c_i t^i` (t in seconds).
    pub c: [f64; 6],
}

/// A Fourier-plus-quintic trajectory of one period `T`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FourierQuintic {
    pub period: f64,
    pub joints: Vec<FqJoint>,
}

/// `d^m/dt^m` of the harmonic part of a joint at `t`.
fn harmonic(j: &FqJoint, wf: f64, t: f64, m: u32) -> f64 {
    let shift = m as f64 * std::f64::consts::FRAC_PI_2;
    j.a.iter()
        .zip(&j.b)
        .enumerate()
        .map(|(k, (&a, &b))| {
            let wk = wf * (k + 1) as f64;
            let th = wk * t + shift;
            wk.powi(m as i32 - 1) * (a * th.sin() - b * th.cos())
        })
        .sum()
}

/// `d^m/dt^m` of `Σ c_i t^i` at `t`.
fn poly(c: &[f64; 6], t: f64, m: u32) -> f64 {
    let m = m as usize;
    (m..6)
        .rev()
        .fold(0.0, |acc, i| acc * t + c[i] * falling(i, m))
}

/// `i·(i−1)·…·(i−m+1)`.
fn falling(i: usize, m: usize) -> f64 {
    (0..m).map(|r| (i - r) as f64).product()
}

impl FourierQuintic {
    /// Builds the trajectory and solves each joint's quintic (`a`, `b` per joint of equal length).
    pub fn new(period: f64, q0: &[f64], a: &[Vec<f64>], b: &[Vec<f64>]) -> Self {
        let wf = std::f64::consts::TAU / period;
        let joints = (0..q0.len())
            .map(|j| {
                let mut joint = FqJoint {
                    q0: q0[j],
                    a: a[j].clone(),
                    b: b[j].clone(),
                    c: [0.0; 6],
                };
                joint.c = boundary_quintic(&joint, wf, period);
                joint
            })
            .collect();
        FourierQuintic { period, joints }
    }

    pub fn wf(&self) -> f64 {
        std::f64::consts::TAU / self.period
    }

    /// `d^m q_j / dt^m` at `t` (`m = 0` is the position).
    pub fn derivative(&self, j: usize, t: f64, m: u32) -> f64 {
        let jt = &self.joints[j];
        let base = if m == 0 { jt.q0 } else { 0.0 };
        base + harmonic(jt, self.wf(), t, m) + poly(&jt.c, t, m)
    }

    /// An upper bound on `|d^m q_j/dt^m|` over `[0, T]` (`m ≥ 1`): the harmonics' amplitudes
    /// plus the quintic's coefficients times the largest powers of `t` (each term bounded alone).
    pub fn sup(&self, j: usize, m: u32) -> f64 {
        let jt = &self.joints[j];
        let wf = self.wf();
        let h: f64 =
            jt.a.iter()
                .zip(&jt.b)
                .enumerate()
                .map(|(k, (a, b))| a.hypot(*b) * (wf * (k + 1) as f64).powi(m as i32 - 1))
                .sum();
        let m = m as usize;
        let p: f64 = (m..6)
            .map(|i| jt.c[i].abs() * falling(i, m) * self.period.powi((i - m) as i32))
            .sum();
        h + p
    }

    /// Multiplies joint `j`'s motion about `q0` by `s` (the quintic is linear in the harmonics).
    pub fn scale_joint(&mut self, j: usize, s: f64) {
        let jt = &mut self.joints[j];
        jt.a.iter_mut().chain(jt.b.iter_mut()).for_each(|v| *v *= s);
        jt.c.iter_mut().for_each(|v| *v *= s);
    }
}

/// The quintic that cancels the harmonics' value, slope and curvature at `0` and `T`.
fn boundary_quintic(j: &FqJoint, wf: f64, period: f64) -> [f64; 6] {
    let f = |m| harmonic(j, wf, 0.0, m);
    let (c0, c1, c2) = (-f(0), -f(1), -0.5 * f(2));
    // p(T) = p(0), p'(T) = p'(0), p''(T) = p''(0) for the remaining c3, c4, c5 (t scaled by T
    // to keep the system well conditioned for any period).
    let t = period;
    let m = Matrix3::new(1.0, 1.0, 1.0, 3.0, 4.0, 5.0, 6.0, 12.0, 20.0);
    let rhs = Vector3::new(-(c1 * t + c2 * t * t), -(2.0 * c2 * t * t), 0.0);
    let x = m.lu().solve(&rhs).unwrap_or_else(Vector3::zeros);
    // x holds c_i·T^i for i = 3, 4, 5
    [
        c0,
        c1,
        c2,
        x[0] / t.powi(3),
        x[1] / t.powi(4),
        x[2] / t.powi(5),
    ]
}

impl Motion for FourierQuintic {
    fn dof(&self) -> usize {
        self.joints.len()
    }

    fn duration(&self) -> f64 {
        self.period
    }

    fn eval(&self, t: f64, q: &mut [f64], dq: &mut [f64], ddq: &mut [f64]) {
        for j in 0..self.joints.len() {
            q[j] = self.derivative(j, t, 0);
            dq[j] = self.derivative(j, t, 1);
            ddq[j] = self.derivative(j, t, 2);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample() -> FourierQuintic {
        FourierQuintic::new(
            7.0,
            &[0.1, -0.4],
            &[vec![0.3, -0.2, 0.1], vec![0.0, 0.5, -0.3]],
            &[vec![0.1, 0.2, -0.4], vec![0.2, 0.0, 0.1]],
        )
    }

    /// Rest at both ends, and each derivative matches a central difference of the one below it
    /// (h = 1e-4 s: truncation error ~h²·sup|q⁽ᵐ⁺³⁾| ≈ 1e-7, far below the 1e-5 tolerance).
    #[test]
    fn rests_at_both_ends_and_derivatives_are_consistent() {
        let f = sample();
        for j in 0..2 {
            for t in [0.0, f.period] {
                assert!((f.derivative(j, t, 0) - f.joints[j].q0).abs() < 1e-12);
                assert!(f.derivative(j, t, 1).abs() < 1e-12);
                assert!(f.derivative(j, t, 2).abs() < 1e-11);
            }
            let h = 1e-4;
            for k in 1..50 {
                let t = k as f64 * f.period / 50.0;
                for m in 1..5 {
                    let fd =
                        (f.derivative(j, t + h, m - 1) - f.derivative(j, t - h, m - 1)) / (2.0 * h);
                    let d = f.derivative(j, t, m);
                    assert!(
                        (fd - d).abs() < 1e-5 * (1.0 + d.abs()),
                        "m={m}: {fd} vs {d}"
                    );
                }
            }
        }
    }

    /// `sup` bounds the densely sampled maximum of every derivative.
    #[test]
    fn sup_bounds_every_derivative() {
        let f = sample();
        for j in 0..2 {
            for m in 1..5 {
                let dense = (0..=10_000)
                    .map(|k| f.derivative(j, k as f64 * f.period / 10_000.0, m).abs())
                    .fold(0.0, f64::max);
                assert!(f.sup(j, m) >= dense, "m={m}: {} < {dense}", f.sup(j, m));
            }
        }
    }

    #[test]
    fn scaling_scales_the_motion_about_q0() {
        let f = sample();
        let mut g = f.clone();
        g.scale_joint(1, 0.5);
        for k in 0..20 {
            let t = k as f64 * 0.33;
            let d = f.derivative(1, t, 0) - f.joints[1].q0;
            assert!((g.derivative(1, t, 0) - g.joints[1].q0 - 0.5 * d).abs() < 1e-12);
            assert_eq!(g.derivative(0, t, 1), f.derivative(0, t, 1));
        }
    }
}
