//! `dynid simulate` on arms without generated kernels: a URDF (imported in memory) or a D-H
//! table runs on the reference recursions, and must give the run the generated kernels give.

use crate::common::{dynid, read_csv};

fn ok(o: std::process::Output) -> std::process::Output {
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    o
}

/// The PUMA 560 with viscous friction, 3 s of a six-joint sine under CTC: simulated on its
/// generated kernels, on its exported URDF (reference recursions, full parameters) and on its D-H
/// table (the stiff wrist needs the 0.2 ms step). Two implementations of the same dynamics: the
/// logs agree to 1e-9 relative (measured 6e-13: 15,000 RK4 steps of a closed loop carry the
/// kernels' rounding differences, nothing more).
#[test]
fn simulate_on_a_urdf_or_table_equals_the_generated_arm() {
    let d = tempfile::tempdir().unwrap();
    let root = concat!(env!("CARGO_MANIFEST_DIR"), "/..");
    let params = format!("{root}/docs/examples/puma560_viscous.params.toml");
    let traj = d.path().join("sine.json");
    std::fs::write(
        &traj,
        r#"{"kind":"sine","amplitude":[1.2,0.9,0.9,1.5,1.2,1.5],"omega":[0.71,1.13,1.37,1.79,2.11,2.53],"offset":[0,0.3,-0.2,0,0,0],"duration":3.0}"#,
    )
    .unwrap();
    let urdf = d.path().join("puma.urdf");
    let o = ok(dynid(&[
        "export-urdf",
        "--arm",
        "puma560",
        "--params",
        &params,
    ]));
    std::fs::write(&urdf, &o.stdout).unwrap();
    let table = format!("{root}/arms/puma560.toml");
    let run = |arm: &str, out: &str| {
        let out = d.path().join(out);
        ok(dynid(&[
            "simulate",
            "--arm",
            arm,
            "--params",
            &params,
            "--trajectory",
            traj.to_str().unwrap(),
            "--controller",
            "ctc",
            "--dt",
            "0.0002",
            "--log-every",
            "50",
            "--out",
            out.to_str().unwrap(),
        ]));
        read_csv(&out)
    };
    let (h0, gen) = run("puma560", "gen.csv");
    assert_eq!(gen.len(), 301, "3 s at the default 100 Hz log, both ends");
    for (arm, out) in [(urdf.to_str().unwrap(), "urdf.csv"), (&table[..], "dh.csv")] {
        let (h, other) = run(arm, out);
        assert_eq!(h, h0);
        assert_eq!(other.len(), gen.len());
        let mut worst = 0.0_f64;
        for (a, b) in gen.iter().zip(&other) {
            for (x, y) in a.iter().zip(b) {
                worst = worst.max((x - y).abs() / (1.0 + x.abs()));
            }
        }
        assert!(worst < 1e-9, "{arm}: worst relative difference {worst:e}");
    }
}

/// A URDF arm without `--params` simulates with the URDF's own inertials: the same log as with
/// the params file `import-urdf` writes from that URDF; a D-H table without `--params` is an error
/// that says what to pass.
#[test]
fn simulate_defaults_to_the_urdf_inertials() {
    let d = tempfile::tempdir().unwrap();
    let root = concat!(env!("CARGO_MANIFEST_DIR"), "/..");
    let urdf = format!("{root}/data/urdf/ur5e.urdf");
    let arm_dir = d.path().join("arm");
    ok(dynid(&[
        "import-urdf",
        &urdf,
        "--out",
        arm_dir.to_str().unwrap(),
    ]));
    let traj = d.path().join("sine.json");
    std::fs::write(
        &traj,
        r#"{"kind":"sine","amplitude":[0.5,0.4,0.4,0.6,0.5,0.6],"omega":[0.7,1.1,1.3,1.7,2.1,2.5],"offset":[0,-1.2,1.0,0,0,0],"duration":2.0}"#,
    )
    .unwrap();
    let run = |extra: &[&str], out: &str| {
        let out = d.path().join(out);
        let mut args = vec![
            "simulate",
            "--arm",
            &urdf,
            "--trajectory",
            traj.to_str().unwrap(),
            "--controller",
            "ctc",
            "--out",
            out.to_str().unwrap(),
        ];
        args.extend_from_slice(extra);
        let o = ok(dynid(&args));
        (std::fs::read(&out).unwrap(), o)
    };
    let params = arm_dir.join("ur5e.params.toml");
    let (own, o) = run(&[], "own.csv");
    assert!(String::from_utf8_lossy(&o.stderr).contains("URDF's own <inertial>s"));
    let (imported, _) = run(&["--params", params.to_str().unwrap()], "imported.csv");
    assert_eq!(own, imported);

    let o = dynid(&[
        "simulate",
        "--arm",
        arm_dir.join("ur5e.toml").to_str().unwrap(),
        "--trajectory",
        traj.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(2));
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(
        e.contains("--params is required unless --arm is a URDF"),
        "{e}"
    );
}
