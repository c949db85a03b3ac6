//! Linearly implicit (Rosenbrock) Euler on `x = (q, q̇)` with the torque held over the step: one
//! Newton iteration of backward Euler from the current state, with the plant's Jacobian.
//!
//! Backward Euler `q₁ = q₀ + h q̇₁`, `q̇₁ = q̇₀ + h q̈(q₁, q̇₁)`, linearised about `(q₀, q̇₀)`, is
//! `(I − h J_v − h² J_q) Δq̇ = h (q̈₀ + h J_q q̇₀)`, `Δq = h (q̇₀ + Δq̇)`: first order and
//! A-stable, so stiff effects (large viscous friction) do not bound the step as they do RK4's.

use nalgebra::{DMatrix, DVector};

use super::{Plant, Work};

/// The Jacobian blocks of one step, allocated once.
pub(super) struct LinearlyImplicitEuler {
    jq: Vec<f64>,
    jv: Vec<f64>,
}

impl LinearlyImplicitEuler {
    pub(super) fn new(n: usize) -> Self {
        Self {
            jq: vec![0.0; n * n],
            jv: vec![0.0; n * n],
        }
    }

    /// Advances `(q, dq)` by `h` from the acceleration `acc` at the start; false when the mass
    /// matrix or the step's matrix is singular.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn step(
        &mut self,
        plant: &Plant,
        q: &mut [f64],
        dq: &mut [f64],
        acc: &[f64],
        tau: &[f64],
        h: f64,
        w: &mut Work,
    ) -> bool {
        let n = q.len();
        if !plant.accel_jacobian(q, dq, tau, acc, &mut self.jq, &mut self.jv, w) {
            return false;
        }
        let (jq, jv) = (&self.jq, &self.jv);
        let s = DMatrix::from_fn(n, n, |i, j| {
            let k = i * n + j;
            f64::from(u8::from(i == j)) - h * jv[k] - h * h * jq[k]
        });
        let rhs = DVector::from_fn(n, |i, _| {
            let jq_dq: f64 = (0..n).map(|j| jq[i * n + j] * dq[j]).sum();
            h * (acc[i] + h * jq_dq)
        });
        let Some(ddq) = s.lu().solve(&rhs) else {
            return false;
        };
        for j in 0..n {
            q[j] += h * (dq[j] + ddq[j]);
            dq[j] += ddq[j];
        }
        true
    }
}
