//! Composite rigid body algorithm: `M(q)` (`dof × dof`, row-major, symmetric).
//!
//! Column i of M is the wrench needed to give joint i a unit acceleration with everything else
//! at rest: the composite body of links i..n moving about joint i's axis, transmitted back to
//! joints j < i.

use nalgebra::{Matrix3, Vector3};

use super::{joint_component, link_params, RefModel, Workspace};
use crate::dh::JointKind;

impl RefModel {
    /// Joint-space mass matrix for full parameters `p`.
    pub fn mass_matrix(&self, ws: &mut Workspace, q: &[f64], p: &[f64], out: &mut [f64]) {
        let n = self.dof();
        self.check(
            ws,
            &[
                (q.len(), n, "q"),
                (p.len(), 10 * n, "p"),
                (out.len(), n * n, "out"),
            ],
        );
        self.kinematics(ws, q);
        for i in 0..n {
            let (inertia, h, m) = link_params(p, i);
            ws.ci[i] = inertia;
            ws.ch[i] = h;
            ws.cm[i] = m;
        }
        // Accumulate composites tip → base: move body i's inertia to frame i-1.
        for i in (1..n).rev() {
            let (r, pos) = (ws.rot[i], ws.pos[i]);
            let m = ws.cm[i];
            let h = r * ws.ch[i];
            let px = pos.cross_matrix();
            let hx = h.cross_matrix();
            // About the new origin: I' = R I Rᵀ − [P]×[h]× − [h]×[P]× − m[P]×[P]×.
            let inertia: Matrix3<f64> =
                r * ws.ci[i] * r.transpose() - px * hx - hx * px - m * px * px;
            ws.cm[i - 1] += m;
            ws.ch[i - 1] += h + m * pos;
            ws.ci[i - 1] += inertia;
        }
        let z = Vector3::z();
        for i in 0..n {
            let (mut f, mut nn) = match self.joints[i].kind {
                JointKind::Revolute => (z.cross(&ws.ch[i]), ws.ci[i] * z),
                JointKind::Prismatic => (ws.cm[i] * z, ws.ch[i].cross(&z)),
            };
            out[i * n + i] = joint_component(self.joints[i].kind, &f, &nn);
            for j in (0..i).rev() {
                let r = ws.rot[j + 1];
                f = r * f;
                nn = r * nn + ws.pos[j + 1].cross(&f);
                let mji = joint_component(self.joints[j].kind, &f, &nn);
                out[j * n + i] = mji;
                out[i * n + j] = mji;
            }
        }
    }
}
