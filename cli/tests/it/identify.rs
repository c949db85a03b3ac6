//! Identification and the residual → effect loop, judged against known answers: the shared
//! simulated dataset (truth in its README), synthetic data from the reference RNEA with chosen
//! effects and noise (`identify::synth`), analytic derivatives of Fourier trajectories, and the
//! real DFKI arm (held-out runs).

use std::path::{Path, PathBuf};
use std::process::Command;

use dynid::arms::{resolve, ArmSource};
use dynid::data::Trajectory;
use dynid::derivative::{self, Method};
use dynid::dh::DhTable;
use dynid::effects::{Effect, EffectsSpec, Term};
use dynid::identify::synth::{generate, Spec, SynthExcitation};
use dynid::identify::{self, base::BaseModel, Config, Outcome};
use dynid::log::Log;

/// A dataset in the repository's `data/` folder.
fn data(rel: &str) -> PathBuf {
    Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/.."))
        .join("data")
        .join(rel)
}

fn arm_table(name: &str) -> DhTable {
    DhTable::from_path(
        &Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/.."))
            .join("arms")
            .join(format!("{name}.toml")),
    )
    .expect("arm table")
}

fn found(o: &Outcome) -> Vec<String> {
    let mut v: Vec<String> = o.selection.steps.iter().map(|s| s.label.clone()).collect();
    v.sort();
    v
}

fn coef(o: &Outcome, label: &str) -> f64 {
    o.effects
        .iter()
        .find(|(t, _)| t.label() == label)
        .map_or(f64::NAN, |(_, e)| e.value)
}

/// Overall validation error of the declared and of the augmented model.
fn validation_before_after(o: &Outcome) -> (f64, f64) {
    let overall = |r: &identify::ModelResult| r.validation.as_ref().unwrap().overall;
    (overall(&o.before), overall(&o.after))
}

/// Each effect coefficient within `rel` of its truth.
fn assert_coefs(o: &Outcome, truth: &[(&str, f64)], rel: f64) {
    for &(label, t) in truth {
        let v = coef(o, label);
        assert!((v - t).abs() < rel * t, "{label} = {v} (truth {t})");
    }
}

/// A planar 2-DOF arm with other geometry than the paper's (shorter first link, gravity along −x).
const PLANAR2_OTHER: &str = r#"
name = "planar2_short"
convention = "modified"
gravity = [-9.81, 0.0, 0.0]
[[joint]]
kind = "revolute"
alpha = 0.0
a = 0.0
d = 0.0
theta = 0.0
[[joint]]
kind = "revolute"
alpha = 0.0
a = 0.45
d = 0.0
theta = 0.3
"#;

fn other_planar() -> DhTable {
    DhTable::from_str(PLANAR2_OTHER, "planar2_short.toml").expect("table")
}

/// Synthetic training and validation data (different trajectories and noise).
fn synth_pair(spec: &Spec) -> (Trajectory, Trajectory) {
    let mut v = spec.clone();
    v.seed += 1000;
    (generate(spec), generate(&v))
}

fn run_synth(spec: &Spec, cfg: &Config) -> (Outcome, Vec<f64>) {
    let arm = ArmSource::Table(spec.table.clone());
    let (tr, va) = synth_pair(spec);
    let o = identify::run(&arm, vec![tr.into()], Some(va.into()), cfg).expect("identification");
    let truth = BaseModel::for_arm(&arm).base_params(&spec.p);
    (o, truth)
}

// --- the datasets in data/ -------------------------------------------------------------------

/// README of sim/planar2_paper_friction: θ = [2,2,0,1,1,0], viscous [0.8,0.5], Coulomb [1.2,0.6],
/// no armature/offset/spring. Tolerances are the issue's (0.02 on θ, 5 % on friction, validation
/// error after ≤ before/5 and ≤ 2 %); the noise is 1 % of the torque RMS, so a correct tool sits
/// well inside them.
#[test]
fn sim_paper_friction_noisy_finds_exactly_viscous_and_coulomb() {
    let d = data("sim/planar2_paper_friction");
    let arm = resolve(d.join("arm.toml").to_str().unwrap()).unwrap();
    let tr = Log::open(&d.join("excite_noisy.csv.gz"), Some(2)).unwrap();
    let va = Log::open(&d.join("validate_noisy.csv.gz"), Some(2)).unwrap();
    let o = identify::run(&arm, vec![tr], Some(va), &Config::default()).unwrap();
    assert_eq!(found(&o), ["coulomb1", "coulomb2", "viscous1", "viscous2"]);
    let truth = [2.0, 2.0, 0.0, 1.0, 1.0, 0.0];
    for (p, t) in o.theta.iter().zip(truth) {
        assert!(
            (p.value - t).abs() < 0.02,
            "{} = {} (truth {t})",
            p.name,
            p.value
        );
    }
    for (label, t) in [
        ("viscous1", 0.8),
        ("viscous2", 0.5),
        ("coulomb1", 1.2),
        ("coulomb2", 0.6),
    ] {
        let v = coef(&o, label);
        assert!((v - t).abs() < 0.05 * t, "{label} = {v} (truth {t})");
    }
    let (before, after) = validation_before_after(&o);
    assert!(
        after <= before / 5.0 && after <= 0.02,
        "validation before {before}, after {after}"
    );
    assert!(o
        .merged
        .iter()
        .any(|(t, w)| t == "armature1" && w == &["ZZR1".to_string()]));
    // Inverse dynamics along a smooth motion: the torque jumps at reversals, so the scan must
    // predict from the states (the filtered rows would smear the jumps).
    assert!(
        !o.train[0].smoothing.filtered_prediction,
        "{:?}",
        o.train[0].smoothing
    );
}

/// A log spilled to a temporary file (as every log over `log::SPILL_ROWS` rows is) identifies
/// exactly like the same log held in memory: same cut-off scan, effects, parameters and errors,
/// bit for bit (the windows read back are the same numbers). Spilled here after 3000 of the
/// shared set's rows, through the gzip stream, validation file spilled too.
#[test]
fn spilled_logs_identify_exactly_like_held_ones() {
    let d = data("sim/planar2_paper_friction");
    let arm = resolve(d.join("arm.toml").to_str().unwrap()).unwrap();
    let open = |f: &str, spill: usize| Log::open_spilling(&d.join(f), Some(2), spill).unwrap();
    let run = |spill: usize| {
        let (tr, va) = (
            open("excite_noisy.csv.gz", spill),
            open("validate_noisy.csv.gz", spill),
        );
        assert_eq!(tr.spilled(), spill < tr.len());
        identify::run(&arm, vec![tr], Some(va), &Config::default()).unwrap()
    };
    let (held, spilled) = (run(usize::MAX), run(3000));
    assert_eq!(found(&held), found(&spilled));
    assert_eq!(held.after.x, spilled.after.x);
    assert_eq!(held.after.validation, spilled.after.validation);
    assert_eq!(held.cutoff_scan, spilled.cutoff_scan);
    let rows = |p: &identify::Predictions| {
        let mut v = Vec::new();
        p.rows(0, p.len(), |t, tau, b, a, _| {
            v.push(t);
            v.extend(tau.iter().chain(b).chain(a));
        });
        v
    };
    let (a, b) = (held.predictions.unwrap(), spilled.predictions.unwrap());
    assert!(!a.is_empty() && rows(&a) == rows(&b));
}

