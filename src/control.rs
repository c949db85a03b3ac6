//! Tracking controllers built on an arm's dynamics with a parameter estimate `θ̂` (the generated
//! kernels, or the reference recursions of a D-H table: [`Dynamics`]).
//!
//! - [`Rhftc`]: the paper's robust finite-time controller (eq. 23),
//!   `τ = M̂(q)[q̈d + Kp Sig(e)^α1 + Kd Sig(ė)^α2] + ĥ(q, q̇)` with `e = qd − q` and
//!   `Sig(x)^α = |x|^α sgn(x)`. The paper prints minus signs before the gains; with `e = qd − q` that
//!   is positive feedback on the error and diverges ([`SignConvention::Paper`] keeps it for the
//!   demonstration, [`SignConvention::Stable`] is the default).
//! - [`Ctc`]: computed-torque PD, `τ = M̂(q)[q̈d + Kp e + Kd ė] + ĥ(q, q̇)`.
//! - [`Pd`]: decentralised PD, `τ = Kp e + Kd ė` (no model).
//!
//! Model-based laws need a positive definite `M̂(q)`: an indefinite one is diagonally loaded (see
//! `LOADING_FLOOR`), and with no inertia at all — `θ̂ = 0`, where eq. 23 commands no torque and
//! the arm would simply fall — they run their PD fallback. Both cases are counted.
//!
//! ```
//! use dynid::control::sig;
//! assert_eq!(sig(-4.0, 0.5), -2.0);
//! ```

use crate::cholesky::cholesky;
use crate::dynamics::{Dynamics, Generated};
use crate::model::Model;

/// A joint-torque feedback law.
pub trait Controller {
    /// Torque for the measured state `(q, q̇)` and the desired `(qd, q̇d, q̈d)`.
    fn torque(
        &mut self,
        q: &[f64],
        dq: &[f64],
        qd: &[f64],
        dqd: &[f64],
        ddqd: &[f64],
        tau: &mut [f64],
    );
}

/// `Sig(x)^α = |x|^α · sgn(x)`.
pub fn sig(x: f64, alpha: f64) -> f64 {
    if x == 0.0 {
        return 0.0;
    }
    x.abs().powf(alpha).copysign(x)
}

/// Decentralised PD (N·m/rad, N·m·s/rad).
#[derive(Debug, Clone, PartialEq)]
pub struct Pd {
    pub kp: Vec<f64>,
    pub kd: Vec<f64>,
}

impl Controller for Pd {
    fn torque(
        &mut self,
        q: &[f64],
        dq: &[f64],
        qd: &[f64],
        dqd: &[f64],
        _ddqd: &[f64],
        tau: &mut [f64],
    ) {
        for j in 0..q.len() {
            tau[j] = self.kp[j] * (qd[j] - q[j]) + self.kd[j] * (dqd[j] - dq[j]);
        }
    }
}

/// Sign of the feedback terms of eq. 23.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SignConvention {
    /// `+Kp Sig(e)^α1 + Kd Sig(ė)^α2` with `e = qd − q`: negative feedback, stable.
    Stable,
    /// As printed in the paper, `−Kp Sig(e)^α1 − Kd Sig(ė)^α2`: unstable with `e = qd − q`.
    Paper,
}

/// Gains of eq. 23 (the paper's: `Kp = (2, 4)`, `Kd = (20, 4)`, `α1 = 0.7`, `α2 = 0.82`).
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct RhftcGains {
    pub kp: Vec<f64>,
    pub kd: Vec<f64>,
    pub alpha1: f64,
    pub alpha2: f64,
}

impl RhftcGains {
    /// The paper's gains for a 2-DOF arm.
    pub fn paper() -> Self {
        Self {
            kp: vec![2.0, 4.0],
            kd: vec![20.0, 4.0],
            alpha1: 0.7,
            alpha2: 0.82,
        }
    }
}

/// How a model-based controller's steps went.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Usage {
    /// Fraction of control steps that used the PD fallback.
    pub fallback: f64,
    /// Fraction of control steps where `M̂(q)` had to be diagonally loaded.
    pub loaded: f64,
}

