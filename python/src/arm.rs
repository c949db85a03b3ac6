//! `dynid.Arm`: an arm's dynamics (generated kernels, or the reference dynamics of a D-H table
//! that is not compiled in) behind numpy arrays.

use std::path::PathBuf;
use std::sync::Arc;

use dynid::arms::{self, ArmSource};
use dynid::dh::DhTable;
use dynid::identify::base::BaseModel;
use dynid::model::Kernel;
use dynid::reference::RefModel;
use numpy::ndarray::IxDyn;
use numpy::prelude::*;
use numpy::PyArrayDyn;
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyTuple;

use crate::batch::{takes, Dynamics, States};
use crate::input::{self, Input};
use crate::DynidError;

/// How the arm was made (what pickling restores it from).
#[derive(Clone)]
pub enum Origin {
    /// A generated arm, by name.
    Generated,
    /// A D-H table's text and where it came from (`from_dh`, `from_urdf`, or a path given to
    /// `Arm(...)`); `how` is the constructor for the repr.
    Table {
        text: String,
        origin: String,
        how: String,
    },
}

pub struct Inner {
    pub dynamics: Dynamics,
    pub table: DhTable,
    pub origin: Origin,
}

/// A robot arm's rigid-body dynamics.
///
/// ``Arm("puma560")`` uses the generated, unrolled kernels compiled into dynid (``dynid.arms()``
/// lists them); ``Arm.from_dh(path)`` and ``Arm.from_urdf(path)`` use the hand-written reference
/// dynamics (recursive Newton–Euler) for an arm that is not compiled in.
///
/// Conventions: full inertial parameters ``params`` have 10 values per link in the order
/// ``XX, XY, XZ, YY, YZ, ZZ, MX, MY, MZ, M`` (inertia and first moment about the link frame's
/// origin, ``param_names``); base parameters ``theta = base_params(params)`` (``base_param_names``,
/// ``base_param_exprs``) satisfy ``regressor(...) @ params == base_regressor(...) @ theta``.
/// Gravity is the arm's own and is included in ``bias``, ``gravity`` and ``inverse_dynamics``.
///
/// Every kernel takes float64 arrays of shape ``(n,)`` (one sample) or ``(N, n)`` (``N`` samples,
/// any memory layout) and returns ``(n, ...)`` or ``(N, n, ...)``. Batches run without the GIL
/// on the lane-batched kernels, over all cores (``threads=`` to choose: 1 = the calling thread);
/// ``out=`` writes into a preallocated C-contiguous float64 array of the output's shape instead of
/// a new one (a repeated large batch then skips the allocation and first-touch of its memory).
#[pyclass(module = "dynid", name = "Arm", frozen)]
pub struct Arm {
    pub inner: Arc<Inner>,
}

impl Arm {
    pub fn of_model(model: &'static dyn dynid::model::Model) -> PyResult<Self> {
        let table = DhTable::from_str(model.arm_toml(), &format!("arms/{}.toml", model.name()))
            .map_err(|e| DynidError::new_err(e.to_string()))?;
        Ok(Arm {
            inner: Arc::new(Inner {
                dynamics: Dynamics::Generated(model),
                table,
                origin: Origin::Generated,
            }),
        })
    }

    pub fn from_table(table: DhTable, text: String, origin: String, how: &str) -> Self {
        let model = RefModel::new(&table);
        let base = BaseModel::numeric(&table);
        Arm {
            inner: Arc::new(Inner {
                dynamics: Dynamics::Reference { model, base },
                table,
                origin: Origin::Table {
                    text,
                    origin,
                    how: how.to_string(),
                },
            }),
        }
    }

    /// The D-H text `text` (read from `origin`) as an arm on the reference dynamics.
    pub fn from_text(text: String, origin: String, how: &str) -> PyResult<Self> {
        let table =
            DhTable::from_str(&text, &origin).map_err(|e| DynidError::new_err(e.to_string()))?;
        Ok(Arm::from_table(table, text, origin, how))
    }

    /// What `dynid::identify` takes.
    /// The file the arm's table came from (a URDF, or a D-H TOML that may record one).
    pub fn urdf_origin(&self) -> Option<String> {
        match &self.inner.origin {
            Origin::Table { origin, .. } => Some(origin.clone()),
            Origin::Generated => None,
        }
    }

