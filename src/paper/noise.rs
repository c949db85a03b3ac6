//! Beyond the paper: how the step-by-step identification degrades under encoder quantisation and
//! torque noise, for four ways of getting `q̇`, `q̈` from the measured positions.
//!
//! The clean closed-loop experiment (converged controller, so the arm follows the Logistic
//! trajectory) is simulated once; each Monte Carlo run then quantises the logged positions (with a
//! random encoder zero, so runs differ) and adds white Gaussian torque noise, estimates the
//! derivatives of the moving joint with each estimator, and redoes both least-squares steps.
//! Every estimator uses the same samples (the ±δ windows) and the same noisy data, so the
//! differences come from the derivative estimates alone. Resting joints get zero derivatives for
//! every estimator (the experiment says they rest).

use crate::progress::Progress;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use serde::Serialize;

use super::ident::{max_abs_diff, step_ls, Signals};
use crate::excitation::StepPlan;
use crate::measurement::quantise_with_zero;
use crate::model::Model;
use crate::signal::{central_uniform, Butterworth};
use crate::trajectory::fourier::fit_periodic;
use crate::trajectory::logistic::LogisticJoint;

/// The derivative estimators compared.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Differentiator {
    /// Eq. 15 applied to the measured position.
    LogisticAnalytic,
    /// 5-point central differences of the raw samples.
    CentralDifferences,
    /// Zero-phase 4th-order Butterworth low-pass, then 5-point central differences.
    LowpassDifferences,
    /// Least-squares Fourier series over the period, differentiated analytically.
    FourierFit,
    /// Ours: analytic reference minus the low-pass-differentiated tracking error
    /// (`q̈ = q̈d − ë`); what the corrected iteration uses.
    ReferenceCorrected,
}

impl Differentiator {
    pub const ALL: [Differentiator; 5] = [
        Self::LogisticAnalytic,
        Self::CentralDifferences,
        Self::LowpassDifferences,
        Self::FourierFit,
        Self::ReferenceCorrected,
    ];

    pub fn label(self) -> &'static str {
        match self {
            Self::LogisticAnalytic => "(a) Logistic eq. 15",
            Self::CentralDifferences => "(b) central differences",
            Self::LowpassDifferences => "(c) low-pass + differences",
            Self::FourierFit => "(d) Fourier fit",
            Self::ReferenceCorrected => "(e) reference − filtered tracking error",
        }
    }
}

/// One step's clean data.
pub struct StepData {
    pub plan: StepPlan,
    pub joint: LogisticJoint,
    /// Sample indices used by the least squares.
    pub window: Vec<usize>,
    pub ts: f64,
    pub t: Vec<f64>,
    /// `n × dof` true positions and applied torques.
    pub q: Vec<f64>,
    pub tau: Vec<f64>,
}

/// Study settings.
#[derive(Debug, Clone, Serialize)]
pub struct NoiseConfig {
    pub runs: usize,
    /// Encoder resolutions as bits per revolution (`None` = exact positions).
    pub quant_bits: Vec<Option<u32>>,
    /// Torque noise standard deviation as a percentage of each joint's RMS torque in the step.
    pub torque_pct: Vec<f64>,
    pub lowpass_hz: f64,
    pub seed: u64,
}

/// Mean and standard deviation of `max |θ̂ − θ|` over the runs of one cell.
#[derive(Debug, Clone, Serialize)]
pub struct Cell {
    pub quant_bits: Option<u32>,
    pub torque_pct: f64,
    pub estimator: Differentiator,
    pub mean: f64,
    pub std: f64,
    /// Runs whose least squares failed (counted, not averaged).
    pub failed: usize,
}

/// The whole study.
#[derive(Debug, Clone, Serialize)]
pub struct NoiseStudy {
    pub config: NoiseConfig,
    pub cells: Vec<Cell>,
}

impl NoiseStudy {
    /// The cell for a level and estimator.
    pub fn cell(&self, bits: Option<u32>, pct: f64, e: Differentiator) -> Option<&Cell> {
        self.cells
            .iter()
            .find(|c| c.quant_bits == bits && c.torque_pct == pct && c.estimator == e)
    }
}

