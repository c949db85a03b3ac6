//! `dynid payload` on simulated payloads. The oracle is the simulation itself: torques of the
//! arm with the payload lumped into its last link (reference Newton–Euler, `Plant`), a payload
//! drawn at random (0.5–5 kg, centre of mass within 15 cm of the flange, a cloud of point masses
//! so it is a real body). Tolerances: noise-free data must give the payload to rounding (1e-6
//! relative, the consistency program's regulariser pulls by ~1e-6 of the data weight); noisy
//! data the targets (median mass error ≤ 2 %, COM ≤ 5 mm) with margin measured below.

use dynid::data::Trajectory;
use dynid::dh::DhTable;
use dynid::params::{Effects, InertialParams};
use dynid::payload::{fit, identify_payload, PayloadError, PayloadOptions};
use dynid::reference::RefModel;
use rand::Rng;

use crate::common::*;

fn puma() -> DhTable {
    DhTable::from_path(concat!(env!("CARGO_MANIFEST_DIR"), "/..", "/arms/puma560.toml").as_ref())
        .unwrap()
}

/// A payload: `(φ about the last link's origin, mass, com)`.
fn random_payload(rng: &mut impl Rng) -> ([f64; 10], f64, [f64; 3]) {
    let m: f64 = rng.gen_range(0.5..5.0);
    let dir: [f64; 3] = [(); 3].map(|_| rng.gen_range(-1.0..1.0));
    let norm = dir.iter().map(|v| v * v).sum::<f64>().sqrt().max(1e-9);
    let r = rng.gen_range(0.0..0.15);
    let c = dir.map(|v| v / norm * r);
    let mut cloud = Vec::new();
    for _ in 0..4 {
        let off: [f64; 3] = [(); 3].map(|_| rng.gen_range(-0.05..0.05));
        cloud.push((m / 4.0, [c[0] + off[0], c[1] + off[1], c[2] + off[2]]));
    }
    let p = cloud_params(&[cloud]);
    let mut phi = [0.0; 10];
    phi.copy_from_slice(&p);
    (
        phi,
        phi[9],
        [phi[6] / phi[9], phi[7] / phi[9], phi[8] / phi[9]],
    )
}

/// A multi-sine motion: five harmonics of 0.1 Hz per joint, `seconds` at 200 Hz from `t0`.
fn motion(rng: &mut impl Rng, n: usize) -> Vec<[f64; 10]> {
    (0..n)
        .map(|_| [(); 10].map(|_| rng.gen_range(-0.35..0.35)))
        .collect()
}

fn state(coef: &[[f64; 10]], t: f64) -> (Vec<f64>, Vec<f64>, Vec<f64>) {
    let (mut q, mut dq, mut ddq) = (vec![], vec![], vec![]);
    for c in coef {
        let (mut a, mut b, mut d) = (0.0, 0.0, 0.0);
        for h in 0..5 {
            let w = 2.0 * std::f64::consts::PI * 0.1 * (h + 1) as f64;
            let (s, co) = (w * t).sin_cos();
            let (x, y) = (c[2 * h] / (h + 1) as f64, c[2 * h + 1] / (h + 1) as f64);
            a += x * s + y * co;
            b += w * (x * co - y * s);
            d += -w * w * (x * s + y * co);
        }
        q.push(a);
        dq.push(b);
        ddq.push(d);
    }
    (q, dq, ddq)
}

/// Noise of a simulated measurement.
#[derive(Clone, Copy)]
struct Noise {
    /// Torque noise σ (N·m), white.
    tau: f64,
    /// Encoder resolution (rad); with noise the file has no dq/ddq columns.
    quantum: f64,
}