/// The plot series are collected by the judging pass: the validation series must be every
/// `stride`-th row of `validation_prediction` (a separate pass, from the estimated states), and
/// the training series the rigid and final models' residuals at about 3000 points.
#[test]
fn plot_series_are_the_judged_predictions_at_every_strided_sample() {
    let d = data("sim/planar2_paper_friction");
    let arm = resolve(d.join("arm.toml").to_str().unwrap()).unwrap();
    let open = |f: &str| Log::open(&d.join(f), Some(2)).unwrap();
    let o = identify::run(
        &arm,
        vec![open("excite_noisy.csv.gz")],
        Some(open("validate_noisy.csv.gz")),
        &Config::default(),
    )
    .unwrap();
    let p = o.predictions.as_ref().unwrap();
    let stride = p.len().div_ceil(4000).max(1);
    let mut table = Vec::new();
    p.rows(0, p.len(), |t, tau, b, a, _| {
        table.push((t, tau.to_vec(), b.to_vec(), a.to_vec()))
    });
    let picked: Vec<_> = table.iter().step_by(stride).collect();
    let scale = table
        .iter()
        .flat_map(|r| r.1.iter())
        .fold(0.0f64, |m, v| m.max(v.abs()));
    for (j, series) in o.series.validation.iter().enumerate() {
        assert_eq!(series.len(), picked.len(), "joint {j}");
        for (&(t, tau, b, a), row) in series.iter().zip(&picked) {
            assert_eq!((t, tau), (row.0, row.1[j]));
            // The judging pass may read a row table (equal to ~1e-7 of the signal, rows.rs).
            let worst = (b - row.2[j]).abs().max((a - row.3[j]).abs());
            assert!(worst <= 1e-6 * scale, "joint {j} at t = {t}: {worst}");
        }
    }
    let used = o.train[0].rows_used;
    for (j, (before, after)) in o.series.resid_vs_vel.iter().enumerate() {
        let want = used.div_ceil(used.div_ceil(3000));
        assert!(
            before.len().abs_diff(want) <= 1 && after.len() == before.len(),
            "joint {j}"
        );
        // Same q̇ for both models; the final model's residuals are smaller (friction found).
        assert!(before.iter().zip(after).all(|(b, a)| b.0 == a.0));
        let ss = |v: &[(f64, f64)]| v.iter().map(|x| x.1 * x.1).sum::<f64>();
        assert!(ss(after) < ss(before), "joint {j}");
    }
}

/// Real arm: held-out run 11 (the swing-up), trained on the other seven. Coulomb friction must be
/// found on both joints and the held-out error must drop; the full rotation is `dfki_leave_one_out`.
#[test]
fn dfki_heldout_run_finds_coulomb_on_both_joints() {
    let d = data("real/dfki_double_pendulum");
    let arm = resolve(d.join("arm.toml").to_str().unwrap()).unwrap();
    let runs = ["00", "01", "02", "04", "05", "12", "13"];
    let train: Vec<Log> = runs
        .iter()
        .map(|r| Log::open(&d.join(format!("run_{r}.csv.gz")), Some(2)).unwrap())
        .collect();
    let va = Log::open(&d.join("run_11.csv.gz"), Some(2)).unwrap();
    let o = identify::run(&arm, train, Some(va), &Config::default()).unwrap();
    let f = found(&o);
    assert!(
        f.contains(&"coulomb1".to_string()) && f.contains(&"coulomb2".to_string()),
        "{f:?}"
    );
    let (b, a) = validation_before_after(&o);
    assert!(
        a < 0.8 * b && a < 0.35,
        "held-out run 11: before {b}, after {a}"
    );
    // Driven by smooth torques: friction kinks the motion instead, which only the filtered
    // rows predict consistently — the scan must see it.
    assert!(
        o.train[0].smoothing.filtered_prediction,
        "{:?}",
        o.cutoff_scan
    );
    // The published estimates (NOTES.md): ZZR1 ≈ 0.108, MXR1 ≈ 0.349; no ground truth, so only
    // a loose physical check: positive and within 20 %.
    let get = |n: &str| o.theta.iter().find(|p| p.name == n).unwrap().value;
    assert!(
        (get("MXR1") - 0.349).abs() < 0.07 && (get("ZZR1") - 0.108).abs() < 0.03,
        "{:?}",
        o.theta
    );
}

/// Counts nothing itself: [`identify::Progress::position`] does.
#[derive(Default)]
struct Folds;

impl dynid::progress::Observer for Folds {
    fn stage(&self, _: &str, _: u64) {}
    fn grow(&self, _: u64) {}
    fn advance(&self, _: u64) {}
}

/// The whole leave-one-run-out rotation over the 8 DFKI runs (a study, ~20 s in release).
#[test]
#[ignore]
fn dfki_leave_one_out() {
    let d = data("real/dfki_double_pendulum");
    let arm = resolve(d.join("arm.toml").to_str().unwrap()).unwrap();
    let runs = ["00", "01", "02", "04", "05", "11", "12", "13"];
    let files: Vec<Log> = runs
        .iter()
        .map(|r| Log::open(&d.join(format!("run_{r}.csv.gz")), Some(2)).unwrap())
        .collect();
    // Progress reports every fold done.
    let progress = identify::Progress::to(std::sync::Arc::new(Folds));
    let cfg = Config {
        progress: progress.clone(),
        ..Config::default()
    };
    let outs = identify::leave_one_out(&arm, files, &cfg).unwrap();
    assert_eq!(progress.position(), 8);
    for (r, o) in runs.iter().zip(&outs) {
        println!("held out run {r}: found {:?}", found(o));
        for s in &o.steps {
            println!(
                "  {:60} validation {:.4}",
                s.model,
                s.validation.as_ref().unwrap().overall
            );
        }
        assert!(
            found(o).contains(&"coulomb1".to_string())
                && found(o).contains(&"coulomb2".to_string())
        );
    }
    let (b, a, _) = identify::pooled_validation(&outs).unwrap();
    println!("pooled validation: before {b:?}\n                   after  {a:?}");
    // The issue's bar: 0.29. Measured 0.2892 (0.366 before predictions went through the
    // filtered rows, 0.2929 before the second stage found load-dependent friction in one fold).
    assert!(a.overall < 0.6 * b.overall && a.overall < 0.29, "{a:?}");
}

// --- no effect on clean data ---------------------------------------------------------------

