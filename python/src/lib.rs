//! `dynid._dynid`, the native module of the `dynid` Python package (re-exported by
//! `dynid/__init__.py`, which adds the pure-Python conveniences: DataFrames, the result object).
//!
//! Errors: the library's messages (`file:line: field: what — how to fix`) become
//! `dynid.DynidError` (a `ValueError`); a wrong array shape or dtype is a plain `ValueError`.

mod arm;
mod batch;
mod ident;
mod input;
mod payload;
mod pool;

use std::path::{Path, PathBuf};

use numpy::ndarray::{Array1, Ix1};
use numpy::prelude::*;
use numpy::{PyArray1, PyReadonlyArray2};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyDict;

pub use arm::Arm;

pyo3::create_exception!(
    dynid,
    DynidError,
    PyValueError,
    "Bad input for dynid (a data file, a D-H table, a URDF, an option): the message says where (file:line: field) and how to fix it."
);

/// Names of the generated arms compiled into this build (``Arm(name)``).
#[pyfunction]
fn arms() -> Vec<&'static str> {
    dynid::arms::names()
}

pub(crate) fn import(
    path: &Path,
    base: Option<String>,
    tip: Option<String>,
    gravity: Option<[f64; 3]>,
    name: Option<String>,
) -> PyResult<dynid::urdf::Imported> {
    let opts = dynid::urdf::ImportOptions {
        base,
        tip,
        gravity,
        name,
    };
    dynid::urdf::import_file(path, &opts).map_err(|e| DynidError::new_err(e.to_string()))
}

/// The native part of ``dynid.import_urdf``: a dict with the arm, texts and parameters.
#[pyfunction]
#[pyo3(signature = (path, base=None, tip=None, gravity=None, name=None))]
fn _import_urdf<'py>(
    py: Python<'py>,
    path: PathBuf,
    base: Option<String>,
    tip: Option<String>,
    gravity: Option<[f64; 3]>,
    name: Option<String>,
) -> PyResult<Bound<'py, PyDict>> {
    let imported = import(&path, base, tip, gravity, name)?;
    let d = PyDict::new(py);
    let params: Bound<'py, PyArray1<f64>> =
        Array1::from_vec(imported.params.full_vector()).into_pyarray(py);
    d.set_item("params", params)?;
    d.set_item("dh_toml", &imported.dh_toml)?;
    d.set_item("params_toml", &imported.params_toml)?;
    d.set_item("chain", &imported.chain)?;
    d.set_item("notes", &imported.notes)?;
    d.set_item("warnings", &imported.warnings)?;
    let arm = Arm::from_table(
        imported.table,
        imported.dh_toml,
        path.display().to_string(),
        "from_urdf",
    );
    d.set_item("arm", Bound::new(py, arm)?)?;
    Ok(d)
}

/// A training or validation input as the Python side hands it over.
#[derive(FromPyObject)]
enum DataArg<'py> {
    /// (label, column names, rows × columns float64, C-contiguous)
    Table(String, Vec<String>, PyReadonlyArray2<'py, f64>),
    Path(PathBuf),
}

fn source<'a>(d: &'a DataArg<'_>) -> PyResult<ident::Source<'a>> {
    Ok(match d {
        DataArg::Path(p) => ident::Source::Path(p.clone()),
        DataArg::Table(label, names, a) => {
            let values = match a.is_c_contiguous() {
                true => a.as_slice().unwrap_or(&[]),
                false => {
                    return Err(PyValueError::new_err(format!(
                        "{label}: the array must be C-contiguous (numpy.ascontiguousarray)"
                    )))
                }
            };
            if a.shape()[1] != names.len() {
                return Err(PyValueError::new_err(format!(
                    "{label}: {} column names for {} columns",
                    names.len(),
                    a.shape()[1]
                )));
            }
            ident::Source::Table {
                label: label.clone(),
                names: names.clone(),
                values,
            }
        }
    })
}

/// The native part of ``dynid.identify``: ``(report_json, files_written, warnings)``.
#[pyfunction]
#[pyo3(signature = (arm, train, validate, effects, cutoff, smoothing, derivative, file_velocity, physical, prior, strict, out, command, topic, joints, torque_scale))]
#[allow(clippy::too_many_arguments)]
fn _identify(
    py: Python<'_>,
    arm: &Arm,
    train: Vec<DataArg<'_>>,
    validate: Option<DataArg<'_>>,
    effects: String,
    cutoff: Option<f64>,
    smoothing: String,
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
) -> PyResult<(String, Vec<String>, Vec<String>)> {
    let sources = train.iter().map(source).collect::<PyResult<Vec<_>>>()?;
    let val = validate.as_ref().map(source).transpose()?;
    let opt = ident::Options {
        effects,
        cutoff,
        smoothing,
        derivative,
        file_velocity,
        physical,
        prior,
        strict,
        out,
        command,
        topic,
        joints,
        torque_scale,
    };
    let src = arm.source();
    let ran = py
        .detach(|| ident::run(&src, &sources, val.as_ref(), &opt))
        .map_err(DynidError::new_err)?;
    Ok((ran.json, ran.files, ran.warnings))
}

/// The native part of ``dynid.payload``: a ``PayloadResult``.
#[pyfunction]
#[pyo3(signature = (arm, params, data, unloaded, mass, torque_scale, cutoff, derivative, out, command))]
#[allow(clippy::too_many_arguments)]
fn _payload(
    py: Python<'_>,
    arm: &Arm,
    params: PathBuf,
    data: Vec<DataArg<'_>>,
    unloaded: Vec<DataArg<'_>>,
    mass: Option<f64>,
    torque_scale: Option<Vec<f64>>,
    cutoff: Option<f64>,
    derivative: String,
    out: Option<PathBuf>,
    command: String,
) -> PyResult<payload::PayloadResult> {
    let loaded = data.iter().map(source).collect::<PyResult<Vec<_>>>()?;
    let twins = unloaded.iter().map(source).collect::<PyResult<Vec<_>>>()?;
    let opt = payload::Options {
        mass,
        torque_scale,
        cutoff,
        derivative,
        out,
        command,
    };
    py.detach(|| payload::run(arm, &params, &loaded, &twins, &opt))
        .map_err(payload::err)
}

/// Full parameters of a params TOML file (``dynid torque --params``), ``(10·n,)``.
#[pyfunction]
fn read_params<'py>(
    py: Python<'py>,
    path: PathBuf,
    dof: usize,
) -> PyResult<Bound<'py, numpy::PyArray<f64, Ix1>>> {
    let p = dynid::params::InertialParams::from_path(
        &path,
        dof,
        &dynid::params::ParamsOptions {
            allow_nonphysical: true,
        },
    )
    .map_err(|e| DynidError::new_err(e.to_string()))?;
    Ok(Array1::from_vec(p.full_vector()).into_pyarray(py))
}

#[pymodule]
fn _dynid(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("DynidError", m.py().get_type::<DynidError>())?;
    m.add_class::<Arm>()?;
    m.add_function(wrap_pyfunction!(arms, m)?)?;
    m.add_function(wrap_pyfunction!(_import_urdf, m)?)?;
    m.add_function(wrap_pyfunction!(_identify, m)?)?;
    m.add_function(wrap_pyfunction!(_payload, m)?)?;
    m.add_class::<payload::PayloadResult>()?;
    m.add_function(wrap_pyfunction!(read_params, m)?)?;
    m.add_function(wrap_pyfunction!(arm::_restore_arm, m)?)?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
