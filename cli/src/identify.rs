//! `dynid identify --arm A --data TRAIN [--data TRAIN2 ...] [--validate VAL] [--effects auto|none|LIST] [--out DIR]`:
//! identify base parameters, find missing effects, write `report.md`, plots, `report.json` and
//! (with `--validate`) `validation_prediction.csv`.
//!
//! With `--leave-one-out` every `--data` file in turn is held out for validation and the others
//! are fitted; each fold's report goes to `DIR/heldout_<file>/` and the summary table to
//! `DIR/leave_one_out.md` / `.json`. Everything is computed before anything is written.

use std::fmt::Write as _;
use std::path::PathBuf;

use anyhow::Result;

use crate::InputError;
use dynid::app::identify::{write_leave_one_out, IdentifyArgs};
use dynid::app::options::CutoffArg;
use dynid::app::source::DataSource;
use dynid::app::Front;
use dynid::arms::resolve;
use dynid::identify::{self, Outcome};

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
    /// `auto` (search), `none` (rigid body only) or a list such as `viscous,coulomb:2`
    /// (`run_offset:2@3`: the third training file's torque offset on joint 2 over the first's).
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
    /// Coulomb friction's smoothing, tanh(q̇ / v): `auto` (v chosen by held-out error from 0.3 %,
    /// 1 % and 3 % of each joint's RMS velocity) or that fraction, e.g. `0.01`.
    #[arg(long, default_value = "auto")]
    pub coulomb_width: String,
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
    /// The estimator's name in the application layer's requests.
    pub fn name(self) -> &'static str {
        match self {
            DerivativeArg::Butterworth => "butterworth",
            DerivativeArg::Savgol => "savgol",
        }
    }
}

impl Args {
    /// The flags as the application layer's options.
    fn app_args(&self) -> IdentifyArgs {
        IdentifyArgs {
            effects: self.effects.clone(),
            cutoff: CutoffArg::Text(self.cutoff.clone()),
            smoothing: self.smoothing.clone(),
            coulomb_width: self.coulomb_width.clone(),
            derivative: self.derivative.name().into(),
            file_velocity: !self.ignore_file_velocity,
            physical: self.physical == "on",
            prior: self.prior.clone(),
            strict: self.strict,
            leave_one_out: self.leave_one_out,
            read: self.bag.read_args(),
        }
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
    if args.coulomb_width != "auto" {
        let _ = write!(c, " --coulomb-width {}", args.coulomb_width);
    }
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

pub fn run(args: &Args) -> Result<()> {
    let arm = resolve(&args.arm)?;
    let request =
        args.app_args()
            .request(&arm, args.data.len(), args.validate.is_some(), Front::Cli)?;
    // On a terminal: the stage and the scan's cut-offs (or the folds) on stderr; nothing elsewhere.
    let (bar, progress) = crate::bar::Bar::start();
    let request = request.with_progress(progress);
    let train: Vec<DataSource> = args.data.iter().cloned().map(DataSource::Path).collect();
    let command = command_line(args);
    if args.leave_one_out {
        let outs = request.leave_one_out(&arm, &train);
        bar.finish_and_clear();
        let folds = outs?;
        print_notes(&folds.notes, &folds.warnings);
        let summary = write_leave_one_out(&args.out, &folds.outs, &command, &arm)?;
        print!("{summary}");
        return Ok(());
    }
    let val = args.validate.clone().map(DataSource::Path);
    let identified = request.run(&arm, &train, val.as_ref());
    bar.finish_and_clear();
    let identified = identified?;
    print_notes(&identified.notes, &identified.warnings);
    let urdf = dynid::arms::urdf_source(&args.arm).map_err(InputError)?;
    let written = identified.write(&args.out, &command, &arm, urdf.as_ref())?;
    for n in &written.notes {
        eprintln!("note: {n}");
    }
    print_summary(&identified.outcome);
    eprintln!(
        "wrote {} files to {}",
        written.files.len(),
        args.out.display()
    );
    Ok(())
}

/// The readers' notes and the warnings (what the data cannot identify), on stderr.
fn print_notes(notes: &[String], warnings: &[String]) {
    for n in notes {
        eprintln!("{n}");
    }
    for w in warnings {
        eprintln!("warning: {w}");
    }
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