/// A run of `seconds` from `t0` of arm parameters `p` (+ effects): the file a user would log.
#[allow(clippy::too_many_arguments)]
fn run(
    table: &DhTable,
    p: &[f64],
    effects: &Effects,
    coef: &[[f64; 10]],
    t0: f64,
    seconds: f64,
    noise: Option<Noise>,
    scale: Option<&[f64]>,
    rng: &mut impl Rng,
) -> Trajectory {
    let n = table.dof();
    let model = RefModel::new(table);
    let mut ws = model.workspace();
    let dt = 0.005;
    let len = (seconds / dt) as usize;
    let mut tr = Trajectory {
        source: "sim.csv".into(),
        dof: n,
        t: vec![],
        q: vec![],
        dq: if noise.is_some() { None } else { Some(vec![]) },
        ddq: if noise.is_some() { None } else { Some(vec![]) },
        tau: Some(vec![]),
    };
    let gauss = |rng: &mut dyn rand::RngCore, s: f64| {
        let (u1, u2): (f64, f64) = (rng.gen_range(1e-12..1.0), rng.gen_range(0.0..1.0));
        s * (-2.0 * u1.ln()).sqrt() * (2.0 * std::f64::consts::PI * u2).cos()
    };
    for k in 0..len {
        let t = t0 + k as f64 * dt;
        let (q, dq, ddq) = state(coef, t);
        let mut tau = vec![0.0; n];
        model.inverse_dynamics(&mut ws, &q, &dq, &ddq, p, &mut tau);
        for j in 0..n {
            tau[j] = effects.load(j, dq[j], tau[j] + effects.torque(j, q[j], dq[j], ddq[j]));
            if let Some(nz) = noise {
                tau[j] += gauss(rng, nz.tau);
            }
            if let Some(s) = scale {
                tau[j] /= s[j];
            }
        }
        // Every file's clock starts at 0, as a logger's would.
        tr.t.push(t - t0);
        match noise {
            Some(nz) => {
                tr.q.extend(q.iter().map(|v| (v / nz.quantum).round() * nz.quantum))
            }
            None => {
                tr.q.extend(&q);
                tr.dq.as_mut().unwrap().extend(&dq);
                tr.ddq.as_mut().unwrap().extend(&ddq);
            }
        }
        tr.tau.as_mut().unwrap().extend(&tau);
    }
    tr
}

struct Case {
    table: DhTable,
    arm: Vec<f64>,
    effects: Effects,
    phi: [f64; 10],
    mass: f64,
    com: [f64; 3],
    coef: Vec<[f64; 10]>,
}

fn case(rng: &mut impl Rng) -> Case {
    let table = puma();
    let n = table.dof();
    let arm = cloud_params(&random_clouds(rng, n));
    let effects = Effects {
        viscous: Some((0..n).map(|_| rng.gen_range(0.1..2.0)).collect()),
        coulomb: Some((0..n).map(|_| rng.gen_range(0.1..1.5)).collect()),
        ..Effects::default()
    };
    let (phi, mass, com) = random_payload(rng);
    let coef = motion(rng, n);
    Case {
        table,
        arm,
        effects,
        phi,
        mass,
        com,
        coef,
    }
}

impl Case {
    fn loaded_params(&self) -> Vec<f64> {
        let mut p = self.arm.clone();
        let k = p.len() - 10;
        for i in 0..10 {
            p[k + i] += self.phi[i];
        }
        p
    }
    fn identified(&self) -> InertialParams {
        InertialParams::from_full_vector(&self.arm, self.effects.clone())
    }
}

fn com_error(a: &[f64; 3], b: &[f64; 3]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).powi(2))
        .sum::<f64>()
        .sqrt()
}

