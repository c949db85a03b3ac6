//! Forward dynamics, the inverse mass matrix and the derivative kernels (generated) against
//! independent oracles, on every registered arm, random states and random physically valid
//! parameters (clouds of point masses):
//!
//! - forward dynamics against the reference (CRBA + run-time Cholesky) and inverted by the
//!   generated inverse dynamics; `M⁻¹·M = 1`;
//! - the derivatives against central differences with one Richardson extrapolation, of the
//!   generated kernels themselves and of the reference algorithms (`reference::derivatives`);
//! - a 10 s passive simulation conserves the total energy (kinetic from the generated `M`,
//!   potential from the point masses' heights) to RK4's order.
//!
//! Tolerance 1e-9 relative to the largest entry of the oracle (or 1): the direct evaluations agree
//! to ~cond(M)·ε ≈ 1e-12; the extrapolated differences are accurate to ~1e-11 (truncation
//! `O(h⁴)` at `h = 1e-3`, rounding ~ε/h), so an error in one column's sign, frame or joint is
//! off by O(1).

use dynid::control::Pd;
use dynid::dh::{DhTable, JointKind};
use dynid::model::Model;
use dynid::params::Effects;
use dynid::reference::RefModel;
use dynid::sim::{simulate_from, Integrator, Plant, SimConfig, SimError, SimLog};
use dynid::trajectory::Sine;
use nalgebra::{Matrix3, Vector3};

use crate::common::*;

const REL: f64 = 1e-9;
const SAMPLES: usize = 12;

fn arm_table(m: &dyn Model) -> DhTable {
    DhTable::from_str(m.arm_toml(), m.name()).unwrap_or_else(|e| panic!("{e}"))
}

/// Column `c` of the Jacobian of `f` along `x[c]`: central differences at `h` and `h/2`,
/// extrapolated (Richardson), `h = 1e-3`.
fn jacobian(x: &[f64], n_out: usize, mut f: impl FnMut(&[f64], &mut [f64])) -> Vec<f64> {
    let n = x.len();
    let h = 1e-3;
    let mut jac = vec![0.0; n_out * n];
    let at = |c: usize, dx: f64, f: &mut dyn FnMut(&[f64], &mut [f64])| {
        let mut xs = x.to_vec();
        xs[c] += dx;
        let mut o = vec![0.0; n_out];
        f(&xs, &mut o);
        o
    };
    for c in 0..n {
        let (a, b) = (at(c, h, &mut f), at(c, -h, &mut f));
        let (a2, b2) = (at(c, h / 2.0, &mut f), at(c, -h / 2.0, &mut f));
        for r in 0..n_out {
            let d1 = (a[r] - b[r]) / (2.0 * h);
            let d2 = (a2[r] - b2[r]) / h;
            jac[r * n + c] = (4.0 * d2 - d1) / 3.0;
        }
    }
    jac
}

struct Case {
    m: &'static dyn Model,
    reference: RefModel,
    p: Vec<f64>,
    theta: Vec<f64>,
    clouds: Vec<Cloud>,
}

fn cases(seed: u64) -> Vec<Case> {
    let mut r = rng(seed);
    dynid::arms::all()
        .iter()
        .map(|&m| {
            let clouds = random_clouds(&mut r, m.dof());
            let p = cloud_params(&clouds);
            let mut theta = vec![0.0; m.nb()];
            m.base_params(&p, &mut theta);
            Case {
                m,
                reference: RefModel::new(&arm_table(m)),
                p,
                theta,
                clouds,
            }
        })
        .collect()
}

#[test]
fn forward_dynamics_and_inverse_mass_matrix_match_the_reference_and_invert_id_and_m() {
    let mut r = rng(41);
    for c in cases(4100) {
        let (m, n) = (c.m, c.m.dof());
        let mut ws = c.reference.workspace();
        for _ in 0..SAMPLES {
            let (q, dq, ddq) = random_state(&mut r, n);
            let what = |k: &str| format!("{}: {k}", m.name());
            let mut tau = vec![0.0; n];
            m.inverse_dynamics(&q, &dq, &ddq, &c.theta, &mut tau);
            let mut acc = vec![0.0; n];
            m.forward_dynamics(&q, &dq, &tau, &c.theta, &mut acc);
            assert_close(&acc, &ddq, REL, &what("FD(q, q̇, ID(q, q̇, q̈)) vs q̈"));
            let mut acc_ref = vec![0.0; n];
            c.reference
                .forward_dynamics(&mut ws, &q, &dq, &tau, &c.p, &mut acc_ref);
            assert_close(&acc, &acc_ref, REL, &what("FD vs CRBA + Cholesky"));

            let (mut mm, mut inv, mut inv_ref) =
                (vec![0.0; n * n], vec![0.0; n * n], vec![0.0; n * n]);
            m.mass_matrix(&q, &c.theta, &mut mm);
            m.inverse_mass_matrix(&q, &c.theta, &mut inv);
            c.reference
                .inverse_mass_matrix(&mut ws, &q, &c.p, &mut inv_ref);
            assert_close(&inv, &inv_ref, REL, &what("M⁻¹ vs Cholesky"));
            let mut prod = vec![0.0; n * n];
            for i in 0..n {
                for j in 0..n {
                    prod[i * n + j] = (0..n).map(|k| inv[i * n + k] * mm[k * n + j]).sum();
                }
            }
            let eye: Vec<f64> = (0..n * n)
                .map(|k| f64::from(u8::from(k % (n + 1) == 0)))
                .collect();
            assert_close(&prod, &eye, REL, &what("M⁻¹·M vs 1"));
        }
    }
}