/// Noise-only data (1 % torque noise, 2^17-count encoders, no effect): nothing may be added, on
/// several arms and seeds, and θ must come out right.
#[test]
fn clean_data_gets_no_effect() {
    let cases: [(DhTable, u64, f64, f64); 5] = [
        (arm_table("planar2"), 1, 30.0, 500.0),
        (arm_table("planar2"), 2, 30.0, 500.0),
        (other_planar(), 3, 30.0, 500.0),
        (arm_table("scara"), 4, 20.0, 250.0),
        (arm_table("puma560"), 5, 12.0, 200.0),
    ];
    for (table, seed, duration, rate) in cases {
        let name = table.name.clone();
        let spec = Spec {
            duration,
            rate_hz: rate,
            ..Spec::new(table, seed)
        };
        let (o, truth) = run_synth(&spec, &Config::default());
        assert!(
            found(&o).is_empty(),
            "{name} seed {seed}: spurious effects {:?}",
            found(&o)
        );
        let v = o.after.validation.as_ref().unwrap().overall;
        // Error ≈ the 1 % noise (plus derivative error): well below 1.5 %; on the SCARA the
        // overall pools its revolute joints only (its prismatic joint is in N), whose 250 Hz
        // log leaves more derivative error: below 2 %.
        let bound = if name == "scara" { 0.02 } else { 0.015 };
        assert!(v < bound, "{name} seed {seed}: validation error {v}");
        // θ: compare torques rather than coefficients (poorly excited parameters may wander).
        let scale = truth.iter().map(|v| v.abs()).fold(0.0, f64::max);
        let err = o
            .theta
            .iter()
            .zip(&truth)
            .map(|(a, b)| (a.value - b).abs())
            .fold(0.0, f64::max);
        assert!(
            err < 0.05 * scale,
            "{name} seed {seed}: θ error {err} (scale {scale})"
        );
    }
}

// --- detection of each effect ----------------------------------------------------------------

/// Each effect alone on one joint (other geometry than the paper's arm): found on that joint,
/// nothing else, coefficient within 4 reported standard deviations (block jackknife) and 10 %.
#[test]
fn each_effect_is_detected_on_the_right_joint() {
    let cases = [
        (Effect::Viscous, 1, 0.3),
        (Effect::Coulomb, 0, 0.5),
        (Effect::Offset, 1, 0.2),
        (Effect::Armature, 1, 0.05),
        (Effect::Spring, 0, 2.0),
    ];
    for (i, (effect, joint, value)) in cases.into_iter().enumerate() {
        let spec = Spec::new(other_planar(), 40 + i as u64).with_effect(effect, joint, value);
        let (o, _) = run_synth(&spec, &Config::default());
        let label = Term::new(effect, joint).label();
        assert_eq!(found(&o), std::slice::from_ref(&label), "{label}");
        let (_, e) = o.effects.iter().find(|(t, _)| t.label() == label).unwrap();
        let err = (e.value - value).abs();
        assert!(
            err < 4.0 * e.std && err < 0.1 * value,
            "{label} = {} ± {} (truth {value})",
            e.value,
            e.std
        );
    }
}

/// Asymmetric Coulomb friction (0.7 N·m forward, 0.3 back) on a smooth motion that never rests:
/// `asym_coulomb` (`|tanh(q̇/v)|`, 0 at rest) is then the `offset` column but around velocity
/// reversals, so it is not searched (every joint at rest in about 1 % of the samples, under
/// `Effect::ASYM_REST_MIN`) and the friction is found as coulomb + offset, the offset
/// ½(Fc⁺ − Fc⁻) = 0.2 within 10 %.
#[test]
fn asymmetric_coulomb_without_rests_is_coulomb_and_offset() {
    let spec = Spec::new(other_planar(), 47)
        .with_effect(Effect::Coulomb, 0, 0.5)
        .with_effect(Effect::AsymCoulomb, 0, 0.2);
    let (o, _) = run_synth(&spec, &Config::default());
    assert!(
        o.at_rest.iter().all(|&r| r < Effect::ASYM_REST_MIN),
        "{:?}",
        o.at_rest
    );
    assert_eq!(found(&o), ["coulomb1", "offset1"]);
    let offset = coef(&o, "offset1");
    assert!((offset - 0.2).abs() < 0.02, "offset1 = {offset}");
}

/// Issue 18's "silent on unidentifiable data": joint 2 held still (the arm's second joint never
/// moves) was fitted and reported without a word. The outcome must name the joint and the fix;
/// a moving joint must not be named. (Failed before `identify::identifiability`: no warnings.)
#[test]
fn a_joint_that_never_moves_is_named() {
    let mut spec = Spec::new(other_planar(), 71);
    spec.still = vec![1];
    let arm = ArmSource::Table(spec.table.clone());
    let (tr, va) = synth_pair(&spec);
    let o = match identify::run(&arm, vec![tr.into()], Some(va.into()), &Config::default()) {
        Ok(o) => o,
        Err(e) => panic!("a still joint must be a warning, not an error: {e}"),
    };
    assert_eq!(o.warnings.len(), 1, "{:?}", o.warnings);
    assert!(
        o.warnings[0].starts_with("joint 2 barely moves") && o.warnings[0].contains("±0.5 rad"),
        "{}",
        o.warnings[0]
    );
    let (moving, _) = run_synth(&Spec::new(other_planar(), 71), &Config::default());
    assert!(moving.warnings.is_empty(), "{:?}", moving.warnings);
}

/// `--strict` turns the warning into an error: exit 2, the joint named, nothing written; without
/// it the warning is printed and the report written.
#[test]
fn strict_refuses_a_joint_that_never_moves() {
    let mut spec = Spec::new(other_planar(), 72);
    spec.still = vec![1];
    let tr = generate(&spec);
    let dir = tempfile::tempdir().unwrap();
    let mut csv = String::from("t,q1,q2,tau1,tau2\n");
    let tau = tr.tau.as_ref().unwrap();
    for k in 0..tr.t.len() {
        csv += &format!(
            "{},{},{},{},{}\n",
            tr.t[k],
            tr.q[2 * k],
            tr.q[2 * k + 1],
            tau[2 * k],
            tau[2 * k + 1]
        );
    }
    let (data, arm) = (dir.path().join("still.csv"), dir.path().join("arm.toml"));
    std::fs::write(&data, csv).unwrap();
    std::fs::write(&arm, PLANAR2_OTHER).unwrap();
    let run = |out: &str, strict: bool| {
        let mut c = std::process::Command::new(env!("CARGO_BIN_EXE_dynid"));
        c.args(["identify", "--arm"])
            .arg(&arm)
            .arg("--data")
            .arg(&data);
        c.arg("--out").arg(dir.path().join(out));
        if strict {
            c.arg("--strict");
        }
        c.output().unwrap()
    };
    let o = run("strict", true);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(
        err.contains("--strict") && err.contains("joint 2 barely moves"),
        "{err}"
    );
    assert!(!dir.path().join("strict").exists());
    let o = run("lenient", false);
    assert!(o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("warning: joint 2 barely moves"));
    let md = std::fs::read_to_string(dir.path().join("lenient/report.md")).unwrap();
    assert!(md.contains("## Warnings") && md.contains("joint 2 barely moves"));
}

/// Stribeck friction (synthetic: `sgn(q̇)·exp(−(q̇/0.1)²)`, active only near velocity reversals)
/// is found on the right joint and nothing else. Its coefficient is not compared: the tool's
/// Stribeck column has its own velocity scale (0.1 × the joint's RMS velocity), so the two
/// coefficients belong to different shapes; the fit must bring the validation error down to
/// about the 1 % noise.
#[test]
fn stribeck_friction_is_found_on_the_right_joint() {
    let spec = Spec::new(other_planar(), 47).with_effect(Effect::Stribeck, 1, 1.0);
    let (o, _) = run_synth(&spec, &Config::default());
    assert_eq!(found(&o), ["stribeck2"]);
    let (before, after) = validation_before_after(&o);
    assert!(
        after < 0.013 && after < 0.7 * before,
        "validation {before} -> {after}"
    );
}

