//! `dynid excite` on shipped URDFs: the contract command (feasible, within the limits on the
//! file's grid, derivatives consistent, condition number reproduced by an independent
//! regressor), infeasible limits and bad input.

use std::path::{Path, PathBuf};

use nalgebra::DMatrix;
use rand::Rng;

use crate::common::{dynid, rng};

fn urdf(name: &str) -> PathBuf {
    Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/.."))
        .join("data/urdf")
        .join(name)
}

struct Csv {
    header: String,
    rows: Vec<Vec<f64>>,
}

fn read_csv(path: &Path) -> Csv {
    let (header, rows) = crate::common::read_csv(path);
    Csv { header, rows }
}

/// The UR5e-like limits of the contract: ±3 rad (shoulder lift −3…0, elbow ±2.5), 2 rad/s, 4 rad/s².
const Q_MIN: [f64; 6] = [-3.0, -3.0, -2.5, -3.0, -3.0, -3.0];
const Q_MAX: [f64; 6] = [3.0, 0.0, 2.5, 3.0, 3.0, 3.0];
const DQ_MAX: f64 = 2.0;
const DDQ_MAX: f64 = 4.0;

fn join(v: &[f64]) -> String {
    v.iter().map(f64::to_string).collect::<Vec<_>>().join(",")
}

fn contract(out: &Path, extra: &[&str]) -> std::process::Output {
    let arm = urdf("ur5e.urdf");
    let (lo, hi) = (join(&Q_MIN), join(&Q_MAX));
    let mut args = vec![
        "excite",
        "--arm",
        arm.to_str().unwrap(),
        "--kind",
        "fourier",
        "--period",
        "10",
        "--q-min",
        &lo,
        "--q-max",
        &hi,
        "--dq-max",
        "2",
        "--ddq-max",
        "4",
        "--out",
        out.to_str().unwrap(),
    ];
    args.extend_from_slice(extra);
    dynid(&args)
}

/// Greedy independent columns of `a` in order (modified Gram–Schmidt; the test's own rank test).
fn independent(a: &DMatrix<f64>, tol: f64) -> Vec<usize> {
    let mut basis: Vec<nalgebra::DVector<f64>> = Vec::new();
    let mut keep = Vec::new();
    for k in 0..a.ncols() {
        let n = a.column(k).norm();
        if n < 1e-12 {
            continue;
        }
        let mut v = a.column(k) / n;
        for _ in 0..2 {
            for b in &basis {
                let d = b.dot(&v);
                v -= b * d;
            }
        }
        if v.norm() > tol {
            keep.push(k);
            basis.push(v.normalize());
        }
    }
    keep
}

/// Full regressor rows plus effect columns (viscous, Coulomb `tanh(q̇/v)` with `v` = 1 % of the
/// RMS velocity, offset, armature) for states `(q, q̇, q̈)`: the test's own observation matrix.
fn observation(
    model: &dynid::reference::RefModel,
    states: &[[Vec<f64>; 3]],
    rms: &[f64],
) -> DMatrix<f64> {
    let n = model.dof();
    let np = model.np();
    let mut ws = model.workspace();
    let mut y = vec![0.0; n * np];
    let mut w = DMatrix::zeros(states.len() * n, np + 4 * n);
    for (s, [q, dq, ddq]) in states.iter().enumerate() {
        model.regressor(&mut ws, q, dq, ddq, &mut y);
        for i in 0..n {
            let r = s * n + i;
            for c in 0..np {
                w[(r, c)] = y[i * np + c];
            }
            w[(r, np + i)] = dq[i];
            w[(r, np + n + i)] = (dq[i] / (0.01 * rms[i])).tanh();
            w[(r, np + 2 * n + i)] = 1.0;
            w[(r, np + 3 * n + i)] = ddq[i];
        }
    }
    w
}

