//! Excitation design for any arm under its own limits: a trajectory family
//! ([`FourierQuintic`] or [`LogisticN`]), the observation matrix identification uses
//! ([`Observation`]), the limits in continuous time, and CMA-ES ([`super::cmaes`]).
//!
//! **Limits by construction.** Both families move each joint about `q0` linearly in their
//! amplitude coefficients, so every candidate is scaled joint by joint to the largest multiple
//! (≤ 1) that keeps `q`, `q̇`, `q̈` inside the limits less a relative margin: on the search grid the
//! peaks are raised by the most a signal can grow between samples (`sup|x''|·h²/8`, with
//! `sup|x''|` bounded by the coefficients, [`FourierQuintic::sup`]); the Logistic peaks are
//! analytic. The search therefore never leaves the position, velocity and acceleration limits;
//! torques (through the arm's inverse dynamics with the given parameters) and the tool height
//! (`keep_above`) are penalised instead, and the result is re-checked on a 1 kHz grid with the
//! same between-sample bound ([`Problem::check`]).
//!
//! **Cost.** `log cond` (or `−log det / columns`) of the observation matrix sampled at
//! `search_rate` (the objective is smooth in time, so a coarser grid ranks designs as the full
//! rate does; the reported numbers are at the output rate), plus a large constant and the relative
//! violation for an infeasible candidate.

use std::time::{Duration, Instant};

use nalgebra::{Matrix4, Vector4};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::Serialize;

use super::cmaes::{self, CmaesConfig};
use super::limits::Limits;
use super::objective::{conditioning, Conditioning, Grid, ObjectiveKind, Observation};
use crate::arms::ArmSource;
use crate::dh::{DhTable, JointKind};
use crate::effects::Effect;
use crate::params::InertialParams;
use crate::progress::Progress;
use crate::reference::RefModel;
use crate::trajectory::fourier_quintic::FourierQuintic;
use crate::trajectory::logistic_n::{min_steepness, LnJoint, LogisticN};
use crate::trajectory::Motion;

/// Trajectory family.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Family {
    /// Fourier series plus a quintic boundary term.
    Fourier,
    /// The paper's Logistic family, all joints at once.
    Logistic,
}

/// A designed trajectory.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(tag = "family", rename_all = "lowercase")]
pub enum Excitation {
    Fourier(FourierQuintic),
    Logistic(LogisticN),
}

impl Excitation {
    /// As a trajectory file entry (`dynid simulate --trajectory` reads it).
    pub fn spec(&self) -> crate::trajectory::TrajectorySpec {
        use crate::trajectory::TrajectorySpec;
        match self {
            Excitation::Fourier(f) => TrajectorySpec::FourierQuintic(f.clone()),
            Excitation::Logistic(l) => TrajectorySpec::LogisticN(l.clone()),
        }
    }

    pub fn as_motion(&self) -> &dyn Motion {
        match self {
            Excitation::Fourier(f) => f,
            Excitation::Logistic(l) => l,
        }
    }

    /// Bound on `|d^m q_j/dt^m|` over the period, for the between-sample guard.
    fn sup(&self, j: usize, m: u32) -> f64 {
        match self {
            Excitation::Fourier(f) => f.sup(j, m),
            // |s^(m)| ≤ 1/4 for m = 1..4 (the logistic's derivatives are polynomials in s(1−s))
            Excitation::Logistic(l) => 0.25 * l.joints[j].a.abs() * l.joints[j].w.powi(m as i32),
        }
    }
}

/// Settings of a design.
#[derive(Debug, Clone, PartialEq)]
pub struct DesignConfig {
    pub family: Family,
    pub period: f64,
    pub harmonics: usize,
    /// Rate of the output trajectory and of the reported condition number, Hz.
    pub rate: f64,
    /// Rate the search evaluates candidates at, Hz (capped by `rate`).
    pub search_rate: f64,
    pub objective: ObjectiveKind,
    pub effects: Vec<Effect>,
    pub seed: u64,
    pub generations: usize,
    /// Wall-clock budget of the search.
    pub budget: Duration,
    /// Relative margin kept from every limit during the search (e.g. 0.005 = 0.5 %).
    pub margin: f64,
    /// Lowest allowed height of the tool point (last frame origin) in the base frame, m.
    pub keep_above: Option<f64>,
    pub population: Option<usize>,
}

