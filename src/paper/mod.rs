//! The seed paper end to end (Qian et al., "Iterative Identification of Robot Dynamic Parameters
//! Based on Logistic Function", Trans. NUAA 39(6), 2022) on the generated `planar2` kernels:
//! GA → Logistic excitation → closed-loop tracking (RHFTC, eq. 23) → step-by-step iterative
//! identification → Fourier comparison → validation → noise study.
//!
//! [`run`] computes everything into [`PaperResults`] (serialised as `results.json`) plus the
//! series behind the figures; [`write_outputs`] writes `report.md`, `results.json` and the SVG
//! figures atomically. `dynid paper --out DIR` does both.
//!
//! ```no_run
//! let cfg = dynid::paper::PaperConfig::default();
//! let model = dynid::arms::find("planar2").unwrap();
//! let (results, traces) = dynid::paper::run(model, &cfg).unwrap();
//! dynid::paper::write_outputs(std::path::Path::new("out/paper"), &results, &traces).unwrap();
//! ```

pub mod figures;
pub mod ident;
pub mod noise;
pub mod report;
mod results;

pub use results::*;

use std::f64::consts::PI;
use std::path::Path;
use std::time::Instant;

use crate::progress::Progress;
use serde::Serialize;

use crate::control::{Ctc, ModelBased, Pd, Rhftc, RhftcGains, Usage};
use crate::excitation::{
    link1_length, minimize, planar_height, FourierProblem, GaConfig, Limits, LogisticDesign,
    LogisticProblem, LogisticSettings, Margins,
};
use crate::model::Model;
use crate::signal::{central_uniform, Butterworth};
use crate::sim::{simulate, Plant, SimConfig, SimError, SimLog};
use crate::trajectory::fourier::Fourier;
use crate::trajectory::logistic::Logistic;
use crate::trajectory::{sample, Sine};
use ident::{full_ls, max_abs_diff, step_ls, IdentError, Signals};