#[test]
fn excite_contract_on_a_6dof_urdf_is_feasible_and_reproducible() {
    let dir = tempfile::tempdir().unwrap();
    let out = contract(dir.path(), &["--generations", "40"]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let csv = read_csv(&dir.path().join("trajectory.csv"));
    let want: Vec<String> = std::iter::once("t".to_string())
        .chain(
            ["q", "dq", "ddq"]
                .iter()
                .flat_map(|p| (1..=6).map(move |j| format!("{p}{j}"))),
        )
        .collect();
    assert_eq!(csv.header, want.join(","));
    let rows = &csv.rows;
    // 10 s at the default 500 Hz, both ends included
    assert_eq!(rows.len(), 5001);
    let h = rows[1][0] - rows[0][0];
    assert!((h - 0.002).abs() < 1e-12);

    // limits on the file's grid, 1 % tolerance; starts and ends at rest
    for r in rows {
        for j in 0..6 {
            let span = Q_MAX[j] - Q_MIN[j];
            assert!(r[1 + j] >= Q_MIN[j] - 0.01 * span && r[1 + j] <= Q_MAX[j] + 0.01 * span);
            assert!(r[7 + j].abs() <= 1.01 * DQ_MAX);
            assert!(r[13 + j].abs() <= 1.01 * DDQ_MAX);
        }
    }
    for r in [&rows[0], &rows[rows.len() - 1]] {
        assert!(r[7..19].iter().all(|v| v.abs() < 1e-9), "{r:?}");
    }

    // q̇, q̈ are the derivatives of q: central differences over 2h = 4 ms err by h²/6·sup|q'''|;
    // with |q'''| < 100 rad/s³ (a 5-harmonic series at 0.5 Hz under 4 rad/s²) that is < 7e-5.
    let mut worst = [0.0_f64; 2];
    for k in 1..rows.len() - 1 {
        for j in 0..6 {
            let fd_v = (rows[k + 1][1 + j] - rows[k - 1][1 + j]) / (2.0 * h);
            let fd_a = (rows[k + 1][7 + j] - rows[k - 1][7 + j]) / (2.0 * h);
            worst[0] = worst[0].max((fd_v - rows[k][7 + j]).abs());
            worst[1] = worst[1].max((fd_a - rows[k][13 + j]).abs());
        }
    }
    assert!(worst[0] < 1e-4 && worst[1] < 1e-3, "{worst:?}");

    // cond from the file, the test's own way: full reference regressor and effect columns,
    // greedy independent columns in parameter order found on random states, SVD of the file's
    // matrix. The library builds the same definition through other code (numerical base,
    // structural merges, Gram eigenvalues); 1e-6 relative covers rounding (cond ≈ 1e2).
    let imported =
        dynid::urdf::import_file(&urdf("ur5e.urdf"), &dynid::urdf::ImportOptions::default())
            .unwrap();
    let model = dynid::reference::RefModel::new(&imported.table);
    let states: Vec<[Vec<f64>; 3]> = rows
        .iter()
        .map(|r| [r[1..7].to_vec(), r[7..13].to_vec(), r[13..19].to_vec()])
        .collect();
    let rms: Vec<f64> = (0..6)
        .map(|j| (rows.iter().map(|r| r[7 + j].powi(2)).sum::<f64>() / rows.len() as f64).sqrt())
        .collect();
    let mut g = rng(99);
    let random: Vec<[Vec<f64>; 3]> = (0..200)
        .map(|_| {
            let mut v = || (0..6).map(|_| g.gen_range(-3.0..3.0)).collect::<Vec<f64>>();
            [v(), v(), v()]
        })
        .collect();
    let keep = independent(&observation(&model, &random, &[1.0; 6]), 1e-6);
    let w = observation(&model, &states, &rms);
    let w = DMatrix::from_columns(&keep.iter().map(|&k| w.column(k)).collect::<Vec<_>>());
    let sv = w.svd(false, false).singular_values;
    let cond = sv.max() / sv.min();
    let doc: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("excitation.json")).unwrap())
            .unwrap();
    let reported = doc["cond"].as_f64().unwrap();
    assert_eq!(doc["columns"].as_array().unwrap().len(), keep.len());
    assert!(
        (reported / cond - 1.0).abs() < 1e-6,
        "reported {reported}, independent {cond}"
    );
    assert!(reported < 1e3, "{reported}");
    for f in [
        "report.md",
        "q.svg",
        "dq.svg",
        "ddq.svg",
        "singular_values.svg",
    ] {
        assert!(dir.path().join(f).exists(), "{f}");
    }
}

