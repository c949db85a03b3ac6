//! The payload regression `d = Y_n·φ`: `Y_n` is the last link's 10 columns of the full
//! regressor (a payload rigidly on the flange adds `φ` to the last link's parameters), `d` the
//! torque the arm model does not explain. With an unloaded twin `d = τ_loaded − τ_unloaded −
//! (τ_model(q_loaded) − τ_model(q_unloaded))`: friction and model errors cancel, and the model
//! only carries the small tracking difference between the runs; without one, `d = τ − τ_model`.

use crate::params::Effects;
use crate::reference::RefModel;

use super::align::Alignment;
use super::runs::Run;

/// Rows of one loaded run: sample `k`, joint `j` is row `k·n + j`.
#[derive(Debug, Clone)]
pub struct Rows {
    pub n: usize,
    pub y: Vec<[f64; 10]>,
    pub d: Vec<f64>,
}

impl Rows {
    pub fn len(&self) -> usize {
        self.d.len()
    }

    pub fn is_empty(&self) -> bool {
        self.d.is_empty()
    }
}

/// The arm model's torque (rigid body + effects) at one state.
pub struct ArmModel<'a> {
    pub model: &'a RefModel,
    pub params: &'a [f64],
    pub effects: &'a Effects,
}

impl ArmModel<'_> {
    fn torque(
        &self,
        ws: &mut crate::reference::Workspace,
        q: &[f64],
        dq: &[f64],
        ddq: &[f64],
    ) -> Vec<f64> {
        let mut tau = vec![0.0; q.len()];
        self.model
            .inverse_dynamics(ws, q, dq, ddq, self.params, &mut tau);
        let e = self.effects;
        if !e.is_empty() {
            for j in 0..q.len() {
                tau[j] = e.load(j, dq[j], tau[j] + e.torque(j, q[j], dq[j], ddq[j]));
            }
        }
        tau
    }
}

/// The rows of `loaded` (and its aligned twin), and the same rows unfiltered. With an estimated
/// run, every column of `Y_n` goes through the run's zero-phase filter once more and `d` twice
/// (the fit's rows: both then carry the filter twice),
/// and the filter's reach is cut off both ends; the unfiltered rows (`Y_n` of the estimated
/// states against the measured `d`) judge the cut-off (see [`super::cutoff`]).
pub fn build(arm: &ArmModel, loaded: &Run, twin: Option<(&Run, &Alignment)>) -> (Rows, Rows) {
    let n = loaded.dof();
    let np = 10 * n;
    let mut ws = arm.model.workspace();
    let mut full = vec![0.0; n * np];
    // The loaded samples the twin covers (one interval: both runs are contiguous).
    let covered = |k: usize| match twin {
        Some((u, a)) => u.at(0, loaded.t[k] + a.shift_s).is_some(),
        None => true,
    };
    let k0 = (0..loaded.len()).find(|&k| covered(k)).unwrap_or(0);
    let k1 = (k0..loaded.len())
        .take_while(|&k| covered(k))
        .last()
        .map_or(k0, |k| k + 1);
    let len = k1 - k0;
    let mut ys = vec![vec![0.0; len]; 10 * n];
    let mut ds = vec![vec![0.0; len]; n];
    let (mut q, mut dq, mut ddq) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
    for (i, k) in (k0..k1).enumerate() {
        for j in 0..n {
            (q[j], dq[j], ddq[j]) = (loaded.q[j][k], loaded.dq[j][k], loaded.ddq[j][k]);
        }
        arm.model.regressor(&mut ws, &q, &dq, &ddq, &mut full);
        for j in 0..n {
            for c in 0..10 {
                ys[10 * j + c][i] = full[j * np + 10 * (n - 1) + c];
            }
        }
        let model_l = arm.torque(&mut ws, &q, &dq, &ddq);
        match twin {
            Some((u, a)) => {
                let t = loaded.t[k] + a.shift_s;
                let (mut qu, mut dqu, mut ddqu, mut tau_u) =
                    (vec![0.0; n], vec![0.0; n], vec![0.0; n], vec![0.0; n]);
                for j in 0..n {
                    (qu[j], dqu[j], ddqu[j], tau_u[j]) = u.at(j, t).unwrap_or_default();
                }
                let model_u = arm.torque(&mut ws, &qu, &dqu, &ddqu);
                for j in 0..n {
                    ds[j][i] = loaded.tau[j][k] - tau_u[j] - (model_l[j] - model_u[j]);
                }
            }
            None => {
                for j in 0..n {
                    ds[j][i] = loaded.tau[j][k] - model_l[j];
                }
            }
        }
    }
    let (raw_ys, raw_ds) = (ys.clone(), ds.clone());
    let mut lo = 0;
    let mut hi = len;
    if let (Some(f), Some(fc)) = (&loaded.filter, loaded.cutoff_hz) {
        // The states already went through the filter once, so `Y_n` of them is the torque
        // filtered once; `d` (measured) is filtered twice to match `Y_n` filtered again. A
        // cut-off inside the motion band would otherwise scale the inertial columns against
        // `d` (a joint the payload loads only through inertia read a drive gain 5 % off).
        let zp = f.as_zero_phase();
        for s in ys.iter_mut().chain(ds.iter_mut()) {
            zp.apply(s, true, true);
        }
        for s in ds.iter_mut() {
            zp.apply(s, true, true);
        }
        let dt = (loaded.t[loaded.len() - 1] - loaded.t[0]) / (loaded.len() - 1).max(1) as f64;
        let edge = ((2.0 / (fc * dt)).ceil() as usize).max(5);
        if len > 4 * edge {
            lo = edge;
            hi = len - edge;
        }
    }
    (
        interleave(n, &ys, &ds, lo, hi),
        interleave(n, &raw_ys, &raw_ds, lo, hi),
    )
}

/// Samples `lo..hi` of per-column series as rows (sample `k`, joint `j` is row `k·n + j`).
fn interleave(n: usize, ys: &[Vec<f64>], ds: &[Vec<f64>], lo: usize, hi: usize) -> Rows {
    let mut rows = Rows {
        n,
        y: Vec::with_capacity((hi - lo) * n),
        d: Vec::with_capacity((hi - lo) * n),
    };
    for i in lo..hi {
        for j in 0..n {
            let mut r = [0.0; 10];
            for (c, v) in r.iter_mut().enumerate() {
                *v = ys[10 * j + c][i];
            }
            rows.y.push(r);
            rows.d.push(ds[j][i]);
        }
    }
    rows
}