impl Default for DesignConfig {
    fn default() -> Self {
        DesignConfig {
            family: Family::Fourier,
            period: 10.0,
            harmonics: 5,
            rate: 500.0,
            search_rate: 25.0,
            objective: ObjectiveKind::Cond,
            effects: vec![
                Effect::Viscous,
                Effect::Coulomb,
                Effect::Offset,
                Effect::Armature,
            ],
            seed: 2022,
            generations: 300,
            budget: Duration::from_secs(60),
            margin: 0.005,
            keep_above: None,
            population: None,
        }
    }
}

/// Per-joint peak use of each limit (1 = at the limit), on the check grid.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct JointUse {
    pub name: String,
    pub q_min_reached: f64,
    pub q_max_reached: f64,
    /// `(q0 − min q)/(q0 − q_min)`.
    pub q_low: f64,
    /// `(max q − q0)/(q_max − q0)`.
    pub q_high: f64,
    pub dq: f64,
    pub ddq: f64,
    /// Peak torque over `tau_max` (when parameters and a torque limit are given).
    pub tau: Option<f64>,
    /// Peak torque, N·m (when parameters are given).
    pub tau_peak: Option<f64>,
}

/// One violated limit of a checked design.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Violation {
    pub joint: Option<usize>,
    pub limit: String,
    /// Peak (with the between-sample bound where there is one) and the limit.
    pub peak: f64,
    pub allowed: f64,
}

/// The check of a design on a dense grid.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Check {
    pub grid_hz: f64,
    pub joints: Vec<JointUse>,
    /// Lowest tool height, m (when `keep_above` is set).
    pub tool_z_min: Option<f64>,
    pub violations: Vec<Violation>,
}

/// A finished design.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Design {
    pub excitation: Excitation,
    pub columns: Vec<String>,
    /// Effect terms left out (structurally merged), with the base parameters they merge into.
    pub dropped: Vec<(String, Vec<String>)>,
    /// At the output rate.
    pub conditioning: Conditioning,
    pub check: Check,
    pub generations: usize,
    pub evaluations: usize,
    pub stopped_by: String,
    pub seconds: f64,
}

/// Why no design was produced.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum DesignError {
    #[error("invalid settings: {0}")]
    Settings(String),
    #[error("no feasible design found: {}", describe(.0))]
    Infeasible(Vec<Violation>),
    #[error("the best design leaves the observation matrix singular ({0} columns): some columns are not excited by any motion within these limits — widen the limits, lengthen --period, or drop effects with --effects")]
    Singular(usize),
}

fn describe(v: &[Violation]) -> String {
    v.iter()
        .map(|v| {
            let hint = match v.limit.as_str() {
                "tau_max" => "raise --tau-max, lower --dq-max/--ddq-max, or lengthen --period",
                "keep_above" => "lower --keep-above or narrow --q-min/--q-max",
                _ => "relax this limit or lengthen --period",
            };
            match v.joint {
                Some(j) => format!(
                    "joint {}: {} peaks at {:.4} > {:.4} — {hint}",
                    j + 1,
                    v.limit,
                    v.peak,
                    v.allowed
                ),
                None => format!("{} {:.4} vs {:.4} — {hint}", v.limit, v.peak, v.allowed),
            }
        })
        .collect::<Vec<_>>()
        .join("; ")
}

/// Torques through the arm's dynamics: the generated kernels when the arm has them, else the
/// reference Newton–Euler on its table; plus the parameter file's effects.
struct Torque {
    generated: Option<(&'static dyn crate::model::Model, Vec<f64>)>,
    reference: RefModel,
    p: Vec<f64>,
    params: InertialParams,
}

impl Torque {
    fn new(arm: &ArmSource, table: &DhTable, params: &InertialParams) -> Self {
        let p = params.full_vector();
        let generated = match arm {
            ArmSource::Generated(m) => {
                let mut theta = vec![0.0; m.nb()];
                m.base_params(&p, &mut theta);
                Some((*m, theta))
            }
            ArmSource::Table(_) => None,
        };
        Torque {
            generated,
            reference: RefModel::new(table),
            p,
            params: params.clone(),
        }
    }

