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
mod source;
mod value;

use std::path::{Path, PathBuf};

use numpy::ndarray::{Array1, Ix1};
use numpy::prelude::*;
use numpy::PyArray1;
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
    m.add_function(wrap_pyfunction!(ident::_identify, m)?)?;
    m.add_function(wrap_pyfunction!(payload::_payload, m)?)?;
    m.add_class::<payload::PayloadResult>()?;
    m.add_function(wrap_pyfunction!(read_params, m)?)?;
    m.add_function(wrap_pyfunction!(arm::_restore_arm, m)?)?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
