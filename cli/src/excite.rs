//! `dynid excite --arm A --out DIR [--kind fourier|logistic] [limits…]`: designs an excitation
//! trajectory for any arm under its own limits and writes `DIR/trajectory.csv`,
//! `DIR/excitation.json` and `DIR/report.md` (see `dynid::excitation::design`). Exit code 0 only
//! for a feasible design; 1 when none was found (nothing is written), 2 for bad input.

use std::path::PathBuf;
use std::time::Duration;

use anyhow::Result;

use crate::InputError;
use dynid::arms::{resolve, resolve_urdf};
use dynid::effects::Effect;
use dynid::excitation::derived;
use dynid::excitation::design::{design, DesignConfig, DesignError, Family};
use dynid::excitation::limits::{self, LimitSources, Limits, LimitsFile, Overrides};
use dynid::excitation::objective::ObjectiveKind;
use dynid::excitation::output;
use dynid::params::{InertialParams, ParamsOptions};

#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Kind {
    Fourier,
    Logistic,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Objective {
    Cond,
    Logdet,
}

#[derive(Debug, clap::Args)]
pub struct Args {
    /// Arm: a name (see `dynid arms`), a D-H table (`.toml`) or a URDF (`.urdf`).
    #[arg(long)]
    pub arm: String,
    /// Trajectory family: Fourier series with a quintic boundary term, or the paper's Logistic.
    #[arg(long, value_enum, default_value = "fourier")]
    pub kind: Kind,
    /// Period of the trajectory, s.
    #[arg(long, default_value_t = 10.0)]
    pub period: f64,
    /// Fourier: harmonics per joint.
    #[arg(long, default_value_t = 5)]
    pub harmonics: usize,
    /// Sample rate of trajectory.csv and of the reported condition number, Hz.
    #[arg(long, default_value_t = 500.0)]
    pub rate: f64,
    /// Rate the search evaluates candidates at, Hz.
    #[arg(long, default_value_t = 25.0)]
    pub search_rate: f64,
    /// What to minimise.
    #[arg(long, value_enum, default_value = "cond")]
    pub objective: Objective,
    /// Effect columns of the observation matrix (comma list, or `none`).
    #[arg(long, default_value = "viscous,coulomb,offset,armature")]
    pub effects: String,
    /// Limits TOML: `[[joint]]` tables with q_min, q_max, dq_max, ddq_max, tau_max.
    #[arg(long)]
    pub limits: Option<PathBuf>,
    /// Lower position limits, rad (comma list: one value or one per joint).
    #[arg(long, allow_hyphen_values = true)]
    pub q_min: Option<String>,
    /// Upper position limits, rad.
    #[arg(long, allow_hyphen_values = true)]
    pub q_max: Option<String>,
    /// Velocity limits, rad/s.
    #[arg(long)]
    pub dq_max: Option<String>,
    /// Acceleration limits, rad/s².
    #[arg(long)]
    pub ddq_max: Option<String>,
    /// Torque limits, N·m (checked when --params is given).
    #[arg(long)]
    pub tau_max: Option<String>,
    /// Start and end posture, rad (default: the middle of each range).
    #[arg(long, allow_hyphen_values = true)]
    pub q0: Option<String>,
    /// Inertial parameters (TOML, as `import-urdf` writes) for the torque limits.
    #[arg(long)]
    pub params: Option<PathBuf>,
    /// Keep the tool point (last frame origin) above this height in the base frame, m.
    #[arg(long, allow_hyphen_values = true)]
    pub keep_above: Option<f64>,
    /// Relative margin kept from the position, velocity and acceleration limits.
    #[arg(long, default_value_t = 0.005)]
    pub margin: f64,
    /// CMA-ES seed.
    #[arg(long, default_value_t = 2022)]
    pub seed: u64,
    /// CMA-ES generations.
    #[arg(long, default_value_t = 300)]
    pub generations: usize,
    /// Wall-clock budget of the search, s.
    #[arg(long, default_value_t = 60.0)]
    pub budget_s: f64,
    /// Output directory.
    #[arg(long)]
    pub out: PathBuf,
}

fn parse_effects(spec: &str) -> Result<Vec<Effect>, InputError> {
    let s = spec.trim();
    if s == "none" || s.is_empty() {
        return Ok(Vec::new());
    }
    let mut out = Vec::new();
    for name in s.split(',') {
        match Effect::parse(name) {
            Some(e) if !e.needs_load() && !e.is_per_run() => out.push(e),
            _ => {
                return Err(InputError(format!(
                    "--effects: `{}` is not one of viscous, coulomb, stribeck, offset, armature, spring (or `none`)",
                    name.trim()
                )))
            }
        }
    }
    out.dedup();
    Ok(out)
}