/// Load-dependent friction (synthetic: `μ·sgn(q̇)·|τ_rigid|`, gear friction growing with the
/// transmitted torque) is found on its joint in the second stage, coefficient within 5 %, and
/// the validation error drops to about the 1 % noise — after the cut-off scan is repeated with
/// the term in its models (the first scan's models cannot follow the load-scaled jumps and pick
/// filtered predictions: 2.1 % instead of 1.2 % on joint 2's seed). The first stage stands in
/// for it with a Coulomb term on the same joint; that term is dropped when redundant, but may
/// stay small (the second stage's load is the first stage's torque, Coulomb included):
/// measured μ = 0.149 of 0.15 with nothing else on joint 2, 0.097 of 0.1 next to a 0.017 N·m
/// Coulomb on joint 1. That small Coulomb term also absorbs what the two-stage model leaves
/// (the load is a model's torque, not the truth): since `drift` joined the candidates, the first
/// stage's larger family (Bonferroni) no longer admits it on seed 49, and joint 1's validation
/// error is 1.46 % instead of 1.26 % — hence the bar of 1.5 × the 1 % noise.
#[test]
fn load_dependent_friction_is_found_in_the_second_stage() {
    for (joint, mu, seed) in [(1, 0.15, 48), (0, 0.1, 49)] {
        let spec = Spec::new(other_planar(), seed).with_effect(Effect::LoadCoulomb, joint, mu);
        let (o, _) = run_synth(&spec, &Config::default());
        let term = |effect| Term::new(effect, joint).label();
        let label = term(Effect::LoadCoulomb);
        let f = found(&o);
        assert!(
            f.contains(&label) && f.iter().all(|l| *l == label || *l == term(Effect::Coulomb)),
            "{label}: found {f:?}"
        );
        let e = coef(&o, &label);
        assert!((e - mu).abs() < 0.05 * mu, "{label} = {e} (truth {mu})");
        // Absent (NaN) or small.
        let coulomb = coef(&o, &term(Effect::Coulomb));
        assert!(
            coulomb.is_nan() || coulomb.abs() < 0.25 * mu,
            "proxy Coulomb {coulomb}"
        );
        let (before, after) = validation_before_after(&o);
        assert!(
            after < 0.015 && after < 0.5 * before,
            "{label}: validation {before} -> {after}"
        );
    }
}

/// Study (`cargo test --release -- --ignored selection_power_and_false_positives`): false
/// positives on 66 clean synthetic runs (planar arms, SCARA) and how often a 1 N·m Stribeck
/// term is found in 10 runs. Measured: 0 / 66 and 10 / 10.
#[test]
#[ignore]
fn selection_power_and_false_positives() {
    let mut spurious = Vec::new();
    let mut clean = Vec::new();
    for seed in 100..130u64 {
        for table in [arm_table("planar2"), other_planar()] {
            clean.push(Spec {
                duration: 30.0,
                rate_hz: 500.0,
                ..Spec::new(table, seed)
            });
        }
    }
    for seed in 200..206u64 {
        clean.push(Spec {
            duration: 20.0,
            rate_hz: 250.0,
            ..Spec::new(arm_table("scara"), seed)
        });
    }
    for spec in &clean {
        let (o, _) = run_synth(spec, &Config::default());
        if !found(&o).is_empty() {
            spurious.push((spec.table.name.clone(), spec.seed, found(&o)));
        }
    }
    let hits = (40..50u64)
        .filter(|&seed| {
            let spec = Spec::new(other_planar(), seed).with_effect(Effect::Stribeck, 1, 1.0);
            found(&run_synth(&spec, &Config::default()).0).contains(&"stribeck2".to_string())
        })
        .count();
    eprintln!(
        "false positives {} / {}: {spurious:?}; Stribeck found {hits} / 10",
        spurious.len(),
        clean.len()
    );
    assert!(spurious.is_empty() && hits >= 9);
}

/// A synthetic PUMA 560 run of 12 s at 200 Hz.
fn puma_12s(seed: u64) -> Spec {
    Spec {
        duration: 12.0,
        rate_hz: 200.0,
        ..Spec::new(arm_table("puma560"), seed)
    }
}

/// A 6-DOF arm with two undeclared effects at once (viscous friction on the shoulder, a torque
/// offset on the wrist): exactly those two are found, with their values.
#[test]
fn puma_with_two_undeclared_effects_finds_exactly_them() {
    let spec = puma_12s(61)
        .with_effect(Effect::Viscous, 1, 0.8)
        .with_effect(Effect::Offset, 4, 0.15);
    let (o, _) = run_synth(&spec, &Config::default());
    assert_eq!(found(&o), ["offset5", "viscous2"], "found {:?}", found(&o));
    assert_coefs(&o, &[("viscous2", 0.8), ("offset5", 0.15)], 0.1);
    let (before, after) = validation_before_after(&o);
    assert!(after < 0.5 * before, "validation {before} -> {after}");
}

/// A per-run offset (a torque sensor re-zeroed between runs): joint 5's offset is 0 in the first
/// training run and 0.3 N·m in the second. `run_offset5@2`, the second run's offset over the
/// first's, is found with its value and nothing else; with the same offset in both runs the
/// offset is found, and no per-run one.
#[test]
fn a_per_run_offset_is_found_and_a_shared_one_is_not() {
    let spec = puma_12s(83);
    let arm = ArmSource::Table(spec.table.clone());
    let run = |seed: u64, offset: f64| {
        let mut s = spec.clone().with_effect(Effect::Offset, 4, offset);
        s.seed += seed;
        Log::from(generate(&s))
    };
    let cfg = Config::default();
    let o = identify::run(
        &arm,
        vec![run(0, 0.0), run(1, 0.3)],
        Some(run(2, 0.1)),
        &cfg,
    )
    .expect("identification");
    assert_eq!(found(&o), ["run_offset5@2"], "found {:?}", found(&o));
    assert_coefs(&o, &[("run_offset5@2", 0.3)], 0.1);
    // The report's offsets per run are the truth's; a new run gets their mean, in the params
    // file's `offset` too.
    let runs = dynid::report::run_offsets::per_joint(&o);
    assert_eq!(runs.len(), 1, "{runs:?}");
    let (got, truth) = (&runs[0], [0.0, 0.3]);
    assert_eq!(got.joint, 5);
    for (g, t) in got.offsets.iter().zip(truth) {
        assert!((g - t).abs() < 0.03, "{runs:?}");
    }
    assert!(
        (got.mean - 0.15).abs() < 0.03 && (got.sd - 0.212).abs() < 0.03,
        "{runs:?}"
    );
    let p = dynid::report::physical::params(&o).expect("a consistent estimate");
    let offset = p.effects.offset.as_ref().map_or(0.0, |v| v[4]);
    assert!((offset - 0.15).abs() < 0.03, "params offset5 {offset}");
    let shared =
        identify::run(&arm, vec![run(0, 0.2), run(1, 0.2)], None, &cfg).expect("identification");
    assert_eq!(found(&shared), ["offset5"], "found {:?}", found(&shared));
    // Declared: one training run has no per-run offset, and run 3 of two does not exist.
    for (train, effects, says) in [
        (vec![run(0, 0.0)], "run_offset:5", "two training files"),
        (
            vec![run(0, 0.0), run(1, 0.3)],
            "run_offset:5@3",
            "there are 2 training runs",
        ),
    ] {
        let cfg = Config {
            effects: dynid::effects::parse_list(effects, 6).unwrap(),
            ..Config::default()
        };
        let err = identify::run(&arm, train, None, &cfg)
            .unwrap_err()
            .to_string();
        assert!(err.contains(says), "{effects}: {err}");
    }
}

