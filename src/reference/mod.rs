//! Hand-written runtime dynamics for any modified D-H table: the test oracle for the generated
//! kernels and the benchmark baseline. Deliberately independent of `codegen/` (numeric
//! recursions in nalgebra, no symbolic work) so that agreement between the two means something.
//!
//! Pinocchio-style split: [`RefModel`] is what the arm is (immutable, built once from a
//! [`DhTable`]); [`Workspace`] is scratch for one evaluation, so repeated calls allocate nothing.
//! Algorithms live in files named after them: [`rnea`](RefModel::inverse_dynamics) (recursive
//! Newton–Euler), [`regressor`](RefModel::regressor), [`crba`](RefModel::mass_matrix),
//! [`forward_dynamics`](RefModel::forward_dynamics) (CRBA + Cholesky) and
//! [`derivatives`](RefModel::inverse_dynamics_derivatives) (central differences).
//!
//! Conventions are those of [`crate::model`]: full parameters `p` per link
//! `XX, XY, XZ, YY, YZ, ZZ, MX, MY, MZ, M` about the link-frame origin; row-major outputs;
//! gravity from the table (entered as a base acceleration `v̇0 = −g`).
//!
//! ```
//! use dynid::dh::DhTable;
//! use dynid::reference::RefModel;
//! # let text = "name = \"pendulum\"\nconvention = \"modified\"\ngravity = [0.0, -9.81, 0.0]\n\
//! #     [[joint]]\nkind = \"revolute\"\nalpha = 0.0\na = 0.0\nd = 0.0\ntheta = 0.0\n";
//! let table = DhTable::from_str(text, "pendulum.toml")?;
//! let model = RefModel::new(&table);
//! let mut ws = model.workspace();
//! // A point mass of 2 kg at x = 0.5 m: ZZ = m·x², MX = m·x.
//! let p = [0.0, 0.0, 0.0, 0.5, 0.0, 0.5, 1.0, 0.0, 0.0, 2.0];
//! let mut tau = [0.0];
//! model.inverse_dynamics(&mut ws, &[0.0], &[0.0], &[0.0], &p, &mut tau);
//! assert!((tau[0] - 9.81 * 1.0).abs() < 1e-12); // g · m · x at q = 0
//! # Ok::<(), dynid::dh::DhError>(())
//! ```

mod crba;
pub mod derivatives;
mod forward_dynamics;
mod regressor;
mod rnea;

use nalgebra::{Matrix3, Vector3};

use crate::dh::{DhTable, JointKind};

/// One joint's constant geometry.
#[derive(Debug, Clone, Copy)]
struct RefJoint {
    kind: JointKind,
    sin_alpha: f64,
    cos_alpha: f64,
    a: f64,
    d: f64,
    theta: f64,
}

/// An arm for the reference algorithms (immutable; build once per table).
#[derive(Debug, Clone)]
pub struct RefModel {
    name: String,
    joints: Vec<RefJoint>,
    gravity: Vector3<f64>,
}

/// Scratch space for one evaluation (per link, in the link's own frame).
#[derive(Debug, Clone)]
pub struct Workspace {
    /// `^{i-1}R_i`: rotation of frame i in frame i-1.
    rot: Vec<Matrix3<f64>>,
    /// `^{i-1}P_i`: origin of frame i in frame i-1.
    pos: Vec<Vector3<f64>>,
    /// Angular velocity, angular acceleration, linear acceleration of the origin.
    w: Vec<Vector3<f64>>,
    dw: Vec<Vector3<f64>>,
    dv: Vec<Vector3<f64>>,
    /// Force and moment (about the origin) exerted on link i by link i-1.
    f: Vec<Vector3<f64>>,
    n: Vec<Vector3<f64>>,
    /// Composite-body mass, first moment and inertia (about the origin) for CRBA.
    cm: Vec<f64>,
    ch: Vec<Vector3<f64>>,
    ci: Vec<Matrix3<f64>>,
}

impl RefModel {
    /// Builds the model of a D-H table.
    pub fn new(table: &DhTable) -> Self {
        let joints = table
            .joints
            .iter()
            .map(|j| {
                let (sin_alpha, cos_alpha) = j.alpha.sin_cos();
                RefJoint {
                    kind: j.kind,
                    sin_alpha,
                    cos_alpha,
                    a: j.a,
                    d: j.d,
                    theta: j.theta,
                }
            })
            .collect();
        RefModel {
            name: table.name.clone(),
            joints,
            gravity: Vector3::from(table.gravity),
        }
    }