/// Everything that can stop the reproduction.
#[derive(Debug, thiserror::Error)]
pub enum PaperError {
    #[error("the paper needs a 2-DOF arm with 6 base parameters (planar2); `{name}` has {dof} joints and {nb} base parameters")]
    WrongArm { name: String, dof: usize, nb: usize },
    #[error("{what}: {source}")]
    Sim { what: String, source: SimError },
    #[error("{what}: {source}")]
    Ident { what: String, source: IdentError },
    #[error("invalid design: {0}")]
    Design(String),
    #[error(transparent)]
    Write(#[from] crate::io::WriteError),
    #[error("figure {name}: {msg}")]
    Figure { name: String, msg: String },
}

/// Settings of the reproduction (defaults = the paper's where it gives them).
#[derive(Debug, Clone, Serialize)]
pub struct PaperConfig {
    /// True base parameters θ (Table 2 order).
    pub theta_true: Vec<f64>,
    /// Start of the iteration.
    pub theta0: Vec<f64>,
    pub ga: GaConfig,
    pub limits: Limits,
    /// Sample time of the identification log (δ counts samples of it), s.
    pub ts: f64,
    /// Integration and control step, s.
    pub dt: f64,
    /// Grid the Logistic periods are rounded up to, s.
    pub period_grid: f64,
    /// Eq. 11 tolerance on `|q̇|`, `|q̈|` at start, end and splice points.
    pub rest_tol: f64,
    pub a_range: (f64, f64),
    pub w_range: (f64, f64),
    pub delta_range: (f64, f64),
    /// Identification iterations.
    pub iterations: usize,
    pub rhftc: RhftcGains,
    /// Decentralised PD used where `M̂(q)` is not positive definite (e.g. `θ̂ = 0`), N·m/rad.
    pub fallback_kp: Vec<f64>,
    pub fallback_kd: Vec<f64>,
    /// Length of link 2 for the "above the ground" constraint (the D-H table has no tool frame), m.
    pub link2_length: f64,
    pub fourier_harmonics: usize,
    pub fourier_wf: f64,
    pub fourier_periods: usize,
    pub fourier_coef_bound: f64,
    /// Cut-off of the low-pass filter of the Fourier pipeline and of estimators (c), (d), Hz.
    pub lowpass_hz: f64,
    pub validation_duration: f64,
    pub noise_runs: usize,
    pub noise_quant_bits: Vec<Option<u32>>,
    pub noise_torque_pct: Vec<f64>,
    /// Where to report progress (each stage: the GAs, the iterations, the noise study).
    #[serde(skip)]
    pub progress: Progress,
}

impl Default for PaperConfig {
    fn default() -> Self {
        let logistic = LogisticSettings::paper();
        Self {
            theta_true: vec![2.0, 2.0, 0.0, 1.0, 1.0, 0.0],
            theta0: vec![0.0; 6],
            ga: GaConfig::default(),
            limits: logistic.limits,
            ts: 0.01,
            dt: 1e-3,
            period_grid: logistic.period_grid,
            rest_tol: logistic.rest_tol,
            a_range: logistic.a_range,
            w_range: logistic.w_range,
            delta_range: logistic.delta_range,
            iterations: 6,
            rhftc: RhftcGains::paper(),
            fallback_kp: vec![2000.0, 1000.0],
            fallback_kd: vec![200.0, 60.0],
            link2_length: logistic.link2_length,
            fourier_harmonics: 5,
            fourier_wf: 2.0 * PI / 10.0,
            fourier_periods: 2,
            fourier_coef_bound: 0.1,
            lowpass_hz: 2.0,
            validation_duration: 10.0,
            noise_runs: 50,
            noise_quant_bits: vec![None, Some(12), Some(14), Some(16), Some(18), Some(20)],
            noise_torque_pct: vec![0.0, 0.1, 0.5, 1.0, 2.0, 5.0],
            progress: Progress::silent(),
        }
    }
}

/// The paper's Table 3.
pub const PAPER_TABLE3: [f64; 6] = [2.313, 2.094, 1.523, 0.996, 367.0, 246.0];
/// The paper's Table 6 (Fourier θ̂).
pub const PAPER_TABLE6: [f64; 6] = [1.98, 2.0, 0.0, 1.007, 1.00, 0.009];
/// The paper's θ̂ after three iterations (θ1..3 from step 2, θ4..6 from step 1).
pub const PAPER_ITER3: [f64; 6] = [1.991, 2.000, 0.002, 0.993, 1.000, 0.000];
/// The paper's maximum tracking error per iteration, rad.
pub const PAPER_TRACKING: [f64; 3] = [0.6, 0.15, 0.0];

/// A new stage of the run on `progress`, returned for its steps.
fn bar(len: u64, prefix: &str, progress: &Progress) -> Progress {
    progress.stage(prefix, len);
    progress.clone()
}

impl PaperConfig {
    /// The Logistic design settings of this configuration.
    pub fn logistic(&self) -> LogisticSettings {
        LogisticSettings {
            limits: self.limits,
            period_grid: self.period_grid,
            rest_tol: self.rest_tol,
            a_range: self.a_range,
            w_range: self.w_range,
            delta_range: self.delta_range,
            link2_length: self.link2_length,
        }
    }
}

/// The paper's excitation problem on `model` with sample time `ts`
/// ([`LogisticProblem::planar`] with the settings of `cfg`).
pub fn logistic_problem<'a>(
    model: &'a dyn Model,
    cfg: &PaperConfig,
    ts: f64,
) -> LogisticProblem<'a> {
    LogisticProblem::planar(model, &cfg.logistic(), ts)
}

fn check(problem: &LogisticProblem, x: &[f64]) -> Result<DesignCheck, PaperError> {
    let d = problem
        .design(x)
        .map_err(|e| PaperError::Design(e.to_string()))?;
    let ev = problem.evaluate(&d);
    Ok(DesignCheck {
        cond_q: ev.cond[0],
        cond_m: ev.cond[1],
        feasible: ev.margins.feasible(),
        margins: ev.margins,
        design: d,
    })
}

