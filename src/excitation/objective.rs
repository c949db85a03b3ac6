//! The quantity an excitation is designed for: how well the observation matrix that
//! identification will use is conditioned. That matrix stacks, for every sample, the base
//! regressor rows (one column per base parameter) and the effect columns asked for (one column
//! per effect and joint, nonzero on that joint's row only; [`Effect::column`], the
//! identification's own, with its Coulomb smoothing `tanh(q̇/v)`, `v` = 1 % of the RMS of `q̇`).
//!
//! Effect columns that equal base-parameter columns for every motion (the armature of a revolute
//! first joint about a fixed axis is `ZZR1`'s column: [`structural_merges`]) are left out, since
//! no motion could separate them; [`Observation::dropped`] lists them.
//!
//! The condition number is `σ_max/σ_min` of the unscaled matrix (the usual figure in the
//! literature, e.g. dynamic_calibration's), from the eigenvalues of `WᵀW`.

use nalgebra::{DMatrix, SymmetricEigen};
use serde::Serialize;

use crate::arms::ArmSource;
use crate::effects::{structural_merges, Effect, Scales, Term};
use crate::identify::base::{random_states, BaseModel, Scratch};
use crate::trajectory::Motion;

/// What the design minimises.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum ObjectiveKind {
    /// `log(cond(W))`.
    Cond,
    /// `−log det(WᵀW / rows) / columns` (D-optimality per column).
    LogDet,
}

/// The observation matrix's columns for an arm.
#[derive(Debug, Clone)]
pub struct Observation {
    base: BaseModel,
    terms: Vec<Term>,
    dropped: Vec<(Term, Vec<String>)>,
    names: Vec<String>,
}

/// Conditioning of an observation matrix.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Conditioning {
    pub cond: f64,
    /// `log det(WᵀW / rows)`.
    pub logdet: f64,
    /// Singular values of `W`, largest first.
    pub singular_values: Vec<f64>,
}

impl Observation {
    /// Base parameters of `arm` plus `effects` on every joint (minus structural merges).
    pub fn new(arm: &ArmSource, effects: &[Effect]) -> Result<Self, crate::dh::DhError> {
        let base = BaseModel::for_arm(arm);
        let table = arm.dh_table()?;
        let dof = base.dof();
        let nb = base.nb();
        let all: Vec<Term> = effects
            .iter()
            .flat_map(|&effect| (0..dof).map(move |joint| Term::new(effect, joint)))
            .collect();
        let states = random_states(&table, 60, 0x6578_6369);
        let mut s = base.scratch();
        let names = base.names();
        let dropped = structural_merges(
            &all,
            nb,
            dof,
            &states,
            |q, dq, ddq, out| base.eval(&mut s, q, dq, ddq, out),
            &names,
        );
        let mut dropped = dropped;
        // A drift is a function of time, not of the motion: no excitation changes its column.
        dropped.extend(
            all.iter()
                .filter(|t| t.effect == Effect::Drift)
                .map(|&t| (t, vec!["time, not the motion".to_string()])),
        );
        // A ripple's wavenumber is found from identification's residual, unknown before it.
        dropped.extend(
            all.iter()
                .filter(|t| t.effect.is_ripple())
                .map(|&t| (t, vec!["a wavenumber identification finds".to_string()])),
        );
        let mut terms: Vec<Term> = all
            .into_iter()
            .filter(|t| !dropped.iter().any(|(d, _)| d == t))
            .collect();
        let mut names = names;
        names.extend(terms.iter().map(Term::label));
        let mut obs = Observation {
            base,
            terms: terms.clone(),
            dropped: Vec::new(),
            names,
        };
        // Effects dependent only together with others (a vertical prismatic joint's armature and
        // offset sum to its mass column, `M·(q̈ + g)`): drop, in order, each effect column that the
        // columns before it span on random states with random velocities.
        let (mut q, mut dq, mut ddq) = (Vec::new(), Vec::new(), Vec::new());
        for [a, b, c] in &states {
            q.extend_from_slice(a);
            dq.extend_from_slice(b);
            ddq.extend_from_slice(c);
        }
        let w = obs.matrix(&mut s, &q, &dq, &ddq);
        let norms: Vec<f64> = (0..w.ncols()).map(|k| w.column(k).norm()).collect();
        let dep = crate::identify::ls::dependent_columns(&w, &norms);
        let late: Vec<usize> = dep.iter().copied().filter(|&k| k >= nb).collect();
        for &k in late.iter().rev() {
            let t = terms.remove(k - nb);
            dropped.push((t, vec!["the columns before it".to_string()]));
        }
        obs.names.truncate(nb);
        obs.names.extend(terms.iter().map(Term::label));
        obs.terms = terms;
        obs.dropped = dropped;
        Ok(obs)
    }

    /// Column names: base parameters, then effect terms (e.g. `viscous2`).
    pub fn columns(&self) -> &[String] {
        &self.names
    }

    /// Effect terms left out, with the base parameters each one is merged into.
    pub fn dropped(&self) -> &[(Term, Vec<String>)] {
        &self.dropped
    }

    pub fn dof(&self) -> usize {
        self.base.dof()
    }

    pub fn scratch(&self) -> Scratch {
        self.base.scratch()
    }

