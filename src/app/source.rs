//! Data sources of a request, opened for an arm: a file (CSV, `.csv.gz` or a ROS 2 bag) or a
//! table from memory (named columns and a row-major block of numbers: a Python array, dict or
//! DataFrame), with the reading options both front ends share (`topic`, `joints` and
//! `torque_scale`). A table is checked as the CSV it stands for ([`Trajectory::from_columns`]).

use std::path::PathBuf;

use super::{AppError, Front};
use crate::arms::ArmSource;
use crate::bag::{self, BagErrorKind, BagLog, BagOptions};
use crate::data::Trajectory;
use crate::log::Log;

/// One input of a request.
#[derive(Debug, Clone)]
pub enum DataSource<'a> {
    /// A file: CSV (plain or gzip) or, ending in `.mcap`, a ROS 2 bag.
    Path(PathBuf),
    /// `values` (`rows × names.len()`, row-major) under column names `names`; `label` names it
    /// in messages (`data (DataFrame)`).
    Table {
        label: String,
        names: Vec<String>,
        values: &'a [f64],
    },
}

impl DataSource<'_> {
    /// How messages name this source: the path, or the table's label.
    pub fn label(&self) -> String {
        match self {
            DataSource::Path(p) => p.display().to_string(),
            DataSource::Table { label, .. } => label.clone(),
        }
    }

    /// Reads a CSV file or a table of an arm of `dof` joints (no bags: commands that need
    /// every sample in memory at once).
    pub fn trajectory(&self, dof: usize) -> Result<Trajectory, AppError> {
        Ok(match self {
            DataSource::Path(p) => Trajectory::from_path(p, Some(dof))?,
            DataSource::Table {
                label,
                names,
                values,
            } => Trajectory::from_columns(label, names, values, Some(dof))?,
        })
    }

    fn is_bag(&self) -> bool {
        matches!(self, DataSource::Path(p) if bag::is_bag(p))
    }
}

/// A list option as a front end got it: the command line's comma-separated text, or a list.
#[derive(Debug, Clone)]
pub enum ListArg<T> {
    Text(String),
    Items(Vec<T>),
}

/// How data is read, as given (`--topic`, `--joints`, `--torque-scale`; Python's keywords).
#[derive(Debug, Clone, Default)]
pub struct ReadArgs {
    /// Bags: the `sensor_msgs/msg/JointState` topic (default: the only one).
    pub topic: Option<String>,
    /// Bags: the arm's joint names in the bag, in the arm's order (default: the D-H table's).
    pub joints: Option<ListArg<String>>,
    /// Torque = k · logged torque (a bag's effort, a table's or CSV's tau), one k per joint.
    pub torque_scale: Option<ListArg<f64>>,
}

/// [`ReadArgs`] checked for one arm: opens the sources of a request.
#[derive(Debug, Clone)]
pub struct Reader {
    front: Front,
    dof: usize,
    /// The D-H table's joint names (how a bag's joints are found without `joints`).
    names: Option<Vec<String>>,
    topic: Option<String>,
    joints: Option<Vec<String>>,
    torque_scale: Option<Vec<f64>>,
    need_effort: bool,
}

/// An opened log, and what the reader wants the user to know (a bag's time base and topic).
#[derive(Debug)]
pub struct Opened {
    pub log: Log,
    pub notes: Vec<String>,
}

impl ReadArgs {
    /// Checks the options for `arm`; `need_effort`: a bag must carry the joint torque.
    pub fn for_arm(
        &self,
        arm: &ArmSource,
        front: Front,
        need_effort: bool,
    ) -> Result<Reader, AppError> {
        let dof = arm.dof();
        let names = arm.dh_table().ok().and_then(|t| t.joint_names());
        self.reader(dof, names, front, need_effort)
    }

    /// Checks the options for an arm of `dof` joints whose D-H table names them `names`.
    pub fn reader(
        &self,
        dof: usize,
        names: Option<Vec<String>>,
        front: Front,
        need_effort: bool,
    ) -> Result<Reader, AppError> {
        let torque_scale = self
            .torque_scale
            .as_ref()
            .map(|k| torque_scale(k, dof, front))
            .transpose()?;
        Ok(Reader {
            front,
            dof,
            names,
            topic: self.topic.clone(),
            joints: self.joints.as_ref().map(|j| match j {
                ListArg::Text(s) => bag::parse_joints(s),
                ListArg::Items(v) => v.clone(),
            }),
            torque_scale,
            need_effort,
        })
    }
}

/// `torque_scale`: one finite factor per joint.
pub fn torque_scale(k: &ListArg<f64>, dof: usize, front: Front) -> Result<Vec<f64>, AppError> {
    let checked = match k {
        ListArg::Text(s) => bag::parse_torque_scale(s, dof).map_err(|e| match e {
            BagErrorKind::TorqueScale(m) => m,
            other => other.to_string(),
        }),
        ListArg::Items(v) => match v.iter().find(|x| !x.is_finite()) {
            Some(x) => Err(format!(
                "`{x}` is not a finite number — give one factor per joint, e.g. 0.1,0.1"
            )),
            None if v.len() != dof => Err(format!(
                "{} factors for an arm with {dof} joints — give one per joint",
                v.len()
            )),
            None => Ok(v.clone()),
        },
    };
    checked.map_err(|m| AppError::Input(format!("{}: {m}", front.name("torque_scale"))))
}

impl Reader {
    /// The arm's joint count.
    pub fn dof(&self) -> usize {
        self.dof
    }

    /// How a bag is read with these options (the whole bag when `spill_rows` is `None`).
    pub fn bag_options(&self) -> BagOptions {
        BagOptions {
            topic: self.topic.clone(),
            joints: self.joints.clone(),
            torque_scale: self.torque_scale.clone(),
            need_effort: self.need_effort,
            spill_rows: None,
        }
    }

    /// An error if a bag option was given for `src`, which is not a bag.
    pub fn reject_bag_options(&self, src: &DataSource) -> Result<(), AppError> {
        if (self.topic.is_some() || self.joints.is_some()) && !src.is_bag() {
            let what = match src {
                DataSource::Path(_) => "drop them for a CSV",
                DataSource::Table { .. } => "drop them for a table",
            };
            return Err(AppError::Input(format!(
                "{}: {} and {} are for ROS 2 bags (.mcap), and this is not one — {what}",
                src.label(),
                self.front.name("topic"),
                self.front.name("joints"),
            )));
        }
        Ok(())
    }

    /// Reads the ROS 2 bag at `path`.
    pub fn bag(&self, path: &std::path::Path) -> Result<BagLog, AppError> {
        Ok(bag::read(
            path,
            self.dof,
            self.names.clone(),
            &self.bag_options(),
        )?)
    }

    /// Opens `src` as a log: a bag through [`crate::bag`], a CSV or a table as a trajectory,
    /// its torque scaled by `torque_scale`.
    pub fn log(&self, src: &DataSource) -> Result<Opened, AppError> {
        self.reject_bag_options(src)?;
        let log = match src {
            DataSource::Path(p) if bag::is_bag(p) => {
                let read = self.bag(p)?;
                return Ok(Opened {
                    log: read.log,
                    notes: read.notes,
                });
            }
            DataSource::Path(p) => Log::open(p, Some(self.dof))?,
            DataSource::Table { .. } => Log::from(src.trajectory(self.dof)?),
        };
        let log = match &self.torque_scale {
            Some(k) => log.scale_torque(k)?,
            None => log,
        };
        Ok(Opened {
            log,
            notes: Vec::new(),
        })
    }
}
