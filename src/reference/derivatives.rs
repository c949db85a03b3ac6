//! `∂τ/∂q`, `∂τ/∂q̇` of inverse dynamics and `∂q̈/∂q`, `∂q̈/∂q̇`, `∂q̈/∂τ` of forward dynamics, by
//! central differences of the reference algorithms with one Richardson extrapolation
//! (`richardson`): an oracle independent of the generator's forward-mode differentiation,
//! accurate to about 1e-11 relative at the step [`STEP`] (four evaluations per column).

use crate::dh::MAX_JOINTS;

use super::{RefModel, Workspace};

/// Step of the central differences (rad, m, rad/s): with one Richardson extrapolation the
/// truncation error is `O(STEP⁴)` (~1e-12 for unit-scale derivatives) and the rounding error
/// about `ε / STEP` (~1e-13 relative).
pub const STEP: f64 = 1e-3;

/// `(4·D(h/2) − D(h)) / 3` of the central differences `D(h) = (f(x + h) − f(x − h)) / 2h`:
/// writes column `c` of the `n × n` Jacobian `jac` (row-major) of `f: ℝⁿ → ℝⁿ` along `x[c]`.
fn richardson(x: &[f64], c: usize, jac: &mut [f64], mut f: impl FnMut(&[f64], &mut [f64])) {
    let n = x.len();
    let mut xs = [0.0; MAX_JOINTS];
    let xs = &mut xs[..n];
    let mut vals = [[0.0; MAX_JOINTS]; 4];
    for (k, dx) in [STEP, -STEP, STEP / 2.0, -STEP / 2.0]
        .into_iter()
        .enumerate()
    {
        xs.copy_from_slice(x);
        xs[c] += dx;
        f(xs, &mut vals[k][..n]);
    }
    for r in 0..n {
        let d1 = (vals[0][r] - vals[1][r]) / (2.0 * STEP);
        let d2 = (vals[2][r] - vals[3][r]) / STEP;
        jac[r * n + c] = (4.0 * d2 - d1) / 3.0;
    }
}

impl RefModel {
    /// `∂τ/∂q` then `∂τ/∂q̇` of [`RefModel::inverse_dynamics`] (`2 · dof²` values, each block
    /// row-major: rows τ, columns q or q̇).
    #[allow(clippy::too_many_arguments)]
    pub fn inverse_dynamics_derivatives(
        &self,
        ws: &mut Workspace,
        q: &[f64],
        dq: &[f64],
        ddq: &[f64],
        p: &[f64],
        out: &mut [f64],
    ) {
        let n = self.dof();
        let (dtau_dq, dtau_ddq) = out.split_at_mut(n * n);
        for c in 0..n {
            richardson(q, c, dtau_dq, |x, o| {
                self.inverse_dynamics(ws, x, dq, ddq, p, o)
            });
            richardson(dq, c, dtau_ddq, |x, o| {
                self.inverse_dynamics(ws, q, x, ddq, p, o)
            });
        }
    }

    /// `∂q̈/∂q`, `∂q̈/∂q̇` of [`RefModel::forward_dynamics`] (by differences) and `∂q̈/∂τ = M⁻¹`
    /// ([`RefModel::inverse_mass_matrix`]): `3 · dof²` values, each block row-major, rows q̈.
    #[allow(clippy::too_many_arguments)]
    pub fn forward_dynamics_derivatives(
        &self,
        ws: &mut Workspace,
        q: &[f64],
        dq: &[f64],
        tau: &[f64],
        p: &[f64],
        out: &mut [f64],
    ) {
        let n = self.dof();
        let (dqdd_dq, rest) = out.split_at_mut(n * n);
        let (dqdd_ddq, m_inv) = rest.split_at_mut(n * n);
        for c in 0..n {
            richardson(q, c, dqdd_dq, |x, o| {
                self.forward_dynamics(ws, x, dq, tau, p, o)
            });
            richardson(dq, c, dqdd_ddq, |x, o| {
                self.forward_dynamics(ws, q, x, tau, p, o)
            });
        }
        self.inverse_mass_matrix(ws, q, p, m_inv);
    }
}
