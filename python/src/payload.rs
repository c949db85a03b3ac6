//! `dynid.payload`: the CLI's `payload` on files or arrays, returning a typed result.

use std::path::PathBuf;

use dynid::data::Trajectory;
use dynid::derivative::{Method, Options as DerivativeOptions};
use dynid::params::{InertialParams, ParamsOptions};
use dynid::payload::{identify_payload, output, PayloadEstimate, PayloadOptions};
use numpy::ndarray::Array1;
use numpy::prelude::*;
use numpy::PyArray1;
use pyo3::prelude::*;

use crate::ident::{CsvText, Source};
use crate::{Arm, DynidError};

/// What ``dynid.payload`` returns: the payload in the last link's frame, each value with its σ.
#[pyclass(frozen, module = "dynid")]
pub struct PayloadResult {
    /// kg.
    #[pyo3(get)]
    pub mass: f64,
    #[pyo3(get)]
    pub sigma_mass: f64,
    pub com: [f64; 3],
    pub sigma_com: [f64; 3],
    pub inertia: [f64; 6],
    pub sigma_inertia: [f64; 6],
    pub params: [f64; 10],
    pub torque_scale: Option<Vec<f64>>,
    pub torque_scale_sigma: Option<Vec<f64>>,
    #[pyo3(get)]
    pub uncalibrated_joints: Vec<usize>,
    #[pyo3(get)]
    pub warnings: Vec<String>,
    #[pyo3(get)]
    pub files: Vec<String>,
    /// payload.json's text.
    #[pyo3(get)]
    pub json: String,
}

fn arr<'py>(py: Python<'py>, v: &[f64]) -> Bound<'py, PyArray1<f64>> {
    Array1::from_vec(v.to_vec()).into_pyarray(py)
}

#[pymethods]
impl PayloadResult {
    /// Centre of mass (m), ``(3,)``.
    #[getter]
    fn com<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        arr(py, &self.com)
    }
    #[getter]
    fn sigma_com<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        arr(py, &self.sigma_com)
    }
    /// Inertia about the centre of mass ``[xx, xy, xz, yy, yz, zz]`` (kg·m²), ``(6,)``.
    #[getter]
    fn inertia<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        arr(py, &self.inertia)
    }
    #[getter]
    fn sigma_inertia<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        arr(py, &self.sigma_inertia)
    }
    /// ``[XX, XY, XZ, YY, YZ, ZZ, MX, MY, MZ, M]`` about the last link's origin, ``(10,)``.
    #[getter]
    fn params<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        arr(py, &self.params)
    }
    /// With ``mass``: the factor per joint the data's torque must be multiplied by, ``(n,)``.
    #[getter]
    fn torque_scale<'py>(&self, py: Python<'py>) -> Option<Bound<'py, PyArray1<f64>>> {
        self.torque_scale.as_ref().map(|v| arr(py, v))
    }
    #[getter]
    fn torque_scale_sigma<'py>(&self, py: Python<'py>) -> Option<Bound<'py, PyArray1<f64>>> {
        self.torque_scale_sigma.as_ref().map(|v| arr(py, v))
    }
    fn __repr__(&self) -> String {
        format!(
            "PayloadResult(mass={:.6}, com=[{:.6}, {:.6}, {:.6}])",
            self.mass, self.com[0], self.com[1], self.com[2]
        )
    }
}

fn read(src: &Source, dof: usize) -> Result<Trajectory, String> {
    match src {
        Source::Path(p) => Trajectory::from_path(p, Some(dof)).map_err(|e| e.to_string()),
        Source::Table {
            label,
            names,
            values,
        } => Trajectory::from_reader(CsvText::new(names, values), label, Some(dof))
            .map_err(|e| e.to_string()),
    }
}

/// Options of a run (the CLI's flags).
pub struct Options {
    pub mass: Option<f64>,
    pub torque_scale: Option<Vec<f64>>,
    pub cutoff: Option<f64>,
    pub derivative: String,
    pub out: Option<PathBuf>,
    pub command: String,
}

pub fn run(
    arm: &Arm,
    params: &std::path::Path,
    data: &[Source],
    unloaded: &[Source],
    o: &Options,
) -> Result<PayloadResult, String> {
    let src = arm.source();
    let table = src.dh_table().map_err(|e| e.to_string())?;
    let dof = table.dof();
    let p = InertialParams::from_path(params, dof, &ParamsOptions::default())
        .map_err(|e| e.to_string())?;
    let method = match o.derivative.as_str() {
        "butterworth" => Method::Butterworth,
        "savgol" => Method::SavitzkyGolay,
        d => {
            return Err(format!(
                "derivative: {d:?} — expected \"butterworth\" or \"savgol\""
            ))
        }
    };
    let opts = PayloadOptions {
        mass: o.mass,
        torque_scale: o.torque_scale.clone(),
        derivative: DerivativeOptions {
            method,
            cutoff_hz: o.cutoff,
        },
    };
    let loaded = data
        .iter()
        .map(|s| read(s, dof))
        .collect::<Result<Vec<_>, _>>()?;
    let twins = unloaded
        .iter()
        .map(|s| read(s, dof))
        .collect::<Result<Vec<_>, _>>()?;
    let est: PayloadEstimate =
        identify_payload(&table, &p, loaded, twins, &opts).map_err(|e| e.to_string())?;
    let mut files = Vec::new();
    if let Some(dir) = &o.out {
        let urdf = arm
            .urdf_origin()
            .and_then(|path| dynid::arms::urdf_source(&path).ok().flatten());
        files = output::write_all(dir, &est, &p, urdf.as_ref(), &o.command)?
            .into_iter()
            .map(|f| f.display().to_string())
            .collect();
    }
    let json = serde_json::to_string_pretty(&est).map_err(|e| e.to_string())?;
    Ok(PayloadResult {
        mass: est.mass,
        sigma_mass: est.sigma.mass,
        com: est.com,
        sigma_com: est.sigma.com,
        inertia: est.inertia,
        sigma_inertia: est.sigma.inertia,
        params: est.params,
        torque_scale: est.torque_scale,
        torque_scale_sigma: est.torque_scale_sigma,
        uncalibrated_joints: est.uncalibrated_joints,
        warnings: est.warnings,
        files,
        json,
    })
}

/// Maps a library error to ``DynidError``.
pub fn err(e: String) -> PyErr {
    DynidError::new_err(e)
}