/// The Panda URDF's own limits (position, velocity, safety controller) with the published
/// accelerations from a limits file: feasible, and the limits used are the URDF's.
#[test]
fn excite_uses_the_urdf_limits() {
    let dir = tempfile::tempdir().unwrap();
    let arm = urdf("panda.urdf");
    let lim = urdf("panda.limits.toml");
    let out = dynid(&[
        "excite",
        "--arm",
        arm.to_str().unwrap(),
        "--limits",
        lim.to_str().unwrap(),
        "--generations",
        "5",
        "--out",
        dir.path().to_str().unwrap(),
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let doc: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("excitation.json")).unwrap())
            .unwrap();
    let j4 = &doc["limits"]["joints"][3];
    assert_eq!(j4["q_min"], -3.0718);
    assert_eq!(j4["q_max"], -0.0698);
    assert_eq!(j4["dq_max"], 2.175);
    assert_eq!(j4["ddq_max"], 12.5);
    assert_eq!(doc["feasible"], true);
}

/// Limits no design can meet end in a non-zero exit that names the limit, and write nothing.
#[test]
fn excite_infeasible_limits_exit_non_zero() {
    let dir = tempfile::tempdir().unwrap();
    let imported =
        dynid::urdf::import_file(&urdf("ur5e.urdf"), &dynid::urdf::ImportOptions::default())
            .unwrap();
    let params = dir.path().join("ur5e.params.toml");
    std::fs::write(&params, &imported.params_toml).unwrap();
    let out_dir = dir.path().join("out");
    // 1 N·m at the shoulder cannot hold the arm against gravity whatever the motion
    let out = contract(
        &out_dir,
        &[
            "--params",
            params.to_str().unwrap(),
            "--tau-max",
            "150,1,150,28,28,28",
            "--generations",
            "5",
        ],
    );
    assert_eq!(out.status.code(), Some(1));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("joint 2") && err.contains("tau_max"), "{err}");
    assert!(!out_dir.join("trajectory.csv").exists());
}

/// Bad input: each a clear error (exit 2) naming the joint and the value.
#[test]
fn excite_bad_limits_name_joint_and_value() {
    let dir = tempfile::tempdir().unwrap();
    let ur5e = urdf("ur5e.urdf");
    // the UR5e URDF without its effort limits: no acceleration limit can be derived
    let no_effort = dir.path().join("no_effort.urdf");
    let text = std::fs::read_to_string(&ur5e).unwrap();
    let stripped = text
        .replace("effort=\"150\"", "effort=\"0\"")
        .replace("effort=\"28\"", "effort=\"0\"");
    assert_ne!(stripped, text);
    std::fs::write(&no_effort, stripped).unwrap();
    let run_on = |arm: &Path, extra: &[&str]| {
        let mut args = vec![
            "excite",
            "--arm",
            arm.to_str().unwrap(),
            "--out",
            dir.path().to_str().unwrap(),
        ];
        args.extend_from_slice(extra);
        let out = dynid(&args);
        assert_eq!(out.status.code(), Some(2), "{extra:?}");
        String::from_utf8_lossy(&out.stderr).into_owned()
    };
    let run = |extra: &[&str]| run_on(&ur5e, extra);
    // no acceleration limit anywhere, and no effort to derive one from
    let e = run_on(&no_effort, &[]);
    assert!(
        e.contains("joint 1 (shoulder_pan_joint)")
            && e.contains("acceleration limit")
            && e.contains("no effort limit")
            && e.contains("--ddq-max"),
        "{e}"
    );
    // an effort that cannot hold the arm: the derivation says so, with the value
    let e = run(&["--tau-max", "150,1,150,28,28,28"]);
    assert!(
        e.contains("joint 2 (shoulder_lift_joint)")
            && e.contains("effort 1 N·m")
            && e.contains("gravity")
            && e.contains("--ddq-max"),
        "{e}"
    );
    // a table without any limit: the first missing one is named
    let e = run_on(Path::new("puma560"), &[]);
    assert!(
        e.contains("joint 1") && e.contains("lower position limit") && e.contains("--q-min"),
        "{e}"
    );
    let e = run(&["--ddq-max", "4", "--q-min", "0,0,0,1,0,0", "--q-max", "1"]);
    assert!(e.contains("joint 4") && e.contains("q_min = 1"), "{e}");
    let e = run(&["--ddq-max", "4", "--q0", "0,0,0,0,0,7"]);
    assert!(e.contains("joint 6") && e.contains("q0 = 7"), "{e}");
    let e = run(&["--ddq-max", "0.01", "--period", "2"]);
    assert!(e.contains("joint 1") && e.contains("--period 2"), "{e}");
    let e = run(&["--ddq-max", "4,4"]);
    assert!(e.contains("--ddq-max") && e.contains("2 values"), "{e}");
}