/// How the iteration gets `q̇`, `q̈` from the measured positions.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum IterEstimator {
    /// The paper: eq. 15 on the measured `q` (held joints: zero).
    Map,
    /// Ours: the analytic reference minus the low-pass-differentiated tracking error,
    /// `q̈ = q̈d − ë`, `q̇ = q̇d − ė` (held joints included). Exact when tracking is perfect, like
    /// eq. 15, but without eq. 15's bias when it is not.
    Corrected,
}

/// Which controller the iteration uses.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Law {
    Rhftc,
    Ctc,
}

impl Law {
    /// The controller as it ran during one experiment, e.g. `RHFTC + PD 12 %`.
    fn label(self, usage: &Usage) -> String {
        let name = match self {
            Law::Rhftc => "RHFTC",
            Law::Ctc => "CTC",
        };
        if usage.fallback >= 0.999 {
            "PD (θ̂ has no inertia)".into()
        } else if usage.fallback > 0.0 {
            format!("{name} + PD {:.0} %", 100.0 * usage.fallback)
        } else if usage.loaded > 0.0 {
            format!("{name}, M̂ loaded {:.0} %", 100.0 * usage.loaded)
        } else {
            name.into()
        }
    }
}

/// Runs the experiment of one step with the estimate `theta_hat`.
fn run_step(
    model: &dyn Model,
    plant: &Plant,
    cfg: &PaperConfig,
    law: Law,
    theta_hat: &[f64],
    traj: &Logistic,
) -> Result<(SimLog, Usage), SimError> {
    let fallback = Pd {
        kp: cfg.fallback_kp.clone(),
        kd: cfg.fallback_kd.clone(),
    };
    let sim = SimConfig {
        dt: cfg.dt,
        log_every: (cfg.ts / cfg.dt).round().max(1.0) as usize,
        divergence_limit: 100.0,
        ..SimConfig::default()
    };
    fn run<C: ModelBased>(
        plant: &Plant,
        mut c: C,
        traj: &Logistic,
        sim: &SimConfig,
    ) -> Result<(SimLog, Usage), SimError> {
        let log = simulate(plant, &mut c, traj, sim)?;
        Ok((log, c.usage()))
    }
    match law {
        Law::Rhftc => run(
            plant,
            Rhftc::new(model, theta_hat.to_vec(), cfg.rhftc.clone(), fallback),
            traj,
            &sim,
        ),
        Law::Ctc => {
            let g = &cfg.rhftc;
            let c = Ctc::new(
                model,
                theta_hat.to_vec(),
                g.kp.clone(),
                g.kd.clone(),
                fallback,
            );
            run(plant, c, traj, &sim)
        }
    }
}

