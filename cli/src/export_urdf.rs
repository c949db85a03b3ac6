//! `dynid export-urdf --arm A [--params P] [--out FILE]`: a D-H arm as a URDF (links are the D-H
//! frames). Written atomically to `--out`, or to stdout.

use std::path::PathBuf;

use anyhow::Result;

use crate::write_output;
use dynid::arms::resolve;
use dynid::params::{InertialParams, ParamsOptions};

#[derive(Debug, clap::Args)]
pub struct Args {
    /// Arm name (see `dynid arms`), path to a D-H table (.toml) or a URDF (.urdf, imported as `import-urdf` does).
    #[arg(long)]
    pub arm: String,
    /// Inertial parameters (TOML); without it the links are massless.
    #[arg(long)]
    pub params: Option<PathBuf>,
    /// Output URDF (default: stdout).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Accept physically impossible inertial parameters (with a warning).
    #[arg(long)]
    pub allow_nonphysical: bool,
}

pub fn run(args: &Args) -> Result<()> {
    let table = resolve(&args.arm)?.dh_table()?;
    let params = match &args.params {
        Some(path) => {
            let opts = ParamsOptions {
                allow_nonphysical: args.allow_nonphysical,
            };
            let p = InertialParams::from_path(path, table.dof(), &opts)?;
            for w in &p.warnings {
                eprintln!("warning: {w}");
            }
            // URDF's <dynamics damping friction> carries viscous and Coulomb friction only.
            let dropped: Vec<&str> = p
                .effects
                .arrays()
                .into_iter()
                .filter(|(k, v)| {
                    v.is_some() && !["viscous", "coulomb", "stribeck_velocity"].contains(k)
                })
                .map(|(k, _)| k)
                .collect();
            if !dropped.is_empty() {
                eprintln!(
                    "note: viscous and Coulomb friction are exported as <dynamics damping friction>; URDF has no place for {} — they are not exported",
                    dropped.join(", ")
                );
            }
            Some(p)
        }
        None => None,
    };
    let text = dynid::urdf::export(&table, params.as_ref())?;
    write_output(args.out.as_deref(), |w| w.write_all(text.as_bytes()))
}
