//! `dynid convert BAG.mcap (--arm A | --joints a,b,c) [--topic T] [--torque-scale k,..] [--out F]`:
//! a ROS 2 bag's joint states as the CSV `identify` and `torque` read (`t, q.., [dq..], [tau..]`).
//!
//! Also the one place that opens a data file for the other commands ([`open_log`]): a `.mcap`
//! bag through [`dynid::bag`] with the options of [`BagArgs`], anything else as CSV.

use std::path::{Path, PathBuf};

use anyhow::Result;

use crate::{write_output, InputError};
use dynid::arms::{resolve, ArmSource};
use dynid::bag::{self, BagError, BagOptions};
use dynid::data::{header, write_header, write_row};
use dynid::log::Log;

/// How a ROS 2 bag (`.mcap`) is read; shared by `convert`, `identify` and `torque`.
#[derive(Debug, Clone, Default, clap::Args)]
pub struct BagArgs {
    /// Bags: the sensor_msgs/msg/JointState topic (default: the only one in the bag).
    #[arg(long)]
    pub topic: Option<String>,
    /// Bags: the arm's joint names in the bag, in the arm's order, e.g. `shoulder,elbow`
    /// (default: the D-H table's joint `name`s, which `import-urdf` writes).
    #[arg(long)]
    pub joints: Option<String>,
    /// Torque = k · logged torque (a bag's effort, a CSV's tau) per joint, e.g. `0.5,0.5` for
    /// drives that log current, or the drive gains `dynid payload --mass` calibrates (default 1).
    #[arg(long)]
    pub torque_scale: Option<String>,
}

impl BagArgs {
    /// The options for an arm of `dof` joints; `file` names the bag in errors.
    fn options(&self, dof: usize, need_effort: bool, file: &Path) -> Result<BagOptions> {
        let torque_scale = self
            .torque_scale
            .as_deref()
            .map(|s| bag::parse_torque_scale(s, dof))
            .transpose()
            .map_err(|kind| BagError {
                file: file.display().to_string(),
                topic: None,
                message: None,
                kind: Box::new(kind),
            })?;
        Ok(BagOptions {
            topic: self.topic.clone(),
            joints: self.joints.as_deref().map(bag::parse_joints),
            torque_scale,
            need_effort,
            spill_rows: None,
        })
    }

    /// An error if a bag option was given for `path`, which is not a bag.
    pub fn reject_for_csv(&self, path: &Path) -> Result<(), InputError> {
        if self.topic.is_some() || self.joints.is_some() {
            return Err(InputError(format!(
                "{}: --topic and --joints are for ROS 2 bags (.mcap), and this is not one — drop them for a CSV",
                path.display()
            )));
        }
        Ok(())
    }
}

/// Opens a data file of `arm`: a ROS 2 bag (`.mcap`, its notes on stderr) or a CSV.
/// `need_effort`: the bag must carry the joint torque (identification).
pub fn open_log(
    path: &Path,
    arm: &ArmSource,
    bag_args: &BagArgs,
    need_effort: bool,
) -> Result<Log> {
    let dof = arm.dof();
    if !bag::is_bag(path) {
        bag_args.reject_for_csv(path)?;
        let log = Log::open(path, Some(dof))?;
        return Ok(match &bag_args.torque_scale {
            Some(s) => {
                let k = bag::parse_torque_scale(s, dof)
                    .map_err(|e| InputError(format!("--torque-scale: {e}")))?;
                log.scale_torque(&k)?
            }
            None => log,
        });
    }
    let names = arm.dh_table().ok().and_then(|t| t.joint_names());
    let opts = bag_args.options(dof, need_effort, path)?;
    let read = bag::read(path, dof, names, &opts)?;
    for n in &read.notes {
        eprintln!("{n}");
    }
    Ok(read.log)
}

#[derive(Debug, clap::Args)]
pub struct Args {
    /// The ROS 2 bag (.mcap) to read.
    pub bag: PathBuf,
    /// Arm name (see `dynid arms`) or path to a D-H table (.toml): its joint names (or
    /// --joints) pick the bag's joints.
    #[arg(long)]
    pub arm: Option<String>,
    /// Output CSV (default: stdout).
    #[arg(long)]
    pub out: Option<PathBuf>,
    #[command(flatten)]
    pub bag_args: BagArgs,
}

pub fn run(args: &Args) -> Result<()> {
    let (dof, names) = match (&args.arm, &args.bag_args.joints) {
        (Some(a), _) => {
            let arm = resolve(a)?;
            (arm.dof(), arm.dh_table().ok().and_then(|t| t.joint_names()))
        }
        (None, Some(j)) => (bag::parse_joints(j).len(), None),
        (None, None) => return Err(InputError(
            "convert: which joints? — pass --arm (a D-H table with joint names) or --joints a,b,c"
                .into(),
        )
        .into()),
    };
    let opts = args.bag_args.options(dof, false, &args.bag)?;
    let read = bag::read(&args.bag, dof, names, &opts)?;
    for n in &read.notes {
        eprintln!("{n}");
    }
    let log = read.log;
    let h = header(dof, log.layout.dq, false, log.layout.tau);
    write_output(args.out.as_deref(), |w| {
        writeln!(
            w,
            "# {} converted by dynid: joints {}",
            args.bag.display(),
            read.joints.join(", ")
        )?;
        write_header(w, &h)?;
        let mut res = Ok(());
        log.rows(0, log.len(), |row| {
            if res.is_ok() {
                res = write_row(w, row);
            }
        });
        res
    })
}
