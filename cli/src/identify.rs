//! `dynid identify --arm A --data TRAIN [--data TRAIN2 ...] [--validate VAL] [--effects auto|none|LIST] [--out DIR]`:
//! identify base parameters, find missing effects, write `report.md`, plots, `report.json` and
//! (with `--validate`) `validation_prediction.csv`.
//!
//! With `--leave-one-out` every `--data` file in turn is held out for validation and the others
//! are fitted; each fold's report goes to `DIR/heldout_<file>/` and the summary table to
//! `DIR/leave_one_out.md` / `.json`. Everything is computed before anything is written.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result};

use crate::InputError;
use dynid::arms::resolve;
use dynid::derivative::Method;
use dynid::effects::parse_list;
use dynid::identify::{self, Config, Outcome};
use dynid::log::Log;

#[derive(Debug, clap::Args)]
pub struct Args {
    /// Arm name (see `dynid arms`), path to a D-H table (.toml) or a URDF (.urdf, imported as `import-urdf` does).
    #[arg(long)]
    pub arm: String,
    /// Training data (CSV or .csv.gz: t, q, [dq], [ddq], tau; or a ROS 2 bag, .mcap, of
    /// sensor_msgs/msg/JointState); repeat for several files.
    #[arg(long, required = true)]
    pub data: Vec<PathBuf>,
    /// Validation data (same format), judged with the fitted models.
    #[arg(long)]
    pub validate: Option<PathBuf>,
    /// `auto` (search), `none` (rigid body only) or a list such as `viscous,coulomb:2`.
    #[arg(long, default_value = "auto")]
    pub effects: String,
    /// Output directory.
    #[arg(long, default_value = "identify_out")]
    pub out: PathBuf,
    /// Low-pass cut-off in Hz, or `auto` (held-out error scan over spectrum-based candidates).
    #[arg(long, default_value = "auto")]
    pub cutoff: String,
    /// Regression filter and prediction: `auto` (chosen with the cut-off by held-out error) or
    /// RATIO,PREDICTION: the regression (parallel) filter's cut-off over the derivative
    /// filter's, and whether models predict from the estimated `states` or the `filtered` rows,
    /// e.g. `0.5,filtered`.
    #[arg(long, default_value = "auto")]
    pub smoothing: String,
    /// Derivative estimator.
    #[arg(long, value_enum, default_value = "butterworth")]
    pub derivative: DerivativeArg,
    /// Differentiate q even when the file has a dq column.
    #[arg(long)]
    pub ignore_file_velocity: bool,
    /// Rotate through the --data files, holding each out for validation in turn.
    #[arg(long)]
    pub leave_one_out: bool,
    /// The physically consistent estimate (every link a possible rigid body, friction and rotor
    /// inertia >= 0), reported beside least squares and written as identified.params.toml /
    /// identified.urdf: `on` or `off`.
    #[arg(long, default_value = "on", value_parser = ["on", "off"])]
    pub physical: String,
    /// Fail (exit 2, nothing written) when the data cannot identify something (a joint that
    /// barely moves); without it such findings are warnings in the summary and the report.
    #[arg(long)]
    pub strict: bool,
    /// Parameters (params TOML, e.g. the CAD values `import-urdf` writes) that the consistent
    /// estimate is pulled towards where the data cannot decide; default: towards zero.
    #[arg(long)]
    pub prior: Option<PathBuf>,
    #[command(flatten)]
    pub bag: crate::convert::BagArgs,
}

#[derive(Debug, Clone, Copy, clap::ValueEnum)]
pub enum DerivativeArg {
    /// Zero-phase 4th-order Butterworth + central differences.
    Butterworth,
    /// Savitzky–Golay (quintic) matched to the cut-off.
    Savgol,
}

impl DerivativeArg {
    pub fn method(self) -> Method {
        match self {
            DerivativeArg::Butterworth => Method::Butterworth,
            DerivativeArg::Savgol => Method::SavitzkyGolay,
        }
    }
}