#[test]
fn noise_free_runs_give_the_payload_to_rounding_with_and_without_a_shifted_twin() {
    let mut rng = rng(390);
    for _ in 0..3 {
        let c = case(&mut rng);
        let loaded = run(
            &c.table,
            &c.loaded_params(),
            &c.effects,
            &c.coef,
            0.0,
            20.0,
            None,
            None,
            &mut rng,
        );
        // The twin starts 0.735 s earlier and ends later: found by the alignment.
        let twin = run(
            &c.table, &c.arm, &c.effects, &c.coef, -0.735, 22.0, None, None, &mut rng,
        );
        for twins in [vec![], vec![twin]] {
            let with = !twins.is_empty();
            let est = identify_payload(
                &c.table,
                &c.identified(),
                vec![loaded.clone()],
                twins,
                &PayloadOptions::default(),
            )
            .unwrap();
            let (m, com, _) = fit::physical(&c.phi);
            assert!(
                (est.mass - m).abs() < 1e-6 * m,
                "twin {with}: {} vs {m}",
                est.mass
            );
            assert!(
                com_error(&est.com, &com) < 1e-6,
                "twin {with}: {:?} vs {:?}",
                est.com,
                com
            );
            let (_, _, i_true) = fit::physical(&c.phi);
            for (k, (a, b)) in est.inertia.iter().zip(&i_true).enumerate() {
                assert!((a - b).abs() < 1e-6 * m, "inertia {k}");
            }
            if with {
                let a = est.runs[0].alignment.as_ref().unwrap();
                assert!((a.shift_s - 0.735).abs() < 1e-6, "shift {}", a.shift_s);
            }
        }
    }
}