#[test]
fn inverse_dynamics_derivatives_are_the_derivatives_of_inverse_dynamics() {
    let mut r = rng(42);
    for c in cases(4200) {
        let (m, n) = (c.m, c.m.dof());
        let mut ws = c.reference.workspace();
        for _ in 0..SAMPLES {
            let (q, dq, ddq) = random_state(&mut r, n);
            let what = |k: &str| format!("{}: {k}", m.name());
            let mut d = vec![0.0; 2 * n * n];
            m.inverse_dynamics_derivatives(&q, &dq, &ddq, &c.theta, &mut d);
            let id =
                |q: &[f64], dq: &[f64], o: &mut [f64]| m.inverse_dynamics(q, dq, &ddq, &c.theta, o);
            let dq_num = jacobian(&q, n, |x, o| id(x, &dq, o));
            let ddq_num = jacobian(&dq, n, |x, o| id(&q, x, o));
            assert_close(
                &d[..n * n],
                &dq_num,
                REL,
                &what("∂τ/∂q vs differences of ID"),
            );
            assert_close(
                &d[n * n..],
                &ddq_num,
                REL,
                &what("∂τ/∂q̇ vs differences of ID"),
            );
            let mut d_ref = vec![0.0; 2 * n * n];
            c.reference
                .inverse_dynamics_derivatives(&mut ws, &q, &dq, &ddq, &c.p, &mut d_ref);
            assert_close(&d, &d_ref, REL, &what("ID derivatives vs the reference's"));
        }
    }
}

/// The compact scalar form of `inverse_dynamics_derivatives` (the Panda's, since generator 0.3.4;
/// with AVX, four directional derivatives of inverse dynamics per call since 0.3.7) is the fused
/// straight-line kernel to rounding: 1e-12 relative to the largest entry.
#[test]
fn inverse_dynamics_derivatives_compact_form_is_the_fused_kernel() {
    let mut r = rng(45);
    for c in cases(4500) {
        let (m, n) = (c.m, c.m.dof());
        for _ in 0..SAMPLES {
            let (q, dq, ddq) = random_state(&mut r, n);
            let (mut d, mut fused) = (vec![0.0; 2 * n * n], vec![0.0; 2 * n * n]);
            m.inverse_dynamics_derivatives(&q, &dq, &ddq, &c.theta, &mut d);
            m.inverse_dynamics_derivatives_straight(&q, &dq, &ddq, &c.theta, &mut fused);
            assert_close(
                &d,
                &fused,
                1e-12,
                &format!("{}: compact vs fused", m.name()),
            );
        }
    }
}

/// The compact scalar form of `forward_dynamics_derivatives` (with AVX: `q̈`, `M⁻¹` and four
/// directional derivatives of inverse dynamics per call; `codegen/FORMAT.md`) is the fused
/// straight-line kernel to rounding: 1e-12 relative to the largest entry.
#[test]
fn forward_dynamics_derivatives_compact_form_is_the_fused_kernel() {
    let mut r = rng(44);
    for c in cases(4400) {
        let (m, n) = (c.m, c.m.dof());
        for _ in 0..SAMPLES {
            let (q, dq, _) = random_state(&mut r, n);
            let tau: Vec<f64> = random_state(&mut r, n).2.iter().map(|x| 4.0 * x).collect();
            let (mut d, mut fused) = (vec![0.0; 3 * n * n], vec![0.0; 3 * n * n]);
            m.forward_dynamics_derivatives(&q, &dq, &tau, &c.theta, &mut d);
            m.forward_dynamics_derivatives_straight(&q, &dq, &tau, &c.theta, &mut fused);
            assert_close(
                &d,
                &fused,
                1e-12,
                &format!("{}: compact vs fused", m.name()),
            );
        }
    }
}

