//! End-to-end tests of the `dynid` binary on small files.

use std::path::{Path, PathBuf};
use std::process::Output;

use crate::common::*;

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, text).expect("write test file");
    p
}

const PLANAR2_PARAMS: &str = "[[link]]\nm = 2.0\ncom = [0.4, 0.05, 0.0]\ninertia_com = [0.01, 0.0, 0.0, 0.05, 0.0, 0.05]\n\n\
[[link]]\nm = 1.5\ncom = [0.3, -0.02, 0.0]\ninertia_com = [0.01, 0.0, 0.0, 0.03, 0.0, 0.03]\n";

fn planar2_csv(n: usize) -> String {
    let mut s = String::from("t,q1,q2,dq1,dq2,ddq1,ddq2\n");
    for k in 0..n {
        let t = k as f64 * 0.01;
        s += &format!(
            "{t},{},{},{},{},{},{}\n",
            t.sin(),
            0.5 * t.cos(),
            t.cos(),
            -0.5 * t.sin(),
            -t.sin(),
            -0.5 * t.cos()
        );
    }
    s
}

fn parse_csv(text: &str) -> Vec<Vec<f64>> {
    text.lines()
        .skip(1)
        .map(|l| l.split(',').map(|c| c.parse().expect("number")).collect())
        .collect()
}

#[test]
fn arms_lists_every_generated_arm_with_base_parameters() {
    let out = dynid(&["arms"]);
    assert!(out.status.success(), "{}", stderr(&out));
    let text = String::from_utf8(out.stdout).unwrap();
    for arm in ["planar2", "puma560", "panda", "scara"] {
        assert!(text.contains(arm), "{arm} missing:\n{text}");
    }
    assert!(
        text.contains("ZZ1 + a1²·M2"),
        "planar2's grouped parameter missing:\n{text}"
    );

    let out = dynid(&["arms", "--json", "planar2"]);
    assert!(out.status.success(), "{}", stderr(&out));
    let json: serde_json::Value = serde_json::from_slice(&out.stdout).expect("valid JSON");
    assert_eq!(json[0]["name"], "planar2");
    assert_eq!(json[0]["nb"], 6);
    assert_eq!(json[0]["base_params"].as_array().map(Vec::len), Some(6));
}

/// The generated kernels (by name) and the reference RNEA (by path) agree, and both match the
/// paper's closed form Φ·θ for planar2.
#[test]
fn torque_generated_and_reference_agree_with_the_closed_form() {
    let dir = tempfile::tempdir().unwrap();
    let params = write(dir.path(), "p.toml", PLANAR2_PARAMS);
    let data = write(dir.path(), "traj.csv", &planar2_csv(50));
    let arm_path = concat!(
        concat!(env!("CARGO_MANIFEST_DIR"), "/.."),
        "/arms/planar2.toml"
    );
    let run = |arm: &str| {
        let out = dynid(&[
            "torque",
            "--arm",
            arm,
            "--params",
            params.to_str().unwrap(),
            "--data",
            data.to_str().unwrap(),
        ]);
        assert!(out.status.success(), "{}", stderr(&out));
        parse_csv(&String::from_utf8(out.stdout).unwrap())
    };
    let generated = run("planar2");
    let reference = run(arm_path);
    assert_eq!(generated.len(), 50);

    let p =
        dynid::params::InertialParams::from_str(PLANAR2_PARAMS, "p.toml", 2, &Default::default())
            .unwrap()
            .full_vector();
    let theta = planar2_theta(&p);
    let traj = dynid::data::Trajectory::from_path(&data, Some(2)).unwrap();
    for k in 0..traj.len() {
        let phi = planar2_phi(
            traj.q_at(k),
            traj.dq_at(k).unwrap(),
            traj.ddq_at(k).unwrap(),
        );
        let expected = mat_vec(&phi, &theta);
        assert_eq!(generated[k][0], traj.t[k]);
        assert_close(&generated[k][1..], &expected, 1e-12, "generated vs Φθ");
        assert_close(&reference[k][1..], &expected, 1e-12, "reference vs Φθ");
    }
}

#[test]
fn torque_adds_effects_from_the_params_file() {
    let dir = tempfile::tempdir().unwrap();
    let plain = write(dir.path(), "p.toml", PLANAR2_PARAMS);
    let with = write(
        dir.path(),
        "pe.toml",
        &format!("{PLANAR2_PARAMS}\n[effects]\nviscous = [0.5, 0.25]\ncoulomb = [1.0, 2.0]\narmature = [0.1, 0.2]\noffset = [0.01, -0.01]\n"),
    );
    let data = write(dir.path(), "traj.csv", &planar2_csv(20));
    let run = |p: &Path| {
        let out = dynid(&[
            "torque",
            "--arm",
            "planar2",
            "--params",
            p.to_str().unwrap(),
            "--data",
            data.to_str().unwrap(),
        ]);
        assert!(out.status.success(), "{}", stderr(&out));
        parse_csv(&String::from_utf8(out.stdout).unwrap())
    };
    let (a, b) = (run(&plain), run(&with));
    let traj = dynid::data::Trajectory::from_path(&data, Some(2)).unwrap();
    for k in 0..traj.len() {
        let (dq, ddq) = (traj.dq_at(k).unwrap(), traj.ddq_at(k).unwrap());
        let sign = |x: f64| {
            if x > 0.0 {
                1.0
            } else if x < 0.0 {
                -1.0
            } else {
                0.0
            }
        };
        let extra = [
            0.5 * dq[0] + 1.0 * sign(dq[0]) + 0.1 * ddq[0] + 0.01,
            0.25 * dq[1] + 2.0 * sign(dq[1]) + 0.2 * ddq[1] - 0.01,
        ];
        for j in 0..2 {
            assert!((b[k][j + 1] - a[k][j + 1] - extra[j]).abs() < 1e-12);
        }
    }
}

