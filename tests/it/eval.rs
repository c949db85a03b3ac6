//! The evaluation suite (`eval/suite.py`: cases simulated by MuJoCo, scored against the truth and
//! an oracle fit) run from the test command: its quick subset, and single cases that reproduce
//! failure patterns of issue 18.

use crate::common::*;

/// Runs the suite with `args`; returns (summary.json, cases.json).
fn suite(args: &[&str]) -> (serde_json::Value, serde_json::Value) {
    let dir = tempfile::tempdir().unwrap();
    let mut all: Vec<&std::ffi::OsStr> = vec!["--out".as_ref(), dir.path().as_os_str()];
    all.extend(args.iter().map(|a| std::ffi::OsStr::new(*a)));
    python_script("eval/suite.py", &all);
    let read = |f: &str| -> serde_json::Value {
        serde_json::from_str(&std::fs::read_to_string(dir.path().join(f)).unwrap()).unwrap()
    };
    (read("summary.json"), read("cases.json"))
}

/// The quick subset (seeds 1–20: ≤ 4 joints, ≤ 500 Hz, 15 s runs). Measured when the group step
/// went in: recall 0.867 for effects of ≥ 3 % torque share, false positives 0.0041 per absent
/// candidate, validation within 1.15 × the oracle in 16 of 20 cases (before the group step:
/// 0.778 / 0.0041 / 15 of 20, worst case 17 × the oracle). The bars are issue 18's for false
/// positives and a guard just under today's numbers for the rest (issue 18's 0.95 bars are
/// not met yet: docs/eval.md).
#[test]
fn eval_suite_quick_subset() {
    let (s, _) = suite(&["--cases", "20", "--quick", "--jobs", "2"]);
    let f = |k: &str| s[k].as_f64().unwrap();
    assert_eq!(s["failed"], 0, "{s}");
    assert!(f("false_positive_rate") <= 0.02, "{s}");
    assert!(f("recall_share_ge_3pct") >= 0.8, "{s}");
    assert!(
        s["validation_over_oracle"]["within_1.15"].as_f64().unwrap() >= 0.75,
        "{s}"
    );
}

/// Issue 18's "misses cluster where two or three effects sit on one joint", simulated by MuJoCo
/// (quick case 15: a spring and an offset on joint 1 of a random 4-joint arm, 21 % and 15 % of
/// its torque RMS, rotor inertia on joint 4). The greedy loop found nothing (validation 28.4 %,
/// the oracle 1.6 %): each of the two alone is partly absorbed by the rigid-body columns. The
/// group step adds both.
#[test]
fn effects_needed_together_on_one_joint_are_found() {
    let (_, cases) = suite(&["--cases", "1", "--first-seed", "15", "--quick"]);
    let c = &cases[0];
    let found: Vec<&str> = c["auto"]["found"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_str().unwrap())
        .collect();
    assert!(
        found.contains(&"offset1") && found.contains(&"spring1"),
        "{found:?}"
    );
    let oracle = c["grid"]
        .as_object()
        .unwrap()
        .values()
        .filter_map(|g| g["validation"].as_f64())
        .fold(f64::INFINITY, f64::min);
    let auto = c["auto"]["validation"].as_f64().unwrap();
    assert!(auto <= 1.15 * oracle, "validation {auto}, oracle {oracle}");
}