/// Step-by-step iterative identification; returns the records and the logs of every iteration.
pub fn iterate(
    model: &dyn Model,
    cfg: &PaperConfig,
    problem: &LogisticProblem,
    design: &LogisticDesign,
    law: Law,
    estimator: IterEstimator,
    pb: &Progress,
) -> Result<(Vec<IterRecord>, Vec<[SimLog; 2]>), PaperError> {
    let plant = Plant::new(model, cfg.theta_true.clone(), None);
    let mut theta = cfg.theta0.clone();
    let mut records = Vec::new();
    let mut logs = Vec::new();
    let moving = problem.moving();
    for it in 1..=cfg.iterations {
        let mut pair: Vec<SimLog> = Vec::with_capacity(2);
        // the controller of a whole iteration uses the previous iteration's estimate (a half-updated
        // θ̂ — new θ4..6 with θ1..3 still 0 in iteration 1 — is not a model of the arm)
        let theta_ctrl = theta.clone();
        for (s, plan) in problem.steps.iter().enumerate() {
            let traj = problem.step_trajectory(design, s);
            let what = format!("iteration {it}, step {}", s + 1);
            let (log, usage) =
                run_step(model, &plant, cfg, law, &theta_ctrl, &traj).map_err(|source| {
                    PaperError::Sim {
                        what: what.clone(),
                        source,
                    }
                })?;
            let (dq, ddq) = match estimator {
                IterEstimator::Map => {
                    let (mut dq, mut ddq) = (vec![0.0; log.q.len()], vec![0.0; log.q.len()]);
                    traj.estimator().estimate(&log.t, &log.q, &mut dq, &mut ddq);
                    (dq, ddq)
                }
                IterEstimator::Corrected => corrected_derivatives(&log, cfg.lowpass_hz, cfg.ts),
            };
            let i = moving.iter().position(|&j| j == plan.joint).unwrap_or(0);
            let joint = traj
                .moving(plan.joint)
                .copied()
                .ok_or_else(|| PaperError::Design(what.clone()))?;
            let idx = problem.window(&joint, design.delta[i]);
            let sig = Signals {
                dof: log.dof,
                q: &log.q,
                dq: &dq,
                ddq: &ddq,
                tau: &log.tau,
            };
            let x = step_ls(model, &sig, &idx, plan.row, &plan.cols, &theta).map_err(|source| {
                PaperError::Ident {
                    what: what.clone(),
                    source,
                }
            })?;
            for (k, &c) in plan.cols.iter().enumerate() {
                theta[c] = x[k];
            }
            let sub: Vec<f64> = plan
                .cols
                .iter()
                .map(|&c| theta[c] - cfg.theta_true[c])
                .collect();
            records.push(IterRecord {
                iteration: it,
                step: s + 1,
                controller: law.label(&usage),
                fallback_fraction: usage.fallback,
                loaded_fraction: usage.loaded,
                theta_hat: theta.clone(),
                max_abs_error: sub.iter().map(|v| v.abs()).fold(0.0, f64::max),
                max_abs_error_all: max_abs_diff(&theta, &cfg.theta_true),
                max_tracking_error: log.max_tracking_error(),
            });
            pair.push(log);
            pb.step();
        }
        let (b, a) = (
            pair.pop().unwrap_or_default(),
            pair.pop().unwrap_or_default(),
        );
        logs.push([a, b]);
    }
    Ok((records, logs))
}

/// The Fourier comparison: GA design, closed-loop experiment under PD (the conventional method needs
/// no model), low-pass + central differences, ordinary least squares on both equations.
fn fourier_comparison(
    model: &dyn Model,
    cfg: &PaperConfig,
    show: &Progress,
) -> Result<(FourierOut, SimLog), PaperError> {
    let geometry = vec![link1_length(model), cfg.link2_length];
    let mut problem = FourierProblem {
        model,
        limits: cfg.limits,
        height: Some(planar_height),
        geometry,
        wf: cfg.fourier_wf,
        harmonics: cfg.fourier_harmonics.max(2),
        coef_bound: cfg.fourier_coef_bound,
        // the GA evaluates on a 20 Hz grid; the result is re-checked on the log grid below
        ts: 0.05,
        penalty: 1000.0,
    };
    let pb = bar(cfg.ga.generations as u64, "GA Fourier", show);
    let ga = GaConfig {
        seed: cfg.ga.seed.wrapping_add(1),
        ..cfg.ga
    };
    let r = minimize(&ga, &problem.bounds(), |x| problem.cost(x), Some(&pb));
    problem.ts = cfg.ts;
    let mut traj = problem.trajectory(&r.best);
    let ev = problem.evaluate(&traj);
    traj.periods = cfg.fourier_periods.max(1);

    let plant = Plant::new(model, cfg.theta_true.clone(), None);
    let mut pd = Pd {
        kp: cfg.fallback_kp.clone(),
        kd: cfg.fallback_kd.clone(),
    };
    let sim = SimConfig {
        dt: cfg.dt,
        log_every: (cfg.ts / cfg.dt).round().max(1.0) as usize,
        divergence_limit: 100.0,
        ..SimConfig::default()
    };
    let log = simulate(&plant, &mut pd, &traj, &sim).map_err(|source| PaperError::Sim {
        what: "Fourier experiment".into(),
        source,
    })?;
    let (dq, ddq) = lowpass_derivatives(&log, cfg.lowpass_hz, cfg.ts);
    // skip one second at each end, where the zero-phase filter sees its padding
    let skip = (1.0 / cfg.ts) as usize;
    let idx: Vec<usize> = (skip..log.len().saturating_sub(skip)).collect();
    let sig = Signals {
        dof: log.dof,
        q: &log.q,
        dq: &dq,
        ddq: &ddq,
        tau: &log.tau,
    };
    let theta_hat = full_ls(model, &sig, &idx).map_err(|source| PaperError::Ident {
        what: "Fourier".into(),
        source,
    })?;
    Ok((
        FourierOut {
            trajectory: traj,
            cond: ev.cond,
            feasible: ev.margins.feasible(),
            margins: ev.margins,
            ga_history: r.history,
            max_abs_error: max_abs_diff(&theta_hat, &cfg.theta_true),
            theta_hat,
            max_tracking_error: log.max_tracking_error(),
            lowpass_hz: cfg.lowpass_hz,
        },
        log,
    ))
}

