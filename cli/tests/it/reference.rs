//! The hand-written reference dynamics against independent oracles:
//! - a Lagrangian built from point masses (forward kinematics with 4×4 transforms, velocities
//!   from the geometric Jacobian), differentiated numerically: τ = d/dt ∂L/∂q̇ − ∂L/∂q;
//! - M(q) recovered from the kinetic energy by polarization (T is quadratic in q̇);
//! - the paper's closed form Φ for planar2;
//! - internal identities: Y·p = τ, τ = M q̈ + h, M symmetric positive definite.

use dynid::dh::{DhTable, Joint, JointKind};
use dynid::reference::RefModel;
use nalgebra::{DMatrix, Matrix4, Vector3, Vector4};
use proptest::prelude::*;

use crate::common::*;

/// Base-frame transform of every joint frame, from elementary transforms
/// `RotX(α)·TransX(a)·RotZ(θ)·TransZ(d)`.
fn frames(table: &DhTable, q: &[f64]) -> Vec<Matrix4<f64>> {
    let rot_x = |t: f64| {
        let (s, c) = t.sin_cos();
        Matrix4::new(
            1.0, 0.0, 0.0, 0.0, 0.0, c, -s, 0.0, 0.0, s, c, 0.0, 0.0, 0.0, 0.0, 1.0,
        )
    };
    let rot_z = |t: f64| {
        let (s, c) = t.sin_cos();
        Matrix4::new(
            c, -s, 0.0, 0.0, s, c, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0,
        )
    };
    let trans = |x: f64, z: f64| Matrix4::new_translation(&Vector3::new(x, 0.0, z));
    let mut t = Matrix4::identity();
    let mut out = Vec::new();
    for (i, j) in table.joints.iter().enumerate() {
        let (theta, d) = match j.kind {
            JointKind::Revolute => (q[i] + j.theta, j.d),
            JointKind::Prismatic => (j.theta, q[i] + j.d),
        };
        t = t * rot_x(j.alpha) * trans(j.a, 0.0) * rot_z(theta) * trans(0.0, d);
        out.push(t);
    }
    out
}

/// Kinetic and potential energy of the point masses.
fn energy(table: &DhTable, clouds: &[Cloud], q: &[f64], dq: &[f64]) -> (f64, f64) {
    let fr = frames(table, q);
    let g = Vector3::from(table.gravity);
    let axis = |i: usize| Vector3::new(fr[i][(0, 2)], fr[i][(1, 2)], fr[i][(2, 2)]);
    let origin = |i: usize| Vector3::new(fr[i][(0, 3)], fr[i][(1, 3)], fr[i][(2, 3)]);
    let (mut kin, mut pot) = (0.0, 0.0);
    for (i, cloud) in clouds.iter().enumerate() {
        for &(m, r) in cloud {
            let x = (fr[i] * Vector4::new(r[0], r[1], r[2], 1.0)).xyz();
            let mut v = Vector3::zeros();
            for (j, (joint, &dqj)) in table.joints.iter().zip(dq).enumerate().take(i + 1) {
                v += match joint.kind {
                    JointKind::Revolute => axis(j).cross(&(x - origin(j))) * dqj,
                    JointKind::Prismatic => axis(j) * dqj,
                };
            }
            kin += 0.5 * m * v.norm_squared();
            pot -= m * g.dot(&x);
        }
    }
    (kin, pot)
}

fn lagrangian(table: &DhTable, clouds: &[Cloud], q: &[f64], dq: &[f64]) -> f64 {
    let (t, v) = energy(table, clouds, q, dq);
    t - v
}

/// Five-point central difference, error O(h⁴).
fn d5(f: impl Fn(f64) -> f64, h: f64) -> f64 {
    (-f(2.0 * h) + 8.0 * f(h) - 8.0 * f(-h) + f(-2.0 * h)) / (12.0 * h)
}

/// τ = d/dt ∂L/∂q̇ − ∂L/∂q, numerically. ∂L/∂q̇ uses a unit step: L is quadratic in q̇, so the
/// central difference is exact up to rounding. The time derivative follows
/// q(t) = q + q̇t + q̈t²/2 with a five-point stencil (h = 1e-3: truncation ~h⁴·f⁽⁵⁾ ≈ 1e-8,
/// rounding ~ε·L/h ≈ 1e-12, both far below the 1e-6 tolerance).
fn lagrange_torque(
    table: &DhTable,
    clouds: &[Cloud],
    q: &[f64],
    dq: &[f64],
    ddq: &[f64],
) -> Vec<f64> {
    let n = q.len();
    let h = 1e-3;
    let shifted = |v: &[f64], i: usize, s: f64| {
        let mut w = v.to_vec();
        w[i] += s;
        w
    };
    (0..n)
        .map(|i| {
            let momentum = |q: &[f64], dq: &[f64]| {
                (lagrangian(table, clouds, q, &shifted(dq, i, 1.0))
                    - lagrangian(table, clouds, q, &shifted(dq, i, -1.0)))
                    / 2.0
            };
            let along = |t: f64| {
                let qt: Vec<f64> = (0..n)
                    .map(|k| q[k] + dq[k] * t + 0.5 * ddq[k] * t * t)
                    .collect();
                let dqt: Vec<f64> = (0..n).map(|k| dq[k] + ddq[k] * t).collect();
                momentum(&qt, &dqt)
            };
            let dmomentum = d5(along, h);
            let dl_dq = d5(|s| lagrangian(table, clouds, &shifted(q, i, s), dq), h);
            dmomentum - dl_dq
        })
        .collect()
}

