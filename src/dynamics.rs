//! An arm's rigid-body dynamics with its parameters bound: what a simulated plant and a
//! model-based controller call, whether the arm has generated kernels or only a D-H table.
//!
//! [`Generated`] runs a generated arm's kernels on its base parameters θ (unrolled, no run-time
//! factorisation); [`Reference`] runs the reference recursions (RNEA, CRBA, a run-time Cholesky
//! factorisation) on full parameters, for an arm given as a D-H table or a URDF imported in
//! memory. Both compute the same functions of the same arm, so a simulation or a controller does
//! not care which one it was handed.

use std::sync::Mutex;

use crate::cholesky::{cholesky, cholesky_solve};
use crate::dh::MAX_JOINTS;
use crate::model::Model;
use crate::reference::{RefModel, Workspace};

/// Rigid-body dynamics of one arm with fixed parameters. Outputs are row-major; a singular mass
/// matrix shows as non-finite outputs of [`forward_dynamics`](Dynamics::forward_dynamics) and
/// [`forward_dynamics_derivatives`](Dynamics::forward_dynamics_derivatives), never as a panic.
pub trait Dynamics: Send + Sync {
    /// The arm's name.
    fn name(&self) -> &str;
    /// Degrees of freedom.
    fn dof(&self) -> usize;
    /// Why the bound parameters do not fit the arm (e.g. the wrong length), if they do not.
    fn invalid(&self) -> Option<String> {
        None
    }
    /// `M(q)`, `dof × dof`.
    fn mass_matrix(&self, q: &[f64], out: &mut [f64]);
    /// `h(q, q̇)`: Coriolis, centrifugal and gravity torques.
    fn bias(&self, q: &[f64], dq: &[f64], out: &mut [f64]);
    /// `τ = M q̈ + h`.
    fn inverse_dynamics(&self, q: &[f64], dq: &[f64], ddq: &[f64], out: &mut [f64]);
    /// `q̈ = M⁻¹ (τ − h)`.
    fn forward_dynamics(&self, q: &[f64], dq: &[f64], tau: &[f64], out: &mut [f64]);
    /// `∂τ/∂q` then `∂τ/∂q̇` (`2 · dof²`).
    fn inverse_dynamics_derivatives(&self, q: &[f64], dq: &[f64], ddq: &[f64], out: &mut [f64]);
    /// `∂q̈/∂q`, `∂q̈/∂q̇` then `M⁻¹` (`3 · dof²`).
    fn forward_dynamics_derivatives(&self, q: &[f64], dq: &[f64], tau: &[f64], out: &mut [f64]);
}

/// A generated arm's kernels on base parameters `theta`.
pub struct Generated<'a> {
    pub model: &'a dyn Model,
    pub theta: Vec<f64>,
}

impl<'a> Generated<'a> {
    pub fn new(model: &'a dyn Model, theta: Vec<f64>) -> Self {
        Self { model, theta }
    }
}

impl Dynamics for Generated<'_> {
    fn name(&self) -> &str {
        self.model.name()
    }
    fn dof(&self) -> usize {
        self.model.dof()
    }
    fn invalid(&self) -> Option<String> {
        (self.theta.len() != self.model.nb()).then(|| {
            format!(
                "arm {} has {} base parameters, θ has {}",
                self.model.name(),
                self.model.nb(),
                self.theta.len()
            )
        })
    }
    fn mass_matrix(&self, q: &[f64], out: &mut [f64]) {
        self.model.mass_matrix(q, &self.theta, out);
    }
    fn bias(&self, q: &[f64], dq: &[f64], out: &mut [f64]) {
        self.model.bias(q, dq, &self.theta, out);
    }
    fn inverse_dynamics(&self, q: &[f64], dq: &[f64], ddq: &[f64], out: &mut [f64]) {
        self.model.inverse_dynamics(q, dq, ddq, &self.theta, out);
    }
    fn forward_dynamics(&self, q: &[f64], dq: &[f64], tau: &[f64], out: &mut [f64]) {
        self.model.forward_dynamics(q, dq, tau, &self.theta, out);
    }
    fn inverse_dynamics_derivatives(&self, q: &[f64], dq: &[f64], ddq: &[f64], out: &mut [f64]) {
        self.model
            .inverse_dynamics_derivatives(q, dq, ddq, &self.theta, out);
    }
    fn forward_dynamics_derivatives(&self, q: &[f64], dq: &[f64], tau: &[f64], out: &mut [f64]) {
        self.model
            .forward_dynamics_derivatives(q, dq, tau, &self.theta, out);
    }
}