    /// Peak `|τ_j|` over samples.
    fn peaks(&self, q: &[f64], dq: &[f64], ddq: &[f64], dof: usize) -> Vec<f64> {
        let mut ws = self.reference.workspace();
        let mut tau = vec![0.0; dof];
        let mut peak = vec![0.0_f64; dof];
        for k in 0..q.len() / dof {
            let r = k * dof..(k + 1) * dof;
            let (qk, dqk, ddqk) = (&q[r.clone()], &dq[r.clone()], &ddq[r]);
            match &self.generated {
                Some((m, theta)) => m.inverse_dynamics(qk, dqk, ddqk, theta, &mut tau),
                None => self
                    .reference
                    .inverse_dynamics(&mut ws, qk, dqk, ddqk, &self.p, &mut tau),
            }
            for j in 0..dof {
                let t = tau[j] + self.params.effects.torque(j, qk[j], dqk[j], ddqk[j]);
                peak[j] = peak[j].max(t.abs());
            }
        }
        peak
    }
}

/// Height (z in the base frame) of the last frame's origin (modified D-H).
pub fn tool_z(table: &DhTable, q: &[f64]) -> f64 {
    let mut t = Matrix4::<f64>::identity();
    for (j, jt) in table.joints.iter().enumerate() {
        let (theta, d) = match jt.kind {
            JointKind::Revolute => (jt.theta + q[j], jt.d),
            _ => (jt.theta, jt.d + q[j]),
        };
        let (sa, ca) = jt.alpha.sin_cos();
        let (st, ct) = theta.sin_cos();
        // Rx(α)·Tx(a)·Rz(θ)·Tz(d)
        let m = Matrix4::new(
            ct,
            -st,
            0.0,
            jt.a,
            ca * st,
            ca * ct,
            -sa,
            -sa * d,
            sa * st,
            sa * ct,
            ca,
            ca * d,
            0.0,
            0.0,
            0.0,
            1.0,
        );
        t *= m;
    }
    (t * Vector4::new(0.0, 0.0, 0.0, 1.0))[2]
}

/// Everything a candidate is evaluated with.
pub struct Problem<'a> {
    pub limits: &'a Limits,
    pub cfg: &'a DesignConfig,
    obs: Observation,
    table: DhTable,
    torque: Option<Torque>,
    /// Logistic: smallest steepness per joint.
    w_min: Vec<f64>,
}

/// Peaks of `q − q0` (max, min), `|q̇|`, `|q̈|` per joint on a grid.
fn grid_peaks(g: &Grid, q0: &[f64]) -> Vec<[f64; 4]> {
    let dof = q0.len();
    let mut p = vec![[f64::MIN, f64::MAX, 0.0, 0.0]; dof];
    for k in 0..g.t.len() {
        for j in 0..dof {
            let i = k * dof + j;
            let d = g.q[i] - q0[j];
            p[j][0] = p[j][0].max(d);
            p[j][1] = p[j][1].min(d);
            p[j][2] = p[j][2].max(g.dq[i].abs());
            p[j][3] = p[j][3].max(g.ddq[i].abs());
        }
    }
    p
}