    /// The observation matrix of samples `(q, q̇, q̈)` (row-major `n × dof` each).
    pub fn matrix(&self, s: &mut Scratch, q: &[f64], dq: &[f64], ddq: &[f64]) -> DMatrix<f64> {
        let dof = self.dof();
        let nb = self.base.nb();
        let nc = self.names.len();
        let n = q.len() / dof;
        // Coulomb smoothing from this motion's RMS velocity, as identification sets it.
        let scales: Vec<Scales> = (0..dof)
            .map(|j| {
                let ms = (0..n).map(|k| dq[k * dof + j].powi(2)).sum::<f64>() / n.max(1) as f64;
                Scales::from_rms_velocity(ms.sqrt())
            })
            .collect();
        let mut w = DMatrix::zeros(n * dof, nc);
        let mut yb = vec![0.0; dof * nb];
        for k in 0..n {
            let r = k * dof..(k + 1) * dof;
            let (qk, dqk, ddqk) = (&q[r.clone()], &dq[r.clone()], &ddq[r]);
            self.base.eval(s, qk, dqk, ddqk, &mut yb);
            for i in 0..dof {
                let row = k * dof + i;
                for c in 0..nb {
                    w[(row, c)] = yb[i * nb + c];
                }
            }
            for (c, t) in self.terms.iter().enumerate() {
                let j = t.joint;
                w[(k * dof + j, nb + c)] = t.effect.column(qk[j], dqk[j], ddqk[j], 0.0, &scales[j]);
            }
        }
        w
    }

    /// The observation matrix of `traj` sampled at `rate` Hz on `[0, T]` (both ends included).
    pub fn of_motion(&self, s: &mut Scratch, traj: &dyn Motion, rate: f64) -> DMatrix<f64> {
        let g = Grid::new(traj, rate);
        self.matrix(s, &g.q, &g.dq, &g.ddq)
    }
}

/// Conditioning from the Gram matrix `WᵀW` (symmetric eigenvalues; `cond = ∞` if singular).
pub fn conditioning(w: &DMatrix<f64>) -> Conditioning {
    let rows = w.nrows().max(1) as f64;
    let gram = w.tr_mul(w);
    let mut eig: Vec<f64> = SymmetricEigen::new(gram)
        .eigenvalues
        .iter()
        .copied()
        .collect();
    eig.sort_by(|a, b| b.total_cmp(a));
    let hi = eig.first().copied().unwrap_or(0.0);
    let lo = eig.last().copied().unwrap_or(0.0);
    let cond = if lo > 0.0 && hi > 0.0 {
        (hi / lo).sqrt()
    } else {
        f64::INFINITY
    };
    let logdet = eig
        .iter()
        .map(|&l| {
            if l > 0.0 {
                (l / rows).ln()
            } else {
                f64::NEG_INFINITY
            }
        })
        .sum();
    Conditioning {
        cond,
        logdet,
        singular_values: eig.iter().map(|&l| l.max(0.0).sqrt()).collect(),
    }
}

/// Samples of a motion on the closed grid `t_k = k/rate`, `k = 0..=round(T·rate)`.
#[derive(Debug, Clone)]
pub struct Grid {
    pub t: Vec<f64>,
    pub q: Vec<f64>,
    pub dq: Vec<f64>,
    pub ddq: Vec<f64>,
}

impl Grid {
    pub fn new(traj: &dyn Motion, rate: f64) -> Self {
        let dof = traj.dof();
        let steps = (traj.duration() * rate).round() as usize;
        let n = steps + 1;
        let mut g = Grid {
            t: Vec::with_capacity(n),
            q: vec![0.0; n * dof],
            dq: vec![0.0; n * dof],
            ddq: vec![0.0; n * dof],
        };
        for k in 0..n {
            // the last sample is the end of the period exactly (the rest posture)
            let t = if k == steps {
                traj.duration()
            } else {
                k as f64 / rate
            };
            g.t.push(t);
            let r = k * dof..(k + 1) * dof;
            traj.eval(t, &mut g.q[r.clone()], &mut g.dq[r.clone()], &mut g.ddq[r]);
        }
        g
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// The Gram-eigenvalue condition number equals the SVD's on a random tall matrix (SVD is the
    /// oracle; cond ≈ 1e2 so the squared Gram loses nothing at 1e-9).
    #[test]
    fn gram_conditioning_matches_the_svd() {
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        let w = DMatrix::from_fn(200, 6, |_, c| rng.gen_range(-1.0..1.0) * (c + 1) as f64);
        let c = conditioning(&w);
        let sv = w.clone().svd(false, false).singular_values;
        let cond = sv.max() / sv.min();
        assert!((c.cond / cond - 1.0).abs() < 1e-9, "{} vs {cond}", c.cond);
        assert!((c.singular_values[0] / sv.max() - 1.0).abs() < 1e-12);
    }

    /// On planar2, the first joint's armature is `ZZR1`'s column and is left out; the others stay.
    #[test]
    fn structurally_merged_effects_are_dropped() {
        let arm = ArmSource::Generated(crate::arms::find("planar2").unwrap());
        let obs = Observation::new(&arm, &[Effect::Viscous, Effect::Armature]).unwrap();
        let names = obs.columns();
        assert!(names.contains(&"viscous1".to_string()));
        assert!(names.contains(&"armature2".to_string()));
        assert!(!names.contains(&"armature1".to_string()), "{names:?}");
        assert_eq!(obs.dropped().len(), 1);
    }
}