/// A controller built on the model (`τ = M̂ v + ĥ`): [`Rhftc`] and [`Ctc`].
pub trait ModelBased: Controller {
    fn usage(&self) -> Usage;
}

/// Model-based part shared by [`Rhftc`] and [`Ctc`]: `τ = M̂ v + ĥ`, or the fallback PD.
struct ModelLaw<'a> {
    body: Box<dyn Dynamics + 'a>,
    fallback: Pd,
    m: Vec<f64>,
    chol: Vec<f64>,
    h: Vec<f64>,
    v: Vec<f64>,
    fallback_steps: usize,
    loaded_steps: usize,
    steps: usize,
}

/// Smallest eigenvalue an indefinite `M̂` is loaded up to, relative to its mean diagonal.
pub const LOADING_FLOOR: f64 = 0.05;

impl<'a> ModelLaw<'a> {
    /// How often the fallback and the loading were needed so far (0 before the first step).
    fn usage(&self) -> Usage {
        let fraction = |count: usize| count as f64 / self.steps.max(1) as f64;
        Usage {
            fallback: fraction(self.fallback_steps),
            loaded: fraction(self.loaded_steps),
        }
    }

    /// Whether `M̂ + shift·I` is positive definite.
    fn is_pd_with_shift(&mut self, n: usize, shift: f64) -> bool {
        self.chol.copy_from_slice(&self.m);
        for i in 0..n {
            self.chol[i * n + i] += shift;
        }
        cholesky(&mut self.chol, n)
    }

    fn new(body: Box<dyn Dynamics + 'a>, fallback: Pd) -> Self {
        let n = body.dof();
        Self {
            body,
            fallback,
            m: vec![0.0; n * n],
            chol: vec![0.0; n * n],
            h: vec![0.0; n],
            v: vec![0.0; n],
            fallback_steps: 0,
            loaded_steps: 0,
            steps: 0,
        }
    }

    /// `τ = M̂(q)·v + ĥ(q, q̇)` with `v` already in `self.v`.
    ///
    /// An estimate can give an indefinite `M̂(q)` (e.g. an underestimated link inertia early in the
    /// iteration); then `M̂` is diagonally loaded just enough that its smallest eigenvalue reaches
    /// `LOADING_FLOOR · trace/n` (bisection on Cholesky, allocation-free), which keeps the feedback
    /// direction and the gravity/Coriolis model. With no inertia at all (`trace M̂ ≤ 0`, e.g.
    /// `θ̂ = 0`) the law has nothing to scale its feedback with and the PD fallback runs instead.
    fn apply(
        &mut self,
        q: &[f64],
        dq: &[f64],
        qd: &[f64],
        dqd: &[f64],
        ddqd: &[f64],
        tau: &mut [f64],
    ) {
        let n = q.len();
        self.steps += 1;
        self.body.mass_matrix(q, &mut self.m);
        let trace: f64 = (0..n).map(|i| self.m[i * n + i]).sum();
        if trace.is_nan() || trace <= 0.0 {
            self.fallback_steps += 1;
            self.fallback.torque(q, dq, qd, dqd, ddqd, tau);
            return;
        }
        let floor = LOADING_FLOOR * trace / n as f64;
        if !self.is_pd_with_shift(n, -floor) {
            // smallest λ ≥ 0 with M̂ + λI − floor·I ≻ 0; λ = trace is always enough
            let (mut lo, mut hi) = (0.0, trace + floor);
            for _ in 0..40 {
                let mid = 0.5 * (lo + hi);
                if self.is_pd_with_shift(n, mid - floor) {
                    hi = mid;
                } else {
                    lo = mid;
                }
            }
            for i in 0..n {
                self.m[i * n + i] += hi;
            }
            self.loaded_steps += 1;
        }
        self.body.bias(q, dq, &mut self.h);
        for (i, t) in tau.iter_mut().enumerate().take(n) {
            *t = self.h[i] + (0..n).map(|k| self.m[i * n + k] * self.v[k]).sum::<f64>();
        }
    }
}