    pub fn source(&self) -> ArmSource {
        match (&self.inner.dynamics, &self.inner.origin) {
            (Dynamics::Generated(m), _) => ArmSource::Generated(*m),
            _ => ArmSource::Table(self.inner.table.clone()),
        }
    }

    fn is_generated(&self) -> bool {
        matches!(self.inner.dynamics, Dynamics::Generated(_))
    }

    fn n(&self) -> usize {
        self.inner.dynamics.dof()
    }

    /// Runs `kernel` on the given states: the output array, `(n, ...)` or `(N, n, ...)`.
    fn kernel<'py>(
        &self,
        py: Python<'py>,
        kernel: Kernel,
        states: [Option<&Bound<'py, PyAny>>; 3],
        params: Option<&Bound<'py, PyAny>>,
        threads: Option<usize>,
        out: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        let n = self.n();
        let d = &self.inner.dynamics;
        let names = match kernel {
            Kernel::ForwardDynamics | Kernel::ForwardDynamicsDerivatives => ["q", "dq", "tau"],
            _ => ["q", "dq", "ddq"],
        };
        let mut inputs: Vec<Input> = Vec::new();
        for (k, s) in states.iter().enumerate() {
            if let Some(obj) = s {
                inputs.push(Input::new(names[k], obj)?);
            }
        }
        let refs: Vec<&Input> = inputs.iter().collect();
        let batch = input::batch(&refs, n)?;
        let p = params.map(|p| input::params(p, n)).transpose()?;
        let samples = batch.unwrap_or(1);
        let mut dims = match kernel {
            Kernel::Regressor => vec![n, d.np()],
            Kernel::BaseRegressor => vec![n, d.nb()],
            Kernel::MassMatrix | Kernel::InverseMassMatrix => vec![n, n],
            Kernel::Bias | Kernel::Gravity | Kernel::InverseDynamics | Kernel::ForwardDynamics => {
                vec![n]
            }
            Kernel::InverseDynamicsDerivatives => vec![2, n, n],
            Kernel::ForwardDynamicsDerivatives => vec![3, n, n],
        };
        if let Some(b) = batch {
            dims.insert(0, b);
        }
        let (out, out_is_new) = match out {
            None => crate::pool::output(py, &dims)?,
            Some(o) => {
                let wrong = || {
                    let shape: Vec<String> = dims.iter().map(usize::to_string).collect();
                    PyValueError::new_err(format!(
                        "out: expected a C-contiguous, writeable float64 array of shape ({}{}) that is not one of the inputs",
                        shape.join(", "),
                        if dims.len() == 1 { "," } else { "" }
                    ))
                };
                let a = o.cast::<PyArrayDyn<f64>>().map_err(|_| wrong())?;
                if a.shape() != dims.as_slice() || !a.is_c_contiguous() {
                    return Err(wrong());
                }
                (a.clone(), false)
            }
        };
        {
            // Fails if `out` is also an input (borrowed read-only above) or not writeable.
            let mut rw = out.try_readwrite().map_err(|_| {
                PyValueError::new_err(
                    "out: not writeable, or also one of the inputs — pass a separate array",
                )
            })?;
            let o = rw.as_slice_mut()?;
            let take = takes(kernel);
            let mut it = inputs.iter();
            let mut next = |t: bool| {
                if t {
                    it.next().map(Input::values)
                } else {
                    None
                }
            };
            let (q, dq, ddq) = (next(take[0]), next(take[1]), next(take[2]));
            let x = States {
                samples,
                q: q.unwrap_or(&[]),
                dq: dq.unwrap_or(&[]),
                ddq: ddq.unwrap_or(&[]),
            };
            let pv = p.as_ref().map(Input::values).unwrap_or(&[]);
            match batch {
                // One sample: on this thread, GIL held (a hand-off would cost more than the kernel).
                None => d.run(kernel, &x, pv, o, 1, out_is_new),
                Some(_) => py.detach(|| d.run(kernel, &x, pv, o, threads.unwrap_or(0), out_is_new)),
            }
        }
        Ok(out)
    }
}

