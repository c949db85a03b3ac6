//! Recursive Newton–Euler inverse dynamics (Craig, modified D-H): forward recursion for link
//! velocities/accelerations, backward recursion for the transmitted wrenches.

use nalgebra::Vector3;

use crate::dh::MAX_JOINTS;

use super::{joint_component, link_params, RefModel, Workspace};

impl RefModel {
    /// Inverse dynamics `τ = M(q)q̈ + C(q,q̇)q̇ + g(q)` for full parameters `p` (length `np`).
    pub fn inverse_dynamics(
        &self,
        ws: &mut Workspace,
        q: &[f64],
        dq: &[f64],
        ddq: &[f64],
        p: &[f64],
        tau: &mut [f64],
    ) {
        self.rnea(ws, q, dq, ddq, p, true, tau);
    }

    /// Coriolis/centrifugal + gravity torques `h(q, q̇)` (inverse dynamics at `q̈ = 0`).
    pub fn bias(&self, ws: &mut Workspace, q: &[f64], dq: &[f64], p: &[f64], out: &mut [f64]) {
        let zero = [0.0; MAX_JOINTS];
        self.rnea(ws, q, dq, &zero[..self.dof()], p, true, out);
    }

    /// Gravity torques `g(q)`.
    pub fn gravity(&self, ws: &mut Workspace, q: &[f64], p: &[f64], out: &mut [f64]) {
        let zero = [0.0; MAX_JOINTS];
        let zero = &zero[..self.dof()];
        self.rnea(ws, q, zero, zero, p, true, out);
    }

    /// RNEA; `with_gravity = false` gives `M q̈ + C q̇` alone.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn rnea(
        &self,
        ws: &mut Workspace,
        q: &[f64],
        dq: &[f64],
        ddq: &[f64],
        p: &[f64],
        with_gravity: bool,
        tau: &mut [f64],
    ) {
        let n = self.dof();
        self.check(
            ws,
            &[
                (q.len(), n, "q"),
                (dq.len(), n, "dq"),
                (ddq.len(), n, "ddq"),
                (p.len(), 10 * n, "p"),
                (tau.len(), n, "tau"),
            ],
        );
        self.kinematics(ws, q);
        self.forward(ws, dq, ddq, with_gravity);
        let mut f_next = Vector3::zeros();
        let mut n_next = Vector3::zeros();
        for i in (0..n).rev() {
            let (inertia, h, m) = link_params(p, i);
            let (w, dw, dv) = (ws.w[i], ws.dw[i], ws.dv[i]);
            // Net force and moment (about the origin) on link i.
            let force = m * dv + dw.cross(&h) + w.cross(&w.cross(&h));
            let moment = inertia * dw + w.cross(&(inertia * w)) + h.cross(&dv);
            // Wrench from link i+1, expressed in frame i.
            let (f_child, n_child) = if i + 1 < n {
                let r = ws.rot[i + 1];
                let fc = r * f_next;
                (fc, r * n_next + ws.pos[i + 1].cross(&fc))
            } else {
                (Vector3::zeros(), Vector3::zeros())
            };
            let f = force + f_child;
            let nn = moment + n_child;
            ws.f[i] = f;
            ws.n[i] = nn;
            tau[i] = joint_component(self.joints[i].kind, &f, &nn);
            (f_next, n_next) = (f, nn);
        }
    }
}
