//! Closed-loop simulation: a fixed-step RK4 plant driven by a [`Controller`] that tracks a
//! [`Motion`].
//!
//! The plant is the forward dynamics of any generated arm, `q̈ = (M(q) + Ia)⁻¹ (τ − h(q, q̇) − f(q̇))`
//! (the generated `forward_dynamics` kernel when there is no armature `Ia`),
//! with optional unmodelled [`Effects`] (viscous and Coulomb friction, armature, offsets) so that
//! identification can be tried on data the rigid-body model does not fully explain. The controller
//! runs at the integration rate with a zero-order hold on the torque (as a real servo loop), the log
//! is decimated to `log_every` steps.
//!
//! ```no_run
//! # fn demo(model: &dyn dynid::model::Model, traj: &dyn dynid::trajectory::Motion, theta: &[f64]) {
//! use dynid::{control::Pd, sim::{Plant, SimConfig}};
//! let plant = Plant::new(model, theta.to_vec(), None);
//! let mut pd = Pd { kp: vec![200.0; 2], kd: vec![40.0; 2] };
//! let log = dynid::sim::simulate(&plant, &mut pd, traj, &SimConfig::default()).unwrap();
//! println!("max tracking error {:?}", log.max_tracking_error());
//! # }
//! ```

use crate::cholesky::{cholesky, cholesky_solve};
use crate::control::Controller;
use crate::model::Model;
use crate::params::Effects;
use crate::trajectory::Motion;

/// Simulation failures.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SimError {
    #[error("simulation diverged at t = {t:.3} s (state not finite or |q| > {limit}); the controller cannot hold this arm — check the gains and the parameter estimate")]
    Diverged { t: f64, limit: f64 },
    #[error(
        "mass matrix not positive definite at t = {t:.3} s: the plant parameters are not physical"
    )]
    SingularMass { t: f64 },
    #[error("invalid simulation setup: {0}")]
    Invalid(String),
}

/// Most integration steps one simulation runs (a day at 1 kHz is 8.6e7).
pub const MAX_STEPS: usize = 100_000_000;

/// Most samples one simulation logs.
pub const MAX_LOGGED: usize = 10_000_000;

/// Integration settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SimConfig {
    /// Integration (and control) step, s.
    pub dt: f64,
    /// Log every `log_every`-th step.
    pub log_every: usize,
    /// `|q|` above which the run counts as diverged.
    pub divergence_limit: f64,
}

impl Default for SimConfig {
    /// 1 kHz integration and control, 100 Hz log.
    fn default() -> Self {
        Self {
            dt: 1e-3,
            log_every: 10,
            divergence_limit: 100.0,
        }
    }
}

/// The simulated arm: true base parameters plus optional unmodelled effects.
pub struct Plant<'a> {
    pub model: &'a dyn Model,
    pub theta: Vec<f64>,
    pub effects: Option<Effects>,
}

/// A simulated experiment, row-major `n × dof` per signal.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct SimLog {
    pub dof: usize,
    pub t: Vec<f64>,
    /// Measured (true) position.
    pub q: Vec<f64>,
    /// True velocity.
    pub dq: Vec<f64>,
    /// True acceleration (from the plant at the logged instant).
    pub ddq: Vec<f64>,
    /// Commanded (= applied) torque.
    pub tau: Vec<f64>,
    /// Desired position, velocity, acceleration.
    pub qd: Vec<f64>,
    pub dqd: Vec<f64>,
    pub ddqd: Vec<f64>,
}

impl SimLog {
    /// Number of logged samples.
    pub fn len(&self) -> usize {
        self.t.len()
    }

    /// True when nothing was logged.
    pub fn is_empty(&self) -> bool {
        self.t.is_empty()
    }

    /// `max_t |q_d − q|` per joint.
    pub fn max_tracking_error(&self) -> Vec<f64> {
        let mut e = vec![0.0_f64; self.dof];
        for (k, (qd, q)) in self.qd.iter().zip(&self.q).enumerate() {
            let j = k % self.dof;
            e[j] = e[j].max((qd - q).abs());
        }
        e
    }

    /// Tracking error `q_d − q` of joint `j` as a series.
    pub fn tracking_error(&self, j: usize) -> Vec<f64> {
        (0..self.len())
            .map(|i| self.qd[i * self.dof + j] - self.q[i * self.dof + j])
            .collect()
    }
}

/// Scratch for one forward-dynamics evaluation.
struct Work {
    m: Vec<f64>,
    h: Vec<f64>,
}

