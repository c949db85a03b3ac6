//! `payload` as both front ends run it: [`PayloadArgs`] (flags or keywords) checked once into a
//! [`PayloadRequest`] (the arm's table, its identified parameters, the library's options),
//! which reads the runs and estimates the flange payload ([`PayloadEstimate`]: the CLI writes
//! it, Python returns it).

use std::path::{Path, PathBuf};

use super::options::{self, CutoffArg};
use super::source::{torque_scale, DataSource, ListArg};
use super::{AppError, Front};
use crate::arms::ArmSource;
use crate::data::Trajectory;
use crate::dh::DhTable;
use crate::params::{InertialParams, ParamsOptions};
use crate::payload::{
    identify_payload_with, output, PayloadError, PayloadEstimate, PayloadOptions,
};
use crate::progress::Progress;
use crate::urdf::roundtrip::UrdfSource;

/// The options of `payload` as a front end got them (Python's keyword names).
#[derive(Debug, Clone)]
pub struct PayloadArgs {
    /// The identified arm (`identified.params.toml` of `identify`).
    pub params: PathBuf,
    /// The payload's known mass (kg): then only its centre of mass and inertia, and the drive
    /// gains.
    pub mass: Option<f64>,
    /// Multiply the data's torque by these per joint.
    pub torque_scale: Option<ListArg<f64>>,
    /// Without dq/ddq columns: the estimator's cut-off and name.
    pub cutoff: CutoffArg,
    pub derivative: String,
}

/// A checked payload estimation: runs on sources.
#[derive(Debug, Clone)]
pub struct PayloadRequest {
    table: DhTable,
    /// The identified arm the payload is added to.
    pub params: InertialParams,
    opts: PayloadOptions,
}

impl PayloadArgs {
    /// Checks every option for `arm` and reads its identified parameters.
    pub fn request(&self, arm: &ArmSource, front: Front) -> Result<PayloadRequest, AppError> {
        let table = arm
            .dh_table()
            .map_err(|e| AppError::step("the arm's D-H table", e))?;
        let dof = table.dof();
        let params = InertialParams::from_path(&self.params, dof, &ParamsOptions::default())?;
        let torque_scale = self
            .torque_scale
            .as_ref()
            .map(|k| torque_scale(k, dof, front))
            .transpose()?;
        let opts = PayloadOptions {
            mass: self.mass,
            torque_scale,
            derivative: options::derivative(&self.derivative, &self.cutoff, front)?,
        };
        Ok(PayloadRequest {
            table,
            params,
            opts,
        })
    }
}

impl PayloadRequest {
    /// Estimates the payload from the `loaded` runs and, when given, one unloaded twin each.
    pub fn run(
        &self,
        loaded: &[DataSource],
        unloaded: &[DataSource],
        progress: &Progress,
    ) -> Result<PayloadEstimate, AppError> {
        let dof = self.table.dof();
        let read = |s: &[DataSource]| -> Result<Vec<Trajectory>, AppError> {
            s.iter().map(|x| x.trajectory(dof)).collect()
        };
        let (loaded, unloaded) = (read(loaded)?, read(unloaded)?);
        identify_payload_with(
            &self.table,
            &self.params,
            loaded,
            unloaded,
            &self.opts,
            progress,
        )
        .map_err(|e| match e {
            PayloadError::Numerical(m) => AppError::Failed(m),
            e => AppError::Input(e.to_string()),
        })
    }

    /// Writes payload.json, payload.params.toml, loaded.params.toml, report.md and (for an arm
    /// read from a URDF, `urdf`) payload.urdf into `dir`; `command` reproduces the run.
    pub fn write(
        &self,
        dir: &Path,
        est: &PayloadEstimate,
        urdf: Option<&UrdfSource>,
        command: &str,
    ) -> Result<Vec<PathBuf>, AppError> {
        output::write_all(dir, est, &self.params, urdf, command).map_err(AppError::Failed)
    }
}
