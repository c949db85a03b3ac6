//! `convert`: a ROS 2 bag's joint states as a log (the CLI writes it as the CSV `identify` and
//! `torque` read). The bag's joints are the arm's (its D-H table's joint names, or `joints`).

use std::path::Path;

use super::source::{ListArg, ReadArgs};
use super::{AppError, Front};
use crate::arms::ArmSource;
use crate::bag::{self, BagLog};

/// Reads the bag at `path` for `arm`, or for the joints `read.joints` names when there is no arm.
pub fn read_bag(
    path: &Path,
    arm: Option<&ArmSource>,
    read: &ReadArgs,
    front: Front,
) -> Result<BagLog, AppError> {
    let reader = match (arm, &read.joints) {
        (Some(a), _) => read.for_arm(a, front, false)?,
        (None, Some(j)) => {
            let dof = match j {
                ListArg::Text(s) => bag::parse_joints(s).len(),
                ListArg::Items(v) => v.len(),
            };
            read.reader(dof, None, front, false)?
        }
        (None, None) => {
            return Err(AppError::Input(format!(
                "convert: which joints? — pass {} (a D-H table with joint names) or {} a,b,c",
                front.name("arm"),
                front.name("joints")
            )))
        }
    };
    reader.bag(path)
}
