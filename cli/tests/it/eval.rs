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

/// The quick subset (seeds 1–20: ≤ 4 joints, ≤ 500 Hz, 15 s runs), against issue 18's bars.
/// Measured with the cut-off scan over a real range: recall 1.0 for effects of ≥ 3 % torque
/// share, no false positive in 295 decisions, validation within 1.15 × the oracle and the
/// automatic cut-off within 1.1 × the best fixed one in 19 of 20 cases each (before it: 0.867,
/// 0.0041, 16 and 14 of 20; docs/eval.md). 20 cases are a small sample — one case is 5 % — so
/// the bars here are the issue's, read with one case of slack where the issue says 95 %.
#[test]
fn eval_suite_quick_subset() {
    let (s, _) = suite(&["--cases", "20", "--quick", "--jobs", "2"]);
    let f = |k: &str| s[k].as_f64().unwrap();
    assert_eq!(s["failed"], 0, "{s}");
    assert!(f("false_positive_rate") <= 0.02, "{s}");
    assert!(f("recall_share_ge_3pct") >= 0.95, "{s}");
    assert!(
        s["validation_over_oracle"]["within_1.15"].as_f64().unwrap() >= 0.95,
        "{s}"
    );
    assert!(
        s["auto_cutoff_over_best_fixed"]["within_1.1"]
            .as_f64()
            .unwrap()
            >= 0.9,
        "{s}"
    );
}

/// The effects real arms show (issue 40, `--extended`), quick seeds 20–21: an asymmetric Coulomb
/// friction (levels differing by direction, 10–14 % of the joint's torque) on a SCARA's joint 2
/// (point-to-point moves) and a random arm's joint 2 (Fourier, with a per-run offset on joint 4).
/// The library models it as `coulomb` + `asym_coulomb` (`|tanh(q̇/v)|`, 0 at rest), which is
/// `offset` on a motion that never rests; both parts must be found, and `asym_coulomb` nowhere
/// else. Measured on seeds 1–200 (docs/eval.md): 0.74 of such cases, no false positive.
#[test]
fn extended_suite_finds_asymmetric_coulomb_and_invents_none() {
    let (_, cases) = suite(&[
        "--cases",
        "2",
        "--first-seed",
        "20",
        "--quick",
        "--extended",
        "--jobs",
        "2",
    ]);
    let mut asym = 0;
    for c in cases.as_array().unwrap() {
        let got = found(c);
        let seed = &c["spec"]["seed"];
        let (truth, invented) = truth_and_found(c, "asym_coulomb");
        for e in c["effects"].as_array().unwrap() {
            if e["effect"] == "asym_coulomb" {
                let j = &e["joint"];
                let coulomb = format!("coulomb{j}");
                assert!(got.contains(&coulomb), "seed {seed}: {coulomb} in {got:?}");
                let level = [format!("asym_coulomb{j}"), format!("offset{j}")];
                assert!(
                    level.iter().any(|t| got.contains(t)),
                    "seed {seed}: one of {level:?} in {got:?}"
                );
                asym += 1;
            }
        }
        let extra: Vec<_> = invented.iter().filter(|t| !truth.contains(t)).collect();
        assert!(extra.is_empty(), "seed {seed}: invented {extra:?}");
    }
    assert_eq!(asym, 2, "the seeds' effects changed: {cases}");
}

/// Asymmetric Coulomb friction under point-to-point motion (issue 40, `--extended`), quick seeds
/// 107 (a random arm's joint 2, 19 % of its torque) and 136 (a SCARA's joint 3, 14 %). Its column
/// differs from an offset only at the rests, which fall in a few held-out blocks: the search's
/// block test missed both (t 2.2 and 2.7 against 3.8–4.1), the coefficient test finds them
/// (z 3.9 and 4.7 against 2.9 and 3.2). `asym_coulomb` itself must be found, beside `coulomb`, on
/// that joint only; measured on seeds 1–200 (docs/eval.md): recall 0.86 → 0.96, no new false
/// positive.
#[test]
fn extended_suite_finds_asymmetric_coulomb_at_the_rests_of_point_to_point_moves() {
    for (seed, joint) in [("107", 2), ("136", 3)] {
        let c = &extended_case(seed);
        assert_eq!(
            c["spec"]["excitation"], "point-to-point",
            "the seed changed"
        );
        let (truth, got) = truth_and_found(c, "asym_coulomb");
        assert_eq!(
            truth,
            vec![format!("asym_coulomb{joint}")],
            "the seed changed"
        );
        assert_eq!(got, truth, "seed {seed}: {c}");
        assert!(
            found(c).contains(&format!("coulomb{joint}")),
            "seed {seed}: {:?}",
            found(c)
        );
    }
}

