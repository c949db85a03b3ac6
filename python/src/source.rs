//! What the Python side hands over for a request, as the application layer's types: a data
//! input (a path, or a label, column names and a C-contiguous float64 block that
//! `dynid/__init__.py` made of an array, dict or DataFrame: borrowed, never copied or turned into
//! text), a cut-off (a number or `"auto"`), and the layer's errors as `DynidError`.

use std::path::PathBuf;

use dynid::app::options::CutoffArg;
use dynid::app::source::DataSource;
use dynid::app::AppError;
use numpy::prelude::*;
use numpy::PyReadonlyArray2;
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;

use crate::{Arm, DynidError};

/// A training or validation input as the Python side hands it over.
#[derive(FromPyObject)]
pub enum DataArg<'py> {
    /// (label, column names, rows × columns float64, C-contiguous)
    Table(String, Vec<String>, PyReadonlyArray2<'py, f64>),
    Path(PathBuf),
}

/// `cutoff=`: Hz or a string (`"auto"`); the application layer checks either.
#[derive(FromPyObject)]
pub enum Cutoff {
    Hz(f64),
    Text(String),
}

impl Cutoff {
    pub fn arg(self) -> CutoffArg {
        match self {
            Cutoff::Hz(f) => CutoffArg::Hz(f),
            Cutoff::Text(s) => CutoffArg::Text(s),
        }
    }
}

/// The data inputs as sources, the tables borrowed from numpy.
pub fn sources<'a>(args: &'a [DataArg<'_>]) -> PyResult<Vec<DataSource<'a>>> {
    args.iter().map(source).collect()
}

fn source<'a>(d: &'a DataArg<'_>) -> PyResult<DataSource<'a>> {
    Ok(match d {
        DataArg::Path(p) => DataSource::Path(p.clone()),
        DataArg::Table(label, names, a) => {
            // `as_slice` also takes Fortran order: only C order is the row-major block.
            let values = match (a.is_c_contiguous(), a.as_slice()) {
                (true, Ok(v)) => v,
                _ => {
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
            DataSource::Table {
                label: label.clone(),
                names: names.clone(),
                values,
            }
        }
    })
}

/// The application layer's error as `DynidError`, its whole message on one line.
pub fn err(e: AppError) -> PyErr {
    DynidError::new_err(e.message())
}

/// The URDF an arm was read from, for the outputs that rewrite it (`identified.urdf`).
pub fn urdf(arm: &Arm) -> Option<dynid::urdf::roundtrip::UrdfSource> {
    arm.urdf_origin()
        .and_then(|path| dynid::arms::urdf_source(&path).ok().flatten())
}