#[test]
fn forward_dynamics_derivatives_are_the_derivatives_of_forward_dynamics() {
    let mut r = rng(43);
    for c in cases(4300) {
        let (m, n) = (c.m, c.m.dof());
        let mut ws = c.reference.workspace();
        for _ in 0..SAMPLES {
            let (q, dq, _) = random_state(&mut r, n);
            let tau: Vec<f64> = random_state(&mut r, n).2.iter().map(|x| 4.0 * x).collect();
            let what = |k: &str| format!("{}: {k}", m.name());
            let mut d = vec![0.0; 3 * n * n];
            m.forward_dynamics_derivatives(&q, &dq, &tau, &c.theta, &mut d);
            let fd = |q: &[f64], dq: &[f64], t: &[f64], o: &mut [f64]| {
                m.forward_dynamics(q, dq, t, &c.theta, o)
            };
            let dq_num = jacobian(&q, n, |x, o| fd(x, &dq, &tau, o));
            let ddq_num = jacobian(&dq, n, |x, o| fd(&q, x, &tau, o));
            let dtau_num = jacobian(&tau, n, |x, o| fd(&q, &dq, x, o));
            assert_close(
                &d[..n * n],
                &dq_num,
                REL,
                &what("∂q̈/∂q vs differences of FD"),
            );
            assert_close(
                &d[n * n..2 * n * n],
                &ddq_num,
                REL,
                &what("∂q̈/∂q̇ vs differences of FD"),
            );
            assert_close(
                &d[2 * n * n..],
                &dtau_num,
                REL,
                &what("∂q̈/∂τ vs differences of FD"),
            );
            let mut inv = vec![0.0; n * n];
            m.inverse_mass_matrix(&q, &c.theta, &mut inv);
            // The same expressions, emitted in another kernel (other fusions): equal to rounding.
            assert_close(&d[2 * n * n..], &inv, 1e-13, &what("∂q̈/∂τ vs M⁻¹"));
            let mut d_ref = vec![0.0; 3 * n * n];
            c.reference
                .forward_dynamics_derivatives(&mut ws, &q, &dq, &tau, &c.p, &mut d_ref);
            assert_close(&d, &d_ref, REL, &what("FD derivatives vs the reference's"));
        }
    }
}

/// World poses `(R, p)` of the link frames at `q` (modified D-H, as `reference`).
fn link_frames(table: &DhTable, q: &[f64]) -> Vec<(Matrix3<f64>, Vector3<f64>)> {
    let (mut r, mut p) = (Matrix3::identity(), Vector3::zeros());
    let mut out = Vec::new();
    for (i, j) in table.joints.iter().enumerate() {
        let (theta, d) = match j.kind {
            JointKind::Revolute => (q[i] + j.theta, j.d),
            JointKind::Prismatic => (j.theta, q[i] + j.d),
        };
        let ((st, ct), (sa, ca)) = (theta.sin_cos(), j.alpha.sin_cos());
        let rot = Matrix3::new(ct, -st, 0.0, ca * st, ca * ct, -sa, sa * st, sa * ct, ca);
        p += r * Vector3::new(j.a, -sa * d, ca * d);
        r *= rot;
        out.push((r, p));
    }
    out
}

/// `½ q̇ᵀ M q̇ − Σ m gᵀ x` over the point masses.
fn energy(c: &Case, table: &DhTable, q: &[f64], dq: &[f64]) -> f64 {
    let n = q.len();
    let mut mm = vec![0.0; n * n];
    c.m.mass_matrix(q, &c.theta, &mut mm);
    let kinetic: f64 = (0..n)
        .flat_map(|i| (0..n).map(move |j| (i, j)))
        .map(|(i, j)| 0.5 * dq[i] * mm[i * n + j] * dq[j])
        .sum();
    let g = Vector3::from(table.gravity);
    let frames = link_frames(table, q);
    let potential: f64 = c
        .clouds
        .iter()
        .zip(&frames)
        .flat_map(|(cloud, (r, p))| {
            cloud
                .iter()
                .map(move |&(m, x)| -m * g.dot(&(p + r * Vector3::from(x))))
        })
        .sum();
    kinetic + potential
}