/// Every URDF the project ships gets a feasible design from the URDF alone: its position,
/// velocity and effort limits, acceleration limits derived from effort and inertia, torques
/// checked through its own `<inertial>`s. The file's 1 kHz grid stays within every limit, the
/// torques recomputed by the reference Newton–Euler (checked against Pinocchio in
/// tests/pinocchio) included; the limit sources say where each value came from.
#[test]
fn excite_from_the_urdf_alone_on_every_shipped_urdf() {
    let root = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/.."));
    for path in [
        urdf("ur5e.urdf"),
        urdf("ur10e.urdf"),
        urdf("panda.urdf"),
        root.join("data/real/tiago_figaroh/tiago.urdf"),
    ] {
        let dir = tempfile::tempdir().unwrap();
        let out = dynid(&[
            "excite",
            "--arm",
            path.to_str().unwrap(),
            "--generations",
            "3",
            "--rate",
            "1000",
            "--out",
            dir.path().to_str().unwrap(),
        ]);
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(out.status.success(), "{}: {err}", path.display());
        assert!(err.contains("note: ddq_max derived"), "{err}");
        let doc: serde_json::Value = serde_json::from_str(
            &std::fs::read_to_string(dir.path().join("excitation.json")).unwrap(),
        )
        .unwrap();
        let imported =
            dynid::urdf::import_file(&path, &dynid::urdf::ImportOptions::default()).unwrap();
        let n = imported.table.dof();
        let lim = &doc["limits"]["joints"];
        let get = |j: usize, k: &str| lim[j][k].as_f64().unwrap();
        for j in 0..n {
            let src = lim[j]["source"].as_str().unwrap();
            assert!(src.contains("ddq: urdf effort/inertia"), "{src}");
            assert_eq!(Some(get(j, "tau_max")), imported.table.joints[j].tau_max);
        }
        let notes = doc["limits"]["notes"].to_string();
        assert!(notes.contains("tau_max checked"), "{notes}");
        let rows = read_csv(&dir.path().join("trajectory.csv")).rows;
        let model = dynid::reference::RefModel::new(&imported.table);
        let mut ws = model.workspace();
        let p = imported.params.full_vector();
        let mut tau = vec![0.0; n];
        let mut peak_use = 0.0_f64;
        for r in &rows {
            let (q, dq, ddq) = (&r[1..1 + n], &r[1 + n..1 + 2 * n], &r[1 + 2 * n..1 + 3 * n]);
            model.inverse_dynamics(&mut ws, q, dq, ddq, &p, &mut tau);
            for j in 0..n {
                let t = tau[j] + imported.params.effects.torque(j, q[j], dq[j], ddq[j]);
                for u in [
                    (q[j] - get(j, "q_max")) / (get(j, "q_max") - get(j, "q_min")) + 1.0,
                    (get(j, "q_min") - q[j]) / (get(j, "q_max") - get(j, "q_min")) + 1.0,
                    dq[j].abs() / get(j, "dq_max"),
                    ddq[j].abs() / get(j, "ddq_max"),
                    t.abs() / get(j, "tau_max"),
                ] {
                    peak_use = peak_use.max(u);
                }
            }
        }
        // the design's own check is on this grid with the same model: no tolerance beyond rounding
        assert!(peak_use <= 1.0 + 1e-9, "{}: {peak_use}", path.display());
    }
}
