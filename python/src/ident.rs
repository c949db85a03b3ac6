//! `dynid.identify`: the application layer's `identify` on files or arrays. The keywords become
//! its [`IdentifyArgs`] (checked there, with the CLI's messages in Python's spelling); the
//! report comes back as the dict `report.json` holds, built from the Rust values.

use std::path::PathBuf;

use dynid::app::identify::IdentifyArgs;
use dynid::app::source::{ListArg, ReadArgs};
use dynid::app::Front;
use pyo3::prelude::*;

use crate::source::{err, sources, urdf, Cutoff, DataArg};
use crate::Arm;

/// The native part of ``dynid.identify``: ``(report, files_written, warnings)``, the report as
/// the dict of ``report.json``.
#[pyfunction]
#[pyo3(signature = (arm, train, validate, effects, cutoff, smoothing, coulomb_width, derivative, file_velocity, physical, prior, strict, out, command, topic, joints, torque_scale))]
#[allow(clippy::too_many_arguments)]
pub fn _identify<'py>(
    py: Python<'py>,
    arm: &Arm,
    train: Vec<DataArg<'py>>,
    validate: Option<DataArg<'py>>,
    effects: String,
    cutoff: Cutoff,
    smoothing: String,
    coulomb_width: String,
    derivative: String,
    file_velocity: bool,
    physical: bool,
    prior: Option<PathBuf>,
    strict: bool,
    out: Option<PathBuf>,
    command: String,
    topic: Option<String>,
    joints: Option<Vec<String>>,
    torque_scale: Option<Vec<f64>>,
) -> PyResult<(Bound<'py, PyAny>, Vec<String>, Vec<String>)> {
    let args = IdentifyArgs {
        effects,
        cutoff: cutoff.arg(),
        smoothing,
        coulomb_width,
        derivative,
        file_velocity,
        physical,
        prior,
        strict,
        leave_one_out: false,
        read: ReadArgs {
            topic,
            joints: joints.map(ListArg::Items),
            torque_scale: torque_scale.map(ListArg::Items),
        },
    };
    let train = sources(&train)?;
    let val = validate
        .as_ref()
        .map(|v| sources(std::slice::from_ref(v)))
        .transpose()?;
    let val = val.as_ref().and_then(|v| v.first());
    let src = arm.source();
    let urdf = urdf(arm);
    let (report, files, warnings) = py
        .detach(|| {
            let request = args.request(&src, train.len(), val.is_some(), Front::Python)?;
            let found = request.run(&src, &train, val)?;
            let files = match &out {
                Some(dir) => {
                    let w = found.write(dir, &command, &src, urdf.as_ref())?;
                    w.files
                        .iter()
                        .chain(&w.urdf)
                        .map(|p| p.display().to_string())
                        .collect()
                }
                None => Vec::new(),
            };
            let report = dynid::report::json_report(&found.outcome, &command);
            Ok((report, files, found.warnings))
        })
        .map_err(err)?;
    Ok((crate::value::to_py(py, &report)?, files, warnings))
}
