//! The Logistic-function excitation of Qian et al. (2022), eq. 14, and its position → derivative
//! map, eq. 15.
//!
//! One period of a joint rises from `h` to `h + A` (midpoint at `T/4`) and falls back (midpoint at
//! `3T/4`):
//!
//! ```text
//! r = rem(t, T)
//! q(t) = A / (1 + exp(-(w r - w T/4))) + h        r <  T/2
//! q(t) = A / (1 + exp(+(w r - 3 w T/4))) + h      r >= T/2
//! ```
//!
//! Because the logistic function solves `s' = s (1 - s)`, velocity and acceleration are functions of
//! the position alone (eq. 15), with `+` on the rising and `-` on the falling half:
//!
//! ```text
//! q̇ = ±(w/A) (q - h)(A - q + h)
//! q̈ =  (w²/A²)(q - h)(A - q + h)(A - 2q + 2h)
//! ```
//!
//! [`LogisticJoint::derivatives_from_position`] is that map; [`LogisticEstimator`] applies it to a
//! measured position series, which makes it a derivative estimator like central differences.
//!
//! ```
//! use dynid::trajectory::logistic::LogisticJoint;
//! let j = LogisticJoint::resting_ends(2.0, 1.0, 0.0, 1e-4, 0.04).unwrap();
//! let (q, dq, ddq) = j.eval(j.period / 4.0 + 0.3);
//! let (dq2, ddq2) = j.derivatives_from_position(j.period / 4.0 + 0.3, q);
//! assert!((dq - dq2).abs() < 1e-12 && (ddq - ddq2).abs() < 1e-12);
//! ```

use serde::{Deserialize, Serialize};

use super::{Motion, TrajectoryError};

/// Largest value of `s(1-s)(1-2s)` over `s ∈ (0, 1)`, reached at `s = (1 - 1/√3)/2`: `1/(6√3)`.
pub const PEAK_ACCEL_FACTOR: f64 = 0.096_225_044_864_937_63;

/// One joint moving on eq. 14.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct LogisticJoint {
    /// Amplitude `A` (rad); the joint moves between `h` and `h + A`.
    pub a: f64,
    /// Steepness `w` (1/s).
    pub w: f64,
    /// Offset `h` (rad).
    pub h: f64,
    /// Period `T` (s).
    pub period: f64,
}

fn sigmoid(x: f64) -> f64 {
    1.0 / (1.0 + (-x).exp())
}

impl LogisticJoint {
    /// A joint with the shortest period (a multiple of `grid` seconds) for which the start, end and
    /// splice points satisfy eq. 11, `|q̇|, |q̈| < tol`, and sit within `tol` of their rest positions
    /// (`h`, `h + A`), with a factor-2 margin.
    ///
    /// At `r = 0` the logistic argument is `x = -wT/4` and `s < e^x`, `s(1-s) < e^x`, so
    /// `|q − h| < A e^x`, `|q̇| < A w e^x` and `|q̈| < A w² e^x`; the period solves
    /// `A·max(1, w, w²)·e^{-wT/4} = tol/2`.
    pub fn resting_ends(
        a: f64,
        w: f64,
        h: f64,
        tol: f64,
        grid: f64,
    ) -> Result<Self, TrajectoryError> {
        let valid = a.is_finite() && a > 0.0 && w.is_finite() && w > 0.0 && h.is_finite();
        let positive = |x: f64| x > 0.0;
        if !valid || !positive(tol) || !positive(grid) {
            return Err(TrajectoryError::Invalid(format!(
                "logistic joint needs A > 0, w > 0, finite h, tol > 0, grid > 0 (got A = {a}, w = {w}, h = {h}, tol = {tol}, grid = {grid})"
            )));
        }
        let scale = a * w.max(w * w).max(1.0);
        let x = ((0.5 * tol) / scale).ln().min(0.0);
        let t_min = -4.0 * x / w;
        let period = (t_min / grid).ceil().max(1.0) * grid;
        Ok(Self { a, w, h, period })
    }

    /// Position, velocity and acceleration at time `t` (periodic in `T`).
    pub fn eval(&self, t: f64) -> (f64, f64, f64) {
        let (s, sign) = self.phase(t);
        let g = s * (1.0 - s);
        let q = self.a * s + self.h;
        let dq = sign * self.a * self.w * g;
        let ddq = self.a * self.w * self.w * g * (1.0 - 2.0 * s);
        (q, dq, ddq)
    }