struct Eval {
    tau: Vec<f64>,
    y: Vec<f64>,
    m: Vec<f64>,
    h: Vec<f64>,
}

fn eval(table: &DhTable, p: &[f64], q: &[f64], dq: &[f64], ddq: &[f64]) -> Eval {
    let model = RefModel::new(table);
    let n = model.dof();
    let mut ws = model.workspace();
    let mut tau = vec![0.0; n];
    let mut y = vec![0.0; n * 10 * n];
    let mut m = vec![0.0; n * n];
    let mut h = vec![0.0; n];
    model.inverse_dynamics(&mut ws, q, dq, ddq, p, &mut tau);
    model.regressor(&mut ws, q, dq, ddq, &mut y);
    model.mass_matrix(&mut ws, q, p, &mut m);
    model.bias(&mut ws, q, dq, p, &mut h);
    Eval { tau, y, m, h }
}

fn state_strategy() -> impl Strategy<Value = (u64, Vec<f64>, Vec<f64>, Vec<f64>)> {
    (
        any::<u64>(),
        prop::collection::vec(-1.6..1.6f64, 12),
        prop::collection::vec(-2.0..2.0f64, 12),
        prop::collection::vec(-5.0..5.0f64, 12),
    )
}

/// Random modified D-H tables with 1..=6 joints of both kinds.
fn table_strategy() -> impl Strategy<Value = DhTable> {
    let joint = (
        any::<bool>(),
        -3.1..3.1f64,
        -0.5..0.5f64,
        -0.5..0.5f64,
        -3.1..3.1f64,
    );
    (
        prop::collection::vec(joint, 1..=6),
        prop::array::uniform3(-10.0..10.0f64),
    )
        .prop_map(|(joints, gravity)| DhTable {
            name: "random".into(),
            convention: "modified".into(),
            gravity,
            joints: joints
                .into_iter()
                .map(|(prismatic, alpha, a, d, theta)| Joint {
                    name: None,
                    kind: if prismatic {
                        JointKind::Prismatic
                    } else {
                        JointKind::Revolute
                    },
                    alpha,
                    a,
                    d,
                    theta,
                    q_min: None,
                    q_max: None,
                    dq_max: None,
                    ddq_max: None,
                    tau_max: None,
                })
                .collect(),
        })
}

fn check_all(table: &DhTable, seed: u64, q: &[f64], dq: &[f64], ddq: &[f64]) {
    let n = table.dof();
    let (q, dq, ddq) = (&q[..n], &dq[..n], &ddq[..n]);
    let clouds = random_clouds(&mut rng(seed), n);
    let p = cloud_params(&clouds);
    let e = eval(table, &p, q, dq, ddq);
    let name = &table.name;

    assert_close(
        &e.tau,
        &lagrange_torque(table, &clouds, q, dq, ddq),
        1e-6,
        &format!("{name}: RNEA vs Lagrange"),
    );
    assert_close(
        &mat_vec(&e.y, &p),
        &e.tau,
        1e-12,
        &format!("{name}: Y·p vs RNEA"),
    );
    let mqh: Vec<f64> = mat_vec(&e.m, ddq)
        .iter()
        .zip(&e.h)
        .map(|(a, b)| a + b)
        .collect();
    assert_close(&mqh, &e.tau, 1e-12, &format!("{name}: M·q̈ + h vs RNEA"));

    // M from the kinetic energy by polarization: T(e_i) = M_ii/2, T(e_i + e_j) = (M_ii + 2M_ij + M_jj)/2.
    let unit = |i: usize, j: usize| {
        (0..n)
            .map(|k| f64::from(u8::from(k == i) + u8::from(k == j)))
            .collect::<Vec<_>>()
    };
    let kin = |v: &[f64]| energy(table, &clouds, q, v).0;
    let mut m_energy = vec![0.0; n * n];
    for i in 0..n {
        for j in 0..n {
            m_energy[i * n + j] = if i == j {
                kin(&unit(i, usize::MAX)) * 2.0
            } else {
                kin(&unit(i, j)) - kin(&unit(i, usize::MAX)) - kin(&unit(j, usize::MAX))
            };
        }
    }
    assert_close(
        &e.m,
        &m_energy,
        1e-11,
        &format!("{name}: CRBA vs kinetic energy"),
    );
    let m = DMatrix::from_row_slice(n, n, &e.m);
    assert!(
        m.clone().cholesky().is_some(),
        "{name}: M is not positive definite: {m}"
    );
    assert!(
        (&m - m.transpose()).amax() <= 1e-12 * m.amax(),
        "{name}: M is not symmetric"
    );

    // Energy balance: dE/dt = q̇ᵀτ (no friction), along the same quadratic trajectory.
    let energy_at = |t: f64| {
        let qt: Vec<f64> = (0..n)
            .map(|k| q[k] + dq[k] * t + 0.5 * ddq[k] * t * t)
            .collect();
        let dqt: Vec<f64> = (0..n).map(|k| dq[k] + ddq[k] * t).collect();
        let (kin, pot) = energy(table, &clouds, &qt, &dqt);
        kin + pot
    };
    let power: f64 = dq.iter().zip(&e.tau).map(|(a, b)| a * b).sum();
    assert_close(
        &[d5(energy_at, 1e-3)],
        &[power],
        1e-6,
        &format!("{name}: dE/dt vs q̇ᵀτ"),
    );
}