/// Friction no closed form fits (issue 40, `--extended`): quick seeds 5 (a random arm's joint 2,
/// a sublinear curve `sign(q̇)·|q̇/r|^0.58` under a Fourier motion, 22 % of its torque) and 18 (a
/// planar arm's joint 1, a superlinear `|q̇/r|^2.03` under point-to-point moves, 24 %), each less
/// what Coulomb and viscous friction explain. The friction spline must be found on that joint
/// and on no other; measured on seeds 1–200 (docs/eval.md): recall 0.89, no false positive.
#[test]
fn extended_suite_finds_friction_curves_as_splines_and_invents_none() {
    for (seed, joint) in [("5", 2), ("18", 1)] {
        let c = &extended_case(seed);
        let (truth, _) = truth_and_found(c, "friction_curve");
        assert_eq!(
            truth,
            vec![format!("friction_curve{joint}")],
            "the seed changed"
        );
        let splines: Vec<String> = found(c)
            .into_iter()
            .filter(|f| f.starts_with("spline"))
            .collect();
        assert_eq!(splines, vec![format!("spline{joint}")], "seed {seed}: {c}");
    }
}

/// The effects real arms show (issue 40, `--extended`), quick seeds 23–27: four slow drifts
/// (`1 − exp(−t/T)`, T = 60–600 s, 4–26 % of the joint's torque) on three arms, two of the cases
/// also with a per-run offset or a position ripple the library cannot model. Every drift must be
/// found by the `drift` column (time since the run's start) and none invented where there is
/// none; measured on seeds 1–200 (docs/eval.md): recall 0.82, no false positive.
#[test]
fn extended_suite_finds_each_drift_and_invents_none() {
    let (_, cases) = suite(&[
        "--cases",
        "5",
        "--first-seed",
        "23",
        "--quick",
        "--new-effects",
        FOUR,
        "--jobs",
        "2",
    ]);
    let mut drifts = 0;
    for c in cases.as_array().unwrap() {
        let (truth, got) = truth_and_found(c, "drift");
        assert_eq!(got, truth, "seed {}: {c}", c["spec"]["seed"]);
        drifts += truth.len();
    }
    assert_eq!(drifts, 4, "the seeds' drifts changed: {cases}");
}

/// Per-run offsets (issue 40, `--extended`), quick seeds 21–22 and 58: a random arm's joint 4
/// and a SCARA's joint 3 (its vertical prismatic joint, whose gravity column is m·(g + q̈₃): there
/// an offset with rotor inertia is rank-deficient, which made seed 58 fail before the guard
/// checked it). Each per-run offset must be found as `run_offset` and none invented; measured on
/// seeds 1–200 (docs/eval.md): recall 0.94, no false positive.
#[test]
fn extended_suite_finds_each_per_run_offset_and_invents_none() {
    let mut offsets = 0;
    for (first, cases) in [("21", "2"), ("58", "1")] {
        let (s, cases) = suite(&[
            "--cases",
            cases,
            "--first-seed",
            first,
            "--quick",
            "--extended",
            "--jobs",
            "2",
        ]);
        assert_eq!(s["failed"], 0, "{s}");
        for c in cases.as_array().unwrap() {
            let (truth, got) = truth_and_found(c, "run_offset");
            assert_eq!(got, truth, "seed {}: {c}", c["spec"]["seed"]);
            offsets += truth.len();
        }
    }
    assert_eq!(offsets, 3, "the seeds' offsets changed");
}

/// A ripple on a joint with other effects the model lacks (issue 40, `--extended`), quick seeds
/// 110 and 138: a random arm's joint 1 with asymmetric Coulomb friction, joint 3 with viscous
/// friction and a drift. The scan finds the right wavenumber, but the pair fails alone (the other
/// effects are in its residual) and they fail alone (it is in theirs); tested together as one
/// joint's group they are found. Each ripple must be found with its joint's other
/// effects, and none invented; measured on seeds 1–200 (docs/eval.md): ripple recall 0.98.
#[test]
fn extended_suite_finds_a_ripple_beside_its_joints_other_effects() {
    for (seed, joint, partners) in [
        ("110", 1, &["coulomb1", "asym_coulomb1"][..]),
        ("138", 3, &["viscous3", "drift3"][..]),
    ] {
        let c = &extended_case(seed);
        let (truth, got) = truth_and_found(c, "ripple");
        assert_eq!(
            truth,
            vec![format!("ripple{joint}")],
            "the seed changed: {c}"
        );
        assert_eq!(got, truth, "seed {seed}: {c}");
        let got = found(c);
        for p in partners {
            assert!(
                got.iter().any(|f| f == p),
                "seed {seed}: {p} not in {got:?}"
            );
        }
    }
}

