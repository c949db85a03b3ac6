//! `dynid payload --arm A --params P --data LOADED.csv [--unloaded TWIN.csv] [--mass M]
//! [--torque-scale s1,..] --out DIR`: the flange payload's inertial parameters (and, with
//! `--mass`, the drive gains); all logic is in [`dynid::payload`].

use std::fmt::Write as _;
use std::path::PathBuf;

use anyhow::Result;

use crate::InputError;
use dynid::app::options::CutoffArg;
use dynid::app::payload::PayloadArgs;
use dynid::app::source::{DataSource, ListArg};
use dynid::app::Front;
use dynid::arms::resolve;

#[derive(Debug, clap::Args)]
pub struct Args {
    /// Arm name (see `dynid arms`), D-H table (.toml) or URDF (.urdf).
    #[arg(long)]
    pub arm: String,
    /// The identified arm (identified.params.toml of `dynid identify`).
    #[arg(long)]
    pub params: PathBuf,
    /// Runs with the payload (CSV: t, q, [dq, ddq], tau); repeat for several.
    #[arg(long, required = true)]
    pub data: Vec<PathBuf>,
    /// The same motions without the payload, one per --data in the same order (aligned in time
    /// automatically); without them the arm model explains the unloaded torque.
    #[arg(long)]
    pub unloaded: Vec<PathBuf>,
    /// The payload's known mass in kg: estimate only its centre of mass and inertia, and the
    /// drive gains (torque_scale).
    #[arg(long)]
    pub mass: Option<f64>,
    /// Multiply the data's torque by these per joint, e.g. `1.02,0.98,1,1,1,1`.
    #[arg(long)]
    pub torque_scale: Option<String>,
    /// Without dq/ddq columns: the estimator's low-pass cut-off in Hz, or `auto`.
    #[arg(long, default_value = "auto")]
    pub cutoff: String,
    /// Without dq/ddq columns: the derivative estimator.
    #[arg(long, value_enum, default_value = "butterworth")]
    pub derivative: crate::identify::DerivativeArg,
    /// Output directory.
    #[arg(long, default_value = "payload_out")]
    pub out: PathBuf,
}

fn command(args: &Args) -> String {
    let mut c = format!(
        "dynid payload --arm {} --params {}",
        args.arm,
        args.params.display()
    );
    for d in &args.data {
        let _ = write!(c, " --data {}", d.display());
    }
    for d in &args.unloaded {
        let _ = write!(c, " --unloaded {}", d.display());
    }
    if let Some(m) = args.mass {
        let _ = write!(c, " --mass {m}");
    }
    if let Some(s) = &args.torque_scale {
        let _ = write!(c, " --torque-scale {s}");
    }
    c
}

pub fn run(args: &Args) -> Result<()> {
    let arm = resolve(&args.arm)?;
    let request = PayloadArgs {
        params: args.params.clone(),
        mass: args.mass,
        torque_scale: args.torque_scale.clone().map(ListArg::Text),
        cutoff: CutoffArg::Text(args.cutoff.clone()),
        derivative: args.derivative.name().into(),
    }
    .request(&arm, Front::Cli)?;
    let paths =
        |p: &[PathBuf]| -> Vec<DataSource> { p.iter().cloned().map(DataSource::Path).collect() };
    let progress = crate::bar::Bars::progress();
    let est = request.run(&paths(&args.data), &paths(&args.unloaded), &progress)?;
    let source = dynid::arms::urdf_source(&args.arm).map_err(InputError)?;
    let files = request.write(&args.out, &est, source.as_ref(), &command(args))?;
    for w in &est.warnings {
        eprintln!("warning: {w}");
    }
    eprintln!(
        "payload: {:.4} kg (σ {:.2e}) at [{:.1}, {:.1}, {:.1}] mm (σ [{:.1}, {:.1}, {:.1}])",
        est.mass,
        est.sigma.mass,
        1e3 * est.com[0],
        1e3 * est.com[1],
        1e3 * est.com[2],
        1e3 * est.sigma.com[0],
        1e3 * est.sigma.com[1],
        1e3 * est.sigma.com[2]
    );
    if let Some(k) = &est.torque_scale {
        let list: Vec<String> = k.iter().map(|v| format!("{v:.4}")).collect();
        eprintln!("torque_scale: {}", list.join(","));
    }
    eprintln!("wrote {} files to {}", files.len(), args.out.display());
    Ok(())
}