/// A log longer than the cut-off scan's sample budget (150 s at 1 kHz): the scan runs on pieces,
/// the final fit on every sample, and the undeclared effects are still found exactly, with their
/// values.
#[test]
fn long_log_is_scanned_on_pieces_and_still_finds_the_effects() {
    let spec = Spec {
        duration: 150.0,
        rate_hz: 1000.0,
        ..Spec::new(arm_table("planar2"), 19)
    }
    .with_effect(Effect::Viscous, 1, 0.5)
    .with_effect(Effect::Coulomb, 0, 0.8);
    let (o, _) = run_synth(&spec, &Config::default());
    assert!(o.train[0].rows > identify::SCAN_SAMPLES);
    assert!(o.cutoff_scan.len() >= 2, "{:?}", o.cutoff_scan);
    assert!(o.train[0].regression_row_every > 1);
    assert_eq!(found(&o), ["coulomb1", "viscous2"], "found {:?}", found(&o));
    assert_coefs(&o, &[("viscous2", 0.5), ("coulomb1", 0.8)], 0.05);
}

/// Armature on joint 1 (fixed axis) is the ZZR1 column: reported as merged, never found, and the
/// data are still fitted (ZZR1 absorbs it).
#[test]
fn joint1_armature_merges_with_zzr1() {
    let table = arm_table("planar2");
    let spec = Spec::new(table, 7).with_effect(Effect::Armature, 0, 0.2);
    let (o, truth) = run_synth(&spec, &Config::default());
    assert!(o
        .merged
        .iter()
        .any(|(t, w)| t == "armature1" && w.contains(&"ZZR1".to_string())));
    assert!(
        !found(&o).iter().any(|f| f == "armature1"),
        "{:?}",
        found(&o)
    );
    let zz = o.theta.iter().find(|p| p.name == "ZZR1").unwrap().value;
    assert!(
        (zz - (truth[0] + 0.2)).abs() < 0.01,
        "ZZR1 {zz} vs {} + 0.2",
        truth[0]
    );
}

/// A fixed list skips the search: exactly those terms, and `none` is the rigid model.
#[test]
fn fixed_effect_lists_are_fitted_as_given() {
    let spec = Spec::new(other_planar(), 9).with_effect(Effect::Viscous, 0, 0.4);
    let cfg = Config {
        effects: EffectsSpec::Fixed(vec![
            Term::new(Effect::Viscous, 0),
            Term::new(Effect::Offset, 1),
        ]),
        ..Config::default()
    };
    let (o, _) = run_synth(&spec, &cfg);
    assert!(o.selection.steps.is_empty());
    assert_eq!(o.effects.len(), 2);
    assert!((coef(&o, "viscous1") - 0.4).abs() < 0.012 && coef(&o, "offset2").abs() < 0.01);
    let none = Config {
        effects: EffectsSpec::Fixed(Vec::new()),
        ..Config::default()
    };
    let (o, _) = run_synth(&spec, &none);
    assert!(o.effects.is_empty() && o.after.train == o.before.train);
}

/// Uneven sampling (±30 % jitter) is resampled, reported, and still identified correctly.
#[test]
fn uneven_sampling_is_tolerated() {
    let spec = Spec {
        jitter: 0.3,
        ..Spec::new(other_planar(), 11)
    }
    .with_effect(Effect::Coulomb, 1, 0.3);
    let (o, truth) = run_synth(&spec, &Config::default());
    assert!(
        o.train[0].derivative.resampled
            && o.train[0].derivative.sampling.dt_max > 1.2 * o.train[0].derivative.sampling.dt_min
    );
    assert_eq!(found(&o), ["coulomb2"]);
    let err = o
        .theta
        .iter()
        .zip(&truth)
        .map(|(a, b)| (a.value - b).abs())
        .fold(0.0, f64::max);
    assert!(err < 0.01, "θ error {err}");
    let rows = o.predictions.as_ref().unwrap().len();
    assert!(rows as f64 >= 0.9 * o.validate.as_ref().unwrap().rows as f64);
}

/// Noise-free data with exact derivatives, unevenly sampled (resampled to a grid) and long enough
/// for several filter chunks: predictions from the states must reproduce the exact torque to
/// the resampling's interpolation error (measured 4e-6), those from the filtered rows to the
/// filter's passband loss on the torque's harmonics (measured 2.5e-5 at 5 Hz, 1.6e-4 at 2.5 Hz).
/// A one-sample misalignment of the interpolated rows would leave ~1e-2, a chunk seam without
/// filter margins a transient of the same order.
#[test]
fn filtered_and_state_predictions_reproduce_noise_free_torque() {
    let spec = Spec {
        jitter: 0.3,
        duration: 40.0,
        tau_noise: 0.0,
        q_resolution: None,
        with_derivatives: true,
        ..Spec::new(other_planar(), 5)
    };
    for (sm, tol) in [
        ("1,states", 1e-4),
        ("1,filtered", 2e-4),
        ("0.5,filtered", 1e-3),
    ] {
        let cfg = Config {
            effects: EffectsSpec::Fixed(Vec::new()),
            smoothing: Some(identify::Smoothing::parse(sm).unwrap()),
            derivative: derivative::Options {
                cutoff_hz: Some(5.0),
                ..derivative::Options::default()
            },
            ..Config::default()
        };
        let (o, truth) = run_synth(&spec, &cfg);
        assert!(o.train[0].derivative.resampled && o.train[0].rows > 16_384);
        assert_eq!(o.train[0].smoothing, cfg.smoothing.unwrap());
        let (tr, va) = (
            o.after.train.overall,
            o.after.validation.as_ref().unwrap().overall,
        );
        assert!(tr < tol && va < tol, "{sm}: train {tr}, validation {va}");
        let err = o
            .theta
            .iter()
            .zip(&truth)
            .map(|(a, b)| (a.value - b).abs())
            .fold(0.0, f64::max);
        assert!(err < 1e-3, "{sm}: θ error {err}");
    }
}

// --- derivative estimators against analytic derivatives ----------------------------------------