/// Largest |E(t) − E(0)| of a passive 10 s RK4 run at step `dt` from `(q0, 0)`.
fn energy_drift(c: &Case, table: &DhTable, q0: &[f64], dt: f64) -> (f64, f64) {
    let n = q0.len();
    let (mut q, mut dq) = (q0.to_vec(), vec![0.0; n]);
    let tau = vec![0.0; n];
    let e0 = energy(c, table, &q, &dq);
    let accel =
        |q: &[f64], dq: &[f64], out: &mut [f64]| c.m.forward_dynamics(q, dq, &tau, &c.theta, out);
    let steps = (10.0 / dt).round() as usize;
    let mut worst: f64 = 0.0;
    let (mut k, mut qs, mut dqs) = ([[0.0; 8]; 8], vec![0.0; n], vec![0.0; n]);
    for _ in 0..steps {
        // k[2s]: q̇ of stage s, k[2s + 1]: q̈.
        for s in 0..4 {
            let f = [0.0, 0.5, 0.5, 1.0][s] * dt;
            for j in 0..n {
                qs[j] = q[j] + if s == 0 { 0.0 } else { f * k[2 * s - 2][j] };
                dqs[j] = dq[j] + if s == 0 { 0.0 } else { f * k[2 * s - 1][j] };
            }
            k[2 * s][..n].copy_from_slice(&dqs);
            accel(&qs, &dqs, &mut k[2 * s + 1][..n]);
        }
        for j in 0..n {
            q[j] += dt / 6.0 * (k[0][j] + 2.0 * k[2][j] + 2.0 * k[4][j] + k[6][j]);
            dq[j] += dt / 6.0 * (k[1][j] + 2.0 * k[3][j] + 2.0 * k[5][j] + k[7][j]);
        }
        worst = worst.max((energy(c, table, &q, &dq) - e0).abs());
    }
    (worst, e0)
}

/// Released from rest, each arm swings for 10 s under gravity alone. RK4's energy error is
/// `O(dt⁴)`: halving the step must divide the drift by about 16 (at least 10: the order is 4 up
/// to the next term), and at 1 ms it must be a small fraction of the energy scale (the largest
/// potential difference the masses see, `Σ m |g| · 2 m`). The SCARA's revolute axes are parallel
/// to gravity: released from rest, only its prismatic joint moves, in free fall, which RK4
/// integrates exactly — its drift is rounding alone (below 1e-9 of the scale), with no order to
/// measure.
#[test]
fn passive_simulation_with_generated_forward_dynamics_conserves_energy_to_rk4_order() {
    let mut r = rng(44);
    let mut measured = 0;
    for c in cases(4400) {
        let table = arm_table(c.m);
        let n = c.m.dof();
        let q0 = random_state(&mut r, n).0;
        let (coarse, _) = energy_drift(&c, &table, &q0, 2e-3);
        let (fine, _) = energy_drift(&c, &table, &q0, 1e-3);
        let scale: f64 = c
            .clouds
            .iter()
            .flatten()
            .map(|&(m, _)| m * 9.81 * 2.0)
            .sum();
        let name = c.m.name();
        eprintln!("{name}: energy drift {coarse:.3e} (2 ms), {fine:.3e} (1 ms), scale {scale:.1}");
        assert!(
            fine < 1e-6 * scale,
            "{name}: drift {fine:.3e} at 1 ms, scale {scale:.3e}"
        );
        if coarse < 1e-9 * scale {
            assert_eq!(name, "scara", "{name}: no drift to measure the order by");
            continue;
        }
        measured += 1;
        assert!(
            coarse / fine > 10.0,
            "{name}: drift ratio {:.2} (2 ms / 1 ms), RK4 gives ~16",
            coarse / fine
        );
    }
    assert!(measured >= 3, "the order was measured on {measured} arms");
}

/// A passive run (zero torque) of `c` from `(q0, 0)` for `duration` s with `integrator` at
/// step `dt`: every step's `(q, q̇)`, or the simulation's error.
fn passive_run(
    c: &Case,
    effects: Option<Effects>,
    q0: &[f64],
    duration: f64,
    dt: f64,
    integrator: Integrator,
) -> Result<SimLog, SimError> {
    let n = q0.len();
    let plant = Plant::new(c.m, c.theta.clone(), effects);
    let mut idle = Pd {
        kp: vec![0.0; n],
        kd: vec![0.0; n],
    };
    let still = Sine {
        amplitude: vec![0.0; n],
        omega: vec![1.0; n],
        offset: q0.to_vec(),
        duration,
    };
    let cfg = SimConfig {
        dt,
        log_every: 1,
        integrator,
        ..SimConfig::default()
    };
    simulate_from(&plant, &mut idle, &still, &cfg, q0, &vec![0.0; n])
}