    /// Normalised logistic value `s ∈ (0, 1)` and the half's sign (+1 rising, −1 falling).
    fn phase(&self, t: f64) -> (f64, f64) {
        let r = t.rem_euclid(self.period);
        let quarter = 0.25 * self.w * self.period;
        if r < 0.5 * self.period {
            (sigmoid(self.w * r - quarter), 1.0)
        } else {
            (sigmoid(-(self.w * r - 3.0 * quarter)), -1.0)
        }
    }

    /// Eq. 15: velocity and acceleration from a (measured) position `q` at time `t`; the time only
    /// selects the sign of the velocity (rising or falling half).
    pub fn derivatives_from_position(&self, t: f64, q: f64) -> (f64, f64) {
        let r = t.rem_euclid(self.period);
        let sign = if r < 0.5 * self.period { 1.0 } else { -1.0 };
        let (a, w) = (self.a, self.w);
        let u = q - self.h;
        let prod = u * (a - u);
        let dq = sign * (w / a) * prod;
        let ddq = (w * w) / (a * a) * prod * (a - 2.0 * u);
        (dq, ddq)
    }

    /// Peak speed `A w / 4` (at the transition midpoints).
    pub fn peak_velocity(&self) -> f64 {
        0.25 * self.a * self.w
    }

    /// Peak acceleration `A w² / (6√3)`.
    pub fn peak_acceleration(&self) -> f64 {
        PEAK_ACCEL_FACTOR * self.a * self.w * self.w
    }

    /// Times of the two transition midpoints of period `k` (where `q = h + A/2`).
    pub fn midpoints(&self, k: usize) -> [f64; 2] {
        let t0 = k as f64 * self.period;
        [t0 + 0.25 * self.period, t0 + 0.75 * self.period]
    }
}

/// What one joint does during a Logistic experiment.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub enum JointMotion {
    /// Held at this position.
    Rest(f64),
    /// Moving on eq. 14.
    Logistic(LogisticJoint),
}

/// A multi-joint Logistic trajectory: every joint either rests or moves on its own eq. 14, for
/// `periods` periods of the slowest moving joint.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Logistic {
    pub joints: Vec<JointMotion>,
    pub periods: usize,
}

impl Logistic {
    /// The logistic joint `j`, if it moves.
    pub fn moving(&self, j: usize) -> Option<&LogisticJoint> {
        match self.joints.get(j) {
            Some(JointMotion::Logistic(l)) => Some(l),
            _ => None,
        }
    }

    /// Number of moving joints.
    pub fn moving_count(&self) -> usize {
        self.joints
            .iter()
            .filter(|m| matches!(m, JointMotion::Logistic(_)))
            .count()
    }

    /// The estimator that maps measured positions to derivatives with eq. 15.
    pub fn estimator(&self) -> LogisticEstimator {
        LogisticEstimator {
            joints: self.joints.clone(),
        }
    }
}

impl Motion for Logistic {
    fn dof(&self) -> usize {
        self.joints.len()
    }

    fn duration(&self) -> f64 {
        let longest = self
            .joints
            .iter()
            .filter_map(|m| match m {
                JointMotion::Logistic(l) => Some(l.period),
                JointMotion::Rest(_) => None,
            })
            .fold(0.0, f64::max);
        longest * self.periods as f64
    }

    fn eval(&self, t: f64, q: &mut [f64], dq: &mut [f64], ddq: &mut [f64]) {
        for (j, m) in self.joints.iter().enumerate() {
            let (p, v, a) = match m {
                JointMotion::Rest(q0) => (*q0, 0.0, 0.0),
                JointMotion::Logistic(l) => l.eval(t),
            };
            q[j] = p;
            dq[j] = v;
            ddq[j] = a;
        }
    }
}

/// Eq. 15 as a derivative estimator: maps a measured position series to velocity and acceleration.
/// Resting joints get zero derivatives (they are meant to be still; a controller holds them).
#[derive(Debug, Clone, PartialEq)]
pub struct LogisticEstimator {
    joints: Vec<JointMotion>,
}