/// Fourier trajectory sampled at 500 Hz through a 2^17-count encoder: both estimators must
/// reproduce q̇ and q̈ to a small fraction of their range (quantisation step 4.8e-5 rad).
#[test]
fn derivative_estimators_match_analytic_derivatives() {
    let f = SynthExcitation::random(&[1.5, 1.0], 0.2, 5, 3);
    let fs = 500.0;
    let t: Vec<f64> = (0..20_000).map(|k| k as f64 / fs).collect();
    let res = 2.0 * std::f64::consts::PI / 131072.0;
    let q: Vec<Vec<f64>> = (0..2)
        .map(|j| {
            t.iter()
                .map(|&t| (f.eval(j, t).0 / res).round() * res)
                .collect()
        })
        .collect();
    for method in [Method::Butterworth, Method::SavitzkyGolay] {
        let est = derivative::estimate(
            &t,
            &q,
            None,
            &derivative::Options {
                method,
                cutoff_hz: None,
            },
        )
        .unwrap();
        for j in 0..2 {
            let (mut e1, mut e2, mut m1, mut m2) = (0.0f64, 0.0f64, 0.0f64, 0.0f64);
            for (k, &tk) in t.iter().enumerate().take(19_000).skip(1000) {
                let (_, dq, ddq) = f.eval(j, tk);
                e1 = e1.max((est.dq[j][k] - dq).abs());
                e2 = e2.max((est.ddq[j][k] - ddq).abs());
                m1 = m1.max(dq.abs());
                m2 = m2.max(ddq.abs());
            }
            assert!(
                e1 < 2e-3 * m1 && e2 < 1e-2 * m2,
                "{method:?} joint {j}: dq err {e1}/{m1}, ddq err {e2}/{m2}"
            );
        }
    }
}

// --- bad input ---------------------------------------------------------------------------

fn bin() -> Command {
    Command::new(env!("CARGO_BIN_EXE_dynid"))
}

/// Runs `cmd`, which must succeed (its stderr shown otherwise).
fn succeed(cmd: &mut Command) {
    let o = cmd.output().unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
}

fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

fn identify_cli(data: &Path, out: &Path) -> (i32, String) {
    let o = bin()
        .args(["identify", "--arm", "planar2", "--data"])
        .arg(data)
        .arg("--out")
        .arg(out)
        .output()
        .unwrap();
    (
        o.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&o.stderr).into_owned(),
    )
}

fn csv_rows(n: usize, f: impl Fn(usize) -> String) -> String {
    let mut s = String::from("t,q1,q2,tau1,tau2\n");
    for k in 0..n {
        s += &f(k);
        s.push('\n');
    }
    s
}

/// Malformed CSV, NaN, wrong column count, duplicate times and too few samples: exit code 2, a message naming the file and where, and no output written.
#[test]
fn bad_input_is_rejected_with_a_clear_message_and_no_output() {
    let dir = tempfile::tempdir().unwrap();
    let good = |k: usize| {
        let t = k as f64 * 0.01;
        format!(
            "{t},{},{},{},{}",
            (0.7 * t).sin(),
            (1.3 * t).cos(),
            (0.5 * t).sin(),
            t.cos()
        )
    };
    let cases: Vec<(&str, String, Vec<&str>)> = vec![
        (
            "malformed.csv",
            csv_rows(200, |k| {
                if k == 10 {
                    "0.1,abc,0,0,0".into()
                } else {
                    good(k)
                }
            }),
            vec!["malformed.csv", ":12", "q1", "abc"],
        ),
        (
            "nan.csv",
            csv_rows(200, |k| {
                if k == 20 {
                    "0.2,0,NaN,0,0".into()
                } else {
                    good(k)
                }
            }),
            vec!["nan.csv", ":22", "q2"],
        ),
        (
            "columns.csv",
            csv_rows(200, |k| if k == 30 { "0.3,0,0,0".into() } else { good(k) }),
            vec!["columns.csv", ":32", "fields"],
        ),
        (
            "duplicate.csv",
            csv_rows(200, |k| good(if k == 41 { 40 } else { k })),
            vec!["duplicate.csv", ":43", "does not increase"],
        ),
        (
            "gap.csv",
            csv_rows(400, |k| {
                let row = good(k);
                if k < 250 {
                    return row;
                }
                let (t, rest) = row.split_once(',').unwrap();
                format!("{},{rest}", t.parse::<f64>().unwrap() + 5.0)
            }),
            vec![
                "gap.csv",
                "gap in the sample times",
                "data row 251",
                "split the file",
            ],
        ),
        (
            "short.csv",
            csv_rows(10, good),
            vec!["short.csv", "10 samples"],
        ),
    ];
    for (name, text, needles) in cases {
        let data = write(dir.path(), name, &text);
        let out = dir.path().join(format!("out_{name}"));
        let (code, err) = identify_cli(&data, &out);
        assert_eq!(code, 2, "{name}: exit code {code}, stderr {err}");
        for n in needles {
            assert!(err.contains(n), "{name}: `{n}` not in: {err}");
        }
        assert!(!out.exists(), "{name}: output written despite the error");
    }
    // Joint 1 never moves: `ZZR1` and one of its gravity pair cannot be identified. That was a
    // rank-deficiency error; now they are held at 0 and named (a warning), and `--strict`
    // refuses (exit 2, nothing written).
    let still = csv_rows(3000, |k| {
        let t = k as f64 * 0.01;
        let (s, c) = ((0.9 * t).sin(), (0.9 * t).cos());
        format!("{t},0.5,{s},{c},{}", 0.1 * t.sin())
    });
    let data = write(dir.path(), "still.csv", &still);
    let out = dir.path().join("out_still");
    let (code, err) = identify_cli(&data, &out);
    assert_eq!(code, 0, "{err}");
    // Which of the gravity pair is held depends on the column order (here `MY1`: q1 = 0.5 rad).
    for n in [
        "warning: joint 1 barely moves",
        "identify `ZZR1`, `M",
        "held at 0",
    ] {
        assert!(err.contains(n), "`{n}` not in: {err}");
    }
    let md = std::fs::read_to_string(out.join("report.md")).unwrap();
    assert!(
        md.contains("held at 0: not identifiable from this data"),
        "{md}"
    );
    let json = std::fs::read_to_string(out.join("report.json")).unwrap();
    let r: serde_json::Value = serde_json::from_str(&json).unwrap();
    assert_eq!(r["fixed"][0], "ZZR1", "{}", r["fixed"]);
    let strict = dir.path().join("out_still_strict");
    let o = bin()
        .args(["identify", "--arm", "planar2", "--strict", "--data"])
        .arg(&data)
        .arg("--out")
        .arg(&strict)
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("identify `ZZR1`, `M"));
    assert!(!strict.exists());
}

// --- the command line end to end -------------------------------------------------------------

