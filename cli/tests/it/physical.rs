//! The physically consistent estimate and the model `identify` hands out
//! (`identified.params.toml`, `identified.urdf`), checked from outside: numpy's eigenvalues of
//! each link's pseudo-inertia, Pinocchio's RNEA and MuJoCo's inverse dynamics on the URDF
//! (`tests/physical/check_identified.py`), and `dynid torque` reproducing the report's
//! prediction.

use std::path::{Path, PathBuf};
use std::process::Output;

use crate::common::*;

fn data(rel: &str) -> String {
    Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/.."))
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

/// `dynid torque` with the identified params file on the raw log `data`, its states estimated at
/// the report's validation cut-off: the rows of `torque.csv` (t, τ₁…τₙ).
fn torque_at_report_cutoff(
    r: &serde_json::Value,
    arm: &str,
    out: &Path,
    data: &str,
) -> Vec<Vec<f64>> {
    let fc = r["data"]["validate"]["derivative"]["cutoff_hz"]
        .as_f64()
        .unwrap();
    let params = out.join("identified.params.toml").display().to_string();
    let tau = out.join("torque.csv");
    let tau_s = tau.display().to_string();
    let fc = format!("{fc}");
    let args = [
        "torque", "--arm", arm, "--params", &params, "--data", data, "--cutoff", &fc, "--out",
        &tau_s,
    ];
    let t = dynid(&args);
    assert!(t.status.success(), "{}", String::from_utf8_lossy(&t.stderr));
    csv_columns(&tau).1
}

/// The rows of `all` (first column t) at the times of `rows` (the validation samples used: the
/// prediction file trims the filter edges).
fn matched<'a>(rows: &[Vec<f64>], all: &'a [Vec<f64>]) -> Vec<&'a Vec<f64>> {
    let mut k = 0;
    rows.iter()
        .map(|row| {
            while all[k][0] < row[0] {
                k += 1;
            }
            assert_eq!(all[k][0], row[0]);
            &all[k]
        })
        .collect()
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

    let (head, pred) = csv_columns(&out.join("validation_prediction.csv"));
    let ours = torque_at_report_cutoff(&r, &sim("arm.toml"), &out, &sim("validate_noisy.csv.gz"));
    let col = |name: &str| head.iter().position(|h| h == name).unwrap();
    let (mut se, mut ss) = (0.0, 0.0);
    for (row, ours) in pred.iter().zip(matched(&pred, &ours)) {
        for j in 1..=2 {
            let (a, b) = (row[col(&format!("consistent{j}"))], ours[j]);
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

/// Real data, a short training set (DFKI runs 00–02, validated on run 04) at the 5.52 Hz cut-off
/// the spectral rule proposes (the scan picks 4.88 Hz, where least squares happens to be
/// physical): least squares is not physical (a negative friction coefficient: Stribeck on joint 2
/// before per-run offsets were searched, viscous on joint 1 with them); the consistent estimate
/// clamps it, says so in one line, and its model passes the outside check.
#[test]
fn dfki_short_training_set_is_made_physical() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("dfki");
    let arm = data("real/dfki_double_pendulum/arm.toml");
    let run = |r: &str| data(&format!("real/dfki_double_pendulum/run_{r}.csv.gz"));
    let (r0, r1, r2, r4) = (run("00"), run("01"), run("02"), run("04"));
    // Runs 00–02 fitted, run 04 validated, into `out` with `extra` arguments.
    let identify = |out: &Path, extra: &[&str]| {
        let o = out.display().to_string();
        let mut args = vec!["identify", "--arm", &arm, "--data", &r0, "--data", &r1];
        args.extend(["--data", &r2, "--validate", &r4, "--out", &o]);
        args.extend(extra);
        dynid(&args)
    };
    let o = identify(&out, &["--cutoff", "5.524"]);
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
    // Which constraint binds depends on the model the search finds on these three runs; the
    // verdict must name what it clamped.
    assert!(
        verdict.contains("binding:") && verdict.contains("= 0 (lower limit)"),
        "{verdict}"
    );
    // The scan predicts from the filtered rows here; the report also gives the errors of the
    // torque from the estimated states. Oracle 1: the same model (effects, cut-off and regression
    // filter fixed) run with `--smoothing 0.5,states`, whose prediction the simulated-set test
    // ties to `dynid torque` — equal up to summation order. Oracle 2: `dynid torque` itself with
    // the params file on the raw log; this log is resampled (uneven steps), where identify
    // interpolates the grid's torque to the raw times and `dynid torque` the grid's states, so the
    // two agree to a fraction of a percent (measured 6e-4 of the error on joint 1), not to 1e-7.
    let c = &ph["error"];
    assert_eq!(
        r["data"]["validate"]["smoothing"]["filtered_prediction"], true,
        "{r}"
    );
    let states = c["from_states"]["validation"]["per_joint"]
        .as_array()
        .unwrap();
    // Every effect of the model: the search's and the per-joint guard's additions.
    let found: Vec<String> = r["effects"]
        .as_array()
        .unwrap()
        .iter()
        .map(|e| {
            let run = e["run"].as_u64().map_or(String::new(), |r| format!("@{r}"));
            format!("{}:{}{run}", e["effect"].as_str().unwrap(), e["joint"])
        })
        .collect();
    let fc = format!("{}", r["data"]["validate"]["derivative"]["cutoff_hz"]);
    let out2 = dir.path().join("dfki_states");
    let effects = found.join(",");
    let o = identify(
        &out2,
        &[
            "--effects",
            &effects,
            "--cutoff",
            &fc,
            "--smoothing",
            "0.5,states",
        ],
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let r2 = report(&out2);
    let (head, pred) = csv_columns(&out.join("validation_prediction.csv"));
    let ours = torque_at_report_cutoff(&r, &arm, &out, &r4);
    let col = |name: &str| head.iter().position(|h| h == name).unwrap();
    for (j, s) in states.iter().enumerate() {
        let got = s.as_f64().unwrap();
        let same = r2["physical"]["error"]["validation"]["per_joint"][j]
            .as_f64()
            .unwrap();
        assert!(
            (same - got).abs() < 1e-9 * got,
            "joint {}: report {got}, states run {same}",
            j + 1
        );
        let (mut se, mut ss) = (0.0, 0.0);
        for (row, ours) in pred.iter().zip(matched(&pred, &ours)) {
            let tau = row[col(&format!("tau{}", j + 1))];
            se += (ours[j + 1] - tau).powi(2);
            ss += tau * tau;
        }
        let torque = (se / ss).sqrt();
        assert!(
            (torque - got).abs() < 5e-3 * got,
            "joint {}: report {got}, dynid torque {torque}",
            j + 1
        );
        let lowpassed = c["validation"]["per_joint"][j].as_f64().unwrap();
        assert!(
            (lowpassed - got).abs() > 1e-2 * got,
            "joint {}: both predictions {got}",
            j + 1
        );
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