    /// The arm's name (from the table).
    pub fn name(&self) -> &str {
        &self.name
    }

    /// Degrees of freedom.
    pub fn dof(&self) -> usize {
        self.joints.len()
    }

    /// Number of full inertial parameters, `10 · dof`.
    pub fn np(&self) -> usize {
        10 * self.dof()
    }

    /// Fresh scratch space for this model.
    pub fn workspace(&self) -> Workspace {
        let n = self.dof();
        let z3 = vec![Vector3::zeros(); n];
        Workspace {
            rot: vec![Matrix3::identity(); n],
            pos: z3.clone(),
            w: z3.clone(),
            dw: z3.clone(),
            dv: z3.clone(),
            f: z3.clone(),
            n: z3.clone(),
            cm: vec![0.0; n],
            ch: z3,
            ci: vec![Matrix3::zeros(); n],
        }
    }

    fn check(&self, ws: &Workspace, lens: &[(usize, usize, &str)]) {
        assert_eq!(
            ws.rot.len(),
            self.dof(),
            "workspace built for another model"
        );
        for &(len, want, what) in lens {
            assert_eq!(
                len, want,
                "reference dynamics: `{what}` has length {len}, expected {want}"
            );
        }
    }

    /// Fills the joint transforms `^{i-1}R_i`, `^{i-1}P_i` for configuration `q`:
    /// `RotX(α_{i-1})·TransX(a_{i-1})·RotZ(θ_i)·TransZ(d_i)`.
    fn kinematics(&self, ws: &mut Workspace, q: &[f64]) {
        for (i, j) in self.joints.iter().enumerate() {
            let (theta, d) = match j.kind {
                JointKind::Revolute => (q[i] + j.theta, j.d),
                JointKind::Prismatic => (j.theta, q[i] + j.d),
            };
            let (st, ct) = theta.sin_cos();
            let (sa, ca) = (j.sin_alpha, j.cos_alpha);
            ws.rot[i] = Matrix3::new(ct, -st, 0.0, ca * st, ca * ct, -sa, sa * st, sa * ct, ca);
            ws.pos[i] = Vector3::new(j.a, -sa * d, ca * d);
        }
    }

    /// Forward recursion: velocities and accelerations of every link (frame i coordinates),
    /// with the base accelerating at `-g` when `with_gravity`.
    fn forward(&self, ws: &mut Workspace, dq: &[f64], ddq: &[f64], with_gravity: bool) {
        let z = Vector3::z();
        let mut w_prev = Vector3::zeros();
        let mut dw_prev = Vector3::zeros();
        let mut dv_prev = if with_gravity {
            -self.gravity
        } else {
            Vector3::zeros()
        };
        for (i, j) in self.joints.iter().enumerate() {
            let rt = ws.rot[i].transpose();
            let p = ws.pos[i];
            let dv_origin = rt * (dw_prev.cross(&p) + w_prev.cross(&w_prev.cross(&p)) + dv_prev);
            let w_in = rt * w_prev;
            let dw_in = rt * dw_prev;
            let (w, dw, dv) = match j.kind {
                JointKind::Revolute => {
                    let w = w_in + z * dq[i];
                    (w, dw_in + w_in.cross(&(z * dq[i])) + z * ddq[i], dv_origin)
                }
                JointKind::Prismatic => (
                    w_in,
                    dw_in,
                    dv_origin + 2.0 * w_in.cross(&(z * dq[i])) + z * ddq[i],
                ),
            };
            ws.w[i] = w;
            ws.dw[i] = dw;
            ws.dv[i] = dv;
            (w_prev, dw_prev, dv_prev) = (w, dw, dv);
        }
    }
}

/// The joint's generalized force from the wrench (force `f`, moment `n` about the origin)
/// transmitted to its link, in its own frame.
fn joint_component(kind: JointKind, f: &Vector3<f64>, n: &Vector3<f64>) -> f64 {
    match kind {
        JointKind::Revolute => n.z,
        JointKind::Prismatic => f.z,
    }
}

/// Link `i`'s parameters from `p`: (inertia about the origin, first moment `m·c`, mass).
fn link_params(p: &[f64], i: usize) -> (Matrix3<f64>, Vector3<f64>, f64) {
    let l = &p[10 * i..10 * i + 10];
    let inertia = Matrix3::new(l[0], l[1], l[2], l[1], l[3], l[4], l[2], l[4], l[5]);
    (inertia, Vector3::new(l[6], l[7], l[8]), l[9])
}