impl<'a> Problem<'a> {
    /// Validates the settings and builds the observation model.
    pub fn new(
        arm: &ArmSource,
        limits: &'a Limits,
        params: Option<&InertialParams>,
        cfg: &'a DesignConfig,
    ) -> Result<Self, DesignError> {
        let bad = |s: String| Err(DesignError::Settings(s));
        if !(cfg.period.is_finite() && cfg.period > 0.0) {
            return bad(format!("--period must be > 0 (got {})", cfg.period));
        }
        if cfg.family == Family::Fourier && cfg.harmonics == 0 {
            return bad("--harmonics must be ≥ 1".into());
        }
        if !(cfg.rate.is_finite() && cfg.rate > 0.0) || cfg.rate * cfg.period < 2.0 {
            return bad(format!(
                "--rate {} Hz gives fewer than 2 samples over the period",
                cfg.rate
            ));
        }
        if cfg.generations == 0 {
            return bad("--generations must be ≥ 1".into());
        }
        if limits.dof() != arm.dof() {
            return bad(format!(
                "{} joint limits for an arm of {} joints",
                limits.dof(),
                arm.dof()
            ));
        }
        limits
            .check_period(cfg.period)
            .map_err(|e| DesignError::Settings(e.to_string()))?;
        let table = arm
            .dh_table()
            .map_err(|e| DesignError::Settings(e.to_string()))?;
        let obs = Observation::new(arm, &cfg.effects)
            .map_err(|e| DesignError::Settings(e.to_string()))?;
        let torque = params.map(|p| Torque::new(arm, &table, p));
        let w_min = limits
            .joints
            .iter()
            .map(|l| min_steepness(l.q_max - l.q_min, cfg.period))
            .collect();
        Ok(Problem {
            limits,
            cfg,
            obs,
            table,
            torque,
            w_min,
        })
    }

    /// Number of design variables.
    pub fn dim(&self) -> usize {
        match self.cfg.family {
            Family::Fourier => self.limits.dof() * 2 * self.cfg.harmonics,
            Family::Logistic => self.limits.dof() * 2,
        }
    }

    /// The trajectory of a design vector, before scaling into the limits.
    fn raw(&self, x: &[f64]) -> Excitation {
        let l = self.limits;
        match self.cfg.family {
            Family::Fourier => {
                let nh = self.cfg.harmonics;
                // x = 1 puts one harmonic's velocity amplitude at dq_max/√N
                let (mut a, mut b) = (Vec::new(), Vec::new());
                for (j, jl) in l.joints.iter().enumerate() {
                    let s = jl.dq_max / (nh as f64).sqrt();
                    let v = &x[j * 2 * nh..(j + 1) * 2 * nh];
                    a.push(v[..nh].iter().map(|c| c * s).collect());
                    b.push(v[nh..].iter().map(|c| c * s).collect());
                }
                Excitation::Fourier(FourierQuintic::new(self.cfg.period, &l.q0, &a, &b))
            }
            Family::Logistic => {
                let joints = l
                    .joints
                    .iter()
                    .enumerate()
                    .map(|(j, jl)| LnJoint {
                        q0: l.q0[j],
                        a: x[2 * j] * 0.5 * (jl.q_max - jl.q_min),
                        w: self.w_min[j] * x[2 * j + 1].abs().min(30.0).exp(),
                    })
                    .collect();
                Excitation::Logistic(LogisticN {
                    period: self.cfg.period,
                    joints,
                })
            }
        }
    }

    /// Scales each joint of `e` into the limits less the margin (see the module docs), given its
    /// peaks on a grid of spacing `h`; returns the scale factors.
    fn fit_into_limits(&self, e: &mut Excitation, peaks: &[[f64; 4]], h: f64) -> Vec<f64> {
        let keep = 1.0 - self.cfg.margin;
        let guard = |e: &Excitation, j: usize, m: u32| e.sup(j, m + 2) * h * h / 8.0;
        let mut scales = Vec::with_capacity(self.limits.dof());
        for (j, jl) in self.limits.joints.iter().enumerate() {
            let q0 = self.limits.q0[j];
            let p = match e {
                Excitation::Logistic(lg) => {
                    let [a, v, acc] = lg.joints[j].peaks();
                    let up = if lg.joints[j].a > 0.0 { a } else { 0.0 };
                    [up, a - up, v, acc]
                }
                Excitation::Fourier(_) => {
                    let g0 = guard(e, j, 0);
                    [
                        peaks[j][0].max(0.0) + g0,
                        (-peaks[j][1]).max(0.0) + g0,
                        peaks[j][2] + guard(e, j, 1),
                        peaks[j][3] + guard(e, j, 2),
                    ]
                }
            };
            let ratio = |room: f64, used: f64| {
                if used > 0.0 {
                    room * keep / used
                } else {
                    f64::INFINITY
                }
            };
            let s = ratio(jl.q_max - q0, p[0])
                .min(ratio(q0 - jl.q_min, p[1]))
                .min(ratio(jl.dq_max, p[2]))
                .min(ratio(jl.ddq_max, p[3]))
                .min(1.0);
            match e {
                Excitation::Fourier(f) => f.scale_joint(j, s),
                Excitation::Logistic(lg) => lg.joints[j].a *= s,
            }
            scales.push(s);
        }
        scales
    }

