//! Closed-loop simulation: a fixed-step plant (RK4, or linearly implicit Euler for stiff effects:
//! [`Integrator`]) driven by a [`Controller`] that tracks a [`Motion`].
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

mod accel_jacobian;
mod linearly_implicit_euler;
mod rk4;

use crate::cholesky::{cholesky, cholesky_solve};
use crate::control::Controller;
use crate::dynamics::{Dynamics, Generated};
use crate::model::Model;
use crate::params::Effects;
use crate::trajectory::Motion;
use linearly_implicit_euler::LinearlyImplicitEuler;
use rk4::Rk4;

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

/// How the plant's state advances over one step (the torque held over it).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Integrator {
    /// Classical fourth-order Runge–Kutta: four forward-dynamics evaluations a step.
    #[default]
    Rk4,
    /// Linearly implicit Euler: one forward dynamics, one Jacobian (the generated derivative
    /// kernels) and one `n × n` solve a step; first order, but stable at any step on stiff
    /// effects (large viscous friction), where RK4 needs `h` below ~2.8 / the fastest rate.
    LinearlyImplicitEuler,
}

/// Integration settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SimConfig {
    /// Integration (and control) step, s.
    pub dt: f64,
    /// Log every `log_every`-th step.
    pub log_every: usize,
    /// `|q|` above which the run counts as diverged.
    pub divergence_limit: f64,
    /// The integration scheme.
    pub integrator: Integrator,
}

impl Default for SimConfig {
    /// 1 kHz RK4 integration and control, 100 Hz log.
    fn default() -> Self {
        Self {
            dt: 1e-3,
            log_every: 10,
            divergence_limit: 100.0,
            integrator: Integrator::Rk4,
        }
    }
}

/// The simulated arm: its true rigid-body dynamics plus optional unmodelled effects.
pub struct Plant<'a> {
    pub body: Box<dyn Dynamics + 'a>,
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

/// Scratch for the forward dynamics and its Jacobian: `M`, effective torque, the effects'
/// slopes, derivative-kernel output (`3n²`) and a column.
struct Work {
    m: Vec<f64>,
    h: Vec<f64>,
    gq: Vec<f64>,
    gv: Vec<f64>,
    d: Vec<f64>,
    col: Vec<f64>,
}

impl Work {
    fn new(n: usize) -> Self {
        let z = |len| vec![0.0; len];
        Work {
            m: z(n * n),
            h: z(n),
            gq: z(n),
            gv: z(n),
            d: z(3 * n * n),
            col: z(n),
        }
    }
}

/// The state of one integration scheme.
enum Stepper {
    Rk4(Rk4),
    LinearlyImplicitEuler(LinearlyImplicitEuler),
}

impl Stepper {
    fn new(integrator: Integrator, n: usize) -> Self {
        match integrator {
            Integrator::Rk4 => Stepper::Rk4(Rk4::new(n)),
            Integrator::LinearlyImplicitEuler => {
                Stepper::LinearlyImplicitEuler(LinearlyImplicitEuler::new(n))
            }
        }
    }

    /// Advances `(q, dq)` by `h`; false when a matrix is singular.
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
        match self {
            Stepper::Rk4(s) => s.step(plant, q, dq, acc, tau, h, w),
            Stepper::LinearlyImplicitEuler(s) => s.step(plant, q, dq, acc, tau, h, w),
        }
    }
}

impl<'a> Plant<'a> {
    /// A generated arm with true base parameters `theta`.
    pub fn new(model: &'a dyn Model, theta: Vec<f64>, effects: Option<Effects>) -> Self {
        Self::on(Box::new(Generated::new(model, theta)), effects)
    }

