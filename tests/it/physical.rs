//! The physically consistent estimate and the model `identify` hands out
//! (`identified.params.toml`, `identified.urdf`), checked from outside: numpy's eigenvalues of
//! each link's pseudo-inertia, Pinocchio's RNEA and MuJoCo's inverse dynamics on the URDF
//! (`tests/physical/check_identified.py`), and `dynid torque` reproducing the report's
//! prediction.

use std::path::{Path, PathBuf};
use std::process::Output;

use crate::common::*;

fn data(rel: &str) -> String {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("data")
        .join(rel)
        .display()
        .to_string()
}

fn sim(file: &str) -> String {
    data(&format!("sim/planar2_paper_friction/{file}"))
}

/// `identify` on the shared simulated set into `out` (extra arguments appended).
fn identify_sim(out: &Path, extra: &[&str]) -> Output {
    let (arm, train, val) = (
        sim("arm.toml"),
        sim("excite_noisy.csv.gz"),
        sim("validate_noisy.csv.gz"),
    );
    let mut args = vec![
        "identify",
        "--arm",
        &arm,
        "--data",
        &train,
        "--validate",
        &val,
    ];
    let o = out.display().to_string();
    args.extend(["--out", &o]);
    args.extend(extra);
    dynid(&args)
}

fn report(out: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).unwrap()).unwrap()
}

fn check_identified(arm: &str, out: &Path) {
    let args = [
        "--arm".as_ref(),
        arm.as_ref(),
        "--report".as_ref(),
        out.as_os_str(),
    ];
    python_script("tests/physical/check_identified.py", &args);
}

fn csv_columns(path: &Path) -> (Vec<String>, Vec<Vec<f64>>) {
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines = text.lines();
    let head = lines
        .next()
        .unwrap()
        .split(',')
        .map(str::to_string)
        .collect();
    let rows = lines
        .map(|l| l.split(',').map(|v| v.parse().unwrap()).collect())
        .collect();
    (head, rows)
}

/// The shared simulated set (friction on both joints, true links are point masses): least
/// squares is already physical there, so the consistent estimate predicts the same; its model
/// passes numpy, Pinocchio and MuJoCo, and `dynid torque` with it on the validation log
/// reproduces the report's `consistent` prediction.
#[test]
fn simulated_set_model_is_physical_loadable_and_reproducible() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("sim");
    let o = identify_sim(&out, &[]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let r = report(&out);
    let ph = &r["physical"];
    assert_eq!(ph["least_squares_consistent"], true, "{ph}");
    let val = |m: &serde_json::Value| m["validation"]["overall"].as_f64().unwrap();
    let (ls, cons) = (val(&r["error"]["after"]), val(&ph["error"]));
    assert!(
        (cons - ls).abs() < 1e-3 * ls,
        "least squares {ls}, consistent {cons}"
    );
    check_identified(&sim("arm.toml"), &out);

    // The report's cut-off, fed to `dynid torque` on the raw validation log.
    let fc = r["data"]["validate"]["derivative"]["cutoff_hz"]
        .as_f64()
        .unwrap();
    let params = out.join("identified.params.toml").display().to_string();
    let tau = out.join("torque.csv").display().to_string();
    let t = dynid(&[
        "torque",
        "--arm",
        &sim("arm.toml"),
        "--params",
        &params,
        "--data",
        &sim("validate_noisy.csv.gz"),
        "--cutoff",
        &format!("{fc}"),
        "--out",
        &tau,
    ]);
    assert!(t.status.success(), "{}", String::from_utf8_lossy(&t.stderr));
    let (head, pred) = csv_columns(&out.join("validation_prediction.csv"));
    let (_, ours) = csv_columns(Path::new(&tau));
    let col = |name: &str| head.iter().position(|h| h == name).unwrap();
    // Rows of the prediction are the validation samples used (edges trimmed): match by time.
    let mut k = 0;
    let (mut se, mut ss) = (0.0, 0.0);
    for row in &pred {
        while ours[k][0] < row[0] {
            k += 1;
        }
        assert_eq!(ours[k][0], row[0]);
        for j in 1..=2 {
            let (a, b) = (row[col(&format!("consistent{j}"))], ours[k][j]);
            se += (a - b) * (a - b);
            ss += a * a;
        }
    }
    // Measured 5.6e-10: the windowed estimator of identify vs the whole-log one of torque agree
    // to ~1e-7 of the signal's range near window edges (derivative tests), far less elsewhere.
    let rel = (se / ss).sqrt();
    assert!(
        rel < 1e-7,
        "torque vs the report's consistent prediction: {rel:e}"
    );
}