#[test]
fn every_arm_matches_its_lagrangian_and_identities() {
    let mut r = rng(7);
    for table in all_tables() {
        for _ in 0..8 {
            let (q, dq, ddq) = random_state(&mut r, table.dof());
            check_all(&table, r.gen_range(0..u64::MAX), &q, &dq, &ddq);
        }
    }
}

use rand::Rng;

proptest! {
    #![proptest_config(ProptestConfig { cases: 48, ..ProptestConfig::default() })]

    #[test]
    fn random_tables_match_their_lagrangian(table in table_strategy(), (seed, q, dq, ddq) in state_strategy()) {
        check_all(&table, seed, &q, &dq, &ddq);
    }

    #[test]
    fn arms_match_their_lagrangian(idx in 0usize..6, (seed, q, dq, ddq) in state_strategy()) {
        let tables = all_tables();
        let table = &tables[idx % tables.len()];
        check_all(table, seed, &q, &dq, &ddq);
    }

    /// The paper's Φ: τ = Φ(q, q̇, q̈)·θ(p) for any parameters (physical or not).
    #[test]
    fn planar2_matches_the_paper_closed_form(
        p in prop::collection::vec(-5.0..5.0f64, 20),
        q in prop::array::uniform2(-3.2..3.2f64),
        dq in prop::array::uniform2(-3.0..3.0f64),
        ddq in prop::array::uniform2(-10.0..10.0f64),
    ) {
        let e = eval(&table(PLANAR2), &p, &q, &dq, &ddq);
        let expected = mat_vec(&planar2_phi(&q, &dq, &ddq), &planar2_theta(&p));
        assert_close(&e.tau, &expected, 1e-12, "planar2 RNEA vs Φ·θ");
        assert_close(&mat_vec(&e.y, &p), &expected, 1e-12, "planar2 Y·p vs Φ·θ");
    }
}

#[test]
fn pendulum_gravity_torque_by_hand() {
    // One link, point mass 2 kg at x = 0.5 m, gravity −y: τ = m g x cos q (hand-derived).
    let t = table(
        "name = \"p\"\nconvention = \"modified\"\ngravity = [0.0, -9.81, 0.0]\n[[joint]]\nkind = \"revolute\"\nalpha = 0.0\na = 0.0\nd = 0.0\ntheta = 0.0\n",
    );
    let p = cloud_params(&[vec![(2.0, [0.5, 0.0, 0.0])]]);
    for q in [0.0, 0.3, -1.2, 2.5] {
        let e = eval(&t, &p, &[q], &[0.0], &[0.0]);
        assert!(
            (e.tau[0] - 2.0 * 9.81 * 0.5 * q.cos()).abs() < 1e-12,
            "q = {q}: {}",
            e.tau[0]
        );
    }
}

#[test]
fn prismatic_lift_by_hand() {
    // A vertical prismatic joint carrying 3 kg against gravity −z: τ = m (q̈ + g), M = m.
    let t = table(
        "name = \"lift\"\nconvention = \"modified\"\ngravity = [0.0, 0.0, -9.81]\n[[joint]]\nkind = \"prismatic\"\nalpha = 0.0\na = 0.0\nd = 0.0\ntheta = 0.0\n",
    );
    let p = cloud_params(&[vec![(3.0, [0.1, 0.2, 0.0])]]);
    let e = eval(&t, &p, &[0.4], &[1.5], &[2.0]);
    assert!(
        (e.tau[0] - 3.0 * (2.0 + 9.81)).abs() < 1e-12,
        "{}",
        e.tau[0]
    );
    assert!((e.m[0] - 3.0).abs() < 1e-12);
}