/// Seed 36: a SCARA's vertical prismatic joint 3 with Coulomb friction, rotor inertia, an offset,
/// asymmetric Coulomb friction and a drift, its mass seen by no other joint. After Coulomb
/// friction no single term passes; the joint's group must leave out one of the offset and the
/// rotor inertia (with the mass, either spans the joint's constant and q̈, so both together are
/// singular) instead of failing as a whole. One of them is found and the other reported
/// collinear with the model, and the drift is found; nothing is invented on the other joints.
#[test]
fn extended_suite_tests_a_group_without_its_collinear_member() {
    let c = &extended_case_of("36", FOUR);
    let (truth, got) = truth_and_found(c, "drift");
    assert_eq!(truth, vec!["drift3"], "the seed changed: {c}");
    assert_eq!(got, truth, "{c}");
    let got = found(c);
    let collinear = auto_terms(c, "collinear");
    let pair = ["offset3", "armature3"];
    assert_eq!(
        pair.iter().filter(|t| got.iter().any(|f| f == *t)).count(),
        1,
        "one of {pair:?} found: {got:?}"
    );
    assert!(
        pair.iter().any(|t| collinear.iter().any(|c| c == t)),
        "the other collinear: {collinear:?}"
    );
    assert!(
        got.iter().all(|f| f.ends_with('3')),
        "only joint 3: {got:?}"
    );
}

/// One quick `--extended` case of the suite, seed `seed`, run without failure: its cases.json entry.
fn extended_case(seed: &str) -> serde_json::Value {
    extended_case_of(seed, &NEW_EFFECTS.join(","))
}

/// The four effects the extended suite had before the friction curve. Each new effect has its own
/// draws, so a test written on a case with them keeps its case; with the curve drawn too, seed
/// 24's joint 1 and seed 36's joints 1 and 3 also get one (docs/eval.md: the drift beside a curve
/// on seed 24 and seed 36's joint 3 is then missed).
const FOUR: &str = "ripple,asym_coulomb,run_offset,drift";

/// Every new effect the suite draws (`eval/suite.py`'s NEW_EFFECTS).
const NEW_EFFECTS: [&str; 5] = [
    "ripple",
    "asym_coulomb",
    "run_offset",
    "drift",
    "friction_curve",
];

/// One quick case of the extended suite with the new effects `new` (a comma list).
fn extended_case_of(seed: &str, new: &str) -> serde_json::Value {
    let (s, cases) = suite(&[
        "--cases",
        "1",
        "--first-seed",
        seed,
        "--quick",
        "--new-effects",
        new,
    ]);
    assert_eq!(s["failed"], 0, "{s}");
    cases[0].clone()
}

/// A case's terms of effect `kind` (`drift3`, …): those drawn in truth, and those found by the
/// library's effect of the same name.
fn truth_and_found(c: &serde_json::Value, kind: &str) -> (Vec<String>, Vec<String>) {
    let truth = c["effects"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|e| e["effect"] == kind)
        .map(|e| format!("{kind}{}", e["joint"]))
        .collect();
    let got = found(c)
        .into_iter()
        .filter(|f| f.starts_with(kind))
        .collect();
    (truth, got)
}

/// One hand-written case (`eval/patterns/NAME.json`) through the suite: its cases.json entry.
fn pattern(name: &str) -> serde_json::Value {
    let file = format!(
        "{}/eval/patterns/{name}.json",
        concat!(env!("CARGO_MANIFEST_DIR"), "/..")
    );
    let (_, cases) = suite(&["--pattern", &file]);
    cases[0].clone()
}

fn found(c: &serde_json::Value) -> Vec<String> {
    auto_terms(c, "found")
}

/// A list of terms in a case's `auto` (the product's run): `found`, `collinear`, ….
fn auto_terms(c: &serde_json::Value, key: &str) -> Vec<String> {
    let f = c["auto"][key].as_array().unwrap();
    f.iter().map(|v| v.as_str().unwrap().to_string()).collect()
}

/// The best validation error of the true effect set over the fixed cut-offs (the oracle).
fn oracle(c: &serde_json::Value) -> f64 {
    let grid = c["grid"].as_object().unwrap();
    grid.values()
        .filter_map(|g| g["validation"].as_f64())
        .fold(f64::INFINITY, f64::min)
}

/// Issue 18's missed effects: a 2-DOF arm with rotor inertia on joint 2 (0.1 kg·m²) and offsets
/// on both joints (0.4, −0.2 N·m), 500 Hz, 17-bit encoders, 1 % torque noise, positions only.
/// Point-to-point moves, shares 2.3 %, 2.7 % and 9 % of the joints' torque. Before the group step
/// (measured with the parent of 36c98e6) the greedy loop found none of them (validation 1.55 ×
/// the oracle's); now all three are found and the validation error is the oracle's.
#[test]
fn rotor_inertia_with_offsets_on_both_joints_is_found() {
    let c = pattern("rotor_and_offsets");
    assert_eq!(found(&c), ["armature2", "offset1", "offset2"], "{c}");
    let auto = c["auto"]["validation"].as_f64().unwrap();
    assert!(
        auto <= 1.15 * oracle(&c),
        "validation {auto}, oracle {}",
        oracle(&c)
    );
}

