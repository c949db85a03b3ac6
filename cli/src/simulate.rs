//! `dynid simulate --arm A --params P --trajectory T [--controller rhftc|ctc|pd] [--estimate P2]
//! [--dt S] [--integrator rk4|implicit-euler] [--log-every N] [--out F]`: closed-loop simulation of
//! an arm (RK4 or linearly implicit Euler plant with the parameter file's effects) tracking a
//! trajectory; writes CSV `t, q…, dq…, ddq…, tau…`. A generated arm runs on its generated
//! kernels; a D-H table or a URDF (imported in memory) on the reference recursions, and a URDF's
//! own `<inertial>`s are the default `--params`.
//!
//! `T` is JSON as written by `dynid excite` (its `trajectory` field is used) or a bare trajectory
//! (`{"kind": "sine", ...}`). The controller's model is `--estimate` (another parameter file) or,
//! by default, the true parameters (rigid body only: the effects stay unmodelled).
//!
//! Measurement models for realistic test data (all off by default): `--tau-noise F` adds white
//! Gaussian noise of F × each joint's RMS torque, `--encoder-counts N` quantises revolute
//! positions to 2π/N rad (prismatic to 1/N m), `--positions-only` writes `t, q…, tau…` (no
//! derivative columns, as a real log), `--seed` makes the noise reproducible.

use std::path::PathBuf;

use anyhow::{Context, Result};

use crate::{write_output, InputError};
use dynid::arms::{resolve, resolve_urdf, ArmSource};
use dynid::control::{Controller, Ctc, Pd, Rhftc, RhftcGains};
use dynid::data::{write_header, write_row};
use dynid::dh::DhTable;
use dynid::dynamics::{Dynamics, Generated, Reference};
use dynid::params::{InertialParams, ParamsOptions};
use dynid::reference::RefModel;
use dynid::sim::{simulate, Integrator, Plant, SimConfig};
use dynid::trajectory::TrajectorySpec;
use dynid::urdf::Imported;

#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum ControllerKind {
    Rhftc,
    Ctc,
    Pd,
}

/// `--integrator`: the plant's integration scheme ([`Integrator`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum IntegratorKind {
    /// Classical RK4.
    Rk4,
    /// Linearly implicit Euler (stable on stiff friction; first order).
    ImplicitEuler,
}

#[derive(Debug, clap::Args)]
pub struct Args {
    /// Arm name (see `dynid arms`), path to a D-H table (.toml) or a URDF (.urdf, imported as `import-urdf` does).
    #[arg(long)]
    pub arm: String,
    /// True inertial parameters of the simulated arm (TOML, optional [effects]); for a URDF arm
    /// the default is the URDF's own `<inertial>`s.
    #[arg(long)]
    pub params: Option<PathBuf>,
    /// Trajectory JSON (from `dynid excite`, or a bare trajectory spec).
    #[arg(long)]
    pub trajectory: PathBuf,
    /// Tracking controller.
    #[arg(long, value_enum, default_value = "rhftc")]
    pub controller: ControllerKind,
    /// Parameters the controller believes (default: the true ones).
    #[arg(long)]
    pub estimate: Option<PathBuf>,
    /// Integration and control step, s.
    #[arg(long, default_value_t = 1e-3)]
    pub dt: f64,
    /// Integration scheme of the plant.
    #[arg(long, value_enum, default_value = "rk4")]
    pub integrator: IntegratorKind,
    /// Log every N-th step.
    #[arg(long, default_value_t = 10)]
    pub log_every: usize,
    /// Proportional gains (per joint; RHFTC/CTC: 1/s², PD: N·m/rad). Default: the paper's for 2 DOF, else 4.
    #[arg(long, value_delimiter = ',')]
    pub kp: Option<Vec<f64>>,
    /// Derivative gains (per joint). Default: the paper's for 2 DOF, else 4.
    #[arg(long, value_delimiter = ',')]
    pub kd: Option<Vec<f64>>,
    /// Add white Gaussian torque noise: standard deviation as a fraction of each joint's RMS torque.
    #[arg(long, default_value_t = 0.0)]
    pub tau_noise: f64,
    /// Quantise logged positions as an encoder with this many counts per revolution (per metre
    /// for prismatic joints).
    #[arg(long)]
    pub encoder_counts: Option<f64>,
    /// Write only `t, q…, tau…` (no dq/ddq columns: `identify` then differentiates q).
    #[arg(long)]
    pub positions_only: bool,
    /// Seed of the measurement noise.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Output CSV (default: stdout).
    #[arg(long)]
    pub out: Option<PathBuf>,
}

