//! Jacobian of the plant's forward dynamics, `∂q̈/∂q` and `∂q̈/∂q̇` at a held torque, from the
//! arm's derivative kernels plus the effects' per-joint slopes.

use super::{Plant, Work};
use crate::cholesky::{cholesky, cholesky_solve};
use crate::params::Effects;

/// Effective torque `g = unload(τ) − f(q, q̇)` of joint `j` and its slopes `∂g/∂q`, `∂g/∂q̇`.
///
/// The effects act joint by joint, so their Jacobian is diagonal; each slope is a central
/// difference of that scalar function (exact for springs and viscous friction, ~1e-10 relative
/// for the smoothed signs; a linearly implicit step only needs an approximate Jacobian).
fn effect_slopes(e: &Effects, j: usize, q: f64, dq: f64, tau: f64) -> [f64; 3] {
    let g = |q: f64, dq: f64| e.unload(j, dq, tau) - e.torque(j, q, dq, 0.0);
    let (hq, hv) = (1e-6 * (1.0 + q.abs()), 1e-6 * (1.0 + dq.abs()));
    [
        g(q, dq),
        (g(q + hq, dq) - g(q - hq, dq)) / (2.0 * hq),
        (g(q, dq + hv) - g(q, dq - hv)) / (2.0 * hv),
    ]
}

impl Plant<'_> {
    /// `∂q̈/∂q` into `jq` and `∂q̈/∂q̇` into `jv` (row-major, rows q̈) at `(q, q̇)`, torque `τ`
    /// and acceleration `acc` (the plant's q̈ there); false if the mass matrix is singular.
    ///
    /// Without armature the generated `forward_dynamics_derivatives` kernel gives the rigid
    /// body's part and `M⁻¹`, and the effects add `M⁻¹·diag(∂g)`. Armature changes `M`, so then
    /// `∂q̈/∂x = (M + Ia)⁻¹ (diag(∂g) − ∂ID/∂x)` from the generated inverse-dynamics derivatives
    /// at `acc` (implicit differentiation of `(M + Ia) q̈ + h = g`).
    #[allow(clippy::too_many_arguments)]
    pub(super) fn accel_jacobian(
        &self,
        q: &[f64],
        dq: &[f64],
        tau: &[f64],
        acc: &[f64],
        jq: &mut [f64],
        jv: &mut [f64],
        w: &mut Work,
    ) -> bool {
        let n = q.len();
        let nn = n * n;
        for j in 0..n {
            let [g, gq, gv] = match &self.effects {
                Some(e) => effect_slopes(e, j, q[j], dq[j], tau[j]),
                None => [tau[j], 0.0, 0.0],
            };
            (w.h[j], w.gq[j], w.gv[j]) = (g, gq, gv);
        }
        let armature = self.effects.as_ref().and_then(|e| e.armature.as_ref());
        let Some(ia) = armature else {
            self.body
                .forward_dynamics_derivatives(q, dq, &w.h, &mut w.d);
            let (aq, rest) = w.d.split_at(nn);
            let (av, minv) = rest.split_at(nn);
            for i in 0..n {
                for j in 0..n {
                    let k = i * n + j;
                    jq[k] = aq[k] + minv[k] * w.gq[j];
                    jv[k] = av[k] + minv[k] * w.gv[j];
                }
            }
            return jq.iter().chain(jv.iter()).all(|x| x.is_finite());
        };
        self.body
            .inverse_dynamics_derivatives(q, dq, acc, &mut w.d[..2 * nn]);
        self.body.mass_matrix(q, &mut w.m);
        for (j, ia) in ia.iter().enumerate() {
            w.m[j * n + j] += ia;
        }
        if !cholesky(&mut w.m, n) {
            return false;
        }
        let (dq_id, dv_id) = w.d[..2 * nn].split_at(nn);
        for (out, did, slope) in [(jq, dq_id, &w.gq), (jv, dv_id, &w.gv)] {
            for j in 0..n {
                for i in 0..n {
                    w.col[i] = -did[i * n + j];
                }
                w.col[j] += slope[j];
                cholesky_solve(&w.m, n, &mut w.col);
                for i in 0..n {
                    out[i * n + j] = w.col[i];
                }
            }
        }
        true
    }
}