/// Real data, a short training set (DFKI runs 00–02, validated on run 04): least squares is not
/// physical (a negative Stribeck coefficient on joint 2); the consistent estimate clamps it, says
/// so in one line, and its model passes the outside check.
#[test]
fn dfki_short_training_set_is_made_physical() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("dfki");
    let arm = data("real/dfki_double_pendulum/arm.toml");
    let run = |r: &str| data(&format!("real/dfki_double_pendulum/run_{r}.csv.gz"));
    let (r0, r1, r2, r4) = (run("00"), run("01"), run("02"), run("04"));
    let o_s = out.display().to_string();
    let o = dynid(&[
        "identify",
        "--arm",
        &arm,
        "--data",
        &r0,
        "--data",
        &r1,
        "--data",
        &r2,
        "--validate",
        &r4,
        "--out",
        &o_s,
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let r = report(&out);
    let ph = &r["physical"];
    let md = std::fs::read_to_string(out.join("report.md")).unwrap();
    let verdict = md
        .lines()
        .find(|l| l.starts_with("**Physical consistency:**"))
        .unwrap_or_else(|| panic!("no verdict line in report.md:\n{md}"));
    assert_eq!(ph["least_squares_consistent"], false, "{ph}");
    assert!(
        verdict.contains("**not** physically consistent"),
        "{verdict}"
    );
    assert!(verdict.contains("stribeck2 = 0"), "{verdict}");
    // Every coefficient that must not be negative is not.
    for e in ph["effects"].as_array().unwrap() {
        let name = e["effect"].as_str().unwrap();
        if ["viscous", "coulomb", "stribeck", "armature"].contains(&name) {
            assert!(e["value"].as_f64().unwrap() >= 0.0, "{e}");
        }
    }
    check_identified(&arm, &out);
}

/// With the true parameters as `--prior`, what the data cannot see (link 1's mass: a planar arm's
/// data hold only ZZR1, MXR1, MY1 of it) comes out true; without a prior it is some physical
/// value (measured 6.9 kg against the true 1 kg), which the report says is not a measurement.
#[test]
fn prior_decides_what_the_data_cannot() {
    let dir = tempfile::tempdir().unwrap();
    let truth = "[[link]]\nm = 1.0\ncom = [1.0, 0.0, 0.0]\ninertia_com = [1e-6, 0.0, 0.0, 1e-6, 0.0, 1e-12]\n\n\
[[link]]\nm = 1.0\ncom = [1.0, 0.0, 0.0]\ninertia_com = [1e-6, 0.0, 0.0, 1e-6, 0.0, 1e-12]\n";
    let prior = dir.path().join("truth.params.toml");
    std::fs::write(&prior, truth).unwrap();
    let (with, without) = (dir.path().join("with"), dir.path().join("without"));
    let p = prior.display().to_string();
    assert!(identify_sim(&with, &["--prior", &p]).status.success());
    assert!(identify_sim(&without, &[]).status.success());
    let mass = |out: &Path, l: usize| {
        report(out)["physical"]["links"][l]["mass"]
            .as_f64()
            .unwrap()
    };
    // Link 1's mass is invisible to a planar arm's data (only ZZR1, MXR1, MY1 are identified).
    assert!(
        (mass(&with, 0) - 1.0).abs() < 0.01,
        "with the prior: {}",
        mass(&with, 0)
    );
    assert!(mass(&without, 0) > 0.0);
    let md = std::fs::read_to_string(without.join("report.md")).unwrap();
    assert!(md.contains("not measurements — give --prior"), "{md}");
    // The base parameters the data do determine stay within the fit's noise either way.
    let (a, b) = (report(&with), report(&without));
    let v = |r: &serde_json::Value| {
        r["physical"]["error"]["validation"]["overall"]
            .as_f64()
            .unwrap()
    };
    assert!(
        (v(&a) - v(&b)).abs() < 1e-3 * v(&b),
        "{} vs {}",
        v(&a),
        v(&b)
    );
}

/// `--physical off` writes no model and says why; a non-physical prior is an input error that
/// names the file and the fix; nothing is written.
#[test]
fn physical_off_and_a_bad_prior() {
    let dir = tempfile::tempdir().unwrap();
    let off = dir.path().join("off");
    assert!(identify_sim(&off, &["--physical", "off"]).status.success());
    assert!(!off.join("identified.params.toml").exists());
    let md = std::fs::read_to_string(off.join("report.md")).unwrap();
    assert!(md.contains("not checked (`--physical off`)"), "{md}");

    let bad: PathBuf = dir.path().join("bad.params.toml");
    std::fs::write(
        &bad,
        "[[link]]\nm = -1.0\ncom = [1.0, 0.0, 0.0]\ninertia_com = [0.1, 0.0, 0.0, 0.1, 0.0, 0.1]\n\n\
[[link]]\nm = 1.0\ncom = [1.0, 0.0, 0.0]\ninertia_com = [0.1, 0.0, 0.0, 0.1, 0.0, 0.1]\n",
    )
    .unwrap();
    let out = dir.path().join("bad");
    let o = identify_sim(&out, &["--prior", &bad.display().to_string()]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(
        err.contains("--prior:")
            && err.contains("bad.params.toml")
            && err.contains("physically consistent"),
        "{err}"
    );
    assert!(!out.exists());
}

/// The case, on data from an independent simulator: short, weakly exciting, noisy PUMA
/// runs simulated by MuJoCo (`tests/physical/consistent_vs_ls.py`: 4 s at 200 Hz, 2 % torque
/// noise, 16-bit encoders; validation on a rich 20 s run). Plain least squares comes out
/// non-physical and the consistent estimate predicts the validation run better. Measured over
/// seeds 1–20: least squares non-physical in 20 of 20, consistent better in 18 (worst ratio
/// 1.16), median validation error ratio 0.911; the bars below leave room for one unlucky seed.
#[test]
fn consistent_estimate_beats_least_squares_on_short_mujoco_runs() {
    let dir = tempfile::tempdir().unwrap();
    let rows = dir.path().join("rows.json");
    let args = [
        "--seeds".as_ref(),
        "8".as_ref(),
        "--json".as_ref(),
        rows.as_os_str(),
    ];
    python_script("tests/physical/consistent_vs_ls.py", &args);
    let rows: Vec<serde_json::Value> =
        serde_json::from_str(&std::fs::read_to_string(&rows).unwrap()).unwrap();
    let not_physical = rows
        .iter()
        .filter(|r| r["least_squares_consistent"] == false)
        .count();
    let mut ratio: Vec<f64> = rows
        .iter()
        .map(|r| {
            r["validation_consistent"].as_f64().unwrap() / r["validation_ls"].as_f64().unwrap()
        })
        .collect();
    ratio.sort_by(f64::total_cmp);
    let better = ratio.iter().filter(|&&x| x < 1.0).count();
    assert!(
        not_physical >= 6,
        "least squares non-physical in only {not_physical} of 8"
    );
    assert!(
        better >= 6,
        "consistent better in only {better} of 8: {ratio:?}"
    );
    assert!(ratio[3] < 0.97 && ratio[7] < 1.1, "ratios {ratio:?}");
}