/// The accuracy targets on noisy data (torque noise 0.05 N·m, 2¹⁶-count encoders,
/// derivatives estimated, friction in the arm, the arm model 5 % off so only the twin makes the
/// difference exact): prints the statistics docs/payload.md quotes.
#[test]
fn noisy_runs_meet_the_accuracy_targets_and_sigma_covers_the_error() {
    let mut rng = rng(3901);
    let noise = Noise {
        tau: 0.05,
        quantum: 2.0 * std::f64::consts::PI / 65536.0,
    };
    let cases = 20;
    let (mut em, mut ec, mut cover_m, mut cover_c) = (vec![], vec![], 0, 0);
    for _ in 0..cases {
        let c = case(&mut rng);
        let loaded = run(
            &c.table,
            &c.loaded_params(),
            &c.effects,
            &c.coef,
            0.0,
            30.0,
            Some(noise),
            None,
            &mut rng,
        );
        let twin = run(
            &c.table,
            &c.arm,
            &c.effects,
            &c.coef,
            -0.4,
            31.0,
            Some(noise),
            None,
            &mut rng,
        );
        let off: Vec<f64> = c
            .arm
            .iter()
            .map(|v| v * rng.gen_range(0.95..1.05))
            .collect();
        let arm = InertialParams::from_full_vector(&off, c.effects.clone());
        let est = identify_payload(
            &c.table,
            &arm,
            vec![loaded],
            vec![twin],
            &PayloadOptions::default(),
        )
        .unwrap();
        let e_m = (est.mass - c.mass).abs();
        let e_c = com_error(&est.com, &c.com);
        em.push(e_m / c.mass);
        ec.push(e_c);
        // Coverage at 2σ (≈ 95 % for a Gaussian); the COM's as the largest axis error in σ.
        if e_m <= 2.0 * est.sigma.mass {
            cover_m += 1;
        }
        let worst = (0..3)
            .map(|k| (est.com[k] - c.com[k]).abs() / est.sigma.com[k].max(1e-300))
            .fold(0.0, f64::max);
        if worst <= 2.0 {
            cover_c += 1;
        }
    }
    let median = |v: &mut Vec<f64>| {
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    let (mm, mc) = (median(&mut em), median(&mut ec));
    eprintln!(
        "payload noisy: median mass error {:.3} %, max {:.3} %; median COM error {:.2} mm, max {:.2} mm; 2σ covers mass {cover_m}/{cases}, COM {cover_c}/{cases}",
        100.0 * mm,
        100.0 * em.last().unwrap(),
        1e3 * mc,
        1e3 * ec.last().unwrap()
    );
    assert!(mm <= 0.01, "median mass error {mm}");
    assert!(mc <= 0.002, "median COM error {mc}");
    assert!(
        cover_m as f64 >= 0.9 * cases as f64 - 1.0,
        "σ covers the mass error in {cover_m}/{cases}"
    );
    assert!(
        cover_c as f64 >= 0.9 * cases as f64 - 1.0,
        "σ covers the COM error in {cover_c}/{cases}"
    );
}

/// Drive gains off by up to ±20 % per joint, a payload of known mass: the calibrated scales are
/// within 1 % of the truth, and on a held-out loaded/unloaded pair (another motion) the scales
/// give the payload's mass within 1 %.
#[test]
fn a_known_mass_calibrates_drive_gains_that_hold_on_another_run() {
    let mut rng = rng(3902);
    let noise = Noise {
        tau: 0.02,
        quantum: 2.0 * std::f64::consts::PI / 65536.0,
    };
    for _ in 0..3 {
        let mut c = case(&mut rng);
        // A payload heavy and off-centre enough to load every joint.
        c.phi.iter_mut().for_each(|v| *v *= 3.0);
        c.mass *= 3.0;
        let n = c.table.dof();
        let s: Vec<f64> = (0..n).map(|_| rng.gen_range(0.8..1.2)).collect();
        let loaded = run(
            &c.table,
            &c.loaded_params(),
            &c.effects,
            &c.coef,
            0.0,
            30.0,
            Some(noise),
            Some(&s),
            &mut rng,
        );
        let twin = run(
            &c.table,
            &c.arm,
            &c.effects,
            &c.coef,
            0.0,
            30.0,
            Some(noise),
            Some(&s),
            &mut rng,
        );
        let opts = PayloadOptions {
            mass: Some(c.mass),
            ..Default::default()
        };
        let est =
            identify_payload(&c.table, &c.identified(), vec![loaded], vec![twin], &opts).unwrap();
        let k = est.torque_scale.clone().unwrap();
        for j in 0..n {
            if est.uncalibrated_joints.contains(&(j + 1)) {
                continue;
            }
            assert!(
                (k[j] / s[j] - 1.0).abs() < 0.01,
                "joint {}: {} vs {}",
                j + 1,
                k[j],
                s[j]
            );
        }
        eprintln!(
            "drive gains: worst relative error {:.3} %, uncalibrated {:?}",
            100.0
                * (0..n)
                    .filter(|j| !est.uncalibrated_joints.contains(&(j + 1)))
                    .map(|j| (k[j] / s[j] - 1.0).abs())
                    .fold(0.0, f64::max),
            est.uncalibrated_joints
        );
        // Held out: another motion, its mass estimated with the calibrated scales.
        let coef = motion(&mut rng, n);
        let l2 = run(
            &c.table,
            &c.loaded_params(),
            &c.effects,
            &coef,
            0.0,
            30.0,
            Some(noise),
            Some(&s),
            &mut rng,
        );
        let u2 = run(
            &c.table,
            &c.arm,
            &c.effects,
            &coef,
            0.0,
            30.0,
            Some(noise),
            Some(&s),
            &mut rng,
        );
        let opts = PayloadOptions {
            torque_scale: Some(k),
            ..Default::default()
        };
        let held = identify_payload(&c.table, &c.identified(), vec![l2], vec![u2], &opts).unwrap();
        assert!(
            (held.mass / c.mass - 1.0).abs() < 0.01,
            "held-out mass {} vs {}",
            held.mass,
            c.mass
        );
    }
}

#[test]
fn a_twin_of_another_motion_is_an_error_saying_by_how_much() {
    let mut rng = rng(3903);
    let c = case(&mut rng);
    let loaded = run(
        &c.table,
        &c.loaded_params(),
        &c.effects,
        &c.coef,
        0.0,
        20.0,
        None,
        None,
        &mut rng,
    );
    let other = motion(&mut rng, c.table.dof());
    let twin = run(
        &c.table, &c.arm, &c.effects, &other, 0.0, 20.0, None, None, &mut rng,
    );
    let e = identify_payload(
        &c.table,
        &c.identified(),
        vec![loaded.clone()],
        vec![twin],
        &PayloadOptions::default(),
    )
    .unwrap_err();
    assert!(matches!(e, PayloadError::Mismatch(_)), "{e}");
    let msg = e.to_string();
    assert!(msg.contains("differs by") && msg.contains('%'), "{msg}");
    // A run too short for ten parameters is an error, a barely moving one a warning naming them.
    let short = loaded.slice(0, 10);
    assert!(identify_payload(
        &c.table,
        &c.identified(),
        vec![short],
        vec![],
        &PayloadOptions::default()
    )
    .is_err());
    let still: Vec<[f64; 10]> = c.coef.iter().map(|r| r.map(|v| v * 0.01)).collect();
    let slow = run(
        &c.table,
        &c.loaded_params(),
        &c.effects,
        &still,
        0.0,
        5.0,
        Some(Noise {
            tau: 0.05,
            quantum: 1e-5,
        }),
        None,
        &mut rng,
    );
    let est = identify_payload(
        &c.table,
        &c.identified(),
        vec![slow],
        vec![],
        &PayloadOptions::default(),
    )
    .unwrap();
    assert!(
        est.warnings
            .iter()
            .any(|w| w.contains("poorly excited") && w.contains('σ')),
        "{:?}",
        est.warnings
    );
}

#[test]
fn the_cli_writes_payload_json_params_and_report() {
    let mut rng = rng(3904);
    let c = case(&mut rng);
    let dir = tempfile::tempdir().unwrap();
    let write = |name: &str, tr: &Trajectory| {
        let p = dir.path().join(name);
        let mut f = std::fs::File::create(&p).unwrap();
        tr.write_csv(&mut f).unwrap();
        p
    };
    let l = write(
        "loaded.csv",
        &run(
            &c.table,
            &c.loaded_params(),
            &c.effects,
            &c.coef,
            0.0,
            15.0,
            None,
            None,
            &mut rng,
        ),
    );
    let u = write(
        "twin.csv",
        &run(
            &c.table, &c.arm, &c.effects, &c.coef, 0.0, 15.0, None, None, &mut rng,
        ),
    );
    let params = dir.path().join("arm.params.toml");
    std::fs::write(&params, c.identified().to_toml(&[])).unwrap();
    let out = dir.path().join("p");
    let s = |p: &std::path::Path| p.to_str().unwrap().to_string();
    let arm = concat!(env!("CARGO_MANIFEST_DIR"), "/..", "/arms/puma560.toml");
    let o = dynid(&[
        "payload",
        "--arm",
        arm,
        "--params",
        &s(&params),
        "--data",
        &s(&l),
        "--unloaded",
        &s(&u),
        "--out",
        &s(&out),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let j: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("payload.json")).unwrap()).unwrap();
    assert!((j["mass"].as_f64().unwrap() - c.mass).abs() < 1e-6 * c.mass);
    assert_eq!(j["com"].as_array().unwrap().len(), 3);
    assert_eq!(j["inertia"].as_array().unwrap().len(), 6);
    assert_eq!(j["sigma"]["inertia"].as_array().unwrap().len(), 6);
    assert!(j["sigma"]["mass"].is_number());
    for f in ["payload.params.toml", "loaded.params.toml", "report.md"] {
        assert!(out.join(f).is_file(), "{f}");
    }
    // The whole loaded file loads and its last link is the arm's plus the payload.
    let loaded =
        InertialParams::from_path(&out.join("loaded.params.toml"), 6, &Default::default()).unwrap();
    let want = c.loaded_params();
    assert_close(&loaded.full_vector(), &want, 1e-6, "loaded.params.toml");
    // With --mass: torque_scale has one entry per joint.
    let o = dynid(&[
        "payload",
        "--arm",
        arm,
        "--params",
        &s(&params),
        "--data",
        &s(&l),
        "--unloaded",
        &s(&u),
        "--mass",
        &format!("{}", c.mass),
        "--out",
        &s(&out),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let j: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("payload.json")).unwrap()).unwrap();
    assert_eq!(j["torque_scale"].as_array().unwrap().len(), 6);
    // Bad input: a wrong --torque-scale count, a negative mass: exit 2 with the field named.
    let o = dynid(&[
        "payload",
        "--arm",
        arm,
        "--params",
        &s(&params),
        "--data",
        &s(&l),
        "--torque-scale",
        "1,1",
        "--out",
        &s(&out),
    ]);
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("--torque-scale"));
    let o = dynid(&[
        "payload",
        "--arm",
        arm,
        "--params",
        &s(&params),
        "--data",
        &s(&l),
        "--mass=-1",
        "--out",
        &s(&out),
    ]);
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("--mass"));
}

