//! Reference trajectories: the paper's Logistic excitation ([`logistic`]), Swevers' Fourier series
//! ([`fourier`]) and a plain sinusoid (the paper's validation motion), all with analytic
//! derivatives.
//!
//! ```
//! use dynid::trajectory::{Sine, Motion};
//! // the paper's validation motion q1 = sin t, q2 = sin(−t)
//! let v = Sine { amplitude: vec![1.0, -1.0], omega: vec![1.0, 1.0], offset: vec![0.0, 0.0], duration: 10.0 };
//! let (mut q, mut dq, mut ddq) = ([0.0; 2], [0.0; 2], [0.0; 2]);
//! v.eval(1.0, &mut q, &mut dq, &mut ddq);
//! assert!((q[0] - 1f64.sin()).abs() < 1e-15 && (q[1] + 1f64.sin()).abs() < 1e-15);
//! ```

pub mod fourier;
pub mod fourier_quintic;
pub mod logistic;
pub mod logistic_n;

use serde::{Deserialize, Serialize};

/// Errors from building or fitting trajectories.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum TrajectoryError {
    #[error("invalid trajectory: {0}")]
    Invalid(String),
}

/// A desired joint motion with analytic derivatives.
pub trait Motion: Send + Sync {
    /// Number of joints.
    fn dof(&self) -> usize;
    /// Length of the motion in seconds (it starts at `t = 0`).
    fn duration(&self) -> f64;
    /// Desired position, velocity and acceleration at `t` (slices of length `dof`).
    fn eval(&self, t: f64, q: &mut [f64], dq: &mut [f64], ddq: &mut [f64]);
}

/// `q_j(t) = offset_j + amplitude_j · sin(omega_j t)`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Sine {
    pub amplitude: Vec<f64>,
    pub omega: Vec<f64>,
    pub offset: Vec<f64>,
    pub duration: f64,
}

impl Motion for Sine {
    fn dof(&self) -> usize {
        self.amplitude.len()
    }

    fn duration(&self) -> f64 {
        self.duration
    }

    fn eval(&self, t: f64, q: &mut [f64], dq: &mut [f64], ddq: &mut [f64]) {
        for j in 0..self.dof() {
            let (a, w) = (self.amplitude[j], self.omega[j]);
            let (s, c) = (w * t).sin_cos();
            q[j] = self.offset[j] + a * s;
            dq[j] = a * w * c;
            ddq[j] = -a * w * w * s;
        }
    }
}

/// A serialisable choice of trajectory (what `dynid excite` writes and `dynid simulate` reads).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "lowercase")]
pub enum TrajectorySpec {
    Logistic(logistic::Logistic),
    Fourier(fourier::Fourier),
    Sine(Sine),
    /// Fourier series with a quintic boundary term (`dynid excite --kind fourier`).
    #[serde(rename = "fourier_quintic")]
    FourierQuintic(fourier_quintic::FourierQuintic),
    /// The Logistic family on all joints at once (`dynid excite --kind logistic`).
    #[serde(rename = "logistic_n")]
    LogisticN(logistic_n::LogisticN),
}