/// `--cutoff`: a positive number of Hz, or `auto` (`None`).
pub fn parse_cutoff(s: &str) -> Result<Option<f64>, InputError> {
    match s.trim() {
        "auto" => Ok(None),
        s => match s.parse::<f64>() {
            Ok(f) if f.is_finite() && f > 0.0 => Ok(Some(f)),
            _ => Err(InputError(format!(
                "--cutoff: `{s}` is not a positive number of Hz or `auto`"
            ))),
        },
    }
}

fn command_line(args: &Args) -> String {
    let mut c = format!("dynid identify --arm {}", args.arm);
    for d in &args.data {
        let _ = write!(c, " --data {}", d.display());
    }
    if let Some(v) = &args.validate {
        let _ = write!(c, " --validate {}", v.display());
    }
    let _ = write!(
        c,
        " --effects {} --cutoff {} --smoothing {} --out {}",
        args.effects,
        args.cutoff,
        args.smoothing,
        args.out.display()
    );
    if matches!(args.derivative, DerivativeArg::Savgol) {
        c += " --derivative savgol";
    }
    if args.ignore_file_velocity {
        c += " --ignore-file-velocity";
    }
    if args.leave_one_out {
        c += " --leave-one-out";
    }
    if args.physical == "off" {
        c += " --physical off";
    }
    if let Some(p) = &args.prior {
        let _ = write!(c, " --prior {}", p.display());
    }
    if args.strict {
        c += " --strict";
    }
    for (flag, v) in [
        ("--topic", &args.bag.topic),
        ("--joints", &args.bag.joints),
        ("--torque-scale", &args.bag.torque_scale),
    ] {
        if let Some(v) = v {
            let _ = write!(c, " {flag} {v}");
        }
    }
    c
}

/// Prints the outcomes' identifiability warnings; with `--strict` they are an error.
fn check_warnings(args: &Args, outs: &[&Outcome]) -> Result<()> {
    let mut all: Vec<&String> = outs.iter().flat_map(|o| &o.warnings).collect();
    all.dedup();
    if args.strict && !all.is_empty() {
        let list: Vec<String> = all.iter().map(|w| format!("  - {w}")).collect();
        return Err(InputError(format!(
            "--strict: the data cannot identify everything:\n{}",
            list.join("\n")
        ))
        .into());
    }
    for w in all {
        eprintln!("warning: {w}");
    }
    Ok(())
}

pub fn run(args: &Args) -> Result<()> {
    let arm = resolve(&args.arm)?;
    let dof = arm.dof();
    let effects = parse_list(&args.effects, dof).map_err(InputError)?;
    let cutoff_hz = parse_cutoff(&args.cutoff)?;
    let smoothing = match args.smoothing.trim() {
        "auto" => None,
        s => Some(
            identify::Smoothing::parse(s).map_err(|e| InputError(format!("--smoothing: {e}")))?,
        ),
    };
    // On a terminal: the stage and the scan's cut-offs (or the folds) on stderr; nothing elsewhere.
    let (bar, progress) = crate::bar::Bar::start();
    let cfg = Config {
        progress,
        smoothing,
        derivative: dynid::derivative::Options {
            method: args.derivative.method(),
            cutoff_hz,
        },
        file_velocity: !args.ignore_file_velocity,
        effects,
        physical: physical_options(args, dof)?,
        ..Config::default()
    };
    let load = |p: &Path| crate::convert::open_log(p, &arm, &args.bag, true);
    let train: Vec<Log> = args
        .data
        .iter()
        .map(|p| load(p))
        .collect::<Result<_, _>>()?;
    let command = command_line(args);
    let bad = |e: identify::IdentifyError| -> anyhow::Error {
        match e {
            identify::IdentifyError::Data(d) => d.into(),
            other => InputError(other.to_string()).into(),
        }
    };
    if args.leave_one_out {
        if train.len() < 2 || args.validate.is_some() {
            return Err(InputError(
                "--leave-one-out needs at least two --data files and no --validate".into(),
            )
            .into());
        }
        let outs = identify::leave_one_out(&arm, train, &cfg).map_err(bad);
        bar.finish_and_clear();
        let outs = outs?;
        check_warnings(args, &outs.iter().collect::<Vec<_>>())?;
        let table = arm.dh_table().ok();
        let summary =
            dynid::report::leave_one_out::write(&args.out, &outs, &command, table.as_ref())
                .context("writing the leave-one-out report")?;
        print!("{summary}");
        return Ok(());
    }
    let val = args.validate.as_deref().map(load).transpose()?;
    let outcome = identify::run(&arm, train, val, &cfg).map_err(bad);
    bar.finish_and_clear();
    let outcome = outcome?;
    check_warnings(args, &[&outcome])?;
    let table = arm.dh_table().ok();
    let files = dynid::report::write(&args.out, &outcome, &command, table.as_ref())
        .context("writing the report")?;
    write_roundtrip(args, &outcome)?;
    print_summary(&outcome);
    eprintln!("wrote {} files to {}", files.len(), args.out.display());
    Ok(())
}