/// `payload.urdf`'s new fixed link, imported again, adds exactly the payload to the last D-H
/// link (the import lumps fixed children into it): on random trees with every joint kind and
/// on TIAGo's arm.
#[test]
fn the_payload_link_imports_back_as_the_payload_on_the_last_link() {
    use dynid::urdf::{attach::attach_body, import_str, ImportOptions};
    let mut rng = rng(3905);
    let mut cases: Vec<(String, ImportOptions)> = (0..10)
        .map(|case| {
            let robot = super::urdf::random_robot(&mut rng, 1 + case % 6);
            let opts = ImportOptions {
                tip: Some(super::urdf::tip_of(&robot)),
                ..Default::default()
            };
            (robot.urdf(), opts)
        })
        .collect();
    let tiago = concat!(
        concat!(env!("CARGO_MANIFEST_DIR"), "/.."),
        "/data/real/tiago_figaroh/tiago.urdf"
    );
    cases.push((
        std::fs::read_to_string(tiago).unwrap(),
        ImportOptions::default(),
    ));
    for (i, (text, opts)) in cases.iter().enumerate() {
        let before = import_str(text, "r.urdf", opts).unwrap();
        let (phi, m, com) = random_payload(&mut rng);
        let (_, _, inertia) = fit::physical(&phi);
        let out = attach_body(text, "r.urdf", opts, "payload", m, com, inertia).unwrap();
        let after = import_str(&out, "r.urdf", opts).unwrap();
        assert_eq!(after.table, before.table, "case {i}: geometry changed");
        let (a, b) = (before.params.full_vector(), after.params.full_vector());
        let n = a.len();
        let mut want = a.clone();
        for k in 0..10 {
            want[n - 10 + k] += phi[k];
        }
        assert_close(
            &b,
            &want,
            1e-9,
            &format!("case {i}: the last link carries the payload"),
        );
        assert!(out.starts_with(&text[..text.rfind("</robot>").unwrap()]));
    }
}