/// Zero-phase 4th-order Butterworth + 5-point central differences of every joint of a log.
fn lowpass_derivatives(log: &SimLog, fc: f64, ts: f64) -> (Vec<f64>, Vec<f64>) {
    let (n, dof) = (log.len(), log.dof);
    let (mut dq, mut ddq) = (vec![0.0; n * dof], vec![0.0; n * dof]);
    for j in 0..dof {
        let mut x: Vec<f64> = (0..n).map(|k| log.q[k * dof + j]).collect();
        if let Ok(f) = Butterworth::lowpass(4, fc, 1.0 / ts) {
            f.filtfilt(&mut x);
        }
        let (v, a) = central_uniform(&x, ts);
        for k in 0..n {
            dq[k * dof + j] = v[k];
            ddq[k * dof + j] = a[k];
        }
    }
    (dq, ddq)
}

/// `q̇ = q̇d − ė`, `q̈ = q̈d − ë` with `e = qd − q` low-pass filtered and differentiated.
fn corrected_derivatives(log: &SimLog, fc: f64, ts: f64) -> (Vec<f64>, Vec<f64>) {
    let (n, dof) = (log.len(), log.dof);
    let e = SimLog {
        q: log.qd.iter().zip(&log.q).map(|(a, b)| a - b).collect(),
        t: log.t.clone(),
        dof,
        ..Default::default()
    };
    let (de, dde) = lowpass_derivatives(&e, fc, ts);
    let dq = (0..n * dof).map(|k| log.dqd[k] - de[k]).collect();
    let ddq = (0..n * dof).map(|k| log.ddqd[k] - dde[k]).collect();
    (dq, ddq)
}

/// Torque of `theta` along the samples.
fn torque_along(model: &dyn Model, s: &crate::trajectory::Samples, theta: &[f64]) -> Vec<f64> {
    let dof = s.dof;
    let mut out = vec![0.0; s.q.len()];
    for k in 0..s.t.len() {
        let r = k * dof..(k + 1) * dof;
        model.inverse_dynamics(
            &s.q[r.clone()],
            &s.dq[r.clone()],
            &s.ddq[r.clone()],
            theta,
            &mut out[r],
        );
    }
    out
}

fn torque_error(measured: &[f64], predicted: &[f64], dof: usize, theta: &[f64]) -> TorqueError {
    let n = measured.len() / dof;
    let mut rms = vec![0.0; dof];
    let mut max = vec![0.0_f64; dof];
    for k in 0..n {
        for j in 0..dof {
            let e = predicted[k * dof + j] - measured[k * dof + j];
            rms[j] += e * e;
            max[j] = max[j].max(e.abs());
        }
    }
    for r in &mut rms {
        *r = (*r / n as f64).sqrt();
    }
    TorqueError {
        theta_hat: theta.to_vec(),
        rms,
        max,
    }
}