/// An arm from a URDF: `identified.urdf` is that URDF with the identified inertials.
fn write_roundtrip(args: &Args, outcome: &Outcome) -> Result<()> {
    let Some(source) = dynid::arms::urdf_source(&args.arm).map_err(InputError)? else {
        return Ok(());
    };
    let Some(rt) = dynid::report::physical::urdf_roundtrip(outcome, &source) else {
        return Ok(());
    };
    let rt = rt.context("writing identified.urdf into the arm's URDF")?;
    for n in &rt.notes {
        eprintln!("note: identified.urdf: {n}");
    }
    let path = args.out.join("identified.urdf");
    dynid::io::atomic_write(&path, |w| w.write_all(rt.urdf.as_bytes()))
        .with_context(|| format!("writing {}", path.display()))?;
    Ok(())
}

/// `--physical` and `--prior`: the prior must be a physically consistent params file of this arm.
fn physical_options(args: &Args, dof: usize) -> Result<identify::physical::PhysicalOptions> {
    let prior = match &args.prior {
        Some(path) => {
            let p = dynid::params::InertialParams::from_path(
                path,
                dof,
                &dynid::params::ParamsOptions::default(),
            )
            .map_err(|e| {
                InputError(format!(
                    "--prior: {e} — the prior must be a physically consistent parameter file of this arm"
                ))
            })?;
            Some(p.full_vector())
        }
        None => None,
    };
    if prior.is_some() && args.physical == "off" {
        return Err(InputError(
            "--prior needs the consistent estimate: drop `--physical off`".into(),
        )
        .into());
    }
    Ok(identify::physical::PhysicalOptions {
        enabled: args.physical == "on",
        prior,
        prior_source: args.prior.as_ref().map(|p| format!("`{}`", p.display())),
    })
}

fn print_summary(o: &Outcome) {
    let found: Vec<String> = o.selection.steps.iter().map(|s| s.label.clone()).collect();
    println!(
        "effects found: {}",
        if found.is_empty() {
            "none".into()
        } else {
            found.join(", ")
        }
    );
    let show = |label: &str, r: &identify::ModelResult| {
        let v = r.validation.as_ref().map_or(String::new(), |v| {
            format!(", validation {:.2} %", 100.0 * v.overall)
        });
        println!("{label}: training {:.2} %{v}", 100.0 * r.train.overall);
    };
    show("before (rigid)", &o.before);
    show("after", &o.after);
    if let Some(c) = &o.consistent {
        show("physically consistent", c);
    }
    println!("{}", dynid::report::physical::verdict(o).replace("**", ""));
    if let Some(f) = o.train.first() {
        println!(
            "filters: cut-off {:.2} Hz, {}",
            f.derivative.cutoff_hz,
            f.smoothing.label()
        );
    }
}