/// Issue 18's wrong cut-off: a ~1 kHz log with jittery, dropped timestamps (resampled) and a
/// velocity column. The jitter reads as motion up to hundreds of hertz, so the spectral rule's
/// grid lay above 0.2·fs and the scan tried nothing: the rule's cut-off was used untested
/// (measured before: validation 3.2 × the oracle's, and `offset3` invented). The scan over a
/// real range picks a cut-off within 1.1 × the best fixed one.
#[test]
fn jittery_log_with_a_velocity_column_gets_a_tested_cutoff() {
    let c = pattern("jittery_1khz_velocity");
    assert_eq!(found(&c), ["coulomb2", "viscous1"], "{c}");
    let best = oracle(&c);
    let true_auto = c["true_auto"]["validation"].as_f64().unwrap();
    assert!(
        true_auto <= 1.1 * best,
        "automatic cut-off {true_auto}, best fixed {best}"
    );
    let auto = c["auto"]["validation"].as_f64().unwrap();
    assert!(auto <= 1.15 * best, "validation {auto}, oracle {best}");
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
    let found = found(c);
    assert!(
        found.iter().any(|f| f == "offset1") && found.iter().any(|f| f == "spring1"),
        "{found:?}"
    );
    let oracle = oracle(c);
    let auto = c["auto"]["validation"].as_f64().unwrap();
    assert!(auto <= 1.15 * oracle, "validation {auto}, oracle {oracle}");
}

/// `eval/excitation.py --quick`: on puma560 and two random 6- and 3-joint arms, identification
/// from the designed trajectory (40 CMA-ES generations) against 3 random feasible Fourier +
/// quintic trajectories of the same period and limits, all simulated by MuJoCo with friction,
/// rotor inertia, offsets, 1 % torque noise and 18-bit encoders. Measured (release build): the
/// designed trajectory's torque-space parameter error is 0.79, 0.59 and 0.53 × the random
/// median; its held-out error is not better (1.05 × the median; docs/excitation.md). The bar
/// here is the parameter error below the random median on at least 2 of the 3 arms.
#[test]
fn excitation_beats_random_trajectories_quick_subset() {
    let dir = tempfile::tempdir().unwrap();
    python_script(
        "eval/excitation.py",
        &["--quick".as_ref(), "--out".as_ref(), dir.path().as_os_str()],
    );
    let s: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("summary.json")).unwrap())
            .unwrap();
    assert_eq!(s["compared"], 3, "{s}");
    let wins = s["designed_beats_random_median"]["parameter"]
        .as_u64()
        .unwrap();
    assert!(wins >= 2, "{s}");
}

/// Runs eval/payload.py with `args`; returns summary.json.
fn payload_eval(args: &[&str]) -> serde_json::Value {
    let dir = tempfile::tempdir().unwrap();
    let mut all: Vec<&std::ffi::OsStr> = vec!["--out".as_ref(), dir.path().as_os_str()];
    all.extend(args.iter().map(|a| std::ffi::OsStr::new(*a)));
    python_script("eval/payload.py", &all);
    let text = std::fs::read_to_string(dir.path().join("summary.json")).unwrap();
    serde_json::from_str(&text).unwrap()
}

/// Issue 39 on MuJoCo, noise-free (`--exact`: logs with exact dq/ddq, the true arm, a twin
/// shifted by whole samples): the payload, its frame (the last D-H frame, found by probing
/// both simulators) and the drive gains must come out at rounding level. Measured: mass
/// ≤ 3e-8 relative, COM ≤ 2e-7 m, scales ≤ 3e-4 on 12 cases; 1e-5 and 1e-6 m leave room
/// for the consistency program's regulariser (~1e-6 of the data weight).
#[test]
fn payload_eval_noise_free_is_exact() {
    let s = payload_eval(&["--cases", "4", "--exact", "--quick", "--jobs", "2"]);
    let max = |k: &str| s[k]["max"].as_f64().unwrap();
    assert_eq!(s["failed"], 0, "{s}");
    assert!(s["frame_residual_max"].as_f64().unwrap() < 1e-9, "{s}");
    assert!(max("mass_error") < 1e-5, "{s}");
    assert!(max("com_error_m") < 1e-6, "{s}");
    assert!(max("held_out_mass_error") < 1e-5, "{s}");
    assert!(max("scale_error_calibrated") < 1e-3, "{s}");
}