/// Linearly implicit Euler (the library's, with the generated derivative kernels as Jacobian)
/// is first order: over 1 s released from rest, its state error against RK4 at 0.1 ms (error
/// ~1e-13, the oracle) and its energy error both halve with the step (ratio 2 ± 0.4, the next
/// term's share at 1–2 ms; backward Euler damps at `O(h)`). Over 10 s the library's RK4, through
/// the same `simulate_from`, drifts at `O(h⁴)`. The SCARA's free fall (see above) is skipped.
#[test]
fn linearly_implicit_euler_is_first_order_against_rk4_and_in_energy() {
    let mut r = rng(45);
    for c in cases(4500) {
        let (n, name) = (c.m.dof(), c.m.name());
        if name == "scara" {
            continue;
        }
        let table = arm_table(c.m);
        let q0 = random_state(&mut r, n).0;
        let drift = |log: &SimLog| {
            let e = |k: usize| energy(&c, &table, &log.q[k * n..][..n], &log.dq[k * n..][..n]);
            (1..log.len())
                .map(|k| (e(k) - e(0)).abs())
                .fold(0.0, f64::max)
        };
        let last = |log: &SimLog| log.q[log.q.len() - n..].to_vec();
        let oracle = last(&passive_run(&c, None, &q0, 1.0, 1e-4, Integrator::Rk4).unwrap());
        let errors = |dt: f64| {
            let log = passive_run(&c, None, &q0, 1.0, dt, Integrator::LinearlyImplicitEuler);
            let log = log.unwrap();
            let q = last(&log);
            let err = q
                .iter()
                .zip(&oracle)
                .map(|(a, b)| (a - b).abs())
                .fold(0.0, f64::max);
            (err, drift(&log))
        };
        let ((coarse, e_coarse), (fine, e_fine)) = (errors(2e-3), errors(1e-3));
        let rk4 = [2e-3, 1e-3]
            .map(|dt| drift(&passive_run(&c, None, &q0, 10.0, dt, Integrator::Rk4).unwrap()));
        eprintln!(
            "{name}: implicit Euler 1 s state error {coarse:.3e}, {fine:.3e}, energy error \
             {e_coarse:.3e}, {e_fine:.3e} (2, 1 ms); RK4 10 s energy drift {:.3e}, {:.3e}",
            rk4[0], rk4[1]
        );
        let order1 = 1.6..2.4;
        assert!(
            order1.contains(&(coarse / fine)),
            "{name}: error ratio {}",
            coarse / fine
        );
        let ratio = e_coarse / e_fine;
        assert!(order1.contains(&ratio), "{name}: energy ratio {ratio}");
        assert!(
            rk4[0] / rk4[1] > 10.0,
            "{name}: RK4 energy ratio {}",
            rk4[0] / rk4[1]
        );
    }
}

/// Stiff viscous friction (every mode's rate ≥ 10/h at h = 10 ms): RK4 diverges, as its
/// stability bound (`h·rate` < 2.8) says, while linearly implicit Euler, A-stable, stays
/// finite and only loses energy, as friction must.
#[test]
fn linearly_implicit_euler_is_stable_on_stiff_friction_where_rk4_diverges() {
    let mut r = rng(46);
    let dt = 1e-2;
    for c in cases(4600) {
        let (n, name) = (c.m.dof(), c.m.name());
        let table = arm_table(c.m);
        let q0 = random_state(&mut r, n).0;
        let mut mm = vec![0.0; n * n];
        c.m.mass_matrix(&q0, &c.theta, &mut mm);
        // trace(M) bounds M's largest eigenvalue, so the slowest friction mode is ≥ 10/h.
        let trace: f64 = (0..n).map(|j| mm[j * n + j]).sum();
        let effects = Effects {
            viscous: Some(vec![10.0 * trace / dt; n]),
            ..Effects::default()
        };
        let rk4 = passive_run(&c, Some(effects.clone()), &q0, 2.0, dt, Integrator::Rk4);
        assert!(
            matches!(rk4, Err(SimError::Diverged { .. })),
            "{name}: RK4 {:?}",
            rk4.map(|l| l.len())
        );
        let log = passive_run(
            &c,
            Some(effects),
            &q0,
            2.0,
            dt,
            Integrator::LinearlyImplicitEuler,
        )
        .unwrap_or_else(|e| panic!("{name}: {e}"));
        let e = |k: usize| energy(&c, &table, &log.q[k * n..][..n], &log.dq[k * n..][..n]);
        let e0 = e(0);
        let rise = (1..log.len()).map(|k| e(k) - e0).fold(f64::MIN, f64::max);
        assert!(
            rise < 1e-9 * e0.abs().max(1.0),
            "{name}: energy rose by {rise:.3e}"
        );
    }
}