/// Box–Muller like [`crate::measurement::gauss`], but drawing `u1` from `gen::<f64>()` (so a
/// different stream): kept so that the published noise study stays reproducible.
fn gauss(rng: &mut ChaCha8Rng) -> f64 {
    let u1: f64 = rng.gen::<f64>().max(1e-300);
    let u2: f64 = rng.gen();
    (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
}

/// Derivatives of the moving joint `j` of a step with estimator `e` (resting joints: zero).
fn derivatives(
    e: Differentiator,
    d: &StepData,
    dof: usize,
    q: &[f64],
    lowpass_hz: f64,
) -> (Vec<f64>, Vec<f64>) {
    let n = d.t.len();
    let j = d.plan.joint;
    let (mut dq, mut ddq) = (vec![0.0; n * dof], vec![0.0; n * dof]);
    let x: Vec<f64> = (0..n).map(|k| q[k * dof + j]).collect();
    let (v, a) = match e {
        Differentiator::LogisticAnalytic => {
            d.t.iter()
                .zip(&x)
                .map(|(&t, &qk)| d.joint.derivatives_from_position(t, qk))
                .unzip()
        }
        Differentiator::CentralDifferences => central_uniform(&x, d.ts),
        Differentiator::LowpassDifferences => {
            let mut y = x.clone();
            if let Ok(f) = Butterworth::lowpass(4, lowpass_hz, 1.0 / d.ts) {
                f.filtfilt(&mut y);
            }
            central_uniform(&y, d.ts)
        }
        Differentiator::FourierFit => {
            // the log is closed ([0, T]); the fit wants exactly one period
            let m = n - 1;
            let wf = std::f64::consts::TAU / d.joint.period;
            let harmonics = ((lowpass_hz * d.joint.period).floor() as usize).clamp(1, m / 2 - 1);
            match fit_periodic(&d.t[..m], &x[..m], wf, harmonics) {
                Ok(fit) => {
                    d.t.iter()
                        .map(|&t| {
                            let (_, v, a) = fit.eval(t);
                            (v, a)
                        })
                        .unzip()
                }
                Err(_) => (vec![f64::NAN; n], vec![f64::NAN; n]),
            }
        }
        Differentiator::ReferenceCorrected => {
            let desired: Vec<(f64, f64, f64)> = d.t.iter().map(|&t| d.joint.eval(t)).collect();
            let mut err: Vec<f64> = desired.iter().zip(&x).map(|(r, &qk)| r.0 - qk).collect();
            if let Ok(f) = Butterworth::lowpass(4, lowpass_hz, 1.0 / d.ts) {
                f.filtfilt(&mut err);
            }
            let (de, dde) = central_uniform(&err, d.ts);
            (0..n)
                .map(|k| (desired[k].1 - de[k], desired[k].2 - dde[k]))
                .unzip()
        }
    };
    for k in 0..n {
        dq[k * dof + j] = v[k];
        ddq[k * dof + j] = a[k];
    }
    (dq, ddq)
}

/// Identifies θ from (noisy) step data with one estimator: step 1 then step 2 with step 1's
/// parameters known. Returns `None` when a least squares fails.
pub fn identify_with(
    model: &dyn Model,
    steps: &[StepData],
    q: &[Vec<f64>],
    tau: &[Vec<f64>],
    e: Differentiator,
    lowpass_hz: f64,
) -> Option<Vec<f64>> {
    let dof = model.dof();
    let mut theta = vec![0.0; model.nb()];
    for (s, d) in steps.iter().enumerate() {
        let (dq, ddq) = derivatives(e, d, dof, &q[s], lowpass_hz);
        let sig = Signals {
            dof,
            q: &q[s],
            dq: &dq,
            ddq: &ddq,
            tau: &tau[s],
        };
        let x = step_ls(model, &sig, &d.window, d.plan.row, &d.plan.cols, &theta).ok()?;
        for (i, &c) in d.plan.cols.iter().enumerate() {
            theta[c] = x[i];
        }
    }
    theta.iter().all(|v| v.is_finite()).then_some(theta)
}

/// Runs the Monte Carlo study over the full grid of levels.
pub fn run(
    model: &dyn Model,
    steps: &[StepData],
    theta_true: &[f64],
    cfg: &NoiseConfig,
    pb: &Progress,
) -> NoiseStudy {
    let dof = model.dof();
    let rms: Vec<Vec<f64>> = steps
        .iter()
        .map(|d| {
            let n = d.t.len() as f64;
            (0..dof)
                .map(|j| {
                    (d.tau
                        .iter()
                        .skip(j)
                        .step_by(dof)
                        .map(|v| v * v)
                        .sum::<f64>()
                        / n)
                        .sqrt()
                })
                .collect()
        })
        .collect();
    let mut levels = Vec::new();
    for &b in &cfg.quant_bits {
        for &p in &cfg.torque_pct {
            levels.push((b, p));
        }
    }
    let mut cells = Vec::new();
    for (li, &(bits, pct)) in levels.iter().enumerate() {
        // errors[run][estimator]
        let errors: Vec<[Option<f64>; 5]> = (0..cfg.runs)
            .into_par_iter()
            .map(|run| {
                let mut rng =
                    ChaCha8Rng::seed_from_u64(cfg.seed ^ ((li as u64) << 32) ^ run as u64);
                let mut q = Vec::with_capacity(steps.len());
                let mut tau = Vec::with_capacity(steps.len());
                for (s, d) in steps.iter().enumerate() {
                    let mut qs = d.q.clone();
                    if let Some(b) = bits {
                        let lsb = std::f64::consts::TAU / (1u64 << b) as f64;
                        let zero: Vec<f64> = (0..dof).map(|_| rng.gen::<f64>() * lsb).collect();
                        quantise_with_zero(&mut qs, lsb, &zero);
                    }
                    let mut ts = d.tau.clone();
                    if pct > 0.0 {
                        for (k, v) in ts.iter_mut().enumerate() {
                            *v += 0.01 * pct * rms[s][k % dof] * gauss(&mut rng);
                        }
                    }
                    q.push(qs);
                    tau.push(ts);
                }
                let mut out = [None; 5];
                for (i, e) in Differentiator::ALL.iter().enumerate() {
                    out[i] = identify_with(model, steps, &q, &tau, *e, cfg.lowpass_hz)
                        .map(|th| max_abs_diff(&th, theta_true));
                }
                out
            })
            .collect();
        for (i, e) in Differentiator::ALL.iter().enumerate() {
            let ok: Vec<f64> = errors.iter().filter_map(|r| r[i]).collect();
            let n = ok.len().max(1) as f64;
            let mean = ok.iter().sum::<f64>() / n;
            let var = ok.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1.0).max(1.0);
            cells.push(Cell {
                quant_bits: bits,
                torque_pct: pct,
                estimator: *e,
                mean,
                std: var.sqrt(),
                failed: cfg.runs - ok.len(),
            });
        }
        pb.step();
    }
    NoiseStudy {
        config: cfg.clone(),
        cells,
    }
}
