//! Classical fourth-order Runge–Kutta on `x = (q, q̇)` with the torque held over the step.

use super::{Plant, Work};

/// Classical RK4 on x = (q, q̇) with τ held over the step: the four stages' (q̇, q̈) and the
/// intermediate state, allocated once.
pub(super) struct Rk4 {
    k: [[Vec<f64>; 2]; 4],
    qs: Vec<f64>,
    dqs: Vec<f64>,
}

impl Rk4 {
    pub(super) fn new(n: usize) -> Self {
        let z = || vec![0.0; n];
        Rk4 {
            k: [[z(), z()], [z(), z()], [z(), z()], [z(), z()]],
            qs: z(),
            dqs: z(),
        }
    }

    /// Advances `(q, dq)` by `h` from the acceleration `acc` at the start; false when the mass
    /// matrix is singular at a stage.
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
        let [[k1v, k1a], [k2v, k2a], [k3v, k3a], [k4v, k4a]] = &mut self.k;
        let (qs, dqs) = (&mut self.qs, &mut self.dqs);
        k1v.copy_from_slice(dq);
        k1a.copy_from_slice(acc);
        for j in 0..n {
            qs[j] = q[j] + 0.5 * h * k1v[j];
            dqs[j] = dq[j] + 0.5 * h * k1a[j];
        }
        k2v.copy_from_slice(dqs);
        let ok2 = plant.accel(qs, dqs, tau, k2a, w);
        for j in 0..n {
            qs[j] = q[j] + 0.5 * h * k2v[j];
            dqs[j] = dq[j] + 0.5 * h * k2a[j];
        }
        k3v.copy_from_slice(dqs);
        let ok3 = plant.accel(qs, dqs, tau, k3a, w);
        for j in 0..n {
            qs[j] = q[j] + h * k3v[j];
            dqs[j] = dq[j] + h * k3a[j];
        }
        k4v.copy_from_slice(dqs);
        let ok4 = plant.accel(qs, dqs, tau, k4a, w);
        if !(ok2 && ok3 && ok4) {
            return false;
        }
        for j in 0..n {
            q[j] += h / 6.0 * (k1v[j] + 2.0 * k2v[j] + 2.0 * k3v[j] + k4v[j]);
            dq[j] += h / 6.0 * (k1a[j] + 2.0 * k2a[j] + 2.0 * k3a[j] + k4a[j]);
        }
        true
    }
}