fn base_params(model: &dyn dynid::model::Model, params: &InertialParams) -> Vec<f64> {
    let mut theta = vec![0.0; model.nb()];
    model.base_params(&params.full_vector(), &mut theta);
    theta
}

/// Numeric options that clap cannot check by type.
fn check_numbers(args: &Args) -> Result<()> {
    if args.dt <= 0.0 || !args.dt.is_finite() || args.log_every == 0 {
        return Err(InputError(format!(
            "--dt must be > 0 and --log-every ≥ 1 (got {}, {})",
            args.dt, args.log_every
        ))
        .into());
    }
    if !(args.tau_noise >= 0.0 && args.tau_noise.is_finite()) {
        return Err(InputError(format!(
            "--tau-noise must be a fraction ≥ 0 (e.g. 0.01 for 1 %), got {}",
            args.tau_noise
        ))
        .into());
    }
    if let Some(c) = args.encoder_counts {
        if !(c >= 1.0 && c.is_finite()) {
            return Err(InputError(format!(
                "--encoder-counts must be ≥ 1 (e.g. 131072 for a 17-bit encoder), got {c}"
            ))
            .into());
        }
    }
    Ok(())
}

/// The trajectory file: the output of `dynid excite` or a bare trajectory spec, for `n` joints.
fn read_trajectory(args: &Args, n: usize, arm: &str) -> Result<TrajectorySpec> {
    let text = std::fs::read_to_string(&args.trajectory)
        .with_context(|| format!("{}: cannot read the trajectory", args.trajectory.display()))?;
    let value: serde_json::Value = serde_json::from_str(&text)
        .map_err(|e| InputError(format!("{}: not JSON: {e}", args.trajectory.display())))?;
    let spec_value = value.get("trajectory").cloned().unwrap_or(value);
    let spec: TrajectorySpec = serde_json::from_value(spec_value).map_err(|e| {
        InputError(format!(
            "{}: not a trajectory ({e}); expected the output of `dynid excite` or {{\"kind\": \"logistic\"|\"fourier\"|\"sine\", ...}}",
            args.trajectory.display()
        ))
    })?;
    spec.validate()
        .map_err(|e| InputError(format!("{}: {e}", args.trajectory.display())))?;
    if spec.as_dyn().dof() != n {
        return Err(InputError(format!(
            "the trajectory has {} joints, arm {arm} has {n}",
            spec.as_dyn().dof()
        ))
        .into());
    }
    Ok(spec)
}

/// The chosen controller with its gains (the paper's for a 2-joint arm, 4 otherwise, unless
/// given), built on the arm's dynamics with the `estimate` bound in.
fn controller(args: &Args, estimate: Box<dyn Dynamics>) -> Result<Box<dyn Controller>> {
    let n = estimate.dof();
    let paper = RhftcGains::paper();
    let default_kp = if n == 2 {
        paper.kp.clone()
    } else {
        vec![4.0; n]
    };
    let default_kd = if n == 2 {
        paper.kd.clone()
    } else {
        vec![4.0; n]
    };
    let kp = args.kp.clone().unwrap_or(default_kp);
    let kd = args.kd.clone().unwrap_or(default_kd);
    if kp.len() != n || kd.len() != n {
        return Err(InputError(format!(
            "--kp and --kd need {n} values each (got {}, {})",
            kp.len(),
            kd.len()
        ))
        .into());
    }
    let fallback = Pd {
        kp: vec![100.0; n],
        kd: vec![20.0; n],
    };
    Ok(match args.controller {
        ControllerKind::Rhftc => Box::new(Rhftc::on(
            estimate,
            RhftcGains { kp, kd, ..paper },
            fallback,
        )),
        ControllerKind::Ctc => Box::new(Ctc::on(estimate, kp, kd, fallback)),
        ControllerKind::Pd => Box::new(Pd { kp, kd }),
    })
}

/// One encoder count per joint: 2π/counts rad for a revolute joint, 1/counts m for a prismatic.
fn encoder_resolution(table: &DhTable, counts: f64) -> Vec<f64> {
    table
        .joints
        .iter()
        .map(|j| {
            if j.kind == dynid::dh::JointKind::Revolute {
                std::f64::consts::TAU / counts
            } else {
                1.0 / counts
            }
        })
        .collect()
}

