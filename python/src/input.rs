//! numpy arrays in: float64 of shape `(n,)` or `(N, n)`, any memory layout (copied to a
//! contiguous block when it is not one), anything else a `ValueError` that says what was expected.

use numpy::prelude::*;
use numpy::{PyArrayDyn, PyReadonlyArrayDyn, PyUntypedArray};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;

/// One input array, borrowed from numpy when it is C-contiguous, else copied in C order.
pub struct Input<'py> {
    pub name: &'static str,
    array: PyReadonlyArrayDyn<'py, f64>,
    copy: Option<Vec<f64>>,
}

impl<'py> Input<'py> {
    /// `obj` as float64: a float64 ndarray as is, a list or tuple through `numpy.asarray`; any
    /// other dtype (including an int array) is a `ValueError`, never a silent conversion.
    pub fn new(name: &'static str, obj: &Bound<'py, PyAny>) -> PyResult<Self> {
        let py = obj.py();
        let owned;
        let obj = if obj.is_instance_of::<pyo3::types::PyList>()
            || obj.is_instance_of::<pyo3::types::PyTuple>()
        {
            owned = py
                .import("numpy")?
                .call_method1("asarray", (obj, "float64"))?;
            &owned
        } else {
            obj
        };
        let array = match obj.cast::<PyArrayDyn<f64>>() {
            Ok(a) => a.readonly(),
            Err(_) => {
                let what = match obj.cast::<PyUntypedArray>() {
                    Ok(a) => format!("a numpy array of dtype {}", a.dtype()),
                    Err(_) => format!("a {}", obj.get_type().name()?),
                };
                return Err(PyValueError::new_err(format!(
                    "{name}: expected a float64 numpy array, got {what} — convert it with numpy.asarray({name}, dtype=float)"
                )));
            }
        };
        // `as_slice` also accepts Fortran order (numpy's "contiguous"): only C order is borrowed.
        let copy = match array.is_c_contiguous() {
            true => None,
            false => Some(array.as_array().iter().copied().collect()),
        };
        Ok(Input { name, array, copy })
    }

    pub fn shape(&self) -> &[usize] {
        self.array.shape()
    }

    pub fn values(&self) -> &[f64] {
        match &self.copy {
            Some(v) => v,
            None => self.array.as_slice().unwrap_or(&[]),
        }
    }
}

fn shape_text(shape: &[usize]) -> String {
    match shape {
        [a] => format!("({a},)"),
        _ => format!(
            "({})",
            shape
                .iter()
                .map(usize::to_string)
                .collect::<Vec<_>>()
                .join(", ")
        ),
    }
}

/// The batch size of joint-space inputs that must all be `(n,)` (`None`: one sample) or all
/// `(N, n)` with the same `N`.
pub fn batch(inputs: &[&Input], n: usize) -> PyResult<Option<usize>> {
    let first = inputs[0];
    let want = match first.shape() {
        [m] if *m == n => None,
        [b, m] if *m == n => Some(*b),
        s => {
            return Err(PyValueError::new_err(format!(
                "{}: expected shape ({n},) for one sample or (N, {n}) for N samples of this {n}-joint arm, got {}",
                first.name,
                shape_text(s)
            )))
        }
    };
    for x in &inputs[1..] {
        let ok = match (x.shape(), want) {
            ([m], None) => *m == n,
            ([b, m], Some(nb)) => *m == n && *b == nb,
            _ => false,
        };
        if !ok {
            let expected = match want {
                None => format!("({n},)"),
                Some(b) => format!("({b}, {n})"),
            };
            return Err(PyValueError::new_err(format!(
                "{}: expected shape {expected} like {}, got {}",
                x.name,
                first.name,
                shape_text(x.shape())
            )));
        }
    }
    Ok(want)
}

/// A full parameter vector: `(10·n,)`.
pub fn params<'py>(obj: &Bound<'py, PyAny>, n: usize) -> PyResult<Input<'py>> {
    let p = Input::new("params", obj)?;
    if p.shape() != [10 * n] {
        return Err(PyValueError::new_err(format!(
            "params: expected shape ({},) — the full inertial parameters, 10 per link in the order XX, XY, XZ, YY, YZ, ZZ, MX, MY, MZ, M (about the link frame's origin; Arm.param_names), got {}",
            10 * n,
            shape_text(p.shape())
        )));
    }
    Ok(p)
}