/// `dynid identify` on a small synthetic log: report files, `report.json` fields, and the
/// validation CSV from which the reported errors can be recomputed.
#[test]
fn cli_identify_writes_report_and_recomputable_predictions() {
    let dir = tempfile::tempdir().unwrap();
    let spec = Spec {
        duration: 20.0,
        ..Spec::new(arm_table("planar2"), 21)
    }
    .with_effect(Effect::Viscous, 1, 0.5);
    let (tr, va) = synth_pair(&spec);
    let (ptr, pva) = (dir.path().join("train.csv"), dir.path().join("val.csv"));
    for (t, p) in [(&tr, &ptr), (&va, &pva)] {
        let mut f = std::fs::File::create(p).unwrap();
        t.write_csv(&mut f).unwrap();
    }
    let out = dir.path().join("report");
    let o = bin()
        .args(["identify", "--arm", "planar2", "--data"])
        .arg(&ptr)
        .arg("--validate")
        .arg(&pva)
        .arg("--out")
        .arg(&out)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    for f in [
        "report.md",
        "report.json",
        "validation_prediction.csv",
        "residual_vs_velocity_joint1.svg",
        "validation_joint2.svg",
    ] {
        assert!(out.join(f).exists(), "{f} missing");
    }
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).unwrap()).unwrap();
    assert_eq!(json["effects_found"][0]["effect"], "viscous");
    assert_eq!(json["effects_found"][0]["joint"], 2);
    assert!(json["theta"]
        .as_array()
        .unwrap()
        .iter()
        .all(|p| p["rel_std_percent"].is_number() || p["rel_std_percent"].is_null()));
    let csv = std::fs::read_to_string(out.join("validation_prediction.csv")).unwrap();
    let mut lines = csv.lines();
    assert_eq!(
        lines.next().unwrap(),
        "t,tau1,tau2,before1,before2,after1,after2,consistent1,consistent2"
    );
    let rows: Vec<Vec<f64>> = lines
        .map(|l| l.split(',').map(|v| v.parse().unwrap()).collect())
        .collect();
    assert!(rows.len() as f64 >= 0.9 * va.len() as f64);
    // t and tau are the validation file's own values.
    let k0 =
        va.t.iter()
            .position(|&t| t == rows[0][0])
            .expect("t copied from the file");
    assert_eq!(rows[0][1], va.tau.as_ref().unwrap()[2 * k0]);
    // Recompute the overall after-error from the CSV: equals report.json's.
    let (mut sse, mut tss) = (0.0, 0.0);
    for r in &rows {
        for j in 0..2 {
            sse += (r[5 + j] - r[1 + j]).powi(2);
            tss += r[1 + j].powi(2);
        }
    }
    let reported = json["error"]["after"]["validation"]["overall"]
        .as_f64()
        .unwrap();
    assert!(
        ((sse / tss).sqrt() - reported).abs() < 1e-9 * reported.max(1.0),
        "{} vs {reported}",
        (sse / tss).sqrt()
    );
    // The same for the consistent estimate's columns.
    let sse: f64 = rows
        .iter()
        .map(|r| (0..2).map(|j| (r[7 + j] - r[1 + j]).powi(2)).sum::<f64>())
        .sum();
    let reported = json["physical"]["error"]["validation"]["overall"]
        .as_f64()
        .unwrap();
    assert!(((sse / tss).sqrt() - reported).abs() < 1e-9 * reported.max(1.0));
    // The guard's paragraph states the critical value and level report.json holds, each in its
    // place (a shifted format argument once printed t_crit after "least-squares solve").
    let md = std::fs::read_to_string(out.join("report.md")).unwrap();
    let t_crit = json["guard"]["joints"][0]["t_crit"].as_f64().unwrap();
    let alpha = json["guard"]["alpha"].as_f64().unwrap();
    let expect = format!(
        "it acts above {t_crit:.2}, family level {} % over the joints",
        100.0 * alpha
    );
    assert!(md.contains(&expect), "{expect:?} not in report.md");
    assert!(md.contains("(one least-squares solve)"), "{md}");
}

/// Issue 18's "parameters the data cannot determine": a PUMA 560 driven for 4 s by one slow
/// harmonic leaves several inertial parameters free to trade torque with others; the outcome must
/// name them (a one-σ change of each moves the prediction by more than the residual), with the
/// fix, while 30 s of five harmonics names none. The named ones are uncertain for real: each
/// one's block-jackknife σ is over 10 × its σ from the rich data.
#[test]
fn parameters_the_data_cannot_determine_are_named() {
    let mut weak = Spec::new(arm_table("puma560"), 5);
    (weak.duration, weak.harmonics) = (4.0, 1);
    let (w, _) = run_synth(&weak, &Config::default());
    let (rich, _) = run_synth(&Spec::new(arm_table("puma560"), 5), &Config::default());
    assert!(rich.undetermined.is_empty(), "{:?}", rich.undetermined);
    assert!(w.undetermined.len() >= 2, "{:?}", w.undetermined);
    let warning = w
        .warnings
        .iter()
        .find(|m| m.starts_with("the training data do not determine"))
        .unwrap_or_else(|| panic!("{:?}", w.warnings));
    for u in &w.undetermined {
        assert!(u.torque_sigma > 1.0, "{u:?}");
        assert!(warning.contains(&format!("`{}`", u.name)), "{warning}");
        // The σ comparison is for the inertial parameters (the per-joint guard may add plain
        // friction terms to the short run's model that the rich run's search did not need).
        let Some(r) = rich.theta.iter().find(|t| t.name == u.name) else {
            continue;
        };
        assert!(
            u.std > 10.0 * r.std,
            "{}: weak σ {}, rich σ {}",
            u.name,
            u.std,
            r.std
        );
    }
    assert!(warning.contains("dynid excite") && warning.contains("--prior"));
}

/// Issue 18's "unidentifiable columns are fixed and reported, never silently fitted": with
/// joint 1 held still, `ZZR1` and `MXR1` are combinations of the other columns (they were a
/// rank-deficiency error before). Now they are held at 0 and named; the rest is fitted and
/// predicts held-out data with joint 1 still at the noise level (1 %); the consistent
/// estimate still exists (it decides them, like any direction the data cannot see).
#[test]
fn base_parameters_the_data_cannot_see_are_held_at_zero_and_named() {
    let mut spec = Spec::new(other_planar(), 71);
    spec.still = vec![0];
    let arm = ArmSource::Table(spec.table.clone());
    let (tr, va) = synth_pair(&spec);
    let o = identify::run(&arm, vec![tr.into()], Some(va.into()), &Config::default())
        .unwrap_or_else(|e| panic!("must be a warning, not an error: {e}"));
    assert_eq!(o.fixed, ["ZZR1", "MXR1"], "{:?}", o.fixed);
    // Named as undetermined only among the fitted ones, with their own σ.
    for u in &o.undetermined {
        assert!(!o.fixed.contains(&u.name) && u.std.is_finite(), "{u:?}");
    }
    for t in &o.theta {
        let fixed = o.fixed.contains(&t.name);
        assert_eq!(fixed, t.value == 0.0 && t.std.is_nan(), "{t:?}");
        assert_eq!(fixed, t.expression.contains("held at 0"), "{t:?}");
    }
    let w = o
        .warnings
        .iter()
        .find(|w| w.starts_with("the training data cannot identify"))
        .unwrap_or_else(|| panic!("{:?}", o.warnings));
    assert!(w.contains("`ZZR1`, `MXR1`") && w.contains("--prior"), "{w}");
    assert!(o
        .warnings
        .iter()
        .any(|w| w.starts_with("joint 1 barely moves")));
    let (_, after) = validation_before_after(&o);
    assert!(after < 0.015, "validation {after}");
    let c = o.consistent.as_ref().expect("consistent estimate");
    let cv = c.validation.as_ref().unwrap().overall;
    assert!(cv < 0.015, "consistent validation {cv}");
}

