//! `dynid.payload`: the application layer's `payload` on files or arrays, returning the
//! estimate as a typed object whose getters read the Rust values (numpy arrays for vectors).

use std::path::PathBuf;

use dynid::app::payload::PayloadArgs;
use dynid::app::source::ListArg;
use dynid::app::Front;
use dynid::payload::PayloadEstimate;
use dynid::progress::Progress;
use numpy::ndarray::Array1;
use numpy::prelude::*;
use numpy::PyArray1;
use pyo3::prelude::*;

use crate::source::{err, sources, urdf, Cutoff, DataArg};
use crate::Arm;

/// What ``dynid.payload`` returns: the payload in the last link's frame, each value with its σ.
#[pyclass(frozen, module = "dynid")]
pub struct PayloadResult {
    est: PayloadEstimate,
    files: Vec<String>,
}

fn arr<'py>(py: Python<'py>, v: &[f64]) -> Bound<'py, PyArray1<f64>> {
    Array1::from_vec(v.to_vec()).into_pyarray(py)
}

#[pymethods]
impl PayloadResult {
    /// kg.
    #[getter]
    fn mass(&self) -> f64 {
        self.est.mass
    }
    #[getter]
    fn sigma_mass(&self) -> f64 {
        self.est.sigma.mass
    }
    /// Centre of mass (m), ``(3,)``.
    #[getter]
    fn com<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        arr(py, &self.est.com)
    }
    #[getter]
    fn sigma_com<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        arr(py, &self.est.sigma.com)
    }
    /// Inertia about the centre of mass ``[xx, xy, xz, yy, yz, zz]`` (kg·m²), ``(6,)``.
    #[getter]
    fn inertia<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        arr(py, &self.est.inertia)
    }
    #[getter]
    fn sigma_inertia<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        arr(py, &self.est.sigma.inertia)
    }
    /// ``[XX, XY, XZ, YY, YZ, ZZ, MX, MY, MZ, M]`` about the last link's origin, ``(10,)``.
    #[getter]
    fn params<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        arr(py, &self.est.params)
    }
    /// With ``mass``: the factor per joint the data's torque must be multiplied by, ``(n,)``.
    #[getter]
    fn torque_scale<'py>(&self, py: Python<'py>) -> Option<Bound<'py, PyArray1<f64>>> {
        self.est.torque_scale.as_ref().map(|v| arr(py, v))
    }
    #[getter]
    fn torque_scale_sigma<'py>(&self, py: Python<'py>) -> Option<Bound<'py, PyArray1<f64>>> {
        self.est.torque_scale_sigma.as_ref().map(|v| arr(py, v))
    }
    /// Joints (1-based) the runs cannot calibrate.
    #[getter]
    fn uncalibrated_joints(&self) -> Vec<usize> {
        self.est.uncalibrated_joints.clone()
    }
    /// What the runs cannot estimate well.
    #[getter]
    fn warnings(&self) -> Vec<String> {
        self.est.warnings.clone()
    }
    /// The files written (with ``out=``).
    #[getter]
    fn files(&self) -> Vec<String> {
        self.files.clone()
    }
    /// The estimate as ``payload.json`` holds it: a dict built from the Rust values.
    fn to_dict<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let v = serde_json::to_value(&self.est)
            .map_err(|e| pyo3::exceptions::PyValueError::new_err(e.to_string()))?;
        crate::value::to_py(py, &v)
    }
    /// ``payload.json``'s text (made when asked for: the result itself holds numbers).
    #[getter]
    fn json(&self) -> PyResult<String> {
        serde_json::to_string_pretty(&self.est)
            .map_err(|e| pyo3::exceptions::PyValueError::new_err(e.to_string()))
    }
    fn __repr__(&self) -> String {
        let (m, c) = (self.est.mass, self.est.com);
        format!(
            "PayloadResult(mass={m:.6}, com=[{:.6}, {:.6}, {:.6}])",
            c[0], c[1], c[2]
        )
    }
}

/// The native part of ``dynid.payload``: a ``PayloadResult``.
#[pyfunction]
#[pyo3(signature = (arm, params, data, unloaded, mass, torque_scale, cutoff, derivative, out, command))]
#[allow(clippy::too_many_arguments)]
pub fn _payload(
    py: Python<'_>,
    arm: &Arm,
    params: PathBuf,
    data: Vec<DataArg<'_>>,
    unloaded: Vec<DataArg<'_>>,
    mass: Option<f64>,
    torque_scale: Option<Vec<f64>>,
    cutoff: Cutoff,
    derivative: String,
    out: Option<PathBuf>,
    command: String,
) -> PyResult<PayloadResult> {
    let args = PayloadArgs {
        params,
        mass,
        torque_scale: torque_scale.map(ListArg::Items),
        cutoff: cutoff.arg(),
        derivative,
    };
    let (loaded, twins) = (sources(&data)?, sources(&unloaded)?);
    let src = arm.source();
    let urdf = urdf(arm);
    py.detach(|| {
        let request = args.request(&src, Front::Python)?;
        let est = request.run(&loaded, &twins, &Progress::silent())?;
        let files = match &out {
            Some(dir) => request
                .write(dir, &est, urdf.as_ref(), &command)?
                .iter()
                .map(|f| f.display().to_string())
                .collect(),
            None => Vec::new(),
        };
        Ok(PayloadResult { est, files })
    })
    .map_err(err)
}