    /// The design of a vector: built, then scaled into the limits on the search grid.
    pub fn excitation(&self, x: &[f64]) -> (Excitation, Vec<f64>) {
        let rate = self.cfg.search_rate.min(self.cfg.rate);
        let mut e = self.raw(x);
        let g = Grid::new(e.as_motion(), rate);
        let peaks = grid_peaks(&g, &self.limits.q0);
        let s = self.fit_into_limits(&mut e, &peaks, 1.0 / rate);
        (e, s)
    }

    /// The search's cost of a vector (see the module docs).
    pub fn cost(&self, x: &[f64]) -> f64 {
        let rate = self.cfg.search_rate.min(self.cfg.rate);
        let (e, scales) = self.excitation(x);
        let g = Grid::new(e.as_motion(), rate);
        let mut violation = 0.0;
        if let Some(t) = &self.torque {
            let peaks = t.peaks(&g.q, &g.dq, &g.ddq, self.limits.dof());
            for (j, jl) in self.limits.joints.iter().enumerate() {
                if let Some(tm) = jl.tau_max {
                    // torque between samples is not bounded analytically: keep 2 % more room
                    violation += (peaks[j] / (tm * (1.0 - self.cfg.margin - 0.02)) - 1.0).max(0.0);
                }
            }
        }
        if let Some(z) = self.cfg.keep_above {
            let dof = self.limits.dof();
            let zmin = (0..g.t.len())
                .map(|k| tool_z(&self.table, &g.q[k * dof..(k + 1) * dof]))
                .fold(f64::INFINITY, f64::min);
            violation += (z + 0.01 - zmin).max(0.0);
        }
        if violation > 0.0 {
            return 1e3 + violation;
        }
        let mut s = self.obs.scratch();
        let w = self.obs.matrix(&mut s, &g.q, &g.dq, &g.ddq);
        let c = conditioning(&w);
        let obj = match self.cfg.objective {
            ObjectiveKind::Cond => c.cond.ln(),
            ObjectiveKind::LogDet => -c.logdet / w.ncols() as f64,
        };
        // a small pull back from vectors far outside the limits (the scaling hides their size)
        let shrink: f64 = scales.iter().map(|s| -s.ln()).sum::<f64>();
        if obj.is_finite() {
            obj + 1e-3 * shrink
        } else {
            1e2
        }
    }

