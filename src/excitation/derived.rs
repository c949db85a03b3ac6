//! Acceleration limits an arm's own model implies, for joints whose sources (URDF, limits file,
//! flags) give none: a URDF has `effort` limits and `<inertial>`s but no acceleration limit.
//!
//! For joint `j` with effort limit `τ_j`, over postures within the position limits,
//!
//! ```text
//! ddq_max_j = (τ_j − max_q |g_j(q)|) / max_q M_jj(q)
//! ```
//!
//! the acceleration the joint's effort can still give its own reflected inertia (the diagonal of
//! the joint-space mass matrix, from the composite rigid body algorithm) after holding gravity,
//! in the worst posture for both. Any motion that accelerates joint `j` alone harder needs more
//! than `τ_j` there. It is a *scale* for the design, not the torque check: coupling and Coriolis
//! torques are bounded by checking `τ = ID(q, q̇, q̈)` against `τ_j` through the same inertials
//! ([`super::design`]). Rotor inertia is not in a URDF, so a real drive with a gearbox reaches
//! less; give `ddq_max` when you know it.
//!
//! The maxima are taken over a fixed, seeded set of postures: uniform in each joint's range (a
//! revolute range of a turn or more is sampled as ±π) plus the range's corners and middle, so the
//! result is deterministic.
//!
//! ```
//! use dynid::excitation::derived::acceleration_limits;
//! let table = dynid::dh::DhTable::from_str(
//!     "name = \"p\"\nconvention = \"modified\"\ngravity = [0.0, 0.0, -9.81]\n\
//!      [[joint]]\nkind = \"revolute\"\nalpha = 0.0\na = 0.0\nd = 0.0\ntheta = 0.0\n",
//!     "p",
//! )
//! .unwrap();
//! // 2 kg, centre of mass 0.5 m off a vertical axis, ZZ = 0.5 kg·m²: M11 = 0.5, no gravity torque
//! let mut p = vec![0.0; 10];
//! p[0..6].copy_from_slice(&[0.5, 0.0, 0.0, 0.5, 0.0, 0.5]); // XX XY XZ YY YZ ZZ about the joint
//! p[6] = 1.0; // MX = m·x
//! p[9] = 2.0; // m
//! let r = acceleration_limits(&table, &p, &[Some((-1.0, 1.0))], &[Some(10.0)]);
//! assert!((r[0].as_ref().unwrap() - 20.0).abs() < 1e-9);
//! ```

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::dh::DhTable;
use crate::reference::RefModel;

/// Random postures besides the corners and the middle of the ranges.
const POSTURES: usize = 2000;

/// The label written into each joint's limit sources.
pub const LABEL: &str = "urdf effort/inertia";

/// One turn either side of zero: the cap on a continuous (or very wide) joint's sampled range.
const TURN: f64 = std::f64::consts::PI;