/// Runs the whole reproduction: the GA design, the four iteration variants, the Fourier
/// comparison, the validation and the noise study, in that order.
pub fn run(model: &dyn Model, cfg: &PaperConfig) -> Result<(PaperResults, Traces), PaperError> {
    let start = Instant::now();
    if model.dof() != 2 || model.nb() != 6 {
        return Err(PaperError::WrongArm {
            name: model.name().into(),
            dof: model.dof(),
            nb: model.nb(),
        });
    }
    let show = &cfg.progress;
    let mut timings: Vec<(String, f64)> = Vec::new();
    let mut lap = Instant::now();
    let mut tick = |name: &str| {
        timings.push((name.to_string(), lap.elapsed().as_secs_f64()));
        lap = Instant::now();
    };

    // 1. GA (eq. 17)
    let problem = logistic_problem(model, cfg, cfg.ts);
    let (ga, design) = design_by_ga(model, cfg, &problem, show)?;
    tick("GA (Logistic)");

    // 2. iterative identification with both controllers
    let v = iterate_variants(model, cfg, &problem, &design, &ga.paper_design.design, show)?;
    tick("iterations (4 variants)");
    let error_vs_iteration = error_table(&v, cfg.iterations);

    // 3. Fourier comparison
    let (fourier, fourier_log) = fourier_comparison(model, cfg, show)?;
    tick("Fourier (GA + experiment)");

    // 4. validation: q1 = sin t, q2 = sin(−t)
    let (validation, validation_t, validation_tau) =
        validate(model, cfg, &v.rhftc, &v.corrected, &fourier.theta_hat);

    // 5. noise study on the converged experiment (the corrected iteration's last one)
    let noise = noise_study(model, cfg, &problem, &design, &v.logs_corrected, show)?;
    tick("noise study");

    let step_trajectories = [
        problem.step_trajectory(&design, 0),
        problem.step_trajectory(&design, 1),
    ];
    let traces = Traces {
        logs: v.logs,
        step_trajectories,
        fourier_log,
        validation_t,
        validation_tau,
    };
    let results = PaperResults {
        command: "dynid paper".into(),
        arm: model.name().into(),
        base_param_names: model
            .base_param_names()
            .iter()
            .map(|s| s.to_string())
            .collect(),
        base_param_exprs: model
            .base_param_exprs()
            .iter()
            .map(|s| s.to_string())
            .collect(),
        theta_true: cfg.theta_true.clone(),
        config: cfg.clone(),
        ga,
        iterations: v.rhftc,
        iterations_corrected: v.corrected,
        iterations_ctc: v.ctc,
        iterations_paper_design: v.paper_design,
        error_vs_iteration,
        fourier,
        validation,
        noise,
        timings,
        runtime_s: start.elapsed().as_secs_f64(),
    };
    Ok((results, traces))
}

/// Step 1: the GA's Logistic design (eq. 17), with the paper's own Table 3 design checked
/// against the same limits at the configured and at a 1 kHz sample time.
fn design_by_ga(
    model: &dyn Model,
    cfg: &PaperConfig,
    problem: &LogisticProblem,
    show: &Progress,
) -> Result<(GaOut, LogisticDesign), PaperError> {
    let pb = bar(cfg.ga.generations as u64, "GA Logistic", show);
    let r = minimize(&cfg.ga, &problem.bounds(), |x| problem.cost(x), Some(&pb));
    let best = check(problem, &r.best)?;
    let design = &best.design;
    let paper_design = check(problem, &PAPER_TABLE3)?;
    let paper_design_1khz = check(&logistic_problem(model, cfg, 1e-3), &PAPER_TABLE3)?;
    let ga = GaOut {
        a1: design.a[0],
        a2: design.a[1],
        w1: design.w[0],
        w2: design.w[1],
        delta1: design.delta[0],
        delta2: design.delta[1],
        period1: design.period[0],
        period2: design.period[1],
        cond_m: best.cond_m,
        cond_q: best.cond_q,
        cost: r.cost,
        feasible: best.feasible,
        margins: best.margins.clone(),
        generations: cfg.ga.generations,
        evaluations: r.evaluations,
        history: r.history,
        paper_design,
        paper_design_1khz,
    };
    Ok((ga, best.design))
}