impl TrajectorySpec {
    /// Checks a trajectory read from a file: consistent lengths, finite numbers, positive periods.
    pub fn validate(&self) -> Result<(), TrajectoryError> {
        let bad = |what: String| Err(TrajectoryError::Invalid(what));
        let finite = |v: &[f64]| v.iter().all(|x| x.is_finite());
        match self {
            Self::Logistic(l) => {
                if l.joints.is_empty() || l.periods == 0 {
                    return bad(
                        "a logistic trajectory needs at least one joint and one period".into(),
                    );
                }
                for (j, m) in l.joints.iter().enumerate() {
                    match m {
                        logistic::JointMotion::Rest(q) if !q.is_finite() => {
                            return bad(format!("joint {}: rest position is not finite", j + 1))
                        }
                        logistic::JointMotion::Logistic(x) => {
                            let ok = finite(&[x.a, x.w, x.h, x.period])
                                && x.a > 0.0
                                && x.w > 0.0
                                && x.period > 0.0;
                            if !ok {
                                return bad(format!("joint {}: logistic needs finite A > 0, w > 0, period > 0 and h", j + 1));
                            }
                        }
                        _ => {}
                    }
                }
                if l.moving_count() == 0 {
                    return bad("a logistic trajectory needs at least one moving joint (it has no duration otherwise)".into());
                }
            }
            Self::Fourier(f) => {
                if f.joints.is_empty() || f.periods == 0 {
                    return bad(
                        "a Fourier trajectory needs at least one joint and one period".into(),
                    );
                }
                for (j, x) in f.joints.iter().enumerate() {
                    if !(finite(&x.a)
                        && finite(&x.b)
                        && x.q0.is_finite()
                        && x.wf.is_finite()
                        && x.wf > 0.0)
                    {
                        return bad(format!(
                            "joint {}: Fourier series needs w_f > 0 and finite coefficients",
                            j + 1
                        ));
                    }
                }
            }
            Self::Sine(x) => {
                let n = x.amplitude.len();
                if n == 0 || x.omega.len() != n || x.offset.len() != n {
                    return bad(format!(
                        "a sine trajectory needs amplitude, omega and offset of the same non-zero length (got {}, {}, {})",
                        n,
                        x.omega.len(),
                        x.offset.len()
                    ));
                }
                if !(finite(&x.amplitude)
                    && finite(&x.omega)
                    && finite(&x.offset)
                    && x.duration.is_finite()
                    && x.duration > 0.0)
                {
                    return bad("a sine trajectory needs finite values and a duration > 0".into());
                }
            }
            Self::FourierQuintic(f) => {
                let ok = f.period.is_finite()
                    && f.period > 0.0
                    && !f.joints.is_empty()
                    && f.joints.iter().all(|j| {
                        j.a.len() == j.b.len()
                            && finite(&j.a)
                            && finite(&j.b)
                            && finite(&j.c)
                            && j.q0.is_finite()
                    });
                if !ok {
                    return bad("a fourier_quintic trajectory needs a period > 0, at least one joint, and finite coefficients with as many a as b".into());
                }
            }
            Self::LogisticN(l) => {
                let ok = l.period.is_finite()
                    && l.period > 0.0
                    && !l.joints.is_empty()
                    && l.joints
                        .iter()
                        .all(|j| finite(&[j.q0, j.a, j.w]) && j.w > 0.0);
                if !ok {
                    return bad("a logistic_n trajectory needs a period > 0, at least one joint, finite q0 and a, and w > 0".into());
                }
            }
        }
        Ok(())
    }

    /// The trajectory as a trait object.
    pub fn as_dyn(&self) -> &dyn Motion {
        match self {
            Self::Logistic(l) => l,
            Self::Fourier(f) => f,
            Self::Sine(s) => s,
            Self::FourierQuintic(f) => f,
            Self::LogisticN(l) => l,
        }
    }
}

/// Samples of a trajectory on a uniform grid `t_i = i·dt`, `i = 0..n` (row-major `n × dof`).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Samples {
    pub dof: usize,
    pub t: Vec<f64>,
    pub q: Vec<f64>,
    pub dq: Vec<f64>,
    pub ddq: Vec<f64>,
}

/// Samples `traj` every `dt` seconds over `[0, duration)` (or `[0, duration]` with `closed`).
pub fn sample(traj: &dyn Motion, dt: f64, closed: bool) -> Samples {
    let dof = traj.dof();
    let steps = (traj.duration() / dt).round() as usize;
    let n = if closed { steps + 1 } else { steps };
    let mut s = Samples {
        dof,
        t: Vec::with_capacity(n),
        q: vec![0.0; n * dof],
        dq: vec![0.0; n * dof],
        ddq: vec![0.0; n * dof],
    };
    for i in 0..n {
        let t = i as f64 * dt;
        s.t.push(t);
        let r = i * dof..(i + 1) * dof;
        traj.eval(t, &mut s.q[r.clone()], &mut s.dq[r.clone()], &mut s.ddq[r]);
    }
    s
}