/// The log as CSV: `t`, `q`, then (unless `--positions-only`) `dq`, `ddq`, then `tau`.
fn write_log(args: &Args, log: &dynid::sim::SimLog, n: usize) -> Result<()> {
    let signals: Vec<(&str, &[f64])> = if args.positions_only {
        vec![("q", &log.q), ("tau", &log.tau)]
    } else {
        vec![
            ("q", &log.q),
            ("dq", &log.dq),
            ("ddq", &log.ddq),
            ("tau", &log.tau),
        ]
    };
    let mut header = vec!["t".to_string()];
    for (sig, _) in &signals {
        header.extend((1..=n).map(|j| format!("{sig}{j}")));
    }
    write_output(args.out.as_deref(), |w| {
        write_header(w, &header)?;
        let mut row = vec![0.0; 1 + signals.len() * n];
        for k in 0..log.len() {
            row[0] = log.t[k];
            for (s, (_, v)) in signals.iter().enumerate() {
                row[1 + s * n..1 + (s + 1) * n].copy_from_slice(&v[k * n..(k + 1) * n]);
            }
            write_row(w, &row)?;
        }
        Ok(())
    })
}

/// The true parameters: `--params`, or a URDF arm's own inertials.
fn truth(args: &Args, n: usize, urdf: Option<Imported>) -> Result<InertialParams> {
    if let Some(p) = &args.params {
        return Ok(InertialParams::from_path(p, n, &ParamsOptions::default())?);
    }
    match urdf {
        Some(imported) => {
            eprintln!(
                "note: no --params: simulating {} with its URDF's own <inertial>s",
                args.arm
            );
            Ok(imported.params)
        }
        None => Err(InputError(
            "--params is required unless --arm is a URDF (whose <inertial>s are then used)".into(),
        )
        .into()),
    }
}

/// The plant's and the controller's dynamics: the generated kernels on base parameters, or the
/// reference recursions of a table on full parameters.
fn bodies(
    arm: &ArmSource,
    truth: &InertialParams,
    estimate: &InertialParams,
) -> (Box<dyn Dynamics>, Box<dyn Dynamics>) {
    match arm {
        ArmSource::Generated(m) => (
            Box::new(Generated::new(*m, base_params(*m, truth))),
            Box::new(Generated::new(*m, base_params(*m, estimate))),
        ),
        ArmSource::Table(t) => (
            Box::new(Reference::new(RefModel::new(t), truth.full_vector())),
            Box::new(Reference::new(RefModel::new(t), estimate.full_vector())),
        ),
    }
}

pub fn run(args: &Args) -> Result<()> {
    // A URDF is imported once: its table is the arm, its inertials the default truth.
    let urdf = resolve_urdf(&args.arm)?;
    let arm = match &urdf {
        Some(imported) => ArmSource::Table(imported.table.clone()),
        None => resolve(&args.arm)?,
    };
    let n = arm.dof();
    check_numbers(args)?;
    let truth = truth(args, n, urdf)?;
    let estimate = match &args.estimate {
        Some(p) => InertialParams::from_path(
            p,
            n,
            &ParamsOptions {
                allow_nonphysical: true,
            },
        )?,
        None => truth.clone(),
    };
    let spec = read_trajectory(args, n, arm.name())?;
    let (body, believed) = bodies(&arm, &truth, &estimate);
    let mut controller = controller(args, believed)?;
    let effects = (!truth.effects.is_empty()).then(|| truth.effects.clone());
    let plant = Plant::on(body, effects);
    let cfg = SimConfig {
        dt: args.dt,
        log_every: args.log_every,
        integrator: match args.integrator {
            IntegratorKind::Rk4 => Integrator::Rk4,
            IntegratorKind::ImplicitEuler => Integrator::LinearlyImplicitEuler,
        },
        ..SimConfig::default()
    };
    let mut log = simulate(&plant, controller.as_mut(), spec.as_dyn(), &cfg)?;
    let resolution = match args.encoder_counts {
        Some(counts) => Some(encoder_resolution(&arm.dh_table()?, counts)),
        None => None,
    };
    let mut rng = <rand_chacha::ChaCha8Rng as rand::SeedableRng>::seed_from_u64(args.seed);
    dynid::measurement::add_measurement_noise(
        n,
        &mut log.q,
        &mut log.tau,
        args.tau_noise,
        resolution.as_deref(),
        &mut rng,
    );
    write_log(args, &log, n)
}