impl<'a> Plant<'a> {
    pub fn new(model: &'a dyn Model, theta: Vec<f64>, effects: Option<Effects>) -> Self {
        Self {
            model,
            theta,
            effects,
        }
    }

    /// Forward dynamics `q̈ = (M + Ia)⁻¹ (τ − h − f)`; false if the mass matrix is singular.
    ///
    /// Without armature the generated forward-dynamics kernel does it all (an unrolled LDLᵀ of
    /// `M`, no run-time factorisation), given the effective torque `τ − f`; armature changes `M`,
    /// so then `M` and `h` are formed and factorised here. The kernel does not test `M` for
    /// definiteness: a singular `M` shows as a non-finite `q̈`, an indefinite one (parameters
    /// that are not physical) as the divergence the caller checks for.
    fn accel(&self, q: &[f64], dq: &[f64], tau: &[f64], ddq: &mut [f64], w: &mut Work) -> bool {
        let n = q.len();
        let armature = self.effects.as_ref().and_then(|e| e.armature.as_ref());
        if armature.is_none() {
            w.h.copy_from_slice(tau);
            if let Some(e) = &self.effects {
                for j in 0..n {
                    w.h[j] = e.unload(j, dq[j], tau[j]) - e.torque(j, q[j], dq[j], 0.0);
                }
            }
            self.model.forward_dynamics(q, dq, &w.h, &self.theta, ddq);
            return ddq.iter().all(|x| x.is_finite());
        }
        self.model.mass_matrix(q, &self.theta, &mut w.m);
        self.model.bias(q, dq, &self.theta, &mut w.h);
        if let Some(e) = &self.effects {
            for j in 0..n {
                ddq[j] = e.unload(j, dq[j], tau[j]) - w.h[j] - e.torque(j, q[j], dq[j], 0.0);
                if let Some(ia) = armature {
                    w.m[j * n + j] += ia[j];
                }
            }
        }
        if !cholesky(&mut w.m, n) {
            return false;
        }
        cholesky_solve(&w.m, n, ddq);
        true
    }

    /// Torque the plant needs for `(q, q̇, q̈)`: rigid body plus effects (the "measured" torque of
    /// an ideal experiment).
    pub fn inverse_dynamics(&self, q: &[f64], dq: &[f64], ddq: &[f64], tau: &mut [f64]) {
        self.model.inverse_dynamics(q, dq, ddq, &self.theta, tau);
        if let Some(e) = &self.effects {
            for j in 0..q.len() {
                tau[j] = e.load(j, dq[j], tau[j] + e.torque(j, q[j], dq[j], ddq[j]));
            }
        }
    }
}

/// Runs `controller` on `plant` along `traj`, starting at rest on the trajectory's start.
pub fn simulate(
    plant: &Plant,
    controller: &mut dyn Controller,
    traj: &dyn Motion,
    cfg: &SimConfig,
) -> Result<SimLog, SimError> {
    let n = plant.model.dof();
    let mut q0 = vec![0.0; n];
    let (mut d0, mut a0) = (vec![0.0; n], vec![0.0; n]);
    traj.eval(0.0, &mut q0, &mut d0, &mut a0);
    simulate_from(plant, controller, traj, cfg, &q0, &vec![0.0; n])
}

/// Checks the inputs of [`simulate_from`] and returns the number of steps.
fn checked_steps(
    plant: &Plant,
    traj: &dyn Motion,
    cfg: &SimConfig,
    q0: &[f64],
    dq0: &[f64],
) -> Result<usize, SimError> {
    let n = plant.model.dof();
    if traj.dof() != n || q0.len() != n || dq0.len() != n || plant.theta.len() != plant.model.nb() {
        return Err(SimError::Invalid(format!(
            "arm {} has {} joints and {} base parameters; trajectory has {}, start state {}/{}, θ {}",
            plant.model.name(),
            n,
            plant.model.nb(),
            traj.dof(),
            q0.len(),
            dq0.len(),
            plant.theta.len()
        )));
    }
    if cfg.dt.is_nan() || cfg.dt <= 0.0 || cfg.log_every == 0 {
        return Err(SimError::Invalid(format!(
            "dt must be > 0 and log_every ≥ 1 (got {}, {})",
            cfg.dt, cfg.log_every
        )));
    }
    let steps_f = (traj.duration() / cfg.dt).round();
    if !(steps_f.is_finite() && (0.0..=MAX_STEPS as f64).contains(&steps_f)) {
        return Err(SimError::Invalid(format!(
            "duration {} s at dt = {} s is {steps_f} steps; at most {MAX_STEPS} are simulated",
            traj.duration(),
            cfg.dt
        )));
    }
    let steps = steps_f as usize;
    if steps / cfg.log_every > MAX_LOGGED {
        return Err(SimError::Invalid(format!(
            "{} logged samples requested; at most {MAX_LOGGED} — log less often",
            steps / cfg.log_every
        )));
    }
    Ok(steps)
}

