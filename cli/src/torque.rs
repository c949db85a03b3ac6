//! `dynid torque --arm A --params P --data D [--out F]`: inverse dynamics along a trajectory.
//!
//! A log without `dq`/`ddq` columns (a measured one) gets them from the estimator
//! `dynid identify` uses (`--cutoff`, `--derivative`; a `dq` column is filtered), evaluated at
//! the log's own sample times; the positions are then the filtered ones too, as in
//! identification's predictions "from estimated states".
//!
//! A registered arm uses its generated kernels (`base_params(p)`, then `inverse_dynamics`); a
//! path to a D-H table uses the reference recursive Newton–Euler. Effects from the parameter
//! file (`[effects]`) are added per joint. Output: CSV `t,tau1..taun`, atomically to `--out` or
//! to stdout. Everything is loaded and checked before anything is written.

use std::path::PathBuf;

use anyhow::Result;

use crate::{write_output, InputError};
use dynid::app::options::{self, CutoffArg};
use dynid::app::source::DataSource;
use dynid::app::Front;
use dynid::arms::{resolve, ArmSource};
use dynid::data::{write_header, write_row, Trajectory};
use dynid::params::{InertialParams, ParamsOptions};
use dynid::reference::RefModel;

#[derive(Debug, clap::Args)]
pub struct Args {
    /// Arm name (see `dynid arms`), path to a D-H table (.toml) or a URDF (.urdf, imported as `import-urdf` does).
    #[arg(long)]
    pub arm: String,
    /// Inertial parameters (TOML: one [[link]] per joint, optional [effects]).
    #[arg(long)]
    pub params: PathBuf,
    /// Trajectory CSV (or .csv.gz) with t, q and optionally dq, ddq columns; or a ROS 2 bag
    /// (.mcap) of sensor_msgs/msg/JointState.
    #[arg(long)]
    pub data: PathBuf,
    /// Output CSV (default: stdout).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Accept physically impossible inertial parameters (with a warning).
    #[arg(long)]
    pub allow_nonphysical: bool,
    /// Without dq/ddq columns: the estimator's low-pass cut-off in Hz, or `auto` (from the
    /// spectrum). Use the cut-off an identification report names to reproduce its predictions.
    #[arg(long, default_value = "auto")]
    pub cutoff: String,
    /// Without dq/ddq columns: the derivative estimator.
    #[arg(long, value_enum, default_value = "butterworth")]
    pub derivative: crate::identify::DerivativeArg,
    #[command(flatten)]
    pub bag: crate::convert::BagArgs,
}

pub fn run(args: &Args) -> Result<()> {
    let arm = resolve(&args.arm)?;
    let dof = arm.dof();
    let opts = ParamsOptions {
        allow_nonphysical: args.allow_nonphysical,
    };
    let params = InertialParams::from_path(&args.params, dof, &opts)?;
    for w in &params.warnings {
        eprintln!("warning: {w}");
    }
    let reader = args.bag.read_args().for_arm(&arm, Front::Cli, false)?;
    let src = DataSource::Path(args.data.clone());
    let mut traj = if dynid::bag::is_bag(&args.data) {
        let opened = reader.log(&src)?;
        for n in &opened.notes {
            eprintln!("{n}");
        }
        opened.log.read(0, opened.log.len())
    } else {
        reader.reject_bag_options(&src)?;
        Trajectory::from_path(&args.data, Some(dof))?
    };
    if traj.dq.is_none() || traj.ddq.is_none() {
        estimate_states(&mut traj, args)?;
    }
    traj.require(true, true, false, "inverse dynamics")?;

    let tau = torques(&arm, &params, &traj);
    let header = std::iter::once("t".to_string())
        .chain((1..=dof).map(|j| format!("tau{j}")))
        .collect::<Vec<_>>();
    write_output(args.out.as_deref(), |w| {
        write_header(w, &header)?;
        let mut row = vec![0.0; dof + 1];
        for k in 0..traj.len() {
            row[0] = traj.t[k];
            row[1..].copy_from_slice(&tau[k * dof..(k + 1) * dof]);
            write_row(w, &row)?;
        }
        Ok(())
    })
}

/// Replaces `q` by its filtered estimate and fills `dq`, `ddq` at the log's sample times.
fn estimate_states(traj: &mut Trajectory, args: &Args) -> Result<()> {
    let cutoff = CutoffArg::Text(args.cutoff.clone());
    let opts = options::derivative(args.derivative.name(), &cutoff, Front::Cli)?;
    let n = traj.dof;
    let cols = |v: &[f64]| -> Vec<Vec<f64>> {
        (0..n)
            .map(|j| v.iter().skip(j).step_by(n).copied().collect())
            .collect()
    };
    let q = cols(&traj.q);
    let dq = traj.dq.as_deref().map(cols);
    let est = dynid::derivative::estimate(&traj.t, &q, dq.as_deref(), &opts)
        .map_err(|e| InputError(format!("{}: {e}", args.data.display())))?;
    eprintln!(
        "{}: no q̇/q̈ columns — estimated with {} (cut-off {:.4} Hz{})",
        args.data.display(),
        est.report.filter,
        est.report.cutoff_hz,
        if est.report.cutoff_auto {
            ", automatic"
        } else {
            ""
        }
    );
    let len = traj.len();
    let (mut qs, mut dqs, mut ddqs) = (vec![0.0; len * n], vec![0.0; len * n], vec![0.0; len * n]);
    for (k, &t) in traj.t.iter().enumerate() {
        for j in 0..n {
            (qs[k * n + j], dqs[k * n + j], ddqs[k * n + j]) = est.at(j, t);
        }
    }
    traj.q = qs;
    traj.dq = Some(dqs);
    traj.ddq = Some(ddqs);
    Ok(())
}

/// Joint torques for every sample (row-major), effects included.
fn torques(arm: &ArmSource, params: &InertialParams, traj: &Trajectory) -> Vec<f64> {
    let dof = traj.dof;
    let p = params.full_vector();
    let mut tau = vec![0.0; traj.len() * dof];
    let (Some(dq), Some(ddq)) = (traj.dq.as_ref(), traj.ddq.as_ref()) else {
        return tau;
    };
    let rows = |k: usize| (k * dof)..((k + 1) * dof);
    match arm {
        ArmSource::Generated(m) => {
            let mut theta = vec![0.0; m.nb()];
            m.base_params(&p, &mut theta);
            for k in 0..traj.len() {
                let r = rows(k);
                m.inverse_dynamics(
                    &traj.q[r.clone()],
                    &dq[r.clone()],
                    &ddq[r.clone()],
                    &theta,
                    &mut tau[r],
                );
            }
        }
        ArmSource::Table(table) => {
            let model = RefModel::new(table);
            let mut ws = model.workspace();
            for k in 0..traj.len() {
                let r = rows(k);
                model.inverse_dynamics(
                    &mut ws,
                    &traj.q[r.clone()],
                    &dq[r.clone()],
                    &ddq[r.clone()],
                    &p,
                    &mut tau[r],
                );
            }
        }
    }
    if !params.effects.is_empty() {
        for k in 0..traj.len() {
            for j in 0..dof {
                let i = k * dof + j;
                let e = &params.effects;
                tau[i] = e.load(j, dq[i], tau[i] + e.torque(j, traj.q[i], dq[i], ddq[i]));
            }
        }
    }
    tau
}