/// The four iteration variants of step 2 and the logs of the ones later steps read.
struct Variants {
    rhftc: Vec<IterRecord>,
    corrected: Vec<IterRecord>,
    ctc: Vec<IterRecord>,
    paper_design: Vec<IterRecord>,
    logs: Vec<[SimLog; 2]>,
    logs_corrected: Vec<[SimLog; 2]>,
}

/// Step 2: the iterative identification with RHFTC (plain and corrected estimator), with CTC,
/// and — for comparison — the paper's method on the paper's own (limit-violating) Table 3 design.
fn iterate_variants(
    model: &dyn Model,
    cfg: &PaperConfig,
    problem: &LogisticProblem,
    design: &LogisticDesign,
    paper_design: &LogisticDesign,
    show: &Progress,
) -> Result<Variants, PaperError> {
    let pb = bar((8 * cfg.iterations) as u64, "iterations", show);
    let run = |d: &LogisticDesign, law: Law, est: IterEstimator| {
        iterate(model, cfg, problem, d, law, est, &pb)
    };
    let (rhftc, logs) = run(design, Law::Rhftc, IterEstimator::Map)?;
    let (corrected, logs_corrected) = run(design, Law::Rhftc, IterEstimator::Corrected)?;
    let (ctc, _) = run(design, Law::Ctc, IterEstimator::Map)?;
    let (paper_design, _) = run(paper_design, Law::Rhftc, IterEstimator::Map)?;
    Ok(Variants {
        rhftc,
        corrected,
        ctc,
        paper_design,
        logs,
        logs_corrected,
    })
}

/// The error and tracking table: per iteration, each variant's last record.
fn error_table(v: &Variants, iterations: usize) -> Vec<ErrorRow> {
    (1..=iterations)
        .map(|it| {
            let last = |recs: &[IterRecord]| recs.iter().rev().find(|r| r.iteration == it).cloned();
            let track = |recs: &[IterRecord]| {
                recs.iter()
                    .filter(|r| r.iteration == it)
                    .flat_map(|r| r.max_tracking_error.clone())
                    .fold(0.0, f64::max)
            };
            ErrorRow {
                iteration: it,
                rhftc: last(&v.rhftc).map_or(f64::NAN, |r| r.max_abs_error_all),
                corrected: last(&v.corrected).map_or(f64::NAN, |r| r.max_abs_error_all),
                ctc: last(&v.ctc).map_or(f64::NAN, |r| r.max_abs_error_all),
                paper_design: last(&v.paper_design).map_or(f64::NAN, |r| r.max_abs_error_all),
                rhftc_tracking: track(&v.rhftc),
                corrected_tracking: track(&v.corrected),
                ctc_tracking: track(&v.ctc),
                paper_design_tracking: track(&v.paper_design),
            }
        })
        .collect()
}

/// The estimate of the last record at or before iteration `upto` (all when `None`), else θ₀.
fn theta_upto(recs: &[IterRecord], upto: Option<usize>, cfg: &PaperConfig) -> Vec<f64> {
    recs.iter()
        .rev()
        .find(|r| upto.is_none_or(|u| r.iteration <= u))
        .map(|r| r.theta_hat.clone())
        .unwrap_or_else(|| cfg.theta0.clone())
}