impl SimLog {
    /// An empty log of an `n`-joint arm with room for `cap` samples.
    fn with_capacity(n: usize, cap: usize) -> Self {
        let mut log = SimLog {
            dof: n,
            ..Default::default()
        };
        for v in [
            &mut log.q,
            &mut log.dq,
            &mut log.ddq,
            &mut log.tau,
            &mut log.qd,
            &mut log.dqd,
            &mut log.ddqd,
        ] {
            v.reserve(cap * n);
        }
        log.t.reserve(cap);
        log
    }
}

/// Classical RK4 on x = (q, q̇) with τ held over the step: the four stages' (q̇, q̈) and the
/// intermediate state, allocated once.
struct Rk4 {
    k: [[Vec<f64>; 2]; 4],
    qs: Vec<f64>,
    dqs: Vec<f64>,
}

impl Rk4 {
    fn new(n: usize) -> Self {
        let z = || vec![0.0; n];
        Rk4 {
            k: [[z(), z()], [z(), z()], [z(), z()], [z(), z()]],
            qs: z(),
            dqs: z(),
        }
    }

    /// Advances `(q, dq)` by `h` from the acceleration `acc` at the start; false when the mass
    /// matrix is singular at a stage.
    #[allow(clippy::too_many_arguments)]
    fn step(
        &mut self,
        plant: &Plant,
        q: &mut [f64],
        dq: &mut [f64],
        acc: &[f64],
        tau: &[f64],
        h: f64,
        w: &mut Work,
    ) -> bool {
        let n = q.len();
        let [[k1v, k1a], [k2v, k2a], [k3v, k3a], [k4v, k4a]] = &mut self.k;
        let (qs, dqs) = (&mut self.qs, &mut self.dqs);
        k1v.copy_from_slice(dq);
        k1a.copy_from_slice(acc);
        for j in 0..n {
            qs[j] = q[j] + 0.5 * h * k1v[j];
            dqs[j] = dq[j] + 0.5 * h * k1a[j];
        }
        k2v.copy_from_slice(dqs);
        let ok2 = plant.accel(qs, dqs, tau, k2a, w);
        for j in 0..n {
            qs[j] = q[j] + 0.5 * h * k2v[j];
            dqs[j] = dq[j] + 0.5 * h * k2a[j];
        }
        k3v.copy_from_slice(dqs);
        let ok3 = plant.accel(qs, dqs, tau, k3a, w);
        for j in 0..n {
            qs[j] = q[j] + h * k3v[j];
            dqs[j] = dq[j] + h * k3a[j];
        }
        k4v.copy_from_slice(dqs);
        let ok4 = plant.accel(qs, dqs, tau, k4a, w);
        if !(ok2 && ok3 && ok4) {
            return false;
        }
        for j in 0..n {
            q[j] += h / 6.0 * (k1v[j] + 2.0 * k2v[j] + 2.0 * k3v[j] + k4v[j]);
            dq[j] += h / 6.0 * (k1a[j] + 2.0 * k2a[j] + 2.0 * k3a[j] + k4a[j]);
        }
        true
    }
}

