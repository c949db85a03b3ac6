//! `dynid import-urdf ROBOT.urdf [--base LINK] [--tip LINK] [--gravity gx,gy,gz] [--name NAME] --out DIR [--json]`:
//! a URDF serial chain → `DIR/NAME.toml` (modified D-H table) + `DIR/NAME.params.toml`.
//! Notes and warnings go to stderr (or into the JSON with `--json`).

use std::path::PathBuf;

use anyhow::Result;
use serde::Serialize;

use dynid::urdf::{import_file, ImportOptions};

#[derive(Debug, clap::Args)]
pub struct Args {
    /// The URDF file (xacro files must be expanded first).
    pub urdf: PathBuf,
    /// First link of the chain, fixed to the ground (default: the URDF root link).
    #[arg(long, value_name = "LINK")]
    pub base: Option<String>,
    /// Last link of the chain (default: the end of the longest serial chain of movable joints).
    #[arg(long, value_name = "LINK")]
    pub tip: Option<String>,
    /// Gravitational acceleration in the URDF root frame, m/s² (default: 0,0,-9.81).
    #[arg(long, value_name = "GX,GY,GZ", value_parser = parse_gravity, allow_hyphen_values = true)]
    pub gravity: Option<[f64; 3]>,
    /// Arm name: file names NAME.toml and NAME.params.toml (default: the URDF file stem).
    #[arg(long)]
    pub name: Option<String>,
    /// Directory for the two files (created if missing).
    #[arg(long, value_name = "DIR")]
    pub out: PathBuf,
    /// Print a JSON summary (files, chain, notes, warnings) instead of text.
    #[arg(long)]
    pub json: bool,
}

fn parse_gravity(s: &str) -> Result<[f64; 3], String> {
    let v: Vec<f64> = s
        .split(',')
        .map(|x| x.trim().parse::<f64>().map_err(|e| format!("`{x}`: {e}")))
        .collect::<Result<_, _>>()?;
    match v.as_slice() {
        [x, y, z] if v.iter().all(|c| c.is_finite()) => Ok([*x, *y, *z]),
        _ => Err("expected three finite numbers gx,gy,gz in m/s², e.g. 0,0,-9.81".into()),
    }
}

#[derive(Serialize)]
struct Summary<'a> {
    name: &'a str,
    dof: usize,
    dh: String,
    params: String,
    chain: &'a [String],
    gravity: [f64; 3],
    notes: &'a [String],
    warnings: &'a [String],
}

pub fn run(args: &Args) -> Result<()> {
    let opts = ImportOptions {
        base: args.base.clone(),
        tip: args.tip.clone(),
        gravity: args.gravity,
        name: args.name.clone(),
    };
    let mut arm = import_file(&args.urdf, &opts)?;
    let source = dynid::urdf::roundtrip::UrdfSource {
        path: args.urdf.clone(),
        opts: opts.clone(),
    };
    arm.dh_toml.push_str(&source.table_text());
    let (dh, params) = arm.write(&args.out)?;
    if args.json {
        let summary = Summary {
            name: &arm.table.name,
            dof: arm.table.dof(),
            dh: dh.display().to_string(),
            params: params.display().to_string(),
            chain: &arm.chain,
            gravity: arm.table.gravity,
            notes: &arm.notes,
            warnings: &arm.warnings,
        };
        println!("{}", serde_json::to_string_pretty(&summary)?);
        return Ok(());
    }
    for n in &arm.notes {
        eprintln!("note: {n}");
    }
    for w in &arm.warnings {
        eprintln!("warning: {w}");
    }
    println!(
        "wrote {} ({} joints) and {}",
        dh.display(),
        arm.table.dof(),
        params.display()
    );
    println!(
        "use: dynid torque --arm {} --params {} --data DATA.csv; for generated kernels copy {} into arms/ and run cargo build",
        dh.display(),
        params.display(),
        dh.display()
    );
    Ok(())
}
