//! What the paper reproduction hands to its report and figures: the GA's design, each iteration,
//! the Fourier comparison, the validation errors (serialised to `results.json`), and the series
//! behind the figures.

use serde::Serialize;

use super::*;

/// Table 3 as found by our GA, plus its evaluation.
#[derive(Debug, Clone, Serialize)]
pub struct GaOut {
    #[serde(rename = "A1")]
    pub a1: f64,
    #[serde(rename = "A2")]
    pub a2: f64,
    pub w1: f64,
    pub w2: f64,
    pub delta1: usize,
    pub delta2: usize,
    /// Periods from eq. 11, s.
    pub period1: f64,
    pub period2: f64,
    #[serde(rename = "cond_M")]
    pub cond_m: f64,
    #[serde(rename = "cond_Q")]
    pub cond_q: f64,
    pub cost: f64,
    pub feasible: bool,
    pub margins: Margins,
    pub generations: usize,
    pub evaluations: usize,
    pub history: Vec<f64>,
    /// The paper's Table 3 under our constraints, δ read as 100 Hz samples.
    pub paper_design: DesignCheck,
    /// The paper's Table 3 with δ read as 1 kHz samples.
    pub paper_design_1khz: DesignCheck,
}

/// A design evaluated under the paper's constraints.
#[derive(Debug, Clone, Serialize)]
pub struct DesignCheck {
    pub design: LogisticDesign,
    #[serde(rename = "cond_M")]
    pub cond_m: f64,
    #[serde(rename = "cond_Q")]
    pub cond_q: f64,
    pub feasible: bool,
    pub margins: Margins,
}

/// One step of one iteration.
#[derive(Debug, Clone, Serialize)]
pub struct IterRecord {
    pub iteration: usize,
    /// 1 = joint 2 moves (θ4..6), 2 = joint 1 moves (θ1..3).
    pub step: usize,
    pub controller: String,
    /// Fraction of control steps that ran the PD fallback (`θ̂` without inertia).
    pub fallback_fraction: f64,
    /// Fraction of control steps where an indefinite `M̂(q)` was diagonally loaded.
    pub loaded_fraction: f64,
    /// Estimate after this step (all six).
    pub theta_hat: Vec<f64>,
    /// `max |θ̂ − θ|` over the parameters this step identifies.
    pub max_abs_error: f64,
    /// `max |θ̂ − θ|` over all parameters after this step.
    pub max_abs_error_all: f64,
    /// `max_t |q_d − q|` per joint during this step, rad.
    pub max_tracking_error: Vec<f64>,
}

/// Fourier comparison (Table 6).
#[derive(Debug, Clone, Serialize)]
pub struct FourierOut {
    pub trajectory: Fourier,
    pub cond: f64,
    pub feasible: bool,
    pub margins: Margins,
    pub ga_history: Vec<f64>,
    pub theta_hat: Vec<f64>,
    pub max_abs_error: f64,
    pub max_tracking_error: Vec<f64>,
    pub lowpass_hz: f64,
}

/// Torque prediction error on the validation motion.
#[derive(Debug, Clone, Serialize)]
pub struct TorqueError {
    pub theta_hat: Vec<f64>,
    pub rms: Vec<f64>,
    pub max: Vec<f64>,
}

/// Validation (Figs 16–17).
#[derive(Debug, Clone, Serialize)]
pub struct ValidationOut {
    pub trajectory: String,
    pub duration: f64,
    /// After three iterations (the paper's claim).
    pub logistic_iter3: TorqueError,
    /// After the last iteration.
    pub logistic: TorqueError,
    /// Our corrected-derivative iteration, after three iterations.
    pub corrected_iter3: TorqueError,
    pub fourier: TorqueError,
}

/// `max |θ̂ − θ|` after each full iteration, for both controllers.
#[derive(Debug, Clone, Serialize)]
pub struct ErrorRow {
    pub iteration: usize,
    /// The paper's method: RHFTC + eq. 15.
    pub rhftc: f64,
    /// RHFTC + tracking-error-corrected derivatives.
    pub corrected: f64,
    /// Computed-torque PD + eq. 15.
    pub ctc: f64,
    /// RHFTC + eq. 15 on the paper's Table 3 design.
    pub paper_design: f64,
    pub rhftc_tracking: f64,
    pub corrected_tracking: f64,
    pub ctc_tracking: f64,
    pub paper_design_tracking: f64,
}

/// `results.json`.
#[derive(Debug, Clone, Serialize)]
pub struct PaperResults {
    pub command: String,
    pub arm: String,
    pub base_param_names: Vec<String>,
    pub base_param_exprs: Vec<String>,
    pub theta_true: Vec<f64>,
    pub config: PaperConfig,
    pub ga: GaOut,
    /// The paper's method (RHFTC, eq. 15 derivatives).
    pub iterations: Vec<IterRecord>,
    /// RHFTC with tracking-error-corrected derivatives (ours).
    pub iterations_corrected: Vec<IterRecord>,
    /// Computed-torque PD, eq. 15 derivatives.
    pub iterations_ctc: Vec<IterRecord>,
    /// The paper's method on the paper's Table 3 design (which violates the limits).
    pub iterations_paper_design: Vec<IterRecord>,
    pub error_vs_iteration: Vec<ErrorRow>,
    pub fourier: FourierOut,
    pub validation: ValidationOut,
    pub noise: noise::NoiseStudy,
    /// Wall-clock seconds per phase.
    pub timings: Vec<(String, f64)>,
    pub runtime_s: f64,
}

/// Series behind the figures (not serialised).
pub struct Traces {
    /// Step logs per iteration: `[iteration][step]`.
    pub logs: Vec<[SimLog; 2]>,
    pub step_trajectories: [Logistic; 2],
    pub fourier_log: SimLog,
    pub validation_t: Vec<f64>,
    /// Measured, Logistic-predicted and Fourier-predicted torque (`n × 2`).
    pub validation_tau: [Vec<f64>; 3],
}