/// `identify --torque-scale` now applies to CSVs: data logged at half the torque, scaled by 2
/// (exact in binary), identify exactly as the original.
#[test]
fn identify_torque_scale_scales_csv_torque() {
    let set = concat!(
        concat!(env!("CARGO_MANIFEST_DIR"), "/.."),
        "/data/sim/planar2_paper_friction"
    );
    let dir = tempfile::tempdir().unwrap();
    let mut tr =
        Trajectory::from_path(format!("{set}/excite_noisy.csv.gz").as_ref(), Some(2)).unwrap();
    tr.tau.as_mut().unwrap().iter_mut().for_each(|v| *v *= 0.5);
    let half = dir.path().join("half.csv");
    tr.write_csv(&mut std::fs::File::create(&half).unwrap())
        .unwrap();
    let val = format!("{set}/validate_noisy.csv.gz");
    let s = |p: &std::path::Path| p.to_str().unwrap().to_string();
    let (a, b) = (dir.path().join("a"), dir.path().join("b"));
    let o = dynid(&[
        "identify",
        "--arm",
        "planar2",
        "--data",
        &format!("{set}/excite_noisy.csv.gz"),
        "--validate",
        &val,
        "--effects",
        "viscous,coulomb",
        "--cutoff",
        "5",
        "--out",
        &s(&a),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let o = dynid(&[
        "identify",
        "--arm",
        "planar2",
        "--data",
        &s(&half),
        "--validate",
        &val,
        "--effects",
        "viscous,coulomb",
        "--cutoff",
        "5",
        "--torque-scale",
        "2,2",
        "--out",
        &s(&b),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let read = |d: &std::path::Path| {
        InertialParams::from_path(&d.join("identified.params.toml"), 2, &Default::default())
            .unwrap()
            .full_vector()
    };
    assert_close(
        &read(&b),
        &read(&a),
        1e-9,
        "identify on torque/2 with --torque-scale 2",
    );
}
