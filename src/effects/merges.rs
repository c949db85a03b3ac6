//! Effects that are rigid-body parameters in disguise for every motion (see the module docs of
//! [`super`]: the armature of a revolute first joint about a fixed axis is the `ZZR1` column).

use super::{JointState, Scales, Term};

/// Candidates merged with rigid-body parameters for every motion, with the base parameters they
/// merge into. `base_rows(state, out)` fills the base regressor; `states` are random states.
pub fn structural_merges(
    terms: &[Term],
    nb: usize,
    dof: usize,
    states: &[[Vec<f64>; 3]],
    mut base_rows: impl FnMut(&[f64], &[f64], &[f64], &mut [f64]),
    names: &[String],
) -> Vec<(Term, Vec<String>)> {
    use nalgebra::{DMatrix, DVector};
    let rows = states.len() * dof;
    let mut a = DMatrix::zeros(rows, nb);
    let mut yb = vec![0.0; dof * nb];
    for (s, [q, dq, ddq]) in states.iter().enumerate() {
        base_rows(q, dq, ddq, &mut yb);
        for i in 0..dof {
            for k in 0..nb {
                a[(s * dof + i, k)] = yb[i * nb + k];
            }
        }
    }
    let unit = Scales {
        coulomb_v: 1.0,
        stribeck_v: 1.0,
        ripple_k: 1.0,
        spline_v: 1.0,
    };
    let svd = a.clone().svd(true, true);
    let mut out = Vec::new();
    for &t in terms {
        let c = DVector::from_fn(rows, |r, _| {
            let (s, i) = (r / dof, r % dof);
            if i == t.joint {
                let [q, dq, ddq] = &states[s];
                // Each random state at its own time, so that `drift` is tested like the rest.
                let st = JointState::new(q[i], dq[i], ddq[i], &unit).at(s as f64);
                t.column_at(&st, 1.0)
            } else {
                0.0
            }
        });
        let Ok(k) = svd.solve(&c, 1e-12) else {
            continue;
        };
        let resid = (&c - &a * &k).norm();
        if resid < 1e-7 * c.norm().max(1e-300) {
            let kmax = k.amax();
            let with = (0..nb)
                .filter(|&i| k[i].abs() > 1e-6 * kmax)
                .map(|i| names[i].clone())
                .collect();
            out.push((t, with));
        }
    }
    out
}