/// The paper's robust finite-time controller, eq. 23.
pub struct Rhftc<'a> {
    law: ModelLaw<'a>,
    pub gains: RhftcGains,
    pub sign: SignConvention,
}

impl<'a> Rhftc<'a> {
    /// Eq. 23 with the estimate `theta_hat` (base parameters of `model`), falling back to `fallback`
    /// where `M̂(q)` is not positive definite.
    pub fn new(model: &'a dyn Model, theta_hat: Vec<f64>, gains: RhftcGains, fallback: Pd) -> Self {
        Self::on(Box::new(Generated::new(model, theta_hat)), gains, fallback)
    }

    /// Eq. 23 on any arm's dynamics with the estimate bound in (e.g. a D-H table's reference
    /// dynamics, [`crate::dynamics::Reference`]).
    pub fn on(estimate: Box<dyn Dynamics + 'a>, gains: RhftcGains, fallback: Pd) -> Self {
        Self {
            law: ModelLaw::new(estimate, fallback),
            gains,
            sign: SignConvention::Stable,
        }
    }
}

impl ModelBased for Rhftc<'_> {
    fn usage(&self) -> Usage {
        self.law.usage()
    }
}

impl Controller for Rhftc<'_> {
    fn torque(
        &mut self,
        q: &[f64],
        dq: &[f64],
        qd: &[f64],
        dqd: &[f64],
        ddqd: &[f64],
        tau: &mut [f64],
    ) {
        let s = match self.sign {
            SignConvention::Stable => 1.0,
            SignConvention::Paper => -1.0,
        };
        let g = &self.gains;
        for j in 0..q.len() {
            let (e, de) = (qd[j] - q[j], dqd[j] - dq[j]);
            self.law.v[j] =
                ddqd[j] + s * (g.kp[j] * sig(e, g.alpha1) + g.kd[j] * sig(de, g.alpha2));
        }
        self.law.apply(q, dq, qd, dqd, ddqd, tau);
    }
}

/// Computed-torque PD, `τ = M̂[q̈d + Kp e + Kd ė] + ĥ`.
pub struct Ctc<'a> {
    law: ModelLaw<'a>,
    pub kp: Vec<f64>,
    pub kd: Vec<f64>,
}

impl<'a> Ctc<'a> {
    pub fn new(
        model: &'a dyn Model,
        theta_hat: Vec<f64>,
        kp: Vec<f64>,
        kd: Vec<f64>,
        fallback: Pd,
    ) -> Self {
        Self::on(Box::new(Generated::new(model, theta_hat)), kp, kd, fallback)
    }

    /// Computed torque on any arm's dynamics with the estimate bound in.
    pub fn on(estimate: Box<dyn Dynamics + 'a>, kp: Vec<f64>, kd: Vec<f64>, fallback: Pd) -> Self {
        Self {
            law: ModelLaw::new(estimate, fallback),
            kp,
            kd,
        }
    }
}

impl ModelBased for Ctc<'_> {
    fn usage(&self) -> Usage {
        self.law.usage()
    }
}

impl Controller for Ctc<'_> {
    fn torque(
        &mut self,
        q: &[f64],
        dq: &[f64],
        qd: &[f64],
        dqd: &[f64],
        ddqd: &[f64],
        tau: &mut [f64],
    ) {
        for j in 0..q.len() {
            self.law.v[j] = ddqd[j] + self.kp[j] * (qd[j] - q[j]) + self.kd[j] * (dqd[j] - dq[j]);
        }
        self.law.apply(q, dq, qd, dqd, ddqd, tau);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sig_is_odd_and_powered() {
        assert_eq!(sig(0.0, 0.7), 0.0);
        assert!((sig(0.25, 0.5) - 0.5).abs() < 1e-15);
        assert!((sig(-0.25, 0.5) + 0.5).abs() < 1e-15);
        assert!((sig(-8.0, 1.0 / 3.0) + 2.0).abs() < 1e-12);
    }
}