/// Runs `controller` on `plant` along `traj` from the state `(q0, dq0)`.
pub fn simulate_from(
    plant: &Plant,
    controller: &mut dyn Controller,
    traj: &dyn Motion,
    cfg: &SimConfig,
    q0: &[f64],
    dq0: &[f64],
) -> Result<SimLog, SimError> {
    let n = plant.model.dof();
    let steps = checked_steps(plant, traj, cfg, q0, dq0)?;
    let mut log = SimLog::with_capacity(n, steps / cfg.log_every + 1);
    let mut w = Work {
        m: vec![0.0; n * n],
        h: vec![0.0; n],
    };
    let (mut q, mut dq) = (q0.to_vec(), dq0.to_vec());
    let (mut qd, mut dqd, mut ddqd) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
    let mut tau = vec![0.0; n];
    let mut acc = vec![0.0; n];
    let mut rk4 = Rk4::new(n);
    let h = cfg.dt;

    for step in 0..=steps {
        let t = step as f64 * h;
        traj.eval(t, &mut qd, &mut dqd, &mut ddqd);
        controller.torque(&q, &dq, &qd, &dqd, &ddqd, &mut tau);
        if !plant.accel(&q, &dq, &tau, &mut acc, &mut w) {
            return Err(SimError::SingularMass { t });
        }
        if step % cfg.log_every == 0 {
            log.t.push(t);
            log.q.extend_from_slice(&q);
            log.dq.extend_from_slice(&dq);
            log.ddq.extend_from_slice(&acc);
            log.tau.extend_from_slice(&tau);
            log.qd.extend_from_slice(&qd);
            log.dqd.extend_from_slice(&dqd);
            log.ddqd.extend_from_slice(&ddqd);
        }
        if step == steps {
            break;
        }
        if !rk4.step(plant, &mut q, &mut dq, &acc, &tau, h, &mut w) {
            return Err(SimError::SingularMass { t });
        }
        let bad = q.iter().chain(&dq).any(|x| !x.is_finite())
            || q.iter().any(|x| x.abs() > cfg.divergence_limit);
        if bad {
            return Err(SimError::Diverged {
                t: t + h,
                limit: cfg.divergence_limit,
            });
        }
    }
    Ok(log)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The generated forward dynamics (no armature) inverts inverse dynamics with the other
    /// effects on, as the factorising path does with armature.
    #[test]
    fn generated_forward_dynamics_inverts_inverse_dynamics_without_armature() {
        let model = crate::arms::find("puma560").expect("puma560");
        let mut p = vec![0.0; 60];
        for (i, l) in p.chunks_mut(10).enumerate() {
            let m = 2.0 + i as f64;
            l.copy_from_slice(&[0.3, 0.01, 0.0, 0.25, -0.02, 0.2, 0.1 * m, 0.05, -0.1, m]);
        }
        let mut theta = vec![0.0; model.nb()];
        model.base_params(&p, &mut theta);
        let effects = Effects {
            viscous: Some(vec![0.3; 6]),
            coulomb: Some(vec![0.2; 6]),
            ..Effects::default()
        };
        let plant = Plant::new(model, theta, Some(effects));
        let mut w = Work {
            m: vec![0.0; 36],
            h: vec![0.0; 6],
        };
        let (q, dq, ddq) = (
            [0.3, -1.2, 0.5, 2.0, -0.7, 1.1],
            [0.8, -0.4, 0.2, 1.0, -1.5, 0.3],
            [2.0, 1.5, -1.0, 0.5, 3.0, -2.0],
        );
        let mut tau = [0.0; 6];
        plant.inverse_dynamics(&q, &dq, &ddq, &mut tau);
        let mut back = [0.0; 6];
        assert!(plant.accel(&q, &dq, &tau, &mut back, &mut w));
        for j in 0..6 {
            assert!((back[j] - ddq[j]).abs() < 1e-9, "{back:?} vs {ddq:?}");
        }
    }

    /// Forward dynamics inverts inverse dynamics with every effect on, load-dependent friction
    /// included (inverted in closed form by `Effects::unload`), motoring and braking.
    #[test]
    fn forward_dynamics_inverts_inverse_dynamics_with_all_effects() {
        let model = crate::arms::find("planar2").expect("planar2");
        let theta = vec![2.0, 2.0, 0.0, 1.0, 1.0, 0.0];
        let effects = Effects {
            viscous: Some(vec![0.3, 0.2]),
            coulomb: Some(vec![0.5, 0.1]),
            armature: Some(vec![0.1, 0.05]),
            offset: Some(vec![0.2, -0.1]),
            spring: Some(vec![1.0, -0.5]),
            loadcoulomb: Some(vec![0.15, 0.3]),
            ..Effects::default()
        };
        let plant = Plant::new(model, theta, Some(effects));
        let mut w = Work {
            m: vec![0.0; 4],
            h: vec![0.0; 2],
        };
        for (q, dq, ddq) in [
            ([0.3, -1.2], [0.8, -0.4], [2.0, 1.5]),
            ([2.0, 0.5], [-0.6, 1.1], [-3.0, 0.2]),
            ([-1.0, 2.5], [0.0, 0.3], [0.5, -4.0]),
        ] {
            let mut tau = [0.0; 2];
            plant.inverse_dynamics(&q, &dq, &ddq, &mut tau);
            let mut back = [0.0; 2];
            assert!(plant.accel(&q, &dq, &tau, &mut back, &mut w));
            for j in 0..2 {
                assert!((back[j] - ddq[j]).abs() < 1e-9, "{back:?} vs {ddq:?}");
            }
        }
    }
}