/// Derived acceleration limit per joint from full parameters `p` (`10·dof`), position ranges and
/// effort limits: `Ok(ddq_max)`, or `Err(why none)` (no effort limit, no inertia, or an effort
/// that cannot hold the arm against gravity somewhere in the range). A joint without a position
/// range is sampled over ±π (revolute) or ±1 m (prismatic).
pub fn acceleration_limits(
    table: &DhTable,
    p: &[f64],
    ranges: &[Option<(f64, f64)>],
    effort: &[Option<f64>],
) -> Vec<Result<f64, String>> {
    let model = RefModel::new(table);
    let n = model.dof();
    // A revolute joint's dynamics repeat every turn: a range of a turn or more is sampled as one.
    let span = |j: usize| -> (f64, f64) {
        let revolute = table.joints[j].kind == crate::dh::JointKind::Revolute;
        let cap = if revolute { TURN } else { 1.0 };
        match ranges.get(j).copied().flatten() {
            Some((lo, hi)) if lo < hi && !(revolute && hi - lo >= 2.0 * TURN) => (lo, hi),
            _ => (-cap, cap),
        }
    };
    let spans: Vec<(f64, f64)> = (0..n).map(span).collect();
    let mut rng = ChaCha8Rng::seed_from_u64(0x00de_5172);
    let mut postures: Vec<Vec<f64>> = vec![
        spans.iter().map(|s| 0.5 * (s.0 + s.1)).collect(),
        spans.iter().map(|s| s.0).collect(),
        spans.iter().map(|s| s.1).collect(),
    ];
    postures.extend((0..POSTURES).map(|_| {
        spans
            .iter()
            .map(|&(lo, hi)| rng.gen_range(lo..=hi))
            .collect()
    }));
    let mut ws = model.workspace();
    let (mut m, mut g) = (vec![0.0; n * n], vec![0.0; n]);
    let (mut m_max, mut g_max) = (vec![0.0_f64; n], vec![0.0_f64; n]);
    for q in &postures {
        model.mass_matrix(&mut ws, q, p, &mut m);
        model.gravity(&mut ws, q, p, &mut g);
        for j in 0..n {
            m_max[j] = m_max[j].max(m[j * n + j]);
            g_max[j] = g_max[j].max(g[j].abs());
        }
    }
    (0..n)
        .map(|j| {
            let unit = match table.joints[j].kind {
                crate::dh::JointKind::Revolute => "N·m",
                _ => "N",
            };
            let tau = effort
                .get(j)
                .copied()
                .flatten()
                .ok_or_else(|| "it has no effort limit either".to_string())?;
            if m_max[j] <= 1e-12 {
                return Err("its links have no inertia to derive one from".to_string());
            }
            let room = tau - g_max[j];
            if room <= 0.0 {
                return Err(format!(
                    "its effort {tau} {unit} does not hold gravity ({:.3} {unit}) everywhere in its range",
                    g_max[j]
                ));
            }
            Ok(room / m_max[j])
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The shipped UR5e-like URDF, imported as `import-urdf` does.
    fn ur5e() -> crate::urdf::Imported {
        let path = concat!(env!("CARGO_MANIFEST_DIR"), "/data/urdf/ur5e.urdf");
        crate::urdf::import_file(
            std::path::Path::new(path),
            &crate::urdf::ImportOptions::default(),
        )
        .unwrap()
    }

    /// On the UR5e-like URDF, each derived limit equals `(τ − max|g|)/max M_jj` with the maxima
    /// found independently: by finite differences of the inverse dynamics (`M_jj` as the torque
    /// of a unit acceleration, `g` as the torque at rest) on a fresh set of postures. The sampled
    /// maxima of two independent sets agree to 2 % (smooth functions of q on 2000 points).
    #[test]
    fn ur5e_limits_match_inverse_dynamics_on_other_postures() {
        let imp = ur5e();
        let p = imp.params.full_vector();
        let n = imp.table.dof();
        let ranges: Vec<Option<(f64, f64)>> = imp
            .table
            .joints
            .iter()
            .map(|j| j.q_min.zip(j.q_max))
            .collect();
        let effort: Vec<Option<f64>> = imp.table.joints.iter().map(|j| j.tau_max).collect();
        let got = acceleration_limits(&imp.table, &p, &ranges, &effort);
        let model = RefModel::new(&imp.table);
        let mut ws = model.workspace();
        let mut rng = ChaCha8Rng::seed_from_u64(77);
        let (mut m_max, mut g_max) = (vec![0.0_f64; n], vec![0.0_f64; n]);
        let zero = vec![0.0; n];
        let (mut t0, mut t1) = (vec![0.0; n], vec![0.0; n]);
        for _ in 0..2000 {
            let q: Vec<f64> = (0..n).map(|_| rng.gen_range(-TURN..TURN)).collect();
            model.inverse_dynamics(&mut ws, &q, &zero, &zero, &p, &mut t0);
            for j in 0..n {
                let mut e = zero.clone();
                e[j] = 1.0;
                model.inverse_dynamics(&mut ws, &q, &zero, &e, &p, &mut t1);
                m_max[j] = m_max[j].max(t1[j] - t0[j]);
                g_max[j] = g_max[j].max(t0[j].abs());
            }
        }
        for j in 0..n {
            let want = (effort[j].unwrap() - g_max[j]) / m_max[j];
            let g = got[j].as_ref().unwrap();
            assert!(
                (g / want - 1.0).abs() < 0.02,
                "joint {}: {g} vs {want}",
                j + 1
            );
        }
    }

    #[test]
    fn no_effort_or_too_little_is_a_reason() {
        let imp = ur5e();
        let p = imp.params.full_vector();
        let n = imp.table.dof();
        let mut effort = vec![Some(150.0); n];
        effort[0] = None;
        effort[1] = Some(1.0); // the shoulder lift cannot hold the arm with 1 N·m
        let r = acceleration_limits(&imp.table, &p, &vec![None; n], &effort);
        assert!(r[0].as_ref().unwrap_err().contains("no effort"));
        let e = r[1].as_ref().unwrap_err();
        assert!(e.contains("effort 1 N·m") && e.contains("gravity"), "{e}");
        assert!(r[2].is_ok());
    }
}