/// The limits from the arm, `--limits` and the flags, with derived acceleration limits where none is
/// given, and the inertial parameters torques are checked with (`--params`, else a URDF's own).
fn resolve_limits(
    args: &Args,
    imported: Option<&dynid::urdf::Imported>,
    table: &dynid::dh::DhTable,
) -> Result<(Limits, Option<InertialParams>)> {
    let dof = table.dof();
    let names: Vec<String> = match (imported, table.joint_names()) {
        (Some(i), _) => i.chain.clone(),
        (None, Some(n)) => n,
        _ => (1..=dof).map(|j| format!("joint {j}")).collect(),
    };
    let list = |flag: &'static str, v: &Option<String>| -> Result<Option<Vec<f64>>> {
        v.as_deref()
            .map(|t| limits::parse_list(flag, t, dof))
            .transpose()
            .map_err(|e| InputError(e.to_string()).into())
    };
    let file = match &args.limits {
        Some(p) => Some((
            p.display().to_string(),
            LimitsFile::read(p, dof).map_err(|e| InputError(e.to_string()))?,
        )),
        None => None,
    };
    let mut sources = LimitSources {
        names,
        arm: limits::from_table(table),
        arm_label: if imported.is_some() {
            "urdf"
        } else {
            "arm table"
        }
        .into(),
        soft: match imported {
            Some(i) => limits::soft_limits(std::path::Path::new(&args.arm), &i.chain),
            None => Vec::new(),
        },
        file,
        overrides: Overrides {
            q_min: list("--q-min", &args.q_min)?,
            q_max: list("--q-max", &args.q_max)?,
            dq_max: list("--dq-max", &args.dq_max)?,
            ddq_max: list("--ddq-max", &args.ddq_max)?,
            tau_max: list("--tau-max", &args.tau_max)?,
            q0: list("--q0", &args.q0)?,
        },
        derived_ddq: Vec::new(),
        derived_label: derived::LABEL.into(),
    };
    // Inertial parameters for the torque limits: --params, else a URDF's own <inertial>s.
    let (params, params_label) = match (&args.params, imported) {
        (Some(p), _) => (
            Some(InertialParams::from_path(
                p,
                dof,
                &ParamsOptions::default(),
            )?),
            p.display().to_string(),
        ),
        (None, Some(i)) => (Some(i.params.clone()), "the URDF's <inertial>s".to_string()),
        (None, None) => (None, String::new()),
    };
    let mut notes = Vec::new();
    if let Some(p) = &params {
        let merged: Vec<_> = (0..dof).map(|j| sources.merged(j)).collect();
        if merged.iter().any(|m| m.ddq_max.0.is_none()) {
            let ranges: Vec<Option<(f64, f64)>> =
                merged.iter().map(|m| m.q_min.0.zip(m.q_max.0)).collect();
            let effort: Vec<Option<f64>> = merged.iter().map(|m| m.tau_max.0).collect();
            sources.derived_ddq =
                derived::acceleration_limits(table, &p.full_vector(), &ranges, &effort);
            let used: Vec<String> = merged
                .iter()
                .zip(&sources.derived_ddq)
                .enumerate()
                .filter_map(|(j, (m, d))| match (m.ddq_max.0, d) {
                    (None, Ok(v)) => Some(format!("joint {} {v:.3}", j + 1)),
                    _ => None,
                })
                .collect();
            if !used.is_empty() {
                notes.push(format!(
                    "ddq_max derived from effort and inertia ((τ_max − max|g|)/max M_jj, {params_label}): {}",
                    used.join(", ")
                ));
            }
        }
    }
    let mut limits = sources.resolve().map_err(|e| InputError(e.to_string()))?;
    if params.is_some() && limits.joints.iter().any(|l| l.tau_max.is_some()) {
        notes.push(format!(
            "tau_max checked through the inverse dynamics with {params_label}"
        ));
    }
    for n in &notes {
        eprintln!("note: {n}");
    }
    limits.notes = notes;
    Ok((limits, params))
}

pub fn run(args: &Args) -> Result<()> {
    let imported = resolve_urdf(&args.arm)?;
    let arm = resolve(&args.arm)?;
    let table = arm.dh_table()?;
    let (limits, params) = resolve_limits(args, imported.as_ref(), &table)?;
    if !(args.budget_s.is_finite() && args.budget_s > 0.0) {
        return Err(InputError(format!("--budget-s must be > 0 (got {})", args.budget_s)).into());
    }
    if !(args.margin >= 0.0 && args.margin < 0.5) {
        return Err(InputError(format!(
            "--margin must be in [0, 0.5) (got {})",
            args.margin
        ))
        .into());
    }
    let cfg = DesignConfig {
        family: match args.kind {
            Kind::Fourier => Family::Fourier,
            Kind::Logistic => Family::Logistic,
        },
        period: args.period,
        harmonics: args.harmonics,
        rate: args.rate,
        search_rate: args.search_rate,
        objective: match args.objective {
            Objective::Cond => ObjectiveKind::Cond,
            Objective::Logdet => ObjectiveKind::LogDet,
        },
        effects: parse_effects(&args.effects)?,
        seed: args.seed,
        generations: args.generations,
        budget: Duration::from_secs_f64(args.budget_s),
        margin: args.margin,
        keep_above: args.keep_above,
        population: None,
    };
    let (bar, pb) = crate::bar::Bar::start();
    let result = design(&arm, &limits, params.as_ref(), &cfg, Some(&pb));
    bar.finish_and_clear();
    let d = match result {
        Ok(d) => d,
        Err(e @ DesignError::Settings(_)) => return Err(InputError(e.to_string()).into()),
        Err(e) => return Err(e.into()),
    };
    output::write_all(&args.out, arm.name(), &d, &limits, &cfg)?;
    eprintln!(
        "{}: cond {:.2} ({} columns), {} generations in {:.1} s; wrote {}",
        arm.name(),
        d.conditioning.cond,
        d.columns.len(),
        d.generations,
        d.seconds,
        args.out.display()
    );
    Ok(())
}