impl LogisticEstimator {
    /// `t` has `n` samples, `q` is `n × dof` row-major; writes `dq`, `ddq` of the same shape.
    pub fn estimate(&self, t: &[f64], q: &[f64], dq: &mut [f64], ddq: &mut [f64]) {
        let dof = self.joints.len();
        for (i, &ti) in t.iter().enumerate() {
            for (j, m) in self.joints.iter().enumerate() {
                let k = i * dof + j;
                let (v, a) = match m {
                    JointMotion::Rest(_) => (0.0, 0.0),
                    JointMotion::Logistic(l) => l.derivatives_from_position(ti, q[k]),
                };
                dq[k] = v;
                ddq[k] = a;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn joint() -> LogisticJoint {
        LogisticJoint::resting_ends(2.313, 1.523, 0.0, 1e-4, 0.04).unwrap()
    }

    #[test]
    fn eq15_matches_eq14_derivatives_everywhere() {
        let j = joint();
        for k in 0..2000 {
            let t = j.period * k as f64 / 2000.0 * 1.999;
            let (q, dq, ddq) = j.eval(t);
            let (dq2, ddq2) = j.derivatives_from_position(t, q);
            assert!((dq - dq2).abs() < 1e-12, "t = {t}: {dq} vs {dq2}");
            assert!((ddq - ddq2).abs() < 1e-12, "t = {t}: {ddq} vs {ddq2}");
        }
    }

    #[test]
    fn analytic_derivatives_match_finite_differences() {
        let j = joint();
        let h = 1e-4;
        for k in 1..200 {
            let t = j.period * k as f64 / 200.0 + 0.0123;
            let (q0, dq, ddq) = j.eval(t);
            let (qp, _, _) = j.eval(t + h);
            let (qm, _, _) = j.eval(t - h);
            // central differences: truncation error ~ h²·q'''/6 ≈ 1e-8 · O(1)
            assert!(((qp - qm) / (2.0 * h) - dq).abs() < 1e-6);
            assert!(((qp - 2.0 * q0 + qm) / (h * h) - ddq).abs() < 1e-4);
        }
    }

    #[test]
    fn period_satisfies_eq11_at_start_end_and_splice() {
        for (a, w) in [(2.313, 1.523), (2.094, 0.996), (0.5, 3.0), (3.0, 0.2)] {
            let j = LogisticJoint::resting_ends(a, w, 0.0, 1e-4, 0.04).unwrap();
            for t in [
                0.0,
                0.5 * j.period - 1e-12,
                0.5 * j.period,
                j.period - 1e-12,
                j.period,
            ] {
                let (_, dq, ddq) = j.eval(t);
                assert!(
                    dq.abs() < 1e-4 && ddq.abs() < 1e-4,
                    "A={a} w={w} t={t}: {dq} {ddq}"
                );
            }
            // and not wastefully long: rounding up to the grid costs at most a factor e^{w·grid/4}
            let (q, dq, ddq) = j.eval(0.0);
            let floor = 0.5e-4 * (-0.25 * w * 0.04).exp() * 0.99;
            assert!(
                q.abs().max(dq.abs()).max(ddq.abs()) > floor,
                "A={a} w={w}: period {} too long",
                j.period
            );
        }
    }

    #[test]
    fn peaks_are_the_closed_forms() {
        let j = joint();
        let mut vmax: f64 = 0.0;
        let mut amax: f64 = 0.0;
        for k in 0..200_000 {
            let (_, dq, ddq) = j.eval(j.period * k as f64 / 200_000.0);
            vmax = vmax.max(dq.abs());
            amax = amax.max(ddq.abs());
        }
        assert!((vmax - j.peak_velocity()).abs() < 1e-6);
        assert!((amax - j.peak_acceleration()).abs() < 1e-5);
    }

    #[test]
    fn rejects_bad_input() {
        assert!(LogisticJoint::resting_ends(0.0, 1.0, 0.0, 1e-4, 0.01).is_err());
        assert!(LogisticJoint::resting_ends(1.0, f64::NAN, 0.0, 1e-4, 0.01).is_err());
        assert!(LogisticJoint::resting_ends(1.0, 1.0, 0.0, 0.0, 0.01).is_err());
    }
}