    /// Any arm's dynamics ([`crate::dynamics::Reference`] for a D-H table or a URDF).
    pub fn on(body: Box<dyn Dynamics + 'a>, effects: Option<Effects>) -> Self {
        Self { body, effects }
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
            self.body.forward_dynamics(q, dq, &w.h, ddq);
            return ddq.iter().all(|x| x.is_finite());
        }
        self.body.mass_matrix(q, &mut w.m);
        self.body.bias(q, dq, &mut w.h);
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
        self.body.inverse_dynamics(q, dq, ddq, tau);
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
    let n = plant.body.dof();
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
    let n = plant.body.dof();
    if let Some(why) = plant.body.invalid() {
        return Err(SimError::Invalid(why));
    }
    if traj.dof() != n || q0.len() != n || dq0.len() != n {
        return Err(SimError::Invalid(format!(
            "arm {} has {} joints; trajectory has {}, start state {}/{}",
            plant.body.name(),
            n,
            traj.dof(),
            q0.len(),
            dq0.len(),
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

/// Runs `controller` on `plant` along `traj` from the state `(q0, dq0)`.
pub fn simulate_from(
    plant: &Plant,
    controller: &mut dyn Controller,
    traj: &dyn Motion,
    cfg: &SimConfig,
    q0: &[f64],
    dq0: &[f64],
) -> Result<SimLog, SimError> {
    let n = plant.body.dof();
    let steps = checked_steps(plant, traj, cfg, q0, dq0)?;
    let mut log = SimLog::with_capacity(n, steps / cfg.log_every + 1);
    let mut w = Work::new(n);
    let (mut q, mut dq) = (q0.to_vec(), dq0.to_vec());
    let (mut qd, mut dqd, mut ddqd) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
    let mut tau = vec![0.0; n];
    let mut acc = vec![0.0; n];
    let mut stepper = Stepper::new(cfg.integrator, n);
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
        if !stepper.step(plant, &mut q, &mut dq, &acc, &tau, h, &mut w) {
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
        let mut w = Work::new(6);
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
        let mut w = Work::new(2);
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

    /// `accel_jacobian` against central differences (one Richardson step) of `accel` itself, on
    /// PUMA 560 with smooth effects, with armature (the ID-derivative path) and without (the
    /// FD-derivative kernel). Tolerance 1e-7 of the largest entry: the effects' slopes are
    /// differences accurate to ~1e-10 of the torque, times `M⁻¹`; the extrapolated check is good
    /// to ~1e-10, so a wrong sign, column or missing effect is off by O(1).
    #[test]
    fn accel_jacobian_is_the_derivative_of_accel() {
        let model = crate::arms::find("puma560").expect("puma560");
        let mut p = vec![0.0; 60];
        for (i, l) in p.chunks_mut(10).enumerate() {
            let m = 2.0 + i as f64;
            l.copy_from_slice(&[0.3, 0.01, 0.0, 0.25, -0.02, 0.2, 0.1 * m, 0.05, -0.1, m]);
        }
        let mut theta = vec![0.0; model.nb()];
        model.base_params(&p, &mut theta);
        let smooth = Effects {
            viscous: Some(vec![0.3; 6]),
            coulomb: Some(vec![0.2; 6]),
            stribeck: Some(vec![0.1; 6]),
            spring: Some(vec![1.0; 6]),
            loadcoulomb: Some(vec![0.1; 6]),
            sign_velocity: Some(vec![0.5; 6]),
            ..Effects::default()
        };
        let with_armature = Effects {
            armature: Some(vec![0.2; 6]),
            ..smooth.clone()
        };
        let (q, dq, tau) = (
            [0.3, -1.2, 0.5, 2.0, -0.7, 1.1],
            [0.8, -0.4, 0.2, 1.0, -1.5, 0.3],
            [2.0, 1.5, -1.0, 0.5, 3.0, -2.0],
        );
        for effects in [None, Some(smooth), Some(with_armature)] {
            let plant = Plant::new(model, theta.clone(), effects);
            let mut w = Work::new(6);
            let mut acc = [0.0; 6];
            assert!(plant.accel(&q, &dq, &tau, &mut acc, &mut w));
            let (mut jq, mut jv) = ([0.0; 36], [0.0; 36]);
            assert!(plant.accel_jacobian(&q, &dq, &tau, &acc, &mut jq, &mut jv, &mut w));
            for (block, analytic) in [(0, &jq), (1, &jv)] {
                let scale = analytic.iter().fold(1.0_f64, |s, x| s.max(x.abs()));
                for j in 0..6 {
                    let mut diff = |h: f64| {
                        let mut ends = [[0.0; 6]; 2];
                        for (sign, end) in [(1.0, 0), (-1.0, 1)] {
                            let (mut qs, mut dqs) = (q, dq);
                            [&mut qs, &mut dqs][block][j] += sign * h;
                            assert!(plant.accel(&qs, &dqs, &tau, &mut ends[end], &mut w));
                        }
                        std::array::from_fn::<f64, 6, _>(|i| (ends[0][i] - ends[1][i]) / (2.0 * h))
                    };
                    let (coarse, fine) = (diff(1e-3), diff(5e-4));
                    for i in 0..6 {
                        let numeric = (4.0 * fine[i] - coarse[i]) / 3.0;
                        let err = (analytic[i * 6 + j] - numeric).abs();
                        assert!(err < 1e-7 * scale, "block {block} [{i}][{j}]: {err:.3e}");
                    }
                }
            }
        }
    }
}