/// The `count` blocks of a `(count, n, n)` or `(N, count, n, n)` output, as views.
fn blocks<'py>(all: &Bound<'py, PyArrayDyn<f64>>, count: usize) -> PyResult<Bound<'py, PyTuple>> {
    let py = all.py();
    let batched = all.ndim() == 4;
    let views = (0..count)
        .map(|k| {
            if batched {
                all.get_item((pyo3::types::PySlice::full(py), k))
            } else {
                all.get_item(k)
            }
        })
        .collect::<PyResult<Vec<_>>>()?;
    PyTuple::new(py, views)
}

fn py_name(kernel: Kernel) -> &'static str {
    kernel.name()
}

#[pymethods]
impl Arm {
    /// ``Arm(name)``: the generated arm ``name`` (``dynid.arms()``); a path to a D-H table
    /// (``.toml``) gives the reference dynamics, as ``Arm.from_dh(path)``.
    #[new]
    fn new(name: &str) -> PyResult<Self> {
        match arms::resolve(name).map_err(|e| DynidError::new_err(e.to_string()))? {
            ArmSource::Generated(m) => Arm::of_model(m),
            ArmSource::Table(_) => Arm::from_dh(PathBuf::from(name)),
        }
    }

    /// ``Arm.from_dh(path)``: a D-H table file (the ``arms/<arm>.toml`` format) on the reference
    /// dynamics (not compiled in).
    #[staticmethod]
    fn from_dh(path: PathBuf) -> PyResult<Self> {
        let origin = path.display().to_string();
        let text = std::fs::read_to_string(&path).map_err(|e| {
            DynidError::new_err(format!(
                "{origin}: cannot read the D-H table: {e} — check the path"
            ))
        })?;
        Arm::from_text(text, origin, "from_dh")
    }

    /// ``Arm.from_urdf(path, base=None, tip=None, gravity=None, name=None)``: a URDF serial chain
    /// converted to a D-H table (as ``dynid import-urdf``) on the reference dynamics. The
    /// URDF's inertial parameters: ``dynid.import_urdf(path).params``.
    #[staticmethod]
    #[pyo3(signature = (path, base=None, tip=None, gravity=None, name=None))]
    fn from_urdf(
        path: PathBuf,
        base: Option<String>,
        tip: Option<String>,
        gravity: Option<[f64; 3]>,
        name: Option<String>,
    ) -> PyResult<Self> {
        let imported = crate::import(&path, base, tip, gravity, name)?;
        Ok(Arm::from_table(
            imported.table,
            imported.dh_toml,
            path.display().to_string(),
            "from_urdf",
        ))
    }

    /// Arm name (the D-H table's ``name``).
    #[getter]
    fn name(&self) -> String {
        self.inner.table.name.clone()
    }

    /// Degrees of freedom ``n``.
    #[getter]
    fn dof(&self) -> usize {
        self.n()
    }

    /// Number of full inertial parameters, ``10·n``.
    #[getter]
    fn np(&self) -> usize {
        self.inner.dynamics.np()
    }

    /// Number of base parameters.
    #[getter]
    fn nb(&self) -> usize {
        self.inner.dynamics.nb()
    }

    /// True for generated kernels, False for the reference dynamics.
    #[getter]
    fn generated(&self) -> bool {
        self.is_generated()
    }