/// Issue 40's residual maps, end to end: `dynid identify` on the shared simulated set writes per
/// joint six maps (q, dq, ddq, time, run, tau_hat) over every used training sample, quantile bins
/// in order with their band around the mean, one SVG per joint and the report.md section. The
/// binned residual is the final model's held-out one: the joints' sums of squares, from any
/// map's bins, against Σ τ² over the samples used (those within the time map's range), give
/// the final model's held-out error over the training blocks in report.json to rounding — not
/// its in-sample training error (0.03 % lower on this data), nor the rigid model's.
#[test]
fn cli_identify_writes_residual_maps_of_the_final_models_heldout_residual() {
    let d = data("sim/planar2_paper_friction");
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("report");
    let o = bin()
        .args(["identify", "--arm"])
        .arg(d.join("arm.toml"))
        .arg("--data")
        .arg(d.join("excite_noisy.csv.gz"))
        .arg("--out")
        .arg(&out)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).unwrap()).unwrap();
    let used = json["data"]["train"][0]["rows_used"].as_u64().unwrap();
    assert_eq!(json["residual_maps_info"]["every"], 1);
    assert_eq!(json["residual_maps_info"]["samples"], used);
    let maps = json["residual_maps"].as_array().unwrap();
    assert_eq!(maps.len(), 12);
    // Σ τ² of each joint over the samples used: those whose time since the file's start lies
    // within the time map's bins (the used samples are one stretch of the file).
    let f = |b: &serde_json::Value, k: &str| b[k].as_f64().unwrap();
    let time_bins = maps[3]["bins"].as_array().unwrap();
    let first = time_bins
        .iter()
        .map(|b| f(b, "lo"))
        .fold(f64::INFINITY, f64::min);
    let last = time_bins
        .iter()
        .map(|b| f(b, "hi"))
        .fold(f64::NEG_INFINITY, f64::max);
    let log = Log::open(&d.join("excite_noisy.csv.gz"), Some(2)).unwrap();
    let at = log.layout.tau_offset().unwrap();
    let t0 = log.t(0);
    let (mut tss, mut rows) = ([0.0; 2], 0);
    log.rows(0, log.len(), |r| {
        if (first..=last).contains(&(r[0] - t0)) {
            rows += 1;
            for j in 0..2 {
                tss[j] += r[at + j] * r[at + j];
            }
        }
    });
    assert_eq!(rows, used);
    let err = |model: &str, key: &str| json["error"][model][key].as_f64().unwrap();
    let mut sse_by_variable = [Vec::new(), Vec::new()];
    for (j, joint) in maps.chunks(6).enumerate() {
        let names: Vec<&str> = joint
            .iter()
            .map(|m| m["variable"].as_str().unwrap())
            .collect();
        assert_eq!(names, ["q", "dq", "ddq", "time", "run", "tau_hat"]);
        for m in joint {
            assert_eq!(m["joint"], j + 1);
            let bins = m["bins"].as_array().unwrap();
            let n: u64 = bins.iter().map(|b| b["n"].as_u64().unwrap()).sum();
            assert_eq!(n, used, "{}", m["variable"]);
            let want = if m["variable"] == "run" { 1 } else { 12 };
            assert_eq!(bins.len(), want);
            for (k, b) in bins.iter().enumerate() {
                assert!(f(b, "lo") <= f(b, "centre") && f(b, "centre") <= f(b, "hi"));
                assert!(f(b, "ci95_lo") < f(b, "mean") && f(b, "mean") < f(b, "ci95_hi"));
                if k > 0 {
                    assert!(f(&bins[k - 1], "hi") < f(b, "lo"));
                }
            }
            let p = m["p_value"].as_f64().unwrap();
            assert!((0.0..=1.0).contains(&p));
            let sse: f64 = bins
                .iter()
                .map(|b| {
                    let n = b["n"].as_u64().unwrap() as f64;
                    (n - 1.0) * f(b, "std").powi(2) + n * f(b, "mean").powi(2)
                })
                .sum();
            sse_by_variable[j].push(sse);
        }
        assert!(out
            .join(format!("residual_map_joint{}.svg", j + 1))
            .exists());
    }
    // Every variable's bins hold the same residuals: one pooled error per variable.
    let [first_joint, second_joint] = &sse_by_variable;
    for (k, (a, b)) in first_joint.iter().zip(second_joint).enumerate() {
        let pooled = ((a + b) / (tss[0] + tss[1])).sqrt();
        let heldout = err("after", "heldout_train_blocks");
        assert!(
            (pooled / heldout - 1.0).abs() < 1e-9,
            "map {k}: {pooled} vs held-out {heldout}"
        );
        assert!(err("before", "heldout_train_blocks") > 1.2 * pooled);
    }
    let md = std::fs::read_to_string(out.join("report.md")).unwrap();
    assert!(md.contains("## Residual maps") && md.contains("](residual_map_joint2.svg)"));
    assert!(md.contains("held-out torque residual"));
}

/// Joint 3 of the real TIAGo run (data/real/tiago_figaroh): `coulomb3` removes about 70 % of its
/// held-out residual, concentrated in the blocks where the joint reverses. With uncapped per-block
/// log ratios the search's t-test fell short (t = 3.2 against 4.0) and only the guard's
/// coefficient route brought it back; with each ratio capped at ±ln 4 the search must find it
/// itself, and joint 3 must predict the unseen last 30 % of the run as well as the plain fit
/// (without the term: 1.40 × the plain fit's error). The coefficient route still runs where the
/// plain fit wins pooled but not block after block (the torso, joint 1): its tests are reported
/// and a term is added only above its critical value.
#[test]
fn tiago_joint3_coulomb_friction_is_found_by_the_search() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../data/real/tiago_figaroh");
    let dir = tempfile::tempdir().unwrap();
    let arm_dir = dir.path().join("arm");
    succeed(
        bin()
            .arg("import-urdf")
            .arg(root.join("tiago.urdf"))
            .arg("--out")
            .arg(&arm_dir),
    );
    let out = dir.path().join("report");
    succeed(
        bin()
            .arg("identify")
            .arg("--arm")
            .arg(arm_dir.join("tiago.toml"))
            .arg("--data")
            .arg(root.join("fit.csv.gz"))
            .arg("--validate")
            .arg(root.join("holdout.csv.gz"))
            .args(["--physical", "off", "--out"])
            .arg(&out),
    );
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).unwrap()).unwrap();
    let found: Vec<String> = json["effects_found"]
        .as_array()
        .unwrap()
        .iter()
        .map(|e| format!("{}{}", e["effect"].as_str().unwrap(), e["joint"]))
        .collect();
    assert!(found.contains(&"coulomb3".to_string()), "{found:?}");
    let j3 = &json["guard"]["joints"][2];
    for t in json["guard"]["joints"]
        .as_array()
        .unwrap()
        .iter()
        .flat_map(|j| j["coefficient_tests"].as_array().unwrap())
    {
        let (z, z_crit) = (t["z"].as_f64().unwrap(), t["z_crit"].as_f64().unwrap());
        assert!(z.is_finite() && z_crit > 2.0, "{t}");
        assert!(z > z_crit || t["added"] == false, "{t}");
    }
    let (sel, plain) = (
        j3["validation_selected"].as_f64().unwrap(),
        j3["validation_plain"].as_f64().unwrap(),
    );
    assert!(
        sel <= 1.02 * plain,
        "joint 3: {sel} against the plain fit's {plain}"
    );
}