    /// Checks `e` on a `grid_hz` grid, raising every sampled peak by the between-sample bound.
    pub fn check(&self, e: &Excitation, grid_hz: f64) -> Check {
        let g = Grid::new(e.as_motion(), grid_hz);
        let h = 1.0 / grid_hz;
        let dof = self.limits.dof();
        let peaks = grid_peaks(&g, &self.limits.q0);
        let tau = self
            .torque
            .as_ref()
            .map(|t| t.peaks(&g.q, &g.dq, &g.ddq, dof));
        let mut violations = Vec::new();
        let mut joints = Vec::new();
        for (j, jl) in self.limits.joints.iter().enumerate() {
            let q0 = self.limits.q0[j];
            let guard = |m: u32| match e {
                Excitation::Fourier(_) => e.sup(j, m + 2) * h * h / 8.0,
                Excitation::Logistic(_) => 0.0,
            };
            let (qmax, qmin) = (q0 + peaks[j][0], q0 + peaks[j][1]);
            let (vmax, amax) = match e {
                Excitation::Logistic(l) => {
                    let p = l.joints[j].peaks();
                    (p[1], p[2])
                }
                Excitation::Fourier(_) => (peaks[j][2], peaks[j][3]),
            };
            let mut push = |limit: &str, peak: f64, allowed: f64| {
                if peak > allowed {
                    violations.push(Violation {
                        joint: Some(j),
                        limit: limit.into(),
                        peak,
                        allowed,
                    });
                }
            };
            push("q_max", qmax + guard(0), jl.q_max);
            push("q_min", -(qmin - guard(0)), -jl.q_min);
            push("dq_max", vmax + guard(1), jl.dq_max);
            push("ddq_max", amax + guard(2), jl.ddq_max);
            let tau_use = match (&tau, jl.tau_max) {
                (Some(t), Some(tm)) => {
                    push("tau_max", t[j], tm);
                    Some(t[j] / tm)
                }
                _ => None,
            };
            joints.push(JointUse {
                name: jl.name.clone(),
                q_min_reached: qmin,
                q_max_reached: qmax,
                q_low: (q0 - qmin) / (q0 - jl.q_min),
                q_high: (qmax - q0) / (jl.q_max - q0),
                dq: vmax / jl.dq_max,
                ddq: amax / jl.ddq_max,
                tau: tau_use,
                tau_peak: tau.as_ref().map(|t| t[j]),
            });
        }
        let tool_z_min = self.cfg.keep_above.map(|z| {
            let zmin = (0..g.t.len())
                .map(|k| tool_z(&self.table, &g.q[k * dof..(k + 1) * dof]))
                .fold(f64::INFINITY, f64::min);
            if zmin < z {
                violations.push(Violation {
                    joint: None,
                    limit: "keep_above".into(),
                    peak: zmin,
                    allowed: z,
                });
            }
            zmin
        });
        Check {
            grid_hz,
            joints,
            tool_z_min,
            violations,
        }
    }

    /// Initial vector: small seeded random coefficients (Fourier) or half amplitudes (Logistic).
    fn start(&self) -> Vec<f64> {
        let mut rng = ChaCha8Rng::seed_from_u64(self.cfg.seed ^ 0x5eed);
        match self.cfg.family {
            Family::Fourier => (0..self.dim()).map(|_| rng.gen_range(-0.5..0.5)).collect(),
            Family::Logistic => (0..self.dim())
                .map(|i| {
                    if i % 2 == 0 {
                        rng.gen_range(-0.8..0.8)
                    } else {
                        rng.gen_range(0.0..1.0)
                    }
                })
                .collect(),
        }
    }
}

/// Designs an excitation for `arm` under `limits` (torques checked when `params` is given).
/// Returns [`DesignError::Infeasible`] rather than a design that violates a limit.
pub fn design(
    arm: &ArmSource,
    limits: &Limits,
    params: Option<&InertialParams>,
    cfg: &DesignConfig,
    progress: Option<&Progress>,
) -> Result<Design, DesignError> {
    let start = Instant::now();
    let problem = Problem::new(arm, limits, params, cfg)?;
    let x0 = problem.start();
    let cc = CmaesConfig {
        population: cfg.population,
        sigma0: 0.3,
        generations: cfg.generations,
        budget: Some(cfg.budget),
        seed: cfg.seed,
        sigma_tol: 1e-8,
    };
    if let Some(p) = progress {
        p.stage("generations", cfg.generations as u64);
    }
    let r = cmaes::minimize(&x0, &cc, |x| problem.cost(x), progress);
    let (excitation, _) = problem.excitation(&r.best);
    let check = problem.check(&excitation, cfg.rate.max(1000.0));
    if !check.violations.is_empty() {
        return Err(DesignError::Infeasible(check.violations));
    }
    let mut s = problem.obs.scratch();
    let w = problem
        .obs
        .of_motion(&mut s, excitation.as_motion(), cfg.rate);
    let conditioning = conditioning(&w);
    if !conditioning.cond.is_finite() {
        return Err(DesignError::Singular(w.ncols()));
    }
    Ok(Design {
        excitation,
        columns: problem.obs.columns().to_vec(),
        dropped: problem
            .obs
            .dropped()
            .iter()
            .map(|(t, with)| (t.label(), with.clone()))
            .collect(),
        conditioning,
        check,
        generations: r.generations,
        evaluations: r.evaluations,
        stopped_by: r.stopped_by.into(),
        seconds: start.elapsed().as_secs_f64(),
    })
}
