//! `dynid convert BAG.mcap (--arm A | --joints a,b,c) [--topic T] [--torque-scale k,..] [--out F]`:
//! a ROS 2 bag's joint states as the CSV `identify` and `torque` read (`t, q.., [dq..], [tau..]`).
//!
//! Also the flags of how a data file is read ([`BagArgs`]), shared by `convert`, `identify` and
//! `torque`; the reading itself is [`dynid::app::source`]'s.

use std::path::PathBuf;

use anyhow::Result;

use crate::write_output;
use dynid::app::convert::read_bag;
use dynid::app::source::{ListArg, ReadArgs};
use dynid::app::Front;
use dynid::arms::resolve;
use dynid::data::{header, write_header, write_row};

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
    /// The flags as the application layer's reading options.
    pub fn read_args(&self) -> ReadArgs {
        ReadArgs {
            topic: self.topic.clone(),
            joints: self.joints.clone().map(ListArg::Text),
            torque_scale: self.torque_scale.clone().map(ListArg::Text),
        }
    }
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
    let arm = args.arm.as_deref().map(resolve).transpose()?;
    let read = read_bag(
        &args.bag,
        arm.as_ref(),
        &args.bag_args.read_args(),
        Front::Cli,
    )?;
    for n in &read.notes {
        eprintln!("{n}");
    }
    let log = read.log;
    let h = header(log.dof(), log.layout.dq, false, log.layout.tau);
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
