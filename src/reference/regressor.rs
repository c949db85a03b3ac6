//! Full regressor `Y(q, q̇, q̈)` (`dof × 10·dof`, row-major) with `τ = Y·p`.
//!
//! Newton–Euler is linear in each link's parameters: link i's net wrench is `A_i·p_i` with a
//! 6×10 matrix built from its velocities and accelerations. Joint j ≤ i feels that wrench
//! transformed back to frame j, so column block i of row j is that projection.

use nalgebra::{Matrix3, SMatrix, Vector3};

use super::{RefModel, Workspace};
use crate::dh::JointKind;

type Block = SMatrix<f64, 3, 10>;

/// `K(v)` with `I·v = K(v)·[XX, XY, XZ, YY, YZ, ZZ]`.
fn inertia_map(v: &Vector3<f64>) -> SMatrix<f64, 3, 6> {
    SMatrix::<f64, 3, 6>::from_row_slice(&[
        v.x, v.y, v.z, 0.0, 0.0, 0.0, //
        0.0, v.x, 0.0, v.y, v.z, 0.0, //
        0.0, 0.0, v.x, 0.0, v.y, v.z,
    ])
}

impl RefModel {
    /// Full regressor into `out` (length `dof · 10·dof`, row-major), gravity included.
    pub fn regressor(
        &self,
        ws: &mut Workspace,
        q: &[f64],
        dq: &[f64],
        ddq: &[f64],
        out: &mut [f64],
    ) {
        let n = self.dof();
        let np = 10 * n;
        self.check(
            ws,
            &[
                (q.len(), n, "q"),
                (dq.len(), n, "dq"),
                (ddq.len(), n, "ddq"),
                (out.len(), n * np, "out"),
            ],
        );
        self.kinematics(ws, q);
        self.forward(ws, dq, ddq, true);
        out.fill(0.0);
        for i in 0..n {
            let (w, dw, dv) = (ws.w[i], ws.dw[i], ws.dv[i]);
            let wx = w.cross_matrix();
            // Force = m·v̇ + (ω̇× + ω×ω×)·h ;  moment = (K(ω̇) + ω×K(ω))·I + (−v̇×)·h.
            let mut force = Block::zeros();
            force
                .fixed_view_mut::<3, 3>(0, 6)
                .copy_from(&(dw.cross_matrix() + wx * wx));
            force.fixed_view_mut::<3, 1>(0, 9).copy_from(&dv);
            let mut moment = Block::zeros();
            moment
                .fixed_view_mut::<3, 6>(0, 0)
                .copy_from(&(inertia_map(&dw) + wx * inertia_map(&w)));
            moment
                .fixed_view_mut::<3, 3>(0, 6)
                .copy_from(&(-dv.cross_matrix()));
            for j in (0..=i).rev() {
                let row = match self.joints[j].kind {
                    JointKind::Revolute => moment.row(2),
                    JointKind::Prismatic => force.row(2),
                };
                for k in 0..10 {
                    out[j * np + 10 * i + k] = row[k];
                }
                if j > 0 {
                    let r: Matrix3<f64> = ws.rot[j];
                    force = r * force;
                    moment = r * moment + ws.pos[j].cross_matrix() * force;
                }
            }
        }
    }
}