    /// ``"generated kernels"`` or ``"reference dynamics (not compiled in)"``.
    #[getter]
    fn dynamics(&self) -> &'static str {
        if self.is_generated() {
            "generated kernels"
        } else {
            "reference dynamics (not compiled in)"
        }
    }

    /// Full parameter names, ``XX1 … M<n>``.
    #[getter]
    fn param_names(&self) -> Vec<String> {
        (1..=self.n())
            .flat_map(|i| {
                dynid::model::PARAM_ORDER
                    .iter()
                    .map(move |p| format!("{p}{i}"))
            })
            .collect()
    }

    /// Base parameter names, e.g. ``ZZR1``.
    #[getter]
    fn base_param_names(&self) -> Vec<String> {
        match &self.inner.dynamics {
            Dynamics::Generated(m) => m.base_param_names().iter().map(|s| s.to_string()).collect(),
            Dynamics::Reference { base, .. } => base.names(),
        }
    }

    /// Each base parameter as an expression in the full ones, e.g. ``ZZ1 + a1²·M2``.
    #[getter]
    fn base_param_exprs(&self) -> Vec<String> {
        match &self.inner.dynamics {
            Dynamics::Generated(m) => m.base_param_exprs().iter().map(|s| s.to_string()).collect(),
            Dynamics::Reference { base, .. } => base.exprs(),
        }
    }

    /// Gravitational acceleration in the base frame, m/s².
    #[getter]
    fn gravity_vector(&self) -> [f64; 3] {
        self.inner.table.gravity
    }

    /// The D-H table's text (TOML).
    #[getter]
    fn dh_toml(&self) -> String {
        match (&self.inner.dynamics, &self.inner.origin) {
            (Dynamics::Generated(m), _) => m.arm_toml().to_string(),
            (_, Origin::Table { text, .. }) => text.clone(),
            (_, Origin::Generated) => String::new(),
        }
    }

    /// The base-parameter map ``B`` (``nb × np``): ``theta = B @ params``.
    #[getter]
    fn base_map<'py>(&self, py: Python<'py>) -> Bound<'py, PyArrayDyn<f64>> {
        let (nb, np) = (self.nb(), self.np());
        let mut b = vec![0.0; nb * np];
        let mut e = vec![0.0; np];
        for c in 0..np {
            e[c] = 1.0;
            for (r, v) in self.inner.dynamics.base_params(&e).into_iter().enumerate() {
                b[r * np + c] = v;
            }
            e[c] = 0.0;
        }
        numpy::ndarray::ArrayD::from_shape_vec(IxDyn(&[nb, np]), b)
            .expect("nb × np values")
            .into_pyarray(py)
    }

    /// Base parameters ``theta`` (``(nb,)``) of full parameters ``params`` (``(10·n,)``).
    fn base_params<'py>(
        &self,
        py: Python<'py>,
        params: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        let p = input::params(params, self.n())?;
        let theta = self.inner.dynamics.base_params(p.values());
        Ok(
            numpy::ndarray::ArrayD::from_shape_vec(IxDyn(&[theta.len()]), theta)
                .expect("nb values")
                .into_pyarray(py),
        )
    }

    /// Full regressor ``Y`` (``(n, 10·n)`` or ``(N, n, 10·n)``): ``tau = Y @ params``.
    #[pyo3(signature = (q, dq, ddq, *, threads=None, out=None))]
    fn regressor<'py>(
        &self,
        q: &Bound<'py, PyAny>,
        dq: &Bound<'py, PyAny>,
        ddq: &Bound<'py, PyAny>,
        threads: Option<usize>,
        out: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        let py = q.py();
        self.kernel(
            py,
            Kernel::Regressor,
            [Some(q), Some(dq), Some(ddq)],
            None,
            threads,
            out,
        )
    }

    /// Base regressor ``Yb`` (``(n, nb)`` or ``(N, n, nb)``): ``tau = Yb @ base_params(params)``.
    #[pyo3(signature = (q, dq, ddq, *, threads=None, out=None))]
    fn base_regressor<'py>(
        &self,
        q: &Bound<'py, PyAny>,
        dq: &Bound<'py, PyAny>,
        ddq: &Bound<'py, PyAny>,
        threads: Option<usize>,
        out: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        let py = q.py();
        self.kernel(
            py,
            Kernel::BaseRegressor,
            [Some(q), Some(dq), Some(ddq)],
            None,
            threads,
            out,
        )
    }

    /// Joint-space mass matrix ``M(q)`` (``(n, n)`` or ``(N, n, n)``) for full parameters
    /// ``params``.
    #[pyo3(signature = (q, params, *, threads=None, out=None))]
    fn mass_matrix<'py>(
        &self,
        q: &Bound<'py, PyAny>,
        params: &Bound<'py, PyAny>,
        threads: Option<usize>,
        out: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        let py = q.py();
        self.kernel(
            py,
            Kernel::MassMatrix,
            [Some(q), None, None],
            Some(params),
            threads,
            out,
        )
    }

    /// Coriolis, centrifugal and gravity torques ``h(q, dq)`` (``(n,)`` or ``(N, n)``).
    #[pyo3(signature = (q, dq, params, *, threads=None, out=None))]
    fn bias<'py>(
        &self,
        q: &Bound<'py, PyAny>,
        dq: &Bound<'py, PyAny>,
        params: &Bound<'py, PyAny>,
        threads: Option<usize>,
        out: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        let py = q.py();
        self.kernel(
            py,
            Kernel::Bias,
            [Some(q), Some(dq), None],
            Some(params),
            threads,
            out,
        )
    }

    /// Gravity torques ``g(q)`` (``(n,)`` or ``(N, n)``).
    #[pyo3(signature = (q, params, *, threads=None, out=None))]
    fn gravity<'py>(
        &self,
        q: &Bound<'py, PyAny>,
        params: &Bound<'py, PyAny>,
        threads: Option<usize>,
        out: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        let py = q.py();
        self.kernel(
            py,
            Kernel::Gravity,
            [Some(q), None, None],
            Some(params),
            threads,
            out,
        )
    }

    /// Inverse dynamics ``tau = M(q) ddq + h(q, dq)`` (``(n,)`` or ``(N, n)``).
    #[pyo3(signature = (q, dq, ddq, params, *, threads=None, out=None))]
    fn inverse_dynamics<'py>(
        &self,
        q: &Bound<'py, PyAny>,
        dq: &Bound<'py, PyAny>,
        ddq: &Bound<'py, PyAny>,
        params: &Bound<'py, PyAny>,
        threads: Option<usize>,
        out: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        let py = q.py();
        self.kernel(
            py,
            Kernel::InverseDynamics,
            [Some(q), Some(dq), Some(ddq)],
            Some(params),
            threads,
            out,
        )
    }

    /// Forward dynamics ``ddq = M(q)⁻¹ (tau − h(q, dq))`` (``(n,)`` or ``(N, n)``), the
    /// generated unrolled LDLᵀ kernel.
    #[pyo3(signature = (q, dq, tau, params, *, threads=None))]
    fn forward_dynamics<'py>(
        &self,
        q: &Bound<'py, PyAny>,
        dq: &Bound<'py, PyAny>,
        tau: &Bound<'py, PyAny>,
        params: &Bound<'py, PyAny>,
        threads: Option<usize>,
    ) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        let py = q.py();
        self.kernel(
            py,
            Kernel::ForwardDynamics,
            [Some(q), Some(dq), Some(tau)],
            Some(params),
            threads,
            None,
        )
    }

    /// Inverse mass matrix ``M(q)⁻¹`` (``(n, n)`` or ``(N, n, n)``).
    #[pyo3(signature = (q, params, *, threads=None))]
    fn inverse_mass_matrix<'py>(
        &self,
        q: &Bound<'py, PyAny>,
        params: &Bound<'py, PyAny>,
        threads: Option<usize>,
    ) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        let py = q.py();
        self.kernel(
            py,
            Kernel::InverseMassMatrix,
            [Some(q), None, None],
            Some(params),
            threads,
            None,
        )
    }

    /// ``(dtau_dq, dtau_ddq)``: the partial derivatives of inverse dynamics, each ``(n, n)`` or
    /// ``(N, n, n)``, rows the joint forces, columns the joint variables (as Pinocchio's
    /// ``computeRNEADerivatives``). Views of one array.
    #[pyo3(signature = (q, dq, ddq, params, *, threads=None))]
    fn inverse_dynamics_derivatives<'py>(
        &self,
        q: &Bound<'py, PyAny>,
        dq: &Bound<'py, PyAny>,
        ddq: &Bound<'py, PyAny>,
        params: &Bound<'py, PyAny>,
        threads: Option<usize>,
    ) -> PyResult<Bound<'py, PyTuple>> {
        let py = q.py();
        let all = self.kernel(
            py,
            Kernel::InverseDynamicsDerivatives,
            [Some(q), Some(dq), Some(ddq)],
            Some(params),
            threads,
            None,
        )?;
        blocks(&all, 2)
    }

    /// ``(dddq_dq, dddq_ddq, minv)``: the partial derivatives of forward dynamics with respect to
    /// ``q``, ``dq`` and ``tau`` (``M(q)⁻¹``), each ``(n, n)`` or ``(N, n, n)``, rows the
    /// accelerations (as Pinocchio's ``computeABADerivatives``). Views of one array.
    #[pyo3(signature = (q, dq, tau, params, *, threads=None))]
    fn forward_dynamics_derivatives<'py>(
        &self,
        q: &Bound<'py, PyAny>,
        dq: &Bound<'py, PyAny>,
        tau: &Bound<'py, PyAny>,
        params: &Bound<'py, PyAny>,
        threads: Option<usize>,
    ) -> PyResult<Bound<'py, PyTuple>> {
        let py = q.py();
        let all = self.kernel(
            py,
            Kernel::ForwardDynamicsDerivatives,
            [Some(q), Some(dq), Some(tau)],
            Some(params),
            threads,
            None,
        )?;
        blocks(&all, 3)
    }

    /// The arm as a URDF (links = the D-H frames, as ``dynid export-urdf``), with the full
    /// parameters ``params`` as the links' inertials (massless links without them): how to hand
    /// Pinocchio or MuJoCo the same arm.
    #[pyo3(signature = (params=None))]
    fn to_urdf(&self, params: Option<&Bound<'_, PyAny>>) -> PyResult<String> {
        let p = params.map(|p| input::params(p, self.n())).transpose()?;
        let inertial = p.map(|p| {
            dynid::params::InertialParams::from_full_vector(p.values(), Default::default())
        });
        dynid::urdf::export(&self.inner.table, inertial.as_ref())
            .map_err(|e| DynidError::new_err(e.to_string()))
    }

    /// The kernel kinds, in the generator's order.
    #[staticmethod]
    fn kernels() -> Vec<&'static str> {
        Kernel::ALL.iter().map(|k| py_name(*k)).collect()
    }

    fn __repr__(&self) -> String {
        let what = format!(
            "{} joints, {} base parameters, {}",
            self.n(),
            self.nb(),
            self.dynamics()
        );
        match &self.inner.origin {
            Origin::Generated => format!("Arm({:?}: {what})", self.name()),
            Origin::Table { origin, how, .. } => {
                format!("Arm.{how}({origin:?}) -> {:?}: {what}", self.name())
            }
        }
    }

    fn __eq__(&self, other: &Bound<'_, PyAny>) -> bool {
        match other.cast::<Arm>() {
            Ok(o) => {
                let o = o.get();
                self.inner.table == o.inner.table && self.is_generated() == o.is_generated()
            }
            Err(_) => false,
        }
    }

    /// Consistent with ``==`` (equal arms have equal tables, so equal names and joint counts):
    /// arms can key a dict or fill a set.
    fn __hash__(&self) -> u64 {
        use std::hash::{Hash, Hasher};
        let mut h = std::collections::hash_map::DefaultHasher::new();
        (self.name(), self.n(), self.is_generated()).hash(&mut h);
        h.finish()
    }

    /// Pickles as its name (generated) or its D-H text (reference dynamics).
    fn __reduce__<'py>(
        &self,
        py: Python<'py>,
    ) -> PyResult<(Bound<'py, PyAny>, Bound<'py, PyTuple>)> {
        let restore = py.import("dynid._dynid")?.getattr("_restore_arm")?;
        let args = match &self.inner.origin {
            Origin::Generated => ("generated", self.name(), String::new(), String::new()),
            Origin::Table { text, origin, how } => {
                ("table", text.clone(), origin.clone(), how.clone())
            }
        };
        Ok((restore, args.into_pyobject(py)?))
    }
}

/// The inverse of `Arm.__reduce__`.
#[pyfunction]
pub fn _restore_arm(kind: &str, a: String, origin: String, how: String) -> PyResult<Arm> {
    match kind {
        "generated" => match arms::find(&a) {
            Some(m) => Arm::of_model(m),
            None => Err(DynidError::new_err(format!(
                "cannot unpickle Arm({a:?}): this build of dynid has no generated arm `{a}` — known arms: {}",
                arms::names().join(", ")
            ))),
        },
        _ => Arm::from_text(a, origin, &how),
    }
}
