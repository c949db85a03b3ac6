//! `dynid excite --arm A [--kind logistic|fourier] [--seed N] [--generations N] [--out F]`:
//! optimise an excitation trajectory with the paper's GA and write it as JSON (readable by
//! `dynid simulate --trajectory F`).
//!
//! `logistic` is the paper's step-by-step design (eq. 17), which relies on the block-triangular
//! base regressor of the paper's 2-DOF arm; `fourier` works for any generated arm (all joints move
//! at once, cost = condition number of the stacked base regressor). Limits are the paper's
//! (`0 < q < π`, `|q̇| < π/6`, `|q̈| < π/15`).

use std::path::PathBuf;

use anyhow::Result;
use serde_json::json;

use crate::{write_output, InputError};
use dynid::arms::{resolve, ArmSource};
use dynid::excitation::{
    minimize, FourierProblem, GaConfig, Limits, LogisticProblem, LogisticSettings,
};
use dynid::trajectory::logistic::Logistic;
use dynid::trajectory::TrajectorySpec;

#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Kind {
    Logistic,
    Fourier,
}

#[derive(Debug, clap::Args)]
pub struct Args {
    /// Arm name (see `dynid arms`).
    #[arg(long)]
    pub arm: String,
    /// Trajectory family.
    #[arg(long, value_enum, default_value = "logistic")]
    pub kind: Kind,
    /// GA seed.
    #[arg(long, default_value_t = 2022)]
    pub seed: u64,
    /// GA generations (the paper: 500).
    #[arg(long, default_value_t = 500)]
    pub generations: usize,
    /// Fourier: harmonics per joint.
    #[arg(long, default_value_t = 5)]
    pub harmonics: usize,
    /// Fourier: period of the fundamental, s.
    #[arg(long, default_value_t = 10.0)]
    pub period: f64,
    /// Output JSON (default: stdout).
    #[arg(long)]
    pub out: Option<PathBuf>,
}

pub fn run(args: &Args) -> Result<()> {
    let model = match resolve(&args.arm)? {
        ArmSource::Generated(m) => m,
        ArmSource::Table(_) => {
            return Err(InputError(
                "excite needs a generated arm (a name from `dynid arms`), not a D-H table path"
                    .into(),
            )
            .into())
        }
    };
    if args.generations == 0 || args.harmonics < 2 || args.period <= 0.0 || !args.period.is_finite()
    {
        return Err(InputError(format!(
            "--generations must be ≥ 1, --harmonics ≥ 2 and --period > 0 (got {}, {}, {})",
            args.generations, args.harmonics, args.period
        ))
        .into());
    }
    let ga = GaConfig {
        seed: args.seed,
        generations: args.generations,
        ..GaConfig::default()
    };
    let (bar, pb) = crate::bar::Bar::start();
    pb.stage("generations", ga.generations as u64);
    let doc = match args.kind {
        Kind::Logistic => {
            if model.dof() != 2 || model.nb() != 6 {
                return Err(InputError(format!(
                    "--kind logistic is the paper's step-by-step design for a 2-DOF arm with the paper's 6 base parameters; `{}` has {} joints and {} base parameters — use --kind fourier",
                    model.name(), model.dof(), model.nb()
                ))
                .into());
            }
            // the paper's design, sampled at the paper's 100 Hz identification log
            let problem = LogisticProblem::planar(model, &LogisticSettings::paper(), 0.01);
            let r = minimize(&ga, &problem.bounds(), |x| problem.cost(x), Some(&pb));
            let design = problem
                .design(&r.best)
                .map_err(|e| InputError(e.to_string()))?;
            let ev = problem.evaluate(&design);
            let steps: Vec<TrajectorySpec> = (0..problem.steps.len())
                .map(|s| TrajectorySpec::Logistic(problem.step_trajectory(&design, s)))
                .collect();
            // one file that `simulate` can run: the first step; all steps are listed too
            let first: Logistic = problem.step_trajectory(&design, 0);
            json!({
                "arm": model.name(), "kind": "logistic", "seed": args.seed, "generations": args.generations,
                "design": design, "cond": ev.cond, "feasible": ev.margins.feasible(), "margins": ev.margins,
                "cost": ev.cost, "steps": steps, "trajectory": TrajectorySpec::Logistic(first),
            })
        }
        Kind::Fourier => {
            let problem = FourierProblem {
                model,
                limits: Limits::paper(),
                height: None,
                geometry: vec![],
                wf: std::f64::consts::TAU / args.period,
                harmonics: args.harmonics,
                coef_bound: 0.1,
                ts: 0.05,
                penalty: 1000.0,
            };
            let r = minimize(&ga, &problem.bounds(), |x| problem.cost(x), Some(&pb));
            let traj = problem.trajectory(&r.best);
            let ev = FourierProblem {
                ts: 0.01,
                ..problem
            }
            .evaluate(&traj);
            json!({
                "arm": model.name(), "kind": "fourier", "seed": args.seed, "generations": args.generations,
                "cond": ev.cond, "feasible": ev.margins.feasible(), "margins": ev.margins, "cost": ev.cost,
                "trajectory": TrajectorySpec::Fourier(traj),
            })
        }
    };
    bar.finish_and_clear();
    let text = serde_json::to_string_pretty(&doc)?;
    write_output(args.out.as_deref(), |w| writeln!(w, "{text}"))
}
