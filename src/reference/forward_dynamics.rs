//! Forward dynamics `q̈ = M(q)⁻¹(τ − h(q, q̇))` and the inverse mass matrix: the composite rigid
//! body algorithm's `M`, the recursive Newton–Euler bias `h`, a run-time Cholesky factorisation
//! ([`crate::cholesky`]). The generated kernels unroll an LDLᵀ factorisation instead; agreement
//! between the two checks the factorisation as well as the dynamics.

use crate::cholesky::{cholesky, cholesky_solve};
use crate::dh::MAX_JOINTS;

use super::{RefModel, Workspace};

/// Scratch for one `n × n` matrix on the stack.
const MAX_M: usize = MAX_JOINTS * MAX_JOINTS;

impl RefModel {
    /// Forward dynamics `q̈` for joint forces `tau` and full parameters `p`. Panics if `M(q)` is
    /// not positive definite (parameters that are not physical).
    pub fn forward_dynamics(
        &self,
        ws: &mut Workspace,
        q: &[f64],
        dq: &[f64],
        tau: &[f64],
        p: &[f64],
        out: &mut [f64],
    ) {
        let n = self.dof();
        let mut m = [0.0; MAX_M];
        let m = &mut m[..n * n];
        self.mass_matrix(ws, q, p, m);
        self.bias(ws, q, dq, p, out);
        for (o, t) in out.iter_mut().zip(tau) {
            *o = t - *o;
        }
        assert!(
            cholesky(m, n),
            "{}: M(q) is not positive definite",
            self.name()
        );
        cholesky_solve(m, n, out);
    }

    /// Inverse mass matrix `M(q)⁻¹` (`dof × dof`, row-major), column by column from one
    /// Cholesky factorisation. Panics if `M(q)` is not positive definite.
    pub fn inverse_mass_matrix(&self, ws: &mut Workspace, q: &[f64], p: &[f64], out: &mut [f64]) {
        let n = self.dof();
        let mut m = [0.0; MAX_M];
        let m = &mut m[..n * n];
        self.mass_matrix(ws, q, p, m);
        assert!(
            cholesky(m, n),
            "{}: M(q) is not positive definite",
            self.name()
        );
        let mut e = [0.0; MAX_JOINTS];
        for c in 0..n {
            e[..n].fill(0.0);
            e[c] = 1.0;
            cholesky_solve(m, n, &mut e[..n]);
            // Symmetric: column c is row c.
            out[c * n..(c + 1) * n].copy_from_slice(&e[..n]);
        }
    }
}
