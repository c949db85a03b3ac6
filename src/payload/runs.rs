//! One run as the payload fit reads it: torque (times the drive gains) and states per joint at
//! its sample times. Files with `dq`/`ddq` columns are used as they are; otherwise the states
//! come from the same estimator `identify` uses, and its zero-phase filter is kept so the fit
//! can filter the torque and the regressor alike (parallel filtering, no bias).

use crate::data::Trajectory;
use crate::derivative::{self, Estimator, Filter};
use crate::log::Log;

use super::PayloadError;

/// A run on its samples: `q[j][k]` (likewise `dq`, `ddq`, `tau`) at time `t[k]`.
#[derive(Debug, Clone)]
pub struct Run {
    pub source: String,
    pub t: Vec<f64>,
    pub q: Vec<Vec<f64>>,
    pub dq: Vec<Vec<f64>>,
    pub ddq: Vec<Vec<f64>>,
    pub tau: Vec<Vec<f64>>,
    /// The low-pass the states were estimated with (`None`: the file's own derivatives).
    pub filter: Option<Filter>,
    pub cutoff_hz: Option<f64>,
}

impl Run {
    /// `traj` with its torque multiplied by `scale` per joint; needs a `tau` column.
    pub fn new(
        traj: Trajectory,
        scale: &[f64],
        opts: &derivative::Options,
    ) -> Result<Run, PayloadError> {
        let n = traj.dof;
        let source = traj.source.clone();
        traj.require(false, false, true, "payload identification")
            .map_err(|e| PayloadError::Input(e.to_string()))?;
        if traj.len() < derivative::MIN_SAMPLES.max(20) {
            return Err(PayloadError::Input(format!(
                "{source}: {} samples — a payload fit needs at least {}",
                traj.len(),
                derivative::MIN_SAMPLES.max(20)
            )));
        }
        let cols = |v: &[f64]| -> Vec<Vec<f64>> {
            (0..n)
                .map(|j| v.iter().skip(j).step_by(n).copied().collect())
                .collect()
        };
        let scaled = |tau: Vec<Vec<f64>>| -> Vec<Vec<f64>> {
            tau.into_iter()
                .zip(scale)
                .map(|(c, s)| c.into_iter().map(|x| x * s).collect())
                .collect()
        };
        if let (Some(dq), Some(ddq), Some(tau)) = (&traj.dq, &traj.ddq, &traj.tau) {
            return Ok(Run {
                source,
                t: traj.t.clone(),
                q: cols(&traj.q),
                dq: cols(dq),
                ddq: cols(ddq),
                tau: scaled(cols(tau)),
                filter: None,
                cutoff_hz: None,
            });
        }
        let log = Log::from(traj);
        let est = Estimator::new(&log, true, opts)
            .map_err(|e| PayloadError::Input(format!("{source}: {e}")))?;
        let len = est.grid.n;
        let st = est.window(&log, 0, len);
        let tau = est.tau_on_grid(&log, 0, len);
        Ok(Run {
            source,
            t: (0..len).map(|k| est.grid.time(k)).collect(),
            q: st.q,
            dq: st.dq,
            ddq: st.ddq,
            tau: scaled(tau),
            cutoff_hz: Some(est.report.cutoff_hz),
            filter: Some(est.filter),
        })
    }

    pub fn len(&self) -> usize {
        self.t.len()
    }

    pub fn is_empty(&self) -> bool {
        self.t.is_empty()
    }

    pub fn dof(&self) -> usize {
        self.q.len()
    }

    /// Joint `j`'s `(q, q̇, q̈, τ)` at time `t` by linear interpolation (`None` outside the run).
    pub fn at(&self, j: usize, t: f64) -> Option<(f64, f64, f64, f64)> {
        let (k, s) = self.locate(t)?;
        let lerp = |v: &[f64]| v[k] + s * (v[(k + 1).min(v.len() - 1)] - v[k]);
        Some((
            lerp(&self.q[j]),
            lerp(&self.dq[j]),
            lerp(&self.ddq[j]),
            lerp(&self.tau[j]),
        ))
    }

    /// The sample interval holding `t` and the fraction into it.
    fn locate(&self, t: f64) -> Option<(usize, f64)> {
        let ts = &self.t;
        let (first, last) = (*ts.first()?, *ts.last()?);
        if !(first..=last).contains(&t) {
            return None;
        }
        let k = ts.partition_point(|&x| x <= t).saturating_sub(1);
        let k = k.min(ts.len().saturating_sub(2));
        let h = ts[k + 1] - ts[k];
        Some((k, if h > 0.0 { (t - ts[k]) / h } else { 0.0 }))
    }
}