#[test]
fn bad_csv_is_reported_with_row_and_column_and_existing_output_survives() {
    let dir = tempfile::tempdir().unwrap();
    let params = write(dir.path(), "p.toml", PLANAR2_PARAMS);
    let mut csv = planar2_csv(5);
    csv += "0.05,0.1,NaN,0,0,0,0\n";
    let data = write(dir.path(), "bad.csv", &csv);
    let out_file = write(dir.path(), "out.csv", "precious\n");
    let out = dynid(&[
        "torque",
        "--arm",
        "planar2",
        "--params",
        params.to_str().unwrap(),
        "--data",
        data.to_str().unwrap(),
        "--out",
        out_file.to_str().unwrap(),
    ]);
    assert_eq!(out.status.code(), Some(2), "{}", stderr(&out));
    let err = stderr(&out);
    assert!(
        err.starts_with("error: ") && err.contains("bad.csv:7: q2: `NaN` is not a finite number"),
        "{err}"
    );
    assert_eq!(std::fs::read_to_string(&out_file).unwrap(), "precious\n");
    let leftovers: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert_eq!(leftovers.len(), 3, "no temporary files left: {leftovers:?}");
}

#[test]
fn torque_writes_out_atomically_and_matches_stdout() {
    let dir = tempfile::tempdir().unwrap();
    let params = write(dir.path(), "p.toml", PLANAR2_PARAMS);
    let data = write(dir.path(), "traj.csv", &planar2_csv(10));
    let out_file = dir.path().join("tau.csv");
    let args = [
        "torque",
        "--arm",
        "planar2",
        "--params",
        params.to_str().unwrap(),
        "--data",
        data.to_str().unwrap(),
    ];
    let to_stdout = dynid(&args);
    let mut with_out = args.to_vec();
    with_out.extend(["--out", out_file.to_str().unwrap()]);
    let to_file = dynid(&with_out);
    assert!(to_file.status.success(), "{}", stderr(&to_file));
    assert!(to_file.stdout.is_empty());
    assert_eq!(std::fs::read(&out_file).unwrap(), to_stdout.stdout);
    assert!(String::from_utf8(to_stdout.stdout)
        .unwrap()
        .starts_with("t,tau1,tau2\n"));
}

#[test]
fn bad_inputs_exit_2_with_a_message_and_never_panic() {
    let dir = tempfile::tempdir().unwrap();
    let params = write(dir.path(), "p.toml", PLANAR2_PARAMS);
    let data = write(dir.path(), "traj.csv", &planar2_csv(3));
    let no_dq = write(dir.path(), "nodq.csv", "t,q1,q2\n0,0,0\n");
    let wrong_dof = write(
        dir.path(),
        "six.csv",
        "t,q1,q2,q3,q4,q5,q6\n0,0,0,0,0,0,0\n",
    );
    let bad_arm = write(
        dir.path(),
        "arm.toml",
        "name = \"x\"\nconvention = \"standard\"\n",
    );
    let (p, d) = (params.to_str().unwrap(), data.to_str().unwrap());
    let out_under_file = format!("{d}/sub/out.csv");
    let cases: Vec<(Vec<&str>, &str)> = vec![
        (
            vec!["torque", "--arm", "pmua560", "--params", p, "--data", d],
            "did you mean `puma560`?",
        ),
        (
            vec![
                "torque",
                "--arm",
                "planar2",
                "--params",
                "/nonexistent/p.toml",
                "--data",
                d,
            ],
            "/nonexistent/p.toml: cannot read",
        ),
        (
            vec![
                "torque",
                "--arm",
                "planar2",
                "--params",
                p,
                "--data",
                no_dq.to_str().unwrap(),
            ],
            // Without q̇/q̈ columns torque estimates them; one row is too few.
            "too few samples: 1 (at least 32 are needed to estimate derivatives)",
        ),
        (
            vec![
                "torque",
                "--arm",
                "planar2",
                "--params",
                p,
                "--data",
                wrong_dof.to_str().unwrap(),
            ],
            "extra column `q3`: the arm has 2 joints",
        ),
        (
            vec!["torque", "--arm", "puma560", "--params", p, "--data", d],
            "2 `[[link]]` tables but the arm has 6 joints",
        ),
        (
            vec![
                "torque",
                "--arm",
                bad_arm.to_str().unwrap(),
                "--params",
                p,
                "--data",
                d,
            ],
            "convention `standard` is not supported",
        ),
        (
            vec![
                "torque",
                "--arm",
                "planar2",
                "--params",
                p,
                "--data",
                d,
                "--out",
                // a directory that cannot be made: its parent is a file (root may write anywhere)
                &out_under_file,
            ],
            "cannot write",
        ),
        (vec!["torque", "--arm", "planar2"], "--params"),
        (
            vec![
                "identify",
                "--arm",
                "planar2",
                "--data",
                d,
                "--coulomb-width",
                "0",
            ],
            "--coulomb-width: `0` is not `auto` or a fraction in (0, 1]",
        ),
        (vec!["frobnicate"], "unrecognized subcommand"),
    ];
    for (args, needle) in cases {
        let out = dynid(&args);
        let err = stderr(&out);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {err}");
        assert!(
            err.contains(needle),
            "{args:?}: expected `{needle}` in:\n{err}"
        );
        assert!(!err.contains("panicked"), "{args:?}: {err}");
    }
}