/// The reference recursions of a D-H table on full parameters `p` (10 per link).
pub struct Reference {
    model: RefModel,
    p: Vec<f64>,
    /// Scratch of the recursions; a lock so that the dynamics can be shared (uncontended in a
    /// simulation, which is sequential).
    ws: Mutex<Workspace>,
}

impl Reference {
    pub fn new(model: RefModel, p: Vec<f64>) -> Self {
        let ws = Mutex::new(model.workspace());
        Self { model, p, ws }
    }

    fn ws(&self) -> std::sync::MutexGuard<'_, Workspace> {
        // A panic elsewhere cannot leave the scratch in a state that matters: every call
        // overwrites what it reads.
        self.ws.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// `M(q)` factorised in place into `m`; false (and `m` unusable) if not positive definite.
    fn factor(&self, q: &[f64], m: &mut [f64]) -> bool {
        self.model.mass_matrix(&mut self.ws(), q, &self.p, m);
        cholesky(m, self.model.dof())
    }
}

impl Dynamics for Reference {
    fn name(&self) -> &str {
        self.model.name()
    }
    fn dof(&self) -> usize {
        self.model.dof()
    }
    fn invalid(&self) -> Option<String> {
        (self.p.len() != self.model.np()).then(|| {
            format!(
                "arm {} has {} inertial parameters, p has {}",
                self.model.name(),
                self.model.np(),
                self.p.len()
            )
        })
    }
    fn mass_matrix(&self, q: &[f64], out: &mut [f64]) {
        self.model.mass_matrix(&mut self.ws(), q, &self.p, out);
    }
    fn bias(&self, q: &[f64], dq: &[f64], out: &mut [f64]) {
        self.model.bias(&mut self.ws(), q, dq, &self.p, out);
    }
    fn inverse_dynamics(&self, q: &[f64], dq: &[f64], ddq: &[f64], out: &mut [f64]) {
        self.model
            .inverse_dynamics(&mut self.ws(), q, dq, ddq, &self.p, out);
    }
    fn forward_dynamics(&self, q: &[f64], dq: &[f64], tau: &[f64], out: &mut [f64]) {
        let n = self.dof();
        let mut m = [0.0; MAX_JOINTS * MAX_JOINTS];
        let m = &mut m[..n * n];
        if !self.factor(q, m) {
            out.fill(f64::NAN);
            return;
        }
        self.bias(q, dq, out);
        for (o, t) in out.iter_mut().zip(tau) {
            *o = t - *o;
        }
        cholesky_solve(m, n, out);
    }
    fn inverse_dynamics_derivatives(&self, q: &[f64], dq: &[f64], ddq: &[f64], out: &mut [f64]) {
        self.model
            .inverse_dynamics_derivatives(&mut self.ws(), q, dq, ddq, &self.p, out);
    }
    fn forward_dynamics_derivatives(&self, q: &[f64], dq: &[f64], tau: &[f64], out: &mut [f64]) {
        // The reference's own version asserts a positive definite `M`; test it first.
        let n = self.dof();
        let mut m = [0.0; MAX_JOINTS * MAX_JOINTS];
        if !self.factor(q, &mut m[..n * n]) {
            out.fill(f64::NAN);
            return;
        }
        self.model
            .forward_dynamics_derivatives(&mut self.ws(), q, dq, tau, &self.p, out);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The two implementations are the same functions of the same arm: every output of the
    /// reference recursions on full parameters equals the generated kernels on the base
    /// parameters they map to (to rounding), on every generated arm.
    #[test]
    fn reference_and_generated_agree() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        for model in crate::arms::all() {
            let n = model.dof();
            let table = crate::dh::DhTable::from_str(model.arm_toml(), model.name()).unwrap();
            // A physical body per link: mass, small COM, a diagonal inertia about the COM
            // moved to the origin (parallel axes).
            let mut p = vec![0.0; 10 * n];
            for l in 0..n {
                let m: f64 = rng.gen_range(0.5..3.0);
                let c: [f64; 3] = [0, 1, 2].map(|_| rng.gen_range(-0.1..0.1));
                let d: [f64; 3] = [0, 1, 2].map(|_| rng.gen_range(0.01..0.05));
                let s = &mut p[10 * l..10 * l + 10];
                s[0] = d[0] + m * (c[1] * c[1] + c[2] * c[2]);
                s[1] = -m * c[0] * c[1];
                s[2] = -m * c[0] * c[2];
                s[3] = d[1] + m * (c[0] * c[0] + c[2] * c[2]);
                s[4] = -m * c[1] * c[2];
                s[5] = d[2] + m * (c[0] * c[0] + c[1] * c[1]);
                s[6..9].copy_from_slice(&c.map(|x| m * x));
                s[9] = m;
            }
            let mut theta = vec![0.0; model.nb()];
            model.base_params(&p, &mut theta);
            let gen = Generated::new(*model, theta);
            let re = Reference::new(RefModel::new(&table), p);
            assert!(gen.invalid().is_none() && re.invalid().is_none());
            let r = |rng: &mut rand_chacha::ChaCha8Rng| -> Vec<f64> {
                (0..n).map(|_| rng.gen_range(-1.0..1.0)).collect()
            };
            let (q, dq, x) = (r(&mut rng), r(&mut rng), r(&mut rng));
            let close = |a: &[f64], b: &[f64], what: &str| {
                let scale = 1.0 + b.iter().fold(0.0_f64, |s, v| s.max(v.abs()));
                for (i, (a, b)) in a.iter().zip(b).enumerate() {
                    assert!(
                        (a - b).abs() <= 1e-9 * scale,
                        "{} {what}[{i}]: {a} vs {b}",
                        model.name()
                    );
                }
            };
            let (mut a, mut b) = (vec![0.0; 3 * n * n], vec![0.0; 3 * n * n]);
            type Call<'c> = &'c dyn Fn(&dyn Dynamics, &mut [f64]);
            let calls: [(&str, usize, Call); 6] = [
                ("M", n * n, &|d, o| d.mass_matrix(&q, o)),
                ("h", n, &|d, o| d.bias(&q, &dq, o)),
                ("ID", n, &|d, o| d.inverse_dynamics(&q, &dq, &x, o)),
                ("FD", n, &|d, o| d.forward_dynamics(&q, &dq, &x, o)),
                ("dID", 2 * n * n, &|d, o| {
                    d.inverse_dynamics_derivatives(&q, &dq, &x, o)
                }),
                ("dFD", 3 * n * n, &|d, o| {
                    d.forward_dynamics_derivatives(&q, &dq, &x, o)
                }),
            ];
            for (what, len, call) in calls {
                call(&gen, &mut a[..len]);
                call(&re, &mut b[..len]);
                close(&a[..len], &b[..len], what);
            }
        }
    }

    /// A singular mass matrix (all parameters zero) gives NaN, not a panic.
    #[test]
    fn singular_mass_is_nan_not_a_panic() {
        let table = crate::dh::DhTable::from_str(
            crate::arms::find("planar2").unwrap().arm_toml(),
            "planar2",
        )
        .unwrap();
        let re = Reference::new(RefModel::new(&table), vec![0.0; 20]);
        let mut out = [0.0; 2];
        re.forward_dynamics(&[0.1, 0.2], &[0.0, 0.0], &[1.0, 1.0], &mut out);
        assert!(out.iter().all(|x| x.is_nan()));
        let mut d = [0.0; 12];
        re.forward_dynamics_derivatives(&[0.1, 0.2], &[0.0, 0.0], &[1.0, 1.0], &mut d);
        assert!(d.iter().all(|x| x.is_nan()));
    }
}