/// Step 4: torque errors on the validation motion q1 = sin t, q2 = sin(−t); also returns its
/// time axis and the measured, Logistic and Fourier torques for the figures.
fn validate(
    model: &dyn Model,
    cfg: &PaperConfig,
    rhftc: &[IterRecord],
    corrected: &[IterRecord],
    fourier_theta: &[f64],
) -> (ValidationOut, Vec<f64>, [Vec<f64>; 3]) {
    let vtraj = Sine {
        amplitude: vec![1.0, -1.0],
        omega: vec![1.0, 1.0],
        offset: vec![0.0, 0.0],
        duration: cfg.validation_duration,
    };
    let vs = sample(&vtraj, cfg.ts, true);
    let measured = torque_along(model, &vs, &cfg.theta_true);
    let final_theta = theta_upto(rhftc, None, cfg);
    let iter3_theta = theta_upto(rhftc, Some(3), cfg);
    let pred_l = torque_along(model, &vs, &final_theta);
    let pred_l3 = torque_along(model, &vs, &iter3_theta);
    let pred_f = torque_along(model, &vs, fourier_theta);
    let corr3_theta = theta_upto(corrected, Some(3), cfg);
    let pred_c3 = torque_along(model, &vs, &corr3_theta);
    let validation = ValidationOut {
        trajectory: "q1 = sin t, q2 = sin(-t)".into(),
        duration: cfg.validation_duration,
        logistic_iter3: torque_error(&measured, &pred_l3, 2, &iter3_theta),
        logistic: torque_error(&measured, &pred_l, 2, &final_theta),
        corrected_iter3: torque_error(&measured, &pred_c3, 2, &corr3_theta),
        fourier: torque_error(&measured, &pred_f, 2, fourier_theta),
    };
    (validation, vs.t, [measured, pred_l, pred_f])
}

/// Step 5: the noise study on the converged experiment (the corrected iteration's last logs).
fn noise_study(
    model: &dyn Model,
    cfg: &PaperConfig,
    problem: &LogisticProblem,
    design: &LogisticDesign,
    logs_corrected: &[[SimLog; 2]],
    show: &Progress,
) -> Result<noise::NoiseStudy, PaperError> {
    let last = logs_corrected
        .last()
        .ok_or_else(|| PaperError::Design("no iterations were run".into()))?;
    let moving = problem.moving();
    let mut steps = Vec::new();
    for (s, plan) in problem.steps.iter().enumerate() {
        let traj = problem.step_trajectory(design, s);
        let joint = traj
            .moving(plan.joint)
            .copied()
            .ok_or_else(|| PaperError::Design("step without motion".into()))?;
        let i = moving.iter().position(|&j| j == plan.joint).unwrap_or(0);
        steps.push(noise::StepData {
            plan: plan.clone(),
            joint,
            window: problem.window(&joint, design.delta[i]),
            ts: cfg.ts,
            t: last[s].t.clone(),
            q: last[s].q.clone(),
            tau: last[s].tau.clone(),
        });
    }
    let ncfg = noise::NoiseConfig {
        runs: cfg.noise_runs,
        quant_bits: cfg.noise_quant_bits.clone(),
        torque_pct: cfg.noise_torque_pct.clone(),
        lowpass_hz: cfg.lowpass_hz,
        seed: cfg.ga.seed,
    };
    let pb = bar(
        (ncfg.quant_bits.len() * ncfg.torque_pct.len()) as u64,
        "noise study",
        show,
    );
    let noise = noise::run(model, &steps, &cfg.theta_true, &ncfg, &pb);
    Ok(noise)
}

/// Writes `report.md`, `results.json` and the figures into `dir` (created if missing).
pub fn write_outputs(
    dir: &Path,
    results: &PaperResults,
    traces: &Traces,
) -> Result<Vec<String>, PaperError> {
    std::fs::create_dir_all(dir).map_err(|cause| crate::io::WriteError {
        path: dir.to_path_buf(),
        cause,
    })?;
    let figs = figures::write_all(dir, results, traces)?;
    let json =
        serde_json::to_string_pretty(results).unwrap_or_else(|e| format!("{{\"error\": \"{e}\"}}"));
    crate::io::atomic_write(&dir.join("results.json"), |w| w.write_all(json.as_bytes()))?;
    let md = report::markdown(results, &figs);
    crate::io::atomic_write(&dir.join("report.md"), |w| w.write_all(md.as_bytes()))?;
    Ok(figs)
}
